//! One control tick: read, compute, limit, write.

use embedded_hal::digital::OutputPin;
use embedded_io::{Read, ReadReady, Write};
use kinematics::ik::IkStatus;
use kinematics::nalgebra::SVector;
use kinematics::trajectory::State;

use super::health::{Fault, TickReport};
use super::limiter::{limit_step, Setpoint};
use super::{Controller, Mode, MoveOutcome, PathTaken, ToolGoal, ToolPath};

/// How long a Cartesian move may make no progress before it goes the rest of the way by joints
/// (s): a few ticks of IK that cannot follow the point are normal at a singularity's edge.
const STALL_TIME: f32 = 0.3;
/// The progress that counts within [`STALL_TIME`] (m), or half the line's pace over it if slower.
const STALL_PROGRESS: f32 = 1e-4;
/// Metres of progress a radian of orientation error counts as.
const STALL_LEVER: f32 = 0.1;
use crate::bus::cycle::ServoGroup;
use crate::bus::master::{Clock, Master};

/// Ticks between two reads of the gripper's load.
pub const LOAD_EVERY: u32 = 4;

/// Ticks that read the torque back after a torque write, at most: a servo that stays silent
/// (counted lost by the position reads) does not cost a second timeout on every tick for ever.
pub const CONFIRM_TRIES: u8 = 10;

impl<const N: usize, const Q: usize> Controller<N, Q> {
    /// Runs one control tick at `now_us` (the caller's clock, the same as the master's): sync read
    /// of present positions, setpoint of the mode, limits, sync write of goals.
    pub fn tick<P, D, C, const BUF: usize>(&mut self, master: &mut Master<P, D, C, BUF>, now_us: u64) -> TickReport
    where
        P: Read + Write + ReadReady,
        D: OutputPin,
        C: Clock,
    {
        let period = u64::from(self.config.period_us);
        let elapsed = self.last_tick_us.map(|t| now_us.saturating_sub(t));
        // A tick later than 1.5 periods skipped a slot.
        let mut late = elapsed.is_some_and(|e| 2 * e > 3 * period);
        // The limiter's step never covers more than one period, so a late tick cannot produce a
        // step beyond the velocity limit per period; the motion slows down instead.
        let dt = elapsed.map_or(period, |e| e.min(period)) as f32 * 1e-6;
        self.last_tick_us = Some(now_us);
        self.counters.ticks = self.counters.ticks.wrapping_add(1);
        let mut report = TickReport::new(self.mode);

        self.read_positions(master, &mut report);
        self.read_gripper_load(master);
        if !self.torque_known && self.pending_torque.is_none() && self.all_seen() {
            self.adopt_torque(master);
        }
        let mut switched_on = false;
        if let Some(on) = self.pending_torque {
            if self.write_torque(master, on) {
                self.pending_torque = None;
                self.torque_unconfirmed = CONFIRM_TRIES;
                switched_on = on;
            }
        } else if self.torque_unconfirmed > 0 {
            self.torque_unconfirmed -= 1;
            self.confirm_torque(master);
        }
        if self.torque {
            self.watchdog(now_us, &mut report);
            let (desired, velocity) = self.desired(dt, &mut report);
            let next = limit_step(&self.setpoint, &desired, &velocity, &self.limits, dt);
            self.setpoint = self.guarded(next, dt, &mut report);
            self.after_step();
            // The gripper's track is in the sender's timeline, as the joints' keyframes are.
            let playing = (self.mode == Mode::Playing).then_some(self.play_time());
            // The gripper's ramp starts a tick after its torque comes on: the goal written with
            // the torque a moment ago is where it stands, and a full step at once would be a
            // period's motion in a fraction of one. (The joints start from rest, limited by
            // their acceleration, so their first step is a small fraction of a tick.)
            if let Some(g) = self.gripper.as_mut().filter(|_| !switched_on) {
                g.step(dt, playing);
            }
            self.write_gripper_effort(master);
            report.wrote_goals = self.write_goals(master);
        } else {
            // Limp: the setpoint follows the arm, so torque on holds it where it is.
            self.setpoint = Setpoint { position: self.measured, velocity: SVector::zeros() };
        }

        let end = master.clock().now_us();
        let loop_us = u32::try_from(end.saturating_sub(now_us)).unwrap_or(u32::MAX);
        late |= u64::from(loop_us) > period;
        self.counters.last_loop_us = loop_us;
        self.counters.max_loop_us = self.counters.max_loop_us.max(loop_us);
        if late {
            self.counters.deadline_misses = self.counters.deadline_misses.saturating_add(1);
        }
        report.late = late;
        report.loop_us = loop_us;
        report.mode = self.mode;
        report
    }

    fn read_positions<P, D, C, const BUF: usize>(&mut self, master: &mut Master<P, D, C, BUF>, report: &mut TickReport)
    where
        P: Read + Write + ReadReady,
        D: OutputPin,
        C: Clock,
    {
        let item = self.group.model.items.present_position;
        let mut gripper_ticks = 0;
        let extra = self.gripper.as_ref().map(|g| (g.config().id, &mut gripper_ticks));
        let result = self.group.read_with(master, item, &mut self.present_ticks, extra);
        if result.is_err() {
            self.counters.bus_errors = self.counters.bus_errors.saturating_add(1);
        }
        if let Some(g) = self.gripper.as_mut() {
            if result.as_ref().is_ok_and(|r| r.answered & (1 << N) != 0) {
                g.observe(gripper_ticks);
            } else {
                self.counters.missing_replies = self.counters.missing_replies.saturating_add(1);
            }
        }
        for j in 0..N {
            let bit = 1u32 << j;
            let fault = match &result {
                Ok(r) if r.answered & bit != 0 => None,
                Ok(r) if r.failed & bit != 0 => Some(Fault::Refused),
                Ok(_) => Some(Fault::NoReply),
                Err(_) => Some(Fault::Port),
            };
            let health = &mut self.health[j];
            match fault {
                None => {
                    self.measured[j] = self.mappings[j].to_radians(self.present_ticks[j]);
                    self.seen |= bit;
                    if result.as_ref().is_ok_and(|r| r.alerts & bit != 0) {
                        health.alerts = health.alerts.saturating_add(1);
                    }
                    if health.lost {
                        health.lost = false;
                        health.recoveries = health.recoveries.saturating_add(1);
                        report.recovered |= bit;
                    }
                    health.consecutive = 0;
                }
                Some(fault) => {
                    health.missed = health.missed.saturating_add(1);
                    health.consecutive = health.consecutive.saturating_add(1);
                    health.last_fault = Some(fault);
                    self.counters.missing_replies = self.counters.missing_replies.saturating_add(1);
                    report.missing |= bit;
                    if !health.lost && health.consecutive >= self.config.lost_after {
                        health.lost = true;
                        report.lost |= bit;
                    }
                }
            }
        }
    }

    /// Reads the gripper's load every [`LOAD_EVERY`] ticks, in a read of its own: the joints' sync
    /// read stays as short as it was, and a grasp builds up over many ticks anyway.
    fn read_gripper_load<P, D, C, const BUF: usize>(&mut self, master: &mut Master<P, D, C, BUF>)
    where
        P: Read + Write + ReadReady,
        D: OutputPin,
        C: Clock,
    {
        let (Some(g), Some(force)) = (self.gripper.as_mut(), self.group.model.force) else { return };
        if !self.counters.ticks.is_multiple_of(LOAD_EVERY) {
            return;
        }
        // A sync read of the one servo, not a plain read: the same code as the joints' cycle, so
        // the firmware carries no second read path.
        let one = ServoGroup::new(self.group.model, [g.config().id]);
        let mut load = [0i32; 1];
        match one.read_all(master, force.present, &mut load) {
            Ok(report) if report.complete() => {
                g.observe_load(load[0] as f32 / f32::from(force.present_full.max(1)) * 100.0)
            }
            _ => self.counters.missing_replies = self.counters.missing_replies.saturating_add(1),
        }
    }

    /// Writes the gripper's effort limit when it changed (or torque came on).
    fn write_gripper_effort<P, D, C, const BUF: usize>(&mut self, master: &mut Master<P, D, C, BUF>)
    where
        P: Read + Write + ReadReady,
        D: OutputPin,
        C: Clock,
    {
        let (Some(g), Some(force)) = (self.gripper.as_mut(), self.group.model.force) else { return };
        let Some(effort) = g.take_effort() else { return };
        let value = (effort / 100.0 * f32::from(force.limit_full)) as i32;
        // A sync write of one record, as the goals go: no reply to wait for, no second write path.
        let one = ServoGroup::new(self.group.model, [g.config().id]);
        if one.write_all(master, force.limit, &[value]).is_ok() {
            g.effort_written();
        } else {
            self.counters.bus_errors = self.counters.bus_errors.saturating_add(1);
        }
    }

    /// Reads every servo's torque item once, at start: servos left torqued (by a run before a
    /// reset, or by the previous command of a PC-hosted core) are held where they are, so the
    /// controller neither reports a torqued arm as limp nor makes it jump. If only some are
    /// torqued, the rest are switched on too, their goals first: one arm, one state.
    fn adopt_torque<P, D, C, const BUF: usize>(&mut self, master: &mut Master<P, D, C, BUF>)
    where
        P: Read + Write + ReadReady,
        D: OutputPin,
        C: Clock,
    {
        let mut on = [0i32; N];
        match self.group.read_all(master, self.group.model.items.torque_enable, &mut on) {
            Ok(report) if report.complete() => {
                self.torque_known = true;
                // The padding joints' values are not read: only the servos' count.
                let servos = on.get(..self.group.servos).unwrap_or(&on);
                if servos.iter().all(|&v| v == 0) || self.mode == Mode::EStopped {
                    return;
                }
                self.setpoint = Setpoint { position: self.clamped(&self.measured), velocity: SVector::zeros() };
                self.enter_hold();
                if let Some(g) = self.gripper.as_mut() {
                    g.adopt();
                }
                // The gripper's torque was not read: written with the joints' to be sure.
                if servos.iter().all(|&v| v != 0) && self.gripper.is_none() {
                    self.torque = true;
                } else {
                    self.pending_torque = Some(true);
                }
            }
            // Someone did not answer: asked again next tick.
            Ok(_) => {}
            Err(_) => self.counters.bus_errors = self.counters.bus_errors.saturating_add(1),
        }
    }

    /// Reads back the torque item the last torque write set, the gripper's too: a servo that
    /// missed the write (its sync write lost on the line) is written again on the next tick. Until
    /// every servo has answered, it is asked again each tick, [`CONFIRM_TRIES`] times at most.
    fn confirm_torque<P, D, C, const BUF: usize>(&mut self, master: &mut Master<P, D, C, BUF>)
    where
        P: Read + Write + ReadReady,
        D: OutputPin,
        C: Clock,
    {
        let mut on = [0i32; N];
        let mut gripper_on = 0;
        let extra = self.gripper.as_ref().map(|g| (g.config().id, &mut gripper_on));
        let has_gripper = extra.is_some();
        let Ok(report) = self.group.read_with(master, self.group.model.items.torque_enable, &mut on, extra) else {
            self.counters.bus_errors = self.counters.bus_errors.saturating_add(1);
            return;
        };
        if !report.complete() {
            return;
        }
        let servos = on.get(..self.group.servos).unwrap_or(&on);
        let missed =
            servos.iter().any(|&v| (v != 0) != self.torque) || (has_gripper && (gripper_on != 0) != self.torque);
        self.torque_unconfirmed = 0;
        if missed {
            self.counters.bus_errors = self.counters.bus_errors.saturating_add(1);
            self.pending_torque = Some(self.torque);
        }
    }

    /// Writes the torque item of every servo; on torque on, the goals first, so that no servo
    /// starts toward a stale goal. True once written.
    fn write_torque<P, D, C, const BUF: usize>(&mut self, master: &mut Master<P, D, C, BUF>, on: bool) -> bool
    where
        P: Read + Write + ReadReady,
        D: OutputPin,
        C: Clock,
    {
        if on && !self.write_goals(master) {
            return false;
        }
        let item = self.group.model.items.torque_enable;
        let gripper = self.gripper.as_ref().map(|g| (g.config().id, i32::from(on)));
        let ok = self.group.write_with(master, item, &[i32::from(on); N], gripper).is_ok();
        if ok {
            self.torque = on;
            self.torque_known = true;
        } else {
            self.counters.bus_errors = self.counters.bus_errors.saturating_add(1);
        }
        ok
    }

    /// Maps the setpoint (with gravity compensation's offsets) to ticks and sends every goal; true
    /// when sent.
    fn write_goals<P, D, C, const BUF: usize>(&mut self, master: &mut Master<P, D, C, BUF>) -> bool
    where
        P: Read + Write + ReadReady,
        D: OutputPin,
        C: Clock,
    {
        // The setpoint plus the sag the servo will leave under gravity (none without
        // compensation), within the joint's limits. With the torque on, the offsets move at a
        // bounded pace; coming on, the goal is where the servo will hold the joint.
        self.gravity.update(&self.chain, &self.setpoint.position, self.config.period_us as f32 * 1e-6, self.torque);
        let goals = self.clamped(&(self.setpoint.position + self.gravity.applied()));
        for j in 0..N {
            match self.mappings[j].to_ticks(goals[j]) {
                Ok(t) => self.goal_ticks[j] = t,
                // The limits keep setpoints inside every servo's range; should one fall outside
                // anyway, the servo keeps its last goal rather than get a wrong one.
                Err(_) => self.counters.mapping_errors = self.counters.mapping_errors.saturating_add(1),
            }
        }
        let item = self.group.model.items.goal_position;
        // The gripper's goal goes in the same sync write, once its position is known.
        let gripper = self.gripper.as_ref().filter(|g| g.seen()).map(|g| (g.config().id, g.goal_ticks()));
        let ok = self.group.write_with(master, item, &self.goal_ticks, gripper).is_ok();
        if !ok {
            self.counters.bus_errors = self.counters.bus_errors.saturating_add(1);
        }
        ok
    }

    /// Stops the arm when the host has been silent too long while the arm moves on its own.
    fn watchdog(&mut self, now_us: u64, report: &mut TickReport) {
        let moving = match self.mode {
            Mode::Tracking => true,
            // A player that ran dry is already ending its motion within the limits: braking,
            // then back to the last keyframe the host sent, a stopping distance away. Stopping
            // it there would leave the arm past where the host asked it to be.
            Mode::Playing => {
                let ending = matches!(self.player.state(), State::Underrun | State::Returning);
                let paused = self.play.paused && self.play.rate == 0.0;
                !(ending || paused)
            }
            _ => false,
        };
        let silent = now_us.saturating_sub(self.last_host_us) > u64::from(self.config.watchdog_ms) * 1000;
        if moving && silent {
            self.begin_stop();
            self.counters.watchdog_trips = self.counters.watchdog_trips.saturating_add(1);
            report.watchdog = true;
        }
    }

    /// What the mode asks for this tick, before the limits: a position and the velocity at which it
    /// moves (zero for a goal to stop on).
    pub(super) fn desired(&mut self, dt: f32, report: &mut TickReport) -> (SVector<f32, N>, SVector<f32, N>) {
        match self.mode {
            Mode::Idle | Mode::Holding | Mode::EStopped => (self.hold, SVector::zeros()),
            Mode::Playing => {
                // Pausing scales the playback clock's rate down within the time the fastest
                // joint needs to stop, so the slow-down respects the acceleration limits.
                let ramp =
                    (0..N).map(|j| self.limits.max_velocity[j] / self.limits.max_acceleration[j]).fold(dt, f32::max);
                let goal = if self.play.paused { 0.0 } else { 1.0 };
                let change = dt / ramp;
                self.play.rate = if self.play.rate < goal {
                    (self.play.rate + change).min(goal)
                } else {
                    (self.play.rate - change).max(goal)
                };
                self.play.time += dt * self.play.rate;
                let tick = self.player.tick(self.play.time);
                if matches!(tick.state, State::Idle | State::Holding) && !self.play.paused {
                    self.mode = Mode::Holding;
                    self.hold = tick.sample.position;
                    return (self.hold, SVector::zeros());
                }
                (tick.sample.position, tick.sample.velocity * self.play.rate)
            }
            Mode::Tracking => {
                let Some(mut goal) = self.tool else {
                    self.mode = Mode::Holding;
                    self.hold = self.setpoint.position;
                    return (self.hold, SVector::zeros());
                };
                // The goal point moves along the straight line at the requested speed.
                let to_go = goal.target.position() - goal.via;
                let distance = to_go.norm();
                let step = goal.speed * dt;
                goal.via =
                    if distance <= step { *goal.target.position() } else { goal.via + to_go * (step / distance) };
                self.tool = Some(goal);
                let solution = self.tracker.step(&self.chain, goal.target.at(goal.via));
                report.ik = Some(solution.status);
                self.last_ik = Some(super::IkSummary::of(&solution));
                if solution.status != IkStatus::Converged {
                    self.counters.ik_failures = self.counters.ik_failures.saturating_add(1);
                }
                // Progress: while IK follows the point it converges; when it does not, what is
                // left to go must still shrink, or the line runs into the joint limits.
                let left =
                    (distance - step).max(0.0) + solution.position_error + STALL_LEVER * solution.orientation_error;
                let needed = (goal.speed * STALL_TIME * 0.5).min(STALL_PROGRESS);
                if solution.status == IkStatus::Converged || left < goal.best - needed {
                    (goal.best, goal.stalled) = (left, 0.0);
                } else {
                    goal.stalled += dt;
                }
                self.tool = Some(goal);
                if goal.stalled > STALL_TIME {
                    if goal.path == ToolPath::Line {
                        // The line only: stop where it is blocked (the host says why).
                        self.begin_stop();
                        self.last_move = Some(self.given_up(&goal, PathTaken::LineStopped));
                        return (self.setpoint.position, SVector::zeros());
                    }
                    // The rest of the way by joints, to the solution found before moving, at the
                    // line's pace (or as fast as the limits allow, if that is slower).
                    if self.move_joints(goal.solution, left / goal.speed).is_ok() {
                        self.counters.line_fallbacks = self.counters.line_fallbacks.saturating_add(1);
                        self.last_move = Some(self.given_up(&goal, PathTaken::LineThenJoints));
                        return (self.setpoint.position, SVector::zeros());
                    }
                }
                (self.tracker.q, SVector::zeros())
            }
            Mode::Stopping => {
                // Each joint's velocity falls by its share of the synchronised brake, never past 0.
                let mut desired = self.setpoint.position;
                let mut velocity = SVector::zeros();
                for j in 0..N {
                    let v = self.braking[j];
                    let dv = libm::fabsf(self.brake[j]) * dt;
                    velocity[j] = if v > 0.0 { (v - dv).max(0.0) } else { (v + dv).min(0.0) };
                    desired[j] += velocity[j] * dt;
                }
                self.braking = velocity;
                (desired, velocity)
            }
        }
    }

    /// The outcome of `goal`'s line, given up now and ending by `path`: it was blocked where the
    /// tool stands at the tracker's last solution, projected onto the line (and kept within it).
    fn given_up(&self, goal: &ToolGoal<N>, path: PathTaken) -> MoveOutcome {
        let line = goal.target.position() - goal.start;
        let length = line.norm();
        let along = (self.tool_position(&self.tracker.q) - goal.start).dot(&line);
        // A line of no length (the tool turning in place) is blocked at its start.
        let at = if length > 0.0 { (along / length).max(0.0).min(length) } else { 0.0 };
        MoveOutcome { path, blocked_at: Some(at), line_length: length }
    }

    /// Mode changes that depend on where the limited step ended.
    fn after_step(&mut self) {
        match self.mode {
            Mode::Stopping if self.setpoint.velocity.iter().all(|v| *v == 0.0) => self.enter_hold(),
            Mode::Tracking => {
                let arrived = self.tool.is_some_and(|g| g.via == *g.target.position());
                let settled = (0..N).all(|j| {
                    libm::fabsf(self.setpoint.position[j] - self.tracker.q[j]) < 1e-5
                        && self.setpoint.velocity[j] == 0.0
                });
                if arrived && settled {
                    let tool = self.tool_position(&self.tracker.q);
                    let reached = self.tool.is_some_and(|g| (tool - g.target.position()).norm() < 1e-3);
                    if reached {
                        self.enter_hold();
                    }
                }
            }
            _ => {}
        }
    }
}
