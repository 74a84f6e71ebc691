//! The virtual clock of the simulation: time moves only when the simulated wire or a waiting master
//! moves it, so runs are deterministic and as fast as the host allows.

use std::cell::Cell;
use std::rc::Rc;

use firmware::bus::master::Clock;

/// Nanoseconds since the start of a simulation, shared by every clone (the master's clock and the
/// simulated port see the same time).
#[derive(Clone, Debug, Default)]
pub struct VirtualClock {
    ns: Rc<Cell<u64>>,
}

impl VirtualClock {
    /// A clock at time 0.
    pub fn new() -> Self {
        Self::default()
    }

    /// Nanoseconds since the start.
    pub fn now_ns(&self) -> u64 {
        self.ns.get()
    }

    /// Moves time forward by `ns`.
    pub fn advance_ns(&self, ns: u64) {
        self.ns.set(self.ns.get().saturating_add(ns));
    }

    /// Moves time forward to `t_ns`; never backwards (the clock is monotonic).
    pub fn advance_to(&self, t_ns: u64) {
        if t_ns > self.ns.get() {
            self.ns.set(t_ns);
        }
    }
}

impl Clock for VirtualClock {
    fn now_us(&mut self) -> u64 {
        self.ns.get() / 1000
    }
}
