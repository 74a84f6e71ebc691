//! The `armctl` command line: argument parsing and the commands, writing JSON to `out`.
//!
//! Every failure is one line on `err` starting with `error:` and a non-zero exit code.

use crate::arm::ArmSpec;
use crate::bench::{self, Protocol};
use crate::dof::{self, DynArm, IkOutcome, IkRequest, Scalar, SolverName};
use crate::parse;
use crate::trajectory;
use anyhow::{bail, Context, Result};
use clap::{Args, Parser, Subcommand};
use kinematics::ik::{IkConfig, IkStatus};
use serde::Deserialize;
use serde_json::{json, Value};
use std::ffi::OsString;
use std::io::{BufRead, Write};

/// Kinematics, inverse kinematics and benchmarks for serial-bus-servo arms.
#[derive(Parser, Debug)]
#[command(name = "armctl", version, about)]
struct Cli {
    #[command(flatten)]
    link: crate::drive::cli::LinkArgs,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// The whole product without hardware: a simulated arm driven through the firmware in
    /// software in the loop, to Cartesian targets and along a streamed pick-and-place path.
    Demo(crate::demo::DemoArgs),
    /// Forward kinematics: tool pose and every joint frame for joint values.
    Fk {
        #[command(flatten)]
        arm: ArmArgs,
        /// Joint values, comma-separated (radians, metres for prismatic joints).
        #[arg(long, allow_hyphen_values = true)]
        q: String,
    },
    /// The 6 x N geometric Jacobian (rows linear x, y, z then angular x, y, z).
    Jacobian {
        #[command(flatten)]
        arm: ArmArgs,
        /// Joint values, comma-separated.
        #[arg(long, allow_hyphen_values = true)]
        q: String,
    },
    /// Inverse kinematics for one target, or for every line of a JSON-lines file.
    Ik(IkArgs),
    /// Benchmarks.
    Bench {
        #[command(subcommand)]
        what: BenchCommand,
    },
    /// Flash, static RAM, panic paths and stack depth of each board binary, against the goals.
    Footprint(crate::footprint::FootprintArgs),
    /// Simulated servo buses (served on a pseudo-terminal), or the firmware under QEMU (--qemu).
    Sim(crate::sim::cli::SimArgs),
    /// Joint trajectories through keyframes.
    Trajectory {
        #[command(subcommand)]
        what: TrajectoryCommand,
    },
    /// Serial bus servo set-up on a real port: scan, read, write, set-id, set-baud, torque.
    Servo(crate::servo::cli::ServoArgs),
    /// Driving an arm (after --port PORT or --sim): move, joints, play, status, stop, torque.
    #[command(flatten)]
    Drive(crate::drive::cli::DriveCommand),
}

#[derive(Subcommand, Debug)]
enum TrajectoryCommand {
    /// Interpolate a keyframe CSV file and sample it at a fixed rate (CSV `t,q...,v...,a...` or
    /// --json on stdout).
    Sample(trajectory::SampleArgs),
}

#[derive(Subcommand, Debug)]
enum BenchCommand {
    /// The IK solve-rate protocol: random reachable full-pose targets, seed at mid-range.
    Ik {
        #[command(flatten)]
        arm: ArmArgs,
        /// Number of targets.
        #[arg(long, default_value_t = 10_000)]
        n: usize,
        /// Scalar of our solver (tolerances 1e-5 in f64, 1e-4 m / 1e-3 rad in f32).
        #[arg(long, value_enum, default_value = "f64")]
        scalar: Scalar,
        /// Seed of the target sampler.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Skip the `k` crate's solver.
        #[arg(long)]
        no_k: bool,
    },
    /// Wire time of one control cycle (sync write goals + sync read positions), computed and
    /// simulated with the firmware's cycle against simulated servos.
    Bus(crate::bench_bus::BusBenchArgs),
    /// Control rate of the firmware's controller (6 servos, a joint move in progress) against
    /// simulated servos on the virtual clock, ticking back to back and on its fixed period,
    /// compared with the bus's wire-time limit. Compute time is free on the virtual clock.
    Rate(crate::bench_rate::RateBenchArgs),
    /// Instructions per operation on the Cortex-M4F (FK, IK, player tick, bus packets), counted by
    /// the firmware's `opcount` binary under `qemu-system-arm -icount shift=0`.
    Mcu(crate::bench_mcu::McuBenchArgs),
}

#[derive(Args, Debug)]
struct ArmArgs {
    /// Arm: a preset name or a path to a .urdf or .toml arm file.
    #[arg(long)]
    arm: String,
    /// Tip link of a URDF arm (needed when the URDF tree has several leaves).
    #[arg(long)]
    tip: Option<String>,
}

#[derive(Args, Debug)]
struct IkArgs {
    #[command(flatten)]
    arm: ArmArgs,
    /// Target tool position x,y,z (m).
    #[arg(long, allow_hyphen_values = true, required_unless_present = "batch", conflicts_with = "batch")]
    target: Option<String>,
    /// Target orientation as a unit quaternion w,x,y,z (omit for a position-only target).
    #[arg(long, allow_hyphen_values = true, conflicts_with = "batch")]
    quat: Option<String>,
    /// Seed joint values (default: the middle of each joint's limits).
    #[arg(long, allow_hyphen_values = true, conflicts_with = "batch")]
    seed: Option<String>,
    /// JSON-lines file of targets (`-` for standard input); one result line each on stdout.
    #[arg(long)]
    batch: Option<String>,
    /// Method.
    #[arg(long, value_enum, default_value = "dls")]
    solver: SolverName,
    /// Scalar the solver runs in.
    #[arg(long, value_enum, default_value = "f64")]
    scalar: Scalar,
    /// Position tolerance (m); default 1e-5 in f64, 1e-4 in f32.
    #[arg(long)]
    position_tolerance: Option<f64>,
    /// Orientation tolerance (rad); default 1e-5 in f64, 1e-3 in f32.
    #[arg(long)]
    orientation_tolerance: Option<f64>,
    /// Metres of position error one radian of orientation error is worth in the residual.
    #[arg(long, default_value_t = 1.0)]
    orientation_weight: f64,
    /// Iteration budget over all restarts.
    #[arg(long, default_value_t = 1000)]
    max_iterations: u32,
}

/// Runs `armctl` with `args` (program name first); returns the exit code.
pub fn main<I, T>(args: I, out: &mut dyn Write, err: &mut dyn Write) -> i32
where
    I: IntoIterator<Item = T>,
    T: Into<OsString> + Clone,
{
    let cli = match Cli::try_parse_from(args) {
        Ok(cli) => cli,
        Err(e) => {
            use clap::error::ErrorKind;
            if matches!(e.kind(), ErrorKind::DisplayHelp | ErrorKind::DisplayVersion) {
                let _ = write!(out, "{e}");
                return 0;
            }
            if e.kind() == ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand {
                // `armctl` or `armctl bench` alone: say so in one line, like every other error.
                let _ = writeln!(err, "error: a command is missing (see armctl --help)");
                return 2;
            }
            // clap's own rendering spans several lines; its first paragraph (joined into one line
            // here, as it lists missing arguments on lines of their own) says what is wrong.
            let text = e.to_string();
            let first = text.split("\n\n").next().unwrap_or_default().split_whitespace().collect::<Vec<_>>().join(" ");
            let _ = writeln!(err, "{first} (see armctl --help)");
            return 2;
        }
    };
    match run(&cli.link, cli.command, out, err) {
        Ok(code) => code,
        // The reader closed the pipe (`armctl ... | head`): it has what it wanted.
        Err(e) if e.downcast_ref::<std::io::Error>().is_some_and(|io| io.kind() == std::io::ErrorKind::BrokenPipe) => 0,
        Err(e) => {
            let _ = writeln!(err, "error: {e:#}");
            1
        }
    }
}

fn load(arm: &ArmArgs) -> Result<Box<dyn DynArm>> {
    dof::build(ArmSpec::load(&arm.arm, arm.tip.as_deref())?)
}

fn run(link: &crate::drive::cli::LinkArgs, command: Command, out: &mut dyn Write, err: &mut dyn Write) -> Result<i32> {
    if !matches!(command, Command::Drive(_)) {
        link.refuse_for_other_commands()?;
    }
    match command {
        Command::Drive(command) => return crate::drive::cli::run(link, command, out, err),
        Command::Demo(args) => return crate::demo::run(&args, out),
        Command::Fk { arm, q } => {
            let arm = load(&arm)?;
            let q = parse::numbers(&q, "--q")?;
            let tool = arm.tool_pose(&q)?;
            let frames: Vec<Value> = arm
                .joint_frames(&q)?
                .iter()
                .zip(&arm.spec().joints)
                .map(|(p, j)| json!({"joint": j.name, "position": vec3(p), "quaternion_wxyz": p.quaternion_wxyz()}))
                .collect();
            let rotation: Vec<[f64; 3]> =
                (0..3).map(|r| [tool.rotation[(r, 0)], tool.rotation[(r, 1)], tool.rotation[(r, 2)]]).collect();
            print_json(
                out,
                &json!({
                    "arm": arm.spec().name,
                    "position": vec3(&tool),
                    "quaternion_wxyz": tool.quaternion_wxyz(),
                    "rotation": rotation,
                    "frames": frames,
                }),
            )?;
        }
        Command::Jacobian { arm, q } => {
            let arm = load(&arm)?;
            let q = parse::numbers(&q, "--q")?;
            print_json(out, &json!({"arm": arm.spec().name, "jacobian": arm.jacobian(&q)?}))?;
        }
        Command::Ik(args) => return ik(&args, out, err),
        Command::Bench { what: BenchCommand::Bus(args) } => return crate::bench_bus::run(&args, out),
        Command::Bench { what: BenchCommand::Rate(args) } => return crate::bench_rate::run(&args, out),
        Command::Footprint(args) => return crate::footprint::run(&args, out, err),
        Command::Bench { what: BenchCommand::Mcu(args) } => return crate::bench_mcu::run(&args, out),
        Command::Servo(args) => return crate::servo::cli::run(args, out, err),
        Command::Sim(args) => return crate::sim::cli::run(args, out, err),
        Command::Trajectory { what: TrajectoryCommand::Sample(args) } => {
            return trajectory::run_sample(&args, out, err)
        }
        Command::Bench { what: BenchCommand::Ik { arm, n, scalar, seed, no_k } } => {
            if n == 0 {
                bail!("--n must be at least 1");
            }
            let arm = load(&arm)?;
            let report = bench::run(arm.as_ref(), &Protocol { n, scalar, seed, with_k: !no_k })?;
            for s in &report.solvers {
                writeln!(
                    err,
                    "{} ({} protocol, {:e} m / {:e} rad): {}: {}/{} solved ({:.2}%), mean {:.2} us, median {:.2} us, \
                     p99 {:.2} us per solve",
                    report.arm,
                    report.scalar,
                    report.position_tolerance,
                    report.orientation_tolerance,
                    s.solver,
                    s.solved,
                    s.targets,
                    s.success_percent,
                    s.mean_us,
                    s.median_us,
                    s.p99_us
                )?;
            }
            print_json(out, &serde_json::to_value(&report)?)?;
        }
    }
    Ok(0)
}

fn vec3(p: &kinematics::Pose<f64>) -> [f64; 3] {
    p.translation.into()
}

fn print_json(out: &mut dyn Write, v: &Value) -> Result<()> {
    writeln!(out, "{v}")?;
    Ok(())
}

fn config(args: &IkArgs) -> Result<IkConfig<f64>> {
    let (p, o) = args.scalar.default_tolerances();
    let config = IkConfig {
        position_tolerance: args.position_tolerance.unwrap_or(p),
        orientation_tolerance: args.orientation_tolerance.unwrap_or(o),
        orientation_weight: args.orientation_weight,
        max_iterations: args.max_iterations,
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

fn outcome_json(outcome: &IkOutcome, position_only: bool) -> Value {
    let mut v = json!({
        "q": outcome.q,
        "status": outcome.status.as_str(),
        "iterations": outcome.iterations,
        "restarts": outcome.restarts,
        "position_error": outcome.position_error,
        "orientation_error": if position_only { Value::Null } else { json!(outcome.orientation_error) },
    });
    if let IkStatus::InvalidInput(reason) = outcome.status {
        // Nothing was solved, so there are no errors to report.
        v["reason"] = json!(reason.to_string());
        v["position_error"] = Value::Null;
        v["orientation_error"] = Value::Null;
    }
    v
}

/// The one-line complaint for an outcome the solver refused (input that passed the f64 checks
/// here but not the solver's, e.g. a value that overflows f32), or `None`.
fn refusal(outcome: &IkOutcome, scalar: Scalar) -> Option<String> {
    match outcome.status {
        IkStatus::InvalidInput(reason) => Some(format!("the solver refused the input in {scalar:?}: {reason}")),
        _ => None,
    }
}

fn ik(args: &IkArgs, out: &mut dyn Write, err: &mut dyn Write) -> Result<i32> {
    let arm = load(&args.arm)?;
    let config = config(args)?;
    let request = |position, quaternion_wxyz, seed| IkRequest {
        position,
        quaternion_wxyz,
        seed,
        solver: args.solver,
        config,
        scalar: args.scalar,
    };
    let Some(batch) = &args.batch else {
        // `target` is required by clap whenever `batch` is absent.
        let position = parse::fixed::<3>(args.target.as_deref().unwrap_or_default(), "--target")?;
        let quat = args.quat.as_deref().map(|q| parse::fixed::<4>(q, "--quat")).transpose()?;
        let seed = args.seed.as_deref().map(|s| parse::numbers(s, "--seed")).transpose()?;
        let outcome = arm.solve(&request(position, quat, seed))?;
        print_json(out, &outcome_json(&outcome, quat.is_none()))?;
        if let Some(complaint) = refusal(&outcome, args.scalar) {
            writeln!(err, "error: {complaint}")?;
            return Ok(1);
        }
        return Ok(0);
    };

    let reader: Box<dyn BufRead> = if batch == "-" {
        Box::new(std::io::BufReader::new(std::io::stdin()))
    } else {
        let file = std::fs::File::open(batch).with_context(|| format!("cannot open batch file {batch}"))?;
        Box::new(std::io::BufReader::new(file))
    };
    let mut times = Vec::new();
    let (mut solved, mut rejected) = (0usize, 0usize);
    for (index, line) in reader.lines().enumerate() {
        let line_number = index + 1;
        let line = line.with_context(|| format!("{batch}: cannot read line {line_number}"))?;
        if line.trim().is_empty() {
            continue;
        }
        let result = serde_json::from_str::<BatchTarget>(&line)
            .map_err(anyhow::Error::from)
            .and_then(|t| arm.solve(&request(t.position, t.quaternion_wxyz, t.seed)).map(|o| (o, t.quaternion_wxyz)));
        match result {
            Ok((outcome, quat)) => {
                let mut v = outcome_json(&outcome, quat.is_none());
                v["line"] = json!(line_number);
                print_json(out, &v)?;
                match refusal(&outcome, args.scalar) {
                    Some(complaint) => {
                        rejected += 1;
                        writeln!(err, "error: {batch}: line {line_number}: {complaint}")?;
                    }
                    None => {
                        times.push(outcome.solve_time);
                        solved += usize::from(outcome.status == IkStatus::Converged);
                    }
                }
            }
            Err(e) => {
                rejected += 1;
                let message = format!("line {line_number}: {e:#}");
                writeln!(err, "error: {batch}: {message}")?;
                print_json(out, &json!({"line": line_number, "error": message}))?;
            }
        }
    }
    let total = times.len() + rejected;
    let bench::SolveTimes { mean_us: mean, p99_us: p99, .. } = bench::SolveTimes::of(&mut times);
    writeln!(
        err,
        "{}: {solved}/{total} converged ({:.2}%), {rejected} rejected lines; mean {mean:.2} us, p99 {p99:.2} us per solve",
        arm.spec().name,
        100.0 * solved as f64 / total.max(1) as f64
    )?;
    Ok(if rejected > 0 { 1 } else { 0 })
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
