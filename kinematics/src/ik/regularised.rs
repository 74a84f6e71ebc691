//! Regularised IK: the joint vector minimising `F(q) = alpha |e(q)|^2 + sum_i q_i^2`, where `e` is
//! the residual's weighted tool error.
//!
//! Not a root finder but a trade-off: the answer bends the chain as little as it can afford, and
//! `alpha` prices reach against bending (larger `alpha`, closer to the target; the course material's
//! value is 10). The minimum is defined by the objective and found from the seed, so random restarts
//! would change the question: [`IkMethod::restarts`] is false. The descent stops at the minimum and
//! says [`DescentEnd::Stalled`] there, unless the tool happens to be within tolerance.
//!
//! Each iteration is a Gauss-Newton step on `F`: linearising `e(q + dq) = e - J dq` gives the
//! always positive definite system `(alpha J^T J + I) dq = alpha J^T e - q`, solved by Cholesky; a
//! step that does not lower `F` is halved a bounded number of times. Rotary joints are measured as
//! the values the chain holds (continuous joints wrapped to (-pi, pi]), so "bending" is
//! `sum q_i^2` of exactly the joint vector returned.

use super::dls::done;
use super::{Descent, DescentEnd, IkMethod, Residual};
use crate::linalg::cholesky_solve;
use crate::{Chain, Real};
use nalgebra::SVector;

/// Minimises `alpha |e|^2 + |q|^2` by Gauss-Newton with step halving.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Regularised<T: Real> {
    /// Weight of the squared tool error against the squared joint values (1/m^2). A value that is
    /// not positive and finite makes the descent return its start, stalled.
    pub alpha: T,
}

impl<T: Real> Regularised<T> {
    /// The regularised objective with weight `alpha`.
    pub fn new(alpha: T) -> Self {
        Self { alpha }
    }
}

impl<T: Real> Default for Regularised<T> {
    /// `alpha = 10`, as in the course material.
    fn default() -> Self {
        Self { alpha: T::of(10.0) }
    }
}

/// Halvings tried before a step counts as failed: then `q` is at the minimum to working precision.
const HALVINGS: u32 = 30;

impl<T: Real, const N: usize> IkMethod<T, N> for Regularised<T> {
    fn descend(&self, chain: &Chain<T, N>, residual: &Residual<T>, start: SVector<T, N>, budget: u32) -> Descent<T, N> {
        if residual.rows() == 3 {
            self.descend_task::<N, 3>(chain, residual, start, budget)
        } else {
            self.descend_task::<N, 6>(chain, residual, start, budget)
        }
    }

    fn restarts(&self) -> bool {
        false
    }
}

impl<T: Real> Regularised<T> {
    /// The objective at `q` with tool error `cost` (which is half the squared error).
    fn objective<const N: usize>(&self, q: &SVector<T, N>, cost: T) -> T {
        self.alpha * cost * T::of(2.0) + q.norm_squared()
    }

    fn descend_task<const N: usize, const M: usize>(
        &self,
        chain: &Chain<T, N>,
        residual: &Residual<T>,
        start: SVector<T, N>,
        budget: u32,
    ) -> Descent<T, N> {
        let mut q = start;
        let mut frames = chain.forward(&q);
        let mut error = residual.error(&frames.tool);
        let end_here = |error, stalled| {
            if residual.converged(error) {
                DescentEnd::Converged
            } else {
                stalled
            }
        };
        if !(self.alpha.finite() && self.alpha > T::zero()) {
            return done(q, error, 0, end_here(&error, DescentEnd::Stalled));
        }
        let mut objective = self.objective(&q, error.cost);
        // A relative fall of F below this is rounding, not progress: the minimum is reached.
        let negligible = T::EPSILON * T::of(16.0);
        for iteration in 0..budget {
            let (j, e) = residual.task::<M, N>(chain, &frames, &error);
            let mut a = j.transpose() * j * self.alpha;
            for i in 0..N {
                a[(i, i)] += T::one();
            }
            let rhs = j.transpose() * e * self.alpha - q;
            let Some(mut dq) = cholesky_solve(&a, &rhs) else {
                return done(q, error, iteration, end_here(&error, DescentEnd::Stalled));
            };
            let mut accepted = None;
            for _ in 0..=HALVINGS {
                let q_new = chain.step(&q, &dq);
                let f = chain.forward(&q_new);
                let e_new = residual.error(&f.tool);
                let objective_new = self.objective(&q_new, e_new.cost);
                if objective_new < objective {
                    accepted = Some((q_new, f, e_new, objective_new));
                    break;
                }
                dq *= T::of(0.5);
            }
            let Some((q_new, f, e_new, objective_new)) = accepted else {
                return done(q, error, iteration + 1, end_here(&error, DescentEnd::Stalled));
            };
            let fall = objective - objective_new;
            (q, frames, error, objective) = (q_new, f, e_new, objective_new);
            if fall <= objective * negligible {
                return done(q, error, iteration + 1, end_here(&error, DescentEnd::Stalled));
            }
        }
        done(q, error, budget, end_here(&error, DescentEnd::OutOfBudget))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ik::{IkConfig, IkProblem, IkStatus, Target};
    use crate::presets;
    use nalgebra::Vector3;

    fn five_links(seed: [f64; 5], target: [f64; 2]) -> (Chain<f64, 5>, IkProblem<f64, 5>) {
        let chain = presets::planar::<f64, 5>().unwrap();
        let target = Target::Position(Vector3::new(target[0], target[1], 0.0));
        (chain, IkProblem { target, seed: seed.into(), config: IkConfig::default() })
    }

    fn bending(q: &SVector<f64, 5>) -> f64 {
        q.norm_squared()
    }

    #[test]
    fn five_links_trade_reach_against_bending() {
        // Both from the straight chain towards (1, 1), which needs the chain folded.
        let (chain, problem) = five_links([0.0; 5], [1.0, 1.0]);
        let dls = chain.solve(&problem);
        let reg = chain.solve_with(&Regularised::default(), &problem);
        assert_eq!(dls.status, IkStatus::Converged);
        assert_eq!(reg.status, IkStatus::BestEffort);
        assert_eq!(reg.restarts, 0);
        // Measured: DLS reaches to 2e-10 with sum q^2 = 5.09; the regularised answer stops 0.076 m
        // short with sum q^2 = 3.79.
        assert!(bending(&reg.q) < 0.8 * bending(&dls.q), "{} vs {}", bending(&reg.q), bending(&dls.q));
        assert!(reg.position_error > 0.05 && reg.position_error > 100.0 * dls.position_error, "{reg:?}");
        // And it is the better of the two on its own objective.
        let f = |s: &crate::ik::IkSolution<f64, 5>| 10.0 * s.position_error.powi(2) + bending(&s.q);
        assert!(f(&reg) < f(&dls));
    }

    #[test]
    fn straight_chain_aimed_at_the_target_is_a_stationary_point() {
        // Target on the axis of the straight chain: J^T e = 0 and q = 0, so the step is zero. The
        // method stays (a saddle of F, not a reach) and says so.
        let (chain, problem) = five_links([0.0; 5], [2.0, 0.0]);
        let s = chain.solve_with(&Regularised::default(), &problem);
        assert_eq!(s.status, IkStatus::BestEffort);
        assert!((s.position_error - 3.0).abs() <= 1e-12 && s.q == SVector::<f64, 5>::zeros());
    }

    #[test]
    fn stops_at_a_stationary_point_of_the_objective() {
        let (chain, problem) = five_links([0.1, 0.2, 0.3, 0.2, 0.1], [2.0, 2.5]);
        let residual = Residual::new(problem.target, &problem.config);
        let d = Regularised::default().descend(&chain, &residual, problem.seed, 1000);
        assert_eq!(d.end, DescentEnd::Stalled);
        assert!(d.iterations < 100, "{d:?}");
        // grad F / 2 = q - alpha J^T e.
        let (j, e) = residual.task::<3, 5>(&chain, &chain.forward(&d.q), &d.error);
        let gradient = d.q - j.transpose() * e * 10.0;
        assert!(gradient.norm() <= 1e-6, "{gradient:?}");
    }

    #[test]
    fn larger_alpha_reaches_closer_and_bends_more() {
        let (chain, problem) = five_links([0.1, 0.2, 0.3, 0.2, 0.1], [2.0, 2.5]);
        let mut previous: Option<crate::ik::IkSolution<f64, 5>> = None;
        for alpha in [1.0, 10.0, 100.0, 1e4] {
            let s = chain.solve_with(&Regularised::new(alpha), &problem);
            if let Some(p) = previous {
                assert!(s.position_error < p.position_error && bending(&s.q) > bending(&p.q), "{alpha}");
            }
            previous = Some(s);
        }
        // With a large enough alpha the reach wins: the tool is within a millimetre.
        assert!(previous.is_some_and(|s| s.position_error < 1e-3));
    }

    #[test]
    fn target_at_the_unbent_pose_converges() {
        // Straight chain, target at its tip: q = 0 minimises both terms.
        let (chain, problem) = five_links([0.3, -0.2, 0.1, 0.2, -0.1], [5.0, 0.0]);
        let s = chain.solve_with(&Regularised::default(), &problem);
        assert_eq!(s.status, IkStatus::Converged, "{s:?}");
        assert!(s.q.norm() <= 1e-5);
    }

    #[test]
    fn ur5e_pose_target_with_large_alpha_converges() {
        let chain = presets::ur5e::<f64>().unwrap();
        let goal = SVector::from([0.3, -1.2, 1.0, -0.5, 1.1, 0.2]);
        let problem = IkProblem {
            target: Target::Pose(chain.tool_pose(&goal)),
            seed: goal * 0.9,
            config: IkConfig { position_tolerance: 1e-4, orientation_tolerance: 1e-4, ..IkConfig::default() },
        };
        // The bias towards q = 0 moves the tool by about |q| / alpha.
        let s = chain.solve_with(&Regularised::new(1e6), &problem);
        assert_eq!(s.status, IkStatus::Converged, "{s:?}");
        assert!(chain.admits(&s.q));
    }

    #[test]
    fn bad_alpha_and_f32_do_not_panic() {
        let chain = presets::ur5e::<f32>().unwrap();
        let residual = Residual::new(Target::Position(Vector3::new(0.3f32, 0.2, 0.4)), &IkConfig::default());
        for alpha in [f32::NAN, -1.0, 0.0, f32::INFINITY] {
            let d = Regularised::new(alpha).descend(&chain, &residual, chain.middle(), 50);
            assert_eq!((d.q, d.end), (chain.middle(), DescentEnd::Stalled));
        }
        let d = Regularised::<f32>::default().descend(&chain, &residual, chain.middle(), 200);
        assert!(chain.admits(&d.q) && d.error.cost.is_finite());
        assert_ne!(d.end, DescentEnd::OutOfBudget);
    }
}
