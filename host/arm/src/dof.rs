//! From run-time joint counts to the kinematics crate's const-generic chains.
//!
//! The kinematics is fixed-size (`Chain<T, N>`) so that the firmware needs no heap; the host reads
//! arms whose joint count it learns at run time. [`build`] matches that count once, for 0 to
//! [`MAX_JOINTS`], and hides the chain behind the object-safe [`DynArm`], so the rest of the host
//! is written once.
//!
//! Every count gets the f64 solvers; only the counts the firmware carries (up to
//! [`F32_MAX_JOINTS`]) get the f32 ones, which exist to run the solver as the firmware does. Each
//! (count, scalar) pair instantiates six solvers, and the build time of the host is mostly these.

use super::ArmSpec;
use anyhow::{anyhow, bail, Result};
use kinematics::ik::analytic::{ClosedForm, Shape, Singularity};
use kinematics::ik::{
    CyclicCoordinateDescent, DampedLeastSquares, GradientDescent, IkConfig, IkProblem, IkStatus, JacobianTranspose,
    PseudoinverseNewton, Regularised, Target,
};
use kinematics::nalgebra::SVector;
use kinematics::{Chain, Pose, Real, SplitMix64};
use std::time::{Duration, Instant};

/// The largest joint count the host dispatches (the kinematics itself has no limit).
pub const MAX_JOINTS: usize = 32;

/// The largest joint count solved in f32: the firmware's, whose scalar f32 is.
pub const F32_MAX_JOINTS: usize = firmware::link::message::MAX_JOINTS;

/// Scalar the solver runs in.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Scalar {
    /// Single precision, as on the firmware.
    F32,
    /// Double precision.
    F64,
}

impl Scalar {
    /// The default position (m) and orientation (rad) tolerances of the solver in this scalar.
    pub fn default_tolerances(self) -> (f64, f64) {
        match self {
            Scalar::F64 => {
                let c = IkConfig::<f64>::default();
                (c.position_tolerance, c.orientation_tolerance)
            }
            Scalar::F32 => {
                let c = IkConfig::<f32>::default();
                (f64::from(c.position_tolerance), f64::from(c.orientation_tolerance))
            }
        }
    }
}

/// How far from 1 a typed quaternion's norm may be (four printed decimals) before it counts as a
/// mistake rather than rounding; within it the quaternion is normalised.
pub const QUATERNION_NORM_TOLERANCE: f64 = 1e-3;

/// The IK methods by name.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SolverName {
    /// The closed form where the arm's geometry has one and it gives a solution within the limits
    /// that reaches, else damped least squares (the default).
    Auto,
    /// The closed form only (an error for an arm without one; f64 only).
    Analytic,
    /// Damped least squares with adaptive damping (Levenberg-Marquardt), the numerical solver.
    Dls,
    /// Newton steps with the pseudoinverse.
    Newton,
    /// Jacobian transpose with Buss's step length.
    Transpose,
    /// Cyclic coordinate descent.
    Ccd,
    /// Gradient descent (the tool as the one handle).
    Gradient,
    /// The regularised objective alpha |e|^2 + |q|^2 (alpha = 10).
    Regularised,
}

/// One IK request in host terms.
#[derive(Clone, Debug)]
pub struct IkRequest {
    /// Target tool position (m, base frame).
    pub position: [f64; 3],
    /// Target orientation, w first; `None` for a position-only target.
    pub quaternion_wxyz: Option<[f64; 4]>,
    /// Seed joint values; `None` for the middle of the limits.
    pub seed: Option<Vec<f64>>,
    /// Method.
    pub solver: SolverName,
    /// Tolerances and budgets (converted to the scalar).
    pub config: IkConfig<f64>,
    /// Scalar the solver runs in.
    pub scalar: Scalar,
    /// Where the arm has fewer than six moving joints, hold the orientation only up to a turn
    /// about the base's z axis ([`kinematics::ik::Target::Tilt`]), as the firmware takes a tool
    /// orientation (a Cartesian keyframe, `move --quat`); a six-joint arm keeps the full pose.
    /// `false` for `armctl ik`, which answers the full pose it is asked.
    pub tilt_only: bool,
}

/// The answer, in f64 whatever the scalar.
#[derive(Clone, Debug)]
pub struct IkOutcome {
    /// Joint values.
    pub q: Vec<f64>,
    /// What happened.
    pub status: IkStatus,
    /// Iterations over all attempts.
    pub iterations: u32,
    /// Restarts drawn.
    pub restarts: u32,
    /// Tool position error at `q` (m).
    pub position_error: f64,
    /// Tool orientation error at `q` (rad).
    pub orientation_error: f64,
    /// Time spent in the solver alone.
    pub solve_time: Duration,
    /// The method that answered: "analytic", or the numerical method's name.
    pub method: &'static str,
}

/// One closed-form solution in host terms (see [`DynArm::all_solutions`]).
#[derive(Clone, Debug)]
pub struct ClosedFormAnswer {
    /// Joint values, fitted into the limits nearest the seed where possible.
    pub q: Vec<f64>,
    /// Every value within its joint's limits.
    pub within_limits: bool,
    /// The shape's equations have it (false: the least-squares answer of a branch that cannot
    /// reach).
    pub exact: bool,
    /// FK at `q` reaches the target within the tolerances.
    pub reaches: bool,
    /// Tool position error at `q` (m).
    pub position_error: f64,
    /// Tool orientation error at `q` (rad).
    pub orientation_error: f64,
    /// The singularity it sits at, if any.
    pub singular: Option<Singularity>,
}

/// An arm of any joint count, for the host's commands. Shared between threads: `ik --batch`
/// solves on one while another prints.
pub trait DynArm: Send + Sync {
    /// The description it was built from.
    fn spec(&self) -> &ArmSpec;
    /// Tool pose at `q`.
    fn tool_pose(&self, q: &[f64]) -> Result<Pose<f64>>;
    /// Every joint frame (after its motion) at `q`.
    fn joint_frames(&self, q: &[f64]) -> Result<Vec<Pose<f64>>>;
    /// The 6 x N geometric Jacobian at `q`, row by row.
    fn jacobian(&self, q: &[f64]) -> Result<Vec<Vec<f64>>>;
    /// The middle of every joint range.
    fn middle(&self) -> Vec<f64>;
    /// A joint vector drawn uniformly within the limits.
    fn random_configuration(&self, rng: &mut SplitMix64) -> Vec<f64>;
    /// True if `q` is within every joint's limits.
    fn admits(&self, q: &[f64]) -> bool;
    /// Solves an IK request. Errors only for a request that cannot be posed (seed length, zero
    /// quaternion, the closed form asked of an arm without one); everything else is in the
    /// outcome's status.
    fn solve(&self, request: &IkRequest) -> Result<IkOutcome>;
    /// The closed form's shape, if the arm's geometry has one.
    fn closed_form_shape(&self) -> Option<Shape>;
    /// True if the arm's closed form answers a target with (`oriented`) or without an orientation:
    /// every shape takes a pose, the yaw-pitch shape a position too.
    fn closed_form_answers(&self, oriented: bool) -> bool {
        self.closed_form_shape().is_some_and(|shape| oriented || shape.answers_position())
    }
    /// Every closed-form solution of the request's target (f64), with the time they took. Errors
    /// for an arm without a closed form, or a target it does not answer.
    fn all_solutions(&self, request: &IkRequest) -> Result<(Vec<ClosedFormAnswer>, Duration)>;
}

/// A chain in one scalar, solving host requests; boxed so that the f32 chain, and its solvers,
/// are instantiated only for the counts that have one.
trait SolveIn<const N: usize>: Send + Sync {
    fn solve(&self, request: &IkRequest, seed: SVector<f64, N>) -> Result<IkOutcome>;
}

impl<T: Real, const N: usize> SolveIn<N> for Chain<T, N> {
    fn solve(&self, request: &IkRequest, seed: SVector<f64, N>) -> Result<IkOutcome> {
        solve_in(self, None, request, seed)
    }
}

struct Arm<const N: usize> {
    spec: ArmSpec,
    f64: Chain<f64, N>,
    /// The f64 chain's closed form, if its geometry has one.
    closed: Option<ClosedForm<f64, N>>,
    /// `None` above [`F32_MAX_JOINTS`].
    f32: Option<Box<dyn SolveIn<N>>>,
}

impl<const N: usize> Arm<N> {
    fn vector(&self, q: &[f64]) -> Result<SVector<f64, N>> {
        if q.len() != N {
            bail!("arm {} has {N} joints but {} joint values were given", self.spec.name, q.len());
        }
        Ok(SVector::from_column_slice(q))
    }
}

impl<const N: usize> DynArm for Arm<N> {
    fn spec(&self) -> &ArmSpec {
        &self.spec
    }

    fn tool_pose(&self, q: &[f64]) -> Result<Pose<f64>> {
        Ok(self.f64.tool_pose(&self.vector(q)?))
    }

    fn joint_frames(&self, q: &[f64]) -> Result<Vec<Pose<f64>>> {
        Ok(self.f64.forward(&self.vector(q)?).joints.to_vec())
    }

    fn jacobian(&self, q: &[f64]) -> Result<Vec<Vec<f64>>> {
        let j = self.f64.jacobian(&self.vector(q)?);
        Ok((0..6).map(|r| j.row(r).iter().copied().collect()).collect())
    }

    fn middle(&self) -> Vec<f64> {
        self.f64.middle().iter().copied().collect()
    }

    fn random_configuration(&self, rng: &mut SplitMix64) -> Vec<f64> {
        self.f64.random_configuration(rng).iter().copied().collect()
    }

    fn admits(&self, q: &[f64]) -> bool {
        self.vector(q).map(|v| self.f64.admits(&v)).unwrap_or(false)
    }

    fn solve(&self, request: &IkRequest) -> Result<IkOutcome> {
        let seed = match &request.seed {
            Some(s) => self.vector(s)?,
            None => self.f64.middle(),
        };
        if request.solver == SolverName::Analytic {
            if self.closed.is_none() {
                bail!(
                    "arm {} has no closed form (it needs six joints with a spherical wrist or three parallel \
                     axes, or a base yaw and three parallel pitch axes); use --solver numeric or auto",
                    self.spec.name
                );
            }
            if request.scalar == Scalar::F32 {
                bail!("the closed form runs in f64 (use --scalar f64)");
            }
        }
        match request.scalar {
            Scalar::F64 => solve_in(&self.f64, self.closed.as_ref(), request, seed),
            Scalar::F32 => match &self.f32 {
                Some(chain) => chain.solve(request, seed),
                None => bail!(
                    "f32 runs the solver as the firmware does, for arms of 1 to {F32_MAX_JOINTS} joints; \
                     arm {} has {N} (use --scalar f64)",
                    self.spec.name
                ),
            },
        }
    }

    fn closed_form_shape(&self) -> Option<Shape> {
        self.closed.as_ref().map(|c| c.shape())
    }

    fn all_solutions(&self, request: &IkRequest) -> Result<(Vec<ClosedFormAnswer>, Duration)> {
        let Some(closed) = &self.closed else {
            bail!("arm {} has no closed form, so no list of every solution", self.spec.name);
        };
        let seed = match &request.seed {
            Some(s) => self.vector(s)?,
            None => self.f64.middle(),
        };
        let problem = problem_in::<f64, N>(request, seed)?;
        if !closed.answers(&problem.target) {
            bail!("the {} closed form needs a full pose (--quat)", closed.shape().as_str());
        }
        let started = Instant::now();
        let all = closed.solutions(&self.f64, &problem);
        let took = started.elapsed();
        let answers = all
            .iter()
            .map(|s| ClosedFormAnswer {
                q: s.q.iter().copied().collect(),
                within_limits: s.within_limits,
                exact: s.exact,
                reaches: s.reaches,
                position_error: s.position_error,
                orientation_error: s.orientation_error,
                singular: s.singular,
            })
            .collect();
        Ok((answers, took))
    }
}

/// Refuses a typed target quaternion (w first) whose norm is not 1 within
/// [`QUATERNION_NORM_TOLERANCE`]: a mistake rather than rounding. Chains and trees ask the same.
pub fn check_unit_quaternion(quat: [f64; 4]) -> Result<()> {
    let norm = quat.iter().map(|v| v * v).sum::<f64>().sqrt();
    if (norm - 1.0).abs() > QUATERNION_NORM_TOLERANCE || norm.is_nan() {
        bail!("the target quaternion w,x,y,z is not a unit quaternion (norm {norm})");
    }
    Ok(())
}

/// The request as the kinematics crate's problem, in `T`.
fn problem_in<T: Real, const N: usize>(request: &IkRequest, seed: SVector<f64, N>) -> Result<IkProblem<T, N>> {
    let position = request.position.map(T::of);
    let target = match request.quaternion_wxyz {
        None => Target::Position(position.into()),
        Some(quat) => {
            check_unit_quaternion(quat)?;
            Target::pose_wxyz(position, quat.map(T::of))
                .ok_or_else(|| anyhow!("the target quaternion must be finite and non-zero"))?
        }
    };
    let c = &request.config;
    let config = IkConfig {
        position_tolerance: T::of(c.position_tolerance),
        orientation_tolerance: T::of(c.orientation_tolerance),
        orientation_weight: T::of(c.orientation_weight),
        max_iterations: c.max_iterations,
        attempt_iterations: c.attempt_iterations,
        max_restarts: c.max_restarts,
        rng_seed: c.rng_seed,
    };
    Ok(IkProblem { target, seed: seed.map(T::of), config })
}

fn solve_in<T: Real, const N: usize>(
    chain: &Chain<T, N>,
    closed: Option<&ClosedForm<T, N>>,
    request: &IkRequest,
    seed: SVector<f64, N>,
) -> Result<IkOutcome> {
    let mut problem = problem_in(request, seed)?;
    if request.tilt_only && chain.moving_joints() < 6 {
        problem.target = problem.target.tilt_only();
    }
    let started = Instant::now();
    let mut method = match request.solver {
        SolverName::Auto | SolverName::Dls => "dls",
        SolverName::Analytic => "analytic",
        SolverName::Newton => "newton",
        SolverName::Transpose => "transpose",
        SolverName::Ccd => "ccd",
        SolverName::Gradient => "gradient",
        SolverName::Regularised => "regularised",
    };
    let solution = match request.solver {
        SolverName::Auto => {
            let (solution, analytic) = chain.solve_auto(closed, &problem);
            if analytic {
                method = "analytic";
            }
            solution
        }
        SolverName::Analytic => {
            let Some(closed) = closed else { bail!("this arm has no closed form") };
            if !closed.answers(&problem.target) {
                bail!("the {} closed form needs a full pose (a quaternion)", closed.shape().as_str());
            }
            chain.solve_closed_form(closed, &problem)
        }
        SolverName::Dls => chain.solve_with(&DampedLeastSquares, &problem),
        SolverName::Newton => chain.solve_with(&PseudoinverseNewton, &problem),
        SolverName::Transpose => chain.solve_with(&JacobianTranspose, &problem),
        SolverName::Ccd => chain.solve_with(&CyclicCoordinateDescent, &problem),
        SolverName::Gradient => chain.solve_with(&GradientDescent::default(), &problem),
        SolverName::Regularised => chain.solve_with(&Regularised::default(), &problem),
    };
    let solve_time = started.elapsed();
    Ok(IkOutcome {
        q: solution.q.iter().map(|v| v.to_f64()).collect(),
        status: solution.status,
        iterations: solution.iterations,
        restarts: solution.restarts,
        position_error: solution.position_error.to_f64(),
        orientation_error: solution.orientation_error.to_f64(),
        solve_time,
        method,
    })
}

fn build_n<const N: usize>(spec: ArmSpec) -> Result<Box<dyn DynArm>> {
    let f64 = spec.chain::<f64, N>()?;
    let closed = ClosedForm::of(&f64);
    Ok(Box::new(Arm { spec, f64, closed, f32: None }))
}

fn build_with_f32_n<const N: usize>(spec: ArmSpec) -> Result<Box<dyn DynArm>> {
    let f64 = spec.chain::<f64, N>()?;
    let f32: Box<dyn SolveIn<N>> = Box::new(spec.chain::<f32, N>()?);
    let closed = ClosedForm::of(&f64);
    Ok(Box::new(Arm { spec, f64, closed, f32: Some(f32) }))
}

fn planar_n<const N: usize>() -> Result<ArmSpec> {
    let chain = kinematics::presets::planar::<f64, N>().map_err(|e| anyhow!("planar:{N}: {e}"))?;
    Ok(ArmSpec::from_chain(&format!("planar:{N}"), &chain))
}

/// Calls `$f::<N>($args)` for the run-time count `$n`, or fails beyond [`MAX_JOINTS`].
macro_rules! dispatch {
    ($n:expr, $f:ident ( $($arg:expr),* )) => {
        dispatch!(@arms $n, $f, ($($arg),*), 0 1 2 3 4 5 6 7 8 9 10 11 12 13 14 15 16 17 18 19 20 21 22 23
            24 25 26 27 28 29 30 31 32)
    };
    (@arms $n:expr, $f:ident, $args:tt, $($k:literal)*) => {
        match $n {
            $($k => dispatch!(@call $f, $k, $args),)*
            n => Err(anyhow!("{n} joints: armctl handles chains of at most {MAX_JOINTS} joints")),
        }
    };
    (@call $f:ident, $k:literal, ($($arg:expr),*)) => { $f::<$k>($($arg),*) };
}

// The list in `dispatch_f32!` is 0 to the firmware's joint count.
const _: () = assert!(F32_MAX_JOINTS == 8, "dispatch_f32! lists the counts 0 to 8");

/// As [`dispatch!`], for the counts that have f32 solvers (0 to [`F32_MAX_JOINTS`]).
macro_rules! dispatch_f32 {
    ($n:expr, $f:ident ( $($arg:expr),* )) => {
        dispatch!(@arms $n, $f, ($($arg),*), 0 1 2 3 4 5 6 7 8)
    };
}

// For the crate's other run-time counts (`arm_dynamics`); the caller has `MAX_JOINTS` and
// `anyhow!` in scope, which the fallback arm names.
pub(crate) use {dispatch, dispatch_f32};

/// The arm of `spec` as a [`DynArm`]; fails for an invalid description or too many joints.
pub fn build(spec: ArmSpec) -> Result<Box<dyn DynArm>> {
    match spec.dof() {
        n @ 0..=F32_MAX_JOINTS => dispatch_f32!(n, build_with_f32_n(spec)),
        n => dispatch!(n, build_n(spec)),
    }
}

/// The `planar:N` preset's description.
pub fn planar_spec(n: usize) -> Result<ArmSpec> {
    dispatch!(n, planar_n())
}

// By their command-line names, without clap (this crate is beneath the command line):
// `armctl::cli::values` offers these names to clap, the Python binding parses them with `FromStr`.

impl Scalar {
    /// Every scalar with its name and what it is.
    pub const NAMES: [(&'static str, Scalar, &'static str); 2] =
        [("f32", Scalar::F32, "Single precision, as on the firmware"), ("f64", Scalar::F64, "Double precision")];
}

impl std::str::FromStr for Scalar {
    type Err = anyhow::Error;

    /// `f32` or `f64`, in any case.
    fn from_str(name: &str) -> Result<Self> {
        Scalar::NAMES.iter().find(|(n, _, _)| n.eq_ignore_ascii_case(name)).map(|&(_, s, _)| s).ok_or_else(|| {
            let known: Vec<&str> = Scalar::NAMES.iter().map(|(n, _, _)| *n).collect();
            anyhow!("scalar {name:?}: one of {}", known.join(", "))
        })
    }
}

impl SolverName {
    /// Every method with its name, its other names and what it is.
    pub const NAMES: [(&'static str, SolverName, &'static [&'static str], &'static str); 8] = [
        (
            "auto",
            SolverName::Auto,
            &[],
            "The closed form where the arm's geometry has one and it gives a solution within the limits that reaches, else damped least squares (the default)",
        ),
        ("analytic", SolverName::Analytic, &[], "The closed form only (an error for an arm without one; f64 only)"),
        (
            "dls",
            SolverName::Dls,
            &["numeric"],
            "Damped least squares with adaptive damping (Levenberg-Marquardt), the numerical solver",
        ),
        ("newton", SolverName::Newton, &[], "Newton steps with the pseudoinverse"),
        ("transpose", SolverName::Transpose, &[], "Jacobian transpose with Buss's step length"),
        ("ccd", SolverName::Ccd, &[], "Cyclic coordinate descent"),
        ("gradient", SolverName::Gradient, &[], "Gradient descent (the tool as the one handle)"),
        ("regularised", SolverName::Regularised, &[], "The regularised objective alpha |e|^2 + |q|^2 (alpha = 10)"),
    ];
}

impl std::str::FromStr for SolverName {
    type Err = anyhow::Error;

    /// A method's name or one of its other names (`numeric` for `dls`), in any case.
    fn from_str(name: &str) -> Result<Self> {
        SolverName::NAMES
            .iter()
            .find(|(n, _, aliases, _)| {
                n.eq_ignore_ascii_case(name) || aliases.iter().any(|a| a.eq_ignore_ascii_case(name))
            })
            .map(|&(_, s, _, _)| s)
            .ok_or_else(|| {
                let known: Vec<&str> = SolverName::NAMES.iter().map(|(n, _, _, _)| *n).collect();
                anyhow!("solver {name:?}: one of {}", known.join(", "))
            })
    }
}
