//! The firmware application ([`firmware::app::Firmware`]) with its bus master, behind an
//! object-safe interface so that arms of any joint count run in one harness: on the simulated
//! servo bus and the virtual clock in SIL, on a serial port and the PC's clock in
//! [`crate::runtime::pc`].

use anyhow::{anyhow, bail, Result};
use embedded_io::{Read, ReadReady, Write};
use firmware::app::{Board, Firmware};
use firmware::bus::master::{Clock, Master, NoDirectionPin};
use firmware::controller::{Counters, GripperState, Mode, TickReport};
use firmware::link::session::SessionStats;
use kinematics::nalgebra::SVector;

pub use crate::sim::monitor::JointBounds;
use crate::sim::{SimPort, VirtualClock};

/// Keyframe queue capacity of the simulated firmware (as on the boards).
pub const QUEUE: usize = 32;

/// What to do with a firmware whose joint count is known only at run time ([`for_joints`]).
pub trait WithFirmware {
    /// What it makes of it.
    type Output;
    /// Called with the firmware of `N` joints.
    fn call<const N: usize>(self, firmware: Firmware<N, QUEUE>) -> Self::Output;
}

/// The firmware for an arm of `joints` joints on `board`, started without an arm (the host
/// configures it over the link), handed to `with`. An arm of up to [`firmware::board::JOINTS`]
/// runs on the boards' own build, its joints padded as on a board; the link's larger counts on a
/// build of their own.
pub fn for_joints<W: WithFirmware>(joints: usize, board: Board, with: W) -> Result<W::Output> {
    const BOARD: usize = firmware::board::JOINTS;
    if (1..=BOARD).contains(&joints) {
        let firmware = Firmware::<BOARD, QUEUE>::new(board, None).map_err(|e| anyhow!("firmware core: {e}"))?;
        return Ok(with.call(firmware));
    }
    macro_rules! build {
        ($($n:literal)*) => {
            match joints {
                $($n => {
                    let firmware = Firmware::<$n, QUEUE>::new(board, None).map_err(|e| anyhow!("firmware core: {e}"))?;
                    Ok(with.call(firmware))
                })*
                _ => bail!(
                    "the firmware drives 1 to {} joints; this arm has {joints}",
                    firmware::link::message::MAX_JOINTS
                ),
            }
        };
    }
    build!(7 8)
}

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
    /// The gripper as the firmware sees it (`None` without one).
    fn gripper(&self) -> Option<GripperState>;
    /// Whether the servos' torque is on.
    fn torque(&self) -> bool;
    /// The goal bounds of the arm in use (empty before there is one).
    fn bounds(&self) -> Vec<JointBounds>;
    /// The controller's counters (`None` before there is an arm).
    fn counters(&self) -> Option<Counters>;
    /// The link session's counters.
    fn session(&self) -> SessionStats;
    /// A stop from the board itself ([`Firmware::stop`]).
    fn stop(&mut self, now_us: u64);
    /// Torque off from the board itself ([`Firmware::torque_off`]).
    fn torque_off(&mut self, now_us: u64);
    /// Whether the arm is in motion (moving, playing, tracking or braking).
    fn moving(&self) -> bool;
    /// Whether a command's torque change is still to be written to the servos.
    fn torque_pending(&self) -> bool;
    /// Whether there is an arm whose servos' torque state is known (see
    /// [`firmware::controller::Controller::torque_known`]).
    fn ready(&self) -> bool;
}

/// A firmware of `N` joints with its master on port `P` and clock `C` (by default the simulated
/// bus and the virtual clock).
pub struct SimBoard<const N: usize, P = SimPort, C = VirtualClock> {
    pub(crate) firmware: Firmware<N, QUEUE>,
    pub(crate) master: Master<P, NoDirectionPin, C>,
}

/// The arm's own joints of a build's vector (the padding after them left out).
fn to_vec<const N: usize>(v: &SVector<f32, N>, joints: usize) -> Vec<f64> {
    v.iter().take(joints).map(|x| f64::from(*x)).collect()
}

impl<const N: usize, P, C> SimFirmware for SimBoard<N, P, C>
where
    P: Read + Write + ReadReady,
    C: Clock,
{
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
        self.firmware.controller().map_or_else(Vec::new, |c| to_vec(&c.setpoint().position, c.joints()))
    }

    fn measured(&self) -> Vec<f64> {
        self.firmware.controller().map_or_else(Vec::new, |c| to_vec(c.measured(), c.joints()))
    }

    fn gripper(&self) -> Option<GripperState> {
        self.firmware.controller().and_then(|c| c.gripper())
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

    fn stop(&mut self, now_us: u64) {
        self.firmware.stop(now_us);
    }

    fn torque_off(&mut self, now_us: u64) {
        self.firmware.torque_off(now_us);
    }

    fn moving(&self) -> bool {
        self.firmware.controller().is_some_and(|c| !matches!(c.mode(), Mode::Idle | Mode::Holding | Mode::EStopped))
    }

    fn torque_pending(&self) -> bool {
        self.firmware.controller().is_some_and(|c| c.torque_pending())
    }

    fn ready(&self) -> bool {
        self.firmware.controller().is_some_and(|c| c.torque_known())
    }

    fn bounds(&self) -> Vec<JointBounds> {
        let Some(c) = self.firmware.controller() else { return Vec::new() };
        let limits = c.limits();
        let period_s = f64::from(self.firmware.period_us()) * 1e-6;
        c.mappings()
            .iter()
            .take(c.joints())
            .enumerate()
            .map(|(j, m)| {
                let a = i64::from(m.to_ticks(limits.lower[j]).unwrap_or(m.min_ticks));
                let b = i64::from(m.to_ticks(limits.upper[j]).unwrap_or(m.max_ticks));
                let per_radian = f64::from(m.ticks_per_revolution) / std::f64::consts::TAU;
                let max_step = (f64::from(limits.max_velocity[j]) * period_s * per_radian).ceil() as i64 + 1;
                JointBounds { id: m.id, goal_range: (a.min(b), a.max(b)), max_step }
            })
            // The gripper: between its closed and open ticks, its goal ramped at its speed.
            .chain(c.gripper_config().map(|g| {
                let stroke = f64::from((g.open - g.closed).abs());
                let max_step = (f64::from(g.speed) / 100.0 * stroke * period_s).ceil() as i64 + 1;
                JointBounds {
                    id: g.id,
                    goal_range: (g.closed.min(g.open).into(), g.closed.max(g.open).into()),
                    max_step,
                }
            }))
            .collect()
    }
}
