//! The independent watchdog (IWDG, RM0383 §17), started first thing in start-up and fed by the
//! main loop. Its timeout is [`firmware::board::watchdog::STM32F411`]: chosen from the LSI's
//! fastest rate, so that a busy pass never trips it on any chip (see that module for the
//! arithmetic and the measurement behind it).
//!
//! Once started it cannot be stopped: every way out of start-up or of the loop that is not a feed
//! (a stop, a panic, a fault, a hang) ends in its reset, and start-up then takes the servos'
//! torque off (a watchdog reset, `firmware::board::reset`).

use firmware::board::watchdog::Iwdg;
use stm32f4xx_hal::pac::{DBGMCU, IWDG};

/// How many times IWDG_SR is polled for a prescaler or reload update to finish. An update takes
/// up to 5 periods of the divided LSI (RM0383 §17.4.4: PVU, RVU), a few milliseconds at the
/// slowest setting; the core polls far faster than that, and a bound keeps a dead LSI from
/// hanging start-up here (the watchdog would then never reset anything either: nothing to wait for).
const UPDATE_POLLS: u32 = 2_000_000;

/// The running watchdog.
pub struct Watchdog {
    iwdg: IWDG,
}

impl Watchdog {
    /// Starts the watchdog with `setting`. In a release build it keeps counting while a debugger
    /// halts the core, so a halt longer than the timeout resets the chip and the servos' torque
    /// goes off: the arm is never held for longer with nothing running it. A debug build's pauses
    /// while halted (DBGMCU_APB1_FZ.DBG_IWDG_STOP), so that breakpoints work; the arm then holds
    /// its last goal while halted.
    pub fn start(iwdg: IWDG, dbgmcu: &DBGMCU, setting: Iwdg) -> Self {
        dbgmcu.apb1_fz().modify(|_, w| w.dbg_iwdg_stop().bit(cfg!(debug_assertions)));
        // Started before it is set, as RM0383's sequence has it: the LSI starts with it, and
        // the setting is written while the count runs from its reset value (about 0.5 s).
        iwdg.kr().write(|w| w.key().start());
        let mut watchdog = Self { iwdg };
        watchdog.set(setting);
        watchdog
    }

    /// Writes `setting`, waits (bounded) for the watchdog to take it, and feeds it, so that the
    /// count restarts from the new reload value.
    pub fn set(&mut self, setting: Iwdg) {
        self.iwdg.kr().write(|w| w.key().unlock());
        self.iwdg.pr().write(|w| w.pr().set(setting.pr));
        self.iwdg.rlr().write(|w| w.rl().set(setting.rlr));
        for _ in 0..UPDATE_POLLS {
            let sr = self.iwdg.sr().read();
            if sr.pvu().bit_is_clear() && sr.rvu().bit_is_clear() {
                break;
            }
        }
        self.feed();
    }

    /// Restarts the count (the main loop's feed on every pass).
    pub fn feed(&mut self) {
        self.iwdg.kr().write(|w| w.key().feed());
    }
}
