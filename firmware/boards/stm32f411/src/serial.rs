//! The host link's transmit side: USART1 through stm32f4xx-hal's `Serial`, as the `embedded-io`
//! writer the firmware core replies on. Received bytes come through USART1's interrupt instead
//! (`link_rx.rs`).
//!
//! The HAL's serial types implement `embedded_io::Write`, but their `write` returns `Ok(0)` when
//! the transmit register is still full, where `embedded-io` asks `write` to block until at least
//! one byte is taken (`write_all` turns `Ok(0)` into a `WriteZero` error). This adapter blocks per
//! byte instead.

use stm32f4xx_hal::nb;
use stm32f4xx_hal::pac::USART1;
use stm32f4xx_hal::serial::{self, Serial};

/// USART1, for writing.
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
