//! Signed distances: how far apart two shapes are, negative when they overlap (then by how much
//! the cores are closer than the radii allow, or how deep a point of the capsule's core is in
//! the solid). Exact for capsules against capsules, half-spaces and boxes (a box's solved piece
//! by piece along the capsule's core).

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
pub(super) fn box_measure<T: Real>(local: &Vector3<T>, half: &Vector3<T>) -> T {
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

/// The signed distance between a capsule and a box, exactly. In the box's frame, between two of
/// the parameters where a coordinate of the core segment crosses a face's plane or the box's
/// middle plane ("knots"), each `|p_k| - h_k` is linear, so [`box_measure`] is a sum of squares
/// of linear functions (outside) or the largest of three (inside). The signed distance is convex
/// along the segment, but every piece is solved (the quadratic's vertex, or where two of the
/// linear functions cross), not only the two beside the lowest knot: knots a rounding apart would
/// bracket the wrong pieces. Most knots fall outside the segment, so a few pieces are solved,
/// each point measured in a few multiplications; one square root in all (a hundred instructions
/// in software on a Cortex-M4F). It replaced a golden-section search of 28 steps in f32 and 70 in
/// f64, several times as costly and exact only to the type's precision of the parameter.
pub fn capsule_box<T: Real>(c: &Capsule<T>, centre: &Vector3<T>, rotation: &Matrix3<T>, half: &Vector3<T>) -> T {
    let (zero, one) = (T::zero(), T::one());
    let a = rotation.tr_mul(&(c.a - centre));
    let d = rotation.tr_mul(&(c.b - c.a));
    if !(a.iter().chain(d.iter()).all(|x| x.finite())) {
        return T::of(f64::NAN);
    }
    let at = |t: T| box_measure(&(a + d * t), half);
    // The knots, sorted as they are inserted.
    let mut knots = [zero; 11];
    let mut count = 0usize;
    let mut insert = |t: T| {
        let mut i = count;
        while i > 0 && knots.get(i - 1).is_some_and(|&k| k > t) {
            if let Some(k) = knots.get(i - 1).copied() {
                if let Some(slot) = knots.get_mut(i) {
                    *slot = k;
                }
            }
            i -= 1;
        }
        if let Some(slot) = knots.get_mut(i) {
            *slot = t;
            count += 1;
        }
    };
    insert(zero);
    insert(one);
    // Plain arrays, indexed within their length: no bounds check left for a firmware to link.
    let (a3, d3, h3) = ([a.x, a.y, a.z], [d.x, d.y, d.z], [half.x, half.y, half.z]);
    for ((&ak, &dk), &hk) in a3.iter().zip(&d3).zip(&h3) {
        if dk != zero {
            for plane in [-hk, zero, hk] {
                let t = (plane - ak) / dk;
                if t > zero && t < one {
                    insert(t);
                }
            }
        }
    }
    let knots = knots.get(..count).unwrap_or(&[]);
    let mut lowest = T::of(f64::INFINITY);
    for &t in knots {
        lowest = lowest.min(at(t));
    }
    for piece in knots.windows(2) {
        let &[t0, t1] = piece else { continue };
        // On this piece each |p_k| - h_k is alpha_k + beta_k t (the sign of p_k is fixed).
        let middle = a + d * ((t0 + t1) * T::of(0.5));
        let line = |m: T, a: T, d: T, h: T| {
            let sign = if m < zero { -one } else { one };
            (sign * a - h, sign * d)
        };
        let lines =
            [line(middle.x, a.x, d.x, half.x), line(middle.y, a.y, d.y, half.y), line(middle.z, a.z, d.z, half.z)];
        let beyond = |(alpha, beta): (T, T)| alpha + beta * (t0 + t1) * T::of(0.5) > zero;
        let mut candidates = [T::of(f64::NAN); 3];
        if lines.iter().any(|&l| beyond(l)) {
            // Outside: the sum of the squares of the positive ones, least at its vertex.
            let (mut num, mut den) = (zero, zero);
            for &(alpha, beta) in lines.iter().filter(|&&l| beyond(l)) {
                num += alpha * beta;
                den += beta * beta;
            }
            if den > zero {
                candidates[0] = (-num / den).max(t0).min(t1);
            }
        } else {
            // Inside: the largest of three lines, least where two of them cross.
            let [x, y, z] = lines;
            for (slot, ((aj, bj), (ak, bk))) in candidates.iter_mut().zip([(x, y), (x, z), (y, z)]) {
                if bj != bk {
                    let t = (ak - aj) / (bj - bk);
                    if t > t0 && t < t1 {
                        *slot = t;
                    }
                }
            }
        }
        for t in candidates.into_iter().filter(|t| t.finite()) {
            lowest = lowest.min(at(t));
        }
    }
    from_box_measure(lowest) - c.radius
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Against dense sampling of the core segment, over random pairs (boxes turned, segments
    /// through, beside and inside them, some parallel to a face): never above any sample (it is
    /// the least), and below the least sample by no more than the samples' spacing allows (the
    /// signed distance to a box moves by at most as far as the point does).
    #[test]
    fn a_capsule_box_distance_is_the_least_of_dense_samples() {
        let mut rng = crate::SplitMix64::new(11);
        let samples = 4000;
        for case in 0..2000 {
            let point = |rng: &mut crate::SplitMix64| {
                Vector3::new(rng.uniform(-0.2, 0.2), rng.uniform(-0.2, 0.2), rng.uniform(-0.2, 0.2))
            };
            let a = point(&mut rng);
            let mut b = point(&mut rng);
            if case % 5 == 0 {
                // Parallel to the box's faces (before it is turned): flat pieces.
                b.z = a.z;
            }
            let axis = point(&mut rng).normalize();
            let rotation = if case % 3 == 0 {
                Matrix3::identity()
            } else {
                crate::axis_angle_matrix(&axis, rng.uniform(-3.0, 3.0))
            };
            let centre = point(&mut rng) * 0.3;
            let half = Vector3::new(rng.uniform(0.01, 0.12), rng.uniform(0.01, 0.12), rng.uniform(0.01, 0.12));
            let capsule = Capsule { a, b, radius: 0.01 };
            let got = capsule_box(&capsule, &centre, &rotation, &half);
            let sampled = (0..=samples)
                .map(|i| point_box(&(a + (b - a) * (i as f64 / samples as f64)), &centre, &rotation, &half))
                .fold(f64::INFINITY, f64::min)
                - 0.01;
            let spacing = (b - a).norm() / samples as f64;
            assert!(got <= sampled + 1e-12, "case {case}: {got} above the sampled {sampled}");
            assert!(
                got >= sampled - 0.5 * spacing - 1e-12,
                "case {case}: {got} below the sampled {sampled} by more than {spacing}"
            );
        }
    }
}
