//! The simulated board: the firmware application ([`firmware::app::Firmware`]) with its bus master
//! on the simulated servo bus, behind an object-safe interface so that arms of any joint count run
//! in one harness.

use firmware::app::Firmware;
use firmware::bus::master::{Master, NoDirectionPin};
use firmware::controller::{Counters, TickReport};
use firmware::link::session::SessionStats;
use kinematics::nalgebra::SVector;

pub use crate::sim::monitor::JointBounds;
use crate::sim::{SimPort, VirtualClock};

/// Keyframe queue capacity of the simulated firmware (as on the boards).
pub const QUEUE: usize = 32;

/// The firmware side of the SIL harness, for any joint count.
pub trait SimFirmware {
    /// Bytes from the host at `now_us`; replies go to `tx`.
    fn receive(&mut self, bytes: &[u8], now_us: u64, tx: &mut Vec<u8>);
    /// One control tick at `now_us`; telemetry goes to `tx`.
    fn tick(&mut self, now_us: u64, tx: &mut Vec<u8>) -> Option<TickReport>;
    /// The control period, µs.
    fn period_us(&self) -> u32;
    /// Setpoints sent on the last tick (rad), empty before there is an arm.
    fn setpoints(&self) -> Vec<f64>;
    /// Measured joint values (rad).
    fn measured(&self) -> Vec<f64>;
    /// Whether the servos' torque is on.
    fn torque(&self) -> bool;
    /// The goal bounds of the arm in use (empty before there is one).
    fn bounds(&self) -> Vec<JointBounds>;
    /// The controller's counters (`None` before there is an arm).
    fn counters(&self) -> Option<Counters>;
    /// The link session's counters.
    fn session(&self) -> SessionStats;
}

/// A firmware of `N` joints with its master on the simulated bus.
pub struct SimBoard<const N: usize> {
    pub(super) firmware: Firmware<N, QUEUE>,
    pub(super) master: Master<SimPort, NoDirectionPin, VirtualClock>,
}

fn to_vec<const N: usize>(v: &SVector<f32, N>) -> Vec<f64> {
    v.iter().map(|x| f64::from(*x)).collect()
}

impl<const N: usize> SimFirmware for SimBoard<N> {
    fn receive(&mut self, bytes: &[u8], now_us: u64, tx: &mut Vec<u8>) {
        // Writing to a Vec cannot fail.
        let _ = self.firmware.receive(bytes, now_us, tx);
    }

    fn tick(&mut self, now_us: u64, tx: &mut Vec<u8>) -> Option<TickReport> {
        self.firmware.tick(&mut self.master, now_us, tx).unwrap_or(None)
    }

    fn period_us(&self) -> u32 {
        self.firmware.period_us()
    }

    fn setpoints(&self) -> Vec<f64> {
        self.firmware.controller().map_or_else(Vec::new, |c| to_vec(&c.setpoint().position))
    }

    fn measured(&self) -> Vec<f64> {
        self.firmware.controller().map_or_else(Vec::new, |c| to_vec(c.measured()))
    }

    fn torque(&self) -> bool {
        self.firmware.controller().is_some_and(|c| c.torque())
    }

    fn counters(&self) -> Option<Counters> {
        self.firmware.controller().map(|c| *c.counters())
    }

    fn session(&self) -> SessionStats {
        self.firmware.session().stats()
    }

    fn bounds(&self) -> Vec<JointBounds> {
        let Some(c) = self.firmware.controller() else { return Vec::new() };
        let limits = c.limits();
        let period_s = f64::from(self.firmware.period_us()) * 1e-6;
        c.mappings()
            .iter()
            .enumerate()
            .map(|(j, m)| {
                let a = i64::from(m.to_ticks(limits.lower[j]).unwrap_or(m.min_ticks));
                let b = i64::from(m.to_ticks(limits.upper[j]).unwrap_or(m.max_ticks));
                let per_radian = f64::from(m.ticks_per_revolution) / std::f64::consts::TAU;
                let max_step = (f64::from(limits.max_velocity[j]) * period_s * per_radian).ceil() as i64 + 1;
                JointBounds { id: m.id, goal_range: (a.min(b), a.max(b)), max_step }
            })
            .collect()
    }
}
