//! Interpolation through keyframes: the Hermite family (Catmull-Rom, Kochanek-Bartels, monotone,
//! given velocities), natural and clamped cubic splines, stepped and linear, Bezier control
//! points, and the approximating uniform B-spline. Checked for exactness at keyframes, continuity
//! at joins, locality, monotonicity, and against SciPy.

use kinematics::trajectory::{
    basis, bezier_point, bspline_sample, Curve, EndCondition, HermiteSegment, Keyframe, KochanekBartels,
    TrajectoryError,
};
use nalgebra::{SVector, Vector1, Vector2};
use proptest::prelude::*;

const K: usize = 16;
type C2 = Curve<f64, 2, K>;
type Build = fn(&[Keyframe<f64, 2>]) -> C2;
type TryBuild = fn(&[Keyframe<f64, 2>]) -> Result<Curve<f64, 2, 4>, TrajectoryError>;

fn keyframes2(points: &[(f64, [f64; 2])]) -> Vec<Keyframe<f64, 2>> {
    points.iter().map(|&(time, p)| Keyframe { time, position: Vector2::from(p) }).collect()
}

/// Non-uniform times, a sign change, a flat stretch and a steep step in the two joints.
fn sample_keys() -> Vec<Keyframe<f64, 2>> {
    keyframes2(&[
        (0.0, [0.0, 1.0]),
        (0.4, [0.8, 1.0]),
        (1.5, [0.3, 1.0]),
        (1.7, [1.9, 2.5]),
        (3.0, [2.0, -0.5]),
        (3.25, [-1.0, 0.0]),
        (4.5, [0.5, 0.25]),
    ])
}

const TCB: KochanekBartels<f64> = KochanekBartels { tension: 0.3, continuity: 0.0, bias: -0.4 };

/// Every C1 construction, by name.
fn c1_curves(keys: &[Keyframe<f64, 2>]) -> Vec<(&'static str, C2)> {
    let clamped = EndCondition::Clamped { start: Vector2::new(1.0, -2.0), end: Vector2::new(0.5, 0.0) };
    let velocities: Vec<_> = (0..keys.len()).map(|i| Vector2::new(i as f64 - 2.0, 0.5 * i as f64)).collect();
    vec![
        ("catmull-rom zero", C2::catmull_rom(keys, EndCondition::ZeroVelocity).unwrap()),
        ("catmull-rom clamped", C2::catmull_rom(keys, clamped).unwrap()),
        ("catmull-rom natural", C2::catmull_rom(keys, EndCondition::Natural).unwrap()),
        ("kochanek-bartels", C2::kochanek_bartels(keys, TCB, EndCondition::Natural).unwrap()),
        ("monotone", C2::monotone(keys).unwrap()),
        ("natural spline", C2::natural_spline(keys).unwrap()),
        ("clamped spline", C2::clamped_spline(keys, Vector2::new(1.0, -2.0), Vector2::new(0.5, 0.0)).unwrap()),
        ("given velocities", C2::with_velocities(keys, &velocities).unwrap()),
    ]
}

fn close(a: SVector<f64, 2>, b: SVector<f64, 2>, tol: f64) -> bool {
    (a - b).amax() <= tol
}

#[test]
fn every_interpolating_method_is_exact_at_keyframes() {
    let keys = sample_keys();
    let mut curves = c1_curves(&keys);
    let corner = KochanekBartels { tension: 0.0, continuity: 0.6, bias: 0.2 };
    curves.push(("kochanek-bartels corner", C2::kochanek_bartels(&keys, corner, EndCondition::ZeroVelocity).unwrap()));
    curves.push(("stepped", C2::stepped(&keys).unwrap()));
    curves.push(("linear", C2::linear(&keys).unwrap()));
    for (name, curve) in &curves {
        for (i, k) in keys.iter().enumerate() {
            assert_eq!(curve.sample(k.time).position, k.position, "{name}, keyframe {i}");
        }
        // The left limit at each keyframe (end of the previous segment) also lands on it.
        if curve.interpolation() == kinematics::trajectory::Interpolation::Hermite {
            for (i, k) in keys.iter().enumerate().skip(1) {
                let left = curve.segment(i - 1).sample(k.time).position;
                assert!(close(left, k.position, 1e-15), "{name}, keyframe {i}: {left:?}");
            }
        }
    }
}

#[test]
fn stepped_holds_and_linear_is_straight() {
    let keys = sample_keys();
    let (stepped, linear) = (C2::stepped(&keys).unwrap(), C2::linear(&keys).unwrap());
    assert_eq!(stepped.sample(1.69).position, keys[2].position);
    let mid = linear.sample(0.2);
    assert!(close(mid.position, Vector2::new(0.4, 1.0), 1e-15));
    assert!(close(mid.velocity, Vector2::new(2.0, 0.0), 1e-14));
}

#[test]
fn c1_at_every_join() {
    let keys = sample_keys();
    for (name, curve) in c1_curves(&keys) {
        for (i, k) in keys.iter().enumerate().take(keys.len() - 1).skip(1) {
            let (left, right) = (curve.segment(i - 1).sample(k.time), curve.segment(i).sample(k.time));
            assert!(close(left.velocity, right.velocity, 1e-9), "{name}, join {i}: {left:?} vs {right:?}");
        }
    }
}

#[test]
fn kochanek_bartels_continuity_makes_a_corner() {
    let keys = sample_keys();
    let corner = KochanekBartels { tension: 0.0, continuity: 0.5, bias: 0.0 };
    let curve = C2::kochanek_bartels(&keys, corner, EndCondition::ZeroVelocity).unwrap();
    let (left, right) = (curve.segment(0).sample(0.4), curve.segment(1).sample(0.4));
    assert!((left.velocity - right.velocity).amax() > 0.1, "{left:?} vs {right:?}");
    // Textbook uniform TCB at keyframe 1 (unit times): arriving (1-c)/2 a + (1+c)/2 e.
    let uniform = keyframes2(&[(0.0, [0.0, 0.0]), (1.0, [1.0, 3.0]), (2.0, [3.0, 2.0])]);
    let tcb = KochanekBartels { tension: 0.2, continuity: 0.5, bias: -0.3 };
    let curve = C2::kochanek_bartels(&uniform, tcb, EndCondition::ZeroVelocity).unwrap();
    let (a, e) = (Vector2::new(1.0, 3.0), Vector2::new(2.0, -1.0));
    let (t, c, b) = (0.2, 0.5, -0.3);
    let arriving = a * ((1.0 - t) * (1.0 + b) * (1.0 - c) / 2.0) + e * ((1.0 - t) * (1.0 - b) * (1.0 + c) / 2.0);
    let leaving = a * ((1.0 - t) * (1.0 + b) * (1.0 + c) / 2.0) + e * ((1.0 - t) * (1.0 - b) * (1.0 - c) / 2.0);
    assert!(close(curve.arriving()[1], arriving, 1e-15), "{:?} vs {arriving:?}", curve.arriving()[1]);
    assert!(close(curve.leaving()[1], leaving, 1e-15), "{:?} vs {leaving:?}", curve.leaving()[1]);
    // Tension 1 flattens every interior tangent.
    let flat = KochanekBartels { tension: 1.0, continuity: 0.0, bias: 0.0 };
    let curve = C2::kochanek_bartels(&keys, flat, EndCondition::ZeroVelocity).unwrap();
    assert!(curve.leaving().iter().all(|v| *v == Vector2::zeros()));
}

#[test]
fn c2_at_every_join_for_the_splines() {
    let keys = sample_keys();
    let natural = C2::natural_spline(&keys).unwrap();
    let clamped = C2::clamped_spline(&keys, Vector2::new(1.0, -2.0), Vector2::new(0.5, 0.0)).unwrap();
    for (name, curve) in [("natural", &natural), ("clamped", &clamped)] {
        for (i, k) in keys.iter().enumerate().take(keys.len() - 1).skip(1) {
            let (left, right) = (curve.segment(i - 1).sample(k.time), curve.segment(i).sample(k.time));
            assert!(close(left.velocity, right.velocity, 1e-9), "{name}, join {i}");
            assert!(close(left.acceleration, right.acceleration, 1e-9), "{name}, join {i}: {left:?} vs {right:?}");
        }
    }
    let last = keys.len() - 1;
    assert!(natural.segment(0).sample(0.0).acceleration.amax() < 1e-12);
    assert!(natural.segment(last - 1).sample(keys[last].time).acceleration.amax() < 1e-12);
    assert_eq!(clamped.leaving()[0], Vector2::new(1.0, -2.0));
    assert_eq!(clamped.arriving()[last], Vector2::new(0.5, 0.0));
}

#[test]
fn catmull_rom_uses_the_non_uniform_chord_and_the_end_conditions() {
    let keys = sample_keys();
    let last = keys.len() - 1;
    let start = Vector2::new(1.0, -2.0);
    let end = Vector2::new(0.5, 0.0);
    let zero = C2::catmull_rom(&keys, EndCondition::ZeroVelocity).unwrap();
    let clamped = C2::catmull_rom(&keys, EndCondition::Clamped { start, end }).unwrap();
    let natural = C2::catmull_rom(&keys, EndCondition::Natural).unwrap();
    for curve in [&zero, &clamped, &natural] {
        for i in 1..last {
            let u = (keys[i + 1].position - keys[i - 1].position) / (keys[i + 1].time - keys[i - 1].time);
            assert_eq!(curve.leaving()[i], u, "keyframe {i}");
            assert_eq!(curve.arriving()[i], u, "keyframe {i}");
        }
    }
    assert_eq!((zero.leaving()[0], zero.arriving()[last]), (Vector2::zeros(), Vector2::zeros()));
    assert_eq!((clamped.leaving()[0], clamped.arriving()[last]), (start, end));
    assert!(natural.segment(0).sample(0.0).acceleration.amax() < 1e-12);
    assert!(natural.segment(last - 1).sample(keys[last].time).acceleration.amax() < 1e-12);
}

#[test]
fn kochanek_bartels_with_zero_parameters_is_catmull_rom() {
    let keys = sample_keys();
    for ends in [
        EndCondition::ZeroVelocity,
        EndCondition::Natural,
        EndCondition::Clamped { start: Vector2::new(0.3, 0.1), end: Vector2::new(-1.0, 2.0) },
    ] {
        let kb = C2::kochanek_bartels(&keys, KochanekBartels::default(), ends).unwrap();
        let cr = C2::catmull_rom(&keys, ends).unwrap();
        for i in 0..keys.len() {
            assert!(close(kb.leaving()[i], cr.leaving()[i], 1e-12), "{ends:?}, keyframe {i}");
            assert!(close(kb.arriving()[i], cr.arriving()[i], 1e-12), "{ends:?}, keyframe {i}");
        }
    }
}

/// Indices of the segments whose Hermite data differ between two curves.
fn changed_segments(a: &C2, b: &C2) -> Vec<usize> {
    (0..a.times().len() - 1).filter(|&i| a.segment(i) != b.segment(i)).collect()
}

#[test]
fn local_methods_change_only_neighbouring_segments_and_splines_change_all() {
    let keys = sample_keys();
    let j = 3;
    let mut moved = keys.clone();
    moved[j].position += Vector2::new(0.35, -0.2);
    let local: [(&str, Build); 3] = [
        ("catmull-rom", |k| C2::catmull_rom(k, EndCondition::Natural).unwrap()),
        ("kochanek-bartels", |k| C2::kochanek_bartels(k, TCB, EndCondition::ZeroVelocity).unwrap()),
        ("monotone", |k| C2::monotone(k).unwrap()),
    ];
    for (name, build) in local {
        let changed = changed_segments(&build(&keys), &build(&moved));
        // Tangents at j - 1, j, j + 1 change: segments j - 2 ..= j + 1 and no others.
        assert!(changed.iter().all(|&i| i + 2 >= j && i <= j + 1), "{name}: {changed:?}");
        assert!(changed.contains(&(j - 1)) && changed.contains(&j), "{name}: {changed:?}");
    }
    let natural = changed_segments(&C2::natural_spline(&keys).unwrap(), &C2::natural_spline(&moved).unwrap());
    assert_eq!(natural, (0..keys.len() - 1).collect::<Vec<_>>());
}

#[test]
fn hermite_basis_matches_finite_differences() {
    let h = 1e-5;
    for i in 0..=20 {
        let s = f64::from(i) / 20.0;
        let [b, d1, d2] = basis(s);
        let ([bp, d1p, _], [bm, d1m, _]) = (basis(s + h), basis(s - h));
        for k in 0..4 {
            assert!(((bp[k] - bm[k]) / (2.0 * h) - d1[k]).abs() < 1e-9, "s {s}, H{k}'");
            assert!(((d1p[k] - d1m[k]) / (2.0 * h) - d2[k]).abs() < 1e-9, "s {s}, H{k}''");
        }
        // Partition of unity for the value weights.
        assert!((b[0] + b[3] - 1.0).abs() < 1e-15);
    }
    // And the time-scaled segment: velocity and acceleration against its own positions.
    let seg = HermiteSegment {
        t0: 0.7,
        t1: 2.2,
        p0: Vector2::new(1.0, -1.0),
        v0: Vector2::new(0.5, 3.0),
        p1: Vector2::new(-0.5, 2.0),
        v1: Vector2::new(-2.0, 0.0),
    };
    for i in 1..10 {
        let t = 0.7 + 1.5 * f64::from(i) / 10.0;
        let (p, m, c) = (seg.sample(t + h), seg.sample(t - h), seg.sample(t));
        assert!(close((p.position - m.position) / (2.0 * h), c.velocity, 1e-8));
        assert!(close((p.velocity - m.velocity) / (2.0 * h), c.acceleration, 1e-7));
    }
}

#[test]
fn bezier_round_trip_and_same_curve() {
    let keys = sample_keys();
    let curve = C2::catmull_rom(&keys, EndCondition::Natural).unwrap();
    for i in 0..keys.len() - 1 {
        let seg = curve.segment(i);
        let control = seg.to_bezier();
        let back = HermiteSegment::from_bezier(seg.t0, seg.t1, control);
        assert_eq!((back.t0, back.t1, back.p0, back.p1), (seg.t0, seg.t1, seg.p0, seg.p1));
        assert!(close(back.v0, seg.v0, 1e-13) && close(back.v1, seg.v1, 1e-13), "segment {i}");
        let again = back.to_bezier();
        for k in 0..4 {
            assert!(close(again[k], control[k], 1e-15), "segment {i}, point {k}");
        }
        for step in 0..=8 {
            let s = f64::from(step) / 8.0;
            let t = seg.t0 + (seg.t1 - seg.t0) * s;
            assert!(close(bezier_point(&control, s), seg.sample(t).position, 1e-14), "segment {i}, s {s}");
        }
    }
    // With representable thirds the round trip is bit-exact.
    let seg = HermiteSegment {
        t0: 0.0,
        t1: 3.0,
        p0: Vector1::new(1.0),
        v0: Vector1::new(0.5),
        p1: Vector1::new(-2.0),
        v1: Vector1::new(4.0),
    };
    assert_eq!(HermiteSegment::from_bezier(0.0, 3.0, seg.to_bezier()), seg);
}

#[test]
fn bspline_is_c2_and_approximating() {
    let keys = sample_keys();
    let curve = C2::linear(&keys).unwrap();
    let (start, end) = (curve.start(), curve.end());
    assert_eq!(curve.bspline_sample(start).position, keys[0].position);
    assert_eq!(curve.bspline_sample(end).position, keys[keys.len() - 1].position);
    let first = curve.bspline_sample(start + 1e-12);
    assert!(close(first.position, keys[0].position, 1e-12));
    // Uniform knots: n + 1 segments over [start, end]. Across each knot the position, velocity and
    // acceleration move by no more than the jerk allows over 2 eps.
    let segments = keys.len() + 1;
    let width = (end - start) / segments as f64;
    let eps = 1e-7;
    for k in 1..segments {
        let knot = start + width * k as f64;
        let (l, r) = (curve.bspline_sample(knot - eps), curve.bspline_sample(knot + eps));
        assert!(close(l.position, r.position, 1e-5), "knot {k}");
        assert!(close(l.velocity, r.velocity, 1e-5), "knot {k}");
        assert!(close(l.acceleration, r.acceleration, 1e-4), "knot {k}: {l:?} vs {r:?}");
    }
    // Misses the interior keyframes: keyframe 3 (a peak in joint 1, 2.5 between 1.0 and -0.5) is
    // not reached anywhere, as the curve stays in the convex hull of its neighbours' points.
    let peak = (0..=1000).map(|i| curve.bspline_sample(start + (end - start) * f64::from(i) / 1000.0).position[1]);
    let highest = peak.fold(f64::NEG_INFINITY, f64::max);
    assert!(highest < 2.5 - 0.3, "{highest}");
    for (i, k) in keys.iter().enumerate().take(keys.len() - 1).skip(1) {
        assert!(!close(curve.bspline_sample(k.time).position, k.position, 1e-3), "keyframe {i}");
    }
    // The free function agrees with the method.
    let positions: Vec<_> = keys.iter().map(|k| k.position).collect();
    assert_eq!(bspline_sample(&positions, start, end, 1.3).unwrap(), curve.bspline_sample(1.3));
}

#[test]
fn one_and_two_keyframes() {
    let one = keyframes2(&[(1.0, [0.5, -0.5])]);
    let two = keyframes2(&[(1.0, [0.5, -0.5]), (3.0, [1.5, 0.5])]);
    let ends = EndCondition::Natural;
    let holds = [
        C2::catmull_rom(&one, ends).unwrap(),
        C2::kochanek_bartels(&one, TCB, ends).unwrap(),
        C2::monotone(&one).unwrap(),
        C2::natural_spline(&one).unwrap(),
        C2::clamped_spline(&one, Vector2::new(1.0, 1.0), Vector2::zeros()).unwrap(),
    ];
    for curve in &holds {
        for t in [0.0, 1.0, 2.0] {
            let s = curve.sample(t);
            assert_eq!((s.position, s.velocity), (one[0].position, Vector2::zeros()));
        }
        assert_eq!(curve.bspline_sample(2.0).position, one[0].position);
    }
    // Natural ends, monotone (one-sided) and the natural spline all give the straight line.
    let lines = [
        C2::catmull_rom(&two, ends).unwrap(),
        C2::kochanek_bartels(&two, KochanekBartels::default(), ends).unwrap(),
        C2::monotone(&two).unwrap(),
        C2::natural_spline(&two).unwrap(),
    ];
    for curve in &lines {
        let s = curve.sample(2.5);
        assert!(close(s.position, Vector2::new(1.25, 0.25), 1e-15) && close(s.velocity, Vector2::new(0.5, 0.5), 1e-15));
    }
    let rest = C2::catmull_rom(&two, EndCondition::ZeroVelocity).unwrap();
    assert_eq!(rest.leaving()[0], Vector2::zeros());
    let clamped = C2::clamped_spline(&two, Vector2::new(1.0, 0.0), Vector2::new(0.0, 2.0)).unwrap();
    assert_eq!((clamped.leaving()[0], clamped.arriving()[1]), (Vector2::new(1.0, 0.0), Vector2::new(0.0, 2.0)));
}

#[test]
fn bad_keyframes_are_errors() {
    let constructors: [(&str, TryBuild); 5] = [
        ("catmull-rom", |k| Curve::catmull_rom(k, EndCondition::ZeroVelocity)),
        ("kochanek-bartels", |k| Curve::kochanek_bartels(k, TCB, EndCondition::Natural)),
        ("monotone", |k| Curve::monotone(k)),
        ("natural", |k| Curve::natural_spline(k)),
        ("clamped", |k| Curve::clamped_spline(k, Vector2::zeros(), Vector2::zeros())),
    ];
    let five = keyframes2(&[(0.0, [0.0; 2]), (1.0, [0.0; 2]), (2.0, [0.0; 2]), (3.0, [0.0; 2]), (4.0, [0.0; 2])]);
    let repeated = keyframes2(&[(0.0, [0.0; 2]), (1.0, [1.0; 2]), (1.0, [2.0; 2])]);
    let nan = keyframes2(&[(0.0, [0.0; 2]), (1.0, [1.0, f64::NAN]), (2.0, [2.0; 2])]);
    let inf_time = keyframes2(&[(0.0, [0.0; 2]), (f64::INFINITY, [1.0; 2])]);
    for (name, build) in constructors {
        assert_eq!(build(&[]).unwrap_err(), TrajectoryError::Empty, "{name}");
        assert_eq!(build(&five).unwrap_err(), TrajectoryError::TooMany { capacity: 4 }, "{name}");
        assert_eq!(build(&repeated).unwrap_err(), TrajectoryError::TimesNotIncreasing { index: 2 }, "{name}");
        assert_eq!(build(&nan).unwrap_err(), TrajectoryError::NonFinite { index: 1 }, "{name}");
        assert_eq!(build(&inf_time).unwrap_err(), TrajectoryError::NonFinite { index: 1 }, "{name}");
    }
    let nan_end = EndCondition::Clamped { start: Vector2::zeros(), end: Vector2::new(f64::NAN, 0.0) };
    assert_eq!(C2::catmull_rom(&five, nan_end).unwrap_err(), TrajectoryError::NonFinite { index: 4 });
    assert_eq!(C2::catmull_rom(&five[..1], nan_end).unwrap_err(), TrajectoryError::NonFinite { index: 0 });
    let nan_clamp = C2::clamped_spline(&five[..1], Vector2::zeros(), Vector2::new(0.0, f64::INFINITY));
    assert_eq!(nan_clamp.unwrap_err(), TrajectoryError::NonFinite { index: 0 });
}

#[test]
fn works_in_f32() {
    let keys: Vec<Keyframe<f32, 1>> = [(0.0, 0.0), (0.5, 1.0), (2.0, 0.5)]
        .iter()
        .map(|&(time, p)| Keyframe { time, position: Vector1::new(p) })
        .collect();
    let cr = Curve::<f32, 1, 4>::catmull_rom(&keys, EndCondition::Natural).unwrap();
    let ns = Curve::<f32, 1, 4>::natural_spline(&keys).unwrap();
    let mono = Curve::<f32, 1, 4>::monotone(&keys).unwrap();
    for curve in [&cr, &ns, &mono] {
        for k in &keys {
            assert_eq!(curve.sample(k.time).position, k.position);
        }
    }
    assert!((cr.leaving()[1][0] - 0.25).abs() < 1e-7);
}

// SciPy reference values (scipy 1.x), produced by this script:
//
//     import numpy as np
//     from scipy.interpolate import CubicSpline, CubicHermiteSpline
//     t = np.array([0.0, 0.5, 1.75, 2.0, 3.5])
//     y = np.array([1.0, -0.5, 2.0, 2.5, 0.0])
//     x = np.array([0.1, 0.5, 0.9, 1.75, 1.9, 2.7, 3.4])
//     def show(name, s):
//         print(name)
//         for d in range(3):
//             print("  d%d: [%s]" % (d, ", ".join(repr(float(v)) for v in s(x, d))))
//     show("natural", CubicSpline(t, y, bc_type='natural'))
//     show("clamped", CubicSpline(t, y, bc_type=((1, 1.5), (1, -2.0))))
//     # Catmull-Rom tangents, zero-velocity ends
//     u = np.zeros_like(y)
//     u[1:-1] = (y[2:] - y[:-2]) / (t[2:] - t[:-2])
//     show("hermite", CubicHermiteSpline(t, y, u))
//
// At a keyframe both SciPy and `Curve::sample` evaluate the segment to its right.
const SCIPY_T: [f64; 5] = [0.0, 0.5, 1.75, 2.0, 3.5];
const SCIPY_Y: [f64; 5] = [1.0, -0.5, 2.0, 2.5, 0.0];
const SCIPY_X: [f64; 7] = [0.1, 0.5, 0.9, 1.75, 1.9, 2.7, 3.4];
const SCIPY_NATURAL: [[f64; 7]; 3] = [
    [0.6211267605633802, -0.5, -0.36889014084507044, 2.0, 2.3367323943661975, 2.1960312989045376, 0.3167010954616587],
    [
        -3.723004694835681,
        -1.3568075117370892,
        1.7251079812206571,
        2.5516431924882625,
        1.901784037558686,
        -1.8876995305164328,
        -3.15361502347418,
    ],
    [
        1.9718309859154908,
        9.859154929577464,
        5.550422535211266,
        -3.605633802816893,
        -5.059154929577465,
        -3.2150234741784036,
        -0.401877934272302,
    ],
];
const SCIPY_CLAMPED: [[f64; 7]; 3] = [
    [0.9926638655462185, -0.5, -0.7475142857142856, 2.0, 2.3491659663865545, 1.9544749455337684, 0.21329956427015295],
    [
        -1.4783823529411764,
        -3.291491596638656,
        1.5930126050420166,
        2.7904411764705883,
        1.847710084033614,
        -2.1766199813258638,
        -2.254904295051352,
    ],
    [
        -24.733613445378158,
        15.668067226890757,
        8.754453781512606,
        -5.936974789915968,
        -6.632773109243697,
        -2.440102707749764,
        2.2164332399626527,
    ],
];
const SCIPY_HERMITE: [[f64; 7]; 3] = [
    [0.8348571428571427, -0.5, 0.03577142857142857, 2.0, 2.413142857142857, 1.1472592592592585, 0.024740740740740286],
    [-3.04, 0.5714285714285714, 1.9611428571428569, 2.0, 2.377142857142858, -2.245079365079365, -0.48507936507936655],
    [
        -22.514285714285712,
        4.571428571428571,
        2.3771428571428563,
        25.142857142857142,
        -20.11428571428569,
        0.46984126984127084,
        4.558730158730158,
    ],
];

fn check_scipy(name: &str, curve: &Curve<f64, 1, K>, expected: &[[f64; 7]; 3]) {
    for (i, &x) in SCIPY_X.iter().enumerate() {
        let s = curve.sample(x);
        let got = [s.position[0], s.velocity[0], s.acceleration[0]];
        for d in 0..3 {
            let want = expected[d][i];
            assert!((got[d] - want).abs() <= 1e-12, "{name}, x = {x}, derivative {d}: {} vs {want}", got[d]);
        }
    }
}

#[test]
fn matches_scipy() {
    let keys: Vec<Keyframe<f64, 1>> =
        SCIPY_T.iter().zip(SCIPY_Y).map(|(&time, y)| Keyframe { time, position: Vector1::new(y) }).collect();
    check_scipy("natural", &Curve::natural_spline(&keys).unwrap(), &SCIPY_NATURAL);
    let clamped = Curve::clamped_spline(&keys, Vector1::new(1.5), Vector1::new(-2.0)).unwrap();
    check_scipy("clamped", &clamped, &SCIPY_CLAMPED);
    check_scipy("catmull-rom", &Curve::catmull_rom(&keys, EndCondition::ZeroVelocity).unwrap(), &SCIPY_HERMITE);
}

/// Strictly increasing times from positive gaps, and values that rise (or fall) by non-negative
/// steps, including flat stretches.
fn monotone_keys() -> impl Strategy<Value = (Vec<Keyframe<f64, 2>>, bool)> {
    (
        proptest::collection::vec((0.01..3.0f64, prop_oneof![Just(0.0), 0.0..5.0f64], 0.0..0.5f64), 2..K),
        any::<bool>(),
        -10.0..10.0f64,
    )
        .prop_map(|(steps, falling, start)| {
            let sign = if falling { -1.0 } else { 1.0 };
            let (mut t, mut p) = (0.0, Vector2::new(start, -start));
            let mut keys = vec![Keyframe { time: t, position: p }];
            for (gap, step0, step1) in steps.into_iter().skip(1) {
                t += gap;
                p += Vector2::new(sign * step0, -sign * step1);
                keys.push(Keyframe { time: t, position: p });
            }
            (keys, falling)
        })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn monotone_never_overshoots((keys, _) in monotone_keys(), fractions in proptest::collection::vec(0.0..1.0f64, 8)) {
        let curve = C2::monotone(&keys).unwrap();
        for i in 0..keys.len() - 1 {
            let (a, b) = (keys[i].position, keys[i + 1].position);
            let seg = curve.segment(i);
            let mut previous = a;
            let mut steps: Vec<f64> = fractions.clone();
            steps.sort_by(f64::total_cmp);
            for f in steps.into_iter().chain([1.0]) {
                let p = seg.sample(seg.t0 + (seg.t1 - seg.t0) * f).position;
                for j in 0..2 {
                    let (lo, hi) = (a[j].min(b[j]), a[j].max(b[j]));
                    let tol = 1e-12 * (1.0 + lo.abs().max(hi.abs()));
                    prop_assert!(p[j] >= lo - tol && p[j] <= hi + tol, "segment {}, joint {}: {} outside [{}, {}]", i, j, p[j], lo, hi);
                    // Monotone along the segment as well, in the direction of the data.
                    let dir = (b[j] - a[j]).signum();
                    prop_assert!((p[j] - previous[j]) * dir >= -tol, "segment {}, joint {}: turns back", i, j);
                }
                previous = p;
            }
        }
    }

    #[test]
    fn constructors_never_panic(
        raw in proptest::collection::vec((-1e300..1e300f64, prop_oneof![Just(f64::NAN), Just(f64::INFINITY), -1e3..1e3f64], -1e3..1e3f64), 0..K + 2),
        tension in -2.0..2.0f64,
        continuity in -2.0..2.0f64,
        bias in -2.0..2.0f64,
        t in -10.0..10.0f64,
        sorted in any::<bool>(),
    ) {
        let mut keys: Vec<Keyframe<f64, 2>> = raw.iter().map(|&(time, a, b)| Keyframe { time: time * 1e-299, position: Vector2::new(a, b) }).collect();
        if sorted {
            // Mostly valid input, so the tangent code itself runs on extreme values.
            keys.sort_by(|a, b| a.time.total_cmp(&b.time));
        }
        let tcb = KochanekBartels { tension, continuity, bias };
        let results = [
            C2::catmull_rom(&keys, EndCondition::Natural),
            C2::kochanek_bartels(&keys, tcb, EndCondition::ZeroVelocity),
            C2::monotone(&keys),
            C2::natural_spline(&keys),
            C2::clamped_spline(&keys, Vector2::new(1.0, f64::MAX), Vector2::zeros()),
        ];
        for curve in results.iter().flatten() {
            let s = curve.sample(t);
            prop_assert!(s.position.iter().all(|x| !x.is_nan()));
            let _ = curve.bspline_sample(t);
        }
        let positions: Vec<_> = keys.iter().map(|k| k.position).collect();
        let _ = bspline_sample(&positions, 0.0, 1.0, t);
    }
}

/// Keyframes 1e-200 s apart: h^2 underflows, so velocity and acceleration could not be finite; the
/// keyframes are refused rather than producing NaN samples. Segment indices past the end are safe.
#[test]
fn unusably_short_intervals_are_refused_and_segment_indices_are_total() {
    use kinematics::nalgebra::SVector;
    use kinematics::trajectory::{Curve, Keyframe, TrajectoryError};
    let keys = [
        Keyframe { time: 0.0, position: SVector::<f64, 1>::from([0.0]) },
        Keyframe { time: 1e-200, position: SVector::<f64, 1>::from([1.0]) },
    ];
    let refused = Err(TrajectoryError::TimesNotIncreasing { index: 1 });
    assert_eq!(Curve::<f64, 1, 4>::monotone(&keys).map(|_| ()), refused);
    assert_eq!(Curve::<f64, 1, 4>::linear(&keys).map(|_| ()), refused);
    assert_eq!(Curve::<f64, 1, 4>::natural_spline(&keys).map(|_| ()), refused);
    let one = Curve::<f64, 1, 4>::linear(&keys[..1]).unwrap();
    let s = one.segment(5).sample(0.5);
    assert_eq!((s.position[0], s.velocity[0], s.acceleration[0]), (0.0, 0.0, 0.0));
    let keys = [keys[0], Keyframe { time: 1.0, position: SVector::from([1.0]) }];
    let two = Curve::<f64, 1, 4>::catmull_rom(&keys, kinematics::trajectory::EndCondition::ZeroVelocity).unwrap();
    assert_eq!(two.segment(7), two.segment(0));
}
