//! Six rotary joints whose last three axes meet in a point (a spherical wrist) and whose second and
//! third axes are parallel: the PUMA 560 and most industrial arms. The wrist centre's position
//! depends on the first three joints only; they follow from subproblems 4, 3 and 1, and the wrist's
//! three from subproblems 2 and 1. Up to 8 solutions.

use super::geometry::{across, mean_direction, Axes};
use super::subproblems::{free_tolerance, sp1, sp2, sp4};
use super::three_parallel::TwoLink;
use super::{Candidates, Singularity};
use crate::{axis_angle_matrix, Pose, Real};
use nalgebra::{Matrix3, Vector3};

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
        let q1s = sp4(&self.h, &self.h1, &reach, self.along);
        let shoulder = q1s.free;
        for &t1 in q1s.as_slice() {
            let q1 = if shoulder { seed[0] } else { -t1 };
            let r1 = axis_angle_matrix(&self.h1, q1);
            let d = r1.transpose() * reach - self.p12;
            let (pairs, t3s) = self.elbow.solve(&d);
            for &(t2, t3) in pairs.get(..t3s.as_slice().len()).unwrap_or(&[]) {
                let r123 = r1 * axis_angle_matrix(&self.h, t2 + t3);
                let exact = q1s.exact && t3s.exact;
                let singular = if shoulder {
                    Some(Singularity::Shoulder)
                } else if t3s.double {
                    Some(Singularity::Elbow)
                } else {
                    None
                };
                self.wrist(&(r123.transpose() * r), [q1, self.s2 * t2, self.s3 * t3], seed, exact, singular, out);
            }
        }
    }

    /// The wrist's angles for the rotation `w = R4 R5 R6` it must make.
    fn wrist(&self, w: &Matrix3<T>, arm: [T; 3], seed: &[T; 6], exact: bool, singular: Option<Singularity>, out: &mut Candidates<T>) {
        let pointing = w * self.h6;
        // Axis 6 lined up with axis 4: only q4 + q6 is defined; q4 keeps the seed's value.
        let lined_up = (pointing - self.h4 * self.h4.dot(&pointing)).norm() <= free_tolerance::<T>();
        let mut finish = |q4: T, q5: T, singular: Option<Singularity>, exact: bool| {
            let r45 = axis_angle_matrix(&self.h4, q4) * axis_angle_matrix(&self.h5, q5);
            let q6 = sp1(&self.h6, &self.across_h6, &(r45.transpose() * w * self.across_h6));
            out.push([arm[0], arm[1], arm[2], q4, q5, q6], exact, singular);
        };
        if lined_up {
            let q4 = seed[3];
            let q5 = sp1(&self.h5, &self.h6, &(axis_angle_matrix(&self.h4, q4).transpose() * pointing));
            finish(q4, q5, Some(Singularity::Wrist), exact);
            return;
        }
        let (pairs, count, wrist_exact) = sp2(&self.h4, &pointing, &self.h5, &self.h6);
        for &(minus_q4, q5) in pairs.get(..count).unwrap_or(&[]) {
            finish(-minus_q4, q5, singular, exact && wrist_exact);
        }
    }
}
