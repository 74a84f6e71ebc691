//! Six rotary joints whose second, third and fourth axes are parallel and whose fifth and sixth
//! axes meet: the Universal Robots family. Rotations about parallel axes leave the component along
//! them unchanged, which gives the first and fifth joints by subproblem 4 each, the sixth and the
//! sum of the parallel three by subproblem 1, and the planar two-link elbow by subproblems 3 and 1.
//! Up to 8 solutions.

use super::geometry::{across, mean_direction, Axes};
use super::subproblems::{free_tolerance, rotate, sp1, sp3, sp4, Angles};
use super::{Candidates, Singularity};
use crate::{Pose, Real};
use nalgebra::Vector3;

/// The shape's constants, from the chain's axes.
#[derive(Clone, Copy, Debug)]
pub struct ThreeParallel<T: Real> {
    h1: Vector3<T>,
    p1: Vector3<T>,
    /// Direction of axes 2 to 4, and each one's sign against it.
    h: Vector3<T>,
    signs: [T; 3],
    h5: Vector3<T>,
    h6: Vector3<T>,
    p12: Vector3<T>,
    elbow: TwoLink<T>,
    /// From axis 4's point to where axes 5 and 6 meet.
    p45: Vector3<T>,
    /// The tool's origin from that point, and its rotation, at the zero configuration.
    tool: Pose<T>,
    along: T,
    across_h: Vector3<T>,
}

/// The planar two-link elbow of parallel axes: angles `t2`, `t3` about `h` with
/// `rot(h, t2) (p23 + rot(h, t3) p34) = d`.
#[derive(Clone, Copy, Debug)]
pub struct TwoLink<T: Real> {
    /// The direction of the parallel axes.
    pub h: Vector3<T>,
    /// From the first axis's point to the second's.
    pub p23: Vector3<T>,
    /// From the second axis's point to the link's end.
    pub p34: Vector3<T>,
}

impl<T: Real> TwoLink<T> {
    /// The elbow's solutions `(t2, t3)` for the point `d`, and whether they reach it.
    pub fn solve(&self, d: &Vector3<T>) -> ([(T, T); 2], Angles<T>) {
        let t3s = sp3(&self.h, &self.p34, &(-self.p23), d.norm());
        let mut pairs = [(T::zero(), T::zero()); 2];
        for (pair, &t3) in pairs.iter_mut().zip(t3s.as_slice()) {
            let arm = self.p23 + rotate(&self.h, t3, &self.p34);
            *pair = (sp1(&self.h, &arm, d), t3);
        }
        (pairs, t3s)
    }
}

impl<T: Real> ThreeParallel<T> {
    /// The shape in `axes`, if they have it.
    pub fn detect<const N: usize>(axes: &Axes<T, N>) -> Option<Self> {
        if N != 6 {
            return None;
        }
        let (s3, s4) = (axes.parallel(1, 2)?, axes.parallel(1, 3)?);
        if axes.parallel(0, 1).is_some() || axes.parallel(1, 4).is_some() {
            return None;
        }
        let c = axes.meeting_point(&[4, 5])?;
        let h = mean_direction(&[(axes.h[1], T::one()), (axes.h[2], s3), (axes.h[3], s4)]);
        let p12 = axes.p[1] - axes.p[0];
        let elbow = TwoLink { h, p23: axes.p[2] - axes.p[1], p34: axes.p[3] - axes.p[2] };
        let p45 = c - axes.p[3];
        Some(Self {
            h1: axes.h[0],
            p1: axes.p[0],
            h,
            signs: [T::one(), s3, s4],
            h5: axes.h[4],
            h6: axes.h[5],
            p12,
            elbow,
            p45,
            tool: Pose { rotation: axes.tool.rotation, translation: axes.tool.translation - c },
            along: h.dot(&(p12 + elbow.p23 + elbow.p34 + p45)),
            across_h: across(&h),
        })
    }

    /// Every solution for the tool pose `target`; `seed` fills the angles a singular pose leaves
    /// free.
    pub fn solve(&self, target: &Pose<T>, seed: &[T; 6], out: &mut Candidates<T>) {
        let r = target.rotation * self.tool.rotation.transpose();
        let reach = target.translation - self.p1 - r * self.tool.translation;
        let r_h6 = r * self.h6;
        let q1s = sp4(&self.h, &self.h1, &reach, self.along);
        for &t1 in q1s.as_slice() {
            let q1 = if q1s.free { seed[0] } else { -t1 };
            // Vectors only, turned by Rodrigues' formula: R1^T x is rotate(h1, -q1, x).
            let q5s = sp4(&self.h, &self.h5, &self.h6, self.h.dot(&rotate(&self.h1, -q1, &r_h6)));
            let to = r.transpose() * rotate(&self.h1, q1, &self.h);
            let reach_1 = rotate(&self.h1, -q1, &reach);
            for &q5 in q5s.as_slice() {
                let from = rotate(&self.h5, -q5, &self.h);
                // Axis 6 along the parallel axes: only q6 plus their sum is defined; q6 keeps the
                // seed's value.
                let wrist = (from - self.h6 * self.h6.dot(&from)).norm() <= free_tolerance::<T>();
                let q6 = if wrist { seed[5] } else { -sp1(&self.h6, &from, &to) };
                // rot(h, theta) = R1^T r R6^T R5^T, read off one vector across h.
                let turned = rotate(&self.h6, -q6, &rotate(&self.h5, -q5, &self.across_h));
                let theta = sp1(&self.h, &self.across_h, &rotate(&self.h1, -q1, &(r * turned)));
                let d = reach_1 - self.p12 - rotate(&self.h, theta, &self.p45);
                let (pairs, t3s) = self.elbow.solve(&d);
                let singular = if q1s.free {
                    Some(Singularity::Shoulder)
                } else if wrist {
                    Some(Singularity::Wrist)
                } else if t3s.double {
                    Some(Singularity::Elbow)
                } else {
                    None
                };
                for &(t2, t3) in pairs.get(..t3s.as_slice().len()).unwrap_or(&[]) {
                    let [s2, s3, s4] = self.signs;
                    let q = [q1, s2 * t2, s3 * t3, s4 * (theta - t2 - t3), q5, q6];
                    out.push(q, q1s.exact && q5s.exact && t3s.exact, singular);
                }
            }
        }
    }
}
