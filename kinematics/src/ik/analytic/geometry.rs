//! A chain's geometry as the closed forms read it: every joint's axis as a line in the base frame
//! at the zero configuration (the product-of-exponentials form, `T(q) = exp(xi_1 q_1) ...
//! exp(xi_N q_N) T(0)`), and the tests that find the known shapes in it, with a stated tolerance.

use crate::{Chain, JointKind, Pose, Real};
use nalgebra::{SVector, Vector3};

/// Two axes count as parallel when the sine of the angle between them is at most this, and as
/// meeting when the lines pass within [`MEET_TOLERANCE`] of each other. Wide enough for a URDF's
/// rounded numbers (pi written as 3.14159 tilts an axis by 3e-6 rad), narrow enough that the
/// idealised shape's answer lies a few polishing iterations from the chain's own: every closed-form
/// answer is checked by forward kinematics on the chain itself, and polished where it falls short.
pub const PARALLEL_TOLERANCE: f64 = 1e-4;

/// See [`PARALLEL_TOLERANCE`] (metres).
pub const MEET_TOLERANCE: f64 = 1e-5;

/// The lines of the joint axes at the zero configuration, and the tool there.
#[derive(Clone, Copy, Debug)]
pub struct Axes<T: Real, const N: usize> {
    /// Unit direction of each axis (base frame).
    pub h: [Vector3<T>; N],
    /// A point on each axis: the joint frame's origin.
    pub p: [Vector3<T>; N],
    /// The tool frame at the zero configuration.
    pub tool: Pose<T>,
}

impl<T: Real, const N: usize> Axes<T, N> {
    /// The axes of `chain`, or `None` if a joint is not rotary (a prismatic or fixed joint fits
    /// none of the closed forms).
    pub fn of(chain: &Chain<T, N>) -> Option<Self> {
        if chain.joints().iter().any(|j| !matches!(j.kind, JointKind::Revolute | JointKind::Continuous)) {
            return None;
        }
        let frames = chain.forward(&SVector::zeros());
        let h = core::array::from_fn(|k| frames.joints[k].rotation * chain.joints()[k].axis);
        let p = core::array::from_fn(|k| frames.joints[k].translation);
        Some(Self { h, p, tool: frames.tool })
    }

    /// The sign that turns axis `j` into the direction of axis `i` if the two are parallel
    /// (either way round), else `None`.
    pub fn parallel(&self, i: usize, j: usize) -> Option<T> {
        let (a, b) = (self.h.get(i)?, self.h.get(j)?);
        if a.cross(b).norm() > T::of(PARALLEL_TOLERANCE) {
            return None;
        }
        Some(if a.dot(b) >= T::zero() { T::one() } else { -T::one() })
    }

    /// The point where the axes `indices` (two or more) meet, if they do: the point nearest all
    /// of them in the least-squares sense, within [`MEET_TOLERANCE`] of each. Parallel axes
    /// count only if they are one line (a wrist's first and last axes at the zero configuration);
    /// `None` if no two cross, so that no single point is defined.
    pub fn meeting_point(&self, indices: &[usize]) -> Option<Vector3<T>> {
        // Minimise sum |(I - h h^T)(x - p)|^2: (sum P_i) x = sum P_i p_i.
        let mut a = nalgebra::Matrix3::<T>::zeros();
        let mut b = Vector3::<T>::zeros();
        for (n, &i) in indices.iter().enumerate() {
            let (h, p) = (self.h.get(i)?, self.p.get(i)?);
            for &j in indices.get(..n)? {
                if self.parallel(i, j).is_some() && distance_to_line(p, &self.h[j], &self.p[j]) > T::of(MEET_TOLERANCE)
                {
                    return None;
                }
            }
            let projector = nalgebra::Matrix3::identity() - h * h.transpose();
            a += projector;
            b += projector * p;
        }
        // Lines that are all one direction leave `a` singular: no single point.
        let x = a.try_inverse()? * b;
        let near = indices.iter().all(|&i| distance_to_line(&x, &self.h[i], &self.p[i]) <= T::of(MEET_TOLERANCE));
        near.then_some(x)
    }
}

/// Distance of `x` from the line through `p` along the unit `h`.
fn distance_to_line<T: Real>(x: &Vector3<T>, h: &Vector3<T>, p: &Vector3<T>) -> T {
    let d = x - p;
    (d - h * h.dot(&d)).norm()
}

/// The mean direction of parallel axes, each turned by its sign to agree with the first.
pub fn mean_direction<T: Real>(directions: &[(Vector3<T>, T)]) -> Vector3<T> {
    let sum = directions.iter().fold(Vector3::zeros(), |acc, (h, s)| acc + h * *s);
    sum.normalize()
}

/// A unit vector across `h`.
pub fn across<T: Real>(h: &Vector3<T>) -> Vector3<T> {
    let other = if h.x.abs() < T::of(0.9) { Vector3::x() } else { Vector3::y() };
    h.cross(&other).normalize()
}
