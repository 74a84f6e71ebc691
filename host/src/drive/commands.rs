//! The arm-driving commands: each checks what the user typed before connecting ([`Request::parse`]),
//! then runs against the connected firmware ([`run`]).

use std::io::Write;

use anyhow::{anyhow, bail, Result};
use firmware::link::message::{
    CartesianTarget, HostMessage, MoveOutcome, MovePath, NakReason, PathTaken, RunState, Status, Timing, MAX_REACH,
    MAX_SPEED, MAX_TIME, QUATERNION_TOLERANCE,
};
use serde_json::json;

use super::args::{DriveCommand, JointsArgs, MoveArgs, OnOff, PathArg};
use super::gripper::GripperRequest;
use super::interrupt;
use super::path::{at_limits, decide, send, where_blocked, SOLVED_ON_HOST};
use super::play::{self, Plan};
use super::session::{check_joints, fmt3, fmt_list, Driver, Waited};
use crate::args::numbers as parse;
use crate::link::client::LinkError;

/// The tool speed of `move` without --speed or --duration (m/s): slow enough to watch.
pub const DEFAULT_TOOL_SPEED: f64 = 0.1;

/// A command with its input checked and converted.
pub enum Request {
    /// `move`.
    Move {
        /// Where, as the user typed it (checked).
        target: CartesianTarget,
        /// How fast.
        timing: Timing,
        /// Which way.
        path: MovePath,
        /// Controller seconds to wait.
        timeout: f64,
    },
    /// `joints`.
    Joints {
        /// Joint values (count checked against the arm after connecting).
        q: Vec<f64>,
        /// How fast.
        timing: Timing,
        /// Controller seconds to wait.
        timeout: f64,
    },
    /// `play`.
    Play(Plan),
    /// `status`.
    Status,
    /// `stop`.
    Stop,
    /// `torque on|off`.
    Torque(bool),
    /// `gripper`.
    Gripper(GripperRequest),
}

impl Request {
    /// Checks a command's arguments (and reads a `play` file) without connecting.
    pub fn parse(command: &DriveCommand) -> Result<Self> {
        Ok(match command {
            DriveCommand::Move(args) => parse_move(args)?,
            DriveCommand::Joints(args) => parse_joints(args)?,
            DriveCommand::Play(args) => Request::Play(Plan::read(&args.file, args.timeout)?),
            DriveCommand::Status(_) => Request::Status,
            DriveCommand::Stop(_) => Request::Stop,
            DriveCommand::Torque(args) => Request::Torque(args.state == OnOff::On),
            DriveCommand::Gripper(args) => Request::Gripper(GripperRequest::parse(args)?),
        })
    }
}

/// A positive finite number no larger than `max`.
fn positive(value: f64, max: f64, what: &str, unit: &str) -> Result<f32> {
    if !(value.is_finite() && value > 0.0 && value <= max) {
        bail!("{what}: {value} {unit} must be above 0 and at most {max} {unit}");
    }
    Ok(value as f32)
}

fn parse_move(args: &MoveArgs) -> Result<Request> {
    let [to] = args.to.as_slice() else {
        bail!("--to is given {} times: once for one arm (with --rig, once per arm as ARM=x,y,z)", args.to.len());
    };
    let quat = match args.quat.as_slice() {
        [] => None,
        [quat] => Some(quat.as_str()),
        more => bail!("--quat is given {} times: at most once for one arm", more.len()),
    };
    let position = parse_position(to, "--to")?;
    let orientation = quat.map(|text| parse_quaternion(text, "--quat")).transpose()?;
    let (timing, path) = parse_motion(args)?;
    Ok(Request::Move { target: CartesianTarget { position, orientation }, timing, path, timeout: args.timeout })
}

/// A tool position x,y,z (m) within any desk arm's reach of its base (or of the world origin).
pub fn parse_position(text: &str, what: &str) -> Result<[f32; 3]> {
    let position = parse::fixed::<3>(text, what)?;
    for (value, axis) in position.iter().zip(["x", "y", "z"]) {
        if value.abs() > f64::from(MAX_REACH) {
            bail!("{what}: {axis} = {value} m is more than {MAX_REACH} m from the base, beyond any desk arm");
        }
    }
    Ok(position.map(|x| x as f32))
}

/// A unit quaternion w,x,y,z.
pub fn parse_quaternion(text: &str, what: &str) -> Result<[f32; 4]> {
    let q = parse::fixed::<4>(text, what)?;
    let norm = q.iter().map(|x| x * x).sum::<f64>().sqrt();
    if (norm - 1.0).abs() > f64::from(QUATERNION_TOLERANCE) {
        bail!("{what}: w,x,y,z must be a unit quaternion; its norm is {norm:.6}");
    }
    Ok(q.map(|x| x as f32))
}

/// A move's timing and path, as `move` takes them.
pub fn parse_motion(args: &MoveArgs) -> Result<(Timing, MovePath)> {
    let timing = match args.duration {
        Some(d) => Timing::Duration(positive(d, f64::from(MAX_TIME), "--duration", "s")?),
        None => Timing::MaxSpeed(positive(
            args.speed.unwrap_or(DEFAULT_TOOL_SPEED),
            f64::from(MAX_SPEED),
            "--speed",
            "m/s",
        )?),
    };
    positive(args.timeout, f64::from(MAX_TIME), "--timeout", "s")?;
    let path = match args.path {
        PathArg::Auto => MovePath::Auto,
        PathArg::Line => MovePath::Line,
        PathArg::Joint => MovePath::Joint,
    };
    Ok((timing, path))
}

fn parse_joints(args: &JointsArgs) -> Result<Request> {
    let q = parse::numbers(&args.q, "--q")?;
    if q.is_empty() {
        bail!("--q: no joint values given");
    }
    let timing = match (args.duration, args.speed) {
        (Some(d), _) => Timing::Duration(positive(d, f64::from(MAX_TIME), "--duration", "s")?),
        (None, Some(s)) => Timing::MaxSpeed(positive(s, f64::from(MAX_SPEED), "--speed", "rad/s")?),
        // As fast as the joint limits allow: they are far below this.
        (None, None) => Timing::MaxSpeed(MAX_SPEED),
    };
    positive(args.timeout, f64::from(MAX_TIME), "--timeout", "s")?;
    Ok(Request::Joints { q, timing, timeout: args.timeout })
}

/// Runs a checked request against the connected firmware; returns the exit code.
pub fn run(driver: &mut Driver, request: Request, json: bool, out: &mut dyn Write, err: &mut dyn Write) -> Result<i32> {
    match request {
        Request::Status => {
            let status = driver.status()?;
            print_status(driver, &status, json, out)?;
            Ok(0)
        }
        Request::Stop => {
            let status = driver.stop()?;
            let at = driver.tool_position(&status.measured)?;
            if json {
                writeln!(
                    out,
                    "{}",
                    json!({"command": "stop", "state": status.state, "tool": at, "joints": status.measured})
                )?;
            } else {
                writeln!(
                    out,
                    "stopped: {:?} at {} m (joints {})",
                    status.state,
                    fmt3(&at),
                    fmt_list(&status.measured)
                )?;
            }
            Ok(0)
        }
        Request::Torque(on) => {
            let result = if on { driver.torque_on() } else { driver.request(&HostMessage::Torque { on }) };
            result.map_err(|e| anyhow!("torque {}: {e}", if on { "on" } else { "off" }))?;
            let status = driver.status()?;
            if json {
                writeln!(out, "{}", json!({"command": "torque", "on": on, "state": status.state}))?;
            } else {
                writeln!(out, "torque {}: state {:?}", if on { "on" } else { "off" }, status.state)?;
            }
            Ok(0)
        }
        Request::Move { target, timing, path, timeout } => {
            let (start, switched) = driver.ready_to_move()?;
            let shown = fmt3(&target.position.map(f64::from));
            // The line first, as the firmware will track it: blocked, --path line refuses before
            // anything moves, and auto goes by joints from the start.
            let (sent, blocked_ahead) = match decide(driver, &start, &target, path) {
                Ok(decided) => decided,
                Err(e) => bail!("move to {shown} m: {e:#}; nothing moved{}", driver.undo_torque(switched)),
            };
            if let (MovePath::Line, Some(b)) = (path, &blocked_ahead) {
                bail!(
                    "move to {shown} m: {}; nothing moved{}; --path auto or joint goes there by joints",
                    where_blocked(driver.arm(), b),
                    driver.undo_torque(switched)
                );
            }
            let mut path = sent;
            interrupt::catch();
            let by_host = match send(driver, &start, target, timing, path) {
                Ok(Ok(by_host)) => by_host,
                Ok(Err(e)) => {
                    let either = match (&e, path) {
                        (LinkError::Nak(NakReason::Unreachable), MovePath::Auto | MovePath::Joint) => {
                            ", and the host's IK finds no solution either"
                        }
                        _ => "",
                    };
                    bail!("move to {shown} m: {e}{either}; nothing moved{}", driver.undo_torque(switched))
                }
                Err(e) => bail!("move to {shown} m: {e:#}; nothing moved{}", driver.undo_torque(switched)),
            };
            if by_host {
                path = MovePath::Joint;
            }
            Driver::note_torque(switched, err)?;
            let status = match driver.wait_until_rest(timeout)? {
                Waited::Done(status) => status,
                Waited::Interrupted => return driver.stop_after_interrupt(err),
            };
            let pose = driver.tool_pose(&status.measured)?;
            let reached: [f64; 3] = pose.translation.into();
            let goal = target.position.map(f64::from);
            let error_mm = 1e3 * (0..3).map(|i| (reached[i] - goal[i]).powi(2)).sum::<f64>().sqrt();
            let angle_deg = target.orientation.map(|q| angle(&q.map(f64::from), &pose.quaternion_wxyz()).to_degrees());
            let took = f64::from(status.time - start.time);
            // The firmware follows the straight line, and finishes by joints where the line runs
            // into the joint limits (it counts each time it does); with --path line it stops there.
            let blocked = status.errors.line_fallbacks > start.errors.line_fallbacks;
            if path == MovePath::Line && error_mm > 1.0 {
                bail!(
                    "move to {shown} m: the straight line ran into the joint limits: stopped {error_mm:.1} mm short{}; \
                     --path auto finishes such a move by joints",
                    at_limits(driver.arm(), status.measured.iter().map(|&x| f64::from(x)))
                );
            }
            let path = match path {
                MovePath::Joint => "joint",
                _ if blocked => "line, then joints",
                _ => "line",
            };
            let ahead = blocked_ahead
                .as_ref()
                .map(|b| format!("; {}, so the arm went by joints", where_blocked(driver.arm(), b)))
                .or_else(|| by_host.then(|| format!("; {SOLVED_ON_HOST}")));
            if json {
                let v = json!({
                    "command": "move",
                    "path": path,
                    "line_blocked_mm": blocked_ahead.as_ref().map(|b| b.along * 1e3),
                    "solved_on_host": by_host,
                    "target": goal,
                    "quaternion_wxyz": target.orientation,
                    "reached": reached,
                    "error_mm": error_mm,
                    "orientation_error_deg": angle_deg,
                    "time_s": took,
                    "joints": status.measured,
                });
                writeln!(out, "{v}")?;
            } else {
                let angle = angle_deg.map(|a| format!(", orientation error {a:.2} deg")).unwrap_or_default();
                let how = match (&ahead, blocked) {
                    (Some(ahead), _) => ahead.as_str(),
                    (None, true) => {
                        "; the straight line ran into the joint limits, so the arm went the rest of the way by joints"
                    }
                    (None, false) => "",
                };
                writeln!(
                    out,
                    "move: target {shown} m, reached {} m, error {error_mm:.2} mm{angle}, took {took:.2} s{how}",
                    fmt3(&reached)
                )?;
            }
            Ok(0)
        }
        Request::Joints { q, timing, timeout } => {
            let positions = check_joints(driver, &q, "--q")?;
            let (start, switched) = driver.ready_to_move()?;
            interrupt::catch();
            let message = HostMessage::MoveJoints { positions: positions.clone(), timing };
            if let Err(e) = driver.request(&message) {
                bail!("joints {}: {e}; nothing moved{}", fmt_list(&positions), driver.undo_torque(switched));
            }
            Driver::note_torque(switched, err)?;
            let status = match driver.wait_until_rest(timeout)? {
                Waited::Done(status) => status,
                Waited::Interrupted => return driver.stop_after_interrupt(err),
            };
            let max_error = positions.iter().zip(&status.measured).map(|(a, b)| (a - b).abs()).fold(0.0f32, f32::max);
            let tool = driver.tool_position(&status.measured)?;
            let took = f64::from(status.time - start.time);
            if json {
                let v = json!({
                    "command": "joints",
                    "target": positions,
                    "reached": status.measured,
                    "max_error": max_error,
                    "tool": tool,
                    "time_s": took,
                });
                writeln!(out, "{v}")?;
            } else {
                writeln!(
                    out,
                    "joints: target {}, reached {} (largest error {max_error:.4}), tool at {} m, took {took:.2} s",
                    fmt_list(&positions),
                    fmt_list(&status.measured),
                    fmt3(&tool)
                )?;
            }
            Ok(0)
        }
        Request::Play(plan) => play::run(driver, plan, json, out, err),
        Request::Gripper(request) => super::gripper::run(driver, request, json, out, err),
    }
}

/// Angle between the rotations of two unit quaternions w, x, y, z (q and -q are one rotation).
fn angle(a: &[f64; 4], b: &[f64; 4]) -> f64 {
    let dot = a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>().abs().min(1.0);
    2.0 * dot.acos()
}

/// `status --json`'s answer: the status with the arm's name and the tool position of the measured
/// joints.
pub fn status_json(driver: &Driver, s: &Status) -> Result<serde_json::Value> {
    let mut v = serde_json::to_value(s)?;
    v["arm"] = json!(driver.arm().name);
    v["tool"] = json!(driver.tool_position(&s.measured)?);
    Ok(v)
}

/// The firmware's account of its last move, as `armctl status` words it.
fn last_move(outcome: Option<&MoveOutcome>) -> String {
    let Some(m) = outcome else { return "none since the arm was configured".to_string() };
    let mm = |m: f32| f64::from(m) * 1e3;
    let blocked = |at: f32| format!("blocked {:.0} mm along its {:.0} mm", mm(at), mm(m.line_length));
    match (m.path, m.blocked_at) {
        (PathTaken::Line, _) => format!("line ({:.0} mm)", mm(m.line_length)),
        (PathTaken::Joints, _) => "joints".to_string(),
        (PathTaken::LineThenJoints, Some(at)) => format!("line, then joints ({})", blocked(at)),
        (PathTaken::LineStopped, Some(at)) => format!("line, stopped there ({})", blocked(at)),
        // The firmware always says where it gave a line up; worded without it all the same.
        (PathTaken::LineThenJoints, None) => "line, then joints".to_string(),
        (PathTaken::LineStopped, None) => "line, stopped where it was blocked".to_string(),
    }
}

/// Prints a status as `armctl status` does (one line of JSON with `json`).
pub fn print_status(driver: &Driver, s: &Status, json: bool, out: &mut dyn Write) -> Result<()> {
    if json {
        writeln!(out, "{}", status_json(driver, s)?)?;
        return Ok(());
    }
    let tool = driver.tool_position(&s.measured)?;
    let ik = &s.ik;
    let e = &s.errors;
    let state = match s.state {
        RunState::Idle => "Idle (holding)".to_string(),
        other => format!("{other:?}"),
    };
    writeln!(out, "arm        {} ({} joints)", driver.arm().name, driver.joints())?;
    writeln!(out, "state      {state}")?;
    writeln!(out, "time       {:.3} s", s.time)?;
    writeln!(out, "measured   {}", fmt_list(&s.measured))?;
    writeln!(out, "setpoints  {}", fmt_list(&s.setpoints))?;
    writeln!(out, "tool       {} m (measured)", fmt3(&tool))?;
    writeln!(out, "queue      {} queued, {} free", s.queued, s.free_slots)?;
    writeln!(out, "last move  {}", last_move(s.last_move.as_ref()))?;
    if let Some(g) = &s.gripper {
        let mm = driver.gripper().map(|spec| f64::from(g.opening).clamp(0.0, 100.0) / 100.0 * spec.opening_mm);
        writeln!(out, "gripper    {}", super::gripper::describe(g, mm))?;
    }
    writeln!(
        out,
        "ik         {}, {} iterations, position error {:.3e} m, orientation error {:.3e} rad",
        if ik.converged { "converged" } else { "not converged" },
        ik.iterations,
        ik.position_error,
        ik.orientation_error
    )?;
    writeln!(
        out,
        "loop       mean {} us, max {} us, {} overruns",
        s.timing.mean_us, s.timing.max_us, s.timing.overruns
    )?;
    writeln!(
        out,
        "errors     link corrupt {}, oversized {}, naks {}, bus timeouts {}, bus errors {}, underruns {}",
        e.link_corrupt, e.link_oversized, e.naks, e.bus_timeouts, e.bus_errors, e.underruns
    )?;
    // Bytes lost before the firmware could read them: a board's receive ring full, its UART
    // overrun (0 where the core runs on this PC).
    writeln!(
        out,
        "link rx    {} bytes dropped (receive ring full), {} UART overruns",
        e.link_dropped, e.link_overruns
    )?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::{last_move, MoveOutcome, PathTaken};

    /// `armctl status`'s line for each way a move can go, in whole millimetres.
    #[test]
    fn the_last_move_in_words() {
        let outcome = |path, blocked_at| MoveOutcome { path, blocked_at, line_length: 0.1449 };
        assert_eq!(last_move(None), "none since the arm was configured");
        assert_eq!(last_move(Some(&outcome(PathTaken::Line, None))), "line (145 mm)");
        assert_eq!(
            last_move(Some(&outcome(PathTaken::LineThenJoints, Some(0.0752)))),
            "line, then joints (blocked 75 mm along its 145 mm)"
        );
        assert_eq!(
            last_move(Some(&outcome(PathTaken::LineStopped, Some(0.0962)))),
            "line, stopped there (blocked 96 mm along its 145 mm)"
        );
        let joints = MoveOutcome { path: PathTaken::Joints, blocked_at: None, line_length: 0.0 };
        assert_eq!(last_move(Some(&joints)), "joints");
    }
}
