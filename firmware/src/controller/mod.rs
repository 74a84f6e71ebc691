//! The control loop: a sans-IO state machine stepped by a fixed-rate tick.
//!
//! Each [`Controller::tick`] reads every present position in one sync read, computes the next
//! setpoint for the mode (hold, trajectory player, Cartesian tracking with warm-started IK, brake),
//! passes it through the [`limiter`] (joint range, velocity and acceleration limits), maps it to
//! ticks and sends every goal in one sync write. [`Controller::command`] is what the host link
//! calls: it validates first and changes nothing when it refuses. Bus writes that a command needs
//! (torque on or off) happen on the next tick, so a command never touches the bus.
//!
//! Time comes in as microseconds on the caller's monotonic clock; the loop's work time is read
//! from the bus master's clock at the end of the tick.
//!
//! # Safety properties
//! - Every goal sent lies inside the joint's limits and the servo's tick range, and differs from
//!   the previous one by at most `max_velocity * period`: the limiter runs on every mode's output.
//!   With gravity compensation ([`gravity`]) the goal is the setpoint plus an offset that changes
//!   by at most `gravity::MAX_SLEW * period` more, within the same limits.
//! - When the host falls silent for [`Config::watchdog_ms`] while the arm moves on its own, the
//!   arm decelerates within the acceleration limits and holds.
//!
//! # Panics
//! Nothing here panics, allocates or loops without a bound.

pub mod collision;
mod command;
mod config;
pub mod gravity;
pub mod gripper;
mod health;
pub mod limiter;
mod refusal;
mod tick;
#[cfg(test)]
mod tool_steps;

pub use collision::{ArmScene, CollisionStop, Guard, MAX_BODIES, MAX_OBSTACLES};
pub use command::{Command, Pace, ToolPath};
pub use config::{joint_limits, minimum_period_us, Config, ConfigError};
pub use gripper::{GripperConfig, GripperState};
pub use health::{Counters, Fault, ServoHealth, TickReport};
pub use refusal::Refusal;

use kinematics::ik::Target;
use kinematics::nalgebra::{SVector, Vector3};
use kinematics::trajectory::{JointLimits, Player};
use kinematics::Chain;

use crate::bus::cycle::ServoGroup;
use crate::bus::mapping::JointMapping;
use crate::bus::master::MAX_GROUP;
use crate::bus::table::Model;
use crate::tracking::Tracker;
use limiter::Setpoint;

/// What the controller is doing.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    /// Torque off: the servos are limp; the setpoint follows the measured positions.
    Idle,
    /// Holding the setpoint.
    Holding,
    /// Playing the keyframe queue (or a joint move), possibly paused.
    Playing,
    /// Moving the tool toward a Cartesian goal.
    Tracking,
    /// Decelerating to a stop within the acceleration limits, then holding.
    Stopping,
    /// Emergency stop: holding where the arm was, or torque off. Only torque on leaves it.
    EStopped,
}

/// The playback clock of the player: seconds since the trajectory started, advanced at a rate
/// that ramps to 0 on pause and back to 1 on start, so pausing slows the motion down smoothly.
#[derive(Clone, Copy, Debug, PartialEq)]
struct PlayClock {
    time: f32,
    rate: f32,
    paused: bool,
    /// A new trajectory is being queued while not playing; it starts at time 0 on start.
    queued_fresh: bool,
}

/// The outcome of the controller's last IK solve (accepting a Cartesian goal or keyframe, or a
/// tracking tick).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IkSummary {
    /// It converged within tolerance.
    pub converged: bool,
    /// Iterations spent.
    pub iterations: u32,
    /// Position error left, m.
    pub position_error: f32,
    /// Orientation error left, rad (0 for a position-only target).
    pub orientation_error: f32,
}

impl IkSummary {
    fn of<const N: usize>(solution: &kinematics::ik::IkSolution<f32, N>) -> Self {
        Self {
            converged: solution.status == kinematics::ik::IkStatus::Converged,
            iterations: solution.iterations,
            position_error: solution.position_error,
            orientation_error: solution.orientation_error,
        }
    }
}

/// The way the tool went on the last move (the link reports it as its `PathTaken`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PathTaken {
    /// Along the straight line, not given up: under way, arrived, or ended by a stop.
    Line,
    /// Along the line until it was blocked ([`ToolPath::Auto`]), then by joints.
    LineThenJoints,
    /// By joints from the start ([`Command::MoveJoints`], or [`ToolPath::Joint`]).
    Joints,
    /// Along the line until it was blocked ([`ToolPath::Line`]), then stopped there.
    LineStopped,
    /// Stopped short of a contact by the collision check ([`Controller::collision`] names it).
    CollisionStopped,
}

/// The last move accepted by [`Controller::command`] and how it went, kept until the next move
/// (keyframes leave it as it is): a host reads it instead of inferring the way from counters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MoveOutcome {
    /// The way it went.
    pub path: PathTaken,
    /// Where the line was given up (m from its start, within `0..=line_length`): the tool at
    /// the tracker's last solution, projected onto the line. `Some` exactly when the line was
    /// given up.
    pub blocked_at: Option<f32>,
    /// The line's length (m), from the tool at acceptance to the target; 0 for a joint move.
    pub line_length: f32,
}

impl MoveOutcome {
    /// A move by joints from the start.
    const JOINTS: Self = Self { path: PathTaken::Joints, blocked_at: None, line_length: 0.0 };
}

impl PlayClock {
    /// At time 0, not running.
    const STOPPED: Self = Self { time: 0.0, rate: 0.0, paused: false, queued_fresh: false };
}

/// A Cartesian goal and the point moving toward it at the requested speed, which IK follows.
#[derive(Clone, Copy, Debug, PartialEq)]
struct ToolGoal<const N: usize> {
    target: Target<f32>,
    via: Vector3<f32>,
    speed: f32,
    /// The joints that reach the target, found before moving: where a joint-space move goes
    /// when the straight line cannot be followed (it runs into the joint limits).
    solution: SVector<f32, N>,
    /// The least the tool has had left to go so far (m), and the time since that last shrank (s).
    best: f32,
    stalled: f32,
    /// What to do when the line is blocked: finish by joints ([`ToolPath::Auto`]) or stop.
    path: ToolPath,
    /// Where the tool was when the move was accepted: the line's start, from which the place
    /// where it is given up is measured.
    start: Vector3<f32>,
}

/// The control loop of an arm of `N` joints with a keyframe queue of `Q` keyframes.
#[derive(Clone, Debug)]
pub struct Controller<const N: usize, const Q: usize> {
    chain: Chain<f32, N>,
    mappings: [JointMapping; N],
    group: ServoGroup<N>,
    player: Player<f32, N, Q>,
    tracker: Tracker<f32, N>,
    limits: JointLimits<f32, N>,
    config: Config,
    mode: Mode,
    torque: bool,
    /// Whether the servos' torque state has been read (or set by a command) since start: the
    /// servos may have been left torqued by a previous run (a board reset, or the PC's core that
    /// ended with the last command), and the controller takes over what they hold.
    torque_known: bool,
    /// A torque change requested by a command, written on the next tick.
    pending_torque: Option<bool>,
    /// Reads left to confirm the last torque write (`CONFIRM_TRIES` in tick.rs after a write, 0
    /// once confirmed): a sync write has no reply, and a line that loses it would leave the servos
    /// limp (or torqued) while the controller thinks otherwise.
    torque_unconfirmed: u8,
    setpoint: Setpoint<N>,
    hold: SVector<f32, N>,
    measured: SVector<f32, N>,
    present_ticks: [i32; N],
    goal_ticks: [i32; N],
    /// Joints whose position has been read at least once (bit per joint).
    seen: u32,
    play: PlayClock,
    tool: Option<ToolGoal<N>>,
    /// Per-joint deceleration of the brake in progress (rad/s²).
    brake: SVector<f32, N>,
    /// The brake's own velocity profile (rad/s), falling by `brake` each tick to exactly zero.
    /// Not the setpoint's velocity: that is measured from positions one f32 step apart, so a
    /// joint creeping by one rounding step per tick would never read below it, and a brake
    /// driven by it would never end.
    braking: SVector<f32, N>,
    last_host_us: u64,
    last_tick_us: Option<u64>,
    counters: Counters,
    health: [ServoHealth; N],
    last_ik: Option<IkSummary>,
    /// Joint values of the last keyframe queued (the setpoint when none is): the seed of the next
    /// Cartesian keyframe's IK.
    queue_tail: SVector<f32, N>,
    /// The gripper, if the arm has one.
    gripper: Option<gripper::Gripper<Q>>,
    /// The last move accepted and how it went.
    last_move: Option<MoveOutcome>,
    /// The last move accepted is still under way (a collision stop then ends it).
    move_active: bool,
    /// The collision scene every goal is checked against, and the last stop.
    guard: Guard,
    /// Gravity compensation: what the links weigh, how far each servo gives, and the offsets the
    /// goals carry ([`gravity`]).
    gravity: gravity::Gravity<N>,
}

impl<const N: usize, const Q: usize> Controller<N, Q> {
    /// A controller for `chain`, whose joint `j` is driven by the servo of `mappings[j]` (all of
    /// `model`), enforcing `limits` (build them with [`joint_limits`]; the period is checked
    /// against the bus with [`minimum_period_us`] by the caller, who knows the bus). It starts
    /// idle: torque stays off until [`Command::TorqueOn`].
    pub fn new(
        chain: Chain<f32, N>,
        mappings: [JointMapping; N],
        model: &'static Model,
        limits: JointLimits<f32, N>,
        config: Config,
    ) -> Result<Self, ConfigError> {
        let mut controller = Self::blank(model, config);
        controller.configure(&chain, &mappings, model, &limits, None, config)?;
        Ok(controller)
    }

    /// A controller without an arm: a motionless chain, no servo on the bus, idle. Built without
    /// a check that could fail, so that a firmware can build it once, in place, in static memory
    /// ([`Controller::blank_at`]), and [`Controller::configure`] it there for each arm it is given.
    pub fn blank(model: &'static Model, config: Config) -> Self {
        let mut slot = core::mem::MaybeUninit::uninit();
        // SAFETY: the pointer is the local slot's, valid and aligned; `blank_at` initialises it whole.
        #[allow(unsafe_code)]
        unsafe {
            Self::blank_at(slot.as_mut_ptr(), model, config);
            slot.assume_init()
        }
    }

    /// [`Controller::blank`] written field by field at `at`, never whole on the stack (see
    /// [`crate::place`]).
    ///
    /// # Safety
    /// `at` must be valid for writes and aligned. Every field is written (the macro's struct
    /// literal makes a missing one a compile error); nothing is read or dropped.
    #[allow(unsafe_code)]
    pub(crate) unsafe fn blank_at(at: *mut Self, model: &'static Model, config: Config) {
        let zero = SVector::zeros();
        crate::place::place_fields!(at: Self {
            chain: Chain::motionless(),
            mappings: [JointMapping::centred(0, model.ticks_per_revolution); N],
            group: ServoGroup { servos: 0, ..ServoGroup::new(model, [0; N]) },
            player: Player::still(),
            tracker: Tracker::new(zero, config.ik_iterations_per_tick),
            limits: JointLimits::still(),
            config: config,
            mode: Mode::Idle,
            torque: false,
            torque_known: false,
            pending_torque: None,
            torque_unconfirmed: 0,
            setpoint: Setpoint { position: zero, velocity: zero },
            hold: zero,
            measured: zero,
            present_ticks: [0; N],
            goal_ticks: [0; N],
            seen: 0,
            play: PlayClock::STOPPED,
            tool: None,
            brake: zero,
            braking: zero,
            last_host_us: 0,
            last_tick_us: None,
            counters: Counters::default(),
            health: [ServoHealth::default(); N],
            last_ik: None,
            queue_tail: zero,
            gripper: None,
            last_move: None,
            move_active: false,
            gravity: gravity::Gravity::none(),
        } in place {
            guard: Guard::empty() => |guard| Guard::empty_at(guard),
        });
    }

    /// Makes this the controller of another arm, in place: what [`Controller::new`] (and
    /// [`Controller::with_gripper`]) would build, without a second controller on the stack.
    /// Everything is checked first; a refused arm changes nothing. The new arm starts idle, its
    /// torque off until [`Command::TorqueOn`], its counters at zero.
    pub fn configure(
        &mut self,
        chain: &Chain<f32, N>,
        mappings: &[JointMapping; N],
        model: &'static Model,
        limits: &JointLimits<f32, N>,
        gripper: Option<GripperConfig>,
        config: Config,
    ) -> Result<(), ConfigError> {
        if N > MAX_GROUP {
            return Err(ConfigError::TooManyJoints);
        }
        if config.period_us == 0 {
            return Err(ConfigError::PeriodTooShort { minimum_us: 1 });
        }
        if let Err(kinematics::trajectory::LimitError::InvalidLimits { joint }) = limits.validate() {
            return Err(ConfigError::BadLimits { joint });
        }
        // The arm's joints come first; fixed joints after them pad a build for more joints than
        // the arm has, and have no servo. A fixed joint before a moving one would leave that one
        // without a servo in the group.
        let servos = chain.moving_joints();
        if let Some(joint) = chain.joints().iter().skip(servos).position(|j| j.kind != kinematics::JointKind::Fixed) {
            return Err(ConfigError::BadLimits { joint: servos + joint });
        }
        if let Some(g) = &gripper {
            let joints = mappings.iter().take(servos);
            if !g.valid() || joints.clone().any(|m| m.id == g.id) || N + 1 > MAX_GROUP {
                return Err(ConfigError::BadGripper);
            }
        }
        let start = chain.middle().zip_zip_map(&limits.lower, &limits.upper, limiter::within);
        // The last check (a start that is not finite): nothing has changed before it.
        self.player.reset(start, limits).map_err(|_| ConfigError::BadLimits { joint: 0 })?;
        self.chain = *chain;
        self.mappings = *mappings;
        self.group = ServoGroup { servos, ..ServoGroup::new(model, mappings.map(|m| m.id)) };
        self.tracker = Tracker::new(start, config.ik_iterations_per_tick);
        self.limits = *limits;
        self.config = config;
        self.mode = Mode::Idle;
        self.torque = false;
        self.torque_known = false;
        self.pending_torque = None;
        self.torque_unconfirmed = 0;
        self.setpoint = Setpoint { position: start, velocity: SVector::zeros() };
        self.hold = start;
        self.measured = start;
        // Each servo's zero until it is read; a padding joint's for good (its angle stays zero).
        self.present_ticks = mappings.map(|m| m.zero);
        self.goal_ticks = [0; N];
        self.seen = 0;
        self.play = PlayClock::STOPPED;
        self.tool = None;
        self.brake = SVector::zeros();
        self.braking = SVector::zeros();
        self.last_host_us = 0;
        self.last_tick_us = None;
        self.counters = Counters::default();
        self.health = [ServoHealth::default(); N];
        self.last_ik = None;
        self.queue_tail = start;
        self.gripper = gripper.map(gripper::Gripper::new);
        self.last_move = None;
        self.move_active = false;
        self.guard.clear();
        // A new arm's links are not the old one's: the host sends them again.
        self.gravity = gravity::Gravity::none();
        Ok(())
    }

    /// The same controller with a gripper (a servo of the joints' model, not one of theirs).
    pub fn with_gripper(mut self, config: GripperConfig) -> Result<Self, ConfigError> {
        let (chain, mappings, limits) = (self.chain, self.mappings, self.limits);
        self.configure(&chain, &mappings, self.group.model, &limits, Some(config), self.config)?;
        Ok(self)
    }

    /// The gripper's configuration, if the arm has one.
    pub fn gripper_config(&self) -> Option<&GripperConfig> {
        self.gripper.as_ref().map(|g| g.config())
    }

    /// The gripper's state, if the arm has one.
    pub fn gripper(&self) -> Option<GripperState> {
        self.gripper.as_ref().map(|g| g.state())
    }

    /// Joint `joint`'s link and servo for gravity compensation ([`gravity`]); `false` for a joint
    /// beyond the arm's. Taken while the arm moves or holds: the goals' offsets move to it at
    /// [`gravity::MAX_SLEW`].
    pub fn set_gravity(&mut self, joint: usize, part: gravity::GravityJoint) -> bool {
        joint < self.joints() && self.gravity.set(joint, part)
    }

    /// The mode.
    pub fn mode(&self) -> Mode {
        self.mode
    }

    /// Whether playback is paused (or slowing down to a pause).
    pub fn paused(&self) -> bool {
        self.mode == Mode::Playing && self.play.paused
    }

    /// Whether the servos' torque is on (as last written).
    pub fn torque(&self) -> bool {
        self.torque
    }

    /// Whether a torque change a command asked for is still to be written (on the next tick).
    pub fn torque_pending(&self) -> bool {
        self.pending_torque.is_some()
    }

    /// Whether the servos' torque state is known yet: read from the servos once every position
    /// has been seen, or set by a torque command. Until then [`Controller::torque`] says off.
    pub fn torque_known(&self) -> bool {
        self.torque_known
    }

    /// The counters.
    pub fn counters(&self) -> &Counters {
        &self.counters
    }

    /// Each servo's bus record, joint by joint.
    pub fn health(&self) -> &[ServoHealth; N] {
        &self.health
    }

    /// The last measured joint values (rad); a joint whose servo did not answer keeps its last.
    pub fn measured(&self) -> &SVector<f32, N> {
        &self.measured
    }

    /// The setpoint sent on the last tick (rad) and its velocity (rad/s).
    pub fn setpoint(&self) -> &Setpoint<N> {
        &self.setpoint
    }

    /// The enforced limits.
    pub fn limits(&self) -> &JointLimits<f32, N> {
        &self.limits
    }

    /// The chain.
    pub fn chain(&self) -> &Chain<f32, N> {
        &self.chain
    }

    /// The configuration.
    pub fn config(&self) -> &Config {
        &self.config
    }

    /// Keyframes waiting in the player's queue.
    pub fn queued(&self) -> usize {
        self.player.queued()
    }

    /// The playback clock in the sender's timeline: seconds since the trajectory started, less
    /// the time late keyframes shifted it by ([`kinematics::trajectory::Player::shift`]). A
    /// keyframe pushed with this time is due now.
    pub fn play_time(&self) -> f32 {
        self.play.time - self.player.shift()
    }

    /// The playback clock at `now_us`, between ticks: the time since the last tick added at the
    /// playback rate, up to one period (a late tick advances the clock by no more). A host that
    /// times keyframes by it needs the clock between ticks: sampled at the tick's own resolution,
    /// it would be up to a period behind.
    pub fn play_time_at(&self, now_us: u64) -> f32 {
        let period = self.config.period_us;
        let since = self.last_tick_us.map_or(0, |t| now_us.saturating_sub(t).min(u64::from(period)) as u32);
        self.play_time() + since as f32 * 1e-6 * self.play.rate
    }

    /// Room left in the keyframe queue: the joints' and, with a gripper, its track's, whichever
    /// is fuller (acks report it, so a host that keeps to it never has a gripper keyframe refused).
    pub fn free_slots(&self) -> usize {
        self.player.free_slots().min(self.gripper.as_ref().map_or(usize::MAX, |g| g.free_slots()))
    }

    /// Times the player ran out of keyframes while playing.
    pub fn underruns(&self) -> u32 {
        self.player.underruns()
    }

    /// The last IK solve, if any.
    pub fn last_ik(&self) -> Option<IkSummary> {
        self.last_ik
    }

    /// The last move accepted and how it went, if there was one since the arm was configured.
    pub fn last_move(&self) -> Option<MoveOutcome> {
        self.last_move
    }

    /// The farthest the player braked past its last keyframe when keyframes ran out while moving,
    /// in the current or last playback (rad, largest joint; the player's count, which a new
    /// trajectory, a stop at rest, torque off or an e-stop start afresh). It went back to that
    /// keyframe afterwards: this says how far the arm overshot on the way.
    pub fn largest_pass(&self) -> f32 {
        self.player.largest_pass()
    }

    /// The arm's own joints: the first this many; the rest, up to `N`, pad the build (fixed
    /// joints, no servo, held at zero).
    pub fn joints(&self) -> usize {
        self.group.servos
    }

    /// The joint-to-servo mappings.
    pub fn mappings(&self) -> &[JointMapping; N] {
        &self.mappings
    }

    /// Every servo's position read at least once, the gripper's too.
    fn all_seen(&self) -> bool {
        let all = if N >= 32 { u32::MAX } else { (1u32 << N) - 1 };
        self.seen & all == all && self.gripper.as_ref().is_none_or(|g| g.seen())
    }

    /// A fresh player at rest at the setpoint, with an empty queue.
    fn reset_player(&mut self) {
        // In place: a second player on the stack would cost its whole queue. The limits were
        // checked when the arm was configured, and the setpoint is always finite.
        let _ = self.player.reset(self.setpoint.position, &self.limits);
        self.play = PlayClock::STOPPED;
        self.queue_tail = self.setpoint.position;
        if let Some(g) = self.gripper.as_mut() {
            g.clear_track();
        }
    }

    /// Freezes the gripper where it is (a stop of any kind).
    fn stop_gripper(&mut self) {
        if let Some(g) = self.gripper.as_mut() {
            g.stop();
        }
    }

    /// Holds the current setpoint from now on.
    fn enter_hold(&mut self) {
        self.mode = Mode::Holding;
        self.move_active = false;
        self.hold = self.setpoint.position;
        self.tool = None;
        self.reset_player();
    }

    /// Starts a time-synchronised brake from the setpoint's velocity: every joint decelerates at
    /// a constant rate within its limit and all stop together.
    fn begin_stop(&mut self) {
        let t = self.limits.stopping_time(&self.setpoint.velocity);
        (self.brake, self.braking) = if t > 0.0 && t.is_finite() {
            (self.setpoint.velocity / t, self.setpoint.velocity)
        } else {
            (SVector::zeros(), SVector::zeros())
        };
        self.mode = Mode::Stopping;
        self.tool = None;
        self.stop_gripper();
    }
}
