//! What every IK solver is asked and what it answers: one problem type, one result type.

use crate::{Pose, Real};
use nalgebra::{Matrix3, SVector, Vector3};

/// Where the tool should go.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Target<T: Real> {
    /// Tool origin at this point (base frame, metres); orientation free.
    Position(Vector3<T>),
    /// Tool frame at this pose (base frame).
    Pose(Pose<T>),
    /// Tool origin at the pose's position, and the tool tilted as the pose is: the base frame's
    /// z axis seen from the tool (`R^T z`) is the pose's (`R_t^T z`), which fixes the tool's
    /// pitch and roll; its turn about the base's z axis (its yaw) is free.
    ///
    /// This is the target of an arm with fewer than six joints whose first joint turns about the
    /// base's z axis (the pan of the SO-101, Koch and OpenManipulator-X): it cannot hold a full
    /// orientation while the pan turns, so a tool moved sideways with its orientation held must
    /// let its yaw follow the pan. The axis is always the base frame's z, whichever way the first
    /// joint turns: the yaw-pitch arms stand on their base with the pan's axis along it.
    Tilt(Pose<T>),
}

impl<T: Real> Target<T> {
    /// A full-pose target from a position and a w-first quaternion (normalised here). `None` for a
    /// zero or non-finite quaternion.
    pub fn pose_wxyz(position: [T; 3], quaternion_wxyz: [T; 4]) -> Option<Self> {
        let rotation: Matrix3<T> = Pose::rotation_from_quaternion_wxyz(quaternion_wxyz)?;
        Some(Target::Pose(Pose { rotation, translation: Vector3::from(position) }))
    }

    /// The same target with the turn about the base's z axis left free: a pose becomes a
    /// [`Target::Tilt`]; a position or a tilt stays as it is.
    pub fn tilt_only(self) -> Self {
        match self {
            Target::Pose(p) => Target::Tilt(p),
            other => other,
        }
    }

    /// The same target at another position (its orientation, if any, as it was).
    pub fn at(self, position: Vector3<T>) -> Self {
        match self {
            Target::Position(_) => Target::Position(position),
            Target::Pose(p) => Target::Pose(Pose { rotation: p.rotation, translation: position }),
            Target::Tilt(p) => Target::Tilt(Pose { rotation: p.rotation, translation: position }),
        }
    }

    /// The target position.
    pub fn position(&self) -> &Vector3<T> {
        match self {
            Target::Position(p) => p,
            Target::Pose(p) | Target::Tilt(p) => &p.translation,
        }
    }

    fn is_finite(&self) -> bool {
        match self {
            Target::Position(p) => p.iter().all(|v| v.finite()),
            Target::Pose(p) | Target::Tilt(p) => p.translation.iter().chain(p.rotation.iter()).all(|v| v.finite()),
        }
    }
}

/// How hard to try and when to stop.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IkConfig<T: Real> {
    /// Largest accepted distance of the tool origin from the target (m).
    pub position_tolerance: T,
    /// Largest accepted rotation angle between tool and target orientation (rad).
    pub orientation_tolerance: T,
    /// Metres of position error one radian of orientation error is worth in the residual the
    /// solvers minimise (tolerances are still checked separately).
    pub orientation_weight: T,
    /// Iteration budget over all attempts together.
    pub max_iterations: u32,
    /// Iterations one attempt may take before it counts as stalled and a restart is drawn.
    pub attempt_iterations: u32,
    /// Restarts from random seeds after a stalled attempt (0 disables them).
    pub max_restarts: u32,
    /// Seed of the restart PRNG: the same seed gives the same restarts.
    pub rng_seed: u64,
}

impl<T: Real> Default for IkConfig<T> {
    /// Tolerances suited to the scalar: 1e-5 m and rad in f64, 1e-4 m and 1e-3 rad in f32.
    fn default() -> Self {
        let single = T::EPSILON > T::of(1e-10);
        Self {
            position_tolerance: T::of(if single { 1e-4 } else { 1e-5 }),
            orientation_tolerance: T::of(if single { 1e-3 } else { 1e-5 }),
            orientation_weight: T::one(),
            max_iterations: 1000,
            attempt_iterations: 150,
            max_restarts: 40,
            rng_seed: 0x5EED,
        }
    }
}

/// One IK problem: target, seed joint values and configuration.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IkProblem<T: Real, const N: usize> {
    /// Where the tool should go.
    pub target: Target<T>,
    /// Where the first attempt starts (brought into the joint limits first).
    pub seed: SVector<T, N>,
    /// Tolerances and budgets.
    pub config: IkConfig<T>,
}

/// Why a problem was refused without solving.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum InvalidInput {
    /// The target contains NaN or infinity.
    NonFiniteTarget,
    /// The seed contains NaN or infinity.
    NonFiniteSeed,
    /// A tolerance or the orientation weight is not a positive finite number.
    BadConfig,
}

impl core::fmt::Display for InvalidInput {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            InvalidInput::NonFiniteTarget => "target contains NaN or infinity",
            InvalidInput::NonFiniteSeed => "seed contains NaN or infinity",
            InvalidInput::BadConfig => "tolerances and orientation weight must be positive and finite",
        })
    }
}

/// What happened.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum IkStatus {
    /// The returned joint values are within limits and reach the target within both tolerances
    /// (checked by forward kinematics on the returned values, never assumed).
    Converged,
    /// Every attempt stalled short of the target (typically unreachable): the closest pose found.
    BestEffort,
    /// The iteration budget ran out while still approaching: the closest pose found.
    IterationLimit,
    /// The problem was refused; the seed is returned unchanged.
    InvalidInput(InvalidInput),
}

impl IkStatus {
    /// The name used in text formats.
    pub fn as_str(&self) -> &'static str {
        match self {
            IkStatus::Converged => "converged",
            IkStatus::BestEffort => "best_effort",
            IkStatus::IterationLimit => "iteration_limit",
            IkStatus::InvalidInput(_) => "invalid_input",
        }
    }
}

/// The answer to an [`IkProblem`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IkSolution<T: Real, const N: usize> {
    /// Joint values, always within limits (continuous joints wrapped).
    pub q: SVector<T, N>,
    /// What happened.
    pub status: IkStatus,
    /// Iterations spent over all attempts.
    pub iterations: u32,
    /// Restarts drawn.
    pub restarts: u32,
    /// Distance of the tool origin from the target at `q` (m).
    pub position_error: T,
    /// Rotation angle between tool and target at `q` (rad); zero for a position-only target; for a
    /// [`Target::Tilt`], the chord `2 sin(theta / 2)` of the angle `theta` between the tool's
    /// vertical and the target's: the angle to within `theta^3 / 24` (see [`super::Residual`]).
    pub orientation_error: T,
}

impl<T: Real, const N: usize> IkSolution<T, N> {
    /// The answer to a problem refused without solving: the seed, unchanged.
    #[inline]
    pub(crate) fn refused(seed: SVector<T, N>, reason: InvalidInput) -> Self {
        Self {
            q: seed,
            status: IkStatus::InvalidInput(reason),
            iterations: 0,
            restarts: 0,
            position_error: T::zero(),
            orientation_error: T::zero(),
        }
    }
}

impl<T: Real, const N: usize> IkProblem<T, N> {
    pub(crate) fn validate(&self) -> Result<(), InvalidInput> {
        if !self.target.is_finite() {
            return Err(InvalidInput::NonFiniteTarget);
        }
        if !self.seed.iter().all(|v| v.finite()) {
            return Err(InvalidInput::NonFiniteSeed);
        }
        let c = &self.config;
        let positive = |v: T| v.finite() && v > T::zero();
        if !(positive(c.position_tolerance) && positive(c.orientation_tolerance) && positive(c.orientation_weight)) {
            return Err(InvalidInput::BadConfig);
        }
        Ok(())
    }
}
