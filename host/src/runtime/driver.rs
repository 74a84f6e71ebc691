//! [`Driver`]: a connection to the firmware with what every arm-driving command needs beside the
//! link's [`Session`]: the arm it runs and its kinematics on the host, torque switched on before a
//! move (and off again if the move is refused), and Ctrl-C between the polls of a wait.

use std::io::Write;

use anyhow::{anyhow, bail, Result};
use firmware::link::message::{Joints, RunState, Status, MAX_JOINTS};
use kinematics::JointKind;

use super::connection::{self, Connection, Target};
use crate::arm::dof::{self, DynArm};
use crate::arm::ArmSpec;
use crate::link::session::{Session, TORQUE_ON_WAITS};
pub use crate::link::session::{Waited, SETTLED};
use crate::link::Transport;
use crate::support::interrupt;

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

    /// The session over the link: every request to the firmware.
    pub fn session(&mut self) -> &mut Session<Box<dyn Transport>> {
        &mut self.conn.session
    }

    /// The simulated board, when the firmware core runs in SIL on this process (`--sim`): its
    /// virtual clock, trace and scene.
    pub fn sil(&mut self) -> Option<&mut crate::runtime::sil::Sil> {
        self.conn.sil()
    }

    /// The host's kinematics of the arm the firmware runs (forward kinematics, IK).
    pub fn model(&self) -> &dyn DynArm {
        self.fk.as_ref()
    }

    /// Whether goals are checked against the arm's collision geometry: always, but with
    /// `--no-collision-check` on the simulated arm (the firmware's check and the host's alike).
    pub fn collision_checked(&self) -> bool {
        self.conn.session.collision_check() == crate::link::arm_config::CollisionCheck::On
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

    /// The firmware's answer to the handshake.
    pub fn info(&self) -> &firmware::link::message::Info {
        &self.conn.info
    }

    /// Keyframe queue capacity of the firmware.
    pub fn queue_capacity(&self) -> usize {
        usize::from(self.conn.info.queue_capacity)
    }

    /// Free keyframe slots by the firmware's last report.
    pub fn free_slots(&self) -> u16 {
        self.conn.session.free_slots()
    }

    /// Waits one read timeout of the link (the pause between status polls: in the simulation's
    /// virtual time for --sim, so a simulated move takes no wall-clock time waiting).
    pub fn pause(&mut self) -> Result<()> {
        Ok(self.conn.session.pause()?)
    }

    /// The controller's status.
    pub fn status(&mut self) -> Result<Status> {
        Ok(self.conn.session.status()?)
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

    /// Switches torque on, through the `NotReady` of a firmware that has not read every servo
    /// yet ([`TORQUE_ON_WAITS`]).
    pub fn torque_on(&mut self) -> Result<(), crate::link::client::LinkError> {
        self.conn.session.torque_on(TORQUE_ON_WAITS)
    }

    /// Switches torque off again if [`Driver::ready_to_move`] switched it on, so that a refused
    /// motion leaves the arm as it was; returns words for the error message.
    pub fn undo_torque(&mut self, switched_on: bool) -> &'static str {
        match switched_on {
            false => "",
            true if self.conn.session.torque_off().is_ok() => " (torque is off again, as it was)",
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

    /// Polls status until the arm is at rest and holding ([`Session::wait_at_rest`]), ending
    /// early on Ctrl-C.
    pub fn wait_until_rest(&mut self, timeout: f64) -> Result<Waited> {
        Ok(self.conn.session.wait_at_rest(timeout, &mut interrupt::requested)?)
    }

    /// Sends stop and waits until the arm no longer moves (holding, limp or emergency-stopped).
    pub fn stop(&mut self) -> Result<Status> {
        Ok(self.conn.session.stop_and_wait()?)
    }

    /// Waits until the servos have caught up with a resting setpoint ([`Session::settle`]).
    pub fn settle(&mut self, status: Status) -> Result<Status> {
        Ok(self.conn.session.settle(status)?)
    }

    /// Gives the arm new collision geometry (obstacles added or removed by a front end): the host's
    /// copy at once, so every later command is checked against it, and the firmware's by sending
    /// the arm again through the session ([`Session::configure_arm`]) where what the firmware
    /// holds changes (its digest says so). A firmware takes a new arm only with the torque off (a
    /// new arm starts limp): with the torque on that is refused, and nothing changes. Returns
    /// whether the arm was sent again.
    pub fn set_collision(&mut self, collision: Option<crate::arm::collision::CollisionSpec>) -> Result<bool> {
        let mut arm = self.conn.arm.clone();
        arm.collision = collision;
        let servos = crate::arm::servos::servos_of(&arm);
        let digest = servos.as_ref().map(|s| crate::link::arm_config::arm_digest(&arm, s)).transpose()?;
        let resend = digest.is_some_and(|d| d != self.conn.info.arm_digest);
        if resend {
            if !matches!(self.status()?.state, RunState::TorqueOff) {
                bail!(
                    "the firmware takes new collision geometry with the arm, which it takes only with the torque off \
                     (a new arm starts limp): switch the torque off first; nothing changed"
                );
            }
            let servos = servos.ok_or_else(|| anyhow!("arm {} has no servo mapping to send", arm.name))?;
            self.conn.session.configure_arm(&arm, &servos, 0)?;
            self.conn.info = self.conn.session.hello()?;
        }
        self.fk = dof::build(arm.clone())?;
        self.conn.arm = arm;
        Ok(resend)
    }

    /// After Ctrl-C: stops the arm, waits until it is at rest, and says where it stopped, after
    /// `before` (a line of what had been done, or nothing).
    pub fn stop_for_interrupt(&mut self, before: &str) -> Result<String> {
        let status = self.stop().map_err(|e| anyhow!("Ctrl-C: {e:#}"))?;
        let at = self.tool_position(&status.measured)?;
        Ok(format!(
            "{before}stopped by Ctrl-C at {} m (joints {}), state {:?}",
            fmt3(&at),
            fmt_list(&status.measured),
            status.state
        ))
    }

    /// After Ctrl-C: [`Driver::stop_for_interrupt`], said on `err`. Returns the exit code.
    pub fn stop_after_interrupt(&mut self, err: &mut dyn Write) -> Result<i32> {
        writeln!(err, "{}", self.stop_for_interrupt("")?)?;
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
