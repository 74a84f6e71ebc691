//! The IK solve-rate protocol of `shared/reference/arms.md` (as TRAC-IK and KDL publish it):
//! joint vectors drawn uniformly inside the limits, their FK poses as targets, the middle of the
//! limits as the seed, success = full-pose error within tolerance *and* joint values within limits,
//! mean time per solve with failures included.
//!
//! Success is judged here, by f64 forward kinematics on the joint values a solver returns, not by
//! the solver's own claim, so our solver and `k` are held to exactly the same test.

use crate::arm::dof::{DynArm, IkRequest, Scalar, SolverName};
use anyhow::Result;
use kinematics::ik::IkConfig;
use kinematics::{rotation_error, Pose, SplitMix64};
use serde::Serialize;
use std::time::Duration;

/// Settings of one protocol run.
#[derive(Clone, Debug)]
pub struct Protocol {
    /// Number of targets.
    pub n: usize,
    /// Scalar of our solver.
    pub scalar: Scalar,
    /// Seed of the target sampler (the solver's restart PRNG has its own, fixed seed).
    pub seed: u64,
    /// Also run `k` on the same targets.
    pub with_k: bool,
}

impl Protocol {
    /// Position and orientation tolerances: 1e-5 m and rad in f64; 1e-4 m and 1e-3 rad in f32.
    pub fn tolerances(&self) -> (f64, f64) {
        self.scalar.default_tolerances()
    }
}

/// Figures for one solver.
#[derive(Clone, Debug, Serialize)]
pub struct SolverFigures {
    /// Solver name.
    pub solver: String,
    /// Targets solved within tolerance and limits.
    pub solved: usize,
    /// Targets tried.
    pub targets: usize,
    /// `solved / targets` in percent.
    pub success_percent: f64,
    /// Mean time per solve, failures included (microseconds).
    pub mean_us: f64,
    /// Median time per solve (microseconds).
    pub median_us: f64,
    /// 99th percentile time per solve (microseconds).
    pub p99_us: f64,
    /// Solves where the solver claimed success but the check here disagreed (must be 0 for ours).
    pub false_claims: usize,
}

/// The report of one run.
#[derive(Clone, Debug, Serialize)]
pub struct Report {
    /// Arm name.
    pub arm: String,
    /// "f32" or "f64".
    pub scalar: String,
    /// Position tolerance (m).
    pub position_tolerance: f64,
    /// Orientation tolerance (rad).
    pub orientation_tolerance: f64,
    /// Target sampler seed.
    pub seed: u64,
    /// One entry per solver, ours first.
    pub solvers: Vec<SolverFigures>,
}

/// Accumulates outcomes into [`SolverFigures`].
struct Tally {
    solver: String,
    times: Vec<Duration>,
    solved: usize,
    false_claims: usize,
}

impl Tally {
    fn new(solver: &str, n: usize) -> Self {
        Self { solver: solver.to_string(), times: Vec::with_capacity(n), solved: 0, false_claims: 0 }
    }

    fn add(&mut self, time: Duration, success: bool, claimed: bool) {
        self.times.push(time);
        self.solved += usize::from(success);
        self.false_claims += usize::from(claimed && !success);
    }

    fn figures(mut self) -> SolverFigures {
        let targets = self.times.len();
        let times = SolveTimes::of(&mut self.times);
        SolverFigures {
            solver: self.solver,
            solved: self.solved,
            targets,
            success_percent: 100.0 * self.solved as f64 / targets.max(1) as f64,
            mean_us: times.mean_us,
            median_us: times.median_us,
            p99_us: times.p99_us,
            false_claims: self.false_claims,
        }
    }
}

/// Mean, median and 99th percentile of solve times, in microseconds (0 when there are none): the
/// figures both `bench ik` and `ik --batch` report.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SolveTimes {
    /// Mean (failures included).
    pub mean_us: f64,
    /// Median.
    pub median_us: f64,
    /// 99th percentile (nearest rank).
    pub p99_us: f64,
}

impl SolveTimes {
    /// The figures of `times` (sorted in place).
    pub fn of(times: &mut [Duration]) -> Self {
        times.sort_unstable();
        let us = |d: Duration| d.as_secs_f64() * 1e6;
        Self {
            mean_us: times.iter().map(|d| us(*d)).sum::<f64>() / times.len().max(1) as f64,
            median_us: percentile(times, 0.5).map_or(0.0, us),
            p99_us: percentile(times, 0.99).map_or(0.0, us),
        }
    }
}

/// The value below which the fraction `p` of the sorted `values` lie (nearest rank).
pub fn percentile<V: Copy>(sorted: &[V], p: f64) -> Option<V> {
    if sorted.is_empty() {
        return None;
    }
    let rank = ((p * sorted.len() as f64).ceil() as usize).clamp(1, sorted.len());
    Some(sorted[rank - 1])
}

/// True if `q` reaches `target` within the tolerances (f64 FK) and lies within the limits.
fn reaches(arm: &dyn DynArm, q: &[f64], target: &Pose<f64>, tolerances: (f64, f64)) -> bool {
    let Ok(pose) = arm.tool_pose(q) else { return false };
    let position = (pose.translation - target.translation).norm();
    let orientation = rotation_error(&target.rotation, &pose.rotation).norm();
    position <= tolerances.0 && orientation <= tolerances.1 && arm.admits(q)
}

/// Runs the protocol.
pub fn run(arm: &dyn DynArm, protocol: &Protocol) -> Result<Report> {
    let tolerances = protocol.tolerances();
    let mut rng = SplitMix64::new(protocol.seed);
    let targets: Vec<Pose<f64>> =
        (0..protocol.n).map(|_| arm.tool_pose(&arm.random_configuration(&mut rng))).collect::<Result<_>>()?;
    let config = IkConfig::<f64> {
        position_tolerance: tolerances.0,
        orientation_tolerance: tolerances.1,
        ..IkConfig::default()
    };

    // The numerical solver, then the closed form where the geometry has one (auto: with the
    // numerical solver behind it), on the same targets. The closed form runs in f64 only.
    let mut methods = vec![(SolverName::Dls, "armctl dls (numeric)".to_string())];
    if let (Some(shape), Scalar::F64) = (arm.closed_form_shape(), protocol.scalar) {
        methods.push((SolverName::Auto, format!("armctl auto (closed form: {})", shape.as_str())));
    }
    let mut solvers = Vec::new();
    for (solver, name) in methods {
        let mut tally = Tally::new(&name, protocol.n);
        for target in &targets {
            let request = IkRequest {
                position: target.translation.into(),
                quaternion_wxyz: Some(target.quaternion_wxyz()),
                seed: None,
                solver,
                config,
                scalar: protocol.scalar,
                tilt_only: false,
            };
            let outcome = arm.solve(&request)?;
            let claimed = outcome.status == kinematics::ik::IkStatus::Converged;
            tally.add(outcome.solve_time, reaches(arm, &outcome.q, target, tolerances), claimed);
        }
        solvers.push(tally.figures());
    }

    #[cfg(feature = "compare-k")]
    if protocol.with_k {
        let k_arm = crate::commands::bench::k::KArm::new(arm.spec())?;
        let seed = arm.middle();
        let mut tally = Tally::new(
            &format!("k JacobianIkSolver (f64, {} tries)", crate::commands::bench::k::K_MAX_TRY),
            protocol.n,
        );
        for target in &targets {
            let outcome = k_arm.solve(target, &seed, tolerances.0, tolerances.1);
            tally.add(outcome.solve_time, reaches(arm, &outcome.q, target, tolerances), outcome.claimed);
        }
        solvers.push(tally.figures());
    }

    Ok(Report {
        arm: arm.spec().name.clone(),
        scalar: match protocol.scalar {
            Scalar::F32 => "f32".into(),
            Scalar::F64 => "f64".into(),
        },
        position_tolerance: tolerances.0,
        orientation_tolerance: tolerances.1,
        seed: protocol.seed,
        solvers,
    })
}
