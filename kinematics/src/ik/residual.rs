//! The error between the tool and the target, in the form the solvers minimise: a 6-vector of
//! position error and weighted rotation-vector error, plus the plain distances the tolerances are
//! checked against.
//!
//! A [`Target::Tilt`] asks only that the tool's vertical (the base's z axis carried by the tool,
//! `v = R R_t^T z`) be the base's z. Its angular error is the swing that carries `v` onto `z`, as
//! a rotation vector: `theta (v x z) / |v x z|`, which is perpendicular to both. Its Jacobian is the
//! tool's angular velocity with the part about `v` taken out, `(I - v v^T) J_w`: a turn about the
//! tool's own vertical leaves the tilt as it is, so the solvers are not asked to undo the yaw the
//! position needs. (Projecting on the plane across the base's z instead, as a first sketch had it,
//! agrees at the solution, where `v = z`; across `v`, the error and the rows lie in the same plane at
//! every iterate, so the damped solve never meets an error along `v`, which no turn changes.)

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
    /// and the swing that carries the tool's vertical onto the base's z for a tilt target.
    pub vector: SVector<T, 6>,
    /// `|target - p|` (m).
    pub position: T,
    /// Rotation angle to the target orientation (rad); for a tilt target, the angle between the
    /// tool's vertical and the base's z.
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
            Target::Tilt(p) => swing(&tilt_vertical(p, tool)),
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
            across(&mut j6, &tilt_vertical(p, &frames.tool));
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

/// The angular rows of `j` across the unit vector `v` (the tool's vertical): a turn about it
/// changes no tilt. Not inlined: the firmware's flash has room for one copy, not one per solver
/// loop that reaches it.
#[inline(never)]
fn across<T: Real, const N: usize>(j: &mut SMatrix<T, 6, N>, v: &Vector3<T>) {
    for mut column in j.column_iter_mut() {
        let w = Vector3::new(column[3], column[4], column[5]);
        let a = w - v * v.dot(&w);
        column[3] = a[0];
        column[4] = a[1];
        column[5] = a[2];
    }
}

/// The base's z axis carried by the tool as the target carries it: `R R_t^T z`, a unit vector that
/// is the base's z exactly when the tool is tilted as the target is.
fn tilt_vertical<T: Real>(target: &Pose<T>, tool: &Pose<T>) -> Vector3<T> {
    let up: Vector3<T> = target.rotation.row(2).transpose();
    tool.rotation * up
}

/// The rotation vector of the shortest rotation carrying the unit vector `v` onto the base's z:
/// axis `v x z`, angle `atan2(|v x z|, v . z)` (in [0, pi]). At `v = -z` every axis across z is as
/// short; x is taken, so the error is never zero there. Not inlined, as [`across`].
#[inline(never)]
fn swing<T: Real>(v: &Vector3<T>) -> Vector3<T> {
    let axis = Vector3::new(v[1], -v[0], T::zero());
    let s = axis.norm();
    let angle = s.atan2(v[2]);
    if s > T::EPSILON {
        axis * (angle / s)
    } else if v[2] >= T::zero() {
        // atan2(s, c) / s -> 1 / c for s -> 0 (c near 1): the small-angle limit, kept smooth.
        axis / v[2].max(T::EPSILON)
    } else {
        Vector3::new(angle, T::zero(), T::zero())
    }
}
