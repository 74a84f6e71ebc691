//! The servo bus: USART2 in single-wire half-duplex mode (RM0383 §19.3.10, CR3.HDSEL), on PA2.
//!
//! With HDSEL set the USART ignores its RX pin and joins RX to TX inside the chip; TX drives the pin
//! only while a frame is going out, so PA2 is an open-drain alternate-function pin with a pull-up
//! and the servos share that one wire. stm32f4xx-hal has no half-duplex mode (its `Serial` resets
//! CR3 and wants a push-pull TX pin and an RX pin), so this file drives the USART2 registers through
//! the PAC, which the HAL owns nothing of once `USART2` is handed here.
//!
//! Because RX is joined to TX, the receiver hears every byte this side sends. The master could skip
//! those echoes (`BusConfig::echo`), but USART2 holds one received byte: while `write` busy-waits on
//! the transmitter nobody reads, the echoes overrun each other and only some of them arrive, so a
//! count of bytes to skip would eat the servo's reply. Instead the receiver is switched off (CR1.RE)
//! for the transmission and back on by `flush` once the last stop bit is out (TC), the way ST's
//! `HAL_HalfDuplex_EnableTransmitter`/`EnableReceiver` do: no echo reaches the master, so the board
//! sets `echo: false`. The transmitter (TE) stays on throughout: turning it on again would send an
//! idle frame first.

use embedded_io::ReadReady;
use stm32f4xx_hal::pac::USART2;
use stm32f4xx_hal::rcc::{BusClock, Enable, Rcc, Reset};

/// USART2, one wire, 8N1.
pub struct HalfDuplex {
    usart: USART2,
    /// APB1's clock, for the baud divider.
    pclk: u32,
}

/// USARTDIV in sixteenths for `baud` from `pclk` (RM0383 §19.3.4, OVER8 = 0: BRR holds it as 12.4
/// fixed point), rounded; `None` when out of BRR's reach (below 1 or above 4095.9375).
fn divider(pclk: u32, baud: u32) -> Option<u32> {
    let div = (pclk + baud / 2).checked_div(baud)?;
    (16..=0xFFFF).contains(&div).then_some(div)
}

impl HalfDuplex {
    /// Sets USART2 up at `baud` (8 data bits, no parity, 1 stop bit, 16x oversampling) in
    /// single-wire mode, receiving. PA2 must already be AF7 open-drain with a pull-up. Returns
    /// `None` when `baud` is out of reach of the APB1 clock (USARTDIV below 1 or above 4095).
    pub fn new(usart: USART2, baud: u32, rcc: &mut Rcc) -> Option<Self> {
        let pclk = USART2::clock(&rcc.clocks).raw();
        let div = divider(pclk, baud)?;
        USART2::enable(rcc);
        USART2::reset(rcc);
        usart.brr().write(|w| w.div_mantissa().set((div >> 4) as u16).div_fraction().set((div & 0xF) as u8));
        // Half-duplex requires LINEN and CLKEN (CR2), SCEN and IREN (CR3) clear: the reset values.
        usart.cr3().write(|w| w.hdsel().set_bit());
        usart.cr1().write(|w| w.ue().set_bit().te().set_bit().re().set_bit());
        Some(Self { usart, pclk })
    }

    /// The fastest baud rate BRR reaches from APB1's clock (USARTDIV 1: 2.625 Mbps at 42 MHz).
    pub fn max_baud(&self) -> u32 {
        self.pclk / 16
    }

    fn receiver(&self, on: bool) {
        self.usart.cr1().modify(|_, w| w.re().bit(on));
    }
}

/// The servo bus's baud rate follows the arm the host sends (the firmware refuses one above
/// [`HalfDuplex::max_baud`]). Changed between bus cycles, with the line idle: the master has
/// flushed, so no frame is cut.
impl firmware::board::BusPort for HalfDuplex {
    fn set_baud(&mut self, baud: u32) {
        if let Some(div) = divider(self.pclk, baud) {
            // RM0383 (fractional baud rate generation): the counters take a new BRR at once, so it
            // must not change during a transfer; between bus cycles the line is idle.
            self.usart.brr().write(|w| w.div_mantissa().set((div >> 4) as u16).div_fraction().set((div & 0xF) as u8));
        }
    }
}

impl embedded_io::ErrorType for HalfDuplex {
    type Error = core::convert::Infallible;
}

impl embedded_io::ReadReady for HalfDuplex {
    fn read_ready(&mut self) -> Result<bool, Self::Error> {
        // A caller that wrote without flushing still gets its receiver back once the line is free.
        if self.usart.cr1().read().re().bit_is_clear() && self.usart.sr().read().tc().bit_is_set() {
            self.receiver(true);
        }
        Ok(self.usart.sr().read().rxne().bit_is_set())
    }
}

impl embedded_io::Read for HalfDuplex {
    /// Blocks until a byte has come, then returns what is there (USART2 holds one byte). Bytes with
    /// a line error (framing, noise, an overrun before them) are passed on as they are: reading SR
    /// then DR clears the flags, and the packet checksum and length tell the master whether the
    /// reply is whole; it retries when it is not.
    fn read(&mut self, buf: &mut [u8]) -> Result<usize, Self::Error> {
        if buf.is_empty() {
            return Ok(0);
        }
        while !self.read_ready()? {}
        let mut n = 0;
        while n < buf.len() && self.usart.sr().read().rxne().bit_is_set() {
            buf[n] = self.usart.dr().read().dr().bits() as u8;
            n += 1;
        }
        Ok(n)
    }
}

impl embedded_io::Write for HalfDuplex {
    /// Switches the receiver off (see the module doc) and sends `buf`; [`Self::flush`] switches it
    /// back on.
    fn write(&mut self, buf: &[u8]) -> Result<usize, Self::Error> {
        if !buf.is_empty() {
            self.receiver(false);
        }
        for &byte in buf {
            while self.usart.sr().read().txe().bit_is_clear() {}
            self.usart.dr().write(|w| w.dr().set(u16::from(byte)));
        }
        Ok(buf.len())
    }

    /// Returns once the last byte's stop bit has left the pin (TC, not just TXE: the master drops
    /// the direction pin right after, which would otherwise cut the last byte short on a buffer
    /// adapter), then listens again.
    fn flush(&mut self) -> Result<(), Self::Error> {
        while self.usart.sr().read().tc().bit_is_clear() {}
        self.receiver(true);
        Ok(())
    }
}
