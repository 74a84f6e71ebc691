//! The descent loop shared by the first-order and Newton-type methods: take the method's step
//! direction, halve it until the cost falls (backtracking), and give up after a run of iterations
//! that barely lower the cost. Only the direction differs between the methods that use it.

use super::dls::done;
use super::{Descent, DescentEnd, Residual};
use crate::{Chain, Real};
use nalgebra::{SMatrix, SVector};

/// A method's step for the task Jacobian `j` (3 or 6 rows) and error `e`; `None` where it has no
/// usable step (a stationary point, a non-finite solve): the descent then ends Stalled.
pub(super) trait StepDirection<T: Real, const N: usize> {
    fn direction<const M: usize>(&self, j: &SMatrix<T, M, N>, e: &SVector<T, M>) -> Option<SVector<T, N>>;
}

/// How patient the loop is.
#[derive(Clone, Copy, Debug)]
pub(super) struct Patience {
    /// Halvings of one step before it counts as failed (and the descent as stalled).
    pub halvings: u32,
    /// Consecutive slow iterations after which the descent counts as stalled.
    pub iterations: u32,
    /// An iteration is slow if it lowers the cost by less than this fraction.
    pub slow: f64,
}

/// One descent with backtracking along `method`'s directions.
pub(super) fn descend<T: Real, const N: usize, D: StepDirection<T, N>>(
    method: &D,
    patience: Patience,
    chain: &Chain<T, N>,
    residual: &Residual<T>,
    start: SVector<T, N>,
    budget: u32,
) -> Descent<T, N> {
    if residual.rows() == 3 {
        descend_task::<T, N, 3, D>(method, patience, chain, residual, start, budget)
    } else {
        descend_task::<T, N, 6, D>(method, patience, chain, residual, start, budget)
    }
}

fn descend_task<T: Real, const N: usize, const M: usize, D: StepDirection<T, N>>(
    method: &D,
    patience: Patience,
    chain: &Chain<T, N>,
    residual: &Residual<T>,
    start: SVector<T, N>,
    budget: u32,
) -> Descent<T, N> {
    let mut q = start;
    let mut frames = chain.forward(&q);
    let mut error = residual.error(&frames.tool);
    let mut unproductive = 0;
    for iteration in 0..budget {
        if residual.converged(&error) {
            return done(q, error, iteration, DescentEnd::Converged);
        }
        let (j, e) = residual.task::<M, N>(chain, &frames, &error);
        let Some(mut dq) = method.direction(&j, &e).filter(|d| d.iter().all(|v| v.finite())) else {
            return done(q, error, iteration, DescentEnd::Stalled);
        };
        let mut accepted = None;
        for _ in 0..=patience.halvings {
            let q_new = chain.step(&q, &dq);
            let f = chain.forward(&q_new);
            let e_new = residual.error(&f.tool);
            if e_new.cost < error.cost {
                accepted = Some((q_new, f, e_new));
                break;
            }
            dq *= T::of(0.5);
        }
        let Some((q_new, f, e_new)) = accepted else {
            return done(q, error, iteration + 1, DescentEnd::Stalled);
        };
        let slow = e_new.cost > error.cost * (T::one() - T::of(patience.slow));
        unproductive = if slow { unproductive + 1 } else { 0 };
        (q, frames, error) = (q_new, f, e_new);
        if unproductive >= patience.iterations {
            let end = if residual.converged(&error) { DescentEnd::Converged } else { DescentEnd::Stalled };
            return done(q, error, iteration + 1, end);
        }
    }
    let end = if residual.converged(&error) { DescentEnd::Converged } else { DescentEnd::OutOfBudget };
    done(q, error, budget, end)
}
