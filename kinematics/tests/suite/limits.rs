//! Joint limits: the analytic check against dense sampling, and time scaling's guarantees.

use kinematics::nalgebra::{SVector, Vector3};
use kinematics::trajectory::{time_scale, Curve, JointLimits, Keyframe, Limit, Location};
use proptest::prelude::*;

const SAMPLES: usize = 400;

fn limits() -> JointLimits<f64, 3> {
    JointLimits::new(
        Vector3::new(-1.0, -2.0, -0.5),
        Vector3::new(1.0, 2.0, 1.5),
        Vector3::new(1.0, 2.5, 0.7),
        Vector3::new(3.0, 10.0, 2.0),
    )
    .unwrap()
}

/// Keyframes inside the range of `limits()` (`u` in [0, 1] maps onto each joint's range), times
/// from gaps, and arbitrary (often infeasible) velocities.
fn trajectory(gaps: &[f64], u: &[[f64; 3]], v: &[[f64; 3]]) -> (Vec<Keyframe<f64, 3>>, Vec<SVector<f64, 3>>) {
    let l = limits();
    let mut time = 0.25;
    let mut keys = Vec::new();
    for (i, u) in u.iter().enumerate() {
        if i > 0 {
            time += gaps[i - 1];
        }
        let position = l.lower + (l.upper - l.lower).component_mul(&Vector3::from(*u));
        keys.push(Keyframe { time, position });
    }
    (keys, v.iter().map(|v| Vector3::from(*v)).collect())
}

/// The largest excess over the limits found by sampling every segment densely (independent of
/// the analytic extrema in `check`): (position, velocity, acceleration).
fn sampled_excess(curve: &Curve<f64, 3, 8>, l: &JointLimits<f64, 3>) -> (f64, f64, f64) {
    let mut worst = (f64::NEG_INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY);
    let times = curve.times();
    for i in 0..times.len() - 1 {
        let seg = curve.segment(i);
        for k in 0..=SAMPLES {
            let t = seg.t0 + (seg.t1 - seg.t0) * k as f64 / SAMPLES as f64;
            let s = seg.sample(t);
            for j in 0..3 {
                worst.0 = worst.0.max(l.lower[j] - s.position[j]).max(s.position[j] - l.upper[j]);
                worst.1 = worst.1.max(s.velocity[j].abs() - l.max_velocity[j]);
                worst.2 = worst.2.max(s.acceleration[j].abs() - l.max_acceleration[j]);
            }
        }
    }
    worst
}

fn case() -> impl Strategy<Value = (Vec<f64>, Vec<[f64; 3]>, Vec<[f64; 3]>)> {
    (2usize..=8).prop_flat_map(|n| {
        (
            proptest::collection::vec(0.02..3.0f64, n - 1),
            proptest::collection::vec(proptest::array::uniform3(0.0..=1.0f64), n),
            proptest::collection::vec(proptest::array::uniform3(-6.0..6.0f64), n),
        )
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    #[test]
    fn time_scaled_trajectories_meet_every_limit((gaps, u, v) in case()) {
        let l = limits();
        let (keys, vel) = trajectory(&gaps, &u, &v);
        let r = time_scale::<f64, 3, 8>(&keys, &vel, &l).unwrap();
        let curve = r.curve().unwrap();
        // The analytic check passes ...
        prop_assert!(l.check(&curve).is_ok(), "{:?}", l.check(&curve));
        // ... and so does dense sampling, a second, independent check.
        let (p, dv, da) = sampled_excess(&curve, &l);
        prop_assert!(p <= 1e-9, "position beyond the range by {p}");
        prop_assert!(dv <= 1e-9, "velocity beyond the limit by {dv}");
        prop_assert!(da <= 1e-9, "acceleration beyond the limit by {da}");
        // Keyframes do not move; time only stretches.
        prop_assert_eq!(r.keyframes.len(), keys.len());
        prop_assert_eq!(r.keyframes[0].time, keys[0].time);
        for (i, (a, b)) in r.keyframes.iter().zip(&keys).enumerate() {
            prop_assert_eq!(a.position, b.position);
            if i > 0 {
                let (new, old) = (a.time - r.keyframes[i - 1].time, b.time - keys[i - 1].time);
                prop_assert!((new / old - r.stretch[i - 1]).abs() < 1e-9);
                prop_assert!(r.stretch[i - 1] >= 1.0);
            }
        }
        // Velocities only shrink, component by component, and keep their sign.
        for (a, b) in r.velocities.iter().zip(&vel) {
            for j in 0..3 {
                prop_assert!(a[j].abs() <= b[j].abs() && a[j] * b[j] >= 0.0);
            }
        }
    }

    #[test]
    fn feasible_trajectories_are_left_alone(
        (gaps, u, _) in case(),
    ) {
        // Zero velocities and long segments: 1.5 * 2 / 10 < 0.7 and 6 * 2 / 100 < 2.
        let l = limits();
        let gaps: Vec<f64> = gaps.iter().map(|g| g + 10.0).collect();
        let zeros = vec![[0.0; 3]; u.len()];
        let (keys, vel) = trajectory(&gaps, &u, &zeros);
        let r = time_scale::<f64, 3, 8>(&keys, &vel, &l).unwrap();
        prop_assert!(!r.slowed() && !r.range_clamped());
        for (a, b) in r.keyframes.iter().zip(&keys) {
            prop_assert_eq!(a, b);
        }
    }

    #[test]
    fn check_misses_nothing_sampling_finds((gaps, u, v) in case()) {
        let l = limits();
        let (keys, vel) = trajectory(&gaps, &u, &v);
        let curve = Curve::<f64, 3, 8>::with_velocities(&keys, &vel).unwrap();
        let (p, dv, da) = sampled_excess(&curve, &l);
        match l.check(&curve) {
            Ok(()) => prop_assert!(p <= 1e-9 && dv <= 1e-9 && da <= 1e-9, "{p} {dv} {da}"),
            Err(violation) => {
                // What it reports is real: the value is on the curve at the reported time.
                prop_assert!(violation.excess > 0.0);
                if let Location::Segment(i) = violation.location {
                    let s = curve.segment(i).sample(violation.time);
                    let j = violation.joint;
                    let found = match violation.limit {
                        Limit::Lower | Limit::Upper => s.position[j],
                        Limit::Velocity => s.velocity[j].abs(),
                        Limit::Acceleration => s.acceleration[j].abs(),
                        Limit::Invalid => f64::NAN,
                    };
                    prop_assert!((found - violation.value).abs() <= 1e-9 * (1.0 + found.abs()));
                }
            }
        }
    }
}

#[test]
fn f32_time_scaling_passes_its_check() {
    let l = JointLimits::<f32, 2>::new(
        SVector::from([-1.0, -1.0]),
        SVector::from([1.0, 1.0]),
        SVector::from([0.5, 0.5]),
        SVector::from([1.0, 1.0]),
    )
    .unwrap();
    let keys = [
        Keyframe { time: 0.0f32, position: SVector::from([0.0, 0.9]) },
        Keyframe { time: 0.1, position: SVector::from([0.9, -0.9]) },
        Keyframe { time: 0.3, position: SVector::from([-0.9, 0.95]) },
    ];
    let vel = [SVector::from([1.0f32, -3.0]), SVector::from([10.0, 0.0]), SVector::from([0.0, 1.0])];
    let r = time_scale::<f32, 2, 4>(&keys, &vel, &l).unwrap();
    assert!(r.slowed() && r.range_clamped());
    l.check(&r.curve().unwrap()).unwrap();
}
