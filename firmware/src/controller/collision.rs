//! The collision check every goal passes before it goes to the servos, whatever mode produced it.
//!
//! The controller keeps one invariant: where the arm would come to rest if it braked now is free,
//! and so is the way there. The brake is the time-synchronised one of `begin_stop` (every joint
//! decelerating at a constant rate, all stopping together), so from a setpoint at `p` moving at
//! `v` it runs along the straight joint-space segment from `p` to `p + v t / 2`, where `t` is the
//! stopping time. Each tick the limiter's step is checked with its own brake segment, sampled at
//! [`brake_samples`] points from the rest end back to the step itself. A step whose segment is
//! free is sent; otherwise the brake step is sent in its place (its segment is the tail of the one
//! checked on the tick before) and the move or stream ends there, stopped short of the contact,
//! its pair and distance recorded ([`CollisionStop`]). Should even the brake step touch (the
//! samples straddled a thin part, or the arm was already in contact), the setpoint stays where it
//! is: no configuration closer than the margin is ever sent.
//!
//! An arm already in contact (committed or switched on there) may hold, but every step away is
//! refused the same way: it moves only once the check is off or the arm is moved clear by hand.

use kinematics::collision::{Contact, Scene};
use kinematics::nalgebra::SVector;
use kinematics::trajectory::JointLimits;
use kinematics::Chain;

use super::health::TickReport;
use super::limiter::{limit_step, Setpoint};
use super::{Controller, Mode, MoveOutcome, PathTaken};

/// The most collision bodies an arm has on this firmware.
pub const MAX_BODIES: usize = 24;
/// The most obstacles.
pub const MAX_OBSTACLES: usize = 8;
/// The scene an arm's goals are checked against.
pub type ArmScene = Scene<f32, MAX_BODIES, MAX_OBSTACLES>;

/// The largest joint-space step between two samples of a brake segment (rad, or m for a prismatic
/// joint): a link of 0.3 m sweeps at most 3 cm between them, well within a few margins' reach.
const SAMPLE_STEP: f32 = 0.1;
/// The most samples of one brake segment (its rest end included, the step itself not): the cost
/// of a tick at full speed.
const MAX_SAMPLES: usize = 6;

/// How many points of a brake segment whose largest joint displacement is `span` are checked,
/// besides the step itself: one per [`SAMPLE_STEP`], at least the rest end, at most
/// [`MAX_SAMPLES`].
pub fn brake_samples(span: f32) -> usize {
    let n = libm::ceilf(span / SAMPLE_STEP);
    if n.is_finite() && n >= 1.0 {
        (n as usize).min(MAX_SAMPLES)
    } else {
        1
    }
}

/// Where the time-synchronised brake from `from` comes to rest, within the joint limits.
pub fn rest_point<const N: usize>(from: &Setpoint<N>, limits: &JointLimits<f32, N>) -> SVector<f32, N> {
    let t = limits.stopping_time(&from.velocity);
    let t = if t.is_finite() { t } else { 0.0 };
    let rest = from.position + from.velocity * (0.5 * t);
    rest.zip_zip_map(&limits.lower, &limits.upper, super::limiter::within)
}

/// The last time the check stopped the arm.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CollisionStop {
    /// The pair and its distance where the arm would have gone.
    pub contact: Contact<f32>,
    /// Collision stops since the arm was configured (wraps).
    pub count: u32,
}

/// What goals are checked against, and what the check did last.
#[derive(Clone, Debug)]
pub struct Guard {
    scene: ArmScene,
    /// The sender asked for the check (`false`: `--no-collision-check`).
    check: bool,
    last: Option<CollisionStop>,
}

impl Guard {
    /// No bodies: nothing checked.
    pub fn empty() -> Self {
        Self { scene: ArmScene::new(0.0), check: true, last: None }
    }

    /// Writes [`Guard::empty`] at `at`. Never inlined: the empty scene (2 KB) is then built in
    /// this function's frame, not in that of the board's start-up, which goes deeper later.
    ///
    /// # Safety
    /// `at` must be valid for writes and aligned; nothing there is read or dropped.
    #[inline(never)]
    #[allow(unsafe_code)]
    pub(crate) unsafe fn empty_at(at: *mut Self) {
        at.write(Self::empty());
    }

    /// No bodies, the check asked for, no stop: what a new arm starts with.
    pub fn clear(&mut self) {
        self.scene.clear();
        self.check = true;
        self.last = None;
    }

    /// The arm's scene, and whether its sender asked for the check; clears the last stop.
    pub fn set(&mut self, scene: &ArmScene, check: bool) {
        self.scene.assign(scene);
        self.check = check;
        self.last = None;
    }

    /// The scene.
    pub fn scene(&self) -> &ArmScene {
        &self.scene
    }

    /// Whether the check was asked for (it runs when there is also a pair to check).
    pub fn requested(&self) -> bool {
        self.check
    }

    /// Whether goals are checked: asked for, and a pair to check.
    pub fn active(&self) -> bool {
        self.check && !self.scene.is_empty()
    }

    /// The last collision stop since the arm was configured.
    pub fn last(&self) -> Option<CollisionStop> {
        self.last
    }

    /// The first checked pair closer than the margin with the arm at `q`.
    pub fn contact_at<const N: usize>(&mut self, chain: &Chain<f32, N>, q: &SVector<f32, N>) -> Option<Contact<f32>> {
        let frames = chain.forward(q);
        self.scene.first_contact(&frames.joints)
    }

    /// The first contact along the brake segment of `from`, checked from its rest end back to
    /// `from` itself: the far end first, since the first contact ahead is what a check must not
    /// miss, and a step whose rest end is free usually is free all along.
    pub fn brake_contact<const N: usize>(
        &mut self,
        chain: &Chain<f32, N>,
        limits: &JointLimits<f32, N>,
        from: &Setpoint<N>,
    ) -> Option<Contact<f32>> {
        let rest = rest_point(from, limits);
        let span = rest - from.position;
        let samples = brake_samples(span.amax());
        for i in (0..=samples).rev() {
            let q = from.position + span * (i as f32 / samples as f32);
            if let Some(contact) = self.contact_at(chain, &q) {
                return Some(contact);
            }
        }
        None
    }

    /// Records a stop short of `contact`.
    fn record(&mut self, contact: Contact<f32>) {
        let count = self.last.map_or(1, |l| l.count.wrapping_add(1));
        self.last = Some(CollisionStop { contact, count });
    }
}

impl<const N: usize, const Q: usize> Controller<N, Q> {
    /// The step the limiter produced (`next`, from the setpoint sent last), checked: sent as it
    /// is when its brake segment is free; otherwise the move or stream ends in a brake, or a
    /// hold where even the brake's next step would touch. See the module's notes.
    pub(super) fn guarded(&mut self, next: Setpoint<N>, dt: f32, report: &mut TickReport) -> Setpoint<N> {
        if !self.guard.active() || next.position == self.setpoint.position {
            return next;
        }
        let braking = self.mode == Mode::Stopping;
        let contact = if braking {
            // The brake's own path was checked before it began: only its steps are checked now.
            self.guard.contact_at(&self.chain, &next.position)
        } else {
            self.guard.brake_contact(&self.chain, &self.limits, &next)
        };
        let Some(contact) = contact else { return next };
        self.guard.record(contact);
        if self.move_active {
            let line_length = self.last_move.map_or(0.0, |m| m.line_length);
            self.last_move = Some(MoveOutcome { path: PathTaken::CollisionStopped, blocked_at: None, line_length });
        }
        if !braking {
            self.begin_stop();
            let (desired, velocity) = self.desired(dt, report);
            let brake = limit_step(&self.setpoint, &desired, &velocity, &self.limits, dt);
            if brake.position == self.setpoint.position || self.guard.contact_at(&self.chain, &brake.position).is_none()
            {
                return brake;
            }
        }
        // Not even the brake's next step is free: stay, and hold there.
        self.setpoint.velocity = SVector::zeros();
        self.enter_hold();
        self.setpoint
    }

    /// The contact a target `q` is in, if it is checked and not free: a move to it is refused,
    /// naming the closest pair (once per command, so the full search is affordable).
    pub(super) fn target_contact(&mut self, q: &SVector<f32, N>) -> Option<Contact<f32>> {
        if !self.guard.active() {
            return None;
        }
        let first = self.guard.contact_at(&self.chain, q)?;
        let frames = self.chain.forward(q);
        Some(self.guard.scene.closest(&frames.joints).unwrap_or(first))
    }

    /// What goals are checked against and the last stop.
    pub fn collision(&self) -> &Guard {
        &self.guard
    }

    /// Gives the arm its collision scene; `check` false turns the check off (a test that must see
    /// the arm reach a contact). Clears the last stop.
    pub fn set_collision(&mut self, scene: &ArmScene, check: bool) {
        self.guard.set(scene, check);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use kinematics::nalgebra::Vector2;

    #[test]
    fn a_brake_segment_is_sampled_every_tenth_of_a_radian_up_to_six_times() {
        assert_eq!(brake_samples(0.0), 1);
        assert_eq!(brake_samples(0.05), 1);
        assert_eq!(brake_samples(0.25), 3);
        assert_eq!(brake_samples(5.0), MAX_SAMPLES);
        assert_eq!(brake_samples(f32::NAN), 1);
    }

    /// The synchronised brake from 1 rad/s and 0.5 rad/s at 4 rad/s^2: the slower joint's
    /// deceleration is scaled so both stop together after 0.25 s, each at half its speed times
    /// that time; clamped into the limits.
    #[test]
    fn the_rest_point_is_where_the_synchronised_brake_ends() {
        let limits = JointLimits::new(
            Vector2::repeat(-1.0),
            Vector2::new(1.0, 0.05),
            Vector2::repeat(2.0),
            Vector2::repeat(4.0),
        )
        .unwrap();
        let from = Setpoint { position: Vector2::new(0.1, 0.0), velocity: Vector2::new(1.0, 0.5) };
        let rest = rest_point(&from, &limits);
        assert!((rest[0] - 0.225).abs() < 1e-6, "{rest:?}");
        assert_eq!(rest[1], 0.05, "clamped to the upper limit");
        // The discrete brake of the controller ends within a period's travel of it: stepping
        // at 100 Hz from the same start, as `Mode::Stopping` does.
        let (dt, t) = (0.01f32, 0.25f32);
        let mut p = from.position[0];
        let mut v = from.velocity[0];
        while v > 0.0 {
            v = (v - from.velocity[0] / t * dt).max(0.0);
            p += v * dt;
        }
        assert!(p <= rest[0] + 1e-6 && rest[0] - p <= from.velocity[0] * dt, "{p} against {}", rest[0]);
    }
}
