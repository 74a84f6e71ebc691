//! The time base: TIM2, a 32-bit timer, counts microseconds (its prescaler divides the timer clock
//! down to 1 MHz) and wraps every 71.6 minutes; [`Tim2Clock::now`] extends the count to 64 bits by
//! noticing each wrap. It needs no interrupt, only a call at least once per wrap period, which the
//! main loop makes thousands of times a second.

use core::cell::Cell;

use cortex_m::interrupt::{self, Mutex};
use stm32f4xx_hal::pac::TIM2;
use stm32f4xx_hal::rcc::{BusTimerClock, Enable, Rcc, Reset};

/// The last count read and the wraps seen so far. One state for the one TIM2, shared by every copy
/// of the clock (the main loop's and the bus master's), so that all of them agree.
static EXTENSION: Mutex<Cell<(u32, u32)>> = Mutex::new(Cell::new((0, 0)));

/// The board's clock for the bus master and the main loop.
#[derive(Clone, Copy)]
pub struct Tim2Clock {
    tim: &'static TIM2,
}

impl Tim2Clock {
    /// Starts TIM2 counting microseconds from 0. Returns `None` if called twice (TIM2 has one
    /// owner) or if the timer clock is not a whole number of MHz (the prescaler could not make
    /// exact microseconds; the clock setup in main gives 84 MHz).
    pub fn start(tim: TIM2, rcc: &mut Rcc) -> Option<Self> {
        let timer_hz = TIM2::timer_clock(&rcc.clocks).raw();
        let prescaler = u16::try_from(timer_hz / 1_000_000).ok()?.checked_sub(1)?;
        if timer_hz % 1_000_000 != 0 {
            return None;
        }
        TIM2::enable(rcc);
        TIM2::reset(rcc);
        // The count is the whole 32 bits; PSC takes effect at the next update event, so make one.
        tim.psc().write(|w| w.psc().set(prescaler));
        tim.arr().write(|w| w.arr().set(u32::MAX));
        tim.egr().write(|w| w.ug().set_bit());
        tim.cr1().write(|w| w.cen().set_bit());
        let tim: &'static mut TIM2 = cortex_m::singleton!(: TIM2 = tim)?;
        Some(Self { tim })
    }

    /// Microseconds since [`Tim2Clock::start`].
    pub fn now(&self) -> u64 {
        // A critical section makes read-count-then-update-state one step, should an interrupt
        // handler ever read the clock too.
        interrupt::free(|cs| {
            let count = self.tim.cnt().read().bits();
            let state = EXTENSION.borrow(cs);
            let (last, wraps) = state.get();
            let wraps = if count < last { wraps.wrapping_add(1) } else { wraps };
            state.set((count, wraps));
            (u64::from(wraps) << 32) | u64::from(count)
        })
    }
}

impl firmware::bus::master::Clock for Tim2Clock {
    fn now_us(&mut self) -> u64 {
        self.now()
    }
}
