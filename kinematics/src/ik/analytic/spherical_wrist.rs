//! Six rotary joints whose last three axes meet in a point (a spherical wrist) and whose second and
//! third axes are parallel: the PUMA 560 and most industrial arms. The wrist centre's position
//! depends on the first three joints only; they follow from subproblems 4, 3 and 1, and the wrist's
//! three from subproblems 2 and 1. Up to 8 solutions.

use super::geometry::{across, mean_direction, Axes};
use super::subproblems::{free_tolerance, rotate, sp1, sp2, sp4};
use super::three_parallel::TwoLink;
use super::{Candidates, Singularity};
use crate::{Pose, Real};
use nalgebra::Vector3;

/// The shape's constants, from the chain's axes.
#[derive(Clone, Copy, Debug)]
pub struct SphericalWrist<T: Real> {
    h1: Vector3<T>,
    p1: Vector3<T>,
    /// Direction of the parallel axes 2 and 3, and each one's sign against it.
    h: Vector3<T>,
    s2: T,
    s3: T,
    h4: Vector3<T>,
    h5: Vector3<T>,
    h6: Vector3<T>,
    p12: Vector3<T>,
    /// Axes 2 and 3, to the wrist centre.
    elbow: TwoLink<T>,
    /// The tool's origin from the wrist centre, and its rotation, at the zero configuration.
    tool: Pose<T>,
    /// Along `h`, the part of the wrist centre's offset no joint changes.
    along: T,
    across_h6: Vector3<T>,
}

impl<T: Real> SphericalWrist<T> {
    /// The shape in `axes`, if they have it.
    pub fn detect<const N: usize>(axes: &Axes<T, N>) -> Option<Self> {
        if N != 6 {
            return None;
        }
        let s3 = axes.parallel(1, 2)?;
        if axes.parallel(0, 1).is_some() {
            return None;
        }
        let c = axes.meeting_point(&[3, 4, 5])?;
        let h = mean_direction(&[(axes.h[1], T::one()), (axes.h[2], s3)]);
        let p12 = axes.p[1] - axes.p[0];
        let elbow = TwoLink { h, p23: axes.p[2] - axes.p[1], p34: c - axes.p[2] };
        Some(Self {
            h1: axes.h[0],
            p1: axes.p[0],
            h,
            s2: T::one(),
            s3,
            h4: axes.h[3],
            h5: axes.h[4],
            h6: axes.h[5],
            p12,
            elbow,
            tool: Pose { rotation: axes.tool.rotation, translation: axes.tool.translation - c },
            along: h.dot(&(p12 + elbow.p23 + elbow.p34)),
            across_h6: across(&axes.h[5]),
        })
    }

    /// Every solution for the tool pose `target`; `seed` fills the angles a singular pose leaves
    /// free.
    pub fn solve(&self, target: &Pose<T>, seed: &[T; 6], out: &mut Candidates<T>) {
        let r = target.rotation * self.tool.rotation.transpose();
        let reach = target.translation - self.p1 - r * self.tool.translation;
        // The wrist's rotation W = (R1 R2 R3)^T r is needed on two vectors only: h6 and one across
        // it. Both are turned back by Rodrigues' formula, R^T x being rotate(h, -q, x).
        let (r_h6, r_across) = (r * self.h6, r * self.across_h6);
        let q1s = sp4(&self.h, &self.h1, &reach, self.along);
        let shoulder = q1s.free;
        for &t1 in q1s.as_slice() {
            let q1 = if shoulder { seed[0] } else { -t1 };
            let d = rotate(&self.h1, -q1, &reach) - self.p12;
            let (back_h6, back_across) = (rotate(&self.h1, -q1, &r_h6), rotate(&self.h1, -q1, &r_across));
            let (pairs, t3s) = self.elbow.solve(&d);
            for &(t2, t3) in pairs.get(..t3s.as_slice().len()).unwrap_or(&[]) {
                let exact = q1s.exact && t3s.exact;
                let singular = if shoulder {
                    Some(Singularity::Shoulder)
                } else if t3s.double {
                    Some(Singularity::Elbow)
                } else {
                    None
                };
                let w_h6 = rotate(&self.h, -(t2 + t3), &back_h6);
                let w_across = rotate(&self.h, -(t2 + t3), &back_across);
                self.wrist(&w_h6, &w_across, [q1, self.s2 * t2, self.s3 * t3], seed, exact, singular, out);
            }
        }
    }

    /// The wrist's angles for the rotation `W = R4 R5 R6` it must make, given as `W h6` and
    /// `W a` (`a` across h6).
    #[allow(clippy::too_many_arguments)]
    fn wrist(
        &self,
        pointing: &Vector3<T>,
        w_across: &Vector3<T>,
        arm: [T; 3],
        seed: &[T; 6],
        exact: bool,
        singular: Option<Singularity>,
        out: &mut Candidates<T>,
    ) {
        // Axis 6 lined up with axis 4: only q4 + q6 is defined; q4 keeps the seed's value.
        let lined_up = (pointing - self.h4 * self.h4.dot(pointing)).norm() <= free_tolerance::<T>();
        let mut finish = |q4: T, q5: T, singular: Option<Singularity>, exact: bool| {
            // R6 a = R5^T R4^T W a.
            let turned = rotate(&self.h5, -q5, &rotate(&self.h4, -q4, w_across));
            let q6 = sp1(&self.h6, &self.across_h6, &turned);
            out.push([arm[0], arm[1], arm[2], q4, q5, q6], exact, singular);
        };
        if lined_up {
            let q4 = seed[3];
            let q5 = sp1(&self.h5, &self.h6, &rotate(&self.h4, -q4, pointing));
            finish(q4, q5, Some(Singularity::Wrist), exact);
            return;
        }
        let (pairs, count, wrist_exact) = sp2(&self.h4, pointing, &self.h5, &self.h6);
        for &(minus_q4, q5) in pairs.get(..count).unwrap_or(&[]) {
            finish(-minus_q4, q5, singular, exact && wrist_exact);
        }
    }
}
