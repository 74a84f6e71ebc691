//! Damped least squares with adaptive damping (Levenberg-Marquardt), the default solver.
//!
//! Step: `dq = J^T (J J^T + lambda I)^-1 e` when the task has no more rows than joints, otherwise the
//! equivalent `(J^T J + lambda I)^-1 J^T e`, so the system solved by Cholesky is always the smaller
//! one (3x3 or 6x6 for a 6-joint arm, NxN for a short chain). `lambda = mu * cost + floor`: damping
//! proportional to the remaining error (Sugihara 2011) gives quadratic convergence near the
//! solution and short, safe steps far from it or near singularities; `mu` adapts: a step is kept
//! only if the error falls, otherwise it is retried with ten times the damping.

use super::{Descent, DescentEnd, ErrorTerms, IkMethod, Residual};
use crate::linalg::{cholesky_solve, cholesky_solve_leading};
use crate::{Chain, Frames, Real};
use nalgebra::{SMatrix, SVector};

/// The default solver. Stateless: all tuning lives in [`super::IkConfig`].
#[derive(Clone, Copy, Debug, Default)]
pub struct DampedLeastSquares;

impl<T: Real, const N: usize> IkMethod<T, N> for DampedLeastSquares {
    fn descend(&self, chain: &Chain<T, N>, residual: &Residual<T>, start: SVector<T, N>, budget: u32) -> Descent<T, N> {
        descend_with(chain, residual, start, budget, T::of(ATTEMPT_PROGRESS), ATTEMPT_PATIENCE)
    }

    fn polish(&self, chain: &Chain<T, N>, residual: &Residual<T>, start: SVector<T, N>, budget: u32) -> Descent<T, N> {
        descend_with(chain, residual, start, budget, T::EPSILON.sqrt(), POLISH_PATIENCE)
    }
}

/// An attempt counts as stalled after this many consecutive iterations that each lower the cost
/// by less than the required fraction (a rejected step lowers it by nothing), plus one per four
/// joints: a long chain's error falls more slowly through its many coupled joints. Attempts are
/// cheap to abandon because a restart follows; the final polish, with nothing after it, is given
/// one iteration more.
const ATTEMPT_PATIENCE: u32 = 4;
const POLISH_PATIENCE: u32 = 5;

/// The fraction of the cost an iteration must remove to count as progress during an attempt.
/// Near a solution damped least squares converges quadratically (the cost falls by orders of
/// magnitude per iteration), so an attempt removing less than a tenth per iteration is creeping
/// towards a local minimum or along a limit, and a restart is cheaper. Measured on ur5e, puma560
/// and iiwa14 (the `bench ik` protocol), 10% with patience 4 instead of 1% with patience 5 cut
/// the p99 iterations per solve by about a seventh on ur5e and puma560 at the same solve rate;
/// an early cut on the cost after a few iterations does not work, because attempts that go on to
/// converge fall no faster at first than the ones that stall. Polishing the final best-effort
/// answer only asks for a numerically visible fall.
const ATTEMPT_PROGRESS: f64 = 0.10;

/// One code path for both kinds of target: the task is held in 6 rows, a position target's last
/// three being zero (see [`Residual::task`]), and the damped system is solved at the task's own
/// size. Zero rows and padded unknowns add exact zeros, so this gives the bits a 3-row solver
/// would, while the firmware carries one copy of the loop instead of two (about 2 KB of flash).
fn descend_with<T: Real, const N: usize>(
    chain: &Chain<T, N>,
    residual: &Residual<T>,
    start: SVector<T, N>,
    budget: u32,
    progress: T,
    patience: u32,
) -> Descent<T, N> {
    descend_task::<T, N, 6>(chain, residual, start, budget, progress, patience)
}

fn descend_task<T: Real, const N: usize, const M: usize>(
    chain: &Chain<T, N>,
    residual: &Residual<T>,
    start: SVector<T, N>,
    budget: u32,
    progress: T,
    patience: u32,
) -> Descent<T, N> {
    let mut q = start;
    let mut frames = chain.forward(&q);
    let mut error = residual.error(&frames.tool);
    // Below sqrt(eps) relative to unit-scale J J^T the damping no longer matters for accuracy but
    // still keeps the system positive definite at exact singularities.
    let floor = T::EPSILON.sqrt() * T::of(1e-3);
    let (mu_min, mu_max) = (T::of(1e-5), T::of(1e8));
    let mut mu = T::of(1.0);
    let mut unproductive = 0;
    for iteration in 0..budget {
        if residual.converged(&error) {
            return done(q, error, iteration, DescentEnd::Converged);
        }
        let lambda = mu * error.cost + floor;
        let trial = damped_step::<T, N, M>(chain, residual, &frames, &error, &q, lambda)
            .map(|dq| chain.step(&q, &dq))
            .map(|q_new| {
                let f = chain.forward(&q_new);
                (q_new, f, residual.error(&f.tool))
            });
        match trial {
            Some((q_new, f, e)) if e.cost < error.cost => {
                unproductive = if e.cost > error.cost * (T::one() - progress) { unproductive + 1 } else { 0 };
                (q, frames, error) = (q_new, f, e);
                mu = (mu * T::of(0.1)).max(mu_min);
            }
            _ => {
                unproductive += 1;
                mu *= T::of(10.0);
            }
        }
        if mu > mu_max || unproductive >= patience + N as u32 / 4 {
            let end = if residual.converged(&error) { DescentEnd::Converged } else { DescentEnd::Stalled };
            return done(q, error, iteration + 1, end);
        }
    }
    let end = if residual.converged(&error) { DescentEnd::Converged } else { DescentEnd::OutOfBudget };
    done(q, error, budget, end)
}

/// The damped step, or `None` if the system is not positive definite (non-finite values).
///
/// Joint limits by an active set (the clamping loop of SNS-style solvers): a joint the step would
/// push past a limit is moved exactly to that limit, its motion is taken out of the error, its
/// column is removed, and the rest of the step is solved again by the other joints. Projecting
/// the full step instead (clamp afterwards) wastes most of it when the solution lies near a limit,
/// which is where a redundant arm's last millimetres are.
fn damped_step<T: Real, const N: usize, const M: usize>(
    chain: &Chain<T, N>,
    residual: &Residual<T>,
    frames: &Frames<T, N>,
    error: &ErrorTerms<T>,
    q: &SVector<T, N>,
    lambda: T,
) -> Option<SVector<T, N>> {
    let (mut j, mut e) = residual.task::<M, N>(chain, frames, error);
    let mut at_limit = SVector::<T, N>::zeros();
    let mut frozen = [false; N];
    // Each round freezes at least one more joint, so N + 1 rounds always end.
    for _round in 0..=N {
        let dq = solve_damped::<T, N, M>(&j, &e, residual.rows(), lambda)?;
        let mut froze = false;
        // Indexed by a range over N (not by the joint slice's enumeration), so that every index
        // below is provably in bounds and the firmware links no panic path.
        for k in 0..N {
            let Some(joint) = chain.joints().get(k) else { break };
            if frozen[k] {
                continue;
            }
            let (value, clamped) = joint.saturate(q[k] + dq[k]);
            if clamped {
                at_limit[k] = value - q[k];
                // Element by element: `column * scalar` builds its result from an iterator, whose
                // length check nalgebra asserts (a panic path on the firmware).
                for (e_i, j_i) in e.iter_mut().zip(j.column(k).iter()) {
                    *e_i -= *j_i * at_limit[k];
                }
                j.column_mut(k).fill(T::zero());
                frozen[k] = true;
                froze = true;
            }
        }
        if !froze {
            return Some(dq + at_limit);
        }
    }
    Some(at_limit)
}

/// `J^T (J J^T + lambda I)^-1 e`, or the equal `(J^T J + lambda I)^-1 J^T e` when that system is
/// the smaller one, for a task whose first `rows` rows are live (the rest are zero).
fn solve_damped<T: Real, const N: usize, const M: usize>(
    j: &SMatrix<T, M, N>,
    e: &SVector<T, M>,
    rows: usize,
    lambda: T,
) -> Option<SVector<T, N>> {
    if N >= rows {
        let mut a = j * j.transpose();
        for i in 0..rows.min(M) {
            a[(i, i)] += lambda;
        }
        cholesky_solve_leading(&a, e, rows).map(|y| j.transpose() * y)
    } else {
        let mut a = j.transpose() * j;
        for i in 0..N {
            a[(i, i)] += lambda;
        }
        cholesky_solve(&a, &(j.transpose() * e))
    }
}

pub(super) fn done<T: Real, const N: usize>(
    q: SVector<T, N>,
    error: ErrorTerms<T>,
    iterations: u32,
    end: DescentEnd,
) -> Descent<T, N> {
    Descent { q, error, iterations, end }
}
