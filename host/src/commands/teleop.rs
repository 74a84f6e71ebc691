//! `armctl teleop`: a leader arm moved by hand drives a follower arm, as LeRobot's
//! `lerobot-teleoperate` does, through this project's one mechanism: the leader's joints are read
//! on a bus of their own (sync read, torque off), passed through both arms' calibrations, and
//! streamed to the follower's firmware as keyframes, which its player plays within its limits.
//!
//! - [`crate::motion::teleop::leader`]: the leader's servos, read as joint angles and a gripper opening;
//! - [`crate::motion::teleop::hand`]: a simulated leader, turned by a scripted hand, to try it without an arm;
//! - [`crate::motion::teleop::stream`]: the loop: its rate, the safety clamp, keyframes timed by the follower's playback
//!   clock, and the figures;
//! - [`crate::motion::teleop::record`]: the session as a keyframe file for `armctl play`.
//!
//! The follower is any drive target: `--port` (a board), `--bus` (the core on this PC with the
//! servos on a USB adapter), or `--sim`, which here runs the core on this PC in real time against
//! simulated servos on a pseudo-terminal (as `armctl serve --sim`), with a USB adapter's 1 ms
//! latency and the safety monitor: teleoperation is a real-time loop, which the virtual clock of
//! the other commands' `--sim` would not pace.
//!
//! What this takes is plain: the follower's [`Place`], the leader ([`LeaderSpec`]) and the loop's
//! checked [`LoopSettings`]; the command line's options become these in `cli::teleop`. Every rig
//! arm driven by its own leader (`teleop --rig`) is [`crate::rig::teleop`], which runs each pair
//! through [`session`] and reports it with [`report`].

use std::io::Write;
use std::path::PathBuf;
use std::time::Duration;

use anyhow::{bail, Result};
use serde_json::json;

use crate::arm::ArmSpec;
use crate::motion::teleop::leader::{LeaderSpec, Reading};
use crate::motion::teleop::stream::{quantile, Figures, Settings};
use crate::runtime::connection::{calibrated, Place, Target, SIM_ADAPTER_LATENCY};
use crate::runtime::driver::{Driver, Waited};
use crate::sim::PtyServer;
use crate::support::interrupt;

/// Added to one period for the default lead: the player heads for a keyframe from the previous
/// one, so each must be queued one period before it is due, and this margin covers the leader's
/// read, the link's delay and the loop's jitter.
pub const LEAD_MARGIN: Duration = Duration::from_millis(8);

/// The loop's settings every follower of a session shares, checked before anything is opened.
#[derive(Clone, Copy, Debug)]
pub struct LoopSettings {
    /// Keyframes per second.
    pub rate: f64,
    /// One keyframe's period, `1 / rate`.
    pub period: Duration,
    /// How long after its reading a keyframe is played on the follower.
    pub lead: Duration,
    /// Largest change of a joint from one keyframe to the next, rad [default: the follower's
    /// speed limit over one period].
    pub max_step: Option<f64>,
    /// End after this many seconds [default: at Ctrl-C, or when a simulated leader's script ends].
    pub duration: Option<f64>,
}

impl LoopSettings {
    /// The settings from the values a person gives (`lead_ms`: milliseconds, [default: one period
    /// plus [`LEAD_MARGIN`]]); each out of range is refused, named by its option.
    pub fn new(rate: f64, lead_ms: Option<f64>, max_step: Option<f64>, duration: Option<f64>) -> Result<LoopSettings> {
        if !(rate.is_finite() && (1.0..=1000.0).contains(&rate)) {
            bail!("--rate: {rate} must be between 1 and 1000 keyframes per second");
        }
        let period = Duration::from_secs_f64(1.0 / rate);
        let lead = match lead_ms {
            Some(ms) if ms.is_finite() && ms > 0.0 && ms <= 1000.0 => Duration::from_secs_f64(ms * 1e-3),
            Some(ms) => bail!("--lead-ms: {ms} must be above 0 and at most 1000"),
            None => period + LEAD_MARGIN,
        };
        if let Some(step) = max_step {
            if !(step.is_finite() && step > 0.0) {
                bail!("--max-step: {step} must be a positive number of radians");
            }
        }
        if let Some(d) = duration {
            if !(d.is_finite() && d > 0.0) {
                bail!("--duration: {d} must be a positive number of seconds");
            }
        }
        Ok(LoopSettings { rate, period, lead, max_step, duration })
    }
}

/// One follower's teleoperation, checked: its leader, the loop, and where to record the session.
#[derive(Clone, Debug)]
pub struct TeleopRequest {
    /// The leader arm.
    pub leader: LeaderSpec,
    /// The loop.
    pub settings: LoopSettings,
    /// Write the session as a joint keyframe file that `armctl play` replays.
    pub record: Option<PathBuf>,
}

/// One leader driving one follower to the end.
pub struct Session {
    /// The loop's figures.
    pub figures: Figures,
    /// How it ended.
    pub ending: Ending,
    /// The exit code of bringing the follower to rest (non-zero after Ctrl-C).
    pub code: i32,
}

/// Runs `armctl teleop` on the follower at `place`; returns the exit code.
pub fn run(
    place: &Place,
    json: bool,
    request: &TeleopRequest,
    out: &mut dyn Write,
    err: &mut dyn Write,
) -> Result<i32> {
    let (target, arm) = place.target_and_arm()?;
    if place.object_mm.is_some() {
        bail!("--object-mm: teleop's simulated follower has no object between its jaws");
    }
    let settings = &request.settings;
    interrupt::catch();
    let s = session(target, arm.map(str::to_string), &request.leader, settings, request.record.as_deref(), None, err)?;
    report(&s.figures, settings.period, settings.lead, &s.ending, json, out)?;
    Ok(if s.ending.monitor.is_some_and(|m| m.violation_count > 0) { 1 } else { s.code })
}

/// What looks at every leader reading before it goes to the follower, and may hold it back (a
/// rig's arms kept apart: [`crate::rig::teleop`]).
pub trait Guard {
    /// The follower's measured joints once it is connected, before the first reading.
    fn begin(&mut self, measured: &[f64]);
    /// A reading about to go to the follower: changed in place to hold it back.
    fn check(&mut self, reading: &mut Reading);
}

/// One leader driving one follower (`target`, running `arm` if named) until the duration, the
/// script's end or Ctrl-C; then the follower brought to rest. What opening said goes to `err`;
/// `guard`, if given, sees every reading first.
pub fn session(
    target: Target,
    arm: Option<String>,
    source: &LeaderSpec,
    settings: &LoopSettings,
    record: Option<&std::path::Path>,
    mut guard: Option<&mut dyn Guard>,
    err: &mut dyn Write,
) -> Result<Session> {
    let LoopSettings { rate, period, lead, max_step, duration } = *settings;
    let leader_arm = calibrated(ArmSpec::load(&source.arm, None)?, source.calibration.as_deref())?;
    let bus = crate::motion::teleop::leader::bus_config(&leader_arm, source.protocol, source.baud)?;
    let mut simulated_leader = match (&source.script, source.port == "sim") {
        (Some(script), true) => {
            Some(crate::motion::teleop::hand::SimLeader::spawn(&leader_arm, script, Some(SIM_ADAPTER_LATENCY))?)
        }
        _ => None,
    };
    let leader_path = simulated_leader.as_ref().map_or(source.port.clone(), |l| l.path().to_string());
    let (mut leader, leader_latency_us) = crate::motion::teleop::leader::Leader::open(&leader_path, bus, &leader_arm)?;

    let (target, follower_servos) = target.in_real_time()?;
    let mut driver = Driver::open(target, arm.as_deref(), err)?;
    if driver.joints() != leader.joints() {
        bail!(
            "the leader arm {} has {} joints, the follower {} has {}: teleoperation maps joint to joint",
            leader_arm.name,
            leader.joints(),
            driver.arm().name,
            driver.joints()
        );
    }
    let gripper = leader.has_gripper() && driver.gripper().is_some();
    let settings = Settings::for_follower(&driver, period, lead, max_step, gripper)?;
    let max_step = settings.max_step[0];
    let mut recorder =
        record.map(|p| crate::motion::teleop::record::Recorder::create(p, driver.joints(), gripper)).transpose()?;

    let until = match (duration, &simulated_leader) {
        (Some(d), _) => Some(Duration::from_secs_f64(d)),
        // The script's end and a little for the follower to get there.
        (None, Some(l)) => Some(l.duration() + Duration::from_millis(200)),
        (None, None) => None,
    };
    writeln!(
        err,
        "teleop: leader {} on {} (adapter latency {:.1} ms) drives follower {} at {:.0} Hz, {:.1} ms ahead, at most \
         {:.4} rad per step{}",
        leader_arm.name,
        source.port,
        leader_latency_us as f64 * 1e-3,
        driver.arm().name,
        rate,
        lead.as_secs_f64() * 1e3,
        max_step,
        if until.is_none() { "; Ctrl-C ends it" } else { "" }
    )?;
    if let Some(l) = simulated_leader.as_mut() {
        l.start()?;
    }
    if let Some(g) = guard.as_deref_mut() {
        let measured: Vec<f64> = driver.status()?.measured.iter().map(|&x| f64::from(x)).collect();
        g.begin(&measured);
    }
    let mut read = || {
        let mut reading = leader.read()?;
        if let Some(g) = guard.as_deref_mut() {
            g.check(&mut reading);
        }
        Ok(reading)
    };
    let mut done = |elapsed: Duration| interrupt::requested() || until.is_some_and(|u| elapsed >= u);
    let figures = crate::motion::teleop::stream::run(&mut driver, &mut read, &settings, recorder.as_mut(), &mut done);
    let figures = match figures {
        Ok(f) => f,
        Err(e) => {
            let _ = driver.stop();
            return Err(e);
        }
    };
    let (code, rest) = if interrupt::requested() {
        (driver.stop_after_interrupt(err)?, None)
    } else {
        match driver.wait_until_rest(10.0)? {
            Waited::Done(status) => (0, Some(status.measured.iter().map(|&x| f64::from(x)).collect::<Vec<_>>())),
            Waited::Interrupted => (driver.stop_after_interrupt(err)?, None),
        }
    };
    let recorded = recorder.map(crate::motion::teleop::record::Recorder::finish).transpose()?;
    let monitor = follower_servos.as_ref().and_then(PtyServer::monitor);
    driver.close(err)?;
    Ok(Session { figures, ending: Ending { rest, monitor, recorded }, code })
}

/// How a session ended.
pub struct Ending {
    /// The follower's measured joints once at rest (`None` after Ctrl-C).
    pub rest: Option<Vec<f64>>,
    /// The simulated follower servos' safety monitor.
    pub monitor: Option<crate::sim::monitor::MonitorReport>,
    /// The keyframe file written.
    pub recorded: Option<PathBuf>,
}

/// The session's figures as JSON.
pub fn report_json(f: &Figures, period: Duration, lead: Duration, ending: &Ending) -> serde_json::Value {
    let (monitor, recorded) = (ending.monitor.as_ref(), ending.recorded.as_deref());
    let (q50, q99) = (quantile(&f.queued_ms, 0.5), quantile(&f.queued_ms, 0.99));
    let (g50, g99) = (quantile(&f.goal_ms, 0.5), quantile(&f.goal_ms, 0.99));
    let (t50, t99, tmax) = (quantile(&f.tracking, 0.5), quantile(&f.tracking, 0.99), quantile(&f.tracking, 1.0));
    json!({
            "keyframes": f.keyframes, "seconds": f.seconds, "rate_hz": f.rate_hz(),
            "period_ms": period.as_secs_f64() * 1e3, "lead_ms": lead.as_secs_f64() * 1e3,
            "late_iterations": f.late_iterations, "read_failures": f.read_failures,
            "latency_ms": {"read_to_queued_p50": q50, "read_to_queued_p99": q99, "read_to_goal_p50": g50, "read_to_goal_p99": g99},
            "late_keyframes": f.late_keyframes, "underruns": f.underruns, "restarts": f.restarts, "retimed": f.retimed,
            "clamped_steps": f.clamped_steps, "limited_values": f.limited_values,
            "tracking_rad": {"p50": t50, "p99": t99, "max": tmax},
            "monitor": monitor.map(|m| json!({"goals": m.checked, "violations": m.violation_count, "max_step_ratio": m.max_step_ratio,
                                              "contacts": m.contacts.as_ref().map(|c| c.json())})),
            "recorded": recorded.map(|p| p.display().to_string()),
            "follower_at_rest": ending.rest,
            "collision_stops": f.collision_stops, "last_collision": f.last_collision,
    })
}

/// The session's figures: on `out`, one line of JSON with `json`, else a few lines of text.
pub fn report(
    f: &Figures,
    period: Duration,
    lead: Duration,
    ending: &Ending,
    as_json: bool,
    out: &mut dyn Write,
) -> Result<()> {
    let (monitor, recorded) = (ending.monitor.as_ref(), ending.recorded.as_deref());
    let (q50, q99) = (quantile(&f.queued_ms, 0.5), quantile(&f.queued_ms, 0.99));
    let (g50, g99) = (quantile(&f.goal_ms, 0.5), quantile(&f.goal_ms, 0.99));
    let (t50, t99, tmax) = (quantile(&f.tracking, 0.5), quantile(&f.tracking, 0.99), quantile(&f.tracking, 1.0));
    if as_json {
        writeln!(out, "{}", report_json(f, period, lead, ending))?;
        return Ok(());
    }
    writeln!(
        out,
        "teleop: {} keyframes in {:.2} s: {:.1} Hz ({} late iterations, {} failed leader reads)",
        f.keyframes,
        f.seconds,
        f.rate_hz(),
        f.late_iterations,
        f.read_failures
    )?;
    writeln!(
        out,
        "latency: read to goal p50 {g50:.1} ms, p99 {g99:.1} ms (read to queued on the follower p50 {q50:.1} ms, p99 \
         {q99:.1} ms; {} keyframes queued after the player needed them); {} underruns, {} keyframes retimed after one, {} \
         restarts",
        f.late_keyframes, f.underruns, f.retimed, f.restarts
    )?;
    writeln!(
        out,
        "safety: {} steps clamped, {} values brought into range; follower setpoint against the leader one lead \
         earlier: p50 {t50:.4} rad, p99 {t99:.4} rad, max {tmax:.4} rad",
        f.clamped_steps, f.limited_values
    )?;
    if let Some(m) = monitor {
        writeln!(out, "safety monitor (simulated follower servos): {}", m.summary())?;
    }
    if let Some(last) = &f.last_collision {
        writeln!(
            out,
            "collision: the follower was held short of a contact {} times (last: {last}); it held there until the \
             leader moved away",
            f.collision_stops
        )?;
    }
    if let Some(q) = &ending.rest {
        writeln!(
            out,
            "follower at rest at joints {}",
            q.iter().map(|x| format!("{x:.4}")).collect::<Vec<_>>().join(", ")
        )?;
    }
    if let Some(p) = recorded {
        writeln!(out, "recorded: {} (replay with `armctl play {}`)", p.display(), p.display())?;
    }
    Ok(())
}
