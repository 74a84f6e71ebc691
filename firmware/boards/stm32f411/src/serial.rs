//! The host link: USART1 through stm32f4xx-hal's `Serial`, as the `embedded-io` port the firmware
//! core reads and writes.
//!
//! The HAL's serial types implement `embedded_io::Write` but neither `Read` nor `ReadReady`, and
//! their `write` returns `Ok(0)` when the transmit register is still full, where `embedded-io` asks
//! `write` to block until at least one byte is taken (`write_all` turns `Ok(0)` into a `WriteZero`
//! error). This adapter blocks per byte instead, and adds the reads.

use embedded_hal_nb::serial::Read as _;
use stm32f4xx_hal::nb;
use stm32f4xx_hal::pac::USART1;
use stm32f4xx_hal::serial::{self, RxISR, Serial};

/// USART1 as a non-blocking byte stream.
pub struct Link {
    serial: Serial<USART1>,
}

impl Link {
    /// Wraps a configured USART1.
    pub fn new(serial: Serial<USART1>) -> Self {
        Self { serial }
    }
}

impl embedded_io::ErrorType for Link {
    type Error = serial::Error;
}

impl embedded_io::ReadReady for Link {
    /// A received byte is waiting (a byte with a line error counts too: reading it clears the
    /// error).
    fn read_ready(&mut self) -> Result<bool, Self::Error> {
        Ok(self.serial.is_rx_not_empty())
    }
}

impl embedded_io::Read for Link {
    /// Blocks until a byte has come, then returns what is there (USART1 holds one byte). A byte
    /// received with a line error (overrun, framing, noise, parity) is dropped and the error
    /// returned if nothing came before it; the link's frame check catches the gap.
    fn read(&mut self, buf: &mut [u8]) -> Result<usize, Self::Error> {
        if buf.is_empty() {
            return Ok(0);
        }
        buf[0] = nb::block!(self.serial.read())?;
        let mut n = 1;
        while n < buf.len() {
            match self.serial.read() {
                Ok(byte) => buf[n] = byte,
                Err(_) => break,
            }
            n += 1;
        }
        Ok(n)
    }
}

impl embedded_io::Write for Link {
    fn write(&mut self, buf: &[u8]) -> Result<usize, Self::Error> {
        for &byte in buf {
            nb::block!(embedded_hal_nb::serial::Write::write(&mut self.serial, byte))?;
        }
        Ok(buf.len())
    }

    /// Returns once the last byte has left the shift register (the HAL waits for TC).
    fn flush(&mut self) -> Result<(), Self::Error> {
        embedded_io::Write::flush(&mut self.serial)
    }
}
