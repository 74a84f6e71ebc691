//! A capsule that contains every point of a mesh: what collision keeps of a link's STL.
//!
//! For each of the points' three principal axes (PCA of their covariance) the core segment lies
//! along that axis, through the centre of the smallest circle holding the points projected across
//! it (Welzl's algorithm), so the radius is that circle's; the segment then runs between the
//! extreme projections and its ends are pulled in as far as every point stays inside (a point at
//! `t` along the axis and `rho` from it stays inside an end at `s` while `|t - s| <= sqrt(r² -
//! rho²)`). The axis giving the smallest volume wins. Finally the ends are rounded to
//! [`ROUNDING`] and the radius grown by what that rounding can move the segment, then rounded up,
//! so the capsule still holds every point and its numbers read well in an arm file.

use kinematics::collision::Capsule;
use kinematics::nalgebra::{Matrix3, Vector2, Vector3};
use kinematics::SplitMix64;

/// The grid the fitted capsule's numbers are rounded to (m): a tenth of a millimetre.
pub const ROUNDING: f64 = 1e-4;

/// The smallest capsule along one of the points' principal axes that holds them all, rounded
/// outwards to [`ROUNDING`]; `None` for no points or points that are not finite.
pub fn capsule_around(points: &[Vector3<f64>]) -> Option<Capsule<f64>> {
    if points.is_empty() || points.iter().any(|p| !p.iter().all(|x| x.is_finite())) {
        return None;
    }
    let points = distinct(points);
    let n = points.len() as f64;
    let mean = points.iter().fold(Vector3::zeros(), |s, p| s + p) / n;
    let covariance = points.iter().fold(Matrix3::zeros(), |s, p| s + (p - mean) * (p - mean).transpose()) / n;
    let axes = covariance.symmetric_eigen().eigenvectors;
    let best = (0..3)
        .filter_map(|k| {
            let axis = axes.column(k).into_owned();
            (axis.norm() > 0.5).then(|| along(&points, &axis.normalize()))
        })
        .min_by(|a, b| volume(a).total_cmp(&volume(b)))?;
    Some(rounded_outwards(&best))
}

/// The volume of a capsule.
pub fn volume(c: &Capsule<f64>) -> f64 {
    let pi = core::f64::consts::PI;
    pi * c.radius * c.radius * (c.b - c.a).norm() + 4.0 / 3.0 * pi * c.radius.powi(3)
}

/// How far `p` is inside the capsule (negative: outside).
pub fn depth(c: &Capsule<f64>, p: &Vector3<f64>) -> f64 {
    let d = c.b - c.a;
    let t = if d.norm_squared() > 0.0 { ((p - c.a).dot(&d) / d.norm_squared()).clamp(0.0, 1.0) } else { 0.0 };
    c.radius - (p - (c.a + d * t)).norm()
}

/// The points without repeats (a mesh lists each vertex once per facet around it).
fn distinct(points: &[Vector3<f64>]) -> Vec<Vector3<f64>> {
    let mut keyed: Vec<([u64; 3], Vector3<f64>)> = points.iter().map(|p| (p.map(f64::to_bits).into(), *p)).collect();
    keyed.sort_unstable_by_key(|(k, _)| *k);
    keyed.dedup_by_key(|(k, _)| *k);
    keyed.into_iter().map(|(_, p)| p).collect()
}

/// The capsule along `axis` (unit) holding `points`.
fn along(points: &[Vector3<f64>], axis: &Vector3<f64>) -> Capsule<f64> {
    // Two unit vectors across the axis.
    let helper = if axis.x.abs() < 0.9 { Vector3::x() } else { Vector3::y() };
    let e1 = axis.cross(&helper).normalize();
    let e2 = axis.cross(&e1);
    let across: Vec<Vector2<f64>> = points.iter().map(|p| Vector2::new(p.dot(&e1), p.dot(&e2))).collect();
    let (centre, _) = smallest_circle(&across);
    // The radius measured again from the centre, so that every point is within it exactly.
    let rho: Vec<f64> = across.iter().map(|q| (q - centre).norm()).collect();
    let radius = rho.iter().fold(0.0f64, |m, r| m.max(*r));
    let (mut low, mut high) = (f64::INFINITY, f64::NEG_INFINITY);
    for (p, r) in points.iter().zip(&rho) {
        let t = p.dot(axis);
        let reach = (radius * radius - r * r).max(0.0).sqrt();
        low = low.min(t + reach);
        high = high.max(t - reach);
    }
    if low > high {
        // Every point is within `radius` of one point of the axis: a sphere there.
        let middle = 0.5 * (low + high);
        (low, high) = (middle, middle);
    }
    let line = e1 * centre.x + e2 * centre.y;
    Capsule { a: line + axis * low, b: line + axis * high, radius }
}

/// Welzl's smallest enclosing circle (the randomised incremental form), points shuffled with a
/// fixed seed so that a fit is the same every time.
fn smallest_circle(points: &[Vector2<f64>]) -> (Vector2<f64>, f64) {
    let mut p = points.to_vec();
    let mut rng = SplitMix64::new(0x5eed);
    for i in (1..p.len()).rev() {
        p.swap(i, (rng.next_u64() % (i as u64 + 1)) as usize);
    }
    let outside = |c: &Vector2<f64>, r: f64, q: &Vector2<f64>| (q - c).norm() > r * (1.0 + 1e-12) + 1e-15;
    let Some(&first) = p.first() else { return (Vector2::zeros(), 0.0) };
    let (mut c, mut r) = (first, 0.0);
    for i in 1..p.len() {
        if !outside(&c, r, &p[i]) {
            continue;
        }
        (c, r) = (p[i], 0.0);
        for j in 0..i {
            if !outside(&c, r, &p[j]) {
                continue;
            }
            (c, r) = ((p[i] + p[j]) * 0.5, (p[i] - p[j]).norm() * 0.5);
            for k in 0..j {
                if outside(&c, r, &p[k]) {
                    (c, r) = circle_through(&p[i], &p[j], &p[k]);
                }
            }
        }
    }
    (c, r)
}

/// The circle through three points; for (nearly) collinear ones, the one on the farthest pair.
fn circle_through(a: &Vector2<f64>, b: &Vector2<f64>, c: &Vector2<f64>) -> (Vector2<f64>, f64) {
    let (ab, ac) = (b - a, c - a);
    let d = 2.0 * (ab.x * ac.y - ab.y * ac.x);
    if d.abs() < 1e-18 {
        let pairs = [(a, b), (a, c), (b, c)];
        let (p, q) =
            pairs.into_iter().max_by(|x, y| (x.0 - x.1).norm().total_cmp(&(y.0 - y.1).norm())).unwrap_or((a, b));
        return ((p + q) * 0.5, (p - q).norm() * 0.5);
    }
    let (s, t) = (ab.norm_squared(), ac.norm_squared());
    let centre = a + Vector2::new(ac.y * s - ab.y * t, ab.x * t - ac.x * s) / d;
    (centre, (centre - a).norm())
}

/// `c` with its ends on the [`ROUNDING`] grid and its radius grown by the most that can move any
/// point of the segment (half a step on each axis), then rounded up to the grid.
fn rounded_outwards(c: &Capsule<f64>) -> Capsule<f64> {
    let round = |v: &Vector3<f64>| v.map(|x| clean((x / ROUNDING).round() * ROUNDING));
    let grown = c.radius + ROUNDING * 0.5 * 3f64.sqrt();
    // The tiny subtraction keeps a radius already on the grid from climbing a step by rounding.
    let radius = clean(((grown / ROUNDING) - 1e-9).ceil() * ROUNDING);
    Capsule { a: round(&c.a), b: round(&c.b), radius }
}

/// `x` with the digits of its nearest multiple of [`ROUNDING`] (`0.1 + 0.2` as `0.3`), and `-0`
/// as `0`, so the arm file shows short numbers.
fn clean(x: f64) -> f64 {
    let text = format!("{x:.4}");
    let v: f64 = text.parse().unwrap_or(x);
    if v == 0.0 {
        0.0
    } else {
        v
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn assert_holds(c: &Capsule<f64>, points: &[Vector3<f64>]) {
        for p in points {
            assert!(depth(c, p) >= 0.0, "{p} is {} m outside {c:?}", -depth(c, p));
        }
    }

    #[test]
    fn a_box_gets_the_capsule_on_its_long_axis_through_its_end_faces() {
        // 0.2 x 0.04 x 0.02 box about (0.1, 0, 0.05): by hand, the core segment from x = 0 to
        // x = 0.2 (its corners are exactly a radius off the axis, so the ends cannot be pulled
        // in) and the radius the cross-section's half diagonal, hypot(0.02, 0.01) = 0.022361 m,
        // rounded up to 0.0225 once the rounding slack (0.0866 mm) is added.
        let corners: Vec<Vector3<f64>> = (0..8)
            .map(|k| {
                let sign = |bit: u32| if k & (1 << bit) == 0 { -1.0 } else { 1.0 };
                Vector3::new(0.1 + 0.1 * sign(0), 0.02 * sign(1), 0.05 + 0.01 * sign(2))
            })
            .collect();
        let c = capsule_around(&corners).unwrap();
        let (a, b) = if c.a.x < c.b.x { (c.a, c.b) } else { (c.b, c.a) };
        assert!((a - Vector3::new(0.0, 0.0, 0.05)).amax() < 1e-12, "{c:?}");
        assert!((b - Vector3::new(0.2, 0.0, 0.05)).amax() < 1e-12, "{c:?}");
        assert_eq!(c.radius, 0.0225);
        assert_holds(&c, &corners);
    }

    #[test]
    fn points_on_a_sphere_give_a_sphere_about_its_centre() {
        let mut rng = SplitMix64::new(9);
        let centre = Vector3::new(0.01, -0.02, 0.03);
        let points: Vec<Vector3<f64>> = (0..2000)
            .map(|_| {
                let v = Vector3::new(rng.uniform(-1.0, 1.0), rng.uniform(-1.0, 1.0), rng.uniform(-1.0, 1.0));
                centre + v.normalize() * 0.05
            })
            .collect();
        let c = capsule_around(&points).unwrap();
        assert_holds(&c, &points);
        // Within a step of the sphere itself: a short core and a radius of about 0.05.
        assert!((c.b - c.a).norm() < 0.005 && c.radius < 0.0505, "{c:?}");
        assert!((0.5 * (c.a + c.b) - centre).amax() < 0.001, "{c:?}");
    }

    /// A mesh as an STL file gives it: a bent tube of 40 x 24 quads, two facets each, read back
    /// from its binary STL bytes (f32), every one of its 5760 vertices inside the capsule.
    #[test]
    fn every_vertex_of_a_meshed_tube_is_inside() {
        let point = |i: usize, k: usize| -> [f32; 3] {
            let (s, a) = (i as f64 / 39.0, k as f64 / 24.0 * core::f64::consts::TAU);
            // Along x for 0.15 m, bending up by 0.02 m, 0.02 m across.
            let centre = Vector3::new(0.15 * s, 0.0, 0.02 * s * s);
            let p = centre + Vector3::new(0.0, 0.02 * a.cos(), 0.02 * a.sin());
            [p.x as f32, p.y as f32, p.z as f32]
        };
        let mut facets = Vec::new();
        for i in 0..39 {
            for k in 0..24 {
                let (a, b, c, d) = (point(i, k), point(i + 1, k), point(i + 1, k + 1), point(i, k + 1));
                facets.push([a, b, c]);
                facets.push([a, c, d]);
            }
        }
        let vertices = crate::collision::stl::parse(&crate::collision::stl::tests::binary_stl(&facets)).unwrap();
        assert_eq!(vertices.len(), 39 * 24 * 2 * 3);
        let c = capsule_around(&vertices).unwrap();
        assert_holds(&c, &vertices);
        // The tube's radius plus the bend's half height at most, and a step of rounding.
        assert!(c.radius <= 0.02 + 0.01 + 2.0 * ROUNDING, "{c:?}");
    }

    #[test]
    fn random_clouds_are_held_whole() {
        let mut rng = SplitMix64::new(4);
        for _ in 0..20 {
            // A stretched, turned, shifted cloud.
            let turn = kinematics::Pose::from_xyz_rpy(
                [rng.uniform(-0.1, 0.1), rng.uniform(-0.1, 0.1), rng.uniform(-0.1, 0.1)],
                [rng.uniform(-3.0, 3.0), rng.uniform(-1.5, 1.5), rng.uniform(-3.0, 3.0)],
            );
            let scale = Vector3::new(rng.uniform(0.01, 0.2), rng.uniform(0.01, 0.05), rng.uniform(0.005, 0.03));
            let points: Vec<Vector3<f64>> = (0..500)
                .map(|_| {
                    let v = Vector3::new(rng.uniform(-1.0, 1.0), rng.uniform(-1.0, 1.0), rng.uniform(-1.0, 1.0));
                    turn.rotation * v.component_mul(&scale) + turn.translation
                })
                .collect();
            let c = capsule_around(&points).unwrap();
            assert_holds(&c, &points);
            // Never much larger than the cloud's bounding sphere.
            let far = points.iter().map(|p| (p - turn.translation).norm()).fold(0.0, f64::max);
            assert!(c.radius <= far + ROUNDING, "{c:?}");
        }
        assert_eq!(capsule_around(&[]), None);
        assert_eq!(capsule_around(&[Vector3::new(f64::NAN, 0.0, 0.0)]), None);
    }
}
