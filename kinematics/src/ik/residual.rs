//! The error between the tool and the target, in the form the solvers minimise: a 6-vector of
//! position error and weighted rotation-vector error, plus the plain distances the tolerances are
//! checked against.

use super::{IkConfig, Target};
use crate::pose::rotation_error;
use crate::{Chain, Frames, Pose, Real};
use nalgebra::{SMatrix, SVector, Vector3};

/// Target plus weights and tolerances, fixed for one solve.
#[derive(Clone, Copy, Debug)]
pub struct Residual<T: Real> {
    /// Where the tool should go.
    pub target: Target<T>,
    /// Orientation weight (m/rad).
    pub weight: T,
    /// Position tolerance (m).
    pub position_tolerance: T,
    /// Orientation tolerance (rad).
    pub orientation_tolerance: T,
    /// Rounding allowance subtracted from the tolerances (see [`Residual::converged`]).
    guard: T,
}

/// The tool's error at one joint vector.
#[derive(Clone, Copy, Debug)]
pub struct ErrorTerms<T: Real> {
    /// `[target - p; weight * log(R_target R^T)]`; the angular part is zero for a position target.
    pub vector: SVector<T, 6>,
    /// `|target - p|` (m).
    pub position: T,
    /// Rotation angle to the target orientation (rad).
    pub orientation: T,
    /// Half the squared norm of `vector`: what the solvers decrease.
    pub cost: T,
}

impl<T: Real> Residual<T> {
    /// The residual of a problem's target and configuration.
    pub fn new(target: Target<T>, config: &IkConfig<T>) -> Self {
        Self {
            target,
            weight: config.orientation_weight,
            position_tolerance: config.position_tolerance,
            orientation_tolerance: config.orientation_tolerance,
            // Forward kinematics in T rounds at about N * eps * reach; 32 eps per metre of target
            // distance (plus one metre) is well above what f32 shows (about 1 eps per metre).
            guard: T::EPSILON * T::of(32.0) * (target.position().norm() + T::one()),
        }
    }

    /// Rows the task has: 3 for a position target, 6 for a pose.
    pub fn rows(&self) -> usize {
        match self.target {
            Target::Position(_) => 3,
            Target::Pose(_) => 6,
        }
    }

    /// Error of the tool pose `tool`.
    pub fn error(&self, tool: &Pose<T>) -> ErrorTerms<T> {
        let dp = self.target.position() - tool.translation;
        let dw = match &self.target {
            Target::Position(_) => Vector3::zeros(),
            Target::Pose(p) => rotation_error(&p.rotation, &tool.rotation),
        };
        let mut vector = SVector::<T, 6>::zeros();
        vector.fixed_rows_mut::<3>(0).copy_from(&dp);
        vector.fixed_rows_mut::<3>(3).copy_from(&(dw * self.weight));
        ErrorTerms { vector, position: dp.norm(), orientation: dw.norm(), cost: vector.norm_squared() * T::of(0.5) }
    }

    /// True if the error is within both tolerances.
    ///
    /// The errors are computed in `T`; each must be within its tolerance less a rounding guard, so
    /// that "converged" still holds when the same joint values are checked against the exact target
    /// in higher precision (the guard is about 6e-6 for f32 at arm scale, 1e-14 for f64).
    pub fn converged(&self, e: &ErrorTerms<T>) -> bool {
        e.position + self.guard <= self.position_tolerance && e.orientation + self.guard <= self.orientation_tolerance
    }

    /// The first `M` rows (3 or 6) of the weighted Jacobian and error: the task the solvers see.
    /// Rows past [`Residual::rows`] are zero (a position target asked for 6 rows), so they add
    /// exactly nothing to any product: a solver can hold every task in 6 rows.
    pub fn task<const M: usize, const N: usize>(
        &self,
        chain: &Chain<T, N>,
        frames: &Frames<T, N>,
        e: &ErrorTerms<T>,
    ) -> (SMatrix<T, M, N>, SVector<T, M>) {
        const { assert!(M == 3 || M == 6, "a task has 3 (position) or 6 (pose) rows") };
        let j6 = chain.jacobian_of(frames);
        let rows = self.rows();
        let j = SMatrix::<T, M, N>::from_fn(|r, c| match r {
            _ if r >= rows => T::zero(),
            0..3 => j6[(r, c)],
            _ => j6[(r, c)] * self.weight,
        });
        let v = SVector::<T, M>::from_fn(|r, _| e.vector[r]);
        (j, v)
    }
}
