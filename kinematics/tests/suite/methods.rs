//! All six IK methods on the same targets, through the shared driver (`Chain::solve_with`).

use kinematics::ik::{
    CyclicCoordinateDescent, DampedLeastSquares, GradientDescent, IkConfig, IkMethod, IkProblem, IkStatus,
    JacobianTranspose, PseudoinverseNewton, Regularised, Target,
};
use kinematics::{presets, Chain, SplitMix64};
use proptest::prelude::*;

const TARGETS: usize = 50;

/// How one method did on all the problems.
struct Tally {
    converged: usize,
    iterations: u32,
}

fn run<M: IkMethod<f64, 6>>(name: &str, method: &M, chain: &Chain<f64, 6>, problems: &[IkProblem<f64, 6>]) -> Tally {
    let mut tally = Tally { converged: 0, iterations: 0 };
    for (i, problem) in problems.iter().enumerate() {
        let s = chain.solve_with(method, problem);
        assert!(chain.admits(&s.q), "{name}, target {i}: {:?} outside the limits", s.q);
        assert!(!matches!(s.status, IkStatus::InvalidInput(_)), "{name}, target {i}: {s:?}");
        // The reported error is the FK distance of exactly the values returned.
        let reached = (chain.tool_pose(&s.q).translation - problem.target.position()).norm();
        assert!((reached - s.position_error).abs() <= 1e-12, "{name}, target {i}: {s:?}");
        if s.status == IkStatus::Converged {
            assert!(reached <= problem.config.position_tolerance, "{name}, target {i}: {s:?}");
            tally.converged += 1;
        }
        tally.iterations += s.iterations;
    }
    eprintln!(
        "{name:>28}: {:2}/{} converged, {:6.1} iterations per target",
        tally.converged,
        problems.len(),
        f64::from(tally.iterations) / problems.len() as f64
    );
    tally
}

#[test]
fn six_methods_on_fifty_reachable_ur5e_position_targets() {
    let chain = presets::ur5e::<f64>().unwrap();
    let mut rng = SplitMix64::new(2024);
    let problems: [IkProblem<f64, 6>; TARGETS] = core::array::from_fn(|_| {
        let goal = chain.random_configuration(&mut rng);
        IkProblem {
            target: Target::Position(chain.tool_pose(&goal).translation),
            seed: chain.middle(),
            config: IkConfig::default(),
        }
    });

    let dls = run("DampedLeastSquares", &DampedLeastSquares, &chain, &problems);
    assert_eq!(dls.converged, TARGETS);
    run("PseudoinverseNewton", &PseudoinverseNewton, &chain, &problems);
    run("JacobianTranspose", &JacobianTranspose, &chain, &problems);
    run("CyclicCoordinateDescent", &CyclicCoordinateDescent, &chain, &problems);
    run("GradientDescent", &GradientDescent::default(), &chain, &problems);
    run("Regularised (alpha 10)", &Regularised::default(), &chain, &problems);
}

/// Every method through the driver on one problem: no panic, values within limits, and the status
/// agrees with forward kinematics on the returned values.
fn check_all<const N: usize, T: kinematics::Real>(chain: &Chain<T, N>, problem: &IkProblem<T, N>) {
    fn one<T: kinematics::Real, const N: usize, M: IkMethod<T, N>>(
        method: &M,
        chain: &Chain<T, N>,
        problem: &IkProblem<T, N>,
    ) -> Result<(), TestCaseError> {
        let s = chain.solve_with(method, problem);
        prop_assert!(chain.admits(&s.q), "{:?} outside the limits", s.q);
        prop_assert!(s.iterations <= problem.config.max_iterations);
        if s.status == IkStatus::Converged {
            let reached = (chain.tool_pose(&s.q).translation - problem.target.position()).norm();
            prop_assert!(reached <= problem.config.position_tolerance, "{s:?}");
        }
        Ok(())
    }
    let results = [
        one(&DampedLeastSquares, chain, problem),
        one(&PseudoinverseNewton, chain, problem),
        one(&JacobianTranspose, chain, problem),
        one(&CyclicCoordinateDescent, chain, problem),
        one(&GradientDescent::default(), chain, problem),
        one(&Regularised::default(), chain, problem),
    ];
    for (name, result) in ["dls", "newton", "transpose", "ccd", "gradient", "regularised"].iter().zip(results) {
        if let Err(e) = result {
            panic!("{name}: {e}");
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// Any finite target, reachable or not, and any seed, in f64 on the UR5e (limited joints).
    #[test]
    fn any_target_and_seed_ur5e_f64(
        target in proptest::array::uniform3(prop_oneof![-2.0..2.0f64, -1e6..1e6f64]),
        seed in proptest::array::uniform6(-20.0..20.0f64),
        pose in proptest::bool::ANY,
        wxyz in proptest::array::uniform4(-1.0..1.0f64),
    ) {
        let chain = presets::ur5e::<f64>().unwrap();
        let target = match Target::pose_wxyz(target, wxyz) {
            Some(t) if pose => t,
            _ => Target::Position(target.into()),
        };
        let config = IkConfig { max_iterations: 300, ..IkConfig::default() };
        check_all(&chain, &IkProblem { target, seed: seed.into(), config });
    }

    /// The same in f32 on a planar chain (continuous joints, wrapping).
    #[test]
    fn any_target_and_seed_planar_f32(
        target in proptest::array::uniform3(prop_oneof![-5.0..5.0f32, -1e30..1e30f32]),
        seed in proptest::array::uniform4(-100.0..100.0f32),
    ) {
        let chain = presets::planar::<f32, 4>().unwrap();
        let config = IkConfig { max_iterations: 300, ..IkConfig::default() };
        check_all(&chain, &IkProblem { target: Target::Position(target.into()), seed: seed.into(), config });
    }
}
