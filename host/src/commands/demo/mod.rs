//! `armctl demo`: the whole product on the PC, without hardware. The firmware application runs
//! in software in the loop ([`crate::runtime::sil`]) against simulated servos; the host drives it over the
//! simulated link exactly as it drives a board: the tool goes to Cartesian targets (IK on the
//! firmware), then plays a pick-and-place path streamed as Cartesian keyframes with flow control,
//! the gripper's opening in them: a simulated object lies at the pick point, and the firmware's
//! gripper closes on it, carries it and lets go at the place point. It prints what was reached,
//! how the grasp went and how the loop ran, and plots planned against measured motion.
//!
//! - [`scenario`]: the targets and the path, drawn from the arm's reachable workspace.
//! - [`grasp`]: how the pick went, read from the recorded ticks.
//! - [`run`](self::run): the run, its measurements and the report.
//!
//! It takes a plain [`DemoRequest`]; the command line's options become one in `cli::demo`. The
//! second scene, two arms of a rig handing the object over (`demo --rig`), is
//! [`crate::rig::handover`], which measures its grasps as [`grasp`] does.

pub mod grasp;
pub mod plot;
mod scenario;

use std::io::Write;
use std::path::PathBuf;
use std::time::Instant;

use anyhow::{anyhow, Context, Result};
use firmware::link::message::{CartesianKeyframe, CartesianTarget, MovePath, Timing};
use serde_json::{json, Value};

use crate::arm::dof::DynArm;
use crate::commands::demo::grasp::Grasp;
use crate::commands::demo::plot::{write_demo_png, DemoTrace, GripperTrace};
use crate::commands::drive::path;
use crate::link::session::Keyframe;
use crate::runtime::connection::open_sil;
use crate::runtime::driver::Driver;
use crate::runtime::gravity::{gravity_parts, Compensation, Gains};
use crate::runtime::sil::{Sil, SilOptions, TraceSample};
use scenario::Scenario;

/// The demo's arm when `--arm` is not given.
pub const DEFAULT_ARM: &str = "so101";

/// Where the demo's plot goes.
#[derive(Clone, Debug, Default, PartialEq)]
pub enum PlotTo {
    /// `demo-ARM.png` in the current directory.
    #[default]
    Default,
    /// This file.
    File(PathBuf),
    /// No plot.
    Nowhere,
}

/// What `armctl demo` runs.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct DemoRequest {
    /// The simulated arm: a preset with servos or an arm file with a [servos] table [default:
    /// [`DEFAULT_ARM`]].
    pub arm: Option<String>,
    /// Where the plot goes.
    pub plot: PlotTo,
    /// The simulated servos; physical ones get the firmware's gravity compensation.
    pub servos: crate::sim::physics::ServoKind,
}

/// One point-to-point move's outcome.
struct Reached {
    target: [f32; 3],
    reached: [f64; 3],
    error_mm: f64,
    time_s: f64,
    ticks_to_1mm: Option<usize>,
    ik_iterations: u16,
}

fn distance(a: [f64; 3], b: [f32; 3]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - f64::from(y)).powi(2)).sum::<f64>().sqrt()
}

fn tool(arm: &dyn DynArm, q: &[f64]) -> Result<[f64; 3]> {
    let p = arm.tool_pose(q)?.translation;
    Ok([p.x, p.y, p.z])
}

/// Controller seconds a move to a target may take before the demo gives up.
const MOVE_TIMEOUT_S: f64 = 20.0;
/// Controller seconds the pick-and-place path may take beyond its keyframes.
const PLAY_TIMEOUT_S: f64 = 60.0;

/// The demo's simulated board behind the driver.
fn sil(d: &mut Driver) -> Result<&mut Sil> {
    d.sil().context("the demo runs on the simulated board")
}

fn to_f64(q: &[f32]) -> Vec<f64> {
    q.iter().map(|x| f64::from(*x)).collect()
}

/// Moves the tool to each target in turn and measures how it got there.
///
/// Each goes as `armctl move` goes ([`crate::commands::drive::path`]: the straight line checked on the host,
/// the firmware's IK tracking it, the host's solution by joints where the firmware finds none),
/// and is waited for as `armctl move` waits.
fn reach_targets(
    d: &mut Driver,
    arm: &dyn DynArm,
    scenario: &Scenario,
    trace: &mut Vec<TraceSample>,
) -> Result<Vec<Reached>> {
    let mut out = Vec::new();
    for &target in &scenario.targets {
        let start = sil(d)?.now_s();
        trace.extend(sil(d)?.take_trace());
        let first_tick = trace.len();
        let from = d.status()?;
        let goal = CartesianTarget { position: target, orientation: None };
        path::take(d, &from, goal, Timing::MaxSpeed(scenario.speed), MovePath::Auto)
            .map_err(|refused| anyhow!("move to {target:?}: {}", refused.reason))?;
        // The status right after the move was accepted reports the IK solve that accepted it.
        let ik_iterations = d.status()?.ik.iterations;
        let end = crate::commands::drive::error::rest(d, MOVE_TIMEOUT_S)?;
        trace.extend(sil(d)?.take_trace());
        let mut ticks_to_1mm = None;
        for (i, sample) in trace[first_tick..].iter().enumerate() {
            if distance(tool(arm, &sample.measured)?, target) < 1e-3 {
                ticks_to_1mm = Some(i + 1);
                break;
            }
        }
        let reached = tool(arm, &to_f64(&end.measured))?;
        out.push(Reached {
            target,
            reached,
            error_mm: distance(reached, target) * 1e3,
            time_s: sil(d)?.now_s() - start,
            ticks_to_1mm,
            ik_iterations,
        });
    }
    Ok(out)
}

/// How the streamed path went.
struct Streamed {
    keyframes: usize,
    acked: usize,
    tool_rms_mm: f64,
    tool_max_mm: f64,
    joint_rms: f64,
    joint_max: f64,
    final_error_mm: f64,
    duration_s: f64,
    /// How the grasp went (`None`: the arm has no gripper).
    grasp: Option<Grasp>,
}

/// Puts the object on the table at the pick point, streams the pick-and-place keyframes (flow
/// control by the client), starts once the queue holds a second of path, and measures the
/// tracking and the grasp while it plays.
fn pick_and_place(
    d: &mut Driver,
    arm: &dyn DynArm,
    scenario: &Scenario,
    trace: &mut Vec<TraceSample>,
) -> Result<Streamed> {
    let gripper = crate::arm::servos::servos_of(arm.spec()).and_then(|s| s.gripper);
    if let Some(width) = scenario.object_mm {
        let follower = crate::arm::dof::build(arm.spec().clone())?;
        sil(d)?.put_object(follower, width, scenario.pick.map(f64::from))?;
    }
    trace.extend(sil(d)?.take_trace());
    let first_tick = trace.len();
    let start = sil(d)?.now_s();
    let keyframes = scenario.keyframes();
    let mut acked = 0;
    let mut started = false;
    for &(time, position, opening) in &keyframes {
        let target = CartesianTarget { position, orientation: None };
        let k = Keyframe::Pose(CartesianKeyframe { time, target, gripper: opening });
        d.session().push(&k).with_context(|| format!("keyframe at {time} s"))?;
        acked += 1;
        if !started && time >= 1.0 {
            d.session().start()?;
            started = true;
        }
    }
    if !started {
        d.session().start()?;
    }
    let end = crate::commands::drive::error::rest(d, PLAY_TIMEOUT_S)?;
    trace.extend(sil(d)?.take_trace());
    let (mut tool_sq, mut tool_max, mut joint_sq, mut joint_max, mut n) = (0.0, 0.0f64, 0.0, 0.0f64, 0usize);
    for s in &trace[first_tick..] {
        let e = distance(tool(arm, &s.measured)?, tool(arm, &s.setpoints)?.map(|x| x as f32)) * 1e3;
        tool_sq += e * e;
        tool_max = tool_max.max(e);
        for (a, b) in s.setpoints.iter().zip(&s.measured) {
            joint_sq += (a - b).powi(2);
            joint_max = joint_max.max((a - b).abs());
        }
        n += 1;
    }
    let joints = arm.spec().dof().max(1);
    let last = keyframes.last().map_or([0.0; 3], |k| k.1);
    let grasp = match (&gripper, sil(d)?.object()) {
        (Some(gripper), Some(object)) => {
            let object = object.position();
            Some(grasp::measure(&trace[first_tick..], start, arm, gripper, scenario, object)?)
        }
        _ => None,
    };
    Ok(Streamed {
        keyframes: keyframes.len(),
        acked,
        tool_rms_mm: (tool_sq / n.max(1) as f64).sqrt(),
        tool_max_mm: tool_max,
        joint_rms: (joint_sq / (n.max(1) * joints) as f64).sqrt(),
        joint_max,
        final_error_mm: distance(tool(arm, &to_f64(&end.measured))?, last) * 1e3,
        duration_s: sil(d)?.now_s() - start,
        grasp,
    })
}

/// The gripper's curves when every sample has it.
fn gripper_trace(samples: &[&TraceSample]) -> Option<GripperTrace> {
    let states: Option<Vec<_>> = samples.iter().map(|s| s.gripper).collect();
    let states = states.filter(|s| !s.is_empty())?;
    Some(GripperTrace {
        goal: states.iter().map(|g| f64::from(g.goal)).collect(),
        opening: states.iter().map(|g| f64::from(g.opening)).collect(),
        load: states.iter().map(|g| f64::from(g.load.abs())).collect(),
        holding: states.iter().map(|g| g.holding).collect(),
    })
}

fn plot(
    path: &std::path::Path,
    arm: &dyn DynArm,
    scenario: &Scenario,
    trace: &[TraceSample],
    phases: Vec<(f64, String)>,
) -> Result<()> {
    let samples: Vec<&TraceSample> = trace.iter().filter(|s| !s.setpoints.is_empty()).collect();
    let mut data = DemoTrace {
        arm: arm.spec().name.clone(),
        joint_names: arm.spec().joints.iter().map(|j| j.name.clone()).collect(),
        time: samples.iter().map(|s| s.time).collect(),
        planned: samples.iter().map(|s| s.setpoints.clone()).collect(),
        measured: samples.iter().map(|s| s.measured.clone()).collect(),
        tool_planned: Vec::new(),
        tool_measured: Vec::new(),
        targets: scenario
            .targets
            .iter()
            .chain(scenario.waypoints.iter().map(|w| &w.1))
            .map(|p| p.map(f64::from))
            .collect(),
        phases,
        gripper: gripper_trace(&samples),
    };
    for s in &samples {
        data.tool_planned.push(tool(arm, &s.setpoints)?);
        data.tool_measured.push(tool(arm, &s.measured)?);
    }
    write_demo_png(path, &data)
}

fn fmt3(p: [f64; 3]) -> String {
    format!("{:7.4} {:7.4} {:7.4}", p[0], p[1], p[2])
}

/// Runs `armctl demo`: the report on `out`, as one line of JSON with `json`; returns the exit code.
pub fn run(request: &DemoRequest, json: bool, out: &mut dyn Write) -> Result<i32> {
    let wall = Instant::now();
    let options =
        SilOptions { servos: request.servos, ..SilOptions::new(request.arm.as_deref().unwrap_or(DEFAULT_ARM))? };
    let mut board = Sil::new(&options)?;
    board.record();
    let mut d = Driver::on(open_sil(board, options.arm.clone())?)?;
    // Physical servos sag: the firmware compensates (nothing sets the simulated board's servos
    // up, so they hold the factory's gains).
    if let crate::sim::physics::ServoKind::Physical(payload) = request.servos {
        let compensation = Compensation::by_default(Gains::Factory, payload.map(|p| p.kg));
        let parts = gravity_parts(&options.arm, &compensation)?;
        d.session().gravity(&parts).context("giving the firmware gravity compensation")?;
    }
    let info = d.info().clone();
    let gripper = d.gripper();
    let arm = crate::arm::dof::build(d.arm().clone())?;
    d.torque_on().context("the simulated servos never reported their positions")?;
    let start = to_f64(&d.status()?.measured);
    let scenario = Scenario::for_arm(arm.as_ref(), &start, gripper.as_ref())?;
    let mut trace = Vec::new();
    let t_targets = sil(&mut d)?.now_s();
    let reached = reach_targets(&mut d, arm.as_ref(), &scenario, &mut trace)?;
    let t_stream = sil(&mut d)?.now_s();
    let streamed = pick_and_place(&mut d, arm.as_ref(), &scenario, &mut trace)?;
    let status = d.status()?;
    trace.extend(sil(&mut d)?.take_trace());
    let plot_path = match &request.plot {
        PlotTo::Default => Some(PathBuf::from(format!("demo-{}.png", arm.spec().name))),
        PlotTo::File(path) => Some(path.clone()),
        PlotTo::Nowhere => None,
    };
    if let Some(path) = &plot_path {
        let phases = vec![(t_targets, "move to targets".to_string()), (t_stream, "pick and place".to_string())];
        plot(path, arm.as_ref(), &scenario, &trace, phases)?;
    }
    let link = d.session().stats();
    let board = sil(&mut d)?;
    let stats = board.stats();
    let monitor = board.monitor().clone();
    let simulated_s = board.now_s();
    let servos = crate::arm::servos::servos_of(&options.arm).context("the simulated arm's servos")?;
    let model = servos.model;
    let bus = format!(
        "{} x {} on {} at {} baud",
        servos.bus_ids().len(),
        model.name,
        if model.protocol == firmware::bus::protocol::Protocol::Dxl2 { "Dynamixel 2.0" } else { "Feetech" },
        options.bus_baud
    );
    let wall_s = wall.elapsed().as_secs_f64();
    if json {
        let targets: Vec<Value> = reached
            .iter()
            .map(|r| {
                json!({"target": r.target, "reached": r.reached, "error_mm": r.error_mm, "time_s": r.time_s,
                "ticks_to_1mm": r.ticks_to_1mm, "ik_iterations": r.ik_iterations})
            })
            .collect();
        let report = json!({
            "arm": info.arm_name.as_str(), "bus": bus, "control_rate_hz": info.control_rate_hz,
            "targets": targets,
            "pick_and_place": {"keyframes": streamed.keyframes, "acked": streamed.acked, "tool_error_rms_mm": streamed.tool_rms_mm,
                "tool_error_max_mm": streamed.tool_max_mm, "joint_error_rms_rad": streamed.joint_rms, "joint_error_max_rad": streamed.joint_max,
                "final_error_mm": streamed.final_error_mm, "duration_s": streamed.duration_s},
            "grasp": streamed.grasp.as_ref().map(|g| g.json(&scenario)),
            "loop": {"ticks": stats.ticks, "late_ticks": stats.late_ticks, "overruns": stats.overruns,
                "loop_time_mean_us": status.timing.mean_us, "deadline_misses": status.timing.overruns,
                "bus_timeouts": status.errors.bus_timeouts, "bus_errors": status.errors.bus_errors, "underruns": status.errors.underruns,
                "link_requests": link.requests, "link_retransmissions": link.retransmissions},
            "safety": {"goals_checked": monitor.checked, "violations": monitor.violation_count, "largest_step_of_limit": monitor.max_step_ratio,
                "contacts": monitor.contacts.as_ref().map(|c| c.json())},
            "plot": plot_path.as_ref().map(|p| p.display().to_string()),
            "simulated_s": simulated_s, "wall_s": wall_s,
        });
        writeln!(out, "{report}")?;
    } else {
        writeln!(
            out,
            "armctl demo: {} ({} joints), {bus}; firmware control loop at {} Hz, in software in the loop",
            info.arm_name, info.joints, info.control_rate_hz
        )?;
        writeln!(out)?;
        writeln!(out, "Cartesian targets (IK on the firmware, tool at most {} m/s):", scenario.speed)?;
        writeln!(
            out,
            "  {:<23}  {:<23}  {:>10}  {:>8}  {:>12}  {:>13}",
            "target (m)", "reached (m)", "error (mm)", "time (s)", "ticks to 1mm", "IK iterations"
        )?;
        for r in &reached {
            let ticks = r.ticks_to_1mm.map_or("never".to_string(), |t| t.to_string());
            writeln!(
                out,
                "  {}  {}  {:>10.3}  {:>8.2}  {:>12}  {:>13}",
                fmt3(r.target.map(f64::from)),
                fmt3(r.reached),
                r.error_mm,
                r.time_s,
                ticks,
                r.ik_iterations
            )?;
        }
        writeln!(out)?;
        writeln!(
            out,
            "Pick and place: {} Cartesian keyframes streamed, {} acknowledged, {:.2} s",
            streamed.keyframes, streamed.acked, streamed.duration_s
        )?;
        writeln!(out, "  tool tracking error (measured against planned): rms {:.2} mm, max {:.2} mm; joints rms {:.4} rad, max {:.4} rad", streamed.tool_rms_mm, streamed.tool_max_mm, streamed.joint_rms, streamed.joint_max)?;
        writeln!(out, "  final tool error to the last keyframe: {:.3} mm", streamed.final_error_mm)?;
        writeln!(out)?;
        match &streamed.grasp {
            Some(grasp) => {
                for line in grasp.lines(&scenario) {
                    writeln!(out, "{line}")?;
                }
            }
            None => writeln!(out, "Grasp: none, the arm has no gripper (the path is played without one)")?,
        }
        writeln!(out)?;
        writeln!(out, "Loop: {} ticks, {} late, {} deadline misses; bus time per tick {} us mean; bus timeouts {}, bus errors {}, queue underruns {}", stats.ticks, stats.late_ticks, status.timing.overruns, status.timing.mean_us, status.errors.bus_timeouts, status.errors.bus_errors, status.errors.underruns)?;
        writeln!(out, "Link: {} requests, {} retransmissions", link.requests, link.retransmissions)?;
        writeln!(
            out,
            "Safety monitor: {} goals checked, {} violations, largest step {:.0}% of the velocity limit",
            monitor.checked,
            monitor.violation_count,
            monitor.max_step_ratio * 100.0
        )?;
        if let Some(contacts) = &monitor.contacts {
            writeln!(out, "Safety monitor, the arm's geometry: {}", contacts.summary())?;
        }
        if let Some(path) = &plot_path {
            writeln!(out, "Plot: {}", path.display())?;
        }
        writeln!(out, "{simulated_s:.1} s simulated in {wall_s:.2} s")?;
    }
    // A violation or a pick that did not pick fails the run; the report above says which.
    let picked = streamed.grasp.as_ref().is_none_or(Grasp::picked);
    Ok(if monitor.violation_count == 0 && picked { 0 } else { 1 })
}
