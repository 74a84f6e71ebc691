//! The CMSDK APB UART of the MPS2 boards (Arm's "Cortex-M System Design Kit" UART), as an
//! `embedded-io` serial port. Registers: DATA (0x00), STATE (0x04: bit 0 TX buffer full, bit 1 RX
//! buffer full, bit 3 RX overrun, write 1 to clear), CTRL (0x08: bit 0 TX enable, bit 1 RX enable, bit 3 RX interrupt enable),
//! INTSTATUS/INTCLEAR (0x0C: bit 1 RX), BAUDDIV (0x10).

use core::ptr::{read_volatile, write_volatile};
use core::sync::atomic::{AtomicU32, Ordering};

use firmware::board::BusPort;

const DATA: usize = 0x00;
const STATE: usize = 0x04;
const CTRL: usize = 0x08;
const INTCLEAR: usize = 0x0C;
const BAUDDIV: usize = 0x10;
const TX_FULL: u32 = 1 << 0;
const RX_FULL: u32 = 1 << 1;
const RX_OVERRUN: u32 = 1 << 3;
const ENABLE_TX_RX: u32 = 0b11;
const RX_INTERRUPT: u32 = 1 << 3;

/// UART0: the host link.
pub const UART0: usize = 0x4000_4000;
/// UART1: the servo bus.
pub const UART1: usize = 0x4000_5000;

/// Bytes written to either UART so far (wrapping): the main loop's measurement
/// ([`crate::loop_pass`]) takes the servo bus's share of a pass from it, which QEMU sends at once
/// and a board's UART in wire time. Only the main loop writes to the UARTs.
pub static SENT: AtomicU32 = AtomicU32::new(0);

/// One UART, owned by whoever holds this value (the board's main creates each once).
pub struct Uart {
    base: usize,
    /// Its peripheral clock, for the baud divider.
    clock_hz: u32,
}

impl Uart {
    /// Enables the UART at `base` at `baud` for a `sysclk_hz` peripheral clock.
    pub fn new(base: usize, sysclk_hz: u32, baud: u32) -> Self {
        let mut uart = Self { base, clock_hz: sysclk_hz };
        uart.set_baud(baud);
        uart.write_reg(CTRL, ENABLE_TX_RX);
        uart
    }

    /// The fastest baud rate the divider reaches (CMSDK: BAUDDIV at least 16).
    pub const fn max_baud(sysclk_hz: u32) -> u32 {
        sysclk_hz / 16
    }

    /// Raises the UART's receive interrupt when a byte comes, so that a core sleeping in `wfi`
    /// wakes for it (the interrupt itself only needs [`clear_rx_interrupt`](Self::clear_rx_interrupt)).
    pub fn enable_rx_interrupt(&mut self) {
        self.write_reg(CTRL, ENABLE_TX_RX | RX_INTERRUPT);
    }

    /// Acknowledges the receive interrupt (the byte stays in DATA until read).
    pub fn clear_rx_interrupt(base: usize) {
        Self { base, clock_hz: 0 }.write_reg(INTCLEAR, RX_FULL);
    }

    /// Hands every byte the UART at `base` holds to `keep`, and each receive overrun it reports to
    /// `overrun` (from its receive interrupt).
    ///
    /// An overrun (STATE bit 3) is a byte that came while DATA still held one, so one of the two
    /// is lost. It happens only while the receive interrupt is pending or this handler runs (the
    /// byte in DATA raised it, and the lost byte raises it again), so the loop sees every one,
    /// and clears it (write 1). QEMU's model never overruns: it holds a byte back until DATA has
    /// been read.
    pub fn drain_rx(base: usize, mut keep: impl FnMut(u8), mut overrun: impl FnMut()) {
        let uart = Self { base, clock_hz: 0 };
        loop {
            let state = uart.read_reg(STATE);
            if state & RX_OVERRUN != 0 {
                uart.write_reg(STATE, RX_OVERRUN);
                overrun();
            }
            if state & RX_FULL == 0 {
                break;
            }
            keep(uart.read_reg(DATA) as u8);
        }
    }

    fn read_reg(&self, offset: usize) -> u32 {
        // SAFETY: `base` is one of the UART blocks of the MPS2 memory map (UART0/UART1 above), so
        // `base + offset` is a valid, aligned device register for volatile access.
        unsafe { read_volatile((self.base + offset) as *const u32) }
    }

    fn write_reg(&self, offset: usize, value: u32) {
        // SAFETY: as in `read_reg`; the registers written (DATA, STATE, CTRL, INTCLEAR, BAUDDIV) have no
        // effect beyond this UART.
        unsafe { write_volatile((self.base + offset) as *mut u32, value) }
    }

    fn rx_ready(&self) -> bool {
        self.read_reg(STATE) & RX_FULL != 0
    }
}

/// The servo bus's baud rate follows the arm the host sends. (QEMU does not time the line; it
/// passes the rate on to the pty, which the simulated servos may follow.)
impl BusPort for Uart {
    fn set_baud(&mut self, baud: u32) {
        // The divider must be at least 16 (CMSDK).
        self.write_reg(BAUDDIV, (self.clock_hz / baud.max(1)).max(16));
    }
}

impl embedded_io::ErrorType for Uart {
    type Error = core::convert::Infallible;
}

impl embedded_io::ReadReady for Uart {
    fn read_ready(&mut self) -> Result<bool, Self::Error> {
        Ok(self.rx_ready())
    }
}

impl embedded_io::Read for Uart {
    /// Blocks until a byte has come, then returns what is there (the UART holds one byte).
    fn read(&mut self, buf: &mut [u8]) -> Result<usize, Self::Error> {
        if buf.is_empty() {
            return Ok(0);
        }
        while !self.rx_ready() {}
        let mut n = 0;
        while n < buf.len() && self.rx_ready() {
            buf[n] = self.read_reg(DATA) as u8;
            n += 1;
        }
        Ok(n)
    }
}

impl embedded_io::Write for Uart {
    fn write(&mut self, buf: &[u8]) -> Result<usize, Self::Error> {
        SENT.store(SENT.load(Ordering::Relaxed).wrapping_add(buf.len() as u32), Ordering::Relaxed);
        for &byte in buf {
            while self.read_reg(STATE) & TX_FULL != 0 {}
            self.write_reg(DATA, u32::from(byte));
        }
        Ok(buf.len())
    }

    fn flush(&mut self) -> Result<(), Self::Error> {
        while self.read_reg(STATE) & TX_FULL != 0 {}
        Ok(())
    }
}
