//! The Paden-Kahan subproblems, the building blocks of every closed-form solution here, in the
//! forms of Elias and Wen's IK-Geo ("IK-Geo: Unified robot inverse kinematics using subproblem
//! decomposition", 2022). Axes are unit vectors through the origin; a caller moves its points to
//! the axis first. Each returns at most two angles and says whether they solve the equation
//! exactly: where no angle does (a target out of reach), the least-squares angle is returned and
//! `exact` is false, so a caller can report the miss instead of inventing a solution.

use crate::Real;
use nalgebra::Vector3;

/// Up to two angles from one subproblem.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Angles<T: Real> {
    values: [T; 2],
    count: usize,
    /// True if the angles satisfy the equation; false for the least-squares answer to one that
    /// has no solution.
    pub exact: bool,
    /// True if the equation does not depend on the angle (a singular pose: any angle solves it,
    /// or none does); the one value returned is then 0, for the caller to replace.
    pub free: bool,
    /// True if the two roots coincide within [`free_tolerance`] (the circle only touches: a fully
    /// stretched or folded arm).
    pub double: bool,
}

/// How small a quantity that leaves an angle undetermined must be to count as zero: about 1e-9
/// in f64 (unit-scale arms, metres), 3e-5 in f32.
pub fn free_tolerance<T: Real>() -> T {
    T::EPSILON.sqrt() * T::of(0.1)
}

impl<T: Real> Angles<T> {
    fn one(value: T, exact: bool) -> Self {
        Self { values: [value, value], count: 1, exact, free: false, double: false }
    }

    fn two(a: T, b: T, double: bool) -> Self {
        Self { values: [a, b], count: 2, exact: true, free: false, double }
    }

    /// The angles found (one or two).
    pub fn as_slice(&self) -> &[T] {
        self.values.get(..self.count).unwrap_or(&[])
    }
}

/// `rot(k, theta) v` by Rodrigues' formula: one sine and cosine and a few products, where building
/// the matrix and multiplying would cost three times as much (the closed forms rotate vectors,
/// never compose rotations).
pub fn rotate<T: Real>(k: &Vector3<T>, theta: T, v: &Vector3<T>) -> Vector3<T> {
    let (s, c) = theta.sin_cos_fast();
    let along = k * (k.dot(v) * (T::one() - c));
    v * c + k.cross(v) * s + along
}

/// `v` less its component along the unit vector `k`.
fn across<T: Real>(k: &Vector3<T>, v: &Vector3<T>) -> Vector3<T> {
    v - k * k.dot(v)
}

/// `a cos(theta) + b sin(theta) = c`: both roots, or the least-squares root when |c| exceeds
/// `sqrt(a^2 + b^2)` (then `exact` is false). `a = b = 0` leaves theta free: 0, not exact unless
/// `c` is zero too.
fn trig_equation<T: Real>(a: T, b: T, c: T) -> Angles<T> {
    let r = (a * a + b * b).sqrt();
    let tolerance = free_tolerance::<T>();
    if r <= tolerance {
        return Angles { free: true, ..Angles::one(T::zero(), c.abs() <= tolerance) };
    }
    let phi = b.atan2(a);
    let ratio = c / r;
    // Beyond 1 by a rounding's worth the equation still touches: one double root, exact.
    let touching = T::EPSILON * T::of(64.0);
    if ratio >= T::one() {
        return Angles { double: true, ..Angles::one(phi, ratio - T::one() <= touching) };
    }
    if ratio <= -T::one() {
        return Angles { double: true, ..Angles::one(phi + T::pi(), -ratio - T::one() <= touching) };
    }
    let spread = ratio.acos();
    Angles::two(phi + spread, phi - spread, spread * spread <= tolerance)
}

/// Subproblem 1: the angle `theta` that turns `p1` about `k` onto `p2`, `rot(k, theta) p1 = p2`,
/// in the least-squares sense (exact when both have the same length across `k` and the same
/// component along it). Undefined where `p1` or `p2` lies on the axis; 0 is returned there.
pub fn sp1<T: Real>(k: &Vector3<T>, p1: &Vector3<T>, p2: &Vector3<T>) -> T {
    let (a, b) = (across(k, p1), across(k, p2));
    k.dot(&a.cross(&b)).atan2(a.dot(&b))
}

/// Subproblem 2: `theta1`, `theta2` with `rot(k1, theta1) p1 = rot(k2, theta2) p2`, for axes
/// that are not parallel: the points where the two circles meet. Returns the pairs
/// `(theta1, theta2)` (up to two) and whether they are exact.
pub fn sp2<T: Real>(k1: &Vector3<T>, p1: &Vector3<T>, k2: &Vector3<T>, p2: &Vector3<T>) -> ([(T, T); 2], usize, bool) {
    // x = alpha k1 + beta k2 + gamma (k1 x k2), with k1.x = k1.p1, k2.x = k2.p2, |x| = |p|.
    let c = k1.dot(k2);
    let (a1, a2) = (k1.dot(p1), k2.dot(p2));
    let det = T::one() - c * c;
    let alpha = (a1 - c * a2) / det;
    let beta = (a2 - c * a1) / det;
    let n = k1.cross(k2);
    // Both points lie on the sphere of their mean radius (they have equal lengths when exact).
    let radius2 = (p1.norm_squared() + p2.norm_squared()) * T::of(0.5);
    let in_plane = alpha * alpha + beta * beta + T::of(2.0) * alpha * beta * c;
    let gamma2 = (radius2 - in_plane) / n.norm_squared();
    let base = k1 * alpha + k2 * beta;
    let pair = |x: Vector3<T>| (sp1(k1, p1, &x), sp1(k2, p2, &x));
    let lengths_agree = (p1.norm() - p2.norm()).abs() <= T::EPSILON.sqrt() * (radius2.sqrt() + T::one());
    if gamma2 <= T::zero() {
        let exact = lengths_agree && -gamma2 <= T::EPSILON.sqrt() * (radius2 + T::one());
        let only = pair(base);
        return ([only, only], 1, exact);
    }
    let gamma = gamma2.sqrt();
    ([pair(base + n * gamma), pair(base - n * gamma)], 2, lengths_agree)
}

/// Subproblem 3: the angles with `|rot(k, theta) p1 - p2| = d`.
pub fn sp3<T: Real>(k: &Vector3<T>, p1: &Vector3<T>, p2: &Vector3<T>, d: T) -> Angles<T> {
    let (a, b) = (across(k, p1), across(k, p2));
    let along = k.dot(p1) - k.dot(p2);
    let d_across2 = d * d - along * along;
    // |R a - b|^2 = |a|^2 + |b|^2 - 2 b.(R a), and b.(R a) = cos b.a + sin b.(k x a).
    let c = (a.norm_squared() + b.norm_squared() - d_across2) * T::of(0.5);
    trig_equation(b.dot(&a), b.dot(&k.cross(&a)), c)
}

/// Subproblem 4: the angles with `h . rot(k, theta) p = d`.
pub fn sp4<T: Real>(h: &Vector3<T>, k: &Vector3<T>, p: &Vector3<T>, d: T) -> Angles<T> {
    let a = across(k, p);
    // rot(k, theta) p = cos a + sin (k x a) + k (k.p).
    trig_equation(h.dot(&a), h.dot(&k.cross(&a)), d - h.dot(k) * k.dot(p))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{axis_angle_matrix, wrap_angle, SplitMix64};

    fn unit(rng: &mut SplitMix64) -> Vector3<f64> {
        Vector3::new(rng.uniform(-1.0, 1.0), rng.uniform(-1.0, 1.0), rng.uniform(-1.0, 1.0)).normalize()
    }

    fn point(rng: &mut SplitMix64) -> Vector3<f64> {
        Vector3::new(rng.uniform(-1.0, 1.0), rng.uniform(-1.0, 1.0), rng.uniform(-1.0, 1.0))
    }

    fn rot(k: &Vector3<f64>, theta: f64) -> nalgebra::Matrix3<f64> {
        axis_angle_matrix(k, theta)
    }

    #[test]
    fn rotate_is_the_rotation_matrix_applied() {
        let mut rng = SplitMix64::new(3);
        for _ in 0..1000 {
            let (k, v, t) = (unit(&mut rng), point(&mut rng), rng.uniform(-7.0, 7.0));
            assert!((rotate(&k, t, &v) - rot(&k, t) * v).norm() < 1e-14);
        }
    }

    /// True if `found` holds `theta` (as an angle).
    fn holds(found: &[f64], theta: f64) -> bool {
        found.iter().any(|v| wrap_angle(v - theta).abs() < 1e-9)
    }

    // Each subproblem is posed from a known angle (by rotating a random point), so the answer is
    // known independently of the formula; every returned angle must also satisfy the equation.
    #[test]
    fn each_subproblem_finds_the_angle_it_was_posed_from() {
        let mut rng = SplitMix64::new(11);
        for _ in 0..2000 {
            let (k, k2, h) = (unit(&mut rng), unit(&mut rng), unit(&mut rng));
            let (p, p2) = (point(&mut rng), point(&mut rng));
            let (t1, t2) = (rng.uniform(-3.1, 3.1), rng.uniform(-3.1, 3.1));

            assert!(wrap_angle(sp1(&k, &p, &(rot(&k, t1) * p)) - t1).abs() < 1e-9);

            let x = rot(&k, t1) * p;
            let p2_on_circle = rot(&k2, -t2) * x;
            let (pairs, count, exact) = sp2(&k, &p, &k2, &p2_on_circle);
            assert!(exact);
            assert!(pairs[..count]
                .iter()
                .any(|(a, b)| wrap_angle(a - t1).abs() < 1e-7 && wrap_angle(b - t2).abs() < 1e-7));
            for (a, b) in &pairs[..count] {
                assert!((rot(&k, *a) * p - rot(&k2, *b) * p2_on_circle).norm() < 1e-7);
            }

            let d = (rot(&k, t1) * p - p2).norm();
            let found = sp3(&k, &p, &p2, d);
            assert!(found.exact && holds(found.as_slice(), t1), "{found:?} {t1}");
            for v in found.as_slice() {
                assert!(((rot(&k, *v) * p - p2).norm() - d).abs() < 1e-9);
            }

            let d = h.dot(&(rot(&k, t1) * p));
            let found = sp4(&h, &k, &p, d);
            assert!(found.exact && holds(found.as_slice(), t1));
            for v in found.as_slice() {
                assert!((h.dot(&(rot(&k, *v) * p)) - d).abs() < 1e-9);
            }
        }
    }

    // Out of reach: the nearest angle, flagged as not exact.
    #[test]
    fn an_unreachable_subproblem_gives_the_closest_angle_and_says_so() {
        let k = Vector3::z();
        let p = Vector3::new(1.0, 0.0, 0.0);
        let far = sp3(&k, &p, &Vector3::new(0.0, 3.0, 0.0), 1.0);
        assert!(!far.exact);
        assert_eq!(far.as_slice().len(), 1);
        assert!((far.as_slice()[0] - core::f64::consts::FRAC_PI_2).abs() < 1e-12);
        let high = sp4(&Vector3::x(), &k, &p, 2.0);
        assert!(!high.exact);
        assert!(high.as_slice()[0].abs() < 1e-12);
        // Circles on spheres of different radii never meet.
        let (_, _, exact) =
            sp2(&Vector3::x(), &Vector3::new(0.0, 1.0, 0.0), &Vector3::y(), &Vector3::new(0.0, 0.0, 3.0));
        assert!(!exact);
        // Circles on one sphere that do not meet: one least-squares pair.
        let (_, count, exact) = sp2(
            &Vector3::z(),
            &Vector3::new(0.0, 0.1, 0.995f64.sqrt()),
            &Vector3::x(),
            &Vector3::new(0.995f64.sqrt(), 0.1, 0.0),
        );
        assert!(!exact);
        assert_eq!(count, 1);
    }
}
