//! The main loop every board runs: the host bytes its receive interrupt kept ([`RxRing`]) go to the
//! firmware, and the control tick runs on its fixed schedule. A board supplies only the hardware:
//! the ring its interrupt fills, the link's transmit side, the bus master with its clock, and how
//! to sleep until the next interrupt.
//!
//! [`MainLoop::poll`] is one pass, so the loop runs on the host too (tests); [`MainLoop::run`]
//! repeats it for ever, sleeping in between.
//!
//! # Panics
//! Nothing here panics.

use embedded_hal::digital::OutputPin;
use embedded_io::{Read, ReadReady, Write};

use super::rx_ring::RxRing;
use super::BusPort;
use crate::app::Firmware;
use crate::bus::master::{Clock, Master};

/// Bytes handed to the firmware at a time.
const CHUNK: usize = 64;

/// The firmware, its bus master and its link's received bytes, on one schedule.
pub struct MainLoop<'a, const N: usize, const Q: usize, const R: usize, P, D, C, const BUF: usize> {
    app: &'a mut Firmware<N, Q>,
    master: &'a mut Master<P, D, C, BUF>,
    rx: &'a RxRing<R>,
    /// When the next control tick is due (µs on the master's clock).
    next_tick: u64,
}

impl<'a, const N: usize, const Q: usize, const R: usize, P, D, C, const BUF: usize> MainLoop<'a, N, Q, R, P, D, C, BUF>
where
    P: Read + Write + ReadReady + BusPort,
    D: OutputPin,
    C: Clock,
{
    /// The loop, its first tick due at once.
    pub fn new(app: &'a mut Firmware<N, Q>, master: &'a mut Master<P, D, C, BUF>, rx: &'a RxRing<R>) -> Self {
        let next_tick = master.clock().now_us();
        Self { app, master, rx, next_tick }
    }

    /// One pass: every byte waiting goes to the firmware (replies to `tx`), then the tick if it is
    /// due. Returns when the next tick is due (µs), for the board to sleep until then.
    pub fn poll<W: Write>(&mut self, tx: &mut W) -> u64 {
        let mut chunk = [0u8; CHUNK];
        loop {
            let n = self.rx.pop_into(&mut chunk);
            if n == 0 {
                break;
            }
            let now = self.master.clock().now_us();
            // A write error is the link's (a full or broken transmit line): the host retransmits.
            let _ = self.app.receive(chunk.get(..n).unwrap_or_default(), now, tx);
            self.follow_bus();
        }
        let now = self.master.clock().now_us();
        if now >= self.next_tick {
            let _ = self.app.tick(self.master, now, tx);
            // The next slot on the fixed schedule; missed slots are skipped, not made up.
            let period = u64::from(self.app.period_us());
            self.next_tick = (self.next_tick + period).max(self.master.clock().now_us());
        }
        self.next_tick
    }

    /// Puts the servo bus where the firmware's arm has it: after an arm on another bus was
    /// committed, the port's baud rate and the master's protocol and timing.
    fn follow_bus(&mut self) {
        let wanted = *self.app.bus();
        if wanted != *self.master.config() {
            if wanted.baud != self.master.config().baud {
                self.master.port_mut().set_baud(wanted.baud);
            }
            self.master.set_config(wanted);
        }
    }

    /// Polls for ever. Between passes `idle(next_tick, rx)` may sleep until an interrupt: it must
    /// not sleep while `rx` holds a byte or past `next_tick` (a board checks both with interrupts
    /// masked, then waits, so that a byte arriving in between still wakes it).
    pub fn run<W: Write>(mut self, tx: &mut W, mut idle: impl FnMut(u64, &RxRing<R>)) -> ! {
        loop {
            let next = self.poll(tx);
            idle(next, self.rx);
        }
    }
}
