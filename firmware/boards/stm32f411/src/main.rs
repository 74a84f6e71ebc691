//! The firmware for an STM32F411 "Black Pill" (STM32F411CEU6, 25 MHz crystal): USART1 is the host
//! link to a USB-serial adapter (its bytes kept by the receive interrupt, `link_rx.rs`), USART2
//! the servo bus (Feetech, 1 Mbps, one wire), TIM2 the time base; the built-in SO-101 arm.
//! Everything else is the firmware core: the application ([`firmware::app::Firmware`]), its
//! start-up in static memory ([`firmware::board::Slots`]) and the main loop every board runs
//! ([`firmware::board::MainLoop`]); this file only wires the hardware to them. The defmt log goes
//! over RTT (`board-support`'s `rtt-log`), which a probe reads.
//!
//! | pin  | use                                                                   |
//! |------|-----------------------------------------------------------------------|
//! | PA9  | USART1 TX, host link (to the adapter's RX)                            |
//! | PA10 | USART1 RX, host link (from the adapter's TX)                          |
//! | PA2  | USART2 TX/RX, servo bus data, open drain, external pull-up to 3.3 V   |
//! | PA1  | bus direction, high while transmitting (for a tri-state buffer board) |
#![no_std]
#![no_main]

mod clock;
mod half_duplex;
mod link_rx;
mod power;
mod serial;
mod watchdog;

// The defmt global logger over RTT (feature `rtt-log`): linked in by this use alone.
use board_support as _;

use cortex_m_rt::{entry, exception, ExceptionFrame};
use firmware::app::Board;
use firmware::board::reset::{ResetCause, ResetFlags};
use firmware::board::{MainLoop, Slots, StartError};
use firmware::bus::master::{BusConfig, Master};
use firmware::bus::table::STS3215;
use firmware::controller::Config;
use stm32f4xx_hal::gpio::{Output, PinState, PA1};
use stm32f4xx_hal::pac;
use stm32f4xx_hal::prelude::*;
use stm32f4xx_hal::rcc;
use stm32f4xx_hal::serial::{config::Config as SerialConfig, Event as SerialEvent, Serial};

use clock::Tim2Clock;
use half_duplex::HalfDuplex;
use serial::Link;
use watchdog::Watchdog;

/// Host link and servo bus baud rate.
const BAUD: u32 = 1_000_000;

/// The bus direction output: high while the board transmits on the bus.
///
/// Driving it costs one pin and makes both wirings work with the same binary: the servo data line
/// straight on PA2 (PA1 left unconnected; the USART's single-wire mode needs no direction signal),
/// or a 74HC126 + 74HC04 tri-state buffer adapter whose transmit buffer PA1 enables (and, inverted,
/// whose receive buffer it disables). The master raises it before the first byte and lowers it after
/// `flush`, which waits for transmission complete.
type DirectionPin = PA1<Output>;
/// Any arm of 1 to [`firmware::board::JOINTS`] joints (the built-in SO-101 has 5).
const JOINTS: usize = firmware::board::JOINTS;
/// Keyframe queue slots.
const QUEUE: usize = 32;
type BusMaster = Master<HalfDuplex, DirectionPin, Tim2Clock>;
/// The main loop over the firmware, the bus master and the link's receive ring.
type Loop = MainLoop<'static, JOINTS, QUEUE, { link_rx::LINK_RX_BYTES }, HalfDuplex, DirectionPin, Tim2Clock>;

/// The firmware state and the bus master, in static RAM (see [`Slots`]).
static SLOTS: Slots<JOINTS, QUEUE, BusMaster> = Slots::new();

/// The independent watchdog's setting: its shortest real timeout (the LSI at its fastest) is twice
/// the main loop's longest measured pass ([`firmware::board::watchdog`]).
const WATCHDOG: firmware::board::watchdog::Iwdg = firmware::board::watchdog::STM32F411;

/// The crystal's start-up time is 2 ms typical (DS10314, HSE 4-26 MHz oscillator
/// characteristics); RCC_CR.HSERDY is polled once a millisecond for this many milliseconds.
const HSE_WAIT_MS: u32 = 100;
/// Cycles of a millisecond on the 16 MHz internal oscillator the chip starts on.
const HSI_CYCLES_PER_MS: u32 = 16_000;

/// Logs why start-up stopped (the host then sees no handshake); the caller then halts, and the
/// watchdog resets the chip ([`halt`]).
fn refused<T>(what: defmt::Str) -> Option<T> {
    defmt::error!("start-up stopped: {=istr}", what);
    None
}

#[entry]
fn main() -> ! {
    let Some((main_loop, link, watchdog)) = start() else { halt() };
    run(main_loop, link, watchdog)
}

/// Brings up the watchdog first, then the bus direction pin, the supply's checks, the clocks, the
/// two USARTs, the timer and the firmware core; `None` (with an error line in the log) if anything
/// is refused or this ran before (the statics are written once). Never inlined, so that its frame
/// is gone before the control loop starts.
#[inline(never)]
fn start() -> Option<(Loop, Link, Watchdog)> {
    let Some(dp) = pac::Peripherals::take() else { return refused(defmt::intern!("peripherals taken")) };
    // The watchdog first: from here on every way start-up can stop (a refusal, a panic, a fault,
    // a hang in a driver) ends in its reset, after which start-up takes the servos' torque off.
    // Its timeout covers start-up's longest step, the crystal's wait (HSE_WAIT_MS).
    let mut watchdog = Watchdog::start(dp.IWDG, &dp.DBGMCU, WATCHDOG);
    // PA1 low next, before the crystal's wait: a tri-state buffer's transmit enable must not
    // float over the servos' replies while start-up runs (the README's 10 kΩ pull-down covers
    // the reset itself). Splitting GPIOA resets the port, whose pins are inputs out of reset
    // anyway, and PA1 is driven at once.
    let mut rcc = dp.RCC.constrain();
    let gpioa = dp.GPIOA.split(&mut rcc);
    let direction: DirectionPin = gpioa.pa1.into_push_pull_output_in_state(PinState::Low);
    // Why the chip was reset decides the servos' torque (firmware::board::reset). Read before
    // the clocks, then cleared (RMVF), so that the next reset's flags are its own.
    let cause = reset_cause(&rcc);
    let supply = power::read(&rcc, &dp.PWR, &dp.FLASH);
    log_reset(cause, supply);
    log_bor_write(power::raise_bor_to_level_3(
        &dp.FLASH,
        &dp.PWR,
        &mut watchdog,
        WATCHDOG,
        cause == ResetCause::PowerOn,
    ));
    // 25 MHz crystal, PLL to 84 MHz: the most the F411 runs at in power scale 2 (RM0383 §5.1.3,
    // PWR_CR.VOS), written here before the PLL starts (`power`). USART1 (APB2, 84 MHz:
    // USARTDIV 5.25) and USART2 (APB1, 42 MHz: USARTDIV 2.625) both divide exactly to 1 Mbps,
    // and TIM2's 84 MHz to microseconds. The HAL's `freeze` waits for the crystal without a
    // bound, so it is given the crystal only once `crystal_runs` has seen it run. Without one,
    // the chip stays on its 16 MHz internal oscillator (HSI) as reset leaves it, PLL off: 1 Mbps
    // still divides exactly on both USARTs (USARTDIV 1) and TIM2 still counts microseconds, but
    // the bus cannot go faster, the loop runs at a fifth of the speed, and the HSI is trimmed to
    // 1 % at 25 °C only (DS10314, HSI oscillator characteristics; more over temperature), as is
    // every baud rate then.
    power::select_scale_2(&dp.PWR);
    if crystal_runs(&rcc) {
        rcc = rcc.freeze(rcc::Config::hse(25.MHz()).sysclk(84.MHz()));
    } else {
        defmt::error!(
            "no crystal (HSERDY not set in {=u32} ms): running on the internal 16 MHz oscillator, PLL off; check the 25 MHz crystal",
            HSE_WAIT_MS
        );
    }
    watchdog.feed();
    let Some(clock) = Tim2Clock::start(dp.TIM2, &mut rcc) else { return refused(defmt::intern!("TIM2 clock")) };

    let link_config = SerialConfig::default().baudrate(BAUD.bps());
    // No internal pull-up on PA10: the pin is 5 V tolerant (FT) only with it off (DS10314, I/O
    // characteristics), and an adapter with 5 V logic would otherwise drive current through it
    // into the 3.3 V supply. With the adapter unplugged RX floats: what noise it reads fails
    // the link's frame check (the README's optional external pull-up keeps it quiet).
    let Ok(mut usart1) = Serial::new(dp.USART1, (gpioa.pa9, gpioa.pa10), link_config, &mut rcc) else {
        return refused(defmt::intern!("USART1 (host link)"));
    };
    usart1.listen(SerialEvent::RxNotEmpty);
    link_rx::enable();
    let link = Link::new(usart1);

    // No internal pull-up on PA2 either (FT only with it off; the receive buffer of a 5 V
    // adapter drives it to 5 V): the bus needs the external ~1 kΩ one to 3.3 V for 1 Mbps edges
    // anyway, which the README's wiring requires.
    let _bus_pin = gpioa.pa2.into_alternate_open_drain::<7>();
    let Some(bus_port) = HalfDuplex::new(dp.USART2, BAUD, &mut rcc) else {
        return refused(defmt::intern!("USART2 (servo bus)"));
    };
    // The receiver is off while the board transmits (see half_duplex.rs): no echo to skip.
    let bus = BusConfig { echo: false, ..BusConfig::new(STS3215.protocol, BAUD) };

    let (scale, scale_ready) = power::scale_in_force(&dp.PWR);
    defmt::info!(
        "stm32f411: link USART1 {=u32} bps (PA9/PA10), bus USART2 {=u32} bps one-wire PA2, sysclk {=u32} Hz, voltage scale {=u8} (VOSRDY {=bool})",
        BAUD,
        BAUD,
        rcc.clocks.sysclk().raw(),
        scale,
        scale_ready
    );

    let board = Board { bus, model: &STS3215, control: Config::default(), max_bus_baud: bus_port.max_baud() };
    // The servos' torque goes off unless the reset button was pressed (`log_reset`).
    let started = SLOTS.start(board, &firmware::builtin::SO101, cause, &link_rx::LINK_RX, || {
        BusMaster::new(bus_port, direction, clock, bus)
    });
    let main_loop = match started {
        Ok(main_loop) => main_loop,
        // Interned, as every text here: defmt keeps it on the host, not in flash.
        Err(StartError::Twice) => return refused(defmt::intern!("started twice")),
        Err(StartError::Arm(_)) => return refused(defmt::intern!("built-in arm refused")),
    };
    Some((main_loop, link, watchdog))
}

/// The control loop ([`MainLoop`]): host bytes as the receive interrupt kept them, a tick on the
/// fixed schedule, the watchdog fed on every pass. It does not sleep: TIM2 counts time but raises
/// no interrupt to wake it.
#[inline(never)]
fn run(main_loop: Loop, mut link: Link, mut watchdog: Watchdog) -> ! {
    main_loop.run(&mut link, |_, _| watchdog.feed())
}

/// The log's first line: the reset's cause and what it does to the servos' torque, the voltage
/// scale and the brown-out reset level as read back, before the clocks start. The texts are
/// interned: defmt keeps them on the host, none in flash.
fn log_reset(cause: ResetCause, supply: power::Supply) {
    let what = match cause {
        ResetCause::PowerOn => defmt::intern!("reset by power-on: servos' torque off"),
        ResetCause::BrownOut => defmt::intern!("reset by brown-out: servos' torque off"),
        ResetCause::Watchdog => defmt::intern!("reset by the watchdog: servos' torque off"),
        ResetCause::Fault => defmt::intern!("reset after a fault: servos' torque off"),
        ResetCause::LowPower => defmt::intern!("reset by low-power management: servos' torque off"),
        ResetCause::Software => defmt::intern!("software reset (a debugger's): servos' torque off"),
        ResetCause::Pin => defmt::intern!("reset by the reset pin: servos found torqued are held where they stand"),
        ResetCause::Unknown => defmt::intern!("reset, no cause flagged: servos' torque off"),
    };
    defmt::info!(
        "stm32f411: {=istr}; voltage scale {=u8}, brown-out reset level {=u8} (0: off); starting the clocks",
        what,
        supply.scale,
        supply.bor_level
    );
}

/// What start-up did about the brown-out reset level, when it was not already set (interned
/// texts, as in [`log_reset`]).
fn log_bor_write(write: power::BorWrite) {
    let what = match write {
        power::BorWrite::AlreadySet => return,
        power::BorWrite::Written => {
            defmt::intern!("was below level 3: level 3 (2.7 V) written to the option bytes and read back")
        }
        power::BorWrite::NotAfterThisReset => defmt::intern!(
            "below level 3: written only after a power-on; until then a sag below 2.7 V runs on unchecked"
        ),
        power::BorWrite::SupplyLow => defmt::intern!(
            "below level 3, not written: the supply is below the PVD's highest threshold; check the 3.3 V rail"
        ),
        power::BorWrite::Failed => {
            defmt::intern!("level 3 written but not read back; set it with a probe (README, bring-up)")
        }
    };
    defmt::warn!("brown-out reset {=istr}", what);
}

/// Why the chip was reset, from RCC_CSR's flags (RM0383 §6.3.19), which are then cleared (RMVF).
fn reset_cause(rcc: &pac::RCC) -> ResetCause {
    let csr = rcc.csr().read();
    let flags = ResetFlags {
        power_on: csr.porrstf().bit_is_set(),
        brown_out: csr.borrstf().bit_is_set(),
        // IWDGRSTF is `wdgrstf` in the device crate.
        watchdog: csr.wdgrstf().bit_is_set() || csr.wwdgrstf().bit_is_set(),
        fault: false,
        low_power: csr.lpwrrstf().bit_is_set(),
        software: csr.sftrstf().bit_is_set(),
        // PINRSTF is `padrstf`.
        pin: csr.padrstf().bit_is_set(),
    };
    rcc.csr().modify(|_, w| w.rmvf().set_bit());
    flags.cause()
}

/// Starts the 25 MHz crystal (RCC_CR.HSEON) and waits at most [`HSE_WAIT_MS`] for it to run
/// (HSERDY); switches it off again and returns false if it does not.
fn crystal_runs(rcc: &pac::RCC) -> bool {
    rcc.cr().modify(|_, w| w.hseon().set_bit());
    for _ in 0..HSE_WAIT_MS {
        if rcc.cr().read().hserdy().bit_is_set() {
            return true;
        }
        cortex_m::asm::delay(HSI_CYCLES_PER_MS);
    }
    rcc.cr().modify(|_, w| w.hseon().clear_bit());
    false
}

/// A fault (a bad address, an undefined instruction, an escalated bus or usage fault): logs
/// where, then waits for the independent watchdog, which start-up starts first thing (the start
/// key written here covers a fault before that: its reset values give about 0.5 s). The servo bus is left alone: the fault may have come
/// from the bus code or left its state half-written, so no packet sent from here could be
/// trusted. The servos hold their last goal until the watchdog's reset, after which start-up
/// takes their torque off (a watchdog reset, firmware::board::reset).
#[exception]
unsafe fn HardFault(frame: &ExceptionFrame) -> ! {
    defmt::error!(
        "HardFault: pc {=u32:#010x}, lr {=u32:#010x}, xpsr {=u32:#010x}; the watchdog resets the chip",
        frame.pc(),
        frame.lr(),
        frame.xpsr()
    );
    // SAFETY: a write of the start key to IWDG_KR, which nothing else writes in a way this could
    // break (a running watchdog stays running; the main loop's feeds write another key).
    let iwdg = unsafe { &*pac::IWDG::ptr() };
    iwdg.kr().write(|w| w.key().start());
    loop {
        cortex_m::asm::nop();
    }
}

/// Stops the core (a start-up that stopped, a panic) and waits for the watchdog, which start-up
/// started first thing and which nothing feeds from here: its reset follows within the timeout,
/// and the next start-up takes the servos' torque off (a watchdog reset). A start-up refused the
/// same way every time goes round that loop, logging why each time.
fn halt() -> ! {
    loop {
        cortex_m::asm::wfi();
    }
}

/// The release firmware has no panic site (`armctl footprint` checks); should one come back, the
/// panic says so in the log, and the watchdog then resets the chip ([`halt`]).
#[panic_handler]
fn panic(_: &core::panic::PanicInfo) -> ! {
    defmt::error!("panic");
    halt()
}
