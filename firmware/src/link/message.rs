//! The messages of the host link, shared by the firmware core and the host.
//!
//! Every field has a fixed largest size (arrays, `heapless` vectors and strings), so a message
//! decodes without a heap and its postcard encoding has a known bound. Values are SI (metres,
//! radians, seconds) in `f32`, the firmware's scalar; quaternions are unit and w-first.
//!
//! A message that decodes is not yet a valid one: [`HostMessage::validate`] refuses NaN, infinite
//! and out-of-range values with a [`ValueError`] naming the field, and the session naks such a
//! message before anything is applied. Checks that need the arm (joint count, joint limits,
//! reachability) are the controller's, which answers with [`NakReason::NotReady`],
//! [`NakReason::BadValue`] or [`NakReason::Unreachable`].
//!
//! # Panics
//! Nothing here panics.

use heapless::{String, Vec};
use serde::{Deserialize, Serialize};

use super::frame::{FrameError, MAX_FRAME};

/// The protocol version carried by the handshake; bumped on any change to the wire format.
pub const PROTOCOL_VERSION: u16 = 10;
/// The most joints a message carries.
pub const MAX_JOINTS: usize = 8;
/// The longest arm name, in bytes of UTF-8.
pub const MAX_NAME: usize = 24;

/// Joint values (radians or metres), one per joint.
pub type Joints = Vec<f32, MAX_JOINTS>;

/// The most collision bodies an arm carries (protocol version 9).
pub const MAX_BODIES: usize = 24;
/// The most obstacles an arm carries.
pub const MAX_OBSTACLES: usize = 8;
/// Largest collision margin (m): far more than any arm keeps, so only garbage fails.
pub const MAX_MARGIN: f32 = 1.0;

/// Largest |coordinate| of a Cartesian target (m): far beyond any desk arm, so only garbage fails.
pub const MAX_REACH: f32 = 10.0;
/// Largest |joint value| (rad or m): continuous joints may be many turns from zero.
pub const MAX_JOINT_VALUE: f32 = 1000.0;
/// Largest |joint velocity| (rad/s or m/s).
pub const MAX_JOINT_VELOCITY: f32 = 1000.0;
/// Longest move or keyframe time (s): a day.
pub const MAX_TIME: f32 = 86_400.0;
/// Fastest tool speed limit (m/s).
pub const MAX_SPEED: f32 = 10.0;
/// Fastest telemetry (Hz); the firmware caps it further at its control rate.
pub const MAX_TELEMETRY_HZ: u16 = 1000;
/// How far a quaternion's norm may be from 1 (f32 text round trips lose about 1e-7).
pub const QUATERNION_TOLERANCE: f32 = 1e-3;

/// How long a move takes.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub enum Timing {
    /// Exactly this long (s, > 0).
    Duration(f32),
    /// As fast as the limits allow, the tool (or, for joint moves, every joint) no faster than this
    /// (m/s for the tool, rad/s or m/s for joints; > 0).
    MaxSpeed(f32),
}

/// Which way the tool goes to a Cartesian target (protocol version 5).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum MovePath {
    /// The straight line; where it runs into the joint limits, the rest of the way by joints.
    #[default]
    Auto,
    /// The straight line only: where it runs into the joint limits, the arm stops there.
    Line,
    /// By joints, to the solution found before moving.
    Joint,
}

/// A Cartesian target of the tool in the base frame.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct CartesianTarget {
    /// Position (m).
    pub position: [f32; 3],
    /// Orientation as a unit quaternion, w-first; `None` leaves it free (position-only IK).
    pub orientation: Option<[f32; 4]>,
}

/// A joint keyframe for the player's queue.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct JointKeyframe {
    /// Time on the trajectory clock (s, >= 0).
    pub time: f32,
    /// Joint values, one per joint.
    pub positions: Joints,
    /// Joint velocities at the keyframe; `None` lets the player choose them.
    pub velocities: Option<Joints>,
    /// The gripper's opening at the keyframe, percent (0 closed to 100 open); `None` leaves it.
    pub gripper: Option<f32>,
}

/// A Cartesian keyframe: the firmware solves IK for it and queues the joint keyframe.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct CartesianKeyframe {
    /// Time on the trajectory clock (s, >= 0).
    pub time: f32,
    /// The tool's pose.
    pub target: CartesianTarget,
    /// The gripper's opening at the keyframe, percent (0 closed to 100 open); `None` leaves it.
    pub gripper: Option<f32>,
}

/// How a joint moves (as in URDF).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum JointType {
    /// Rotation within limits.
    Revolute,
    /// Rotation without limits.
    Continuous,
    /// Translation within limits.
    Prismatic,
}

/// One joint of an arm sent by the host: geometry, limits and servo mapping.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct JointConfig {
    /// Revolute, continuous or prismatic.
    pub kind: JointType,
    /// Translation from the parent frame at zero joint value (m).
    pub origin_xyz: [f32; 3],
    /// Rotation from the parent frame, roll-pitch-yaw as in URDF (rad).
    pub origin_rpy: [f32; 3],
    /// Motion axis in the joint frame (unit length within the quaternion tolerance).
    pub axis: [f32; 3],
    /// Lowest position (rad or m).
    pub lower: f32,
    /// Highest position (rad or m), above `lower`.
    pub upper: f32,
    /// Largest |velocity| (> 0).
    pub max_velocity: f32,
    /// Largest |acceleration| (> 0).
    pub max_acceleration: f32,
    /// The servo driving the joint.
    pub servo: ServoConfig,
}

/// Servo mapping of one joint (see `firmware::bus::mapping`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct ServoConfig {
    /// Servo id on the bus (0..=252).
    pub id: u8,
    /// Ticks per revolution (> 0).
    pub ticks_per_revolution: u32,
    /// Ticks at joint value zero.
    pub zero: i32,
    /// The servo turns against the joint axis.
    pub reversed: bool,
    /// Lowest tick the servo may be sent (0 for a servo's whole single-turn range).
    pub min_ticks: i32,
    /// Highest tick (`ticks_per_revolution - 1` for the whole range; a calibration's `range_max`).
    pub max_ticks: i32,
    /// Zero lies half a tick above `zero` (a LeRobot calibration's middle).
    pub zero_half: bool,
    /// Ticks by truncation toward zero (LeRobot's degree mode), not to the nearest.
    pub truncate: bool,
}

/// The arm's gripper: a servo of the joints' model outside the chain.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct GripperConfig {
    /// Servo id on the bus (0..=252, not a joint's).
    pub id: u8,
    /// Ticks with the jaws closed (0 %).
    pub closed: i32,
    /// Ticks with the jaws open (100 %), not `closed`.
    pub open: i32,
    /// Effort limit, percent of the servo's full torque or current, (0, 100].
    pub effort: f32,
    /// Speed, percent of the stroke per second (> 0).
    pub speed: f32,
}

/// The gripper as the firmware sees it.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct GripperStatus {
    /// Measured opening, percent (beyond 0..100 when pushed past the range).
    pub opening: f32,
    /// The goal, percent.
    pub goal: f32,
    /// Load, percent of the servo's full effort.
    pub load: f32,
    /// It holds something: stopped short of its goal with the load above the threshold.
    pub holding: bool,
}

/// Emergency stop behaviour.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum EStopMode {
    /// Hold the current position with torque on.
    Hold,
    /// Switch torque off (the arm falls where gravity takes it).
    TorqueOff,
}

/// Messages from the host. Each travels in a request frame and is answered by one reply.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum HostMessage {
    /// Handshake: answered by [`FirmwareMessage::Info`]. Starts a new session.
    Hello {
        /// The host's [`PROTOCOL_VERSION`].
        protocol_version: u16,
    },
    /// Starts sending an arm: its name and joint count; the joints follow one per message, since
    /// a whole arm does not fit one frame.
    ConfigureBegin {
        /// The arm's name.
        name: String<MAX_NAME>,
        /// Joints to follow (1..=MAX_JOINTS).
        joints: u8,
        /// The tool frame's origin in the last joint's frame (m).
        tool_xyz: [f32; 3],
        /// The tool frame's rotation, roll-pitch-yaw as in URDF (rad).
        tool_rpy: [f32; 3],
        /// Model number of the servos (as their model item reads, e.g. 777 for the STS3215, 1020
        /// for the XM430-W350): the firmware needs its control table and refuses a model it has
        /// no table for or that does not speak its bus's protocol.
        model: u16,
    },
    /// One joint of the arm being sent.
    ConfigureJoint {
        /// Its index (0-based, below the announced count).
        index: u8,
        /// The joint.
        joint: JointConfig,
    },
    /// Ends the arm: the firmware validates the whole arm and switches to it, or naks and keeps
    /// the arm it had.
    ConfigureCommit,
    /// Drops a configured arm and uses the firmware's built-in one.
    UseBuiltinArm,
    /// Torque on or off on every servo.
    Torque {
        /// On.
        on: bool,
    },
    /// Moves the tool to a Cartesian target, IK solved on the firmware.
    MoveTo {
        /// Where.
        target: CartesianTarget,
        /// How long.
        timing: Timing,
        /// Which way (protocol version 5).
        path: MovePath,
    },
    /// Moves to joint values.
    MoveJoints {
        /// Joint values.
        positions: Joints,
        /// How long.
        timing: Timing,
    },
    /// Appends a joint keyframe to the queue.
    PushKeyframe(JointKeyframe),
    /// Appends a Cartesian keyframe (IK on the firmware) to the queue.
    PushCartesianKeyframe(CartesianKeyframe),
    /// Starts (or resumes) playing the queue.
    Start,
    /// Pauses playback: decelerates and holds, keeping the queue.
    Pause,
    /// Stops: decelerates within the limits and clears the queue.
    Stop,
    /// Emergency stop: at once, no deceleration.
    EStop {
        /// Hold or torque off.
        mode: EStopMode,
    },
    /// Asks for a [`FirmwareMessage::Status`].
    GetStatus,
    /// Asks for an ack: the free keyframe slots in a short reply (the host's flow-control poll),
    /// and proof that the host is alive (the watchdog).
    Ping,
    /// Telemetry ([`FirmwareMessage::Telemetry`]) at this rate (Hz); 0 switches it off.
    SetTelemetry {
        /// Rate (Hz, 0..=MAX_TELEMETRY_HZ).
        rate_hz: u16,
    },
    // Added in protocol version 3, after the others so that their encodings stay as they were.
    /// The gripper of the arm being sent (optional, after ConfigureBegin and before ConfigureCommit).
    ConfigureGripper(GripperConfig),
    /// Drives the gripper to an opening at its speed.
    Gripper {
        /// Opening, percent (0 closed to 100 open).
        opening: f32,
        /// Effort limit from now on, percent of the servo's full torque or current; `None`
        /// keeps it.
        effort: Option<f32>,
    },
    // Added in protocol version 4.
    /// The servo bus of the arm being sent (optional, after ConfigureBegin and before
    /// ConfigureCommit): its protocol and baud rate. Without it the arm is on the bus the firmware
    /// runs now. The firmware switches its bus when the arm is committed.
    ConfigureBus {
        /// The servos' protocol.
        protocol: BusProtocol,
        /// Their baud rate ([`MIN_BAUD`]..=[`MAX_BAUD`]).
        baud: u32,
    },
    /// The digest of the arm being sent (optional, after ConfigureBegin and before
    /// ConfigureCommit): what [`Info::arm_digest`] reports while it runs, so that a host can tell
    /// whether the board runs exactly the arm it has.
    ConfigureDigest {
        /// The sender's digest of the arm's other configure messages.
        digest: u32,
    },
    // Added in protocol version 9: the arm's collision geometry, after ConfigureBegin and before
    // ConfigureCommit, covered by the digest like the rest of the arm. Without it nothing is
    // checked.
    /// The margin every checked pair keeps, and whether the firmware checks at all.
    ConfigureCollision {
        /// The distance every checked pair keeps (m, 0..=[`MAX_MARGIN`]).
        margin: f32,
        /// Check every goal against the bodies and obstacles; `false` only for a test that must
        /// see the arm reach a contact (`--no-collision-check`): the status says it is off.
        check: bool,
    },
    /// One body of the arm: a capsule (a sphere when `a == b`) fixed to a frame. Bodies are sent
    /// in order of their index.
    ConfigureBody {
        /// Its index (0-based, below [`MAX_BODIES`]).
        index: u8,
        /// The capsule and its frame.
        body: BodyConfig,
    },
    /// One obstacle, in the base frame. Obstacles are sent in order of their index, after the
    /// bodies.
    ConfigureObstacle {
        /// Its index (0-based, below [`MAX_OBSTACLES`]).
        index: u8,
        /// Its shape.
        shape: ObstacleShape,
    },
    /// A pair never checked (neighbouring links, the base on the table), after the bodies and
    /// obstacles it names.
    ConfigureAllowed {
        /// The arm's body.
        body: u8,
        /// The other part.
        other: CollisionPart,
    },
    // Added in protocol version 10.
    /// What one joint's link weighs and how far its servo's own loop gives under a torque: the
    /// firmware offsets the goal it writes to each servo by the deflection the arm's gravity
    /// torque will leave ([`crate::controller::gravity`]). Sent to the running arm, joint by
    /// joint, after it is committed; a new arm starts without.
    SetGravity {
        /// The joint (0-based, below the arm's joint count).
        joint: u8,
        /// The mass its motion carries (kg, 0..=[`MAX_LINK_MASS`]): its link, and for the last
        /// joint a payload in the tool.
        mass: f32,
        /// That mass's centre, in the joint's moving frame (m, each within [`MAX_COM`]).
        com: [f32; 3],
        /// The servo's deflection per unit of torque at rest (rad per N m, or m per N for a
        /// prismatic joint; 0..=[`MAX_COMPLIANCE`]): the inverse of its loop's stiffness.
        compliance: f32,
    },
}

/// The heaviest link [`HostMessage::SetGravity`] carries (kg).
pub const MAX_LINK_MASS: f32 = 50.0;
/// How far from its joint a link's centre of mass may lie (m, each coordinate).
pub const MAX_COM: f32 = 5.0;
/// The softest servo loop [`HostMessage::SetGravity`] carries (rad per N m).
pub const MAX_COMPLIANCE: f32 = 2.0;

/// A collision body as the link carries it: a capsule in the frame of a joint after its motion,
/// or of the base (protocol version 9).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct BodyConfig {
    /// The joint (0-based) whose moving frame carries it; `None`: the base.
    pub frame: Option<u8>,
    /// One end of the core segment, in that frame (m).
    pub a: [f32; 3],
    /// The other end (m); `a` again for a sphere.
    pub b: [f32; 3],
    /// Radius (m, >= 0).
    pub radius: f32,
}

/// An obstacle's shape, in the base frame (protocol version 9).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub enum ObstacleShape {
    /// A capsule, or a sphere when `a == b`.
    Capsule {
        /// One end (m).
        a: [f32; 3],
        /// The other end (m).
        b: [f32; 3],
        /// Radius (m, >= 0).
        radius: f32,
    },
    /// A box.
    Box {
        /// Centre (m).
        centre: [f32; 3],
        /// Its axes as a unit quaternion, w-first.
        rotation: [f32; 4],
        /// Half its size along each axis (m, > 0).
        half: [f32; 3],
    },
    /// The half-space `normal . x <= offset` (a table: normal up, offset its height).
    HalfSpace {
        /// Unit normal, out of the solid.
        normal: [f32; 3],
        /// The surface's distance from the origin along the normal (m).
        offset: f32,
    },
}

/// What a body can come too close to, by index (protocol version 9).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum CollisionPart {
    /// Another body of the arm.
    Body(u8),
    /// An obstacle.
    Obstacle(u8),
}

impl From<CollisionPart> for kinematics::collision::Part {
    fn from(p: CollisionPart) -> Self {
        match p {
            CollisionPart::Body(i) => Self::Body(i),
            CollisionPart::Obstacle(o) => Self::Obstacle(o),
        }
    }
}

impl From<kinematics::collision::Part> for CollisionPart {
    fn from(p: kinematics::collision::Part) -> Self {
        match p {
            kinematics::collision::Part::Body(i) => Self::Body(i),
            kinematics::collision::Part::Obstacle(o) => Self::Obstacle(o),
        }
    }
}

/// What the firmware checks goals against (protocol version 9).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum CollisionCheck {
    /// The arm came without collision geometry: nothing is checked.
    NoGeometry,
    /// Every goal is checked against this many bodies and obstacles.
    On {
        /// Bodies.
        bodies: u8,
        /// Obstacles.
        obstacles: u8,
    },
    /// The arm has geometry but its sender turned the check off (`--no-collision-check`).
    Off,
}

/// The last time the firmware stopped the arm short of a contact (protocol version 9).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct CollisionStop {
    /// The arm's body.
    pub body: u8,
    /// What it would have come too close to.
    pub other: CollisionPart,
    /// Their signed distance where the arm would have gone (m; negative: overlapping).
    pub distance: f32,
    /// Collision stops since the arm was configured (wraps): a host tells a new stop by it.
    pub count: u32,
}

/// Lowest servo bus baud rate an arm may name (the slowest either protocol's servos offer).
pub const MIN_BAUD: u32 = 9_600;
/// Highest servo bus baud rate an arm may name (Dynamixel X-series' 4.5 Mbps).
pub const MAX_BAUD: u32 = 4_500_000;

/// A servo protocol, as the link names it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum BusProtocol {
    /// ROBOTIS Dynamixel Protocol 2.0.
    Dynamixel2,
    /// Feetech SCS/STS.
    Feetech,
}

impl From<BusProtocol> for crate::bus::Protocol {
    fn from(p: BusProtocol) -> Self {
        match p {
            BusProtocol::Dynamixel2 => Self::Dxl2,
            BusProtocol::Feetech => Self::Feetech,
        }
    }
}

impl From<crate::bus::Protocol> for BusProtocol {
    fn from(p: crate::bus::Protocol) -> Self {
        match p {
            crate::bus::Protocol::Dxl2 => Self::Dynamixel2,
            crate::bus::Protocol::Feetech => Self::Feetech,
        }
    }
}

/// The handshake's answer.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Info {
    /// The firmware's [`PROTOCOL_VERSION`].
    pub protocol_version: u16,
    /// Firmware version (major, minor, patch).
    pub firmware_version: [u8; 3],
    /// Joints of the current arm.
    pub joints: u8,
    /// Name of the current arm.
    pub arm_name: String<MAX_NAME>,
    /// Capacity of the keyframe queue.
    pub queue_capacity: u16,
    /// Control rate (Hz).
    pub control_rate_hz: u16,
    /// The digest of the current arm, as its sender computed it ([`HostMessage::ConfigureDigest`];
    /// [`crate::builtin::DIGEST`] for the built-in arm, 0 for an arm sent without one): two arms
    /// of one name that differ (another calibration, an edited file) have different digests.
    pub arm_digest: u32,
}

/// What the player is doing.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum RunState {
    /// At rest, holding position.
    Idle,
    /// Playing the queue or a move.
    Moving,
    /// Paused (decelerating or holding), queue kept.
    Paused,
    /// Decelerating after a stop.
    Stopping,
    /// Emergency-stopped; needs a new command.
    EStopped,
    /// Torque off.
    TorqueOff,
}

/// The last IK solve on the firmware.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct IkStatus {
    /// It converged within tolerance.
    pub converged: bool,
    /// Iterations used.
    pub iterations: u16,
    /// Position error left (m).
    pub position_error: f32,
    /// Orientation error left (rad).
    pub orientation_error: f32,
}

/// Control-loop timing.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct LoopTiming {
    /// Mean busy time of a control tick (us).
    pub mean_us: u32,
    /// Longest busy time since the last status (us).
    pub max_us: u32,
    /// Ticks that overran their period.
    pub overruns: u32,
}

/// Error counters since start.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct ErrorCounters {
    /// Link frames dropped for a bad CRC or COBS encoding.
    pub link_corrupt: u32,
    /// Link frames dropped as oversized.
    pub link_oversized: u32,
    /// Requests refused (nak).
    pub naks: u32,
    /// Servo replies missing.
    pub bus_timeouts: u32,
    /// Servo replies broken or reporting errors.
    pub bus_errors: u32,
    /// Queue underruns of the player.
    pub underruns: u32,
    /// Times the watchdog stopped the arm because the host fell silent.
    pub watchdog_trips: u32,
    /// Tracking ticks whose IK did not converge within the per-tick budget.
    pub ik_failures: u32,
    /// Cartesian moves whose straight line ran into the joint limits, finished by a joint-space
    /// move to the solution found before moving.
    pub line_fallbacks: u32,
    // Added in protocol version 6.
    /// Bytes from the host that a board dropped because its link receive ring was full (the
    /// main loop fell behind the line). Wraps at 2^32. 0 where the core runs on a PC: its link
    /// has no such ring.
    pub link_dropped: u32,
    /// Receive overruns of a board's link UART: bytes lost in the UART because its receive
    /// interrupt came too late (each overrun loses at least one). Wraps at 2^32. 0 on a PC.
    pub link_overruns: u32,
}

/// A snapshot of the controller.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Status {
    /// Controller time (s).
    pub time: f32,
    /// The playback clock (s) when the status was made: the time the player samples its keyframes
    /// at, zero at `Start` (and while not playing), advanced between ticks by the time since the
    /// last one. A host streaming keyframes times them by it: a keyframe is due when this clock
    /// reaches its time.
    pub play_time: f32,
    /// What the player is doing.
    pub state: RunState,
    /// Measured joint positions.
    pub measured: Joints,
    /// Joint setpoints sent last.
    pub setpoints: Joints,
    /// Keyframes queued.
    pub queued: u16,
    /// Free keyframe slots.
    pub free_slots: u16,
    /// The last IK solve.
    pub ik: IkStatus,
    /// Loop timing.
    pub timing: LoopTiming,
    /// Error counters.
    pub errors: ErrorCounters,
    /// Servos (bit `j` for joint `j`) that have stopped answering; cleared when one answers again.
    pub lost_servos: u32,
    /// The gripper, if the arm has one.
    pub gripper: Option<GripperStatus>,
    // Added in protocol version 7.
    /// The last move the firmware accepted (`MoveTo` or `MoveJoints`) and the way it went; `None`
    /// until one is accepted (and after a new arm). Keyframes do not change it: it tells a host
    /// how its last move went without comparing counters before and after.
    pub last_move: Option<MoveOutcome>,
    // Added in protocol version 8.
    /// The farthest the player braked past its last keyframe when the keyframes ran out while
    /// moving (a stream that stopped), in this playback: rad (or m), the largest joint's; 0 when
    /// they never ran out. It then went back to that keyframe and ended there.
    pub largest_pass: f32,
    // Added in protocol version 9.
    /// What goals are checked against.
    pub collision_check: CollisionCheck,
    /// The last collision stop since the arm was configured; `None` before one.
    pub last_collision: Option<CollisionStop>,
}

/// The way the tool went on a move (protocol version 7).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum PathTaken {
    /// Along the straight line, tracked by IK, and not given up (yet): under way, arrived, or
    /// ended by a stop, the watchdog or an emergency stop (the run state and the tool say which).
    Line,
    /// Along the straight line until it ran into the joint limits ([`MovePath::Auto`]), then the
    /// rest of the way by joints to the solution found before moving.
    LineThenJoints,
    /// By joints from the start: a `MoveJoints`, or a `MoveTo` with [`MovePath::Joint`].
    Joints,
    /// Along the straight line until it ran into the joint limits ([`MovePath::Line`]), then
    /// stopped there, short of the target.
    LineStopped,
    /// Stopped short of a contact (protocol version 9): the status's `last_collision` names the
    /// pair.
    CollisionStopped,
}

/// The last move and how it went (protocol version 7): set when the firmware accepts a `MoveTo`
/// or `MoveJoints`, updated when it gives a line up.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct MoveOutcome {
    /// The way it went.
    pub path: PathTaken,
    /// Where the line was given up (m along it from the start, 0..=`line_length`): the tool's
    /// place, projected onto the line, when the firmware found it blocked. `Some` exactly for
    /// [`PathTaken::LineThenJoints`] and [`PathTaken::LineStopped`].
    pub blocked_at: Option<f32>,
    /// The straight line's length (m): from where the tool was when the move was accepted to the
    /// target. 0 for a move by joints from the start.
    pub line_length: f32,
}

/// Which field of a message a [`ValueError`] is about.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Field {
    /// A Cartesian position.
    Position,
    /// A quaternion.
    Orientation,
    /// A move duration.
    Duration,
    /// A speed limit.
    Speed,
    /// A keyframe time.
    Time,
    /// Joint values.
    Joints,
    /// Joint velocities.
    Velocities,
    /// The joint count of an arm.
    JointCount,
    /// A joint index.
    JointIndex,
    /// A joint's origin.
    Origin,
    /// A joint's axis.
    Axis,
    /// A joint's limits.
    Limits,
    /// A joint's servo mapping.
    Servo,
    /// A telemetry rate.
    Rate,
    /// An arm name.
    Name,
    /// A gripper's configuration, opening or effort.
    Gripper,
    /// The servo bus of an arm: its baud rate, or a control period it cannot keep.
    Bus,
    // Added in protocol version 9.
    /// The collision margin.
    Margin,
    /// A collision body: its index, frame, ends or radius.
    Body,
    /// An obstacle: its index, place, rotation or size.
    Obstacle,
    /// An allowed pair: an index that names nothing, or bodies or obstacles that are not valid
    /// together.
    Allowed,
    // Added in protocol version 10.
    /// A link's mass or centre of mass, or its servo's compliance.
    Gravity,
}

/// What is wrong with a field.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Problem {
    /// NaN or infinite.
    NotFinite,
    /// Outside its range.
    OutOfRange,
    /// A quaternion or axis not of unit length.
    NotUnit,
    /// Too few or too many values, or lengths that disagree.
    Count,
}

/// Why a message's values are refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct ValueError {
    /// The field.
    pub field: Field,
    /// What is wrong.
    pub problem: Problem,
}

/// Why a request was refused. A refused request changes nothing.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub enum NakReason {
    /// A frame failed its CRC or COBS decoding (its sequence number cannot be trusted).
    Corrupt,
    /// A frame longer than [`MAX_FRAME`].
    Oversized,
    /// The frame kind or message is not one this protocol version knows.
    UnknownMessage,
    /// A value is refused.
    BadValue(ValueError),
    /// A keyframe push found the queue full.
    QueueFull,
    /// The request does not fit the controller's state (e.g. no arm yet, nothing to start or
    /// pause, a configure step out of order, servo positions not read yet).
    NotReady,
    /// IK found no solution for a Cartesian target within the joint limits.
    Unreachable,
    /// A joint value lies outside that joint's limits.
    JointLimit {
        /// The joint (0-based).
        joint: u8,
    },
    /// A keyframe's time is not later than the previous keyframe's.
    KeyframeTime,
    /// The torque is off: motion needs torque on first.
    TorqueOff,
    /// Emergency-stopped: only torque on (or off) is accepted.
    EStopped,
    /// A gripper command or value for an arm without a gripper.
    NoGripper,
    // Added in protocol version 9.
    /// A move's target brings two checked parts closer than the margin.
    Collision {
        /// The arm's body.
        body: u8,
        /// What it comes too close to.
        other: CollisionPart,
        /// Their signed distance at the target (m).
        distance: f32,
    },
    /// The arm's collision geometry was refused at commit: a body on a joint the arm does not
    /// have, more than this build holds, or an allowed pair naming nothing.
    BadCollision,
}

/// The nak reported for bytes that are no frame, or a payload that is no message. Here rather than
/// beside [`FrameError`]: framing is the layer below the messages and knows none of them.
impl From<FrameError> for NakReason {
    fn from(error: FrameError) -> Self {
        match error {
            FrameError::Oversized { .. } | FrameError::BufferTooSmall => Self::Oversized,
            FrameError::UnknownKind { .. } | FrameError::UnknownMessage => Self::UnknownMessage,
            FrameError::Cobs(_) | FrameError::Truncated { .. } | FrameError::Crc { .. } => Self::Corrupt,
        }
    }
}

impl core::fmt::Display for NakReason {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Corrupt => write!(f, "corrupt frame"),
            Self::Oversized => write!(f, "frame longer than {MAX_FRAME} bytes"),
            Self::UnknownMessage => write!(f, "unknown message"),
            Self::BadValue(e) => write!(f, "bad value: {:?} is {:?}", e.field, e.problem),
            Self::QueueFull => write!(f, "keyframe queue full"),
            Self::NotReady => write!(f, "not possible in the controller's present state"),
            Self::Unreachable => write!(f, "target unreachable within the joint limits"),
            Self::JointLimit { joint } => write!(f, "joint {} outside its limits", joint + 1),
            Self::KeyframeTime => write!(f, "keyframe time not later than the previous keyframe"),
            Self::TorqueOff => write!(f, "torque is off (turn it on first)"),
            Self::EStopped => write!(f, "emergency-stopped (torque on to leave it)"),
            Self::NoGripper => write!(f, "the arm has no gripper"),
            Self::Collision { body, other, distance } => {
                write!(f, "the target brings body {body} within {:.1} mm of {other:?}", distance * 1e3)
            }
            Self::BadCollision => write!(f, "the arm's collision geometry does not fit it or this build"),
        }
    }
}

/// Messages from the firmware.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum FirmwareMessage {
    /// The request was applied (or had been: a repeat). Carries the free keyframe slots, which
    /// the host's flow control relies on.
    Ack {
        /// Free keyframe slots after the request.
        free_slots: u16,
    },
    /// The request was refused and changed nothing.
    Nak {
        /// Why.
        reason: NakReason,
    },
    /// Answer to [`HostMessage::Hello`].
    Info(Info),
    /// Answer to [`HostMessage::GetStatus`] (its `free_slots` acknowledges like an ack).
    Status(Status),
    /// Unrequested status at the telemetry rate.
    Telemetry(Status),
}

impl FirmwareMessage {
    /// The free keyframe slots the message reports, if it reports them.
    pub fn free_slots(&self) -> Option<u16> {
        match self {
            Self::Ack { free_slots } => Some(*free_slots),
            Self::Status(s) | Self::Telemetry(s) => Some(s.free_slots),
            Self::Info(_) | Self::Nak { .. } => None,
        }
    }
}

fn check(field: Field, ok: bool, problem: Problem) -> Result<(), ValueError> {
    if ok {
        Ok(())
    } else {
        Err(ValueError { field, problem })
    }
}

/// Finite and within `[lo, hi]`.
fn range(field: Field, x: f32, lo: f32, hi: f32) -> Result<(), ValueError> {
    check(field, x.is_finite(), Problem::NotFinite)?;
    check(field, lo <= x && x <= hi, Problem::OutOfRange)
}

fn all_range(field: Field, xs: &[f32], limit: f32) -> Result<(), ValueError> {
    xs.iter().try_for_each(|&x| range(field, x, -limit, limit))
}

fn unit(field: Field, xs: &[f32]) -> Result<(), ValueError> {
    all_range(field, xs, 2.0)?;
    let norm = libm::sqrtf(xs.iter().map(|x| x * x).sum());
    check(field, libm::fabsf(norm - 1.0) <= QUATERNION_TOLERANCE, Problem::NotUnit)
}

fn joints(field: Field, xs: &[f32], limit: f32) -> Result<(), ValueError> {
    check(field, !xs.is_empty(), Problem::Count)?;
    all_range(field, xs, limit)
}

impl Timing {
    fn validate(&self) -> Result<(), ValueError> {
        match *self {
            Self::Duration(t) => {
                range(Field::Duration, t, 0.0, MAX_TIME).and(check(Field::Duration, t > 0.0, Problem::OutOfRange))
            }
            Self::MaxSpeed(v) => {
                range(Field::Speed, v, 0.0, MAX_SPEED).and(check(Field::Speed, v > 0.0, Problem::OutOfRange))
            }
        }
    }
}

impl CartesianTarget {
    fn validate(&self) -> Result<(), ValueError> {
        all_range(Field::Position, &self.position, MAX_REACH)?;
        self.orientation.as_ref().map_or(Ok(()), |q| unit(Field::Orientation, q))
    }
}

/// An opening or effort: a finite percentage (an effort above 0).
fn percent(x: f32, above_zero: bool) -> Result<(), ValueError> {
    range(Field::Gripper, x, 0.0, 100.0)?;
    check(Field::Gripper, !above_zero || x > 0.0, Problem::OutOfRange)
}

impl GripperConfig {
    fn validate(&self) -> Result<(), ValueError> {
        check(Field::Gripper, self.id <= 252 && self.closed != self.open, Problem::OutOfRange)?;
        percent(self.effort, true)?;
        range(Field::Gripper, self.speed, 0.0, 1e4)?;
        check(Field::Gripper, self.speed > 0.0, Problem::OutOfRange)
    }
}

impl JointKeyframe {
    fn validate(&self) -> Result<(), ValueError> {
        range(Field::Time, self.time, 0.0, MAX_TIME)?;
        self.gripper.map_or(Ok(()), |g| percent(g, false))?;
        joints(Field::Joints, &self.positions, MAX_JOINT_VALUE)?;
        if let Some(v) = &self.velocities {
            check(Field::Velocities, v.len() == self.positions.len(), Problem::Count)?;
            all_range(Field::Velocities, v, MAX_JOINT_VELOCITY)?;
        }
        Ok(())
    }
}

impl JointConfig {
    fn validate(&self) -> Result<(), ValueError> {
        all_range(Field::Origin, &self.origin_xyz, MAX_REACH)?;
        all_range(Field::Origin, &self.origin_rpy, 2.0 * core::f32::consts::PI)?;
        unit(Field::Axis, &self.axis)?;
        range(Field::Limits, self.lower, -MAX_JOINT_VALUE, MAX_JOINT_VALUE)?;
        range(Field::Limits, self.upper, -MAX_JOINT_VALUE, MAX_JOINT_VALUE)?;
        check(Field::Limits, self.lower < self.upper, Problem::OutOfRange)?;
        range(Field::Limits, self.max_velocity, 0.0, MAX_JOINT_VELOCITY)?;
        range(Field::Limits, self.max_acceleration, 0.0, 1e6)?;
        check(Field::Limits, self.max_velocity > 0.0 && self.max_acceleration > 0.0, Problem::OutOfRange)?;
        // Dynamixel Protocol 2.0 reserves ids above 252 (0xFE is broadcast on both buses).
        check(Field::Servo, self.servo.id <= 252, Problem::OutOfRange)?;
        check(Field::Servo, self.servo.ticks_per_revolution > 0, Problem::OutOfRange)?;
        check(Field::Servo, self.servo.min_ticks < self.servo.max_ticks, Problem::OutOfRange)
    }
}

fn capsule(field: Field, a: &[f32; 3], b: &[f32; 3], radius: f32) -> Result<(), ValueError> {
    all_range(field, a, MAX_REACH)?;
    all_range(field, b, MAX_REACH)?;
    range(field, radius, 0.0, MAX_REACH)
}

impl BodyConfig {
    fn validate(&self) -> Result<(), ValueError> {
        check(Field::Body, self.frame.is_none_or(|f| usize::from(f) < MAX_JOINTS), Problem::OutOfRange)?;
        capsule(Field::Body, &self.a, &self.b, self.radius)
    }
}

impl ObstacleShape {
    fn validate(&self) -> Result<(), ValueError> {
        match self {
            Self::Capsule { a, b, radius } => capsule(Field::Obstacle, a, b, *radius),
            Self::Box { centre, rotation, half } => {
                all_range(Field::Obstacle, centre, MAX_REACH)?;
                unit(Field::Obstacle, rotation)?;
                all_range(Field::Obstacle, half, MAX_REACH)?;
                check(Field::Obstacle, half.iter().all(|h| *h > 0.0), Problem::OutOfRange)
            }
            Self::HalfSpace { normal, offset } => {
                unit(Field::Obstacle, normal)?;
                range(Field::Obstacle, *offset, -MAX_REACH, MAX_REACH)
            }
        }
    }
}

impl CollisionPart {
    fn validate(&self) -> Result<(), ValueError> {
        let ok = match *self {
            Self::Body(i) => usize::from(i) < MAX_BODIES,
            Self::Obstacle(o) => usize::from(o) < MAX_OBSTACLES,
        };
        check(Field::Allowed, ok, Problem::OutOfRange)
    }
}

impl HostMessage {
    /// Checks every value the message carries on its own (not against the arm): finite, in
    /// range, counts within [`MAX_JOINTS`] and consistent, quaternions and axes unit.
    pub fn validate(&self) -> Result<(), ValueError> {
        match self {
            Self::Hello { .. }
            | Self::ConfigureCommit
            | Self::ConfigureDigest { .. }
            | Self::UseBuiltinArm
            | Self::Torque { .. }
            | Self::Start
            | Self::Pause
            | Self::Stop
            | Self::EStop { .. }
            | Self::GetStatus
            | Self::Ping => Ok(()),
            Self::ConfigureBegin { name, joints, tool_xyz, tool_rpy, .. } => {
                check(Field::Name, !name.is_empty(), Problem::Count)?;
                check(Field::JointCount, (1..=MAX_JOINTS as u8).contains(joints), Problem::OutOfRange)?;
                all_range(Field::Origin, tool_xyz, MAX_REACH)?;
                all_range(Field::Origin, tool_rpy, 2.0 * core::f32::consts::PI)
            }
            Self::ConfigureJoint { index, joint } => {
                check(Field::JointIndex, usize::from(*index) < MAX_JOINTS, Problem::OutOfRange)?;
                joint.validate()
            }
            Self::MoveTo { target, timing, .. } => {
                target.validate()?;
                timing.validate()
            }
            Self::MoveJoints { positions, timing } => {
                joints(Field::Joints, positions, MAX_JOINT_VALUE)?;
                timing.validate()
            }
            Self::PushKeyframe(k) => k.validate(),
            Self::PushCartesianKeyframe(k) => {
                range(Field::Time, k.time, 0.0, MAX_TIME)?;
                k.gripper.map_or(Ok(()), |g| percent(g, false))?;
                k.target.validate()
            }
            Self::ConfigureGripper(g) => g.validate(),
            Self::Gripper { opening, effort } => {
                percent(*opening, false)?;
                effort.map_or(Ok(()), |e| percent(e, true))
            }
            Self::SetTelemetry { rate_hz } => check(Field::Rate, *rate_hz <= MAX_TELEMETRY_HZ, Problem::OutOfRange),
            Self::ConfigureBus { baud, .. } => {
                check(Field::Bus, (MIN_BAUD..=MAX_BAUD).contains(baud), Problem::OutOfRange)
            }
            Self::ConfigureCollision { margin, .. } => range(Field::Margin, *margin, 0.0, MAX_MARGIN),
            Self::ConfigureBody { index, body } => {
                check(Field::Body, usize::from(*index) < MAX_BODIES, Problem::OutOfRange)?;
                body.validate()
            }
            Self::ConfigureObstacle { index, shape } => {
                check(Field::Obstacle, usize::from(*index) < MAX_OBSTACLES, Problem::OutOfRange)?;
                shape.validate()
            }
            Self::ConfigureAllowed { body, other } => {
                check(Field::Allowed, usize::from(*body) < MAX_BODIES, Problem::OutOfRange)?;
                other.validate()
            }
            Self::SetGravity { joint, mass, com, compliance } => {
                check(Field::JointIndex, usize::from(*joint) < MAX_JOINTS, Problem::OutOfRange)?;
                range(Field::Gravity, *mass, 0.0, MAX_LINK_MASS)?;
                all_range(Field::Gravity, com, MAX_COM)?;
                range(Field::Gravity, *compliance, 0.0, MAX_COMPLIANCE)
            }
        }
    }

    /// Whether the message appends a keyframe (and so needs a free slot).
    pub fn is_keyframe_push(&self) -> bool {
        matches!(self, Self::PushKeyframe(_) | Self::PushCartesianKeyframe(_))
    }
}
