//! Host requests carried out: each [`HostMessage`] becomes a controller command (or an arm change,
//! a status snapshot, a telemetry rate) and its reply. A refused request changes nothing.

use kinematics::nalgebra::SVector;
use kinematics::trajectory::PlayerKeyframe;

use super::report::{free_slots, LinkCounts};
use super::Core;
use crate::bus::master::BusConfig;
use crate::controller::gravity::GravityJoint;
use crate::controller::{minimum_period_us, Command, Pace, Refusal, ToolPath};
use crate::link::message::{
    EStopMode, Field, FirmwareMessage, HostMessage, Info, Joints, MovePath, NakReason, Problem, Timing, ValueError,
    PROTOCOL_VERSION,
};

/// The firmware's version (major, minor, patch), from the crate version.
const FIRMWARE_VERSION: [u8; 3] = [
    parse_u8(env!("CARGO_PKG_VERSION_MAJOR")),
    parse_u8(env!("CARGO_PKG_VERSION_MINOR")),
    parse_u8(env!("CARGO_PKG_VERSION_PATCH")),
];

const fn parse_u8(s: &str) -> u8 {
    let bytes = s.as_bytes();
    let mut value: u32 = 0;
    let mut i = 0;
    while i < bytes.len() {
        value = value * 10 + (bytes[i] - b'0') as u32;
        i += 1;
    }
    if value > 255 {
        255
    } else {
        value as u8
    }
}

fn bad(field: Field, problem: Problem) -> NakReason {
    NakReason::BadValue(ValueError { field, problem })
}

/// The nak a controller refusal is reported with.
fn nak(refusal: Refusal) -> NakReason {
    match refusal {
        Refusal::NotFinite => bad(Field::Joints, Problem::NotFinite),
        Refusal::OutOfRange { joint } => NakReason::JointLimit { joint: u8::try_from(joint).unwrap_or(u8::MAX) },
        Refusal::BadParameter => bad(Field::Duration, Problem::OutOfRange),
        Refusal::Unreachable { .. } => NakReason::Unreachable,
        Refusal::EStopped => NakReason::EStopped,
        Refusal::TorqueOff => NakReason::TorqueOff,
        Refusal::NoPosition | Refusal::WrongMode => NakReason::NotReady,
        Refusal::QueueFull => NakReason::QueueFull,
        Refusal::TimeNotIncreasing => NakReason::KeyframeTime,
        Refusal::NoGripper => NakReason::NoGripper,
        Refusal::Collision { contact } => {
            NakReason::Collision { body: contact.body, other: contact.other.into(), distance: contact.distance }
        }
    }
}

/// Joint values of a message as the build's vector, if there is one value per joint of the arm
/// (`joints`); the padding joints after the arm's are zero, where they are held.
fn vector<const N: usize>(values: &Joints, joints: usize, field: Field) -> Result<SVector<f32, N>, NakReason> {
    if values.len() != joints || joints > N {
        return Err(bad(field, Problem::Count));
    }
    Ok(SVector::from_fn(|j, _| values.get(j).copied().unwrap_or(0.0)))
}

impl<const N: usize, const Q: usize> Core<N, Q> {
    /// Carries out `message` (already checked by [`HostMessage::validate`]) received at `now_us`.
    ///
    /// Never inlined: its frame (every request's temporaries) then exists only while a request is
    /// carried out, not under every control tick of the board's main loop.
    #[inline(never)]
    pub(super) fn apply(&mut self, message: &HostMessage, now_us: u64, link: LinkCounts) -> FirmwareMessage {
        match self.carry_out(message, now_us, link) {
            Ok(reply) => reply,
            Err(reason) => FirmwareMessage::Nak { reason },
        }
    }

    fn ack(&self) -> FirmwareMessage {
        let free = self.running().map_or(0, |c| c.free_slots());
        FirmwareMessage::Ack { free_slots: free_slots(free) }
    }

    fn info(&self) -> FirmwareMessage {
        let control_rate_hz = 1_000_000 / self.board.control.period_us.max(1);
        FirmwareMessage::Info(Info {
            protocol_version: PROTOCOL_VERSION,
            firmware_version: FIRMWARE_VERSION,
            // The arm's own joints: the host sends and reads that many values.
            joints: self.running().map_or(N, |c| c.joints()) as u8,
            arm_name: self.arm.as_ref().map(|a| a.name.clone()).unwrap_or_default(),
            queue_capacity: free_slots(Q),
            control_rate_hz: u16::try_from(control_rate_hz).unwrap_or(u16::MAX),
            arm_digest: self.arm.as_ref().map_or(0, |a| a.digest),
        })
    }

    /// Swaps the arm for the one just committed (in `incoming`; [`Core::commit_arm`] has checked
    /// that the torque is off: a new arm starts limp and reads its servos). Its bus becomes the
    /// firmware's ([`super::Firmware::bus`]; the board's loop switches the port). Refused,
    /// changing nothing, when the control period is shorter than one bus cycle of the arm's
    /// servos at its baud rate. The arm is configured from its slot in place, never copied.
    #[inline(never)]
    fn switch_arm(&mut self) -> Result<(), NakReason> {
        let setup = &self.incoming;
        let current = self.board.bus;
        let protocol = setup.model.protocol;
        let baud = setup.baud.unwrap_or(current.baud);
        // Another bus: the protocol's factory return delay and the baud's idle gap; what the board's
        // wiring sets (an echo to skip, the margin) stays.
        let bus = if (protocol, baud) == (current.protocol, current.baud) {
            current
        } else {
            BusConfig { echo: current.echo, margin_us: current.margin_us, ..BusConfig::new(protocol, baud) }
        };
        let servos = setup.joints() + usize::from(setup.gripper.is_some());
        if baud > self.board.max_bus_baud || self.board.control.period_us < minimum_period_us(setup.model, &bus, servos)
        {
            return Err(bad(Field::Bus, Problem::OutOfRange));
        }
        let board = super::Board { bus, model: setup.model, ..self.board };
        setup.configure(&mut self.controller, &board).map_err(|_| bad(Field::Limits, Problem::OutOfRange))?;
        self.arm = Some(super::ArmId { name: setup.name.clone(), digest: setup.digest });
        self.board.bus = bus;
        Ok(())
    }

    /// The staged arm becomes the running one. Never inlined: inlined, its frame would be
    /// reserved in the frame of every request.
    #[inline(never)]
    fn commit_arm(&mut self) -> Result<FirmwareMessage, NakReason> {
        // Before the staging is emptied: refused, the arm can be committed again once the torque
        // is off.
        if self.running().is_some_and(|c| c.torque()) {
            return Err(NakReason::NotReady);
        }
        self.staging.commit(&self.board, &mut self.incoming)?;
        self.switch_arm()?;
        Ok(self.ack())
    }

    /// The built-in arm becomes the running one: its configure messages, replayed as a host sends
    /// them (an arm half sent by the host is dropped, as a new `ConfigureBegin` drops it). The
    /// reply is the commit's.
    pub(super) fn use_builtin_arm(&mut self) -> Result<FirmwareMessage, NakReason> {
        let arm = self.builtin.ok_or(NakReason::NotReady)?;
        let mut reply = Err(NakReason::NotReady);
        for message in arm.messages() {
            let checked = message.validate().map_err(NakReason::BadValue);
            reply = checked.and_then(|()| self.configure(&message).unwrap_or(Err(NakReason::UnknownMessage)));
            if reply.is_err() {
                // Nothing of it stays staged: no host sent it, so none will correct and resend
                // a joint of it.
                self.staging = super::Staging::new();
                return reply;
            }
        }
        reply
    }

    /// Carries out a message that configures an arm (begin, a joint, the gripper, the digest, the
    /// bus, commit); `None` for any other.
    fn configure(&mut self, message: &HostMessage) -> Option<Result<FirmwareMessage, NakReason>> {
        let staged = match message {
            HostMessage::ConfigureBegin { name, joints, tool_xyz, tool_rpy, model } => {
                let tool = kinematics::Pose::from_xyz_rpy(*tool_xyz, *tool_rpy);
                self.staging.begin(name, *joints, tool, *model, &mut self.incoming)
            }
            HostMessage::ConfigureCollision { margin, check } => {
                self.staging.collision(*margin, *check, &mut self.incoming)
            }
            HostMessage::ConfigureBody { index, body } => self.staging.body(*index, body, &mut self.incoming),
            HostMessage::ConfigureObstacle { index, shape } => self.staging.obstacle(*index, shape, &mut self.incoming),
            HostMessage::ConfigureAllowed { body, other } => self.staging.allowed(*body, *other, &mut self.incoming),
            HostMessage::ConfigureJoint { index, joint } => self.staging.joint(*index, joint),
            HostMessage::ConfigureGripper(g) => self.staging.gripper(g),
            HostMessage::ConfigureDigest { digest } => self.staging.digest(*digest),
            HostMessage::ConfigureBus { protocol, baud } => self.staging.bus((*protocol).into(), *baud),
            HostMessage::ConfigureCommit => return Some(self.commit_arm()),
            _ => return None,
        };
        Some(staged.map(|()| self.ack()))
    }

    fn carry_out(
        &mut self,
        message: &HostMessage,
        now_us: u64,
        link: LinkCounts,
    ) -> Result<FirmwareMessage, NakReason> {
        // Requests that do not need an arm.
        match message {
            HostMessage::Hello { .. } => return Ok(self.info()),
            HostMessage::Ping => {
                if let Some(c) = self.running_mut() {
                    let _ = c.command(Command::HostAlive, now_us);
                }
                return Ok(self.ack());
            }
            HostMessage::GetStatus => {
                if let Some(c) = self.running_mut() {
                    // Polling status proves the host alive: the watchdog leaves the arm alone.
                    let _ = c.command(Command::HostAlive, now_us);
                }
                return Ok(FirmwareMessage::Status(self.status(now_us, link)));
            }
            HostMessage::SetTelemetry { rate_hz } => {
                let period = u64::from(self.board.control.period_us);
                self.telemetry = match *rate_hz {
                    0 => None,
                    // No faster than the control rate: a frame per tick at most.
                    hz => Some((u64::from(1_000_000 / u32::from(hz)).max(period), now_us)),
                };
                return Ok(self.ack());
            }
            HostMessage::UseBuiltinArm => return self.use_builtin_arm(),
            _ => {}
        }
        if let Some(reply) = self.configure(message) {
            return reply;
        }
        let controller = self.running_mut().ok_or(NakReason::NotReady)?;
        let joints = controller.joints();
        if let HostMessage::SetGravity { joint, mass, com, compliance } = *message {
            let part = GravityJoint { mass, com, compliance };
            if !controller.set_gravity(usize::from(joint), part) {
                return Err(bad(Field::JointIndex, Problem::OutOfRange));
            }
            return Ok(self.ack());
        }
        let command = match message {
            HostMessage::Torque { on: true } => Command::TorqueOn,
            HostMessage::Torque { on: false } => Command::TorqueOff,
            HostMessage::MoveTo { target, timing, path } => Command::MoveTool {
                position: target.position,
                orientation: target.orientation,
                pace: match *timing {
                    Timing::Duration(d) => Pace::Duration(d),
                    Timing::MaxSpeed(v) => Pace::Speed(v),
                },
                path: match path {
                    MovePath::Auto => ToolPath::Auto,
                    MovePath::Line => ToolPath::Line,
                    MovePath::Joint => ToolPath::Joint,
                },
            },
            HostMessage::MoveJoints { positions, timing } => {
                let q: SVector<f32, N> = vector(positions, joints, Field::Joints)?;
                let duration = match *timing {
                    Timing::Duration(d) => d,
                    // The joint that moves furthest sets the time; the controller lengthens it
                    // further if the acceleration limits need.
                    Timing::MaxSpeed(v) => (q - controller.setpoint().position).amax() / v,
                };
                Command::MoveJoints { q: q.into(), duration }
            }
            HostMessage::PushKeyframe(k) => {
                let position = vector(&k.positions, joints, Field::Joints)?;
                let velocity = match &k.velocities {
                    Some(v) => Some(vector(v, joints, Field::Velocities)?),
                    None => None,
                };
                Command::PushKeyframe {
                    keyframe: PlayerKeyframe { time: k.time, position, velocity },
                    gripper: k.gripper,
                }
            }
            HostMessage::PushCartesianKeyframe(k) => Command::PushToolKeyframe {
                time: k.time,
                position: k.target.position,
                orientation: k.target.orientation,
                gripper: k.gripper,
            },
            HostMessage::Gripper { opening, effort } => Command::Gripper { opening: *opening, effort: *effort },
            HostMessage::Start => Command::Start,
            HostMessage::Pause => Command::Pause,
            HostMessage::Stop => Command::Stop,
            HostMessage::EStop { mode } => Command::EStop { torque_off: *mode == EStopMode::TorqueOff },
            // Answered above.
            HostMessage::Hello { .. }
            | HostMessage::GetStatus
            | HostMessage::Ping
            | HostMessage::SetTelemetry { .. }
            | HostMessage::ConfigureBegin { .. }
            | HostMessage::ConfigureJoint { .. }
            | HostMessage::ConfigureGripper(_)
            | HostMessage::ConfigureBus { .. }
            | HostMessage::ConfigureDigest { .. }
            | HostMessage::ConfigureCommit
            | HostMessage::ConfigureCollision { .. }
            | HostMessage::ConfigureBody { .. }
            | HostMessage::ConfigureObstacle { .. }
            | HostMessage::ConfigureAllowed { .. }
            | HostMessage::SetGravity { .. }
            | HostMessage::UseBuiltinArm => return Err(NakReason::UnknownMessage),
        };
        controller.command(command, now_us).map_err(nak)?;
        Ok(self.ack())
    }
}
