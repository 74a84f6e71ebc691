//! `armctl ik`: one target, or a JSON-lines file of them (`--batch`); on a tree, one target per
//! end effector solved at once (`super::tree`).

use std::io::{Read, Write};
use std::sync::mpsc::{sync_channel, Receiver, SyncSender, TryRecvError};
use std::time::Instant;

use anyhow::{bail, Context, Result};
use clap::Args;
use kinematics::ik::{IkConfig, IkStatus};
use serde::{Deserialize, Serialize};
use serde_json::json;

use super::tree::{self, TreeIk};
use super::{load_body, print_json, ArmArgs, Loaded};
use crate::arm::dof::{DynArm, IkOutcome, IkRequest, Scalar, SolverName};
use crate::arm::dyn_tree::{self, DynTree};
use crate::commands::bench::ik as bench;
use crate::support::json_lines::{self, Line, Parsed};
use crate::support::numbers as parse;

#[derive(Args, Debug)]
pub(crate) struct IkArgs {
    #[command(flatten)]
    pub(super) arm: ArmArgs,
    /// Target tool position x,y,z (m). For a tree (a URDF with several leaves and no --tip):
    /// NAME=x,y,z[,qw,qx,qy,qz], once per end effector with a target (NAME its link).
    #[arg(long, allow_hyphen_values = true, required_unless_present = "batch", conflicts_with = "batch")]
    target: Vec<String>,
    /// Target orientation as a unit quaternion w,x,y,z (omit for a position-only target).
    #[arg(long, allow_hyphen_values = true, conflicts_with = "batch")]
    quat: Option<String>,
    /// Seed joint values (default: the middle of each joint's limits).
    #[arg(long, allow_hyphen_values = true, conflicts_with = "batch")]
    seed: Option<String>,
    /// JSON-lines file of targets (`-` for standard input); one result line each on stdout.
    #[arg(long)]
    batch: Option<String>,
    /// Method: auto (the closed form where the arm's geometry has one, else dls), analytic,
    /// numeric (= dls) or another numerical method.
    #[arg(long, value_parser = crate::cli::values::solver(), default_value = "auto")]
    solver: SolverName,
    /// Print every closed-form solution of the target (one target; arms with a closed form),
    /// each with whether it is within the limits and reaches, instead of the one nearest the seed.
    #[arg(long, conflicts_with = "batch")]
    all_solutions: bool,
    /// Scalar the solver runs in.
    #[arg(long, value_parser = crate::cli::values::scalar(), default_value = "f64")]
    scalar: Scalar,
    /// Position tolerance (m); default 1e-5 in f64, 1e-4 in f32. KDL calls it eps.
    #[arg(long, visible_alias = "tolerance")]
    position_tolerance: Option<f64>,
    /// Orientation tolerance (rad); default 1e-5 in f64, 1e-3 in f32.
    #[arg(long)]
    orientation_tolerance: Option<f64>,
    /// Metres of position error one radian of orientation error is worth in the residual.
    #[arg(long, default_value_t = 1.0)]
    orientation_weight: f64,
    /// A tree's priority mode: the end effectors (NAME,NAME...) whose targets are met first; the
    /// other targets only in the null space those leave, as far as they can be without
    /// disturbing them. Without it every target weighs alike.
    #[arg(long)]
    priority: Option<String>,
    /// Iteration budget over all restarts [default: 1000; for a tree 6000].
    #[arg(long)]
    max_iterations: Option<u32>,
    /// Changes nothing: every result is one line of JSON already.
    #[arg(long)]
    pub(super) json: bool,
}

/// A chain's iteration budget unless `--max-iterations` is given.
const CHAIN_MAX_ITERATIONS: u32 = 1000;

/// The solver's settings from the options; `max_iterations` is the budget where
/// `--max-iterations` is not given.
fn config(args: &IkArgs, max_iterations: u32) -> Result<IkConfig<f64>> {
    let (p, o) = args.scalar.default_tolerances();
    let config = IkConfig {
        position_tolerance: args.position_tolerance.unwrap_or(p),
        orientation_tolerance: args.orientation_tolerance.unwrap_or(o),
        orientation_weight: args.orientation_weight,
        max_iterations: args.max_iterations.unwrap_or(max_iterations),
        ..IkConfig::default()
    };
    let positive = |v: f64| v.is_finite() && v > 0.0;
    if !(positive(config.position_tolerance) && positive(config.orientation_tolerance)) {
        bail!("tolerances must be positive finite numbers");
    }
    if !positive(config.orientation_weight) {
        bail!("--orientation-weight must be a positive finite number");
    }
    Ok(config)
}

/// One result as printed: the fields in alphabetical order, as `serde_json`'s maps print them.
/// `line` only in a batch; `reason` only for a refused input, whose errors are `null` (nothing was
/// solved); `orientation_error` is `null` for a position-only target.
#[derive(Serialize)]
struct Printed<'a> {
    iterations: u32,
    #[serde(skip_serializing_if = "Option::is_none")]
    line: Option<usize>,
    orientation_error: Option<f64>,
    position_error: Option<f64>,
    q: &'a [f64],
    #[serde(skip_serializing_if = "Option::is_none")]
    reason: Option<String>,
    restarts: u32,
    /// The method that answered ("analytic", "dls", ...).
    solver: &'static str,
    status: &'static str,
}

fn printed(outcome: &IkOutcome, position_only: bool, line: Option<usize>) -> Printed<'_> {
    let refused = match outcome.status {
        IkStatus::InvalidInput(reason) => Some(reason.to_string()),
        _ => None,
    };
    let solved = refused.is_none();
    Printed {
        iterations: outcome.iterations,
        line,
        orientation_error: (solved && !position_only).then_some(outcome.orientation_error),
        position_error: solved.then_some(outcome.position_error),
        q: &outcome.q,
        reason: refused,
        restarts: outcome.restarts,
        solver: outcome.method,
        status: outcome.status.as_str(),
    }
}

/// The one-line complaint for an outcome the solver refused (input that passed the f64 checks
/// here but not the solver's, e.g. a value that overflows f32), or `None`.
fn refusal(outcome: &IkOutcome, scalar: Scalar) -> Option<String> {
    match outcome.status {
        IkStatus::InvalidInput(reason) => Some(format!("the solver refused the input in {scalar:?}: {reason}")),
        _ => None,
    }
}

/// Runs `armctl ik`; returns the exit code.
pub(crate) fn run(args: &IkArgs, out: &mut dyn Write, err: &mut dyn Write) -> Result<i32> {
    let started = Instant::now();
    let arm = match load_body(&args.arm)? {
        Loaded::Chain(arm) => arm,
        Loaded::Tree(tree) => return run_tree(&tree, args, out, err),
    };
    let config = config(args, CHAIN_MAX_ITERATIONS)?;
    if args.priority.is_some() {
        bail!(
            "--priority ranks the targets of a tree's end effectors; arm {} is a chain with one tool",
            arm.spec().name
        );
    }
    if args.target.len() > 1 {
        bail!(
            "--target is given {} times; arm {} is a chain with one tool (several --target NAME=... are for a tree: a \
             URDF with several leaves, without --tip)",
            args.target.len(),
            arm.spec().name
        );
    }
    let request = |position, quaternion_wxyz, seed| IkRequest {
        position,
        quaternion_wxyz,
        seed,
        solver: args.solver,
        config,
        scalar: args.scalar,
        tilt_only: false,
    };
    let Some(batch) = &args.batch else {
        // `target` is required by clap whenever `batch` is absent.
        let position = parse::fixed::<3>(args.target.first().map(String::as_str).unwrap_or_default(), "--target")?;
        let quat = args.quat.as_deref().map(|q| parse::fixed::<4>(q, "--quat")).transpose()?;
        let seed = args.seed.as_deref().map(|s| parse::numbers(s, "--seed")).transpose()?;
        if args.all_solutions {
            if args.scalar == Scalar::F32 {
                bail!("--all-solutions: the closed form runs in f64 (leave out --scalar f32)");
            }
            return all_solutions(&*arm, &request(position, quat, seed), out);
        }
        let outcome = arm.solve(&request(position, quat, seed))?;
        print_json(out, &printed(&outcome, quat.is_none(), None))?;
        if let Some(complaint) = refusal(&outcome, args.scalar) {
            writeln!(err, "error: {complaint}")?;
            return Ok(1);
        }
        return Ok(0);
    };

    let source: Box<dyn Read + Send> = if batch == "-" {
        Box::new(std::io::stdin())
    } else {
        Box::new(std::fs::File::open(batch).with_context(|| format!("cannot open batch file {batch}"))?)
    };
    // One write per 64 KiB rather than per line (a terminal's stdout is line-buffered).
    let mut out = std::io::BufWriter::with_capacity(1 << 16, out);
    let mut times = Vec::new();
    let (mut solved, mut rejected, mut lines) = (0usize, 0usize, 0usize);
    // Three stages, each on its own thread: reading and parsing, solving, and here printing, so
    // that the solver does nothing else.
    std::thread::scope(|scope| -> Result<()> {
        let parsed = json_lines::spawn::<BatchTarget, _>(scope, source);
        let (answers, answered) = sync_channel(json_lines::IN_FLIGHT);
        let (arm, request) = (&*arm, &request);
        scope.spawn(move || solve_lines(arm, request, parsed, &answers));
        loop {
            let chunk = match answered.try_recv() {
                Ok(chunk) => chunk,
                // The results so far go out before waiting for more: a program that writes a
                // target and waits for its answer gets it.
                Err(TryRecvError::Empty) => {
                    out.flush()?;
                    match answered.recv() {
                        Ok(chunk) => chunk,
                        Err(_) => return Ok(()),
                    }
                }
                Err(TryRecvError::Disconnected) => return Ok(()),
            };
            for answer in chunk {
                lines += 1;
                match answer {
                    Answer::Solved { number, outcome, position_only } => {
                        print_json(&mut out, &printed(&outcome, position_only, Some(number)))?;
                        match refusal(&outcome, args.scalar) {
                            Some(complaint) => {
                                rejected += 1;
                                writeln!(err, "error: {batch}: line {number}: {complaint}")?;
                            }
                            None => {
                                times.push(outcome.solve_time);
                                solved += usize::from(outcome.status == IkStatus::Converged);
                            }
                        }
                    }
                    Answer::Bad { number, message } => {
                        rejected += 1;
                        let message = format!("line {number}: {message}");
                        writeln!(err, "error: {batch}: {message}")?;
                        print_json(&mut out, &json!({"line": number, "error": message}))?;
                    }
                    Answer::Unreadable { number, error } => {
                        return Err(anyhow::Error::from(error).context(format!("{batch}: cannot read line {number}")))
                    }
                }
            }
        }
    })?;
    out.flush()?;
    let total = times.len() + rejected;
    let solves = times.len();
    let bench::SolveTimes { mean_us: mean, median_us: median, p99_us: p99 } = bench::SolveTimes::of(&mut times);
    // End to end: from the start of the command (arm loaded, file opened) to the last line written.
    let per_line = started.elapsed().as_secs_f64() * 1e6 / lines.max(1) as f64;
    let overhead = per_line - mean * solves as f64 / lines.max(1) as f64;
    writeln!(
        err,
        "{}: {solved}/{total} converged ({:.2}%), {rejected} rejected lines; per solve mean {mean:.2} us, median \
         {median:.2} us, p99 {p99:.2} us; end to end {per_line:.2} us per line, of which {overhead:.2} us \
         reading, writing and set-up",
        arm.spec().name,
        100.0 * solved as f64 / total.max(1) as f64
    )?;
    Ok(if rejected > 0 { 1 } else { 0 })
}

/// `armctl ik` on a tree: the options a tree's solve has no use for are refused, not ignored.
fn run_tree(tree: &DynTree, args: &IkArgs, out: &mut dyn Write, err: &mut dyn Write) -> Result<i32> {
    let name = &tree.spec().name;
    let one_per_target = "one --target NAME=x,y,z[,qw,qx,qy,qz] per end effector";
    if args.batch.is_some() {
        bail!("--batch is for chains; tree {name} takes its targets on the command line, {one_per_target}");
    }
    if args.quat.is_some() {
        bail!("--quat is for chains; a tree's target carries its own quaternion, {one_per_target}");
    }
    if args.all_solutions {
        bail!("--all-solutions lists a chain's closed-form solutions; tree {name} has no closed form");
    }
    if args.scalar == Scalar::F32 {
        bail!("--scalar f32: tree {name} is solved in f64 only");
    }
    if !matches!(args.solver, SolverName::Auto | SolverName::Dls) {
        bail!("--solver: tree {name} is solved by damped least squares over every target (auto or dls)");
    }
    let request = TreeIk {
        targets: &args.target,
        seed: args.seed.as_deref(),
        priority: args.priority.as_deref(),
        config: config(args, dyn_tree::DEFAULT_MAX_ITERATIONS)?,
    };
    tree::ik(tree, request, out, err)
}

/// `ik --all-solutions`: every closed-form solution, and the time they took together.
fn all_solutions(arm: &dyn DynArm, request: &IkRequest, out: &mut dyn Write) -> Result<i32> {
    let (solutions, took) = arm.all_solutions(request)?;
    let listed: Vec<_> = solutions
        .iter()
        .map(|s| {
            json!({
                "q": s.q,
                "within_limits": s.within_limits,
                "exact": s.exact,
                "reaches": s.reaches,
                "position_error": s.position_error,
                "orientation_error": s.orientation_error,
                "singular": s.singular.map(|s| s.as_str()),
            })
        })
        .collect();
    print_json(
        out,
        &json!({
            "shape": arm.closed_form_shape().map(|s| s.as_str()),
            "solutions": listed,
            "reaching_within_limits": solutions.iter().filter(|s| s.within_limits && s.reaches).count(),
            "solve_time_us": took.as_secs_f64() * 1e6,
        }),
    )?;
    Ok(0)
}

/// What became of one line of an `ik --batch` file, in the solver's thread.
enum Answer {
    /// Solved (or refused by the solver, which the outcome says).
    Solved { number: usize, outcome: IkOutcome, position_only: bool },
    /// Not a target, or one that cannot be posed (a seed of the wrong length).
    Bad { number: usize, message: String },
    /// The input could not be read here; nothing follows.
    Unreadable { number: usize, error: std::io::Error },
}

/// The solving stage of `ik --batch`: every parsed line in, one answer each out, chunk for chunk.
fn solve_lines(
    arm: &dyn DynArm,
    request: &(impl Fn([f64; 3], Option<[f64; 4]>, Option<Vec<f64>>) -> IkRequest + Sync),
    lines: Receiver<Vec<Line<BatchTarget>>>,
    answers: &SyncSender<Vec<Answer>>,
) {
    for chunk in lines {
        let answered = chunk
            .into_iter()
            .map(|Line { number, parsed }| match parsed {
                Parsed::Value(t) => match arm.solve(&request(t.position, t.quaternion_wxyz, t.seed)) {
                    Ok(outcome) => Answer::Solved { number, outcome, position_only: t.quaternion_wxyz.is_none() },
                    Err(e) => Answer::Bad { number, message: format!("{e:#}") },
                },
                Parsed::Invalid(e) => Answer::Bad { number, message: e.to_string() },
                Parsed::Unreadable(error) => Answer::Unreadable { number, error },
            })
            .collect();
        if answers.send(answered).is_err() {
            return;
        }
    }
}

/// One line of an `ik --batch` file.
#[derive(Deserialize, Debug)]
#[serde(deny_unknown_fields)]
struct BatchTarget {
    position: [f64; 3],
    #[serde(default)]
    quaternion_wxyz: Option<[f64; 4]>,
    #[serde(default)]
    seed: Option<Vec<f64>>,
}
