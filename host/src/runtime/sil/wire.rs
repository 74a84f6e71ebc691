//! One direction of the simulated host link: bytes take 10 bit times each at the baud rate, one
//! after another, and may be lost or get a bit flipped on the way (seeded, so runs repeat).

use std::collections::VecDeque;

use crate::sim::faults::{FaultState, FaultStats};
use crate::sim::Faults;

/// A serial line in one direction, on the virtual clock.
#[derive(Debug)]
pub struct Wire {
    /// Bytes on their way, with the time (ns) their stop bit arrives.
    in_flight: VecDeque<(u64, u8)>,
    /// When the line has finished sending what it was given.
    free_ns: u64,
    byte_ns: u64,
    faults: FaultState,
}

impl Wire {
    /// A line at `baud` with `faults` (only its drop and bit-flip rates apply).
    pub fn new(baud: u32, faults: Faults) -> Self {
        Self {
            in_flight: VecDeque::new(),
            free_ns: 0,
            byte_ns: 10_000_000_000 / u64::from(baud.max(1)),
            faults: FaultState::new(faults),
        }
    }

    /// Sends `bytes` from `now_ns`, after whatever the line is still sending.
    pub fn send(&mut self, bytes: &[u8], now_ns: u64) {
        let mut t = self.free_ns.max(now_ns);
        for &byte in bytes {
            t += self.byte_ns;
            if let Some(byte) = self.faults.on_byte(byte) {
                self.in_flight.push_back((t, byte));
            }
        }
        self.free_ns = t;
    }

    /// When the next byte arrives, if one is on its way.
    pub fn next_arrival_ns(&self) -> Option<u64> {
        self.in_flight.front().map(|(t, _)| *t)
    }

    /// Moves the bytes that have arrived by `now_ns` into `out` (at most `max`); returns how many.
    pub fn take_arrived(&mut self, now_ns: u64, out: &mut Vec<u8>, max: usize) -> usize {
        let mut n = 0;
        while n < max {
            match self.in_flight.front() {
                Some(&(t, byte)) if t <= now_ns => {
                    out.push(byte);
                    self.in_flight.pop_front();
                    n += 1;
                }
                _ => break,
            }
        }
        n
    }

    /// The fault configuration, to change faults mid-run.
    pub fn faults_mut(&mut self) -> &mut Faults {
        self.faults.config_mut()
    }

    /// What the faults did so far.
    pub fn fault_stats(&self) -> FaultStats {
        self.faults.stats()
    }
}
