//! USART1's receive interrupt: it moves every byte of the host link into [`LINK_RX`] as it comes,
//! so that none is lost while the main loop is busy with the servo bus or sending a reply. The
//! F411's USART holds one received byte and has no FIFO (RM0383 §19.3.3): at 1 Mbps the next byte
//! overwrites it 10 µs later (an overrun), while a bus cycle takes about 1 ms.
//!
//! The handler is the device crate's `USART1` vector (stm32f4's `rt` feature, on by default, lays
//! out the table; every other device interrupt stays masked and at `DefaultHandler`).

use cortex_m::peripheral::NVIC;
use firmware::board::RxRing;
use stm32f4xx_hal::pac::{self, interrupt, Interrupt};

/// The host link's received bytes: two of the largest frames, more than 3.5 ms of bytes at 1 Mbps.
pub static LINK_RX: RxRing<LINK_RX_BYTES> = RxRing::new();
/// [`LINK_RX`]'s size in bytes.
pub const LINK_RX_BYTES: usize = 512;

/// Lets USART1's interrupt reach the NVIC. Call once USART1 listens for RXNE.
pub fn enable() {
    // SAFETY: `USART1` below only reads USART1's status and data registers and pushes into the
    // lock-free ring; the main loop uses USART1 for transmitting only and the ring's consumer side,
    // so the interrupt cannot break a critical section of the main loop.
    unsafe { NVIC::unmask(Interrupt::USART1) };
}

/// USART1's interrupt: a byte received (RXNE), or an overrun (ORE).
#[interrupt]
fn USART1() {
    // SAFETY: the USART1 register block's address from the device crate; reading SR then DR is
    // the documented sequence that clears RXNE and the error flags (RM0383 §19.6.1), and nothing
    // else reads USART1's receive side.
    let usart = unsafe { &*pac::USART1::ptr() };
    loop {
        let sr = usart.sr().read();
        if sr.rxne().bit_is_clear() && sr.ore().bit_is_clear() {
            break;
        }
        // ORE: a byte came while RXNE was still set, and the shift register's byte (at least one)
        // was lost (RM0383 §19.6.1, USART_SR). Counted for the status; the DR read below clears it.
        if sr.ore().bit_is_set() {
            LINK_RX.overrun();
        }
        let byte = usart.dr().read().dr().bits() as u8;
        // After an overrun DR still holds the byte before the lost one; a byte with a framing,
        // noise or parity error is dropped. Either way the link's frame check sees the gap and the
        // host sends the frame again.
        if sr.fe().bit_is_clear() && sr.nf().bit_is_clear() && sr.pe().bit_is_clear() {
            LINK_RX.push(byte);
        }
    }
}
