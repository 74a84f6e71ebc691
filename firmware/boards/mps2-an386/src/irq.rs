//! The UART receive interrupts: they exist only to wake the core from `wfi` when a host byte comes,
//! so the main loop sleeps between ticks instead of spinning. That matters under QEMU with
//! `-icount`: a spinning core executes a billion instructions per virtual second and runs about 13
//! times slower than real time, while a sleeping one lets virtual time follow the wall clock.

use cortex_m::interrupt::InterruptNumber;
use cortex_m::peripheral::NVIC;
use cortex_m_rt::exception;

use crate::uart::{Uart, UART0};

/// The MPS2 AN386's interrupt lines used here (CMSDK UART n: RX on 2n, TX on 2n + 1).
#[derive(Clone, Copy, Debug)]
#[repr(u16)]
pub enum Irq {
    /// UART0 (the host link) received a byte.
    Uart0Rx = 0,
}

// SAFETY: the numbers are the AN386's external interrupt lines (Application Note AN386, table of
// interrupts), all below the 32 lines the board has.
unsafe impl InterruptNumber for Irq {
    fn number(self) -> u16 {
        self as u16
    }
}

/// Lets the host link's receive interrupt reach the NVIC (and so wake `wfi`).
pub fn enable_link_wakeup(link: &mut Uart) {
    link.enable_rx_interrupt();
    // SAFETY: the handler (`DefaultHandler` below) only clears the UART's interrupt flag, so taking
    // the interrupt cannot break a critical section of the main loop.
    unsafe { NVIC::unmask(Irq::Uart0Rx) };
}

/// Every external interrupt lands here (the board has no device crate with a vector table); only
/// the link's receive interrupt is enabled.
#[exception]
unsafe fn DefaultHandler(irqn: i16) {
    if irqn == Irq::Uart0Rx as i16 {
        Uart::clear_rx_interrupt(UART0);
    }
}
