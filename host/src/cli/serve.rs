//! `armctl serve`: one firmware core kept running on this PC, its host link on a pseudo-terminal,
//! so that consecutive `armctl --port PTY` commands, scripts and other programs drive one arm
//! whose state (torque, position, queue, counters) persists between them.
//!
//! `--bus PORT` drives real servos on a USB adapter; `--sim` drives simulated ones (served on a pty
//! of their own, with the simulator's safety monitor watching every goal). The first signal
//! (Ctrl-C or SIGTERM) stops the arm within its limits and exits 0 once it holds; a second one
//! switches the torque off and exits 130.

use crate::runtime::gravity::{gravity_parts, Compensation, Gains};
use std::io::Write;
use std::time::{Duration, Instant};

use anyhow::{anyhow, bail, Result};
use clap::Args;

use crate::arm::servos::servos_of;
use crate::arm::ArmSpec;
use crate::cli::bus_args::ProtocolArg;
use crate::link::session::Session;
use crate::runtime::connection::handshake_with;
use crate::runtime::connection::{calibrated, default_bus_arm, DEFAULT_SIM_ARM};
use crate::runtime::pc::{Pc, PcOptions};
use crate::runtime::serve::PtyLink;
use crate::sim::PtyServer;
use crate::support::interrupt;

/// How long the core may take to read its servos after the arm is configured.
const READY_TIMEOUT: Duration = Duration::from_secs(2);
/// Violations `finish` prints after the monitor's summary, at most.
const MAX_VIOLATION_LINES: usize = 10;
/// How long the second signal's torque off may take.
const TORQUE_OFF_TIMEOUT: Duration = Duration::from_secs(1);

/// Arguments of `armctl serve`. Its options are the drive options' namesakes, and may come before
/// the command as well (`armctl --sim serve`).
#[derive(Args, Debug)]
pub struct ServeArgs {
    /// Drive the servos on this USB adapter's serial port (this or --sim is required).
    #[arg(long, value_name = "PORT", conflicts_with = "sim")]
    pub bus: Option<String>,
    /// Drive simulated servos instead (served on a pseudo-terminal of their own, in real time).
    #[arg(long)]
    pub sim: bool,
    /// The servos' protocol, sts (Feetech) or dxl2 (Dynamixel 2.0); with --sim, the arm's.
    #[arg(long, value_enum)]
    pub protocol: Option<ProtocolArg>,
    /// The servos' baud rate [default: the arm file's `baud`, else 1000000].
    #[arg(long)]
    pub baud: Option<u32>,
    /// A preset with servos (so101, open-manipulator-x) or an arm file with a [servos] table
    /// [default: so101 on sts, open-manipulator-x on dxl2; so101 with --sim].
    #[arg(long)]
    pub arm: Option<String>,
    /// With --sim: deliver the simulated servos' replies in bursts every MS milliseconds, as a USB
    /// adapter's latency timer does (16 on FTDI by default, 1 when tuned).
    #[arg(long, value_name = "MS", requires = "sim")]
    pub burst_ms: Option<f64>,
    /// With --sim: the servos, `ideal` (the default) or `physical` (docs/servo-model.md).
    #[arg(long, value_name = "KIND", requires = "sim", value_parser = ["ideal", "physical"])]
    pub servos: Option<String>,
    /// With --sim --servos physical: a payload of KG kilograms at the tool frame's origin.
    #[arg(long, value_name = "KG", requires = "sim", allow_negative_numbers = true)]
    pub payload_kg: Option<f64>,
    /// A LeRobot calibration file (JSON) of the arm's servos (see `armctl --help`'s --calibration).
    #[arg(long, value_name = "FILE")]
    pub calibration: Option<std::path::PathBuf>,
    /// An obstacle more around the arm (see `armctl --help`'s --obstacle). Repeatable.
    #[arg(long = "obstacle", value_name = "SPEC")]
    pub obstacles: Vec<crate::arm::collision::ObstacleSpec>,
    /// Without the table the arm stands on.
    #[arg(long)]
    pub no_table: bool,
    /// With --sim: the firmware gets the collision geometry with its check off, and so does
    /// every client's host check (see `armctl --help`'s --no-collision-check).
    #[arg(long, requires = "sim")]
    pub no_collision_check: bool,
    /// Print the first line as JSON, {"pty": PATH}, instead of the bare path.
    #[arg(long)]
    pub json: bool,
}

/// Runs `armctl serve`; returns the exit code.
pub fn run(args: ServeArgs, out: &mut dyn Write, err: &mut dyn Write) -> Result<i32> {
    match (&args.bus, args.sim) {
        (None, false) => bail!("serve needs --bus PORT (servos on a USB adapter) or --sim (simulated servos)"),
        (Some(_), true) => bail!("--bus and --sim exclude each other: give one"),
        _ => {}
    }
    let arm_name = match (&args.arm, args.protocol) {
        (Some(arm), _) => arm.clone(),
        (None, Some(protocol)) => default_bus_arm(protocol.into()).to_string(),
        (None, None) if args.sim => DEFAULT_SIM_ARM.to_string(),
        (None, None) => bail!("--bus needs --protocol: sts (Feetech) or dxl2 (Dynamixel)"),
    };
    let surroundings =
        crate::arm::collision::obstacle::Surroundings { obstacles: args.obstacles.clone(), no_table: args.no_table };
    let arm =
        calibrated(ArmSpec::load(&arm_name, None)?.with_surroundings(&surroundings)?, args.calibration.as_deref())?;
    let servos = servos_of(&arm)
        .ok_or_else(|| anyhow!("arm {} has no servo mapping: add a [servos] table to its arm file", arm.name))?;
    let protocol = match args.protocol {
        Some(p) => p.into(),
        None => servos.model.protocol,
    };
    // The arm file's rate unless --baud names one.
    let baud = args.baud.unwrap_or(servos.baud);
    let burst = args.burst_ms.map(burst).transpose()?;
    // With --sim the servos are served on a pty of their own, and the core drives them there
    // exactly as it drives an adapter's port.
    let kind = crate::sim::physics::servo_kind(args.servos.as_deref(), args.payload_kg)?;
    let contact = crate::arm::collision::collision_of(&arm);
    let simulated = args.sim.then(|| crate::sim::serve_arm(&arm, baud, burst, kind, contact)).transpose()?;
    let path = match (&simulated, &args.bus) {
        (Some(server), _) => server.path().to_string(),
        (None, Some(path)) => path.clone(),
        (None, None) => bail!("give --bus PORT or --sim"),
    };
    let calibration_file = args.calibration.as_ref().map(|f| f.display().to_string());
    let monitor = simulated.as_ref().and_then(PtyServer::monitor_handle);
    let options = PcOptions { path, protocol, baud, arm, calibration_file, monitor, gravity: None };
    let mut pc = Pc::start(&options, false, err)?;
    let shared = pc.shared();
    // The arm is configured now, so that the first client finds it running.
    let link = pc.take_link().ok_or_else(|| anyhow!("the core's link was taken"))?;
    let mut session = Session::over(link);
    if args.no_collision_check {
        session.set_collision_check(crate::link::arm_config::CollisionCheck::Off);
    }
    handshake_with(&mut session, Some(options.arm.clone()))?;
    // Physical simulated servos sag: the core compensates (the set-up's gains), for every client.
    if let (true, crate::sim::physics::ServoKind::Physical(payload)) = (args.sim, kind) {
        let compensation = Compensation::by_default(Gains::SetUp, payload.map(|p| p.kg));
        session.gravity(&gravity_parts(&options.arm, &compensation)?)?;
    }
    let started = Instant::now();
    while !shared.ready() {
        if started.elapsed() > READY_TIMEOUT || pc.is_finished() {
            bail!("the firmware core did not read every servo within {} s", READY_TIMEOUT.as_secs());
        }
        std::thread::sleep(Duration::from_millis(1));
    }
    let pty = PtyLink::spawn(session.into_transport())?;
    if args.json {
        crate::support::json_out::print_json(out, &serde_json::json!({ "pty": pty.path() }))?;
    } else {
        writeln!(out, "{}", pty.path())?;
    }
    out.flush()?;
    writeln!(
        err,
        "serving arm {} on {} (e.g. `armctl --port {} status`); Ctrl-C stops the arm and exits, a second Ctrl-C \
         switches the torque off",
        options.arm.name,
        pty.path(),
        pty.path()
    )?;
    err.flush()?;
    interrupt::catch();
    let mut stopping = false;
    loop {
        std::thread::sleep(Duration::from_millis(10));
        if pc.is_finished() {
            bail!("the firmware core stopped");
        }
        if simulated.as_ref().is_some_and(PtyServer::is_finished) {
            bail!("the simulated servos stopped");
        }
        let signals = interrupt::count();
        if signals >= 2 {
            shared.request_torque_off();
            let asked = Instant::now();
            while (shared.request_pending() || shared.torque()) && asked.elapsed() < TORQUE_OFF_TIMEOUT {
                std::thread::sleep(Duration::from_millis(1));
            }
            let limp = !shared.torque();
            writeln!(err, "second signal: {}", if limp { "torque off" } else { "torque off was not confirmed" })?;
            finish(&mut pc, simulated.as_ref(), err)?;
            return Ok(interrupt::EXIT_CODE);
        }
        if signals == 1 && !stopping {
            shared.request_stop();
            stopping = true;
            writeln!(err, "stopping: the arm decelerates within its limits, then holds (Ctrl-C again: torque off)")?;
            err.flush()?;
        }
        if stopping && !shared.request_pending() && !shared.moving() {
            writeln!(err, "holding")?;
            finish(&mut pc, simulated.as_ref(), err)?;
            return Ok(0);
        }
    }
}

/// A burst period from the command line.
fn burst(ms: f64) -> Result<Duration> {
    if !(ms.is_finite() && ms > 0.0 && ms <= 100.0) {
        bail!("--burst-ms: {ms} must be above 0 and at most 100");
    }
    Ok(Duration::from_secs_f64(ms * 1e-3))
}

/// Ends the core and says what the loop and, for simulated servos, the safety monitor saw.
fn finish(pc: &mut Pc, simulated: Option<&PtyServer>, err: &mut dyn Write) -> Result<()> {
    let summary = pc.shared().summary();
    pc.shutdown()?;
    writeln!(err, "bus: {summary}")?;
    if let Some(report) = simulated.and_then(PtyServer::monitor) {
        writeln!(err, "safety monitor: {}", report.summary())?;
        for v in report.violations.iter().take(MAX_VIOLATION_LINES) {
            writeln!(err, "  violation: {v}")?;
        }
        for c in report.contacts.iter().flat_map(|c| &c.contacts).take(MAX_VIOLATION_LINES) {
            writeln!(err, "  within the margin: {c}")?;
        }
    }
    Ok(())
}
