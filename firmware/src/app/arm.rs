//! The arm the firmware drives, as the host sends it joint by joint (configure begin, one message
//! per joint, commit; the built-in arm is the same messages, replayed from flash), built in a slot
//! of its own and checked as a whole before it replaces the arm in use.
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
use crate::controller::{joint_limits, ArmScene, ConfigError, Controller, GripperConfig};
use crate::link::message::{
    BodyConfig, CollisionPart, Field, JointConfig, JointType, NakReason, ObstacleShape, Problem, ValueError, MAX_NAME,
};
use kinematics::collision::{Body, Capsule, Part, SceneError, Shape};

// The link carries no more bodies and obstacles than the controller holds.
const _: () = assert!(
    crate::link::message::MAX_BODIES <= crate::controller::MAX_BODIES
        && crate::link::message::MAX_OBSTACLES <= crate::controller::MAX_OBSTACLES
);

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
    /// Its collision geometry (empty: nothing is checked), built here as it arrives: a scene is
    /// a few kilobytes, too much to build on a board's stack and copy.
    pub scene: ArmScene,
    /// Whether its sender asked for every goal to be checked against the scene.
    pub collision_check: bool,
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

/// Why an arm cannot be built: the nak names the axis or the limits.
enum Unusable {
    /// Its joints and tool make no chain.
    Chain,
    /// Its limits leave a joint no range within its servo's, or are not positive.
    Limits,
}

impl<const N: usize> ArmSetup<N> {
    /// No arm: a motionless chain of `model`'s servos, none on the bus. The slot a firmware
    /// builds an arm in, in place.
    pub fn blank(model: &'static Model) -> Self {
        Self {
            name: String::new(),
            chain: Chain::motionless(),
            mappings: [padding_mapping(model); N],
            model,
            limits: JointLimits::still(),
            gripper: None,
            baud: None,
            digest: 0,
            scene: ArmScene::new(0.0),
            collision_check: true,
        }
    }

    /// Writes [`ArmSetup::blank`] at `at`. Never inlined: the blank set-up (its collision scene
    /// included, about 4 KB) is then built in this function's own frame, which a board's start-up
    /// leaves before it goes deeper, not in the frame of the start-up itself.
    ///
    /// # Safety
    /// `at` must be valid for writes and aligned; nothing there is read or dropped.
    #[inline(never)]
    #[allow(unsafe_code)]
    pub(crate) unsafe fn blank_at(at: *mut Self, model: &'static Model) {
        // Field by field: a whole set-up built here first would double this frame.
        crate::place::place_fields!(at: Self {
            name: String::new(),
            chain: Chain::motionless(),
            mappings: [padding_mapping(model); N],
            model: model,
            limits: JointLimits::still(),
            gripper: None,
            baud: None,
            digest: 0,
            scene: ArmScene::new(0.0),
            collision_check: true,
        });
    }

    /// Makes this slot the arm `arm` describes, in place (the chain alone is larger than a
    /// board's stack can spare twice); its gripper, bus and digest are left to the caller. On
    /// failure the slot holds part of an arm: it is a scratch slot, never the running arm.
    fn fill(&mut self, name: &String<MAX_NAME>, arm: &Staged<'_>, model: &'static Model) -> Result<(), Unusable> {
        let n = arm.configs.len();
        self.chain
            .set(|j| if j < n { arm.joint(j) } else { padding_joint() }, arm.tool)
            .map_err(|_| Unusable::Chain)?;
        for (j, slot) in self.mappings.iter_mut().enumerate() {
            *slot = if j < n { arm.mapping(j) } else { padding_mapping(model) };
        }
        let velocity = padded_limits((0..n).map(|j| arm.velocity(j)));
        let acceleration = padded_limits((0..n).map(|j| arm.acceleration(j)));
        self.limits =
            joint_limits(&self.chain, &self.mappings, velocity, acceleration).map_err(|_| Unusable::Limits)?;
        self.model = model;
        self.name.clone_from(name);
        self.gripper = None;
        self.baud = None;
        self.digest = 0;
        Ok(())
    }

    /// The arm's own joints: the first this many (the rest pad the build).
    pub fn joints(&self) -> usize {
        self.chain.moving_joints()
    }

    /// Makes `controller` this arm's on `board`, in place; a refused arm changes nothing.
    pub(super) fn configure<const Q: usize>(
        &self,
        controller: &mut Controller<N, Q>,
        board: &Board,
    ) -> Result<(), ConfigError> {
        controller.configure(&self.chain, &self.mappings, self.model, &self.limits, self.gripper, board.control)?;
        controller.set_collision(&self.scene, self.collision_check);
        Ok(())
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
    /// A collision message of this arm was refused: the arm is refused as a whole at commit.
    collision_refused: bool,
    /// The check was turned off by the sender.
    unchecked: bool,
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
        Self {
            begun: None,
            joints: [EMPTY; N],
            received: 0,
            gripper: None,
            bus: None,
            digest: 0,
            collision_refused: false,
            unchecked: false,
        }
    }

    /// Starts an arm of `joints` joints (1 to this firmware's `N`), dropping any arm half
    /// received (and its collision geometry, built in `into`).
    pub fn begin(
        &mut self,
        name: &String<MAX_NAME>,
        joints: u8,
        tool: Pose<f32>,
        model: u16,
        into: &mut ArmSetup<N>,
    ) -> Result<(), NakReason> {
        let joints = usize::from(joints);
        if joints == 0 || joints > N {
            return Err(bad(Field::JointCount, Problem::Count));
        }
        *self = Self::new();
        into.scene.clear();
        into.scene.set_margin(0.0);
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

    /// The arm's collision margin, and whether goals are checked.
    pub fn collision(&mut self, margin: f32, check: bool, into: &mut ArmSetup<N>) -> Result<(), NakReason> {
        if self.begun.is_none() {
            return Err(NakReason::NotReady);
        }
        into.scene.set_margin(margin);
        self.unchecked = !check;
        Ok(())
    }

    /// A refused collision message: the arm will be refused at commit as well.
    fn refuse_collision(&mut self, field: Field, error: SceneError) -> NakReason {
        self.collision_refused = true;
        match error {
            SceneError::Invalid => bad(field, Problem::OutOfRange),
            SceneError::NoFrame | SceneError::Full | SceneError::NoSuchPart => bad(field, Problem::Count),
        }
    }

    /// Stores body `index` in `into`'s scene. Bodies come in order; one sent again as it was is
    /// a repeat (nothing changes), another in its place is refused.
    pub fn body(&mut self, index: u8, body: &BodyConfig, into: &mut ArmSetup<N>) -> Result<(), NakReason> {
        let begun = self.begun.as_ref().ok_or(NakReason::NotReady)?;
        let body = Body {
            frame: body.frame,
            capsule: Capsule { a: Vector3::from(body.a), b: Vector3::from(body.b), radius: body.radius },
        };
        let held = into.scene.bodies();
        if let Some(old) = held.get(usize::from(index)) {
            return if *old == body { Ok(()) } else { Err(self.refuse_collision(Field::Body, SceneError::Full)) };
        }
        if usize::from(index) != held.len() {
            return Err(self.refuse_collision(Field::Body, SceneError::NoSuchPart));
        }
        let joints = begun.joints;
        into.scene.add_body(body, joints).map(|_| ()).map_err(|e| self.refuse_collision(Field::Body, e))
    }

    /// Stores obstacle `index` in `into`'s scene, in order as the bodies.
    pub fn obstacle(&mut self, index: u8, shape: &ObstacleShape, into: &mut ArmSetup<N>) -> Result<(), NakReason> {
        if self.begun.is_none() {
            return Err(NakReason::NotReady);
        }
        let shape = match *shape {
            ObstacleShape::Capsule { a, b, radius } => {
                Shape::Capsule(Capsule { a: Vector3::from(a), b: Vector3::from(b), radius })
            }
            ObstacleShape::Box { centre, rotation, half } => match Pose::rotation_from_quaternion_wxyz(rotation) {
                Some(rotation) => Shape::Box { centre: Vector3::from(centre), rotation, half: Vector3::from(half) },
                None => return Err(self.refuse_collision(Field::Obstacle, SceneError::Invalid)),
            },
            ObstacleShape::HalfSpace { normal, offset } => Shape::HalfSpace { normal: Vector3::from(normal), offset },
        };
        let held = into.scene.obstacles();
        if let Some(old) = held.get(usize::from(index)) {
            return if *old == shape { Ok(()) } else { Err(self.refuse_collision(Field::Obstacle, SceneError::Full)) };
        }
        if usize::from(index) != held.len() {
            return Err(self.refuse_collision(Field::Obstacle, SceneError::NoSuchPart));
        }
        into.scene.add_obstacle(shape).map(|_| ()).map_err(|e| self.refuse_collision(Field::Obstacle, e))
    }

    /// Never checks `body` against `other` (both already sent).
    pub fn allowed(&mut self, body: u8, other: CollisionPart, into: &mut ArmSetup<N>) -> Result<(), NakReason> {
        if self.begun.is_none() {
            return Err(NakReason::NotReady);
        }
        into.scene.allow(body, Part::from(other)).map_err(|e| self.refuse_collision(Field::Allowed, e))
    }

    /// The whole arm, checked, built in `into`: every joint sent, distinct servo ids, a model of
    /// the arm's bus protocol (the one named, or `board`'s), a valid chain, limits that leave
    /// each joint a range within its servo's. The staging is emptied on success; on failure it is
    /// kept, so a corrected joint can be resent (and `into`, a scratch slot, holds part of an arm).
    pub fn commit(&mut self, board: &Board, into: &mut ArmSetup<N>) -> Result<(), NakReason> {
        let begun = self.begun.as_ref().ok_or(NakReason::NotReady)?;
        let n = begun.joints;
        // N is at most MAX_JOINTS (8), so the mask fits.
        if self.received != (1u32 << n) - 1 {
            return Err(NakReason::NotReady);
        }
        if self.collision_refused {
            return Err(NakReason::BadCollision);
        }
        let configs = self.joints.get(..n).ok_or(NakReason::NotReady)?;
        let protocol = self.bus.map_or(board.bus.protocol, |(p, _)| p);
        let model = Model::by_number(protocol, begun.model).ok_or(bad(Field::Servo, Problem::OutOfRange))?;
        for (j, a) in configs.iter().enumerate() {
            if configs.iter().take(j).any(|b| b.servo.id == a.servo.id) {
                return Err(bad(Field::Servo, Problem::OutOfRange));
            }
        }
        let staged = Staged { configs, tool: begun.tool };
        into.fill(&begun.name, &staged, model).map_err(|e| match e {
            Unusable::Chain => bad(Field::Axis, Problem::OutOfRange),
            Unusable::Limits => bad(Field::Limits, Problem::OutOfRange),
        })?;
        into.baud = self.bus.map(|(_, baud)| baud);
        into.digest = self.digest;
        into.collision_check = !self.unchecked;
        if let Some(g) = self.gripper {
            // Within the servo's range, and not one of the joints' servos.
            let top = i64::from(model.ticks_per_revolution) - 1;
            let inside = |t: i32| (0..=top).contains(&i64::from(t));
            if !g.valid() || !inside(g.closed) || !inside(g.open) || configs.iter().any(|c| c.servo.id == g.id) {
                return Err(bad(Field::Gripper, Problem::OutOfRange));
            }
            into.gripper = Some(g);
        }
        *self = Self::new();
        Ok(())
    }
}

/// The joints the host sent, as an arm.
struct Staged<'a> {
    configs: &'a [JointConfig],
    tool: Pose<f32>,
}

impl Staged<'_> {
    fn config(&self, j: usize) -> &JointConfig {
        self.configs.get(j).unwrap_or(&EMPTY)
    }

    fn joint(&self, j: usize) -> Joint<f32> {
        let c = self.config(j);
        Joint {
            origin: Pose::from_xyz_rpy(c.origin_xyz, c.origin_rpy),
            axis: Vector3::from(c.axis),
            kind: match c.kind {
                JointType::Revolute => JointKind::Revolute,
                JointType::Continuous => JointKind::Continuous,
                JointType::Prismatic => JointKind::Prismatic,
            },
            limits: Limits::new(c.lower, c.upper),
        }
    }
    fn mapping(&self, j: usize) -> JointMapping {
        let c = &self.config(j).servo;
        JointMapping {
            id: c.id,
            ticks_per_revolution: c.ticks_per_revolution,
            zero: c.zero,
            direction: if c.reversed { Direction::Reverse } else { Direction::Forward },
            min_ticks: c.min_ticks,
            max_ticks: c.max_ticks,
            zero_half: c.zero_half,
            truncate: c.truncate,
        }
    }
    fn velocity(&self, j: usize) -> f32 {
        self.config(j).max_velocity
    }
    fn acceleration(&self, j: usize) -> f32 {
        self.config(j).max_acceleration
    }
}
