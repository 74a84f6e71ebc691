//! The commands the host link delivers, and their validation: a refused command changes nothing
//! (except that it proves the host alive).

use kinematics::ik::{IkConfig, IkProblem, IkStatus, Target};
use kinematics::nalgebra::{SVector, Vector3};
use kinematics::trajectory::{PlayerKeyframe, PushError};

use super::refusal::Refusal;
use super::{Controller, IkSummary, Mode, MoveOutcome, PathTaken, ToolGoal};
use crate::tracking::Tracker;

/// How fast the tool goes to a Cartesian goal.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Pace {
    /// Arrive after this many seconds (> 0), joint limits permitting.
    Duration(f32),
    /// Move the goal point at this speed, m/s (> 0), joint limits permitting.
    Speed(f32),
}

/// Which way the tool goes to a Cartesian goal.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ToolPath {
    /// The straight line; where it runs into the joint limits, the rest of the way by joints.
    #[default]
    Auto,
    /// The straight line only: where it runs into the joint limits, stop there.
    Line,
    /// By joints, to the solution found before moving.
    Joint,
}

/// A command from the host.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Command<const N: usize> {
    /// Torque on, holding the present position (refused if a joint reads beyond its limits). Also
    /// leaves an emergency stop.
    TorqueOn,
    /// Torque off: the arm goes limp. Drops any motion.
    TorqueOff,
    /// Move the joints to `q` (rad) in `duration` seconds, or in the least time the velocity and
    /// acceleration limits allow if that is longer; ends at rest.
    MoveJoints {
        /// Target joint values, inside the joint limits.
        q: [f32; N],
        /// Seconds (>= 0).
        duration: f32,
    },
    /// Move the tool to `position` (m, base frame), and to `orientation` (unit quaternion, w
    /// first) if given, along a straight line at the given pace.
    MoveTool {
        /// Target tool position.
        position: [f32; 3],
        /// Target tool orientation, w first; `None` leaves it free. On an arm of fewer than six
        /// moving joints, only its tilt: the turn about the base's z is free (see
        /// `Controller::tool_target`).
        orientation: Option<[f32; 4]>,
        /// How fast.
        pace: Pace,
        /// Which way.
        path: ToolPath,
    },
    /// Queue a keyframe. Its time is seconds on the playback clock, which starts at 0 when a
    /// trajectory starts from rest ([`Command::Start`]); while playing, keyframes append.
    PushKeyframe {
        /// The joints' keyframe.
        keyframe: PlayerKeyframe<f32, N>,
        /// The gripper's opening at the keyframe, percent (0 closed to 100 open); `None` leaves
        /// the gripper as the keyframes before put it.
        gripper: Option<f32>,
    },
    /// Queue a keyframe given as a tool pose: IK (with restarts, seeded by the previous keyframe
    /// so the arm keeps its posture) turns it into a joint keyframe with player-chosen velocity.
    PushToolKeyframe {
        /// Seconds on the playback clock, as for [`Command::PushKeyframe`].
        time: f32,
        /// Tool position (m, base frame).
        position: [f32; 3],
        /// Tool orientation, w first; `None` leaves it free. On an arm of fewer than six moving
        /// joints, only its tilt: the turn about the base's z is free.
        orientation: Option<[f32; 4]>,
        /// The gripper's opening, as for [`Command::PushKeyframe`].
        gripper: Option<f32>,
    },
    /// Drive the gripper to an opening (percent, 0 closed to 100 open) at its speed, and set its
    /// effort limit (percent of the servo's full torque or current, (0, 100]) if given.
    Gripper {
        /// Opening, percent.
        opening: f32,
        /// Effort limit, percent.
        effort: Option<f32>,
    },
    /// Start the queued trajectory, or resume a paused one.
    Start,
    /// Slow the playback to a standstill on its path (resume with [`Command::Start`]).
    Pause,
    /// Decelerate to a stop within the acceleration limits and hold; the queue is dropped.
    Stop,
    /// Emergency stop: hold where the arm is now, or turn the torque off.
    EStop {
        /// Turn the torque off instead of holding.
        torque_off: bool,
    },
    /// The host is alive (feeds the watchdog; every command does).
    HostAlive,
}

/// How far beyond its limits (rad) a joint may read at torque on and still be held (clamped onto
/// the limit): a servo resting on its limit reads a tick or two either side.
const HOLD_TOLERANCE: f32 = 0.02;

impl<const N: usize, const Q: usize> Controller<N, Q> {
    /// Carries out `cmd`, received at `now_us`; on refusal nothing changes.
    pub fn command(&mut self, cmd: Command<N>, now_us: u64) -> Result<(), Refusal> {
        self.last_host_us = now_us;
        let result = self.apply(cmd);
        if result.is_err() {
            self.counters.refusals = self.counters.refusals.saturating_add(1);
        }
        result
    }

    fn apply(&mut self, cmd: Command<N>) -> Result<(), Refusal> {
        match cmd {
            Command::HostAlive => Ok(()),
            Command::TorqueOn => {
                if !self.all_seen() {
                    return Err(Refusal::NoPosition);
                }
                if self.torque && self.mode != Mode::EStopped && self.pending_torque.is_none() {
                    return Ok(());
                }
                // Hold where the arm is: the servos get that goal before their torque comes on.
                // An arm moved by hand beyond its limits is refused: holding it there would
                // send a goal outside the limits, and pulling it back would jump.
                if let Some(joint) = (0..N).find(|&j| {
                    self.measured[j] < self.limits.lower[j] - HOLD_TOLERANCE
                        || self.measured[j] > self.limits.upper[j] + HOLD_TOLERANCE
                }) {
                    return Err(Refusal::OutOfRange { joint });
                }
                self.setpoint.position = self.clamped(&self.measured);
                self.setpoint.velocity = SVector::zeros();
                self.pending_torque = Some(true);
                self.enter_hold();
                if let Some(g) = self.gripper.as_mut() {
                    g.adopt();
                    g.rewrite_effort();
                }
                Ok(())
            }
            Command::TorqueOff => {
                self.pending_torque = Some(false);
                self.stop_gripper();
                if self.mode != Mode::EStopped {
                    self.mode = Mode::Idle;
                }
                self.tool = None;
                self.reset_player();
                Ok(())
            }
            Command::EStop { torque_off } => {
                self.mode = Mode::EStopped;
                self.tool = None;
                // Where the arm is, within the limits (a reading beyond them is a servo's noise
                // or a reply gone wrong, never a place to hold).
                self.setpoint.position = self.clamped(&self.measured);
                self.setpoint.velocity = SVector::zeros();
                self.hold = self.setpoint.position;
                self.reset_player();
                self.stop_gripper();
                if torque_off {
                    self.pending_torque = Some(false);
                }
                Ok(())
            }
            Command::MoveJoints { q, duration } => {
                self.move_joints(SVector::from(q), duration)?;
                self.last_move = Some(MoveOutcome::JOINTS);
                Ok(())
            }
            Command::MoveTool { position, orientation, pace, path } => {
                self.move_tool(position, orientation, pace, path)
            }
            Command::PushKeyframe { keyframe, gripper } => self.push_keyframe(keyframe, gripper),
            Command::PushToolKeyframe { time, position, orientation, gripper } => {
                self.push_tool_keyframe(time, position, orientation, gripper)
            }
            Command::Gripper { opening, effort } => {
                let gripper = self.gripper.as_ref().ok_or(Refusal::NoGripper)?;
                // Values first, so a bad one is reported as such whatever the state.
                let mut checked = gripper.clone();
                checked.command(opening, effort)?;
                self.ready()?;
                self.gripper = Some(checked);
                Ok(())
            }
            Command::Start => {
                self.ready()?;
                if self.mode == Mode::Playing {
                    self.play.paused = false;
                    return Ok(());
                }
                if self.player.queued() == 0 {
                    return Err(Refusal::WrongMode);
                }
                self.mode = Mode::Playing;
                self.tool = None;
                self.play = super::PlayClock { time: 0.0, rate: 1.0, paused: false, queued_fresh: false };
                Ok(())
            }
            Command::Pause => {
                if self.mode != Mode::Playing {
                    return Err(Refusal::WrongMode);
                }
                self.play.paused = true;
                Ok(())
            }
            Command::Stop => {
                match self.mode {
                    Mode::Playing | Mode::Tracking => self.begin_stop(),
                    Mode::Holding | Mode::Idle => self.reset_player(),
                    Mode::Stopping | Mode::EStopped => {}
                }
                Ok(())
            }
        }
    }

    /// `q` clamped into the joint limits.
    pub(super) fn clamped(&self, q: &SVector<f32, N>) -> SVector<f32, N> {
        q.zip_zip_map(&self.limits.lower, &self.limits.upper, super::limiter::within)
    }

    /// Refuses motion while e-stopped or limp.
    fn ready(&self) -> Result<(), Refusal> {
        if self.mode == Mode::EStopped {
            return Err(Refusal::EStopped);
        }
        if !self.torque && self.pending_torque != Some(true) {
            return Err(Refusal::TorqueOff);
        }
        Ok(())
    }

    fn check_joints(&self, q: &SVector<f32, N>) -> Result<(), Refusal> {
        if !q.iter().all(|x| x.is_finite()) {
            return Err(Refusal::NotFinite);
        }
        for j in 0..N {
            if q[j] < self.limits.lower[j] || q[j] > self.limits.upper[j] {
                return Err(Refusal::OutOfRange { joint: j });
            }
        }
        Ok(())
    }

    pub(super) fn move_joints(&mut self, q: SVector<f32, N>, duration: f32) -> Result<(), Refusal> {
        self.check_joints(&q)?;
        if !duration.is_finite() {
            return Err(Refusal::NotFinite);
        }
        if duration < 0.0 {
            return Err(Refusal::BadParameter);
        }
        self.ready()?;
        if let Some(contact) = self.target_contact(&q) {
            return Err(Refusal::Collision { contact });
        }
        let needed = self.limits.rest_to_rest_time(&self.setpoint.position, &q);
        let duration = duration.max(needed).max(self.config.period_us as f32 * 1e-6);
        let rest = Some(SVector::zeros());
        if self.mode == Mode::Playing {
            // From the player's present position and velocity: no jump.
            let keyframe = PlayerKeyframe { time: self.play.time + duration, position: q, velocity: rest };
            self.player.replace(&[keyframe]).map_err(refusal)?;
            self.play.paused = false;
        } else {
            self.reset_player();
            let keyframe = PlayerKeyframe { time: duration, position: q, velocity: rest };
            self.player.push(keyframe).map_err(refusal)?;
            self.play.rate = 1.0;
            self.mode = Mode::Playing;
            self.tool = None;
        }
        self.move_active = true;
        Ok(())
    }

    fn push_keyframe(&mut self, keyframe: PlayerKeyframe<f32, N>, gripper: Option<f32>) -> Result<(), Refusal> {
        self.check_joints(&keyframe.position)?;
        if let Some(pct) = gripper {
            super::gripper::check_percent(pct)?;
            if !self.gripper.as_ref().ok_or(Refusal::NoGripper)?.has_room() {
                return Err(Refusal::QueueFull);
            }
        }
        let velocity_ok = keyframe.velocity.as_ref().is_none_or(|v| v.iter().all(|x| x.is_finite()));
        if !keyframe.time.is_finite() || !velocity_ok {
            return Err(Refusal::NotFinite);
        }
        if let Some(v) = keyframe.velocity {
            if let Some(j) = (0..N).find(|&j| libm::fabsf(v[j]) > self.limits.max_velocity[j]) {
                return Err(Refusal::OutOfRange { joint: j });
            }
        }
        if self.mode == Mode::EStopped {
            return Err(Refusal::EStopped);
        }
        let fresh = self.mode != Mode::Playing && !self.play.queued_fresh;
        if fresh {
            // The first keyframe of a new trajectory: it starts from the setpoint, at rest. The
            // keyframe was checked above, so a fresh player accepts it.
            self.reset_player();
            self.play.queued_fresh = true;
        }
        self.player.push(keyframe).map_err(refusal)?;
        // Keyframes are a stream of their own now: a collision stop ends it, not the last move.
        self.move_active = false;
        self.queue_tail = keyframe.position;
        let play_time = self.play_time();
        if let (Some(pct), Some(g)) = (gripper, self.gripper.as_mut()) {
            // The gripper's track starts where the gripper is: at time 0 for a new trajectory,
            // at the playback time when keyframes append to a playing one.
            let anchor = if fresh || g.track_empty() { Some(if fresh { 0.0 } else { play_time }) } else { None };
            g.push(keyframe.time, pct, anchor);
        }
        self.counters.keyframes = self.counters.keyframes.wrapping_add(1);
        Ok(())
    }

    /// The IK target of a tool pose, refusing NaN and a zero quaternion.
    ///
    /// On an arm with fewer than six moving joints an orientation is a tilt
    /// ([`Target::Tilt`]): the tool tilted as the quaternion has it (its pitch and roll against
    /// the base's vertical), its turn about the base's z axis free. Such an arm (the SO-101 and
    /// Koch: a base yaw, three pitches and a wrist roll) cannot hold a full orientation while its
    /// pan turns, so a tool moved sideways with its orientation held would be unreachable at
    /// every step: the yaw has to follow the pan. This is what LeRobot's end-effector actions
    /// (position steps, the orientation held) need. A six-joint arm keeps the full pose.
    fn tool_target(&self, position: [f32; 3], orientation: Option<[f32; 4]>) -> Result<Target<f32>, Refusal> {
        if !position.iter().all(|x| x.is_finite()) || !orientation.iter().flatten().all(|x| x.is_finite()) {
            return Err(Refusal::NotFinite);
        }
        match orientation {
            Some(quaternion) => {
                let pose = Target::pose_wxyz(position, quaternion).ok_or(Refusal::BadParameter)?;
                Ok(if self.chain.moving_joints() < 6 { pose.tilt_only() } else { pose })
            }
            None => Ok(Target::Position(Vector3::from(position))),
        }
    }

    /// Solves `target` from `seed` with restarts, within the limits; refuses it if IK does not
    /// converge, so nothing unreachable is ever accepted.
    fn solve_reachable(&mut self, target: Target<f32>, seed: SVector<f32, N>) -> Result<SVector<f32, N>, Refusal> {
        let config = IkConfig {
            max_iterations: self.config.ik_check_iterations,
            attempt_iterations: self.config.ik_check_iterations.div_ceil(4).max(1),
            max_restarts: 8,
            ..IkConfig::default()
        };
        let solution = self.chain.solve(&IkProblem { target, seed, config });
        self.last_ik = Some(IkSummary::of(&solution));
        if solution.status != IkStatus::Converged {
            return Err(Refusal::Unreachable { position_error: solution.position_error });
        }
        Ok(solution.q)
    }

    /// Where the tool is at joint values `q`. Through [`Chain::forward`], which IK runs anyway,
    /// rather than the leaner `Chain::tool_pose`: this is called once per move and once on
    /// arrival, and a second copy of forward kinematics would cost 1 KB of flash.
    pub(super) fn tool_position(&self, q: &SVector<f32, N>) -> Vector3<f32> {
        self.chain.forward(q).tool.translation
    }

    fn move_tool(
        &mut self,
        position: [f32; 3],
        orientation: Option<[f32; 4]>,
        pace: Pace,
        path: ToolPath,
    ) -> Result<(), Refusal> {
        let target = self.tool_target(position, orientation)?;
        let (value, is_speed) = match pace {
            Pace::Duration(d) => (d, false),
            Pace::Speed(s) => (s, true),
        };
        if !value.is_finite() {
            return Err(Refusal::NotFinite);
        }
        if value <= 0.0 {
            return Err(Refusal::BadParameter);
        }
        self.ready()?;
        // Refuse what IK cannot reach from here, with restarts, before anything moves; the
        // solution is where the arm goes by joints if the line turns out to be blocked.
        let solution = self.solve_reachable(target, self.setpoint.position)?;
        // A target whose solution is in contact is refused before anything moves. (Another
        // solution might be free; the host's planner looks for one.)
        if let Some(contact) = self.target_contact(&solution) {
            return Err(Refusal::Collision { contact });
        }
        let start = self.tool_position(&self.setpoint.position);
        let distance = (target.position() - start).norm();
        let speed = if is_speed { value } else { (distance / value).max(1e-6) };
        if path == ToolPath::Joint {
            // At the line's pace, or as fast as the limits allow if that is slower.
            self.move_joints(solution, distance / speed)?;
            self.last_move = Some(MoveOutcome::JOINTS);
            return Ok(());
        }
        self.reset_player();
        self.tracker = Tracker::new(self.setpoint.position, self.config.ik_iterations_per_tick);
        self.tool =
            Some(ToolGoal { target, via: start, speed, solution, best: f32::INFINITY, stalled: 0.0, path, start });
        self.mode = Mode::Tracking;
        self.move_active = true;
        self.last_move = Some(MoveOutcome { path: PathTaken::Line, blocked_at: None, line_length: distance });
        Ok(())
    }

    fn push_tool_keyframe(
        &mut self,
        time: f32,
        position: [f32; 3],
        orientation: Option<[f32; 4]>,
        gripper: Option<f32>,
    ) -> Result<(), Refusal> {
        let target = self.tool_target(position, orientation)?;
        if let Some(pct) = gripper {
            super::gripper::check_percent(pct)?;
            self.gripper.as_ref().ok_or(Refusal::NoGripper)?;
        }
        if !time.is_finite() {
            return Err(Refusal::NotFinite);
        }
        if self.mode == Mode::EStopped {
            return Err(Refusal::EStopped);
        }
        let fresh = self.mode != Mode::Playing && !self.play.queued_fresh;
        let seed = if fresh { self.setpoint.position } else { self.queue_tail };
        let q = self.solve_reachable(target, seed)?;
        self.push_keyframe(PlayerKeyframe { time, position: q, velocity: None }, gripper)
    }
}

fn refusal(e: PushError) -> Refusal {
    match e {
        PushError::QueueFull => Refusal::QueueFull,
        PushError::NonFinite => Refusal::NotFinite,
        PushError::TimeNotIncreasing => Refusal::TimeNotIncreasing,
    }
}
