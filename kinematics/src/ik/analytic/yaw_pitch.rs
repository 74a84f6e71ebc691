//! The hobby-arm shape: a base yaw, then three parallel pitch axes (shoulder, elbow, wrist), and
//! optionally a wrist roll last: the SO-100/SO-101, Koch and OpenManipulator-X. Four or five
//! joints cannot reach every pose, so the target is the tool's position plus its pitch (the sum
//! of the three pitch angles): from a pose target's orientation, or, for a position target, the
//! pitch whose solution lies nearest the seed (with the seed's roll). Up to 4 solutions: the arm
//! facing the target or turned over the top, each elbow up or down.

use super::geometry::{across, mean_direction, Axes};
use super::subproblems::{sp1, sp4};
use super::three_parallel::TwoLink;
use super::{Candidates, Singularity};
use crate::ik::Target;
use crate::{axis_angle_matrix, Pose, Real};
use nalgebra::{Matrix3, Vector3};

/// A position target's first reachable pitch is searched this far either side of the seed's, in
/// steps of [`PITCH_STEP`] (radians), nearest first.
const PITCH_STEPS: u32 = 90;
const PITCH_STEP: f64 = core::f64::consts::PI / 90.0;

/// From there, the pitch nearest the seed is searched this far either side (radians): a scan in
/// `COARSE_STEPS` steps each way, then golden-section steps around the best (its two neighbours'
/// interval shrinks to 0.618^16 of itself, 4e-5 rad).
const PITCH_WINDOW: f64 = 0.35;
const COARSE_STEPS: u32 = 8;
const GOLDEN_STEPS: u32 = 16;

/// The shape's constants, from the chain's axes.
#[derive(Clone, Copy, Debug)]
pub struct YawPitch<T: Real> {
    joints: usize,
    h1: Vector3<T>,
    p1: Vector3<T>,
    /// Direction of the pitch axes, and each one's sign against it.
    h: Vector3<T>,
    signs: [T; 3],
    p12: Vector3<T>,
    elbow: TwoLink<T>,
    /// The roll axis (five joints), and from axis 4's point to it.
    h5: Vector3<T>,
    p45: Vector3<T>,
    /// The tool's origin from the last axis's point, and its rotation, at the zero configuration.
    tool: Pose<T>,
    along: T,
    across_h: Vector3<T>,
}

impl<T: Real> YawPitch<T> {
    /// The shape in `axes`, if they have it.
    pub fn detect<const N: usize>(axes: &Axes<T, N>) -> Option<Self> {
        if N != 4 && N != 5 {
            return None;
        }
        let (s3, s4) = (axes.parallel(1, 2)?, axes.parallel(1, 3)?);
        if axes.parallel(0, 1).is_some() {
            return None;
        }
        let h = mean_direction(&[(axes.h[1], T::one()), (axes.h[2], s3), (axes.h[3], s4)]);
        let last = N - 1;
        let (h5, p45) = if N == 5 { (axes.h[4], axes.p[4] - axes.p[3]) } else { (h, Vector3::zeros()) };
        let p12 = axes.p[1] - axes.p[0];
        let elbow = TwoLink { h, p23: axes.p[2] - axes.p[1], p34: axes.p[3] - axes.p[2] };
        Some(Self {
            joints: N,
            h1: axes.h[0],
            p1: axes.p[0],
            h,
            signs: [T::one(), s3, s4],
            p12,
            elbow,
            h5,
            p45,
            tool: Pose { rotation: axes.tool.rotation, translation: axes.tool.translation - axes.p[last] },
            along: h.dot(&(p12 + elbow.p23 + elbow.p34 + p45)),
            across_h: across(&h),
        })
    }

    /// Every solution for `target`. `cost` gives a joint vector's distance from the seed, or
    /// `None` if it is outside the limits: a position target's pitch is the one whose solution is
    /// nearest the seed (see [`YawPitch::pitch_nearest_the_seed`]).
    pub fn solve(
        &self,
        target: &Target<T>,
        seed: &[T; 6],
        cost: &dyn Fn(&[T; 6]) -> Option<T>,
        out: &mut Candidates<T>,
    ) {
        match target {
            Target::Pose(pose) => {
                // All the joints together turn the tool's offset from the last axis to
                // `r * offset`, known before any angle is: what is left is reached by the yaw and
                // the pitch joints.
                let r = pose.rotation * self.tool.rotation.transpose();
                let reach = pose.translation - self.p1 - r * self.tool.translation;
                self.solve_at(&reach, &self.p45, seed, out, |r1| {
                    // The roll from the orientation: rot(h5, -q5) h = r^T R1 h.
                    let q5 = if self.joints == 5 {
                        -sp1(&self.h5, &self.h, &(r.transpose() * r1 * self.h))
                    } else {
                        T::zero()
                    };
                    let m = r1.transpose() * r * self.roll(q5).transpose();
                    (sp1(&self.h, &self.across_h, &(m * self.across_h)), q5)
                });
            }
            Target::Position(p) => {
                let roll = if self.joints == 5 { seed[4] } else { T::zero() };
                let tail = self.p45 + self.roll(roll) * self.tool.translation;
                let reach = p - self.p1;
                let at = |theta: T, out: &mut Candidates<T>| self.solve_at(&reach, &tail, seed, out, |_| (theta, roll));
                if let Some(theta) = self.pitch_nearest_the_seed(seed, &at, cost) {
                    at(theta, out);
                }
            }
            // Not answered (see `ClosedForm::answers`): no candidates, the numerical solver takes it.
            Target::Tilt(_) => {}
        }
    }

    /// For a position target, the pitch is free: the one whose best solution (exact, within the
    /// limits) lies nearest the seed, so that a tool moved a little moves the joints a little (a
    /// stream of targets, retargeted motion, never flips the arm). From the seed's own pitch, or
    /// the nearest reachable one found by widening in steps either side, a scan over
    /// [`PITCH_WINDOW`] either side and a golden-section search around its best find the minimum. `None` if no pitch within half a turn
    /// reaches within the limits.
    fn pitch_nearest_the_seed(
        &self,
        seed: &[T; 6],
        at: &dyn Fn(T, &mut Candidates<T>),
        cost: &dyn Fn(&[T; 6]) -> Option<T>,
    ) -> Option<T> {
        let [s2, s3, s4] = self.signs;
        let pitch = s2 * seed[1] + s3 * seed[2] + s4 * seed[3];
        let best = |theta: T| {
            let mut found = Candidates::new();
            at(theta, &mut found);
            found
                .iter()
                .filter(|(_, exact, _)| *exact)
                .filter_map(|(q, _, _)| cost(q))
                .fold(None, |b: Option<T>, c| Some(b.map_or(c, |b| b.min(c))))
        };
        let start = (0..=2 * PITCH_STEPS).find_map(|step| {
            // 0, +1, -1, +2, -2, ... steps from the seed's pitch.
            let k = T::of(f64::from(step.div_ceil(2)) * PITCH_STEP);
            let theta = if step % 2 == 1 { pitch + k } else { pitch - k };
            best(theta).map(|_| theta)
        })?;
        let f = |theta: T| best(theta).unwrap_or_else(|| T::of(f64::MAX));
        // A coarse scan first: near a joint limit the seed's own branch can reach over a window
        // narrower than a golden-section search's first probes, which would then settle on
        // another branch's minimum.
        let step = T::of(PITCH_WINDOW / f64::from(COARSE_STEPS));
        let (mut centre, mut lowest) = (start, f(start));
        for k in 1..=COARSE_STEPS {
            for theta in [start + step * T::of(f64::from(k)), start - step * T::of(f64::from(k))] {
                let value = f(theta);
                if value < lowest {
                    (centre, lowest) = (theta, value);
                }
            }
        }
        let (mut a, mut b) = (centre - step, centre + step);
        let ratio = T::of(0.618_033_988_749_894_8);
        let (mut c, mut d) = (b - (b - a) * ratio, a + (b - a) * ratio);
        let (mut fc, mut fd) = (f(c), f(d));
        for _ in 0..GOLDEN_STEPS {
            if fc < fd {
                (b, d, fd) = (d, c, fc);
                c = b - (b - a) * ratio;
                fc = f(c);
            } else {
                (a, c, fc) = (c, d, fd);
                d = a + (b - a) * ratio;
                fd = f(d);
            }
        }
        let middle = (a + b) * T::of(0.5);
        Some(if f(middle) < lowest { middle } else { centre })
    }

    fn roll(&self, q5: T) -> Matrix3<T> {
        if self.joints == 5 {
            axis_angle_matrix(&self.h5, q5)
        } else {
            Matrix3::identity()
        }
    }

    /// The solutions for `reach` (the target less axis 1's point and any offset already known in
    /// the base frame), where `tail` follows the pitch joints in their own frame, and
    /// `pitch_and_roll` gives the pitch and roll for each base yaw's rotation.
    fn solve_at(
        &self,
        reach: &Vector3<T>,
        tail: &Vector3<T>,
        seed: &[T; 6],
        out: &mut Candidates<T>,
        pitch_and_roll: impl Fn(&Matrix3<T>) -> (T, T),
    ) {
        // Along the pitch axes only the yaw moves the tool, so the yaw comes first.
        let along = self.along - self.h.dot(&self.p45) + self.h.dot(tail);
        let q1s = sp4(&self.h, &self.h1, reach, along);
        let [s2, s3, s4] = self.signs;
        for &t1 in q1s.as_slice() {
            let q1 = if q1s.free { seed[0] } else { -t1 };
            let r1 = axis_angle_matrix(&self.h1, q1);
            let (theta, q5) = pitch_and_roll(&r1);
            let d = r1.transpose() * reach - self.p12 - axis_angle_matrix(&self.h, theta) * tail;
            let (pairs, t3s) = self.elbow.solve(&d);
            let singular = if q1s.free {
                Some(Singularity::Shoulder)
            } else if t3s.double {
                Some(Singularity::Elbow)
            } else {
                None
            };
            for &(t2, t3) in pairs.get(..t3s.as_slice().len()).unwrap_or(&[]) {
                let q = [q1, s2 * t2, s3 * t3, s4 * (theta - t2 - t3), q5, T::zero()];
                out.push(q, q1s.exact && t3s.exact, singular);
            }
        }
    }
}
