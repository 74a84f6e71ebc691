//! The gripper: one servo outside the kinematic chain, driven in the same sync write and read as
//! the joints.
//!
//! Its opening is a percentage, 0 closed to 100 open (LeRobot's `RANGE_0_100`), mapped linearly to
//! ticks between the closed and the open position and truncated as LeRobot's `_unnormalize` does.
//! - The setpoint moves toward the goal at the configured speed, so opening and closing are ramps
//!   rather than a jump at the servo's full speed.
//! - In a trajectory the goal follows the keyframes' gripper values, linearly between them on the
//!   playback clock; a keyframe without one leaves the gripper where the previous one put it.
//! - Grasping: while closing, once the jaw has stood still short of its setpoint for
//!   [`GRASP_READS`] reads with the load at [`HOLD_LOAD`] or more, the gripper holds. Its goal
//!   becomes the position where it stopped plus [`SQUEEZE`] of the stroke toward closed, so the
//!   servo pushes with the torque of that small error (and no more than the effort limit) instead
//!   of driving at full torque toward a goal it cannot reach. It lets go when told to open, or
//!   when the load falls away (the object slipped out or was taken) and the jaw closes further.
//!
//! # Panics
//! Nothing here panics.

use heapless::Deque;

use super::refusal::Refusal;
use crate::bus::Id;

/// A stall shorter than this many position reads is motion slowing down, not a grasp.
pub const GRASP_READS: u8 = 5;
/// Movement per read (fraction of the stroke) below which the jaw counts as standing still.
pub const STILL: f32 = 0.004;
/// How far short of its setpoint (fraction of the stroke) a still jaw must be to be blocked.
pub const GRASP_GAP: f32 = 0.03;
/// The load (percent of the servo's full effort) at which a blocked jaw is holding something.
pub const HOLD_LOAD: f32 = 10.0;
/// How far beyond the contact point (fraction of the stroke) the holding goal lies.
pub const SQUEEZE: f32 = 0.03;

/// A gripper as the host configures it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GripperConfig {
    /// Bus id (the joints' model).
    pub id: Id,
    /// Ticks with the jaws closed (0 %).
    pub closed: i32,
    /// Ticks with the jaws open (100 %); differs from `closed`.
    pub open: i32,
    /// Effort limit, percent of the servo's full torque or current, in (0, 100].
    pub effort: f32,
    /// Setpoint speed, percent of the stroke per second (> 0).
    pub speed: f32,
}

/// What the gripper reports.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GripperState {
    /// Measured opening, percent (beyond 0..100 when pushed past the range).
    pub opening: f32,
    /// The goal, percent.
    pub goal: f32,
    /// Load, percent of the servo's full effort (signed as the servo reports it).
    pub load: f32,
    /// Whether it holds something: stopped short of its goal under load.
    pub holding: bool,
}

/// The gripper's state.
#[derive(Clone, Debug)]
pub struct Gripper<const Q: usize> {
    config: GripperConfig,
    /// Goal opening, percent.
    goal: f32,
    /// Opening sent (before any holding), percent, moving toward the goal.
    setpoint: f32,
    /// Last present position read, ticks, and whether there has been one.
    present: i32,
    seen: bool,
    load: f32,
    effort: f32,
    /// The effort limit is still to be written.
    effort_pending: bool,
    still_reads: u8,
    slack_reads: u8,
    /// Where the jaw stopped on the object, ticks, while holding.
    holding: Option<i32>,
    /// Gripper keyframes not reached yet: (playback time, opening).
    track: Deque<(f32, f32), Q>,
    /// The keyframe last reached (or the anchor a fresh track starts from): where the segment
    /// being played starts. Kept out of the queue so that a tick reads only its front.
    passed: Option<(f32, f32)>,
}

impl GripperConfig {
    /// Whether the values are usable: distinct positions, effort and speed in range.
    pub fn valid(&self) -> bool {
        self.closed != self.open
            && self.effort.is_finite()
            && self.effort > 0.0
            && self.effort <= 100.0
            && self.speed.is_finite()
            && self.speed > 0.0
    }
}

/// Refuses what is not a percentage.
pub fn check_percent(pct: f32) -> Result<f32, Refusal> {
    if !pct.is_finite() {
        return Err(Refusal::NotFinite);
    }
    if !(0.0..=100.0).contains(&pct) {
        return Err(Refusal::BadParameter);
    }
    Ok(pct)
}

impl<const Q: usize> Gripper<Q> {
    /// A gripper not read yet, its effort limit to be written.
    pub fn new(config: GripperConfig) -> Self {
        Self {
            config,
            goal: 0.0,
            setpoint: 0.0,
            present: config.closed,
            seen: false,
            load: 0.0,
            effort: config.effort,
            effort_pending: true,
            still_reads: 0,
            slack_reads: 0,
            holding: None,
            track: Deque::new(),
            passed: None,
        }
    }

    /// Its configuration.
    pub fn config(&self) -> &GripperConfig {
        &self.config
    }

    /// Whether its position has been read.
    pub fn seen(&self) -> bool {
        self.seen
    }

    fn stroke(&self) -> f32 {
        (self.config.open - self.config.closed) as f32
    }

    /// The ticks of an opening (percent, clamped to 0..=100), truncated toward zero.
    pub fn ticks_of(&self, pct: f32) -> i32 {
        let pct = pct.clamp(0.0, 100.0);
        (self.config.closed as f32 + pct / 100.0 * self.stroke()) as i32
    }

    /// The opening of `ticks`, percent.
    pub fn percent_of(&self, ticks: i32) -> f32 {
        (ticks - self.config.closed) as f32 / self.stroke() * 100.0
    }

    /// The goal to send now, ticks: the setpoint's, always between the closed and the open
    /// position.
    pub fn goal_ticks(&self) -> i32 {
        self.ticks_of(self.setpoint)
    }

    /// The effort limit to write, percent, once.
    pub fn take_effort(&mut self) -> Option<f32> {
        self.effort_pending.then_some(self.effort)
    }

    /// The effort limit was written.
    pub fn effort_written(&mut self) {
        self.effort_pending = false;
    }

    /// The effort limit must be written again (after a torque change or a servo reboot).
    pub fn rewrite_effort(&mut self) {
        self.effort_pending = true;
    }

    /// Sets the goal (percent) and, if given, the effort limit (percent, (0, 100]). Drops the
    /// trajectory's gripper keyframes: the latest command wins. Refused values change nothing.
    pub fn command(&mut self, opening: f32, effort: Option<f32>) -> Result<(), Refusal> {
        let opening = check_percent(opening)?;
        if let Some(e) = effort {
            if !e.is_finite() {
                return Err(Refusal::NotFinite);
            }
            if !(e > 0.0 && e <= 100.0) {
                return Err(Refusal::BadParameter);
            }
            if e != self.effort {
                self.effort = e;
                self.effort_pending = true;
            }
        }
        self.goal = opening;
        self.clear_track();
        Ok(())
    }

    /// Whether a gripper keyframe can be queued (checked before the joint keyframe is).
    pub fn has_room(&self) -> bool {
        self.free_slots() > 0
    }

    /// How many more gripper keyframes can be queued. The track keeps the keyframe last passed
    /// (the start of the segment being played) and one slot for the anchor of a fresh trajectory,
    /// so it fills before the joints' queue does when every keyframe carries the gripper.
    pub fn free_slots(&self) -> usize {
        Q.saturating_sub(self.track.len() + usize::from(self.passed.is_some()) + 1)
    }

    /// Queues a gripper keyframe at `time`; `anchor` (a playback time) starts the track afresh
    /// from where the gripper is now. Checked with [`check_percent`] and [`Gripper::has_room`]
    /// first.
    pub fn push(&mut self, time: f32, opening: f32, anchor: Option<f32>) {
        if let Some(at) = anchor {
            self.track.clear();
            self.passed = Some((at, self.setpoint));
        }
        let _ = self.track.push_back((time, opening));
    }

    /// Whether no gripper keyframe is queued.
    pub fn track_empty(&self) -> bool {
        self.track.is_empty() && self.passed.is_none()
    }

    /// A new trajectory without gripper keyframes: the gripper stays as it is.
    pub fn clear_track(&mut self) {
        self.track.clear();
        self.passed = None;
    }

    /// Freezes the gripper where its setpoint is (stop, emergency stop, torque off).
    pub fn stop(&mut self) {
        self.clear_track();
        if self.holding.is_none() {
            self.goal = self.setpoint;
        }
    }

    /// Takes the measured opening as goal and setpoint (torque coming on: hold it where it is).
    pub fn adopt(&mut self) {
        let here = self.percent_of(self.present).clamp(0.0, 100.0);
        self.goal = here;
        self.setpoint = here;
        self.holding = None;
        self.clear_track();
    }

    /// The goal at `time` on the playback clock from the keyframes, dropping those passed.
    fn sample(&mut self, time: f32) -> Option<f32> {
        while let Some(&next) = self.track.front() {
            if next.0 > time {
                break;
            }
            self.passed = Some(next);
            let _ = self.track.pop_front();
        }
        let next = self.track.front();
        match (self.passed, next) {
            (Some((t0, g0)), Some(&(t1, g1))) if time > t0 => {
                Some(g0 + (g1 - g0) * ((time - t0) / (t1 - t0)).clamp(0.0, 1.0))
            }
            (Some((_, g)), _) | (None, Some(&(_, g))) => Some(g),
            (None, None) => None,
        }
    }

    /// Advances the setpoint by `dt` seconds, following the keyframes at `play_time` if playing.
    pub fn step(&mut self, dt: f32, play_time: Option<f32>) {
        if let Some(goal) = play_time.and_then(|t| self.sample(t)) {
            self.goal = goal;
        }
        let mut target = self.goal;
        if let Some(at) = self.holding {
            let squeezed = (self.percent_of(at) - SQUEEZE * 100.0).clamp(0.0, 100.0);
            if self.goal > self.percent_of(at) + SQUEEZE * 100.0 {
                // Told to open past the contact point: let go.
                self.holding = None;
            } else {
                // Back from wherever closing had taken the setpoint to just past the contact,
                // at the same speed: no jump in the goal.
                target = squeezed;
            }
        }
        let step = self.config.speed * dt;
        let to_go = target - self.setpoint;
        self.setpoint = if libm::fabsf(to_go) <= step { target } else { self.setpoint + step * to_go.signum() };
    }

    /// Takes a present position read (ticks): grasp and release detection.
    pub fn observe(&mut self, present: i32) {
        let moved = libm::fabsf((present - self.present) as f32 / self.stroke());
        let first = !self.seen;
        self.present = present;
        self.seen = true;
        if first {
            self.adopt();
            return;
        }
        match self.holding {
            None => {
                // Short of the setpoint on the closing side (percent above the setpoint).
                let short = self.percent_of(present) - self.setpoint > GRASP_GAP * 100.0;
                let closing = self.goal < self.percent_of(present);
                self.still_reads =
                    if moved < STILL && short && closing { self.still_reads.saturating_add(1) } else { 0 };
                if self.still_reads >= GRASP_READS && libm::fabsf(self.load) >= HOLD_LOAD {
                    self.holding = Some(present);
                    self.still_reads = 0;
                    self.slack_reads = 0;
                }
            }
            Some(at) => {
                // The object gone: the jaw closes past where it held, and the load drops.
                let past = self.percent_of(at) - self.percent_of(present) > SQUEEZE * 50.0;
                let slack = libm::fabsf(self.load) < HOLD_LOAD / 2.0;
                self.slack_reads = if past || slack { self.slack_reads.saturating_add(1) } else { 0 };
                if self.slack_reads >= GRASP_READS {
                    self.holding = None;
                    self.setpoint = self.percent_of(present).clamp(0.0, 100.0);
                }
            }
        }
    }

    /// Takes a load read: percent of the servo's full effort.
    pub fn observe_load(&mut self, load: f32) {
        self.load = load;
    }

    /// What it reports.
    pub fn state(&self) -> GripperState {
        GripperState {
            opening: self.percent_of(self.present),
            goal: self.goal,
            load: self.load,
            holding: self.holding.is_some(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const SO101: GripperConfig = GripperConfig { id: 6, closed: 1934, open: 3186, effort: 50.0, speed: 100.0 };

    #[test]
    fn percent_maps_to_ticks_as_lerobot_unnormalises() {
        let g = Gripper::<4>::new(SO101);
        // int(pct / 100 * (max - min) + min), checked by hand: 1934 + 0.333 * 1252 = 2350.9.
        assert_eq!(g.ticks_of(0.0), 1934);
        assert_eq!(g.ticks_of(100.0), 3186);
        assert_eq!(g.ticks_of(33.3), 2350);
        assert_eq!(g.ticks_of(150.0), 3186);
        assert!((g.percent_of(2560) - 50.0).abs() < 1e-4);
    }

    #[test]
    fn bad_percent_and_effort_change_nothing() {
        let mut g = Gripper::<4>::new(SO101);
        g.observe(2560);
        g.effort_written();
        assert_eq!(g.command(f32::NAN, None), Err(Refusal::NotFinite));
        assert_eq!(g.command(101.0, None), Err(Refusal::BadParameter));
        assert_eq!(g.command(-1.0, None), Err(Refusal::BadParameter));
        assert_eq!(g.command(20.0, Some(0.0)), Err(Refusal::BadParameter));
        assert_eq!(g.command(20.0, Some(f32::INFINITY)), Err(Refusal::NotFinite));
        assert!((g.state().goal - 50.0).abs() < 1e-4);
        assert_eq!(g.take_effort(), None);
        g.command(20.0, Some(30.0)).unwrap();
        assert_eq!(g.take_effort(), Some(30.0));
    }

    #[test]
    fn setpoint_ramps_at_the_speed() {
        let mut g = Gripper::<4>::new(SO101);
        g.observe(g.ticks_of(100.0));
        g.command(0.0, None).unwrap();
        g.step(0.1, None);
        assert_eq!(g.goal_ticks(), g.ticks_of(90.0));
        for _ in 0..20 {
            g.step(0.1, None);
        }
        assert_eq!(g.goal_ticks(), SO101.closed);
    }

    /// A jaw blocked at 40 % under load holds; the goal squeezes just past the contact; opening
    /// lets go.
    #[test]
    fn grasp_and_release() {
        let mut g = Gripper::<4>::new(SO101);
        g.observe(g.ticks_of(100.0));
        g.command(0.0, None).unwrap();
        let contact = g.ticks_of(40.0);
        let mut jaw = g.ticks_of(100.0);
        for _ in 0..40 {
            g.step(0.02, None);
            jaw = g.goal_ticks().max(contact);
            g.observe_load(if jaw == contact { 35.0 } else { 2.0 });
            g.observe(jaw);
            if g.state().holding {
                break;
            }
        }
        assert!(g.state().holding, "no grasp: {:?}", g.state());
        assert_eq!(jaw, contact);
        // Held: the goal comes back to just past the contact and stays there.
        let squeezed = g.ticks_of(g.percent_of(contact) - SQUEEZE * 100.0);
        assert!((contact - squeezed - (SQUEEZE * 1252.0) as i32).abs() <= 1);
        for _ in 0..25 {
            g.step(0.02, None);
            g.observe(contact);
        }
        assert_eq!(g.goal_ticks(), squeezed);
        assert!(g.state().holding);
        g.command(100.0, None).unwrap();
        g.step(0.02, None);
        assert!(!g.state().holding);
        // Opening from the squeeze, at the speed.
        assert_eq!(g.goal_ticks(), g.ticks_of(g.percent_of(squeezed) + 2.0));
        g.step(1.0, None);
        assert_eq!(g.goal_ticks(), SO101.open);
    }

    /// A jaw that just closes on nothing never holds.
    #[test]
    fn closing_on_nothing_does_not_hold() {
        let mut g = Gripper::<4>::new(SO101);
        g.observe(g.ticks_of(100.0));
        g.command(0.0, None).unwrap();
        for _ in 0..100 {
            g.step(0.02, None);
            let t = g.goal_ticks();
            g.observe_load(3.0);
            g.observe(t);
        }
        assert!(!g.state().holding);
        assert_eq!(g.goal_ticks(), SO101.closed);
    }

    #[test]
    fn keyframes_interpolate_linearly_on_the_playback_clock() {
        let mut g = Gripper::<8>::new(SO101);
        g.observe(g.ticks_of(100.0));
        assert!(g.has_room());
        g.push(1.0, 100.0, Some(0.0));
        g.push(2.0, 0.0, None);
        g.push(3.0, 50.0, None);
        let goal_at = |g: &mut Gripper<8>, t: f32| {
            g.step(0.0, Some(t));
            g.state().goal
        };
        assert!((goal_at(&mut g, 0.5) - 100.0).abs() < 1e-4);
        assert!((goal_at(&mut g, 1.5) - 50.0).abs() < 1e-4);
        assert!((goal_at(&mut g, 2.5) - 25.0).abs() < 1e-4);
        assert!((goal_at(&mut g, 9.0) - 50.0).abs() < 1e-4);
    }

    #[test]
    fn free_slots_count_the_pushes_that_fit() {
        let mut g = Gripper::<8>::new(SO101);
        g.observe(g.ticks_of(100.0));
        // Fresh: the anchor and the first keyframe take two slots, each later one a slot.
        assert_eq!(g.free_slots(), 7);
        g.push(1.0, 100.0, Some(0.0));
        let mut pushed = 1;
        while g.has_room() {
            let before = g.free_slots();
            g.push(1.0 + pushed as f32, 0.0, None);
            pushed += 1;
            assert_eq!(g.free_slots(), before - 1);
        }
        assert_eq!((pushed, g.free_slots()), (6, 0));
        // Passing keyframes frees their slots, all but the one the segment starts from.
        g.step(0.0, Some(3.5));
        assert_eq!(g.free_slots(), 3);
    }
}
