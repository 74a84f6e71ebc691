//! The time base: SysTick on the core clock, interrupting every millisecond; microseconds are the
//! milliseconds counted plus the part of the current one that has elapsed.

use core::sync::atomic::{AtomicU32, Ordering};

use cortex_m::peripheral::syst::SystClkSource;
use cortex_m::peripheral::SYST;
use cortex_m_rt::exception;

/// The MPS2's core clock (Hz).
pub const SYSCLK_HZ: u32 = 25_000_000;
const TICKS_PER_MS: u32 = SYSCLK_HZ / 1000;

static MILLIS: AtomicU32 = AtomicU32::new(0);

/// Starts SysTick.
pub fn start(mut syst: SYST) {
    syst.set_clock_source(SystClkSource::Core);
    syst.set_reload(TICKS_PER_MS - 1);
    syst.clear_current();
    syst.enable_interrupt();
    syst.enable_counter();
}

#[exception]
fn SysTick() {
    MILLIS.fetch_add(1, Ordering::Relaxed);
}

/// The board's clock for the bus master and the main loop.
#[derive(Clone, Copy, Debug, Default)]
pub struct SysTickClock;

impl SysTickClock {
    /// Microseconds since [`start`] (wraps after 49 days of milliseconds).
    pub fn now(&self) -> u64 {
        loop {
            let ms = MILLIS.load(Ordering::Acquire);
            let elapsed = TICKS_PER_MS - 1 - SYST::get_current();
            // A SysTick interrupt between the two reads changes the count: read again.
            if MILLIS.load(Ordering::Acquire) == ms {
                return u64::from(ms) * 1000 + u64::from(elapsed / (TICKS_PER_MS / 1000));
            }
        }
    }
}

impl firmware::bus::master::Clock for SysTickClock {
    fn now_us(&mut self) -> u64 {
        self.now()
    }
}
