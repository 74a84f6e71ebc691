//! The host link's receive interrupt: it moves every byte UART0 receives into [`LINK_RX`] at once,
//! so that none is lost while the main loop is busy with the servo bus (the UART holds one byte),
//! and it wakes the core from `wfi`, so the main loop sleeps between ticks instead of spinning.
//! Sleeping matters under QEMU with `-icount`: a spinning core executes a billion instructions per
//! virtual second and runs about 13 times slower than real time, while a sleeping one lets virtual
//! time follow the wall clock.

use cortex_m::interrupt::InterruptNumber;
use cortex_m::peripheral::NVIC;
use cortex_m_rt::exception;
use firmware::board::RxRing;

use crate::uart::{Uart, UART0};

/// The host link's received bytes, filled by the receive interrupt and drained by the main loop:
/// two of the largest frames, more than 3.5 ms of bytes at 1 Mbps (a servo-bus cycle with a servo
/// missing).
pub static LINK_RX: RxRing<LINK_RX_BYTES> = RxRing::new();
/// [`LINK_RX`]'s size in bytes.
pub const LINK_RX_BYTES: usize = 512;

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

/// Lets the host link's receive interrupt reach the NVIC: from now on its bytes arrive in
/// [`LINK_RX`], and each wakes `wfi`.
pub fn enable_link_receive(link: &mut Uart) {
    link.enable_rx_interrupt();
    // SAFETY: the handler (`DefaultHandler` below) only reads UART0's received bytes into the
    // lock-free ring and clears the UART's interrupt and overrun flags; the main loop touches neither the
    // receive side of UART0 nor the ring's producer side, so taking the interrupt cannot break a
    // critical section of the main loop.
    unsafe { NVIC::unmask(Irq::Uart0Rx) };
}

/// Every external interrupt lands here (the board has no device crate with a vector table); only
/// the link's receive interrupt is enabled.
#[exception]
unsafe fn DefaultHandler(irqn: i16) {
    if irqn == Irq::Uart0Rx as i16 {
        Uart::clear_rx_interrupt(UART0);
        Uart::drain_rx(
            UART0,
            |byte| {
                LINK_RX.push(byte);
            },
            || LINK_RX.overrun(),
        );
    }
}
