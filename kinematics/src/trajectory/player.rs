//! The streaming player the firmware runs: a fixed-capacity keyframe queue and a motion evaluated
//! at arbitrary tick times.
//!
//! * **Segments.** The player moves on one Hermite segment at a time, from the state it is in
//!   (a keyframe it reached, or the current position and velocity when it resumes or a trajectory
//!   is replaced) to the next queued keyframe. A segment is fixed once entered: its end velocity is
//!   chosen then, and keyframes appended later never change it. An end velocity not given with the
//!   keyframe is the Catmull-Rom one, `(p_next - p_start) / (t_next - t_start)` over the segment's
//!   start and the keyframe after it, or zero when the keyframe is the last one queued, so running
//!   out of keyframes ends at rest. Chosen velocities are clamped to the velocity limits.
//! * **Appending** while playing joins without a jump in position or velocity: the next segment
//!   starts from the keyframe (position and velocity) the current one ends at.
//! * **Underrun.** Reaching the last queued keyframe with a non-zero (given) velocity and no
//!   keyframe after it: the player brakes to a stop within the limits, reports it
//!   ([`Tick::underrun`], [`State::Underrun`]), then goes back to that keyframe, rest to rest
//!   within the limits ([`State::Returning`]), and ends there ([`State::Idle`]): the last keyframe
//!   is what the sender asked for (a stream that stops: a policy ending, a leader put down), and
//!   the brake only carried the joints past it. How far is [`Player::largest_pass`]. Keyframes
//!   pushed meanwhile are played at once, from the current position and velocity.
//! * **Replacement** ([`Player::replace`]): the queue is replaced; at the next tick the current
//!   segment is abandoned and a new one starts from the position and velocity at that instant (as
//!   ros2_control's joint trajectory controller does). New keyframes not later than that tick are
//!   dropped; if none is left the player brakes as for an underrun, and goes back to the last of
//!   them.
//! * **Stop** ([`Player::stop`]): the queue is cleared and the player brakes from the state at the
//!   next tick. Keyframes pushed afterwards are played once it is at rest.
//! * **Braking** is time-synchronised: all joints decelerate at constant rates and stop together
//!   after `T = max_j |v_j| / a_max_j`, joint `j` at `|v_j| / T <= a_max_j`. The path stays on the
//!   straight line in joint space along the velocity, and no joint exceeds its acceleration limit.
//! * **Late keyframes.** When the player starts a segment at time `now` (resuming from rest or a
//!   brake) and the next keyframe's time is not after `now`, every queued keyframe is shifted later
//!   so that this segment keeps its planned duration (the gap to the keyframe before it) but at
//!   least the smoothstep time the position change needs within the limits. Keyframes pushed
//!   later are shifted by the same total ([`Player::shift`]), so a stream longer than the queue
//!   keeps its spacing: its times stay those of the sender's timeline, which runs `shift` behind
//!   the player's clock. [`Player::stop`], [`Player::replace`] and [`Player::reset`] start a new
//!   timeline (no shift).
//!
//! The player enforces the limits only on what it generates (braking, chosen velocities); the
//! keyframes and their timing are the sender's responsibility (see [`super::time_scale`]).
//! Nothing allocates and nothing panics, whatever the input.

use super::{HermiteSegment, JointLimits, LimitError, Sample};
use crate::Real;
use heapless::Deque;
use nalgebra::SVector;

/// A keyframe for the player: time, position, and an optional velocity (chosen when absent).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlayerKeyframe<T: Real, const J: usize> {
    /// Time on the tick clock (s).
    pub time: T,
    /// Joint values.
    pub position: SVector<T, J>,
    /// Velocity at the keyframe; `None` lets the player choose it.
    pub velocity: Option<SVector<T, J>>,
}

impl<T: Real, const J: usize> PlayerKeyframe<T, J> {
    /// A keyframe whose velocity the player chooses.
    pub fn new(time: T, position: SVector<T, J>) -> Self {
        Self { time, position, velocity: None }
    }

    fn finite(&self) -> bool {
        let finite = |v: &SVector<T, J>| v.iter().all(|x| x.finite());
        self.time.finite() && finite(&self.position) && self.velocity.as_ref().is_none_or(finite)
    }
}

/// Why a keyframe was refused. The player is unchanged.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PushError {
    /// The queue is full ([`Player::free_slots`] is 0), or a replacement is longer than it.
    QueueFull,
    /// The time, a position or the velocity is NaN or infinite.
    NonFinite,
    /// The time is not later than the last keyframe accepted.
    TimeNotIncreasing,
}

impl core::fmt::Display for PushError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            PushError::QueueFull => write!(f, "keyframe queue full"),
            PushError::NonFinite => write!(f, "NaN or infinite keyframe"),
            PushError::TimeNotIncreasing => write!(f, "keyframe time not later than the previous one"),
        }
    }
}

/// What the player is doing.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum State {
    /// Moving along a segment towards a keyframe.
    Playing,
    /// Braking because the queue ran dry while moving.
    Underrun,
    /// Going back, from rest, to the keyframe an underrun's brake carried the joints past.
    Returning,
    /// Braking after [`Player::stop`].
    Stopping,
    /// At rest after a stop, waiting for keyframes.
    Holding,
    /// At rest with nothing to do (never started, or ended at a keyframe: at rest, or back on
    /// it after an underrun).
    Idle,
}

/// The result of one tick.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tick<T: Real, const J: usize> {
    /// Commanded position, velocity and acceleration at the tick time.
    pub sample: Sample<T, J>,
    /// What the player is doing.
    pub state: State,
    /// True on the tick at which an underrun began.
    pub underrun: bool,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Cause {
    Underrun,
    Stop,
}

#[derive(Clone, Copy, Debug)]
enum Motion<T: Real, const J: usize> {
    Segment(HermiteSegment<T, J>),
    Brake {
        t0: T,
        p0: SVector<T, J>,
        v0: SVector<T, J>,
        decel: SVector<T, J>,
        duration: T,
        cause: Cause,
    },
    /// Back to the keyframe an underrun's brake passed, rest to rest.
    Return(HermiteSegment<T, J>),
    Rest {
        position: SVector<T, J>,
        held: bool,
    },
}

impl<T: Real, const J: usize> Motion<T, J> {
    fn sample(&self, now: T) -> Sample<T, J> {
        // Matched by reference: a copy of the segment would cost a tenth of a tick on the M4F.
        match self {
            Motion::Segment(seg) | Motion::Return(seg) => seg.sample(now),
            &Motion::Brake { t0, p0, v0, decel, duration, .. } => {
                let tau = (now - t0).max(T::zero()).min(duration);
                let half = T::of(0.5);
                let acceleration = if tau < duration { -decel } else { SVector::zeros() };
                Sample {
                    position: p0 + v0 * tau - decel * (half * tau * tau),
                    velocity: v0 - decel * tau,
                    acceleration,
                }
            }
            &Motion::Rest { position, .. } => {
                Sample { position, velocity: SVector::zeros(), acceleration: SVector::zeros() }
            }
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Request {
    None,
    Replace,
    Stop,
}

/// A streaming trajectory player with a queue of up to `Q` keyframes of `J` joints.
#[derive(Clone, Debug)]
pub struct Player<T: Real, const J: usize, const Q: usize> {
    limits: JointLimits<T, J>,
    queue: Deque<PlayerKeyframe<T, J>, Q>,
    motion: Motion<T, J>,
    request: Request,
    /// Pushed keyframes must be later than this (the last keyframe accepted).
    tail: Option<T>,
    /// Time of the last keyframe reached or started from (the reference for late keyframes).
    reached: Option<T>,
    /// How far late keyframes have shifted the sender's timeline onto the player's clock.
    shift: T,
    underruns: u32,
    /// The keyframe the brake in progress must come back to (an underrun's), if any.
    comeback: Option<SVector<T, J>>,
    /// The farthest an underrun's brake carried the joints past their keyframe since the reset.
    largest_pass: T,
}

impl<T: Real, const J: usize, const Q: usize> Player<T, J, Q> {
    /// A player at rest at `position`.
    pub fn new(position: SVector<T, J>, limits: JointLimits<T, J>) -> Result<Self, LimitError<T>> {
        let mut player = Self::still();
        player.reset(position, &limits)?;
        Ok(player)
    }

    /// A player at rest at zero that cannot move ([`JointLimits::still`]), built without a check
    /// that could fail: the placeholder of a controller before it has an arm.
    pub fn still() -> Self {
        Self {
            limits: JointLimits::still(),
            queue: Deque::new(),
            motion: Motion::Rest { position: SVector::zeros(), held: false },
            request: Request::None,
            tail: None,
            reached: None,
            shift: T::zero(),
            underruns: 0,
            comeback: None,
            largest_pass: T::zero(),
        }
    }

    /// The player at rest at `position` under `limits`, its queue empty and its counts zero, as
    /// [`Player::new`] makes it, but in place: a firmware keeps its player in static memory and
    /// has no stack for a second one. Refused, changing nothing, if the limits are invalid or the
    /// position is not finite.
    pub fn reset(&mut self, position: SVector<T, J>, limits: &JointLimits<T, J>) -> Result<(), LimitError<T>> {
        limits.validate()?;
        if !position.iter().all(|x| x.finite()) {
            return Err(LimitError::Trajectory(super::TrajectoryError::NonFinite { index: 0 }));
        }
        self.limits = *limits;
        self.queue.clear();
        self.motion = Motion::Rest { position, held: false };
        self.request = Request::None;
        self.tail = None;
        self.reached = None;
        self.shift = T::zero();
        self.underruns = 0;
        self.comeback = None;
        self.largest_pass = T::zero();
        Ok(())
    }

    /// The limits braking and chosen velocities respect.
    pub fn limits(&self) -> &JointLimits<T, J> {
        &self.limits
    }

    /// Room left in the queue.
    pub fn free_slots(&self) -> usize {
        Q - self.queue.len()
    }

    /// Keyframes waiting (the one being moved towards is no longer queued).
    pub fn queued(&self) -> usize {
        self.queue.len()
    }

    /// Underruns so far.
    pub fn underruns(&self) -> u32 {
        self.underruns
    }

    /// The farthest an underrun's brake carried the joints past the keyframe they ran out at, since
    /// the player was reset: the largest joint's distance (rad or m), known once a brake has ended;
    /// zero before any.
    pub fn largest_pass(&self) -> T {
        self.largest_pass
    }

    /// What the player is doing, as of its last tick.
    pub fn state(&self) -> State {
        match self.motion {
            Motion::Segment(_) => State::Playing,
            Motion::Brake { cause: Cause::Underrun, .. } => State::Underrun,
            Motion::Brake { cause: Cause::Stop, .. } => State::Stopping,
            Motion::Return(_) => State::Returning,
            Motion::Rest { held: true, .. } => State::Holding,
            Motion::Rest { held: false, .. } => State::Idle,
        }
    }

    /// How far the sender's timeline runs behind the player's clock: the total by which late
    /// keyframes were shifted since the timeline began. A keyframe pushed at time `t` plays at
    /// `t + shift`; the sender's time at the player's `now` is `now - shift`.
    pub fn shift(&self) -> T {
        self.shift
    }

    /// Appends a keyframe, at its time plus [`Player::shift`]. Its time must be later than every
    /// keyframe accepted before.
    pub fn push(&mut self, mut keyframe: PlayerKeyframe<T, J>) -> Result<(), PushError> {
        if !keyframe.finite() {
            return Err(PushError::NonFinite);
        }
        keyframe.time += self.shift;
        if self.tail.is_some_and(|tail| keyframe.time <= tail) {
            return Err(PushError::TimeNotIncreasing);
        }
        self.queue.push_back(keyframe).map_err(|_| PushError::QueueFull)?;
        self.tail = Some(keyframe.time);
        Ok(())
    }

    /// Replaces the rest of the trajectory with `keyframes` (times increasing). From the next tick
    /// the player heads for the first of them later than that tick, starting from the position and
    /// velocity it has then. All or nothing: on error the player is unchanged.
    pub fn replace(&mut self, keyframes: &[PlayerKeyframe<T, J>]) -> Result<(), PushError> {
        if keyframes.len() > Q {
            return Err(PushError::QueueFull);
        }
        for (i, k) in keyframes.iter().enumerate() {
            if !k.finite() {
                return Err(PushError::NonFinite);
            }
            if i > 0 && k.time <= keyframes[i - 1].time {
                return Err(PushError::TimeNotIncreasing);
            }
        }
        self.queue.clear();
        for k in keyframes {
            // Capacity was checked above.
            let _ = self.queue.push_back(*k);
        }
        if let Some(last) = keyframes.last() {
            self.tail = Some(last.time);
        }
        self.shift = T::zero();
        self.request = Request::Replace;
        Ok(())
    }

    /// Clears the queue and brakes to a stop within the acceleration limits from the next tick.
    /// Keyframes pushed afterwards may have any time (late ones are shifted when the player
    /// resumes at rest).
    pub fn stop(&mut self) {
        self.queue.clear();
        self.tail = None;
        self.shift = T::zero();
        self.request = Request::Stop;
    }

    /// The commanded sample at `now` (tick times should not decrease; a NaN time evaluates at the
    /// current segment's start). Advances through every keyframe reached by `now`.
    pub fn tick(&mut self, now: T) -> Tick<T, J> {
        let now = if now.finite() { now } else { self.start_time() };
        let mut underrun = false;
        match core::mem::replace(&mut self.request, Request::None) {
            Request::None => {}
            Request::Stop => {
                let s = self.motion.sample(now);
                self.brake(now, s, Cause::Stop, None);
            }
            Request::Replace => {
                let s = self.motion.sample(now);
                let mut last_dropped = None;
                while self.queue.front().is_some_and(|k| k.time <= now) {
                    last_dropped = self.queue.pop_front().map(|k| k.position);
                }
                if self.queue.is_empty() {
                    underrun = self.brake(now, s, Cause::Underrun, last_dropped);
                } else {
                    self.reached = Some(now);
                    self.enter(now, s.position, s.velocity, false);
                }
            }
        }
        // Each pass consumes a keyframe or moves Brake -> Return -> Rest; the bound only guards
        // the loop.
        for _ in 0..Q + 4 {
            match self.motion {
                // Inside the segment, the common case: decided without copying it.
                Motion::Segment(ref seg) if now < seg.t1 => break,
                Motion::Segment(seg) => {
                    self.reached = Some(seg.t1);
                    if !self.queue.is_empty() {
                        self.enter(seg.t1, seg.p1, seg.v1, false);
                    } else if seg.v1.iter().all(|v| *v == T::zero()) {
                        self.motion = Motion::Rest { position: seg.p1, held: false };
                    } else {
                        let s = Sample { position: seg.p1, velocity: seg.v1, acceleration: SVector::zeros() };
                        underrun |= self.brake(seg.t1, s, Cause::Underrun, Some(seg.p1));
                    }
                }
                Motion::Brake { t0, duration, cause, .. } => {
                    if cause == Cause::Underrun && !self.queue.is_empty() {
                        let s = self.motion.sample(now);
                        self.enter(now, s.position, s.velocity, true);
                    } else if now >= t0 + duration {
                        let position = self.motion.sample(t0 + duration).position;
                        self.come_back(t0 + duration, position);
                    } else {
                        break;
                    }
                }
                Motion::Return(ref seg) if self.queue.is_empty() && now < seg.t1 => break,
                Motion::Return(seg) => {
                    if self.queue.is_empty() {
                        self.motion = Motion::Rest { position: seg.p1, held: false };
                    } else {
                        // Through `Motion::sample`, the one place a segment is sampled: a second
                        // call site would take the segment's sampling out of line (330 B of flash).
                        let s = self.motion.sample(now);
                        self.enter(now, s.position, s.velocity, true);
                    }
                }
                Motion::Rest { position, .. } => {
                    if self.queue.is_empty() {
                        break;
                    }
                    self.enter(now, position, SVector::zeros(), true);
                }
            }
        }
        Tick { sample: self.motion.sample(now), state: self.state(), underrun }
    }

    fn start_time(&self) -> T {
        match self.motion {
            Motion::Segment(seg) | Motion::Return(seg) => seg.t0,
            Motion::Brake { t0, .. } => t0,
            Motion::Rest { .. } => self.reached.unwrap_or(T::zero()),
        }
    }

    /// Starts braking from `s` at `t0`, to come back to `comeback` once at rest (an underrun's
    /// keyframe); true (and counted) when it is an underrun.
    fn brake(&mut self, t0: T, s: Sample<T, J>, cause: Cause, comeback: Option<SVector<T, J>>) -> bool {
        let duration = self.limits.stopping_time(&s.velocity);
        self.comeback = comeback;
        if duration > T::zero() && duration.finite() {
            let decel = s.velocity / duration;
            self.motion = Motion::Brake { t0, p0: s.position, v0: s.velocity, decel, duration, cause };
        } else {
            self.come_back(t0, s.position);
        }
        let underrun = cause == Cause::Underrun;
        if underrun {
            self.underruns = self.underruns.saturating_add(1);
        }
        underrun
    }

    /// At rest at `position` at `t0`, the brake done: goes back to the keyframe it passed, if any
    /// (rest to rest, within the limits), else holds there.
    fn come_back(&mut self, t0: T, position: SVector<T, J>) {
        let Some(keyframe) = self.comeback.take() else {
            self.motion = Motion::Rest { position, held: true };
            return;
        };
        self.largest_pass = self.largest_pass.max((keyframe - position).amax());
        // At least a millisecond, as a late keyframe's segment: never a segment of no length (the
        // brake ended on the keyframe only if it never moved).
        let duration = self.limits.rest_to_rest_time(&position, &keyframe).max(T::of(1e-3));
        let zero = SVector::zeros();
        self.motion =
            Motion::Return(HermiteSegment { t0, t1: t0 + duration, p0: position, v0: zero, p1: keyframe, v1: zero });
    }

    /// Enters the segment from `(t0, p0, v0)` to the front keyframe (which must exist), shifting
    /// late keyframes when `resume`.
    fn enter(&mut self, t0: T, p0: SVector<T, J>, v0: SVector<T, J>, resume: bool) {
        let Some(next) = self.queue.front().copied() else {
            return;
        };
        if resume && next.time <= t0 {
            let planned = self.reached.map_or(T::zero(), |r| next.time - r);
            let needed = self.limits.rest_to_rest_time(&p0, &next.position);
            let duration = planned.max(needed).max(T::of(1e-3));
            let shift = t0 - next.time + duration;
            for k in self.queue.iter_mut() {
                k.time += shift;
            }
            self.tail = self.tail.map(|t| t + shift);
            self.shift += shift;
        }
        let Some(next) = self.queue.pop_front() else {
            return;
        };
        if next.time <= t0 {
            // Cannot happen (times increase and late keyframes were shifted); never divide by a
            // non-positive duration.
            self.motion = Motion::Rest { position: p0, held: true };
            return;
        }
        let v1 = match (next.velocity, self.queue.front()) {
            (Some(v), _) => v,
            (None, Some(after)) => {
                let v = (after.position - p0) / (after.time - t0);
                let vmax = &self.limits.max_velocity;
                v.zip_map(vmax, |x, m| x.max(-m).min(m))
            }
            (None, None) => SVector::zeros(),
        };
        self.motion = Motion::Segment(HermiteSegment { t0, t1: next.time, p0, v0, p1: next.position, v1 });
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector2;

    fn player() -> Player<f64, 2, 4> {
        let l =
            JointLimits::new(Vector2::repeat(-3.0), Vector2::repeat(3.0), Vector2::repeat(2.0), Vector2::repeat(5.0));
        Player::new(Vector2::zeros(), l.unwrap()).unwrap()
    }

    fn key(time: f64, a: f64, b: f64) -> PlayerKeyframe<f64, 2> {
        PlayerKeyframe::new(time, Vector2::new(a, b))
    }

    #[test]
    fn idle_until_keyframes_then_plays_and_ends_at_rest() {
        let mut p = player();
        assert_eq!(p.tick(0.0).state, State::Idle);
        p.push(key(1.0, 0.5, -0.5)).unwrap();
        p.push(key(2.0, 1.0, 0.0)).unwrap();
        let t = p.tick(0.5);
        assert_eq!(t.state, State::Playing);
        let t = p.tick(1.0);
        // Catmull-Rom at keyframe 1: (1.0 - 0) / (2.0 - 0.5) per joint 0.
        assert!((t.sample.position - Vector2::new(0.5, -0.5)).norm() < 1e-12);
        assert!((t.sample.velocity[0] - 1.0 / 1.5).abs() < 1e-12);
        let t = p.tick(2.5);
        assert_eq!(t.state, State::Idle);
        assert!(!t.underrun);
        assert_eq!(t.sample.position, Vector2::new(1.0, 0.0));
    }

    #[test]
    fn push_errors_leave_the_player_unchanged() {
        let mut p = player();
        p.push(key(1.0, 0.1, 0.1)).unwrap();
        assert_eq!(p.push(key(1.0, 0.2, 0.2)), Err(PushError::TimeNotIncreasing));
        assert_eq!(p.push(key(f64::NAN, 0.2, 0.2)), Err(PushError::NonFinite));
        assert_eq!(p.push(key(2.0, f64::INFINITY, 0.2)), Err(PushError::NonFinite));
        let bad_velocity = PlayerKeyframe { velocity: Some(Vector2::new(0.0, f64::NAN)), ..key(2.0, 0.0, 0.0) };
        assert_eq!(p.push(bad_velocity), Err(PushError::NonFinite));
        for i in 0..3 {
            p.push(key(2.0 + f64::from(i), 0.0, 0.0)).unwrap();
        }
        assert_eq!(p.free_slots(), 0);
        assert_eq!(p.push(key(9.0, 0.0, 0.0)), Err(PushError::QueueFull));
        assert_eq!(p.replace(&[key(1.0, 0.0, 0.0); 5]), Err(PushError::QueueFull));
        assert_eq!(p.replace(&[key(1.0, 0.0, 0.0), key(1.0, 0.0, 0.0)]), Err(PushError::TimeNotIncreasing));
        assert_eq!(p.queued(), 4);
    }

    /// A player reset in place is the one `new` makes (compared field by field through Debug,
    /// which shows the queue's keyframes), and a refused reset changes nothing.
    #[test]
    fn reset_in_place_is_new_and_a_refused_reset_changes_nothing() {
        let mut p = player();
        p.push(key(0.5, 1.0, 1.0)).unwrap();
        p.push(key(1.0, 2.0, -1.0)).unwrap();
        p.tick(0.2);
        let before = format!("{p:?}");
        let nan = JointLimits { max_velocity: Vector2::new(f64::NAN, 1.0), ..*p.limits() };
        assert!(p.reset(Vector2::zeros(), &nan).is_err());
        let limits = *p.limits();
        assert!(p.reset(Vector2::new(f64::INFINITY, 0.0), &limits).is_err());
        assert_eq!(format!("{p:?}"), before);
        let limits =
            JointLimits::new(Vector2::repeat(-1.0), Vector2::repeat(1.0), Vector2::repeat(3.0), Vector2::repeat(4.0));
        let limits = limits.unwrap();
        p.reset(Vector2::new(0.25, -0.5), &limits).unwrap();
        let fresh: Player<f64, 2, 4> = Player::new(Vector2::new(0.25, -0.5), limits).unwrap();
        assert_eq!(format!("{p:?}"), format!("{fresh:?}"));
    }

    #[test]
    fn nan_tick_does_not_panic() {
        let mut p = player();
        p.push(key(1.0, 0.1, 0.1)).unwrap();
        let t = p.tick(f64::NAN);
        assert!(t.sample.position.iter().all(|x| x.is_finite()));
    }

    #[test]
    fn underrun_with_given_velocity_brakes_within_limits() {
        let mut p = player();
        let v = Vector2::new(1.0, -0.5);
        p.push(PlayerKeyframe { velocity: Some(v), ..key(1.0, 0.5, -0.25) }).unwrap();
        assert_eq!(p.tick(0.0).state, State::Playing);
        let t = p.tick(1.0 + 1e-9);
        assert!(t.underrun);
        assert_eq!(t.state, State::Underrun);
        assert_eq!(p.underruns(), 1);
        // Joint 0 limits the stop: 1.0 / 5.0 = 0.2 s; joint 1 decelerates at 2.5.
        let t = p.tick(1.1);
        assert!((t.sample.acceleration - Vector2::new(-5.0, 2.5)).norm() < 1e-9);
        // At rest 0.2 s later, past the keyframe by v² / 2a = 0.1 on joint 0 (0.05 on joint 1),
        // it goes back: rest to rest, sqrt(6 * 0.1 / 5) = 0.346 s (joint 0's acceleration bound).
        let t = p.tick(1.2 + 1e-9);
        assert_eq!(t.state, State::Returning);
        assert!((t.sample.position - Vector2::new(0.6, -0.3)).norm() < 1e-9);
        assert!((p.largest_pass() - 0.1).abs() < 1e-9);
        let back = (6.0f64 * 0.1 / 5.0).sqrt();
        let t = p.tick(1.2 + back / 2.0);
        assert_eq!(t.state, State::Returning);
        assert!((t.sample.velocity[0] + 1.5 * 0.1 / back).abs() < 1e-9, "the smoothstep's peak");
        let t = p.tick(1.2 + back + 1e-9);
        assert_eq!(t.state, State::Idle);
        assert_eq!(t.sample.velocity, Vector2::zeros());
        assert_eq!(t.sample.position, Vector2::new(0.5, -0.25));
        assert_eq!(p.underruns(), 1);
    }

    #[test]
    fn a_stop_holds_where_it_stopped_and_a_keyframe_cuts_a_return_short() {
        let mut p = player();
        let v = Vector2::new(1.0, 0.0);
        p.push(PlayerKeyframe { velocity: Some(v), ..key(1.0, 0.5, 0.0) }).unwrap();
        p.tick(0.0);
        p.tick(0.9);
        p.stop();
        p.tick(0.95);
        let t = p.tick(5.0);
        assert_eq!(t.state, State::Holding, "a stop is not an underrun: no way back");
        assert_eq!(p.largest_pass(), 0.0);

        let mut p = player();
        p.push(PlayerKeyframe { velocity: Some(v), ..key(1.0, 0.5, 0.0) }).unwrap();
        p.tick(0.0);
        assert_eq!(p.tick(1.25).state, State::Returning);
        let here = p.tick(1.3).sample;
        p.push(key(2.0, -0.5, 0.0)).unwrap();
        let t = p.tick(1.3);
        assert_eq!(t.state, State::Playing, "a keyframe is taken at once, from where the return is");
        assert!((t.sample.position - here.position).norm() < 1e-12);
        assert!((t.sample.velocity - here.velocity).norm() < 1e-12);
    }
}
