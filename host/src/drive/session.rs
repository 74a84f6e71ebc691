//! [`Driver`]: a connection to the firmware with what every arm-driving command needs: status
//! polling until the arm is at rest, torque on before a move, forward kinematics of the measured
//! joints on the host, and stopping the arm after Ctrl-C.

use std::io::Write;
use std::time::Instant;

use anyhow::{anyhow, bail, Result};
use firmware::link::message::{FirmwareMessage, HostMessage, Joints, RunState, Status, MAX_JOINTS};
use kinematics::JointKind;

use super::connection::{self, Connection, Target};
use super::interrupt;
use crate::arm::dof::{self, DynArm};
use crate::arm::ArmSpec;
use crate::link::client::LinkError;

/// Longest wait for the arm to come to rest after a stop (controller seconds).
const STOP_TIMEOUT: f64 = 30.0;
/// A joint this close to its setpoint (rad or m) has arrived.
pub const SETTLED: f32 = 1e-3;
/// A joint that moved less than this between two polls (rad or m) stands still.
const STILL: f32 = 1e-4;
/// Longest wait for the servos to catch up with a resting setpoint (controller seconds).
const SETTLE_TIMEOUT: f32 = 2.0;

/// How a wait ended.
pub enum Waited {
    /// At rest (holding), with this status.
    Done(Status),
    /// Ctrl-C was pressed; nothing was sent about it yet.
    Interrupted,
}

/// A connected firmware and the arm it runs.
pub struct Driver {
    conn: Connection,
    fk: Box<dyn DynArm>,
}

impl Driver {
    /// Connects (handshake, arm configuration when asked); what connecting to `--bus` measured is
    /// said on `err`.
    pub fn open(target: Target, arm: Option<&str>, err: &mut dyn Write) -> Result<Self> {
        Self::on(connection::open(target, arm, err)?)
    }

    /// A driver over a connection already open.
    pub fn on(conn: Connection) -> Result<Self> {
        let fk = dof::build(conn.arm.clone())?;
        Ok(Self { conn, fk })
    }

    /// Ends the connection, saying on `err` what the place that ran the core did (for `--bus`, the
    /// control loop's counts).
    pub fn close(self, err: &mut dyn Write) -> Result<()> {
        self.conn.close(err)
    }

    /// The host's kinematics of the arm the firmware runs (forward kinematics, IK).
    pub fn model(&self) -> &dyn DynArm {
        self.fk.as_ref()
    }

    /// The arm the firmware runs.
    pub fn arm(&self) -> &ArmSpec {
        &self.conn.arm
    }

    /// The arm's gripper, if it has one.
    pub fn gripper(&self) -> Option<crate::arm::servos::GripperSpec> {
        crate::arm::servos::servos_of(&self.conn.arm).and_then(|s| s.gripper)
    }

    /// Joints of the firmware's arm.
    pub fn joints(&self) -> usize {
        usize::from(self.conn.info.joints)
    }

    /// Keyframe queue capacity of the firmware.
    pub fn queue_capacity(&self) -> usize {
        usize::from(self.conn.info.queue_capacity)
    }

    /// Sends one request (no flow control).
    pub fn request(&mut self, message: &HostMessage) -> Result<FirmwareMessage, LinkError> {
        self.conn.client.request(message)
    }

    /// Pushes a keyframe, waiting for a free slot (the client's flow control).
    pub fn push(&mut self, message: &HostMessage) -> Result<FirmwareMessage, LinkError> {
        self.conn.client.push(message)
    }

    /// Free keyframe slots by the firmware's last report.
    pub fn free_slots(&self) -> u16 {
        self.conn.client.free_slots()
    }

    /// Waits one read timeout of the link (the pause between status polls: in the simulation's
    /// virtual time for --sim, so a simulated move takes no wall-clock time waiting).
    pub fn pause(&mut self) -> Result<()> {
        Ok(self.conn.client.wait_once()?)
    }

    /// The controller's status.
    pub fn status(&mut self) -> Result<Status> {
        Ok(self.conn.client.status()?)
    }

    /// The tool pose for joint values, by the host's forward kinematics of the arm.
    pub fn tool_pose(&self, q: &[f32]) -> Result<kinematics::Pose<f64>> {
        let q: Vec<f64> = q.iter().map(|&x| f64::from(x)).collect();
        self.fk.tool_pose(&q)
    }

    /// The tool position (m) for joint values.
    pub fn tool_position(&self, q: &[f32]) -> Result<[f64; 3]> {
        Ok(self.tool_pose(q)?.translation.into())
    }

    /// Switches torque on if it is off; refuses to leave an emergency stop on its own. Returns
    /// the status after that and whether torque was switched on (to be said once the motion is
    /// accepted, or undone with [`Driver::undo_torque`] if it is refused).
    pub fn ready_to_move(&mut self) -> Result<(Status, bool)> {
        let status = self.status()?;
        match status.state {
            RunState::TorqueOff => {
                self.torque_on()
                    .map_err(|e| anyhow::anyhow!("torque is off, and switching it on failed: {e}; nothing moved"))?;
                Ok((self.status()?, true))
            }
            RunState::EStopped => bail!(
                "the arm is emergency-stopped: check it, then `torque on` leaves the emergency stop; nothing was sent"
            ),
            _ => Ok((status, false)),
        }
    }

    /// Switches torque on. Right after the board starts or gets a new arm, the firmware has not
    /// read every servo yet and refuses (`NotReady`) for a tick or two: that is retried for up to
    /// 25 read timeouts (0.5 s) before it counts as a failure.
    pub fn torque_on(&mut self) -> Result<FirmwareMessage, LinkError> {
        crate::link::ready::request_when_ready(&mut self.conn.client, &HostMessage::Torque { on: true }, 25)
    }

    /// Switches torque off again if [`Driver::ready_to_move`] switched it on, so that a refused
    /// motion leaves the arm as it was; returns words for the error message.
    pub fn undo_torque(&mut self, switched_on: bool) -> &'static str {
        match switched_on {
            false => "",
            true if self.request(&HostMessage::Torque { on: false }).is_ok() => " (torque is off again, as it was)",
            true => " (torque was switched on and could not be switched off again)",
        }
    }

    /// Says that torque was switched on, once the motion is accepted.
    pub fn note_torque(switched_on: bool, err: &mut dyn Write) -> Result<()> {
        if switched_on {
            writeln!(err, "torque was off: switched it on")?;
        }
        Ok(())
    }

    /// Polls status until the arm is at rest and holding.
    /// Gives up after `timeout` seconds of controller time (stopping the arm first); fails if the
    /// arm ends up limp or emergency-stopped.
    pub fn wait_until_rest(&mut self, timeout: f64) -> Result<Waited> {
        let started = Instant::now();
        let mut first: Option<f32> = None;
        loop {
            if interrupt::requested() {
                return Ok(Waited::Interrupted);
            }
            let status = self.status()?;
            match status.state {
                RunState::Idle => return Ok(Waited::Done(self.settle(status)?)),
                RunState::TorqueOff => bail!("the arm went limp (torque off) before reaching the target"),
                RunState::EStopped => bail!("the arm was emergency-stopped before reaching the target"),
                _ => {}
            }
            let t0 = *first.get_or_insert(status.time);
            let waited = f64::from(status.time - t0);
            // The wall clock is a backstop for a controller whose clock stands still.
            if waited > timeout || started.elapsed().as_secs_f64() > 4.0 * timeout + 10.0 {
                let stopped = self.request(&HostMessage::Stop).is_ok();
                bail!(
                    "timed out after {waited:.1} s with the arm still {:?}; {}",
                    status.state,
                    if stopped { "sent stop" } else { "stop was not acknowledged" }
                );
            }
            self.pause()?;
        }
    }

    /// Once the setpoint rests: waits until the servos have caught up with it (every measured
    /// joint within [`SETTLED`] of its setpoint) or stand still (a servo held back by a load), at
    /// most [`SETTLE_TIMEOUT`]. Returns the last status.
    pub fn settle(&mut self, mut status: Status) -> Result<Status> {
        let t0 = status.time;
        loop {
            let lag = status.measured.iter().zip(&status.setpoints).map(|(m, s)| (m - s).abs()).fold(0.0, f32::max);
            if lag <= SETTLED || status.state != RunState::Idle || status.time - t0 > SETTLE_TIMEOUT {
                return Ok(status);
            }
            self.pause()?;
            let next = self.status()?;
            let moved = next.measured.iter().zip(&status.measured).map(|(a, b)| (a - b).abs()).fold(0.0, f32::max);
            let still = moved <= STILL;
            status = next;
            if still {
                return Ok(status);
            }
        }
    }

    /// Sends stop and waits until the arm no longer moves (holding, limp or emergency-stopped).
    pub fn stop(&mut self) -> Result<Status> {
        self.request(&HostMessage::Stop)?;
        let mut first = None;
        let started = Instant::now();
        loop {
            let status = self.status()?;
            let t0 = *first.get_or_insert(status.time);
            if !matches!(status.state, RunState::Moving | RunState::Stopping | RunState::Paused) {
                return self.settle(status);
            }
            if f64::from(status.time - t0) > STOP_TIMEOUT || started.elapsed().as_secs_f64() > 4.0 * STOP_TIMEOUT {
                bail!("sent stop, but the arm was still {:?} after {STOP_TIMEOUT} s", status.state);
            }
            self.pause()?;
        }
    }

    /// After Ctrl-C: stops the arm, waits until it is at rest, and says where it stopped.
    /// Returns the exit code.
    pub fn stop_after_interrupt(&mut self, err: &mut dyn Write) -> Result<i32> {
        let status = self.stop().map_err(|e| anyhow::anyhow!("Ctrl-C: {e:#}"))?;
        let at = self.tool_position(&status.measured)?;
        writeln!(
            err,
            "stopped by Ctrl-C at {} m (joints {}), state {:?}",
            fmt3(&at),
            fmt_list(&status.measured),
            status.state
        )?;
        Ok(interrupt::EXIT_CODE)
    }
}

/// `x, y, z` with 4 decimals (0.1 mm).
pub fn fmt3(p: &[f64; 3]) -> String {
    format!("{:.4}, {:.4}, {:.4}", p[0], p[1], p[2])
}

/// Joint values with 4 decimals.
pub fn fmt_list(q: &[f32]) -> String {
    q.iter().map(|x| format!("{x:.4}")).collect::<Vec<_>>().join(", ")
}

/// Checks joint values against the arm: the count, and each value within its joint's limits.
/// `what` starts each error (e.g. `--q` or `file.csv: line 3`).
pub fn check_joints(driver: &Driver, q: &[f64], what: &str) -> Result<Joints> {
    let arm = driver.arm();
    if q.len() != driver.joints() {
        bail!("{what}: {} joint values, but the arm {} has {} joints", q.len(), arm.name, driver.joints());
    }
    for (j, (value, joint)) in q.iter().zip(&arm.joints).enumerate() {
        if joint.kind != JointKind::Continuous && !(joint.lower..=joint.upper).contains(value) {
            bail!(
                "{what}: joint {} ({}) value {value} is outside its limits {}..={}",
                j + 1,
                joint.name,
                joint.lower,
                joint.upper
            );
        }
    }
    // The joint count fits: the arm was checked against MAX_JOINTS when it was connected.
    Joints::from_slice(&q.iter().map(|&x| x as f32).collect::<Vec<_>>())
        .map_err(|_| anyhow!("{what}: more than {MAX_JOINTS} joints"))
}
