//! SLERP and SQUAD: exact endpoints, constant angular speed, shortest arc, the angles 0 and pi,
//! agreement with nalgebra's `UnitQuaternion::slerp`, keyframe interpolation, C1 continuity on
//! non-uniform times and the analytic angular velocity against finite differences.

use kinematics::nalgebra::{Quaternion as NaQuaternion, UnitQuaternion, Vector3};
use kinematics::trajectory::{OrientationKeyframe, Quaternion, RotationError, Squad};
use kinematics::SplitMix64;
use std::f64::consts::PI;

type Q = Quaternion<f64>;

fn random_quaternion(rng: &mut SplitMix64) -> Q {
    loop {
        let v = [rng.uniform(-1.0, 1.0), rng.uniform(-1.0, 1.0), rng.uniform(-1.0, 1.0), rng.uniform(-1.0, 1.0)];
        if v.iter().map(|c| c * c).sum::<f64>() > 0.01 {
            return Q::new(v).unwrap();
        }
    }
}

fn axis_angle(axis: [f64; 3], angle: f64) -> Q {
    Q::from_axis_angle(&Vector3::from(axis), angle).unwrap()
}

fn norm_error(q: &Q) -> f64 {
    (q.dot(q) - 1.0).abs()
}

/// Same rotation: equal up to the sign of the whole quaternion.
fn same_rotation(a: &Q, b: &Q, tol: f64) -> bool {
    let (a, b) = (a.wxyz(), b.wxyz());
    let plus = (0..4).all(|i| (a[i] - b[i]).abs() <= tol);
    let minus = (0..4).all(|i| (a[i] + b[i]).abs() <= tol);
    plus || minus
}

/// World angular velocity from a central difference in the quaternion algebra:
/// `S(t + d) S(t - d)* = exp(omega d)` (Shoemake's half-angle exp), so `omega = log(..) / d`.
fn finite_difference<const K: usize>(c: &Squad<f64, K>, t: f64, d: f64) -> Vector3<f64> {
    (c.orientation(t + d) * c.orientation(t - d).conjugate()).log() / d
}

#[test]
fn slerp_endpoints_are_exact() {
    let mut rng = SplitMix64::new(1);
    for _ in 0..200 {
        let (a, b) = (random_quaternion(&mut rng), random_quaternion(&mut rng));
        assert_eq!(a.slerp(&b, 0.0), a);
        let end = a.slerp(&b, 1.0);
        let expected = if a.dot(&b) < 0.0 { -b } else { b };
        assert_eq!(end, expected);
    }
}

#[test]
fn slerp_has_constant_angular_speed() {
    let mut rng = SplitMix64::new(2);
    for _ in 0..200 {
        let (a, b) = (random_quaternion(&mut rng), random_quaternion(&mut rng));
        let total = a.angle_to(&b);
        assert!(total <= PI);
        let mut prev = a;
        for k in 1..=20 {
            let t = k as f64 / 20.0;
            let q = a.slerp(&b, t);
            assert!((a.angle_to(&q) - t * total).abs() < 1e-12);
            assert!((prev.angle_to(&q) - total / 20.0).abs() < 1e-12);
            prev = q;
        }
        // The rotation axis of each step is the same (a single great circle).
        let step = (a.slerp(&b, 0.2) * a.conjugate()).log();
        let later = (a.slerp(&b, 0.9) * a.slerp(&b, 0.7).conjugate()).log();
        assert!((step - later).norm() < 1e-12);
    }
}

#[test]
fn slerp_takes_the_shortest_arc_for_q_and_minus_q() {
    let mut rng = SplitMix64::new(3);
    for _ in 0..200 {
        let (a, b) = (random_quaternion(&mut rng), random_quaternion(&mut rng));
        for t in [0.1, 0.5, 0.8] {
            let (p, m) = (a.slerp(&b, t), a.slerp(&-b, t));
            assert!(same_rotation(&p, &m, 1e-15), "{p:?} vs {m:?}");
            // Half way along a rotation of at most pi.
            assert!((a.angle_to(&p) - t * a.angle_to(&b)).abs() < 1e-12);
        }
    }
    // A rotation of 3pi/2 about z is reached the short way: -pi/2 about z.
    let id = Q::identity();
    let long = axis_angle([0.0, 0.0, 1.0], 1.5 * PI);
    let mid = id.slerp(&long, 0.5);
    assert!(same_rotation(&mid, &axis_angle([0.0, 0.0, 1.0], -0.25 * PI), 1e-15));
}

#[test]
fn slerp_at_angle_zero_and_tiny_angles() {
    let mut rng = SplitMix64::new(4);
    for _ in 0..50 {
        let a = random_quaternion(&mut rng);
        for t in [0.0, 0.25, 0.5, 1.0, 2.0] {
            assert_eq!(a.slerp(&a, t), a);
            assert!(same_rotation(&a.slerp(&-a, t), &a, 0.0));
        }
        for angle in [1e-6, 1e-9, 1e-12, 1e-15] {
            let b = axis_angle([0.3, -0.2, 0.9], angle) * a;
            let q = a.slerp(&b, 0.3);
            assert!(norm_error(&q) < 1e-15);
            assert!(q.wxyz().iter().all(|c| c.is_finite()));
            // Angles below ~1e-8 are not resolved by the rotation itself (its quaternion rounds).
            let expected = 0.3 * a.angle_to(&b);
            assert!((a.angle_to(&q) - expected).abs() < 1e-15, "{angle}: {} vs {expected}", a.angle_to(&q));
        }
    }
}

#[test]
fn slerp_at_and_near_angle_pi() {
    let axes = [[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.6, -0.8, 0.0], [0.2, 0.3, -0.9]];
    for axis in axes {
        let n = Vector3::from(axis).normalize();
        let a = Q::identity();
        // Exactly pi: the dot product is 0; either direction is shortest, the sign convention
        // keeps `b` as given (no flip), so the path is the rotation about +axis.
        let b = axis_angle(axis, PI);
        assert!(a.dot(&b).abs() < 1e-16);
        for t in [0.25, 0.5, 0.75] {
            let q = a.slerp(&b, t);
            assert!(norm_error(&q) < 1e-15);
            assert!(same_rotation(&q, &axis_angle(axis, t * PI), 1e-15), "{q:?}");
        }
        // Just below and just above pi: the path goes the short way, through +axis or -axis.
        for (angle, sign) in [(PI - 1e-9, 1.0), (PI + 1e-9, -1.0), (PI - 1e-15, 1.0)] {
            let b = axis_angle(axis, angle);
            let q = a.slerp(&b, 0.5);
            assert!(norm_error(&q) < 1e-15 && q.wxyz().iter().all(|c| c.is_finite()));
            let shortest = if sign > 0.0 { angle } else { angle - 2.0 * PI };
            let rv = q.log() * 2.0;
            assert!((rv - n * (0.5 * shortest)).norm() < 1e-12, "{angle}: {rv:?}");
        }
    }
}

#[test]
fn slerp_result_is_always_unit() {
    let mut rng = SplitMix64::new(5);
    for _ in 0..2000 {
        let (a, b) = (random_quaternion(&mut rng), random_quaternion(&mut rng));
        let t = rng.uniform(-3.0, 4.0);
        let q = a.slerp(&b, t);
        assert!(norm_error(&q) < 4.0 * f64::EPSILON, "{q:?}");
    }
    let (a, b) = (random_quaternion(&mut rng), random_quaternion(&mut rng));
    for t in [f64::NAN, f64::INFINITY, -f64::INFINITY, 1e12, -1e12] {
        let q = a.slerp(&b, t);
        assert!(q.wxyz().iter().all(|c| c.is_finite()) && norm_error(&q) < 1e-15, "{t}");
    }
    // f32 too.
    let a32 = Quaternion::<f32>::new([0.3, -0.1, 0.9, 0.2]).unwrap();
    let b32 = Quaternion::<f32>::new([-0.5, 0.5, 0.1, -0.7]).unwrap();
    for k in 0..=10 {
        let q = a32.slerp(&b32, k as f32 / 10.0);
        assert!((q.dot(&q) - 1.0).abs() < 4.0 * f32::EPSILON);
    }
}

#[test]
fn slerp_matches_nalgebra() {
    let mut rng = SplitMix64::new(6);
    let mut worst = 0.0f64;
    for _ in 0..5000 {
        let (a, b) = (random_quaternion(&mut rng), random_quaternion(&mut rng));
        let t = rng.uniform(0.0, 1.0);
        let na = |q: &Q| {
            let [w, x, y, z] = q.wxyz();
            UnitQuaternion::from_quaternion(NaQuaternion::new(w, x, y, z))
        };
        let r = na(&a).slerp(&na(&b), t);
        let ours = a.slerp(&b, t).wxyz();
        for (x, y) in ours.iter().zip([r.w, r.i, r.j, r.k]) {
            worst = worst.max((x - y).abs());
        }
    }
    assert!(worst < 1e-12, "worst component difference {worst:e}");
}

fn keyframes(times: &[f64], orientations: &[Q]) -> std::vec::Vec<OrientationKeyframe<f64>> {
    times.iter().zip(orientations).map(|(&time, q)| OrientationKeyframe { time, orientation: q.wxyz() }).collect()
}

/// Five orientations, well apart, at strongly non-uniform times (intervals 0.2, 1.3, 0.4, 2.0).
fn non_uniform() -> (std::vec::Vec<f64>, std::vec::Vec<Q>) {
    let times = vec![0.5, 0.7, 2.0, 2.4, 4.4];
    let qs = vec![
        Q::identity(),
        axis_angle([0.0, 0.0, 1.0], 0.6),
        axis_angle([1.0, 1.0, 0.0], 1.9),
        axis_angle([0.2, -1.0, 0.4], 2.8),
        axis_angle([1.0, 0.0, -0.3], -1.2),
    ];
    (times, qs)
}

#[test]
fn squad_passes_through_every_keyframe() {
    let (times, qs) = non_uniform();
    // Alternate the signs: the curve makes them consistent itself.
    let signed: std::vec::Vec<Q> = qs.iter().enumerate().map(|(i, q)| if i % 2 == 1 { -*q } else { *q }).collect();
    let c: Squad<f64, 8> = Squad::new(&keyframes(&times, &signed)).unwrap();
    assert_eq!(c.len(), 5);
    for (i, (&t, q)) in times.iter().zip(&qs).enumerate() {
        assert!(same_rotation(&c.orientation(t), q, 1e-15), "keyframe {i}");
        assert!(c.keyframes()[i].dot(q).abs() > 1.0 - 1e-15);
        if i > 0 {
            assert!(c.keyframes()[i].dot(&c.keyframes()[i - 1]) >= 0.0, "hemisphere {i}");
        }
    }
    // Outside the time range the end orientations are held.
    assert_eq!(c.orientation(-10.0), c.keyframes()[0]);
    assert_eq!(c.orientation(100.0), c.keyframes()[4]);
    assert_eq!(c.angular_velocity(100.0), Vector3::zeros());
    assert_eq!(c.orientation(f64::NAN), c.keyframes()[0]);
    // Always unit in between.
    for k in 0..=1000 {
        let q = c.orientation(0.5 + 3.9 * k as f64 / 1000.0);
        assert!(norm_error(&q) < 4.0 * f64::EPSILON);
    }
}

#[test]
fn squad_is_c1_across_non_uniform_keyframes() {
    let (times, qs) = non_uniform();
    let c: Squad<f64, 8> = Squad::new(&keyframes(&times, &qs)).unwrap();
    // Angular velocity just before and just after each interior keyframe: the difference is
    // bounded by |angular acceleration| * 2e, about 1e-7 here (1e-5 allows for it).
    let e = 1e-9;
    for &t in &times[1..4] {
        let (before, after) = (c.angular_velocity(t - e), c.angular_velocity(t + e));
        let at = c.angular_velocity(t);
        assert!((before - after).norm() < 1e-5, "t = {t}: {before:?} vs {after:?}");
        assert!((before - at).norm() < 1e-5 && at.norm() > 0.1);
    }
    // The angular velocity is continuous and the orientation has no jumps: the largest change
    // between samples 1e-4 s apart is small everywhere (including across keyframes).
    let mut prev = c.angular_velocity(times[0]);
    for k in 1..=39_000 {
        let t = times[0] + k as f64 * 1e-4;
        let w = c.angular_velocity(t);
        assert!((w - prev).norm() < 0.05, "jump at {t}: {prev:?} -> {w:?}");
        prev = w;
    }
}

#[test]
fn squad_angular_velocity_matches_finite_differences() {
    let (times, qs) = non_uniform();
    let c: Squad<f64, 8> = Squad::new(&keyframes(&times, &qs)).unwrap();
    for k in 1..400 {
        let t = times[0] + 3.9 * k as f64 / 400.0;
        let analytic = c.angular_velocity(t);
        let numeric = finite_difference(&c, t, 1e-6);
        // Central difference error ~ d^2 |omega''| plus rounding ~ eps / d.
        assert!((analytic - numeric).norm() < 1e-6 * (1.0 + analytic.norm()), "t = {t}: {analytic:?} vs {numeric:?}");
    }
}

#[test]
fn squad_of_two_keyframes_is_slerp() {
    let mut rng = SplitMix64::new(7);
    for _ in 0..50 {
        let (a, b) = (random_quaternion(&mut rng), random_quaternion(&mut rng));
        let (t0, t1) = (rng.uniform(-2.0, 2.0), rng.uniform(2.5, 5.0));
        let c: Squad<f64, 2> = Squad::new(&keyframes(&[t0, t1], &[a, b])).unwrap();
        let rate = a.angle_to(&b) / (t1 - t0);
        for k in 0..=20 {
            let t = if k == 20 { t1 } else { t0 + (t1 - t0) * k as f64 / 20.0 };
            let s = a.slerp(&b, (t - t0) / (t1 - t0));
            assert!(same_rotation(&c.orientation(t), &s, 1e-14));
            assert!((c.angular_velocity(t).norm() - rate).abs() < 1e-12);
        }
    }
}

#[test]
fn squad_reproduces_constant_angular_velocity_on_non_uniform_times() {
    // q(t) = exp(t w / 2) (rotation vector t w): every keyframe lies on one uniform rotation, so
    // the scaled tangents are exact and the curve is that rotation, for any spacing.
    let w = Vector3::new(0.4, -0.9, 0.3);
    let times = [0.0, 0.1, 0.25, 1.4, 1.5, 3.0];
    let qs: std::vec::Vec<Q> = times.iter().map(|&t| Q::exp(&(w * (0.5 * t))).unwrap()).collect();
    let c: Squad<f64, 8> = Squad::new(&keyframes(&times, &qs)).unwrap();
    for k in 0..=300 {
        let t = 3.0 * k as f64 / 300.0;
        assert!(same_rotation(&c.orientation(t), &Q::exp(&(w * (0.5 * t))).unwrap(), 1e-13));
        assert!((c.angular_velocity(t) - w).norm() < 1e-12, "t = {t}: {:?}", c.angular_velocity(t));
    }
}

#[test]
fn squad_in_f32() {
    let keys = [
        OrientationKeyframe { time: 0.0f32, orientation: [1.0, 0.0, 0.0, 0.0] },
        OrientationKeyframe { time: 0.4, orientation: [0.8, 0.6, 0.0, 0.0] },
        OrientationKeyframe { time: 1.5, orientation: [0.0, 0.6, 0.8, 0.0] },
    ];
    let c: Squad<f32, 4> = Squad::new(&keys).unwrap();
    let (b, a) = (c.angular_velocity(0.4 - 1e-4), c.angular_velocity(0.4 + 1e-4));
    assert!((b - a).norm() < 1e-2, "{b:?} {a:?}");
    for k in 0..=100 {
        let q = c.orientation(1.5 * k as f32 / 100.0);
        assert!((q.dot(&q) - 1.0).abs() < 4.0 * f32::EPSILON);
    }
}

#[test]
fn squad_rejects_bad_keyframes() {
    let k = |time: f64, orientation: [f64; 4]| OrientationKeyframe { time, orientation };
    let id = [1.0, 0.0, 0.0, 0.0];
    assert_eq!(Squad::<f64, 4>::new(&[]).unwrap_err(), RotationError::Empty);
    assert_eq!(
        Squad::<f64, 2>::new(&[k(0.0, id), k(1.0, id), k(2.0, id)]).unwrap_err(),
        RotationError::TooMany { capacity: 2 }
    );
    assert_eq!(
        Squad::<f64, 4>::new(&[k(0.0, id), k(1.0, [0.0; 4])]).unwrap_err(),
        RotationError::InvalidQuaternion { index: 1 }
    );
    assert_eq!(
        Squad::<f64, 4>::new(&[k(0.0, id), k(1.0, [f64::NAN, 0.0, 0.0, 1.0])]).unwrap_err(),
        RotationError::InvalidQuaternion { index: 1 }
    );
    assert_eq!(
        Squad::<f64, 4>::new(&[k(0.0, id), k(0.0, id)]).unwrap_err(),
        RotationError::TimesNotIncreasing { index: 1 }
    );
    assert_eq!(Squad::<f64, 4>::new(&[k(f64::NAN, id)]).unwrap_err(), RotationError::NonFiniteTime { index: 0 });
    assert_eq!(
        Squad::<f64, 4>::new(&[k(-1e308, id), k(1e308, id)]).unwrap_err(),
        RotationError::NonFiniteTime { index: 1 }
    );
    // A single keyframe is a constant orientation.
    let one = Squad::<f64, 1>::new(&[k(3.0, [0.0, 2.0, 0.0, 0.0])]).unwrap();
    assert_eq!(one.orientation(5.0).wxyz(), [0.0, 1.0, 0.0, 0.0]);
    assert_eq!(one.angular_velocity(3.0), Vector3::zeros());
}
