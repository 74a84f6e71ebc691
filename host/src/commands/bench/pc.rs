//! `armctl bench pc`: the firmware core hosted on this PC (`--bus`) driving simulated servos on a
//! pseudo-terminal in real time, optionally with a USB adapter's burst latency: the control rate
//! it reaches and the time each tick spends on the bus.
//!
//! The arm is a planar chain of N joints (as many servos as asked) with the protocol's servo model,
//! so that the figure is about the bus, not about one arm's geometry. The motion is a joint move
//! back and forth at the limits' pace for the time asked; the simulator's safety monitor judges
//! every goal.

use std::io::Write;
use std::time::{Duration, Instant};

use anyhow::{bail, Context, Result};
use firmware::bus::table::Model;
use firmware::link::message::{Joints, RunState, Timing};
use serde_json::json;

use crate::arm::servos::ServoSetup;
use crate::arm::ArmSpec;
use crate::runtime::connection::{self, Connection, Target};
use crate::runtime::pc::PcOptions;
use crate::sim::{Faults, PtyServer, SimConfig};

/// What `armctl bench pc` measures.
#[derive(Clone, Copy, Debug)]
pub struct PcBenchRequest {
    /// The servos' model (the command line's: its protocol's usual one); the bus speaks its
    /// protocol.
    pub model: &'static Model,
    /// Number of servos (ids 1..=N), 1 to 8.
    pub servos: usize,
    /// Baud rate.
    pub baud: u32,
    /// Deliver the servos' replies in bursts every so many milliseconds (a USB adapter's latency
    /// timer: 16 on FTDI by default); `None`: at once.
    pub burst_ms: Option<u64>,
    /// Seconds of motion measured.
    pub seconds: f64,
}

/// The benchmark's arm: `planar:N` driven by servos of the request's model, ids 1..=N.
fn arm(args: &PcBenchRequest) -> Result<ArmSpec> {
    let model = args.model;
    let mut spec = ArmSpec::load(&format!("planar:{}", args.servos), None)?;
    spec.servos = Some(ServoSetup {
        model,
        ids: (1..=args.servos as u8).collect(),
        zero: None,
        reversed: None,
        max_velocity: 2.0,
        max_acceleration: 8.0,
        baud: armctl_arm::servos::DEFAULT_BAUD,
        calibration: None,
        gripper: None,
        gripper_calibration: None,
    });
    Ok(spec)
}

/// Polls until the arm rests (at most `limit`).
fn until_rest(conn: &mut Connection, limit: Duration) -> Result<firmware::link::message::Status> {
    let started = Instant::now();
    loop {
        let status = conn.session.status()?;
        if status.state == RunState::Idle {
            return Ok(status);
        }
        if started.elapsed() > limit {
            bail!("the arm did not come to rest within {} s", limit.as_secs());
        }
        std::thread::sleep(Duration::from_millis(10));
    }
}

/// Runs the benchmark: one JSON line on `out`, what connecting said on `err`. The rate and tick
/// times cover the whole run, torque on included.
pub fn run(args: &PcBenchRequest, out: &mut dyn Write, err: &mut dyn Write) -> Result<i32> {
    if !(1..=8).contains(&args.servos) {
        bail!("--servos must be 1 to 8 (the firmware's joint limit)");
    }
    if !(args.seconds.is_finite() && args.seconds > 0.0 && args.seconds <= 600.0) {
        bail!("--seconds must be above 0 and at most 600");
    }
    if args.burst_ms.is_some_and(|ms| ms == 0 || ms > 100) {
        bail!("--burst-ms must be 1 to 100");
    }
    let spec = arm(args)?;
    let servos = spec.servos.clone().context("the benchmark arm has servos")?;
    let server = PtyServer::spawn(SimConfig {
        protocol: servos.model.protocol,
        model: servos.model,
        ids: servos.ids.clone(),
        baud: args.baud,
        faults: Faults::default(),
        duplicates: Vec::new(),
        fixed_baud: false,
        burst: args.burst_ms.map(Duration::from_millis),
        limits: Some(crate::sim::monitor::limits_of(&spec)?),
        world: crate::sim::World::of(&spec)?,
        physics: crate::sim::physics::ServoKind::default().physics(Some(&spec))?,
    })
    .context("cannot open a pseudo-terminal")?;
    let options = PcOptions {
        path: server.path().to_string(),
        protocol: args.model.protocol,
        baud: args.baud,
        arm: spec,
        calibration_file: None,
        monitor: server.monitor_handle(),
        gravity: None,
    };
    let mut conn = connection::open(Target::Bus(Box::new(options)), None, err)?;
    let pc = conn.pc.as_ref().context("a --bus connection has its core")?;
    let connected = pc.connected().clone();
    let shared = pc.shared();
    conn.session.torque_on(0).context("torque on")?;
    until_rest(&mut conn, Duration::from_secs(2))?;
    let ticks_before = shared.summary();
    let started = Instant::now();
    let mut sign = 1.0f32;
    while started.elapsed().as_secs_f64() < args.seconds {
        let q: Vec<f32> = (0..args.servos).map(|j| sign * if j % 2 == 0 { 0.6 } else { -0.6 }).collect();
        let positions = Joints::from_slice(&q).map_err(|_| anyhow::anyhow!("joint count"))?;
        conn.session.move_joints(positions, Timing::MaxSpeed(10.0)).context("joints")?;
        until_rest(&mut conn, Duration::from_secs(10))?;
        sign = -sign;
    }
    let summary = shared.summary();
    drop(conn);
    let monitor = server.monitor().context("the monitor is on")?;
    let ticks = summary.ticks - ticks_before.ticks;
    let v = json!({
        "protocol": connected.choice.bus.protocol.name(),
        "servos": args.servos,
        "baud": args.baud,
        "burst_ms": args.burst_ms,
        "sync_read_median_ms": connected.measured.median_us() as f64 * 1e-3,
        "sync_read_max_ms": connected.measured.max_us() as f64 * 1e-3,
        "period_ms": f64::from(connected.choice.period_us) * 1e-3,
        "ticks": ticks,
        "rate_hz": summary.rate_hz,
        "tick_median_ms": summary.tick_median_ms,
        "tick_max_ms": summary.tick_max_ms,
        "late_ticks": summary.late,
        "goals_checked": monitor.checked,
        "violations": monitor.violation_count,
        "contacts": monitor.contacts.as_ref().map(|c| c.json()),
    });
    writeln!(out, "{v}")?;
    Ok(if monitor.violation_count == 0 { 0 } else { 1 })
}
