//! The arm the firmware drives: the built-in one, or one the host sends joint by joint
//! (configure begin, one message per joint, commit), checked as a whole before it replaces the arm
//! in use.
//!
//! A firmware of `N` joints drives any arm of 1 to `N`: the arm's joints come first and fixed
//! joints pad the rest ([`kinematics::JointKind::Fixed`]: no motion, no servo, held at zero), so one
//! build, one copy of the controller in flash, serves every arm.

use heapless::String;
use kinematics::nalgebra::{SVector, Vector3};
use kinematics::trajectory::JointLimits;
use kinematics::{Chain, Joint, JointKind, Limits, Pose};

use super::Board;
use crate::bus::mapping::{Direction, JointMapping};
use crate::bus::table::Model;
use crate::bus::Protocol;
use crate::controller::{joint_limits, ConfigError, Controller, GripperConfig};
use crate::link::message::{Field, JointConfig, JointType, NakReason, Problem, ValueError, MAX_NAME};

/// Everything the controller needs about an arm.
#[derive(Clone, Debug)]
pub struct ArmSetup<const N: usize> {
    /// Its name, reported in the handshake.
    pub name: String<MAX_NAME>,
    /// Its kinematics.
    pub chain: Chain<f32, N>,
    /// The servo of each joint.
    pub mappings: [JointMapping; N],
    /// The servos' model.
    pub model: &'static Model,
    /// Position (already within each servo's range), velocity and acceleration limits.
    pub limits: JointLimits<f32, N>,
    /// The gripper, if the arm has one.
    pub gripper: Option<GripperConfig>,
    /// The baud rate of its servos' bus; `None`: whatever the firmware's bus runs at.
    pub baud: Option<u32>,
    /// Its digest as its sender computed it (see [`crate::link::message::Info::arm_digest`]).
    pub digest: u32,
}

/// What pads joint `j` of an arm with fewer joints than the build: fixed at the tool end, no
/// servo (id 0 is never asked: the group leaves padding out), zero at the servo's middle.
fn padding_joint() -> Joint<f32> {
    Joint::fixed(Pose::identity())
}

fn padding_mapping(model: &Model) -> JointMapping {
    JointMapping::centred(0, model.ticks_per_revolution)
}

/// A speed or acceleration limit per joint of the build: the arm's own, then for the padding the
/// largest of the arm's. A padding joint never moves, but the player and the limiter take minima
/// and maxima over every joint (how soon a pause can stop, how long a move must last): the
/// largest of the arm's own changes neither.
fn padded_limits<const N: usize>(own: impl Iterator<Item = f32> + Clone) -> SVector<f32, N> {
    let largest = own.clone().fold(0.0f32, f32::max);
    let mut own = own;
    SVector::from_fn(|_, _| own.next().unwrap_or(largest))
}

impl<const N: usize> ArmSetup<N> {
    /// A setup from its parts; the limits are the chain's intersected with the servos' ranges.
    /// Joints after the arm's own ([`Chain::moving_joints`]) must be fixed padding.
    pub fn new(
        name: &str,
        chain: Chain<f32, N>,
        mappings: [JointMapping; N],
        model: &'static Model,
        max_velocity: SVector<f32, N>,
        max_acceleration: SVector<f32, N>,
    ) -> Result<Self, ConfigError> {
        let limits = joint_limits(&chain, &mappings, max_velocity, max_acceleration)?;
        let mut owned = String::new();
        for c in name.chars() {
            if owned.push(c).is_err() {
                break;
            }
        }
        Ok(Self { name: owned, chain, mappings, model, limits, gripper: None, baud: None, digest: 0 })
    }

    /// An arm of `joints.len()` joints (at most `N`) on this build: its joints, servos and
    /// limits first, padding after ([`Joint::fixed`] at the tool end, so the tool is where the
    /// arm's own chain puts it).
    #[allow(clippy::too_many_arguments)]
    pub fn padded(
        name: &str,
        joints: &[Joint<f32>],
        tool: Pose<f32>,
        mappings: &[JointMapping],
        model: &'static Model,
        max_velocity: &[f32],
        max_acceleration: &[f32],
    ) -> Result<Self, ConfigError> {
        let n = joints.len();
        if n == 0 || n > N || mappings.len() != n || max_velocity.len() != n || max_acceleration.len() != n {
            return Err(ConfigError::TooManyJoints);
        }
        let joint = |j: usize| joints.get(j).copied().unwrap_or_else(padding_joint);
        let chain = Chain::new(core::array::from_fn(joint), tool).map_err(|e| match e {
            kinematics::ChainError::ZeroAxis { joint } | kinematics::ChainError::BadLimits { joint } => {
                ConfigError::BadLimits { joint }
            }
            _ => ConfigError::BadLimits { joint: 0 },
        })?;
        let mappings = core::array::from_fn(|j| mappings.get(j).copied().unwrap_or_else(|| padding_mapping(model)));
        let (velocity, acceleration) =
            (padded_limits(max_velocity.iter().copied()), padded_limits(max_acceleration.iter().copied()));
        Self::new(name, chain, mappings, model, velocity, acceleration)
    }

    /// The arm's own joints: the first this many (the rest pad the build).
    pub fn joints(&self) -> usize {
        self.chain.moving_joints()
    }

    /// A controller for this arm on `board`.
    pub(super) fn controller<const Q: usize>(&self, board: &Board) -> Result<Controller<N, Q>, ConfigError> {
        let controller = Controller::new(self.chain, self.mappings, self.model, self.limits, board.control)?;
        match self.gripper {
            Some(g) => controller.with_gripper(g),
            None => Ok(controller),
        }
    }
}

/// An arm being received from the host.
#[derive(Clone, Debug)]
pub struct Staging<const N: usize> {
    begun: Option<Begun>,
    joints: [JointConfig; N],
    /// Joints received (bit per joint); the others hold [`EMPTY`].
    received: u32,
    gripper: Option<GripperConfig>,
    /// The bus named by the host: protocol and baud rate.
    bus: Option<(Protocol, u32)>,
    /// The digest named by the host.
    digest: u32,
}

/// The arm-wide part of an arm being received.
#[derive(Clone, Debug)]
struct Begun {
    name: String<MAX_NAME>,
    /// Its joint count (1..=N).
    joints: usize,
    tool: Pose<f32>,
    model: u16,
}

/// What a joint slot holds until its joint arrives (never used: commit needs every joint).
const EMPTY: JointConfig = JointConfig {
    kind: JointType::Revolute,
    origin_xyz: [0.0; 3],
    origin_rpy: [0.0; 3],
    axis: [0.0, 0.0, 1.0],
    lower: 0.0,
    upper: 0.0,
    max_velocity: 0.0,
    max_acceleration: 0.0,
    servo: crate::link::message::ServoConfig {
        id: 0,
        ticks_per_revolution: 0,
        zero: 0,
        reversed: false,
        min_ticks: 0,
        max_ticks: 0,
        zero_half: false,
        truncate: false,
    },
};

impl<const N: usize> Default for Staging<N> {
    fn default() -> Self {
        Self::new()
    }
}

fn bad(field: Field, problem: Problem) -> NakReason {
    NakReason::BadValue(ValueError { field, problem })
}

impl<const N: usize> Staging<N> {
    /// Nothing received.
    pub const fn new() -> Self {
        Self { begun: None, joints: [EMPTY; N], received: 0, gripper: None, bus: None, digest: 0 }
    }

    /// Starts an arm of `joints` joints (1 to this firmware's `N`), dropping any arm half
    /// received.
    pub fn begin(&mut self, name: &String<MAX_NAME>, joints: u8, tool: Pose<f32>, model: u16) -> Result<(), NakReason> {
        let joints = usize::from(joints);
        if joints == 0 || joints > N {
            return Err(bad(Field::JointCount, Problem::Count));
        }
        *self = Self::new();
        self.begun = Some(Begun { name: name.clone(), joints, tool, model });
        Ok(())
    }

    /// Stores the bus the arm's servos are on.
    pub fn bus(&mut self, protocol: Protocol, baud: u32) -> Result<(), NakReason> {
        if self.begun.is_none() {
            return Err(NakReason::NotReady);
        }
        self.bus = Some((protocol, baud));
        Ok(())
    }

    /// Stores the arm's digest.
    pub fn digest(&mut self, digest: u32) -> Result<(), NakReason> {
        if self.begun.is_none() {
            return Err(NakReason::NotReady);
        }
        self.digest = digest;
        Ok(())
    }

    /// Stores joint `index`.
    pub fn joint(&mut self, index: u8, joint: &JointConfig) -> Result<(), NakReason> {
        let begun = self.begun.as_ref().ok_or(NakReason::NotReady)?;
        if usize::from(index) >= begun.joints {
            return Err(bad(Field::JointIndex, Problem::OutOfRange));
        }
        let slot = self.joints.get_mut(usize::from(index)).ok_or(bad(Field::JointIndex, Problem::OutOfRange))?;
        *slot = *joint;
        self.received |= 1 << index;
        Ok(())
    }

    /// Stores the gripper.
    pub fn gripper(&mut self, gripper: &crate::link::message::GripperConfig) -> Result<(), NakReason> {
        if self.begun.is_none() {
            return Err(NakReason::NotReady);
        }
        self.gripper = Some(GripperConfig {
            id: gripper.id,
            closed: gripper.closed,
            open: gripper.open,
            effort: gripper.effort,
            speed: gripper.speed,
        });
        Ok(())
    }

    /// The whole arm, checked: every joint sent, distinct servo ids, a model of the arm's bus
    /// protocol (the one named, or `board`'s), a valid chain, limits that leave each joint a range
    /// within its servo's. The staging is emptied on success; on failure it is kept, so a
    /// corrected joint can be resent.
    pub fn commit(&mut self, board: &Board) -> Result<ArmSetup<N>, NakReason> {
        let begun = self.begun.as_ref().ok_or(NakReason::NotReady)?;
        let n = begun.joints;
        // N is at most MAX_JOINTS (8), so the mask fits.
        if self.received != (1u32 << n) - 1 {
            return Err(NakReason::NotReady);
        }
        let configs = self.joints.get(..n).ok_or(NakReason::NotReady)?;
        let protocol = self.bus.map_or(board.bus.protocol, |(p, _)| p);
        let model = Model::by_number(protocol, begun.model).ok_or(bad(Field::Servo, Problem::OutOfRange))?;
        for (j, a) in configs.iter().enumerate() {
            if configs.iter().take(j).any(|b| b.servo.id == a.servo.id) {
                return Err(bad(Field::Servo, Problem::OutOfRange));
            }
        }
        let joint = |c: &JointConfig| Joint {
            origin: Pose::from_xyz_rpy(c.origin_xyz, c.origin_rpy),
            axis: Vector3::from(c.axis),
            kind: match c.kind {
                JointType::Revolute => JointKind::Revolute,
                JointType::Continuous => JointKind::Continuous,
                JointType::Prismatic => JointKind::Prismatic,
            },
            limits: Limits::new(c.lower, c.upper),
        };
        let mapping = |c: &JointConfig| JointMapping {
            id: c.servo.id,
            ticks_per_revolution: c.servo.ticks_per_revolution,
            zero: c.servo.zero,
            direction: if c.servo.reversed { Direction::Reverse } else { Direction::Forward },
            min_ticks: c.servo.min_ticks,
            max_ticks: c.servo.max_ticks,
            zero_half: c.servo.zero_half,
            truncate: c.servo.truncate,
        };
        // The arm's joints, servos and limits, each as an array of N padded after the arm's.
        let config = |j: usize| configs.get(j);
        let joints: [Joint<f32>; N] = core::array::from_fn(|j| config(j).map_or_else(padding_joint, joint));
        let chain = Chain::new(joints, begun.tool).map_err(|_| bad(Field::Axis, Problem::OutOfRange))?;
        let mappings = core::array::from_fn(|j| config(j).map_or_else(|| padding_mapping(model), mapping));
        let velocity = padded_limits(configs.iter().map(|c| c.max_velocity));
        let acceleration = padded_limits(configs.iter().map(|c| c.max_acceleration));
        let mut setup = ArmSetup::new(&begun.name, chain, mappings, model, velocity, acceleration)
            .map_err(|_| bad(Field::Limits, Problem::OutOfRange))?;
        setup.baud = self.bus.map(|(_, baud)| baud);
        setup.digest = self.digest;
        if let Some(g) = self.gripper {
            // Within the servo's range, and not one of the joints' servos.
            let top = i64::from(model.ticks_per_revolution) - 1;
            let inside = |t: i32| (0..=top).contains(&i64::from(t));
            if !g.valid() || !inside(g.closed) || !inside(g.open) || configs.iter().any(|c| c.servo.id == g.id) {
                return Err(bad(Field::Gripper, Problem::OutOfRange));
            }
            setup.gripper = Some(g);
        }
        *self = Self::new();
        Ok(setup)
    }
}
