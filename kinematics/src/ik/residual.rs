//! The error between the tool and the target, in the form the solvers minimise: a 6-vector of
//! position error and weighted rotation-vector error, plus the plain distances the tolerances are
//! checked against.
//!
//! A [`Target::Tilt`] asks only that the tool's vertical (the base's z axis carried by the tool as
//! the target carries it, `v = R R_t^T z`, a unit vector) be the base's z. Its angular error is the
//! chord `z - v`, whose length is `2 sin(theta / 2)` for the angle `theta` between the two: the
//! angle to within `theta^3 / 24` (5e-11 rad at f32's tolerance of 1e-3, far below the rounding
//! guard of [`Residual::converged`]), and what is reported as the orientation error. Its
//! Jacobian is the exact one: a turn `w` of the tool moves `v` by `w x v`, so the angular rows are
//! `J_w` crossed with `v` column by column. They have rank 2: a turn about the tool's own vertical
//! changes no tilt, so the solvers are not asked to undo the yaw the position needs. The cost
//! `|z - v|^2 = 2 - 2 cos(theta)` grows with the angle all the way to a half turn, so there is no
//! false minimum with the tool upside down. (A first sketch had the swing's rotation vector and
//! `J_w` projected across `z`: it needs an arc tangent, which the firmware's flash had no room
//! for, and its rows are the derivative only at the solution.)

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
    /// `[target - p; weight * log(R_target R^T)]`; the angular part is zero for a position target,
    /// and `weight * (z - v)` for a tilt target (`v` the tool's vertical, see the module docs).
    pub vector: SVector<T, 6>,
    /// `|target - p|` (m).
    pub position: T,
    /// Rotation angle to the target orientation (rad); for a tilt target, the chord between the
    /// tool's vertical and the base's z, `2 sin(theta / 2)`: the angle to within `theta^3 / 24`.
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

    /// Rows the task has: 3 for a position target, 6 for a pose or a tilt (whose three angular
    /// rows have rank 2: the turn about the tool's vertical is free).
    pub fn rows(&self) -> usize {
        match self.target {
            Target::Position(_) => 3,
            Target::Pose(_) | Target::Tilt(_) => 6,
        }
    }

    /// Error of the tool pose `tool`.
    pub fn error(&self, tool: &Pose<T>) -> ErrorTerms<T> {
        let dp = self.target.position() - tool.translation;
        let dw = match &self.target {
            Target::Position(_) => Vector3::zeros(),
            Target::Pose(p) => rotation_error(&p.rotation, &tool.rotation),
            Target::Tilt(p) => Vector3::z() - tilt_vertical(p, tool),
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
        let mut j6 = chain.jacobian_of(frames);
        if let Target::Tilt(p) = &self.target {
            moving_vertical(&mut j6, &tilt_vertical(p, &frames.tool));
        }
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

/// The angular rows of `j` made the motion of the unit vector `v` (the tool's vertical): a turn
/// `w` moves it by `w x v`, column by column. Not inlined: the firmware's flash has room for one
/// copy, not one in every solver loop that reaches it.
#[inline(never)]
fn moving_vertical<T: Real, const N: usize>(j: &mut SMatrix<T, 6, N>, v: &Vector3<T>) {
    for mut column in j.column_iter_mut() {
        let moved = Vector3::new(column[3], column[4], column[5]).cross(v);
        column[3] = moved[0];
        column[4] = moved[1];
        column[5] = moved[2];
    }
}

/// The base's z axis carried by the tool as the target carries it: `R R_t^T z`, a unit vector that
/// is the base's z exactly when the tool is tilted as the target is.
fn tilt_vertical<T: Real>(target: &Pose<T>, tool: &Pose<T>) -> Vector3<T> {
    let up: Vector3<T> = target.rotation.row(2).transpose();
    tool.rotation * up
}
