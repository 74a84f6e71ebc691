//! Newton's method with the true pseudoinverse: `dq = J^+ e`, the minimum-norm least-squares step.
//!
//! The textbook solver, kept for comparison with damped least squares. Near the solution it
//! converges quadratically; near a singularity the pseudoinverse has huge gains in the directions
//! that are barely controllable, so singular values below `sqrt(eps)` times the largest are treated
//! as zero, and a step that does not lower the cost is halved (backtracking) a bounded number of
//! times. The halving is what keeps the method stable when the target jumps far from the current
//! pose: the full Newton step is only a linear prediction and can overshoot by whole turns. What
//! it cannot fix is the stretched arm reaching for an unreachable target: there the gain along the
//! nearly singular direction swamps the useful part of the step and the descent stalls short of the
//! closest pose, which is the case damped least squares exists for.

use super::line_search::{self, Patience, StepDirection};
use super::{Descent, IkMethod, Residual};
use crate::linalg::pseudoinverse_solve;
use crate::{Chain, Real};
use nalgebra::{SMatrix, SVector};

/// Newton's method with the pseudoinverse and backtracking. Stateless.
#[derive(Clone, Copy, Debug, Default)]
pub struct PseudoinverseNewton;

impl<T: Real, const N: usize> IkMethod<T, N> for PseudoinverseNewton {
    fn descend(&self, chain: &Chain<T, N>, residual: &Residual<T>, start: SVector<T, N>, budget: u32) -> Descent<T, N> {
        // 30 halvings: near a singularity the full step can be thousands of radians, and only a
        // tiny fraction of it is still inside the region where the linear model holds. Stalled
        // after 8 iterations each removing less than 1% of the cost.
        let patience = Patience { halvings: 30, iterations: 8, slow: 0.01 };
        line_search::descend(self, patience, chain, residual, start, budget)
    }
}

impl<T: Real, const N: usize> StepDirection<T, N> for PseudoinverseNewton {
    fn direction<const M: usize>(&self, j: &SMatrix<T, M, N>, e: &SVector<T, M>) -> Option<SVector<T, N>> {
        Some(pseudoinverse_solve(j, e, T::EPSILON.sqrt()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ik::{DescentEnd, IkConfig, IkProblem, IkStatus, Target};
    use crate::{presets, SplitMix64};
    use nalgebra::Vector3;

    fn seed_check<const N: usize>(seed: [f64; N], target: [f64; 2]) -> crate::ik::IkSolution<f64, N> {
        let chain = presets::planar::<f64, N>().unwrap();
        // The seed checks' values hold to about 1e-8, so that is the tolerance, not the default 1e-5.
        let config = IkConfig { max_iterations: 8, max_restarts: 0, position_tolerance: 1e-8, ..IkConfig::default() };
        let target = Target::Position(Vector3::new(target[0], target[1], 0.0));
        let solution = chain.solve_with(&PseudoinverseNewton, &IkProblem { target, seed: seed.into(), config });
        let reached = chain.tool_pose(&solution.q).translation;
        assert!((reached - target.position()).norm() <= 1e-8, "reached {reached:?}, {solution:?}");
        assert_eq!(solution.status, IkStatus::Converged);
        assert!(solution.iterations <= 8);
        solution
    }

    #[test]
    fn seed_check_one_link_reaches_straight_up_in_eight() {
        let s = seed_check([0.0], [0.0, 1.0]);
        assert!((s.q[0] - core::f64::consts::FRAC_PI_2).abs() <= 1e-8);
    }

    #[test]
    fn seed_check_two_links_leave_the_straight_singularity_in_eight() {
        // [0, 0] is singular (the x row of J is zero): only the pseudoinverse's cut-off makes the
        // first step finite.
        seed_check([0.0, 0.0], [0.5, 0.5]);
    }

    #[test]
    fn converges_quadratically_near_the_solution() {
        let chain = presets::ur5e::<f64>().unwrap();
        let goal = SVector::from([0.3, -1.2, 1.0, -0.5, 1.1, 0.2]);
        let residual = Residual::new(Target::Pose(chain.tool_pose(&goal)), &IkConfig::default());
        let start = goal + SVector::from([0.05, -0.04, 0.03, 0.05, -0.05, 0.04]);
        let d = PseudoinverseNewton.descend(&chain, &residual, start, 10);
        assert_eq!(d.end, DescentEnd::Converged);
        // From 0.05 rad away: ~1e-3, ~1e-6, below 1e-10; linear convergence would need many more.
        assert!(d.iterations <= 4, "{d:?}");
    }

    #[test]
    fn ur5e_pose_targets_converge_within_limits() {
        let chain = presets::ur5e::<f64>().unwrap();
        let mut rng = SplitMix64::new(7);
        let mut converged = 0;
        for _ in 0..20 {
            let goal = chain.random_configuration(&mut rng);
            let problem = IkProblem {
                target: Target::Pose(chain.tool_pose(&goal)),
                seed: chain.middle(),
                config: IkConfig::default(),
            };
            let s = chain.solve_with(&PseudoinverseNewton, &problem);
            assert!(chain.admits(&s.q));
            converged += usize::from(s.status == IkStatus::Converged);
        }
        assert!(converged >= 19, "{converged}/20");
    }

    #[test]
    fn thirty_links_stay_stable_when_the_target_jumps_far() {
        let chain = presets::planar::<f64, 30>().unwrap();
        let config = IkConfig { max_restarts: 0, attempt_iterations: 1000, ..IkConfig::default() };
        let mut q = chain.middle();
        for target in [[25.0, 10.0], [-20.0, -15.0], [0.5, 0.5], [3.0, -28.0], [-29.0, 1.0], [10.0, 10.0]] {
            let target = Target::Position(Vector3::new(target[0], target[1], 0.0));
            let s = chain.solve_with(&PseudoinverseNewton, &IkProblem { target, seed: q, config });
            assert_eq!(s.status, IkStatus::Converged, "{target:?}: {s:?}");
            assert_eq!(s.restarts, 0);
            assert!(chain.admits(&s.q));
            // Measured: 5 to 105 iterations per jump.
            assert!(s.iterations <= 200, "{target:?}: {s:?}");
            q = s.q;
        }
    }

    #[test]
    fn unreachable_target_stalls_honestly_within_limits() {
        // Stretched towards an unreachable target the arm nears the singularity where the
        // pseudoinverse's gain along the folding direction explodes: Newton stalls short of the
        // closest pose (damped least squares gets there), but it must say so and stay finite.
        let chain = presets::planar::<f64, 2>().unwrap();
        let residual = Residual::new(Target::Position(Vector3::new(5.0, 0.0, 0.0)), &IkConfig::default());
        let start = SVector::from([0.3, -0.2]);
        let before = residual.error(&chain.tool_pose(&start)).position;
        let d = PseudoinverseNewton.descend(&chain, &residual, start, 100);
        assert_eq!(d.end, DescentEnd::Stalled);
        assert!(chain.admits(&d.q) && d.q.iter().all(|v| v.is_finite()));
        assert!(d.error.position >= 3.0 && d.error.position < before, "{d:?}");
    }

    #[test]
    fn f32_and_no_budget_do_not_panic() {
        let chain = presets::ur5e::<f32>().unwrap();
        let residual = Residual::new(Target::Position(Vector3::new(0.3f32, 0.2, 0.4)), &IkConfig::default());
        let d = PseudoinverseNewton.descend(&chain, &residual, chain.middle(), 0);
        assert_eq!((d.iterations, d.end), (0, DescentEnd::OutOfBudget));
        let d = PseudoinverseNewton.descend(&chain, &residual, chain.middle(), 50);
        assert_eq!(d.end, DescentEnd::Converged);
        assert!(chain.admits(&d.q));
    }
}
