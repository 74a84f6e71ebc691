//! Rigid transforms as a rotation matrix and a translation.
//!
//! Matrices rather than quaternions because FK composes one transform per joint and a 3x3 product
//! is cheaper than a quaternion product followed by a conversion for every Jacobian column.

use crate::Real;
use nalgebra::{Matrix3, Vector3, Vector4};

/// A rigid transform: `p_parent = rotation * p_child + translation`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pose<T: Real> {
    /// Orthonormal rotation matrix (columns are the child axes in the parent frame).
    pub rotation: Matrix3<T>,
    /// Child origin in the parent frame, metres.
    pub translation: Vector3<T>,
}

impl<T: Real> Default for Pose<T> {
    fn default() -> Self {
        Self::identity()
    }
}

impl<T: Real> Pose<T> {
    /// The identity transform.
    pub fn identity() -> Self {
        Self { rotation: Matrix3::identity(), translation: Vector3::zeros() }
    }

    /// A pure translation.
    pub fn from_translation(translation: Vector3<T>) -> Self {
        Self { rotation: Matrix3::identity(), translation }
    }

    /// URDF `<origin xyz rpy>`: translation, then fixed-axis roll about x, pitch about y, yaw about
    /// z, i.e. `R = Rz(yaw) * Ry(pitch) * Rx(roll)` (URDF specification, joint origin).
    pub fn from_xyz_rpy(xyz: [T; 3], rpy: [T; 3]) -> Self {
        let (sr, cr) = rpy[0].sin_cos_fast();
        let (sp, cp) = rpy[1].sin_cos_fast();
        let (sy, cy) = rpy[2].sin_cos_fast();
        #[rustfmt::skip]
        let rotation = Matrix3::new(
            cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr,
            sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr,
            -sp,     cp * sr,                cp * cr,
        );
        Self { rotation, translation: Vector3::new(xyz[0], xyz[1], xyz[2]) }
    }

    /// Rotation by `angle` about the unit vector `axis` (Rodrigues' formula).
    pub fn from_axis_angle(axis: &Vector3<T>, angle: T) -> Self {
        Self { rotation: axis_angle_matrix(axis, angle), translation: Vector3::zeros() }
    }

    /// Rotation from a unit quaternion given w first. The quaternion is normalised here; a zero
    /// quaternion gives `None`.
    pub fn rotation_from_quaternion_wxyz(q: [T; 4]) -> Option<Matrix3<T>> {
        let v = Vector4::new(q[0], q[1], q[2], q[3]);
        let n = v.norm();
        // NaN norms fail the comparison and are rejected with the zero quaternion.
        #[allow(clippy::neg_cmp_op_on_partial_ord)]
        if !(n > T::EPSILON) || !n.finite() {
            return None;
        }
        let (w, x, y, z) = (q[0] / n, q[1] / n, q[2] / n, q[3] / n);
        let two = T::of(2.0);
        let one = T::one();
        #[rustfmt::skip]
        let m = Matrix3::new(
            one - two * (y * y + z * z), two * (x * y - w * z), two * (x * z + w * y),
            two * (x * y + w * z), one - two * (x * x + z * z), two * (y * z - w * x),
            two * (x * z - w * y), two * (y * z + w * x), one - two * (x * x + y * y),
        );
        Some(m)
    }

    /// `self * other`: first `other`, then `self`.
    ///
    /// Written out entry by entry: nalgebra's general product runs as loops, which the firmware's
    /// size-optimised build does not unroll, and FK spends most of its time here (a third fewer
    /// instructions on the M4F this way). `tests/fk.rs` checks it against published poses.
    #[inline]
    pub fn compose(&self, other: &Self) -> Self {
        let a = &*self.rotation;
        let b = &*other.rotation;
        let t = &*other.translation;
        let p = &*self.translation;
        #[rustfmt::skip]
        let rotation = Matrix3::new(
            a.m11 * b.m11 + a.m12 * b.m21 + a.m13 * b.m31, a.m11 * b.m12 + a.m12 * b.m22 + a.m13 * b.m32, a.m11 * b.m13 + a.m12 * b.m23 + a.m13 * b.m33,
            a.m21 * b.m11 + a.m22 * b.m21 + a.m23 * b.m31, a.m21 * b.m12 + a.m22 * b.m22 + a.m23 * b.m32, a.m21 * b.m13 + a.m22 * b.m23 + a.m23 * b.m33,
            a.m31 * b.m11 + a.m32 * b.m21 + a.m33 * b.m31, a.m31 * b.m12 + a.m32 * b.m22 + a.m33 * b.m32, a.m31 * b.m13 + a.m32 * b.m23 + a.m33 * b.m33,
        );
        let translation = Vector3::new(
            a.m11 * t.x + a.m12 * t.y + a.m13 * t.z + p.x,
            a.m21 * t.x + a.m22 * t.y + a.m23 * t.z + p.y,
            a.m31 * t.x + a.m32 * t.y + a.m33 * t.z + p.z,
        );
        Self { rotation, translation }
    }

    /// The inverse transform.
    pub fn inverse(&self) -> Self {
        let rt = self.rotation.transpose();
        Self { rotation: rt, translation: -(rt * self.translation) }
    }

    /// Unit quaternion of the rotation, `[w, x, y, z]` with `w >= 0`.
    pub fn quaternion_wxyz(&self) -> [T; 4] {
        quaternion_wxyz(&self.rotation)
    }
}

/// Rodrigues: `R = I + sin(a) K + (1 - cos(a)) K^2` for the unit axis `k`.
#[inline]
pub fn axis_angle_matrix<T: Real>(k: &Vector3<T>, angle: T) -> Matrix3<T> {
    let (s, c) = angle.sin_cos_fast();
    let v = T::one() - c;
    let (x, y, z) = (k.x, k.y, k.z);
    #[rustfmt::skip]
    let m = Matrix3::new(
        c + x * x * v,     x * y * v - z * s, x * z * v + y * s,
        y * x * v + z * s, c + y * y * v,     y * z * v - x * s,
        z * x * v - y * s, z * y * v + x * s, c + z * z * v,
    );
    m
}

/// Shepperd's method: take the square root of the largest of the four diagonal combinations so
/// that the division is never by a small number (accurate at every angle, including pi).
pub fn quaternion_wxyz<T: Real>(r: &Matrix3<T>) -> [T; 4] {
    let one = T::one();
    let (m00, m11, m22) = (r[(0, 0)], r[(1, 1)], r[(2, 2)]);
    let trace = m00 + m11 + m22;
    let q = if trace >= m00 && trace >= m11 && trace >= m22 {
        let s = (one + trace).max(T::zero()).sqrt() * T::of(2.0);
        [s * T::of(0.25), (r[(2, 1)] - r[(1, 2)]) / s, (r[(0, 2)] - r[(2, 0)]) / s, (r[(1, 0)] - r[(0, 1)]) / s]
    } else if m00 >= m11 && m00 >= m22 {
        let s = (one + m00 - m11 - m22).max(T::zero()).sqrt() * T::of(2.0);
        [(r[(2, 1)] - r[(1, 2)]) / s, s * T::of(0.25), (r[(0, 1)] + r[(1, 0)]) / s, (r[(0, 2)] + r[(2, 0)]) / s]
    } else if m11 >= m22 {
        let s = (one - m00 + m11 - m22).max(T::zero()).sqrt() * T::of(2.0);
        [(r[(0, 2)] - r[(2, 0)]) / s, (r[(0, 1)] + r[(1, 0)]) / s, s * T::of(0.25), (r[(1, 2)] + r[(2, 1)]) / s]
    } else {
        let s = (one - m00 - m11 + m22).max(T::zero()).sqrt() * T::of(2.0);
        [(r[(1, 0)] - r[(0, 1)]) / s, (r[(0, 2)] + r[(2, 0)]) / s, (r[(1, 2)] + r[(2, 1)]) / s, s * T::of(0.25)]
    };
    let n = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]).sqrt();
    let sign = if q[0] < T::zero() { -one } else { one };
    let k = sign / n;
    [q[0] * k, q[1] * k, q[2] * k, q[3] * k]
}

/// The rotation vector `w` (axis times angle, angle in [0, pi]) with `exp([w]x) = target * current^T`,
/// i.e. the world-frame rotation that carries `current` onto `target`.
pub fn rotation_error<T: Real>(target: &Matrix3<T>, current: &Matrix3<T>) -> Vector3<T> {
    let q = quaternion_wxyz(&(target * current.transpose()));
    let v = Vector3::new(q[1], q[2], q[3]);
    let s = v.norm();
    // angle = 2 atan2(|v|, w); w >= 0 so the angle is at most pi (shortest rotation).
    // For small |v|, 2 atan2(s, w) / s -> 2 / w, which keeps the gradient well defined at 0.
    let scale = if s > T::EPSILON { T::of(2.0) * s.atan2(q[0]) / s } else { T::of(2.0) / q[0] };
    v * scale
}
