//! The Jacobian transpose method: `dq = alpha J^T e`, a steepest-descent step on the cost.
//!
//! Kept for comparison: it needs no linear solve at all (one matrix-vector product each way), so it
//! is the cheapest iteration there is, and it is well defined at singularities, but it converges
//! only linearly, slowly on ill-conditioned arms. The step length is Buss's choice
//! `alpha = <e, J J^T e> / |J J^T e|^2`, the step along `J^T e` that best reduces the error of the
//! linearised model; because the model is only linear, a step that does not lower the true cost is
//! halved a bounded number of times, so every accepted iterate is better than the last.

use super::line_search::{self, Patience, StepDirection};
use super::{Descent, IkMethod, Residual};
use crate::{Chain, Real};
use nalgebra::{SMatrix, SVector};

/// The Jacobian transpose method with Buss's step length. Stateless.
#[derive(Clone, Copy, Debug, Default)]
pub struct JacobianTranspose;

impl<T: Real, const N: usize> IkMethod<T, N> for JacobianTranspose {
    fn descend(&self, chain: &Chain<T, N>, residual: &Residual<T>, start: SVector<T, N>, budget: u32) -> Descent<T, N> {
        // Linear convergence is expected, so the bar for "slow" is far lower than the 1% of the
        // second-order methods: only a descent that has practically stopped gives up.
        let patience = Patience { halvings: 20, iterations: 8, slow: 1e-4 };
        line_search::descend(self, patience, chain, residual, start, budget)
    }
}

impl<T: Real, const N: usize> StepDirection<T, N> for JacobianTranspose {
    fn direction<const M: usize>(&self, j: &SMatrix<T, M, N>, e: &SVector<T, M>) -> Option<SVector<T, N>> {
        let g = j.transpose() * e;
        let jg = j * g;
        let alpha = e.dot(&jg) / jg.norm_squared();
        // alpha is NaN or infinite exactly when J J^T e vanishes: e is in the null space of J^T,
        // a stationary point (a local minimum or a singular pose) that this method cannot leave.
        (alpha.finite() && alpha > T::zero()).then(|| g * alpha)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ik::{DescentEnd, IkConfig, IkProblem, IkStatus, Target};
    use crate::{presets, SplitMix64};
    use nalgebra::Vector3;

    #[test]
    fn buss_step_is_exact_for_a_one_link_arm_near_the_target() {
        // One link, target a small rotation away: J J^T e is parallel to e, so Buss's alpha makes the
        // step the Newton step and the error falls quadratically.
        let chain = presets::planar::<f64, 1>().unwrap();
        let residual =
            Residual::new(Target::Position(Vector3::new(0.6f64.cos(), 0.6f64.sin(), 0.0)), &IkConfig::default());
        let d = JacobianTranspose.descend(&chain, &residual, SVector::from([0.5]), 10);
        assert_eq!(d.end, DescentEnd::Converged);
        assert!(d.iterations <= 4, "{d:?}");
        assert!((d.q[0] - 0.6).abs() <= 1e-5);
    }

    #[test]
    fn planar_targets_converge() {
        let chain = presets::planar::<f64, 3>().unwrap();
        let config = IkConfig { attempt_iterations: 2000, max_iterations: 20_000, ..IkConfig::default() };
        let mut rng = SplitMix64::new(3);
        for _ in 0..20 {
            let goal = chain.random_configuration(&mut rng);
            let target = Target::Position(chain.tool_pose(&goal).translation);
            let s = chain.solve_with(&JacobianTranspose, &IkProblem { target, seed: chain.middle(), config });
            assert_eq!(s.status, IkStatus::Converged, "{s:?}");
        }
    }

    #[test]
    fn ur5e_position_targets_converge_within_limits() {
        let chain = presets::ur5e::<f64>().unwrap();
        let config = IkConfig { attempt_iterations: 2000, max_iterations: 20_000, ..IkConfig::default() };
        let mut rng = SplitMix64::new(5);
        let mut converged = 0;
        for _ in 0..20 {
            let goal = chain.random_configuration(&mut rng);
            let target = Target::Position(chain.tool_pose(&goal).translation);
            let s = chain.solve_with(&JacobianTranspose, &IkProblem { target, seed: chain.middle(), config });
            assert!(chain.admits(&s.q));
            converged += usize::from(s.status == IkStatus::Converged);
        }
        assert!(converged >= 19, "{converged}/20");
    }

    #[test]
    fn every_accepted_step_lowers_the_cost() {
        let chain = presets::ur5e::<f64>().unwrap();
        let goal = SVector::from([0.3, -1.2, 1.0, -0.5, 1.1, 0.2]);
        let residual = Residual::new(Target::Pose(chain.tool_pose(&goal)), &IkConfig::default());
        let mut q = chain.middle();
        let mut cost = residual.error(&chain.tool_pose(&q)).cost;
        for _ in 0..50 {
            let d = JacobianTranspose.descend(&chain, &residual, q, 1);
            assert!(d.error.cost <= cost && chain.admits(&d.q));
            (q, cost) = (d.q, d.error.cost);
        }
        assert!(cost < 0.5 * residual.error(&chain.tool_pose(&chain.middle())).cost);
    }

    #[test]
    fn stationary_point_stalls_instead_of_dividing_by_zero() {
        // Straight arm, target straight behind the base: J^T e = 0 exactly.
        let chain = presets::planar::<f64, 2>().unwrap();
        let residual = Residual::new(Target::Position(Vector3::new(-1.0, 0.0, 0.0)), &IkConfig::default());
        let d = JacobianTranspose.descend(&chain, &residual, SVector::zeros(), 10);
        assert_eq!((d.end, d.iterations), (DescentEnd::Stalled, 0));
        assert_eq!(d.q, SVector::<f64, 2>::zeros());
    }

    #[test]
    fn f32_does_not_panic() {
        let chain = presets::ur5e::<f32>().unwrap();
        let residual = Residual::new(Target::Position(Vector3::new(0.3f32, 0.2, 0.4)), &IkConfig::default());
        let d = JacobianTranspose.descend(&chain, &residual, chain.middle(), 200);
        assert!(chain.admits(&d.q) && d.error.cost.is_finite());
    }
}
