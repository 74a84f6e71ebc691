//! `armctl bench plan`: the planner's time on blocked moves, and one full collision check's, on
//! the host. The scene is [`boxed_scene`]: the arm's collision geometry (capsules from its frames
//! where it has none) on its table, and a box in front of it. Moves are pairs of random free
//! configurations (fixed seed) whose straight joint segment is blocked; each is planned from
//! scratch ([`plan`]: the straight check that finds it blocked, RRT-Connect, shortcutting), and
//! timed on the wall clock of this PC. A benchmark, not a test: the figures go in docs/.

use std::io::Write;
use std::time::Instant;

use anyhow::{bail, Result};
use kinematics::SplitMix64;
use serde::Serialize;

use super::ik::SolveTimes;
use crate::arm::dof::build;
use crate::arm::ArmSpec;
use crate::motion::collision::Checker;
#[cfg(test)]
use crate::motion::plan::DEFAULT_SHORTCUTS;
use crate::motion::plan::{boxed_scene, length, plan, Options};

/// A `bench plan` run.
#[derive(Clone, Debug, PartialEq)]
pub struct PlanBenchRequest {
    /// The arm (a preset or an arm file).
    pub arm: String,
    /// Blocked moves planned.
    pub moves: usize,
    /// Seed of the move sampler.
    pub seed: u64,
    /// Random shortcuts tried on each path.
    pub shortcuts: usize,
}

/// Its figures.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PlanBenchReport {
    /// The arm.
    pub arm: String,
    /// Where its collision geometry came from.
    pub geometry: &'static str,
    /// Blocked moves tried.
    pub moves: usize,
    /// Of them, planned.
    pub planned: usize,
    /// Planning time, median (us).
    pub median_us: f64,
    /// Planning time, 99th percentile (us).
    pub p99_us: f64,
    /// Configurations checked per plan, median.
    pub checks_median: u64,
    /// The planned path's joint-space length over the straight segment's, median.
    pub length_ratio_median: f64,
    /// One full check of a configuration (forward kinematics and every pair), median (ns).
    pub check_ns_median: f64,
}

/// Runs the benchmark and prints its report (one JSON object with `json`, else a few lines).
pub fn run(request: &PlanBenchRequest, json: bool, out: &mut dyn Write) -> Result<i32> {
    if request.moves == 0 {
        bail!("--moves must be at least 1");
    }
    let report = measure(request)?;
    if json {
        writeln!(out, "{}", serde_json::to_string_pretty(&report)?)?;
    } else {
        writeln!(
            out,
            "bench plan, {} ({}), {} blocked moves: {} planned; planning time median {:.0} us, p99 {:.0} us; \
             {} checks per plan (median); path {:.2} times the straight segment's length (median); \
             one full check {:.0} ns (median)",
            report.arm,
            report.geometry,
            report.moves,
            report.planned,
            report.median_us,
            report.p99_us,
            report.checks_median,
            report.length_ratio_median,
            report.check_ns_median
        )?;
    }
    Ok(0)
}

/// The figures of `request`.
pub fn measure(request: &PlanBenchRequest) -> Result<PlanBenchReport> {
    let arm = build(ArmSpec::load(&request.arm, None)?)?;
    let geometry = match arm.spec().collision {
        Some(_) => "its own collision geometry, a box",
        None => "capsules of 20 mm from its frames, the table, a box",
    };
    let spec = boxed_scene(arm.as_ref())?;
    let mut checker = Checker::new(arm.as_ref(), spec)?;
    let mut rng = SplitMix64::new(request.seed);
    let free = |checker: &mut Checker, rng: &mut SplitMix64| -> Result<Vec<f64>> {
        for _ in 0..10_000 {
            let q = arm.random_configuration(rng);
            if checker.is_free(&q) {
                return Ok(q);
            }
        }
        bail!("{}: no free configuration in 10000 random ones", request.arm)
    };
    // One full check, over free configurations.
    let mut check_times = Vec::new();
    for _ in 0..2000 {
        let q = arm.random_configuration(&mut rng);
        let began = Instant::now();
        let _ = std::hint::black_box(checker.contact(std::hint::black_box(&q))?);
        check_times.push(began.elapsed());
    }
    let check_ns_median = SolveTimes::of(&mut check_times).median_us * 1e3;
    let (mut times, mut checks, mut ratios) = (Vec::new(), Vec::new(), Vec::new());
    let mut tried = 0usize;
    let mut draws = 0usize;
    while tried < request.moves {
        draws += 1;
        if draws > 1000 * request.moves {
            bail!("{}: fewer than {} blocked moves in {draws} draws", request.arm, request.moves);
        }
        let (start, goal) = (free(&mut checker, &mut rng)?, free(&mut checker, &mut rng)?);
        if checker.straight_free(&start, &goal) {
            continue;
        }
        tried += 1;
        let began = Instant::now();
        let options = Options { shortcuts: request.shortcuts, ..Options::default() };
        let planned = plan(&mut checker, &start, &goal, &options);
        let took = began.elapsed();
        if let Ok(path) = planned {
            times.push(took);
            checks.push(path.checks);
            ratios.push(path.length() / length(&[start, goal]));
        } else {
            times.push(took);
        }
    }
    let planned = checks.len();
    let figures = SolveTimes::of(&mut times);
    checks.sort_unstable();
    ratios.sort_by(f64::total_cmp);
    Ok(PlanBenchReport {
        arm: arm.spec().name.clone(),
        geometry,
        moves: tried,
        planned,
        median_us: figures.median_us,
        p99_us: figures.p99_us,
        checks_median: super::ik::percentile(&checks, 0.5).unwrap_or(0),
        length_ratio_median: super::ik::percentile(&ratios, 0.5).unwrap_or(0.0),
        check_ns_median,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A few moves, some of them planned, and the figures are what they say. (How many of the
    /// blocked moves are planned is the bench's figure, over 1000 in a release build: a plan
    /// with the SO-101's fitted geometry costs seconds in the test profile.)
    #[test]
    fn a_short_run_plans_blocked_moves() {
        let report =
            measure(&PlanBenchRequest { arm: "so101".into(), moves: 3, seed: 3, shortcuts: DEFAULT_SHORTCUTS })
                .unwrap();
        assert_eq!(report.moves, 3, "{report:?}");
        assert!((1..=3).contains(&report.planned), "{report:?}");
        assert!(report.median_us > 0.0 && report.p99_us >= report.median_us && report.check_ns_median > 0.0);
        assert!(report.length_ratio_median >= 1.0 && report.checks_median > 0, "{report:?}");
    }
}
