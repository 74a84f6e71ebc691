//! Orientation interpolation: unit-quaternion SLERP and a C1 SQUAD curve through timed
//! orientations (Cartesian tool keyframes).
//!
//! Quaternions are `[w, x, y, z]`, w first, as everywhere in this crate. [`Quaternion`] is always
//! unit (to rounding) and finite: every constructor normalises and refuses a zero, NaN or infinite
//! input with [`RotationError`], and every operation renormalises its result.
//!
//! Exp and log follow Shoemake (1987): for `q = (cos a, n sin a)` with unit `n`,
//! `log q = a n` (a pure quaternion, returned as a vector) and `exp(a n) = q`. The rotation angle of
//! `q` is `2a`, so the rotation vector of `q` is `2 log q`, and a world-frame angular velocity is
//! `omega = 2 q' q*`.
//!
//! # SQUAD on non-uniform times
//!
//! Segment `i` (from keyframe `i` at `t_i` to keyframe `i + 1`, `h = (t - t_i) / d_i`,
//! `d_i = t_{i+1} - t_i`) is Shoemake's
//! `squad(h) = slerp(slerp(q_i, q_{i+1}, h), slerp(a_i, b_{i+1}, h), 2h(1 - h))`, whose derivative in
//! `h` is `q_i (L_i + 2 log(q_i* a_i))` at `h = 0` and `q_{i+1} (L_i - 2 log(q_{i+1}* b_{i+1}))` at
//! `h = 1`, with `L_i = log(q_i* q_{i+1})`.
//!
//! Shoemake's control quaternion `s_i = q_i exp(-(log(q_i* q_{i+1}) + log(q_i* q_{i-1})) / 4)` is
//! used for both `a_i` and `b_i`; it makes these two derivatives equal to `q_i (L_i + L_{i-1}) / 2`
//! per unit of `h`, which is C1 in time only when `d_{i-1} = d_i`. For non-uniform times the
//! tangent is scaled by the neighbouring interval lengths (the Kochanek-Bartels / non-uniform
//! Catmull-Rom adjustment): the body-frame velocity at keyframe `i` is the central difference
//! `V_i = (L_{i-1} + L_i) / (d_{i-1} + d_i)` per second, the outgoing tangent is `T_out = d_i V_i`
//! and the incoming one `T_in = d_{i-1} V_i` (per unit `h` of their segments), and separate
//! controls are solved from the derivative formulas above:
//! `a_i = q_i exp((T_out - L_i) / 2)` and `b_i = q_i exp((L_{i-1} - T_in) / 2)`.
//! With uniform times both reduce exactly to Shoemake's `s_i`. The angular velocity at keyframe `i`
//! is then `q_i (2 V_i) q_i*` from both sides (C1). The end keyframes use `a_0 = q_0` and
//! `b_{n-1} = q_{n-1}` (Shoemake's choice), so two keyframes give exactly the SLERP between them.
//!
//! Before any of this the keyframes are made sign-consistent: each `q_i` is negated when needed to
//! lie in the hemisphere of `q_{i-1}` (non-negative dot product), so every segment takes the
//! shorter arc and `|L_i| <= pi/2`; then `|log(q_i* a_i)|, |log(q_i* b_i)| <= 3pi/4 < pi`, so the
//! principal logarithm recovers them and the derivative formulas hold.
//!
//! The angular velocity is analytic (chain rule through the SO(3) left Jacobian of the inner
//! exponential), not a finite difference.

use crate::Real;
use heapless::Vec;
use nalgebra::Vector3;

/// Why a quaternion or a set of orientation keyframes was refused. Indices count keyframes from 0.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RotationError {
    /// A quaternion (keyframe `index`; 0 for a lone quaternion or vector) is zero, NaN or infinite,
    /// or an axis is zero, or an angle or exponent is NaN or infinite.
    InvalidQuaternion {
        /// Offending keyframe (0 outside a keyframe list).
        index: usize,
    },
    /// No keyframe at all.
    Empty,
    /// More keyframes than the fixed capacity.
    TooMany {
        /// The capacity.
        capacity: usize,
    },
    /// Keyframe `index`'s time is NaN or infinite (or its interval overflows).
    NonFiniteTime {
        /// Offending keyframe.
        index: usize,
    },
    /// Keyframe `index` is not later than the one before it.
    TimesNotIncreasing {
        /// Offending keyframe.
        index: usize,
    },
}

impl core::fmt::Display for RotationError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            RotationError::InvalidQuaternion { index } => {
                write!(f, "keyframe {index}: zero, NaN or infinite quaternion")
            }
            RotationError::Empty => write!(f, "no keyframes"),
            RotationError::TooMany { capacity } => write!(f, "more than {capacity} keyframes"),
            RotationError::NonFiniteTime { index } => write!(f, "keyframe {index}: NaN or infinite time"),
            RotationError::TimesNotIncreasing { index } => {
                write!(f, "keyframe {index}: time is not later than the previous keyframe's")
            }
        }
    }
}

/// A unit quaternion `[w, x, y, z]` (always finite and normalised).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Quaternion<T: Real> {
    q: [T; 4],
}

impl<T: Real> Default for Quaternion<T> {
    fn default() -> Self {
        Self::identity()
    }
}

impl<T: Real> Quaternion<T> {
    /// The identity rotation `[1, 0, 0, 0]`.
    pub fn identity() -> Self {
        Self { q: [T::one(), T::zero(), T::zero(), T::zero()] }
    }

    /// Normalises `[w, x, y, z]` (any non-zero finite length, without overflow); a zero, NaN or
    /// infinite quaternion gives an error.
    pub fn new(wxyz: [T; 4]) -> Result<Self, RotationError> {
        let bad = RotationError::InvalidQuaternion { index: 0 };
        let mut m = T::zero();
        for c in wxyz {
            if !c.finite() {
                return Err(bad);
            }
            m = m.max(c.abs());
        }
        if m <= T::zero() {
            return Err(bad);
        }
        let s = wxyz.map(|c| c / m);
        let n = dot4(&s, &s).sqrt();
        Ok(Self { q: s.map(|c| c / n) })
    }

    /// Rotation by `angle` (rad) about `axis` (any non-zero finite length).
    pub fn from_axis_angle(axis: &Vector3<T>, angle: T) -> Result<Self, RotationError> {
        let bad = RotationError::InvalidQuaternion { index: 0 };
        if !angle.finite() {
            return Err(bad);
        }
        let n = Self::new([T::zero(), axis.x, axis.y, axis.z])?.q;
        let (s, c) = (angle * T::of(0.5)).sin_cos_fast();
        Ok(Self::renormalised([c, n[1] * s, n[2] * s, n[3] * s]))
    }

    /// Shoemake's exponential of the pure quaternion `(0, v)`: `(cos |v|, sin |v| v / |v|)`, the
    /// rotation by `2|v|` about `v`. Non-finite `v` gives an error.
    pub fn exp(v: &Vector3<T>) -> Result<Self, RotationError> {
        if !(v.x.finite() && v.y.finite() && v.z.finite()) {
            return Err(RotationError::InvalidQuaternion { index: 0 });
        }
        Ok(exp_unchecked(v))
    }

    /// Shoemake's logarithm: the vector `a n` for `self = (cos a, n sin a)`, `a` in `[0, pi]`
    /// (half the rotation angle). The exact half-turn `[-1, 0, 0, 0]` (`a = pi`, any axis) gives
    /// `(pi, 0, 0)`.
    pub fn log(&self) -> Vector3<T> {
        let [w, x, y, z] = self.q;
        let s = (x * x + y * y + z * z).sqrt();
        let a = s.atan2(w);
        if s > T::zero() && (w < T::zero() || s > T::EPSILON) {
            // Divide first: |x / s| <= 1, so this stays finite even for subnormal `s`.
            Vector3::new(x / s * a, y / s * a, z / s * a)
        } else if w >= T::zero() {
            // atan2(s, w) / s = (1 - s^2 / (3 w^2) + ...) / w and s^2 < eps^2 here.
            Vector3::new(x / w, y / w, z / w)
        } else {
            Vector3::new(T::pi(), T::zero(), T::zero())
        }
    }

    /// `[w, x, y, z]`.
    pub fn wxyz(&self) -> [T; 4] {
        self.q
    }

    /// The scalar part `w`.
    pub fn w(&self) -> T {
        self.q[0]
    }

    /// The vector part `(x, y, z)`.
    pub fn vector(&self) -> Vector3<T> {
        Vector3::new(self.q[1], self.q[2], self.q[3])
    }

    /// The conjugate, which is the inverse of a unit quaternion.
    pub fn conjugate(&self) -> Self {
        let [w, x, y, z] = self.q;
        Self { q: [w, -x, -y, -z] }
    }

    /// The 4D dot product (the cosine of half the angle between the rotations, up to sign).
    pub fn dot(&self, other: &Self) -> T {
        dot4(&self.q, &other.q)
    }

    /// The rotation angle (rad, in `[0, pi]`) carrying `self` onto `other`, either sign of either.
    pub fn angle_to(&self, other: &Self) -> T {
        let d = self.dot(other);
        let b = if d < T::zero() { -*other } else { *other };
        T::of(2.0) * angle4(&self.q, &b.q)
    }

    /// Rotates the vector `v`: `self (0, v) self*`.
    pub fn rotate(&self, v: &Vector3<T>) -> Vector3<T> {
        let u = self.vector();
        let t = u.cross(v) * T::of(2.0);
        v + t * self.q[0] + u.cross(&t)
    }

    /// Spherical linear interpolation along the shortest arc: `other` is negated first when the
    /// dot product is negative, so the rotation angle covered is at most pi. `t` is not clamped
    /// (outside `[0, 1]` it extrapolates along the same great circle); `t = 0` and `t = 1` return
    /// `self` and the (possibly negated) `other` exactly; a NaN or infinite `t` returns `self`.
    ///
    /// After the flip the 4D angle `W` between the two is at most pi/2 (a rotation of pi is
    /// `W = pi/2`, where the formula is perfectly conditioned). `W` comes from
    /// `2 atan2(|a - b|, |a + b|)`, accurate at every angle, and below `sqrt(eps)` the normalised
    /// lerp is used (it differs from SLERP by `O(W^3)`).
    pub fn slerp(&self, other: &Self, t: T) -> Self {
        let b = if self.dot(other) < T::zero() { -*other } else { *other };
        Self { q: slerp_path(&self.q, &b.q, t) }
    }

    fn renormalised(q: [T; 4]) -> Self {
        let n = dot4(&q, &q).sqrt();
        // Only reached with |q| close to 1; the fallback keeps the invariant for any input anyway.
        if n > T::zero() && n.finite() {
            Self { q: q.map(|c| c / n) }
        } else {
            Self::identity()
        }
    }
}

impl<T: Real> core::ops::Mul for Quaternion<T> {
    type Output = Self;

    /// The Hamilton product `self * rhs` (first `rhs`, then `self`), renormalised.
    fn mul(self, rhs: Self) -> Self {
        let [a0, a1, a2, a3] = self.q;
        let [b0, b1, b2, b3] = rhs.q;
        Self::renormalised([
            a0 * b0 - a1 * b1 - a2 * b2 - a3 * b3,
            a0 * b1 + a1 * b0 + a2 * b3 - a3 * b2,
            a0 * b2 - a1 * b3 + a2 * b0 + a3 * b1,
            a0 * b3 + a1 * b2 - a2 * b1 + a3 * b0,
        ])
    }
}

impl<T: Real> core::ops::Neg for Quaternion<T> {
    type Output = Self;

    /// `-q`: the same rotation, the other hemisphere.
    fn neg(self) -> Self {
        Self { q: self.q.map(|c| -c) }
    }
}

fn dot4<T: Real>(a: &[T; 4], b: &[T; 4]) -> T {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3]
}

/// Angle between two unit 4-vectors, in `[0, pi]`, accurate everywhere (Kahan).
fn angle4<T: Real>(a: &[T; 4], b: &[T; 4]) -> T {
    let (mut d, mut s) = (T::zero(), T::zero());
    for i in 0..4 {
        d += (a[i] - b[i]) * (a[i] - b[i]);
        s += (a[i] + b[i]) * (a[i] + b[i]);
    }
    T::of(2.0) * d.sqrt().atan2(s.sqrt())
}

/// `exp` for a finite vector (norm computed with scaling, so no overflow).
fn exp_unchecked<T: Real>(v: &Vector3<T>) -> Quaternion<T> {
    let m = v.x.abs().max(v.y.abs()).max(v.z.abs());
    if m <= T::zero() {
        return Quaternion::identity();
    }
    let a = m * (v / m).norm();
    let (s, c) = a.sin_cos_fast();
    // sin(a) / a is accurate for every a > 0 (no cancellation); below eps it is 1 to rounding.
    let k = if a > T::EPSILON { s / a } else { T::one() };
    Quaternion::renormalised([c, v.x * k, v.y * k, v.z * k])
}

/// SLERP along the great circle from `a` to `b` as given (no hemisphere flip), unit result.
/// Within the curve the 4D angle is below pi; the antipodal limit falls back to a great circle
/// through an arbitrary perpendicular so the result stays finite and unit.
fn slerp_path<T: Real>(a: &[T; 4], b: &[T; 4], t: T) -> [T; 4] {
    if t == T::zero() || !t.finite() {
        return *a;
    }
    if t == T::one() {
        return *b;
    }
    let one = T::one();
    let w = angle4(a, b);
    if w == T::zero() {
        return *a;
    }
    let small = T::EPSILON.sqrt();
    let r = if w < small {
        let u = one - t;
        [u * a[0] + t * b[0], u * a[1] + t * b[1], u * a[2] + t * b[2], u * a[3] + t * b[3]]
    } else if T::pi() - w < small {
        let c = [-a[1], a[0], -a[3], a[2]];
        let (s, co) = (t * w).sin_cos_fast();
        [co * a[0] + s * c[0], co * a[1] + s * c[1], co * a[2] + s * c[2], co * a[3] + s * c[3]]
    } else {
        let sw = w.sin_cos_fast().0;
        let ka = ((one - t) * w).sin_cos_fast().0 / sw;
        let kb = (t * w).sin_cos_fast().0 / sw;
        [ka * a[0] + kb * b[0], ka * a[1] + kb * b[1], ka * a[2] + kb * b[2], ka * a[3] + kb * b[3]]
    };
    Quaternion::renormalised(r).q
}

/// `J_l(phi) v` for the SO(3) left Jacobian: `v + (1 - cos x)/x^2 phi x v + (x - sin x)/x^3 phi x (phi x v)`.
fn left_jacobian<T: Real>(phi: &Vector3<T>, v: &Vector3<T>) -> Vector3<T> {
    let x2 = phi.norm_squared();
    let x = x2.sqrt();
    let (a, b) = if x < T::of(0.03) {
        (
            T::of(0.5) - x2 / T::of(24.0) + x2 * x2 / T::of(720.0),
            T::of(1.0 / 6.0) - x2 / T::of(120.0) + x2 * x2 / T::of(5040.0),
        )
    } else {
        let h = (x * T::of(0.5)).sin_cos_fast().0 / x;
        (T::of(2.0) * h * h, (x - x.sin_cos_fast().0) / (x2 * x))
    };
    let c = phi.cross(v);
    v + c * a + phi.cross(&c) * b
}

/// `J_l(phi)^-1 v = v - phi x v / 2 + (1/x^2 - (1 + cos x) / (2 x sin x)) phi x (phi x v)`.
fn left_jacobian_inverse<T: Real>(phi: &Vector3<T>, v: &Vector3<T>) -> Vector3<T> {
    let x2 = phi.norm_squared();
    let x = x2.sqrt();
    let k = if x < T::of(0.03) {
        T::of(1.0 / 12.0) + x2 / T::of(720.0) + x2 * x2 / T::of(30240.0)
    } else {
        let (s, c) = x.sin_cos_fast();
        let k = T::one() / x2 - (T::one() + c) / (T::of(2.0) * x * s);
        // Singular only at a full turn (|phi| = 2 pi), which the curve does not reach.
        if k.finite() {
            k
        } else {
            T::zero()
        }
    };
    let c = phi.cross(v);
    v - c * T::of(0.5) + phi.cross(&c) * k
}

/// A timed orientation for [`Squad`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OrientationKeyframe<T: Real> {
    /// Time (s).
    pub time: T,
    /// Orientation `[w, x, y, z]` (any non-zero length; normalised when the curve is built).
    pub orientation: [T; 4],
}

/// A C1 orientation curve through up to `K` timed keyframes: SQUAD with tangents scaled for
/// non-uniform times (see the module documentation).
#[derive(Clone, Debug)]
pub struct Squad<T: Real, const K: usize> {
    times: Vec<T, K>,
    /// Keyframes, sign-consistent (each in the hemisphere of the previous one).
    q: Vec<Quaternion<T>, K>,
    /// Outgoing control `a_i` (start of segment i).
    a: Vec<Quaternion<T>, K>,
    /// Incoming control `b_i` (end of segment i - 1).
    b: Vec<Quaternion<T>, K>,
    /// `L_i = log(q_i* q_{i+1})` per segment.
    chord: Vec<Vector3<T>, K>,
    /// `log(a_i* b_{i+1})` per segment.
    control: Vec<Vector3<T>, K>,
}

impl<T: Real, const K: usize> Squad<T, K> {
    /// Builds the curve. Times must be finite and strictly increasing; quaternions non-zero and
    /// finite (they are normalised, and negated where needed for sign consistency).
    pub fn new(keyframes: &[OrientationKeyframe<T>]) -> Result<Self, RotationError> {
        let n = keyframes.len();
        if n == 0 {
            return Err(RotationError::Empty);
        }
        if n > K {
            return Err(RotationError::TooMany { capacity: K });
        }
        let mut times: Vec<T, K> = Vec::new();
        let mut q: Vec<Quaternion<T>, K> = Vec::new();
        for (index, k) in keyframes.iter().enumerate() {
            if !k.time.finite() {
                return Err(RotationError::NonFiniteTime { index });
            }
            let mut qi = Quaternion::new(k.orientation).map_err(|_| RotationError::InvalidQuaternion { index })?;
            if let (Some(&tp), Some(qp)) = (times.last(), q.last()) {
                if k.time <= tp {
                    return Err(RotationError::TimesNotIncreasing { index });
                }
                if !(k.time - tp).finite() {
                    return Err(RotationError::NonFiniteTime { index });
                }
                if qp.dot(&qi) < T::zero() {
                    qi = -qi;
                }
            }
            // Capacity was checked above; these pushes cannot fail.
            let _ = times.push(k.time);
            let _ = q.push(qi);
        }
        let mut chord: Vec<Vector3<T>, K> = Vec::new();
        for i in 0..n - 1 {
            let _ = chord.push((q[i].conjugate() * q[i + 1]).log());
        }
        let (mut a, mut b) = (q.clone(), q.clone());
        let half = T::of(0.5);
        for i in 1..n - 1 {
            let (d0, d1) = (times[i] - times[i - 1], times[i + 1] - times[i]);
            let sum = d0 + d1;
            let v = if sum.finite() { (chord[i - 1] + chord[i]) / sum } else { Vector3::zeros() };
            a[i] = q[i] * exp_unchecked(&((v * d1 - chord[i]) * half));
            b[i] = q[i] * exp_unchecked(&((chord[i - 1] - v * d0) * half));
        }
        let mut control: Vec<Vector3<T>, K> = Vec::new();
        for i in 0..n - 1 {
            let _ = control.push((a[i].conjugate() * b[i + 1]).log());
        }
        Ok(Self { times, q, a, b, chord, control })
    }

    /// Number of keyframes.
    pub fn len(&self) -> usize {
        self.times.len()
    }

    /// Never true: a curve has at least one keyframe.
    pub fn is_empty(&self) -> bool {
        self.times.is_empty()
    }

    /// The keyframe times (s).
    pub fn times(&self) -> &[T] {
        &self.times
    }

    /// The normalised, sign-consistent keyframe orientations the curve passes through.
    pub fn keyframes(&self) -> &[Quaternion<T>] {
        &self.q
    }

    /// Time of the first keyframe.
    pub fn start_time(&self) -> T {
        self.times[0]
    }

    /// Time of the last keyframe.
    pub fn end_time(&self) -> T {
        self.times[self.times.len() - 1]
    }

    /// Orientation at time `t`. Before the first keyframe (and for a NaN `t`) it is the first
    /// keyframe, after the last one the last keyframe.
    pub fn orientation(&self, t: T) -> Quaternion<T> {
        self.sample(t).0
    }

    /// World-frame angular velocity (rad/s) at time `t`, analytic. Zero outside
    /// `[start_time, end_time]`, for a NaN `t` and for a single keyframe; at the two end times it is
    /// the one-sided value from inside.
    pub fn angular_velocity(&self, t: T) -> Vector3<T> {
        self.sample(t).1
    }

    /// Orientation and world-frame angular velocity (rad/s) at time `t` (see
    /// [`orientation`](Self::orientation) and [`angular_velocity`](Self::angular_velocity)).
    pub fn sample(&self, t: T) -> (Quaternion<T>, Vector3<T>) {
        let n = self.times.len();
        let last = n - 1;
        // A NaN time is unordered and holds the first keyframe.
        if n == 1 || matches!(t.partial_cmp(&self.times[0]), None | Some(core::cmp::Ordering::Less)) {
            return (self.q[0], Vector3::zeros());
        }
        if t > self.times[last] {
            return (self.q[last], Vector3::zeros());
        }
        // First segment whose end is at or after t (the last segment holds t = end_time).
        let i = self.times[1..].partition_point(|&x| x < t).min(last - 1);
        let i = if i + 1 < last && t == self.times[i + 1] { i + 1 } else { i };
        let d = self.times[i + 1] - self.times[i];
        let h = ((t - self.times[i]) / d).max(T::zero()).min(T::one());
        let (s, w) = self.segment(i, h);
        (s, w / d)
    }

    /// Segment `i` at `h` in `[0, 1]`: the orientation and the world angular velocity per unit `h`.
    ///
    /// `S = P exp(g u)` with `P = q_i exp(h L)`, `R = a_i exp(h C)`, `u = log(P* R)`,
    /// `g = 2h(1 - h)`. Then `omega_S = omega_P + P omega_E P*` with `omega_P = q_i (2L) q_i*`,
    /// `omega_E = J_l(2gu) (2g'u + 2g u')`, and `2u' = J_l(2u)^-1 omega_M` for `M = P* R`,
    /// `omega_M = -2L + M (2C) M*`.
    fn segment(&self, i: usize, h: T) -> (Quaternion<T>, Vector3<T>) {
        let two = T::of(2.0);
        let (qi, l, c) = (self.q[i], self.chord[i], self.control[i]);
        let p = Quaternion { q: slerp_path(&qi.q, &self.q[i + 1].q, h) };
        let r = Quaternion { q: slerp_path(&self.a[i].q, &self.b[i + 1].q, h) };
        let g = two * h * (T::one() - h);
        let gd = two - two * two * h;
        let s = Quaternion { q: slerp_path(&p.q, &r.q, g) };
        let m = p.conjugate() * r;
        let u = m.log();
        let omega_m = m.rotate(&(c * two)) - l * two;
        let ud2 = left_jacobian_inverse(&(u * two), &omega_m);
        let omega_e = left_jacobian(&(u * (two * g)), &(u * (two * gd) + ud2 * g));
        (s, qi.rotate(&(l * two)) + p.rotate(&omega_e))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn q(w: f64, x: f64, y: f64, z: f64) -> Quaternion<f64> {
        Quaternion::new([w, x, y, z]).unwrap()
    }

    fn close(a: &Quaternion<f64>, b: &Quaternion<f64>, tol: f64) -> bool {
        a.wxyz().iter().zip(b.wxyz()).all(|(x, y)| (x - y).abs() <= tol)
    }

    #[test]
    fn invalid_quaternions_are_errors() {
        for bad in [[0.0; 4], [f64::NAN, 1.0, 0.0, 0.0], [f64::INFINITY, 0.0, 0.0, 0.0]] {
            assert_eq!(Quaternion::new(bad), Err(RotationError::InvalidQuaternion { index: 0 }));
        }
        let huge = Quaternion::new([1e300, 1e300, 0.0, 0.0]).unwrap();
        assert!((huge.w() - 0.5f64.sqrt()).abs() < 1e-15);
        let tiny = Quaternion::new([0.0, 0.0, 1e-310, 0.0]).unwrap();
        assert_eq!(tiny.wxyz(), [0.0, 0.0, 1.0, 0.0]);
        assert!(Quaternion::exp(&Vector3::new(f64::NAN, 0.0, 0.0)).is_err());
        assert!(Quaternion::from_axis_angle(&Vector3::zeros(), 1.0).is_err());
    }

    #[test]
    fn exp_log_round_trip() {
        for v in [
            Vector3::new(0.0, 0.0, 0.0),
            Vector3::new(1e-20f64, -2e-20, 0.0),
            Vector3::new(1e-9, 0.0, 3e-9),
            Vector3::new(0.3, -0.4, 1.2),
            Vector3::new(0.0, 3.0, 0.0),
        ] {
            let e = Quaternion::exp(&v).unwrap();
            assert!((e.dot(&e) - 1.0).abs() < 1e-15);
            let back = e.log();
            assert!((back - v).norm() <= 1e-15 * (1.0 + v.norm()) * 4.0, "{v:?} -> {back:?}");
        }
        assert_eq!(q(-1.0, 0.0, 0.0, 0.0).log(), Vector3::new(core::f64::consts::PI, 0.0, 0.0));
        let big = Quaternion::exp(&Vector3::new(1e300f64, 1e300, 0.0)).unwrap();
        assert!(big.wxyz().iter().all(|c| c.is_finite()));
    }

    #[test]
    fn slerp_handles_equal_and_nearly_equal() {
        let a = q(0.2, 0.3, -0.5, 0.7);
        assert_eq!(a.slerp(&a, 0.3), a);
        let b = a * Quaternion::exp(&Vector3::new(1e-12, 0.0, 0.0)).unwrap();
        let m = a.slerp(&b, 0.5);
        assert!((a.angle_to(&m) - 1e-12).abs() < 1e-15);
        assert!(a.slerp(&b, f64::NAN) == a);
    }

    #[test]
    fn slerp_path_antipodal_is_finite() {
        let a = [1.0f64, 0.0, 0.0, 0.0];
        let r = slerp_path(&a, &[-1.0, 0.0, 0.0, 0.0], 0.5);
        assert!((dot4(&r, &r) - 1.0).abs() < 1e-15);
    }

    #[test]
    fn jacobians_are_inverse() {
        for phi in [Vector3::new(0.0, 0.0, 0.0), Vector3::new(0.01, 0.0, 0.02), Vector3::new(1.0, -2.0, 0.5)] {
            let v = Vector3::new(0.3, 0.7, -1.1);
            let back = left_jacobian_inverse(&phi, &left_jacobian(&phi, &v));
            assert!((back - v).norm() < 1e-14, "{phi:?}");
        }
    }

    #[test]
    fn knot_velocities_match_from_both_sides() {
        let keys = [
            OrientationKeyframe { time: 0.0, orientation: [1.0, 0.0, 0.0, 0.0] },
            OrientationKeyframe { time: 0.3, orientation: [0.9, 0.3, -0.2, 0.1] },
            OrientationKeyframe { time: 1.7, orientation: [-0.2, 0.1, 0.9, 0.4] },
            OrientationKeyframe { time: 2.0, orientation: [0.5, -0.5, 0.5, 0.5] },
        ];
        let c: Squad<f64, 8> = Squad::new(&keys).unwrap();
        for i in 1..3 {
            let (sl, wl) = c.segment(i - 1, 1.0);
            let (sr, wr) = c.segment(i, 0.0);
            assert!(close(&sl, &c.q[i], 0.0) && close(&sr, &c.q[i], 0.0));
            let dl = c.times[i] - c.times[i - 1];
            let dr = c.times[i + 1] - c.times[i];
            assert!((wl / dl - wr / dr).norm() < 1e-12, "knot {i}: {:?} vs {:?}", wl / dl, wr / dr);
        }
    }
}
