//! The `armctl` command line: argument parsing and the commands, writing JSON to `out`.
//!
//! Every failure is one line on `err` starting with `error:` and a non-zero exit code.

mod bench;
pub mod bus_args;
mod calibrate;
pub mod collision;
mod demo;
mod doctor;
pub mod drive;
mod footprint;
mod ik;
pub mod link;
pub mod retarget;
pub mod serve;
pub mod servo;
pub mod sim;
mod teleop;
mod trajectory;
mod tree;
pub mod values;
pub mod view;

use crate::arm::body::Body;
use crate::arm::dof::{self, DynArm, Scalar};
use crate::arm::dyn_tree::DynTree;
use crate::arm::ArmSpec;
use crate::commands::bench::ik::{self as ik_bench, Protocol};
use crate::support::numbers as parse;
use anyhow::{bail, Result};
use clap::{Args, CommandFactory, FromArgMatches, Parser, Subcommand};
use link::LinkArgs;
use serde_json::{json, Value};
use std::ffi::OsString;
use std::io::Write;

/// armctl drives arms of serial bus servos (Dynamixel Protocol 2.0, Feetech STS/SCS) through the
/// firmware core: simulated on this PC (--sim), on a board running the firmware (--port), or with
/// this PC as the board, on the servos' USB adapter (--bus). It sets up, calibrates, teleoperates
/// and checks the servos and the arm, and has kinematics, simulation and firmware tools.
#[derive(Parser, Debug)]
#[command(
    name = "armctl",
    version,
    after_help = "The drive options (all but --json) are for the commands that drive an arm; before another command, \
                  each goes to that command's option of the same name where it has one. Every command takes --json. \
                  `armctl COMMAND --help` tells what a command does, its options and what it prints."
)]
struct Cli {
    #[command(flatten)]
    link: LinkArgs,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// The whole product without hardware: a simulated arm driven through the firmware core
    ///
    /// Software in the loop on a virtual clock: the arm goes to Cartesian targets and along a
    /// streamed pick-and-place path, then the report (--json: one line of JSON) and a plot
    /// (demo-ARM.png unless --plot or --no-plot). With --rig: two simulated arms hand an object
    /// over.
    Demo(demo::DemoArgs),
    /// Forward kinematics: the tool's pose and every joint's frame for joint values (JSON)
    ///
    /// For a tree (a URDF with several leaves and no --tip), every end effector's pose.
    Fk {
        #[command(flatten)]
        arm: ArmArgs,
        /// Joint values, comma-separated (radians, metres for prismatic joints).
        #[arg(long, allow_hyphen_values = true)]
        q: String,
        /// Changes nothing: the output is one line of JSON already.
        #[arg(long)]
        json: bool,
    },
    /// The 6 x N geometric Jacobian at joint values (JSON)
    ///
    /// Rows linear x, y, z then angular x, y, z; one column per joint. For a tree (a URDF with
    /// several leaves and no --tip), each end effector's, over every joint of the tree.
    Jacobian {
        #[command(flatten)]
        arm: ArmArgs,
        /// Joint values, comma-separated (radians, metres for prismatic joints).
        #[arg(long, allow_hyphen_values = true)]
        q: String,
        /// Changes nothing: the output is one line of JSON already.
        #[arg(long)]
        json: bool,
    },
    /// Inverse kinematics for one target, or for every line of a JSON-lines file (JSON lines)
    Ik(ik::IkArgs),
    /// Benchmarks: IK solve rate, bus wire time, control rate, instructions on the MCU, the main
    /// loop's longest pass, the core on this PC
    Bench {
        #[command(subcommand)]
        what: BenchCommand,
    },
    /// Flash, static RAM, panic paths and stack depth of each board binary, against the goals
    ///
    /// Builds the board binaries (or reads --elf) and measures the stack under QEMU unless
    /// --no-qemu. Needs an armctl built with the board-tools feature.
    Footprint(footprint::FootprintArgs),
    /// Simulated servos on a pseudo-terminal (sim servos), or the firmware under QEMU (sim --qemu)
    Sim(sim::SimArgs),
    /// Joint trajectories through keyframes: sampled at a fixed rate (trajectory sample)
    Trajectory {
        #[command(subcommand)]
        what: TrajectoryCommand,
    },
    /// The serial ports with the USB device behind each: which one is the arm's adapter
    ///
    /// One line per port: its path, vendor:product id, maker, product, serial number and
    /// /dev/serial/by-id name.
    Ports {
        /// One JSON array (one line) instead of a line per port.
        #[arg(long)]
        json: bool,
    },
    /// Keep one firmware core running on this PC, its host link on a pseudo-terminal for --port
    ///
    /// Servos on a USB adapter with --bus, simulated with --sim. Prints the pty's path on the first
    /// line of stdout (--json: {"pty": PATH}); consecutive `armctl --port PTY` commands then drive
    /// one arm whose state persists. Ctrl-C stops the arm, then exits.
    Serve(serve::ServeArgs),
    /// Serial bus servos on a port: scan, read, write, set-id, set-baud, calibration, torque
    Servo(crate::cli::servo::ServoArgs),
    /// What is wrong with a servo bus (--bus PORT): one line per finding, OK, WARN or FAIL, with the fix
    ///
    /// Ids, models, firmware, supply, temperature, error flags, return delay, the adapter's echo
    /// and latency, lost replies, stale goals, the calibration, whether a control cycle fits.
    /// Writes nothing unless --fix. Scans both protocols at the usual baud rates when --protocol
    /// and --baud are not given.
    Doctor(doctor::DoctorArgs),
    /// Calibrate an arm's servos as LeRobot does, each step answered with a line on stdin
    ///
    /// Homing offsets at the middle of each joint's range, the ranges moved through by hand as
    /// position limits. Writes the servos, an arm file (--out) and LeRobot's file
    /// (--lerobot-json).
    Calibrate {
        #[command(flatten)]
        args: calibrate::CalibrateArgs,
        /// The dialog (steps, live table, results) on stderr instead, and on stdout one line of
        /// JSON once done: the files written, each joint's limits (rad) and the calibration as
        /// LeRobot's file has it.
        #[arg(long)]
        json: bool,
    },
    /// A human arm from a BVH motion-capture file onto the arm, as keyframes; --play streams them
    ///
    /// Joint keyframes for `armctl play` (--out), the hand's and the tool's paths (--plot) and
    /// tracking figures (one line of JSON); --play streams them to the arm (its report a second
    /// JSON line). With --rig RIG: the human's arms onto every arm of the rig, one keyframe file
    /// for all.
    Retarget(retarget::RetargetArgs),
    /// Teleoperation: a leader arm moved by hand drives the follower (--port, --bus or --sim)
    ///
    /// The leader's servos (torque off) are read by sync read and mapped through both
    /// calibrations to keyframes the follower's firmware plays within its limits. Reports the
    /// loop's rate and latency (--json: one line of JSON); --record writes the session as a
    /// keyframe file for `armctl play`.
    Teleop(teleop::TeleopArgs),
    /// The arm live in a browser, and the same as a JSON API: prints the page's URL
    ///
    /// A local page with the arm in 3D, joint sliders, a target to drag (IK preview, then the
    /// move on the firmware), telemetry, keyframe files, stop and torque. Prints the page's URL
    /// on the first line (--json: {"url": URL}); opens no browser. Drives --sim (the default, in
    /// real time), --port or --bus; --rig, every arm of a rig.
    View(view::ViewArgs),
    /// The arm's collision geometry: fit it from a URDF (collision fit), check joint values
    /// against it (collision check)
    Collision(collision::CollisionArgs),
    // The drive commands (move, joints, play, status, stop, torque, gripper), each with the drive
    // options before or after it.
    #[command(flatten)]
    Drive(drive::DriveCommand),
}

#[derive(Subcommand, Debug)]
enum TrajectoryCommand {
    /// Interpolate a keyframe CSV file and sample it at a fixed rate (CSV `t,q...,v...,a...` on
    /// stdout, or one line of JSON with --json).
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
        #[arg(long, value_parser = crate::cli::values::scalar(), default_value = "f64")]
        scalar: Scalar,
        /// Seed of the target sampler.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Skip the `k` crate's solver (run only when built with `--features compare-k`).
        #[arg(long)]
        no_k: bool,
        /// Changes nothing: the report on stdout is one line of JSON already (the summary lines
        /// go to stderr).
        #[arg(long)]
        json: bool,
    },
    /// Wire time of one control cycle (sync write goals + sync read positions), computed and
    /// simulated with the firmware's cycle against simulated servos.
    Bus(bench::BusBenchArgs),
    /// Control rate of the firmware's controller (6 servos, a joint move in progress) against
    /// simulated servos on the virtual clock, ticking back to back and on its fixed period,
    /// compared with the bus's wire-time limit. Compute time is free on the virtual clock.
    Rate(bench::RateBenchArgs),
    /// Instructions per operation on the Cortex-M4F (FK, IK, player tick, bus packets), counted by
    /// the firmware's `opcount` binary under `qemu-system-arm -icount shift=0`.
    Mcu(bench::McuBenchArgs),
    /// The main loop's longest pass (every servo silent, the link flooded with status requests),
    /// measured on the MPS2 under QEMU at two -icount shifts, scaled to the STM32F411 at 84 MHz and
    /// checked against its watchdog's shortest timeout; exits 1 when the margin is not met.
    LoopPass(bench::LoopPassBenchArgs),
    /// Control rate and bus time per tick of the firmware core hosted on this PC (as --bus runs it) against
    /// simulated servos on a pseudo-terminal in real time, with or without a USB adapter's burst
    /// latency.
    Pc(bench::PcBenchArgs),
    /// Planning around obstacles on the host: time (median, p99) over blocked moves between random
    /// free configurations, with the arm on its table and a box in front of it, and one full
    /// collision check's time.
    Plan(bench::PlanBenchArgs),
    /// The simulator's physical servos (docs/servo-model.md): wall time per servo per step with
    /// physics against ideal servos, on an arm moving between random configurations.
    Servos(bench::ServosBenchArgs),
}

#[derive(Args, Debug)]
pub(crate) struct ArmArgs {
    /// Arm: a preset (so101, open-manipulator-x, ur5e, puma560, iiwa14, planar:N) or a .urdf or
    /// .toml arm file (required; may come before the command too).
    #[arg(long)]
    arm: Option<String>,
    /// Tip link of a URDF arm: the chain to it. Without it, a URDF with several leaves is a tree
    /// (fk, jacobian and ik answer for every end effector; other commands need --tip).
    #[arg(long)]
    tip: Option<String>,
}

/// The commands by what a person does with them, in the order `armctl --help` lists them. Each
/// command's line there is its own short help, read from clap when the help is shown, so that it
/// is written once.
pub const GROUPS: &[(&str, &[&str])] = &[
    (
        "Drive an arm",
        &["move", "joints", "play", "gripper", "status", "stop", "torque", "view", "teleop", "retarget", "serve"],
    ),
    ("Set up the servos and the arm", &["ports", "servo", "doctor", "calibrate", "collision"]),
    ("Kinematics", &["fk", "jacobian", "ik", "trajectory"]),
    ("Simulate and test", &["demo", "sim", "bench"]),
    ("Firmware", &["footprint"]),
];

/// The command line's definition: clap's, with the commands listed by [`GROUPS`] instead of in one
/// flat list (clap puts a command under one heading only, and would list them twice).
pub fn command() -> clap::Command {
    let cli = Cli::command();
    let width = GROUPS.iter().flat_map(|(_, names)| names.iter().map(|n| n.len())).max().unwrap_or(0);
    let mut groups = String::new();
    for (heading, names) in GROUPS {
        groups.push_str(&format!("{heading}:\n"));
        for name in *names {
            let about =
                cli.find_subcommand(name).and_then(|c| c.get_about()).map(|a| a.to_string()).unwrap_or_default();
            groups.push_str(&format!("  {name:<width$}  {about}\n"));
        }
        groups.push('\n');
    }
    cli.help_template(format!(
        "{{about-with-newline}}\n{{usage-heading}} {{usage}}\n\n{groups}Options (before the command or after it):\n{{options}}{{after-help}}"
    ))
}

/// Runs `armctl` with `args` (program name first); returns the exit code.
pub fn main<I, T>(args: I, out: &mut dyn Write, err: &mut dyn Write) -> i32
where
    I: IntoIterator<Item = T>,
    T: Into<OsString> + Clone,
{
    let parsed = command()
        .try_get_matches_from(args)
        .and_then(|matches| Ok((Cli::from_arg_matches(&matches)?, command_name(&matches))));
    let (cli, name) = match parsed {
        Ok(parsed) => parsed,
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
            // The usage line names the command the error is about: its help is the one to read.
            let usage = text.lines().find_map(|l| l.strip_prefix("Usage: ")).unwrap_or("armctl");
            let command: Vec<&str> = usage.split_whitespace().take_while(|w| !w.starts_with(['[', '<', '-'])).collect();
            let _ = writeln!(err, "{first} (see {} --help)", command.join(" "));
            return 2;
        }
    };
    match run(&cli.link, cli.command, &name, out, err) {
        Ok(code) => code,
        // The reader closed the pipe (`armctl ... | head`): it has what it wanted.
        Err(e) if e.downcast_ref::<std::io::Error>().is_some_and(|io| io.kind() == std::io::ErrorKind::BrokenPipe) => 0,
        Err(e) => {
            let _ = writeln!(err, "error: {e:#}");
            1
        }
    }
}

/// `--arm`'s value, or the error for its absence.
fn arm_name(arm: &ArmArgs) -> Result<&str> {
    match &arm.arm {
        Some(name) => Ok(name),
        None => bail!("--arm is missing: a preset name or a .urdf or .toml arm file"),
    }
}

pub(crate) fn load(arm: &ArmArgs) -> Result<Box<dyn DynArm>> {
    dof::build(ArmSpec::load(arm_name(arm)?, arm.tip.as_deref())?)
}

/// What `fk`, `jacobian` and `ik` work on: a chain, or a tree (a URDF with several leaves and no
/// `--tip`, [`Body::load`]).
pub(crate) enum Loaded {
    Chain(Box<dyn DynArm>),
    /// Boxed: the tree is held in its full fixed capacity, kilobytes.
    Tree(Box<DynTree>),
}

pub(crate) fn load_body(arm: &ArmArgs) -> Result<Loaded> {
    Ok(match Body::load(arm_name(arm)?, arm.tip.as_deref())? {
        Body::Chain(spec) => Loaded::Chain(dof::build(spec)?),
        Body::Tree(spec) => Loaded::Tree(Box::new(DynTree::build(spec)?)),
    })
}

/// The command as typed, subcommands included: `fk`, `bench ik`, `servo scan`.
fn command_name(matches: &clap::ArgMatches) -> String {
    let mut names = Vec::new();
    let mut at = matches;
    while let Some((name, sub)) = at.subcommand() {
        names.push(name);
        at = sub;
    }
    names.join(" ")
}

/// Moves the options given before the command (the drive options, [`LinkArgs`]) into the
/// command's own namesakes, so that a global option works on either side of the command: `--json`
/// into every command's; `--arm` into the kinematics commands' and demo's; `--rig` into demo's;
/// serve's and calibrate's bus options into theirs. The commands that take the drive options themselves (the
/// drive commands, teleop, view, retarget, doctor) merge them on their own. An option the command
/// has no use for is refused in one line.
fn take_globals(link: &LinkArgs, mut command: Command, name: &str) -> Result<Command> {
    use link::either;
    let mut rest = link.clone();
    let json = std::mem::take(&mut rest.json);
    match &mut command {
        Command::Drive(_) | Command::Teleop(_) | Command::View(_) | Command::Doctor(_) | Command::Retarget(_) => {
            return Ok(command)
        }
        Command::Fk { arm, json: own, .. }
        | Command::Jacobian { arm, json: own, .. }
        | Command::Bench { what: BenchCommand::Ik { arm, json: own, .. } } => {
            *own |= json;
            arm.arm = either("--arm", rest.arm.take(), arm.arm.take())?;
        }
        Command::Ik(args) => {
            args.json |= json;
            args.arm.arm = either("--arm", rest.arm.take(), args.arm.arm.take())?;
        }
        Command::Collision(args) => match &mut args.what {
            collision::CollisionCommand::Fit(args) => {
                args.json |= json;
                args.arm = either("--arm", rest.arm.take(), args.arm.take())?;
            }
            collision::CollisionCommand::Check(args) => {
                args.json |= json;
                args.arm = either("--arm", rest.arm.take(), args.arm.take())?;
                args.obstacles.splice(0..0, std::mem::take(&mut rest.obstacles));
                args.no_table |= std::mem::take(&mut rest.no_table);
            }
        },
        Command::Demo(args) => {
            args.json |= json;
            args.arm = either("--arm", rest.arm.take(), args.arm.take())?;
            args.rig = either("--rig", rest.rig.take(), args.rig.take())?;
            args.servos = either("--servos", rest.servos.take(), args.servos.take())?;
            args.payload_kg = either("--payload-kg", rest.payload_kg.take(), args.payload_kg.take())?;
        }
        Command::Serve(args) => {
            args.json |= json;
            args.bus = either("--bus", rest.bus.take(), args.bus.take())?;
            args.sim |= std::mem::take(&mut rest.sim);
            args.protocol = either("--protocol", rest.protocol.take(), args.protocol.take())?;
            args.baud = either("--baud", rest.baud.take(), args.baud.take())?;
            args.arm = either("--arm", rest.arm.take(), args.arm.take())?;
            args.calibration = either("--calibration", rest.calibration.take(), args.calibration.take())?;
            args.obstacles.splice(0..0, std::mem::take(&mut rest.obstacles));
            args.no_table |= std::mem::take(&mut rest.no_table);
        }
        Command::Bench { what: BenchCommand::Bus(args) } => args.json |= json,
        Command::Bench { what: BenchCommand::Rate(args) } => args.json |= json,
        Command::Bench { what: BenchCommand::Mcu(args) } => args.json |= json,
        Command::Bench { what: BenchCommand::LoopPass(args) } => args.json |= json,
        Command::Bench { what: BenchCommand::Pc(args) } => args.json |= json,
        Command::Bench { what: BenchCommand::Plan(args) } => args.json |= json,
        Command::Bench { what: BenchCommand::Servos(args) } => args.json |= json,
        Command::Footprint(args) => args.json |= json,
        Command::Sim(args) => match &mut args.what {
            Some(sim::SimCommand::Servos(servos)) => servos.json |= json,
            None => args.json |= json,
        },
        Command::Trajectory { what: TrajectoryCommand::Sample(args) } => args.json |= json,
        Command::Ports { json: own } => *own |= json,
        Command::Servo(args) => args.json |= json,
        Command::Calibrate { args, json: own } => {
            *own |= json;
            args.bus = either("--bus", rest.bus.take(), args.bus.take())?;
            args.protocol = either("--protocol", rest.protocol.take(), args.protocol.take())?;
            args.baud = either("--baud", rest.baud.take(), args.baud.take())?;
            args.arm = either("--arm", rest.arm.take(), args.arm.take())?;
        }
    }
    rest.refuse_for(name)?;
    Ok(command)
}

fn run(link: &LinkArgs, command: Command, name: &str, out: &mut dyn Write, err: &mut dyn Write) -> Result<i32> {
    let command = take_globals(link, command, name)?;
    match command {
        Command::Drive(command) => return drive::run(link, command, out, err),
        Command::Demo(args) => return demo::run(&args, out),
        Command::Retarget(args) => return retarget::run(link, args, out, err),
        Command::Teleop(args) => return teleop::run(link, args, out, err),
        Command::View(args) => return view::run(link, args, out, err),
        Command::Fk { arm, q, json: _ } => {
            let arm = match load_body(&arm)? {
                Loaded::Chain(arm) => arm,
                Loaded::Tree(tree) => return tree::fk(&tree, &q, out),
            };
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
        Command::Jacobian { arm, q, json: _ } => {
            let arm = match load_body(&arm)? {
                Loaded::Chain(arm) => arm,
                Loaded::Tree(tree) => return tree::jacobian(&tree, &q, out),
            };
            let q = parse::numbers(&q, "--q")?;
            print_json(out, &json!({"arm": arm.spec().name, "jacobian": arm.jacobian(&q)?}))?;
        }
        Command::Ik(args) => return ik::run(&args, out, err),
        Command::Collision(args) => return collision::run(args.what, out),
        Command::Bench { what: BenchCommand::Bus(args) } => {
            return crate::commands::bench::bus::run(&args.request()?, out)
        }
        Command::Bench { what: BenchCommand::Rate(args) } => {
            return crate::commands::bench::rate::run(&args.request()?, out)
        }
        Command::Footprint(args) => return crate::commands::footprint::run(&args.request(), out, err),
        Command::Bench { what: BenchCommand::Mcu(args) } => return crate::commands::bench::mcu::run(args.json, out),
        Command::Bench { what: BenchCommand::LoopPass(args) } => {
            return crate::commands::bench::loop_pass::run(args.seconds, args.json, out)
        }
        Command::Bench { what: BenchCommand::Pc(args) } => {
            return crate::commands::bench::pc::run(&args.request()?, out, err)
        }
        Command::Bench { what: BenchCommand::Plan(args) } => {
            return crate::commands::bench::plan::run(&args.request(), args.json, out)
        }
        Command::Bench { what: BenchCommand::Servos(args) } => {
            return crate::commands::bench::servos::run(&args.request(), args.json, out)
        }
        Command::Servo(args) => return crate::cli::servo::run(args, out, err),
        Command::Doctor(args) => return doctor::run(link, args, out, err),
        Command::Calibrate { args, json } => return calibrate::run(args.request()?, json, out, err),
        Command::Ports { json } => {
            let ports = crate::commands::servo::ports::usb_ports(std::path::Path::new("/dev"));
            if json {
                print_json(out, &ports)?;
            } else if ports.is_empty() {
                writeln!(
                    out,
                    "no USB serial port found (is the adapter plugged in? on Linux `dmesg | tail` shows what the kernel saw)"
                )?;
            } else {
                for port in &ports {
                    writeln!(out, "{}", crate::commands::servo::ports::describe(port))?;
                }
            }
        }
        Command::Sim(args) => return sim::run(args, out, err),
        Command::Serve(args) => return serve::run(args, out, err),
        Command::Trajectory { what: TrajectoryCommand::Sample(args) } => {
            return crate::motion::sample::run(&args.request(), out, err)
        }
        Command::Bench { what: BenchCommand::Ik { arm, n, scalar, seed, no_k, json: _ } } => {
            if n == 0 {
                bail!("--n must be at least 1");
            }
            let arm = load(&arm)?;
            let report = ik_bench::run(arm.as_ref(), &Protocol { n, scalar, seed, with_k: !no_k })?;
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
            if !no_k && !cfg!(feature = "compare-k") {
                writeln!(
                    err,
                    "note: k's solver is not beside ours: this armctl was built without the compare-k feature \
                     (cargo run --release -p armctl --features compare-k -- bench ik ...)"
                )?;
            }
            // Through a `Value`, whose maps print their keys sorted, as this output always has.
            print_json(out, &serde_json::to_value(&report)?)?;
        }
    }
    Ok(0)
}

fn vec3(p: &kinematics::Pose<f64>) -> [f64; 3] {
    p.translation.into()
}

pub(crate) use crate::support::json_out::print_json;
