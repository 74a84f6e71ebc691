//! Signed distances: how far apart two shapes are, negative when they overlap (then by how much
//! the cores are closer than the radii allow, or how deep a point of the capsule's core is in
//! the solid). Exact for capsules against capsules and half-spaces; against a box, the minimum
//! of a convex function of one variable, found by golden-section search to the type's precision.

use nalgebra::{Matrix3, Vector3};

use super::shape::{Capsule, Shape};
use crate::Real;

/// The signed distance between a capsule and an obstacle.
pub fn distance<T: Real>(capsule: &Capsule<T>, obstacle: &Shape<T>) -> T {
    match obstacle {
        Shape::Capsule(other) => capsule_capsule(capsule, other),
        Shape::Box { centre, rotation, half } => capsule_box(capsule, centre, rotation, half),
        Shape::HalfSpace { normal, offset } => {
            normal.dot(&capsule.a).min(normal.dot(&capsule.b)) - *offset - capsule.radius
        }
    }
}

/// The signed distance between two capsules: their cores' distance less both radii.
pub fn capsule_capsule<T: Real>(p: &Capsule<T>, q: &Capsule<T>) -> T {
    segment_segment(&p.a, &p.b, &q.a, &q.b) - p.radius - q.radius
}

/// The distance between segments `p1 p2` and `q1 q2` (Ericson, Real-Time Collision Detection,
/// 5.1.9), either of which may be a point.
pub fn segment_segment<T: Real>(p1: &Vector3<T>, p2: &Vector3<T>, q1: &Vector3<T>, q2: &Vector3<T>) -> T {
    let (zero, one) = (T::zero(), T::one());
    let d1 = p2 - p1;
    let d2 = q2 - q1;
    let r = p1 - q1;
    let a = d1.dot(&d1);
    let e = d2.dot(&d2);
    let f = d2.dot(&r);
    let tiny = T::EPSILON * T::EPSILON;
    let (s, t);
    if a <= tiny && e <= tiny {
        return r.norm_squared().root();
    }
    if a <= tiny {
        s = zero;
        t = unit(f / e);
    } else {
        let c = d1.dot(&r);
        if e <= tiny {
            t = zero;
            s = unit(-c / a);
        } else {
            let b = d1.dot(&d2);
            let denominator = a * e - b * b;
            // Parallel segments: any s does; 0 is as good as another.
            let s0 = if denominator > tiny * a * e { unit((b * f - c * e) / denominator) } else { zero };
            let t0 = (b * s0 + f) / e;
            if t0 < zero {
                t = zero;
                s = unit(-c / a);
            } else if t0 > one {
                t = one;
                s = unit((b - c) / a);
            } else {
                t = t0;
                s = s0;
            }
        }
    }
    ((p1 + d1 * s) - (q1 + d2 * t)).norm_squared().root()
}

/// `x` within `0..=1`; NaN gives 0.
fn unit<T: Real>(x: T) -> T {
    let (zero, one) = (T::zero(), T::one());
    if x > one {
        one
    } else if x > zero {
        x
    } else {
        zero
    }
}

/// The signed distance from point `p` to the box: outside, the Euclidean distance; inside, minus
/// the distance to the nearest face.
pub fn point_box<T: Real>(p: &Vector3<T>, centre: &Vector3<T>, rotation: &Matrix3<T>, half: &Vector3<T>) -> T {
    from_box_measure(box_measure(&rotation.tr_mul(&(p - centre)), half))
}

/// A strictly increasing function of the signed distance from a point to a box, which costs no
/// square root: the squared distance outside, minus the distance to the nearest face inside.
/// `local` is the point in the box's frame, from its centre.
fn box_measure<T: Real>(local: &Vector3<T>, half: &Vector3<T>) -> T {
    let d = local.abs() - half;
    let inside = d.x.max(d.y).max(d.z);
    if inside > T::zero() {
        d.map(|x| x.max(T::zero())).norm_squared()
    } else {
        inside
    }
}

/// The signed distance from [`box_measure`]'s value.
fn from_box_measure<T: Real>(m: T) -> T {
    if m > T::zero() {
        m.root()
    } else {
        m
    }
}

/// Golden-section steps: each keeps 0.618 of the interval; 28 reach f32's resolution on a
/// segment, 70 f64's.
fn golden_steps<T: Real>() -> usize {
    if T::EPSILON.to_f64() > 1e-10 {
        28
    } else {
        70
    }
}

/// The signed distance between a capsule and a box. The signed distance to the box is convex
/// along the core segment, so [`box_measure`], a strictly increasing function of it, has one
/// minimum there, found by golden-section search (ends included). The segment is taken into the
/// box's frame once, and the search compares measures, so a step costs a few multiplications and
/// the whole search one square root (a hundred instructions each in software on a Cortex-M4F).
pub fn capsule_box<T: Real>(c: &Capsule<T>, centre: &Vector3<T>, rotation: &Matrix3<T>, half: &Vector3<T>) -> T {
    let a = rotation.tr_mul(&(c.a - centre));
    let d = rotation.tr_mul(&(c.b - c.a));
    let at = |t: T| box_measure(&(a + d * t), half);
    let ends = at(T::zero()).min(at(T::one()));
    if d.norm_squared() <= T::EPSILON * T::EPSILON {
        return from_box_measure(ends) - c.radius;
    }
    let ratio = T::of(0.618_033_988_749_894_9);
    let (mut lo, mut hi) = (T::zero(), T::one());
    let mut x1 = hi - (hi - lo) * ratio;
    let mut x2 = lo + (hi - lo) * ratio;
    let (mut f1, mut f2) = (at(x1), at(x2));
    for _ in 0..golden_steps::<T>() {
        if f1 <= f2 {
            hi = x2;
            x2 = x1;
            f2 = f1;
            x1 = hi - (hi - lo) * ratio;
            f1 = at(x1);
        } else {
            lo = x1;
            x1 = x2;
            f1 = f2;
            x2 = lo + (hi - lo) * ratio;
            f2 = at(x2);
        }
    }
    from_box_measure(ends.min(f1).min(f2)) - c.radius
}
