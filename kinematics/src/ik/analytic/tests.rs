//! The closed forms against forward kinematics and the numerical solver, on random targets of each
//! shape, with every solution checked; and the singular targets, reported rather than mishandled.

use super::*;
use crate::ik::IkConfig;
use crate::{presets, rotation_error, SplitMix64};
use nalgebra::Vector3;

fn problem<const N: usize>(target: Target<f64>, seed: SVector<f64, N>) -> IkProblem<f64, N> {
    IkProblem { target, seed, config: IkConfig::default() }
}

/// The largest joint difference, whole turns apart counting as the same angle.
fn angle_gap<const N: usize>(a: &SVector<f64, N>, b: &SVector<f64, N>) -> f64 {
    a.iter().zip(b.iter()).map(|(x, y)| wrap_angle(x - y).abs()).fold(0.0, f64::max)
}

#[test]
fn the_shape_is_read_from_the_geometry() {
    let shape = |s: Option<Shape>| s.map(|s| s.as_str());
    assert_eq!(shape(ClosedForm::of(&presets::ur5e::<f64>().unwrap()).map(|c| c.shape())), Some("three_parallel"));
    assert_eq!(shape(ClosedForm::of(&presets::puma560::<f64>().unwrap()).map(|c| c.shape())), Some("spherical_wrist"));
    assert_eq!(shape(ClosedForm::of(&presets::so101::<f64>().unwrap()).map(|c| c.shape())), Some("yaw_pitch"));
    assert_eq!(
        shape(ClosedForm::of(&presets::open_manipulator_x::<f64>().unwrap()).map(|c| c.shape())),
        Some("yaw_pitch")
    );
    assert!(ClosedForm::of(&presets::iiwa14::<f64>().unwrap()).is_none());
    assert!(ClosedForm::of(&presets::planar::<f64, 3>().unwrap()).is_none());
    assert!(ClosedForm::of(&presets::planar::<f64, 6>().unwrap()).is_none());
}

/// For a six-joint arm: random joint vectors within the limits, their pose by FK; every solution
/// must reach the pose to 1e-9 by FK, the vector posed from must be among them, and the answer
/// nearest a seed at that vector must be the vector itself.
fn six_joint_arm_solves_every_pose(chain: Chain<f64, 6>) {
    let closed = ClosedForm::of(&chain).unwrap();
    let mut rng = SplitMix64::new(42);
    let mut counts = [0usize; MAX_SOLUTIONS + 1];
    for _ in 0..2000 {
        let q = chain.random_configuration(&mut rng);
        let pose = chain.tool_pose(&q);
        let all = closed.solutions(&chain, &problem(Target::Pose(pose), chain.middle()));
        counts[all.len()] += 1;
        let mut found = false;
        for s in &all {
            let at = chain.tool_pose(&s.q);
            let (dp, dr) =
                ((at.translation - pose.translation).norm(), rotation_error(&pose.rotation, &at.rotation).norm());
            // Every exact solution reaches; a least-squares one (a branch that cannot reach this
            // pose) is marked so and never claims to.
            if s.exact {
                assert!(dp < 1e-9 && dr < 1e-9, "{:?}: {dp} {dr}", s.q);
                assert!(s.reaches || !s.within_limits);
                assert_eq!(s.polish_iterations, 0);
            } else {
                assert!(!s.reaches);
            }
            found |= angle_gap(&s.q, &q) < 1e-7;
        }
        assert!(found, "{q:?} not among {all:?}");
        let own = chain.solve_closed_form(&closed, &problem(Target::Pose(pose), q));
        assert_eq!(own.status, IkStatus::Converged);
        assert!((own.q - q).amax() < 1e-7, "{:?} {q:?}", own.q);
    }
    // A generic pose of these arms has 8 solutions (some outside the limits).
    assert!(counts[8] > 1500, "{counts:?}");
}

#[test]
fn ur5e_every_solution_reaches_by_fk() {
    six_joint_arm_solves_every_pose(presets::ur5e().unwrap());
}

#[test]
fn puma560_every_solution_reaches_by_fk() {
    six_joint_arm_solves_every_pose(presets::puma560().unwrap());
}

/// Where the numerical solver converges from the middle of the ranges, its answer is one of the
/// closed form's solutions (it cannot find one the closed form misses).
#[test]
fn the_numerical_answer_is_among_the_closed_form_solutions() {
    for chain in [presets::ur5e::<f64>().unwrap(), presets::puma560().unwrap()] {
        let closed = ClosedForm::of(&chain).unwrap();
        let mut rng = SplitMix64::new(5);
        for _ in 0..300 {
            let pose = chain.tool_pose(&chain.random_configuration(&mut rng));
            // Tight tolerances: near a singularity (the two base angles close together) an answer
            // within 1e-5 of the pose can lie 1e-2 from the exact joint values.
            let mut p = problem(Target::Pose(pose), chain.middle());
            p.config.position_tolerance = 1e-12;
            p.config.orientation_tolerance = 1e-12;
            let numeric = chain.solve(&p);
            assert_eq!(numeric.status, IkStatus::Converged);
            let all = closed.solutions(&chain, &p);
            assert!(all.iter().any(|s| angle_gap(&s.q, &numeric.q) < 1e-5), "{:?} not among {all:?}", numeric.q);
        }
    }
}

/// The hobby arms: a pose posed from a joint vector is solved exactly, and a position target with
/// that vector as seed is solved at the seed's pitch, by the vector itself.
fn yaw_pitch_arm<const N: usize>(chain: Chain<f64, N>) {
    let closed = ClosedForm::of(&chain).unwrap();
    let mut rng = SplitMix64::new(9);
    for _ in 0..2000 {
        let q = chain.random_configuration(&mut rng);
        let pose = chain.tool_pose(&q);
        let all = closed.solutions(&chain, &problem(Target::Pose(pose), chain.middle()));
        assert!(all.iter().any(|s| angle_gap(&s.q, &q) < 1e-6 && s.reaches), "{q:?}: {all:?}");
        for s in all.iter().filter(|s| s.reaches) {
            assert!(s.position_error < 1e-5 && s.orientation_error < 1e-5);
        }
        let by_position = chain.solve_closed_form(&closed, &problem(Target::Position(pose.translation), q));
        assert_eq!(by_position.status, IkStatus::Converged);
        assert!(angle_gap(&by_position.q, &q) < 1e-6, "{:?} {q:?}", by_position.q);
    }
}

#[test]
fn so101_by_pose_and_by_position() {
    yaw_pitch_arm(presets::so101().unwrap());
}

#[test]
fn open_manipulator_x_by_pose_and_by_position() {
    yaw_pitch_arm(presets::open_manipulator_x().unwrap());
}

/// A position target seeded at the middle: the pitch widens from the seed's until the position is
/// reachable within the limits, so wherever the numerical solver converges, so does the closed
/// form (and its answer reaches by FK).
#[test]
fn a_position_target_finds_a_pitch_wherever_the_numerical_solver_converges() {
    let chain = presets::so101::<f64>().unwrap();
    let closed = ClosedForm::of(&chain).unwrap();
    let mut rng = SplitMix64::new(13);
    let (mut numeric_only, mut both) = (0, 0);
    for _ in 0..1000 {
        let target = Target::Position(chain.tool_pose(&chain.random_configuration(&mut rng)).translation);
        let p = problem(target, chain.middle());
        let closed_form = chain.solve_closed_form(&closed, &p);
        let reached = closed_form.status == IkStatus::Converged;
        if reached {
            assert!(closed_form.position_error <= 1e-5 && chain.admits(&closed_form.q));
        }
        match (chain.solve(&p).status == IkStatus::Converged, reached) {
            (true, false) => numeric_only += 1,
            (true, true) => both += 1,
            _ => {}
        }
    }
    assert!(both > 900, "{both}");
    assert!(numeric_only <= 5, "the closed form missed {numeric_only} targets the numerical solver reached");
}

#[test]
fn singular_targets_are_reported() {
    // UR5e stretched (q3 = 0) and with its wrist lined up (q5 = 0).
    let ur = presets::ur5e::<f64>().unwrap();
    let closed = ClosedForm::of(&ur).unwrap();
    let stretched = SVector::from([0.3, -1.0, 0.0, 0.4, 1.0, 0.2]);
    let all = closed.solutions(&ur, &problem(Target::Pose(ur.tool_pose(&stretched)), stretched));
    assert!(
        all.iter().any(|s| s.singular == Some(Singularity::Elbow) && s.reaches && angle_gap(&s.q, &stretched) < 1e-6),
        "{all:?}"
    );
    let lined_up = SVector::from([0.3, -1.0, 1.2, 0.4, 0.0, 0.2]);
    let all = closed.solutions(&ur, &problem(Target::Pose(ur.tool_pose(&lined_up)), lined_up));
    let wrist: Vec<_> = all.iter().filter(|s| s.singular == Some(Singularity::Wrist)).collect();
    assert!(!wrist.is_empty() && wrist.iter().all(|s| s.reaches && s.q.iter().all(|v| v.is_finite())), "{all:?}");

    // PUMA 560 with axes 4 and 6 lined up: q4 keeps the seed's value, and the pose is reached.
    let puma = presets::puma560::<f64>().unwrap();
    let closed = ClosedForm::of(&puma).unwrap();
    let q = SVector::from([0.3, -0.5, 0.4, 0.7, 0.0, -0.2]);
    let all = closed.solutions(&puma, &problem(Target::Pose(puma.tool_pose(&q)), q));
    assert!(
        all.iter().any(|s| s.singular == Some(Singularity::Wrist) && s.reaches && (s.q[3] - 0.7).abs() < 1e-12),
        "{all:?}"
    );

    // The PUMA's wrist centre can never be on the first axis (the shoulder's 0.15 m offset): such
    // a target is reported as a shoulder singularity that reaches nothing, and nothing is NaN.
    let mut pose = puma.tool_pose(&q);
    pose.translation = Vector3::new(0.0, 0.0, 1.2) + pose.rotation * Vector3::zeros();
    let all = closed.solutions(&puma, &problem(Target::Pose(pose), q));
    assert!(!all.is_empty() && all.iter().all(|s| !s.reaches && s.q.iter().all(|v| v.is_finite())), "{all:?}");
    assert!(all.iter().all(|s| s.singular == Some(Singularity::Shoulder)));
    let miss = puma.solve_closed_form(&closed, &problem(Target::Pose(pose), q));
    assert_eq!(miss.status, IkStatus::BestEffort);
    assert!(miss.position_error > 0.1, "{miss:?}");

    // Out of reach entirely: no solution reaches; solve_auto falls back to the numerical solver.
    let far = Target::Position(Vector3::new(3.0, 0.0, 0.0));
    let so101 = presets::so101::<f64>().unwrap();
    let closed = ClosedForm::of(&so101).unwrap();
    let miss = so101.solve_closed_form(&closed, &problem(far, so101.middle()));
    assert!(miss.status == IkStatus::BestEffort && miss.position_error > 2.0, "{miss:?}");
    let (fallback, closed_form) = so101.solve_auto(Some(&closed), &problem(far, so101.middle()));
    assert!(!closed_form && fallback.status != IkStatus::Converged);
}

#[test]
fn bad_input_gives_no_solutions() {
    let chain = presets::ur5e::<f64>().unwrap();
    let closed = ClosedForm::of(&chain).unwrap();
    let mut pose = chain.tool_pose(&chain.middle());
    pose.translation.x = f64::NAN;
    assert!(closed.solutions(&chain, &problem(Target::Pose(pose), chain.middle())).is_empty());
    // A six-joint shape needs the full pose: a position target goes to the numerical solver.
    assert!(closed
        .solutions(&chain, &problem(Target::Position(Vector3::new(0.3, 0.2, 0.4)), chain.middle()))
        .is_empty());
}
