//! The master's end of an in-memory serial line to a [`SimBus`], on the virtual clock.
//!
//! `write` only buffers; `flush` is the transmission: it charges the buffered bytes' wire time to
//! the clock, hands them to the bus at that time and queues the replies byte by byte with the time
//! each has fully arrived. Reading never blocks in real time: [`ReadReady::read_ready`] moves the
//! clock to the next queued byte's arrival, or by one poll step when nothing is queued, so a
//! master waiting for a silent servo reaches its timeout in virtual time.

use std::cell::RefCell;
use std::collections::VecDeque;
use std::convert::Infallible;
use std::rc::Rc;

use embedded_io::{ErrorType, Read, ReadReady, Write};
use firmware::bus::timing::wire_time_ns;

use super::bus::{SimBus, WireByte};
use super::clock::VirtualClock;

/// A bus shared by its port and the test that inspects its servos.
pub type SharedBus = Rc<RefCell<SimBus>>;

/// Bytes counted by a [`SimPort`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PortStats {
    /// Bytes the master sent.
    pub sent: u64,
    /// Bytes the master read.
    pub received: u64,
}

/// The master side of an in-memory line to a [`SimBus`].
#[derive(Debug)]
pub struct SimPort {
    bus: SharedBus,
    clock: VirtualClock,
    tx: Vec<u8>,
    rx: VecDeque<WireByte>,
    poll_ns: u64,
    stats: PortStats,
}

impl SimPort {
    /// A port to `bus` on `clock`; the poll step is one byte time at the bus's baud.
    pub fn new(bus: SharedBus, clock: VirtualClock) -> Self {
        let poll_ns = wire_time_ns(1, bus.borrow().baud());
        Self { bus, clock, tx: Vec::new(), rx: VecDeque::new(), poll_ns, stats: PortStats::default() }
    }

    /// The clock advance of a `read_ready` that finds nothing queued: the granularity at which a
    /// waiting master sees time pass.
    pub fn poll_ns(&self) -> u64 {
        self.poll_ns
    }

    /// Changes the poll step.
    pub fn set_poll_ns(&mut self, ns: u64) {
        self.poll_ns = ns.max(1);
    }

    /// The bus.
    pub fn bus(&self) -> &SharedBus {
        &self.bus
    }

    /// The clock.
    pub fn clock(&self) -> &VirtualClock {
        &self.clock
    }

    /// Bytes each way so far.
    pub fn stats(&self) -> PortStats {
        self.stats
    }

    /// Reply bytes queued, arrived or not.
    pub fn queued(&self) -> usize {
        self.rx.len()
    }

    fn arrived(&self) -> bool {
        self.rx.front().is_some_and(|&(t, _)| t <= self.clock.now_ns())
    }
}

/// A board's main loop switches the line's baud rate when the host sends an arm on another bus:
/// only the servos set to the new rate hear it, as on a real bus, and a waiting master's poll
/// step becomes a byte time at it.
impl firmware::board::BusPort for SimPort {
    fn set_baud(&mut self, baud: u32) {
        self.bus.borrow_mut().set_baud(baud);
        self.set_poll_ns(wire_time_ns(1, baud));
    }
}

impl ErrorType for SimPort {
    type Error = Infallible;
}

impl Write for SimPort {
    fn write(&mut self, buf: &[u8]) -> Result<usize, Infallible> {
        self.tx.extend_from_slice(buf);
        Ok(buf.len())
    }

    fn flush(&mut self) -> Result<(), Infallible> {
        if self.tx.is_empty() {
            return Ok(());
        }
        let bytes = std::mem::take(&mut self.tx);
        self.clock.advance_ns(wire_time_ns(bytes.len(), self.bus.borrow().baud()));
        self.stats.sent += bytes.len() as u64;
        let mut bus = self.bus.borrow_mut();
        let replies = bus.receive(&bytes, self.clock.now_ns());
        self.rx.extend(replies);
        // A flush is a whole burst: the line is quiet after it until the next one, so a packet
        // left incomplete (bytes lost to a fault, noise) times out in the servos.
        self.rx.extend(bus.line_idle());
        drop(bus);
        // Late replies of an earlier instruction may still be queued: keep arrival order.
        self.rx.make_contiguous().sort_by_key(|&(t, _)| t);
        Ok(())
    }
}

impl ReadReady for SimPort {
    fn read_ready(&mut self) -> Result<bool, Infallible> {
        if self.arrived() {
            return Ok(true);
        }
        match self.rx.front() {
            Some(&(t, _)) => {
                self.clock.advance_to(t);
                Ok(true)
            }
            None => {
                self.clock.advance_ns(self.poll_ns);
                Ok(false)
            }
        }
    }
}

impl Read for SimPort {
    /// The bytes arrived by now; when none has but one is queued, waits (in virtual time) for it;
    /// 0 when nothing is queued at all (the line is idle: there is nothing to wait for).
    fn read(&mut self, buf: &mut [u8]) -> Result<usize, Infallible> {
        if !self.arrived() {
            match self.rx.front() {
                Some(&(t, _)) => self.clock.advance_to(t),
                None => return Ok(0),
            }
        }
        let mut n = 0;
        while n < buf.len() && self.arrived() {
            if let Some((_, b)) = self.rx.pop_front() {
                buf[n] = b;
                n += 1;
            }
        }
        self.stats.received += n as u64;
        Ok(n)
    }
}
