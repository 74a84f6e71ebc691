//! The `armctl` command line: argument parsing and the commands, writing JSON to `out`.
//!
//! Every failure is one line on `err` starting with `error:` and a non-zero exit code.

mod ik;
pub mod retarget;
pub mod serve;
pub mod sim;

use crate::args::numbers as parse;
use crate::arm::dof::{self, DynArm, Scalar};
use crate::arm::ArmSpec;
use crate::bench::ik::{self as bench, Protocol};
use anyhow::{bail, Result};
use clap::{Args, Parser, Subcommand};
use serde_json::{json, Value};
use std::ffi::OsString;
use std::io::Write;

/// Kinematics, inverse kinematics and benchmarks for serial-bus-servo arms.
#[derive(Parser, Debug)]
#[command(name = "armctl", version, about)]
struct Cli {
    #[command(flatten)]
    link: crate::drive::args::LinkArgs,
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
    Ik(ik::IkArgs),
    /// Benchmarks.
    Bench {
        #[command(subcommand)]
        what: BenchCommand,
    },
    /// Flash, static RAM, panic paths and stack depth of each board binary, against the goals.
    Footprint(crate::footprint::FootprintArgs),
    /// Simulated servo buses (served on a pseudo-terminal), or the firmware under QEMU (--qemu).
    Sim(sim::SimArgs),
    /// Joint trajectories through keyframes.
    Trajectory {
        #[command(subcommand)]
        what: TrajectoryCommand,
    },
    /// The serial ports with the USB device behind each (vendor:product id, maker, product, serial
    /// number, /dev/serial/by-id name): which one is the arm's adapter.
    Ports {
        /// One JSON array instead of a line per port.
        #[arg(long)]
        json: bool,
    },
    /// Keep one firmware core running on this PC (servos on a USB adapter with --bus, simulated with
    /// --sim) and serve its host link on a pseudo-terminal for `armctl --port`: prints the pty's
    /// path on the first line of stdout.
    Serve(serve::ServeArgs),
    /// Serial bus servo set-up on a real port: scan, read, write, set-id, set-baud, torque.
    Servo(crate::servo::cli::ServoArgs),
    /// What is wrong with a servo bus (--bus PORT): ids, models, firmware, supply, temperature,
    /// error flags, return delay, the adapter's echo and latency, lost replies, stale goals, the
    /// calibration, whether a control cycle fits. One line per finding, OK, WARN or FAIL with the
    /// fix; writes nothing unless --fix. Scans both protocols at the usual baud rates when
    /// --protocol and --baud are not given.
    Doctor(crate::doctor::DoctorArgs),
    /// Calibrate an arm's servos as LeRobot does (homing offsets at the middle of each joint's
    /// range, the ranges moved through by hand as position limits), answering each step with a
    /// line on stdin; writes the servos, an arm file (--out) and LeRobot's file (--lerobot-json).
    Calibrate(crate::servo::calibrate::CalibrateArgs),
    /// A human arm from a BVH motion-capture file onto the arm: joint keyframes for `armctl play`
    /// (--out), the hand's and the tool's paths (--plot), tracking figures; --play streams them.
    /// With --rig RIG: the human's arms onto every arm of the rig, one keyframe file for all.
    Retarget(retarget::RetargetArgs),
    /// Teleoperation: a leader arm moved by hand (torque off, read by sync read) drives the
    /// follower given by the drive options (--port, --bus or --sim), through both calibrations,
    /// as keyframes the follower's firmware plays within its limits. Reports the loop's rate and
    /// latency; --record writes the session as a keyframe file for `armctl play`.
    Teleop(crate::teleop::TeleopArgs),
    /// The arm live in a browser: a local page with the arm in 3D, joint sliders, a target to
    /// drag (IK preview, then the move on the firmware), telemetry, keyframe files, stop and
    /// torque, and the same as a JSON API. Prints the page's URL on the first line; opens no
    /// browser. Drives --sim (the default, in real time), --port or --bus.
    View(crate::view::ViewArgs),
    /// Driving an arm (after --port PORT, --bus PORT --protocol P or --sim): move, joints, play,
    /// status, stop, torque.
    #[command(flatten)]
    Drive(crate::drive::args::DriveCommand),
}

#[derive(Subcommand, Debug)]
enum TrajectoryCommand {
    /// Interpolate a keyframe CSV file and sample it at a fixed rate (CSV `t,q...,v...,a...` or
    /// --json on stdout).
    Sample(crate::motion::sample::SampleArgs),
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
        /// Skip the `k` crate's solver (run only when built with `--features compare-k`).
        #[arg(long)]
        no_k: bool,
    },
    /// Wire time of one control cycle (sync write goals + sync read positions), computed and
    /// simulated with the firmware's cycle against simulated servos.
    Bus(crate::bench::bus::BusBenchArgs),
    /// Control rate of the firmware's controller (6 servos, a joint move in progress) against
    /// simulated servos on the virtual clock, ticking back to back and on its fixed period,
    /// compared with the bus's wire-time limit. Compute time is free on the virtual clock.
    Rate(crate::bench::rate::RateBenchArgs),
    /// Instructions per operation on the Cortex-M4F (FK, IK, player tick, bus packets), counted by
    /// the firmware's `opcount` binary under `qemu-system-arm -icount shift=0`.
    Mcu(crate::bench::mcu::McuBenchArgs),
    /// Control rate and bus time per tick of the firmware core hosted on this PC (--bus) against
    /// simulated servos on a pseudo-terminal in real time, with or without a USB adapter's burst
    /// latency.
    Pc(crate::bench::pc::PcBenchArgs),
}

#[derive(Args, Debug)]
pub(crate) struct ArmArgs {
    /// Arm: a preset name or a path to a .urdf or .toml arm file.
    #[arg(long)]
    arm: String,
    /// Tip link of a URDF arm (needed when the URDF tree has several leaves).
    #[arg(long)]
    tip: Option<String>,
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

pub(crate) fn load(arm: &ArmArgs) -> Result<Box<dyn DynArm>> {
    dof::build(ArmSpec::load(&arm.arm, arm.tip.as_deref())?)
}

fn run(link: &crate::drive::args::LinkArgs, command: Command, out: &mut dyn Write, err: &mut dyn Write) -> Result<i32> {
    // `retarget --play` drives an arm too: it takes the drive options; `retarget --rig` takes the rig.
    if !matches!(&command, Command::Drive(_) | Command::Teleop(_) | Command::View(_) | Command::Doctor(_))
        && !matches!(&command, Command::Retarget(a) if a.plays() || link.rig.is_some())
    {
        link.refuse_for_other_commands()?;
    }
    match command {
        Command::Drive(command) => {
            let merged = link.merged(command.link())?;
            if let Some(rig) = &merged.rig {
                return crate::rig::commands::run(rig, &merged, command, out, err);
            }
            return crate::drive::run(link, command, out, err);
        }
        Command::Demo(args) => return crate::demo::run(&args, out),
        Command::Retarget(args) => return retarget::run(link, args, out, err),
        Command::Teleop(args) => return crate::teleop::run(link, args, out, err),
        Command::View(args) => return crate::view::run(link, args, out, err),
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
        Command::Ik(args) => return ik::run(&args, out, err),
        Command::Bench { what: BenchCommand::Bus(args) } => return crate::bench::bus::run(&args, out),
        Command::Bench { what: BenchCommand::Rate(args) } => return crate::bench::rate::run(&args, out),
        Command::Footprint(args) => return crate::footprint::run(&args, out, err),
        Command::Bench { what: BenchCommand::Mcu(args) } => return crate::bench::mcu::run(&args, out),
        Command::Bench { what: BenchCommand::Pc(args) } => return crate::bench::pc::run(&args, out, err),
        Command::Servo(args) => return crate::servo::cli::run(args, out, err),
        Command::Doctor(args) => return crate::doctor::run(link, args, out, err),
        Command::Calibrate(args) => return crate::servo::calibrate::run(args, out, err),
        Command::Ports { json } => {
            let ports = crate::servo::ports::usb_ports(std::path::Path::new("/dev"));
            if json {
                print_json(out, &ports)?;
            } else if ports.is_empty() {
                writeln!(
                    out,
                    "no USB serial port found (is the adapter plugged in? on Linux `dmesg | tail` shows what the kernel saw)"
                )?;
            } else {
                for port in &ports {
                    writeln!(out, "{}", crate::servo::ports::describe(port))?;
                }
            }
        }
        Command::Sim(args) => return sim::run(args, out, err),
        Command::Serve(args) => return serve::run(args, out, err),
        Command::Trajectory { what: TrajectoryCommand::Sample(args) } => {
            return crate::motion::sample::run(&args, out, err)
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

/// Writes `value` as one line of JSON. The line is serialised in memory and written at once: into
/// `dyn Write` directly, every key, comma and number is a call of its own (a third of the
/// per-line cost of `ik --batch` went there). The buffer is kept from line to line.
pub(crate) fn print_json(out: &mut dyn Write, value: &impl serde::Serialize) -> Result<()> {
    thread_local! {
        static LINE: std::cell::RefCell<Vec<u8>> = const { std::cell::RefCell::new(Vec::new()) };
    }
    LINE.with_borrow_mut(|line| {
        line.clear();
        serde_json::to_writer(&mut *line, value)?;
        line.push(b'\n');
        out.write_all(line)?;
        Ok(())
    })
}
