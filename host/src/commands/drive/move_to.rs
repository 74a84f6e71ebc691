//! `move`: the tool to a point (and orientation), IK on the firmware, by the path
//! [`super::path`] decides; waits until the arm is at rest and reports where the tool is.

use std::io::Write;

use anyhow::anyhow;
use firmware::link::message::{
    CartesianTarget, MovePath, Timing, MAX_REACH, MAX_SPEED, MAX_TIME, QUATERNION_TOLERANCE,
};
use serde::Serialize;

use super::error::{rest, DriveError, DriveResult};
use super::path;
use crate::runtime::driver::{fmt3, Driver};
use crate::support::interrupt;

/// The tool speed of `move` without a speed or a duration (m/s): slow enough to watch.
pub const DEFAULT_TOOL_SPEED: f64 = 0.1;

/// A checked `move`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MoveRequest {
    /// Where.
    pub target: CartesianTarget,
    /// How fast.
    pub timing: Timing,
    /// Which way.
    pub path: MovePath,
    /// Controller seconds to wait.
    pub timeout: f64,
}

impl MoveRequest {
    /// Checks a move's values: a tool position within any desk arm's reach (m), a unit
    /// quaternion w,x,y,z if given, a speed (m/s) or a duration (s), and the wait. The messages
    /// name the command line's options, which name the values in the manual.
    pub fn new(
        position: [f64; 3],
        orientation: Option<[f64; 4]>,
        speed: Option<f64>,
        duration: Option<f64>,
        path: MovePath,
        timeout: f64,
    ) -> DriveResult<Self> {
        let position = check_position(position, "--to").map_err(DriveError::Input)?;
        let orientation = orientation.map(|q| check_quaternion(q, "--quat")).transpose().map_err(DriveError::Input)?;
        let timing = tool_timing(speed, duration).map_err(DriveError::Input)?;
        positive(timeout, f64::from(MAX_TIME), "--timeout", "s").map_err(DriveError::Input)?;
        Ok(Self { target: CartesianTarget { position, orientation }, timing, path, timeout })
    }
}

/// Each value finite, with the words of the command line's number parser
/// ([`crate::support::numbers::numbers`]) for one that is not.
pub fn check_finite(values: &[f64], what: &str) -> anyhow::Result<()> {
    match values.iter().position(|x| !x.is_finite()) {
        Some(i) => Err(anyhow!("{what}: value {} ({:?}) is not a finite number", i + 1, format!("{:?}", values[i]))),
        None => Ok(()),
    }
}

/// A tool position x,y,z (m) within any desk arm's reach of its base (or of the world origin).
pub fn check_position(position: [f64; 3], what: &str) -> anyhow::Result<[f32; 3]> {
    check_finite(&position, what)?;
    for (value, axis) in position.iter().zip(["x", "y", "z"]) {
        if value.abs() > f64::from(MAX_REACH) {
            anyhow::bail!("{what}: {axis} = {value} m is more than {MAX_REACH} m from the base, beyond any desk arm");
        }
    }
    Ok(position.map(|x| x as f32))
}

/// A unit quaternion w,x,y,z.
pub fn check_quaternion(q: [f64; 4], what: &str) -> anyhow::Result<[f32; 4]> {
    check_finite(&q, what)?;
    let norm = q.iter().map(|x| x * x).sum::<f64>().sqrt();
    if (norm - 1.0).abs() > f64::from(QUATERNION_TOLERANCE) {
        anyhow::bail!("{what}: w,x,y,z must be a unit quaternion; its norm is {norm:.6}");
    }
    Ok(q.map(|x| x as f32))
}

/// A positive finite number no larger than `max`.
pub fn positive(value: f64, max: f64, what: &str, unit: &str) -> anyhow::Result<f32> {
    if !(value.is_finite() && value > 0.0 && value <= max) {
        anyhow::bail!("{what}: {value} {unit} must be above 0 and at most {max} {unit}");
    }
    Ok(value as f32)
}

/// A tool move's timing: a duration, else a speed along the line (default
/// [`DEFAULT_TOOL_SPEED`]).
pub fn tool_timing(speed: Option<f64>, duration: Option<f64>) -> anyhow::Result<Timing> {
    Ok(match (duration, speed) {
        (Some(_), Some(_)) => anyhow::bail!("give speed or duration, not both (nothing was sent)"),
        (Some(d), None) => Timing::Duration(positive(d, f64::from(MAX_TIME), "--duration", "s")?),
        (None, speed) => {
            Timing::MaxSpeed(positive(speed.unwrap_or(DEFAULT_TOOL_SPEED), f64::from(MAX_SPEED), "--speed", "m/s")?)
        }
    })
}

/// What `move` did.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct MoveReport {
    /// Always "move".
    pub command: &'static str,
    /// The way the tool went: "line", "line, then joints", "joint" or "planned" (by joints around
    /// what was in the way of the line and of the straight joint path, for an arm with collision
    /// geometry).
    pub path: &'static str,
    /// Where the straight line was found blocked (mm along it), if it was: by the host's check
    /// before the move (the arm then went by joints), or by the firmware on the way (it went the
    /// rest of the way by joints), as its status reports.
    pub line_blocked_mm: Option<f64>,
    /// Whether the arm went by joints to the host's IK solution, the firmware's having found none.
    pub solved_on_host: bool,
    /// The target (m).
    #[serde(serialize_with = "super::as_list")]
    pub target: [f64; 3],
    /// The target orientation, w first.
    #[serde(serialize_with = "super::as_optional_list")]
    pub quaternion_wxyz: Option<[f32; 4]>,
    /// The tool's position at rest (m), by forward kinematics of the measured joints.
    #[serde(serialize_with = "super::as_list")]
    pub reached: [f64; 3],
    /// Its distance from the target (mm).
    pub error_mm: f64,
    /// The orientation's angle from the target's (degrees), if one was given; on an arm of fewer
    /// than six joints, the tilt's (the angle between the tool's and the target's view of the
    /// base's z), since such an arm's yaw follows its pan.
    pub orientation_error_deg: Option<f64>,
    /// Controller seconds from the request to rest.
    pub time_s: f64,
    /// The measured joints at rest.
    pub joints: Vec<f32>,
    /// Why the arm went by joints, in words ("the straight line is blocked 75 mm along its 145 mm,
    /// joint 1 (shoulder_pan) at its upper limit 1.920, so the arm went by joints").
    #[serde(skip)]
    pub why: Option<String>,
}

impl MoveReport {
    /// The report as `armctl move` prints it.
    pub fn text(&self) -> String {
        let angle = self.orientation_error_deg.map(|a| format!(", orientation error {a:.2} deg")).unwrap_or_default();
        let how = self.why.as_ref().map(|why| format!("; {why}")).unwrap_or_default();
        format!(
            "move: target {} m, reached {} m, error {:.2} mm{angle}, took {:.2} s{how}",
            fmt3(&self.target),
            fmt3(&self.reached),
            self.error_mm,
            self.time_s
        )
    }
}

/// Moves the tool to the request's target and waits until the arm is at rest. Torque is switched
/// on if it is off (said on `notes`), and off again if the move is refused.
pub fn move_to(driver: &mut Driver, request: &MoveRequest, notes: &mut dyn Write) -> DriveResult<MoveReport> {
    let MoveRequest { target, timing, path, timeout } = *request;
    let (start, switched) = driver.ready_to_move()?;
    let shown = fmt3(&target.position.map(f64::from));
    interrupt::catch();
    let route = match path::take(driver, &start, target, timing, path) {
        Ok(route) => route,
        Err(refused) => {
            let undone = driver.undo_torque(switched);
            return Err(DriveError::failed(format!(
                "move to {shown} m: {}; nothing moved{undone}{}",
                refused.reason, refused.hint
            )));
        }
    };
    Driver::note_torque(switched, notes)?;
    let status = rest(driver, timeout)?;
    let pose = driver.tool_pose(&status.measured)?;
    let reached: [f64; 3] = pose.translation.into();
    let goal = target.position.map(f64::from);
    let error_mm = 1e3 * (0..3).map(|i| (reached[i] - goal[i]).powi(2)).sum::<f64>().sqrt();
    // An arm of fewer than six joints holds only the tilt (its yaw follows the pan: the
    // firmware's `Target::Tilt`), so that is what is measured there.
    let tilt_only = driver.arm().dof() < 6;
    let orientation_error_deg = target.orientation.map(|q| {
        let q = q.map(f64::from);
        if tilt_only { tilt_angle(&q, &pose.rotation) } else { angle(&q, &pose.quaternion_wxyz()) }.to_degrees()
    });
    let outcome = path::outcome(driver.arm(), &route, &status, error_mm)
        .map_err(|e| DriveError::failed(format!("move to {shown} m: {e}")))?;
    Ok(MoveReport {
        command: "move",
        path: outcome.path,
        line_blocked_mm: outcome.blocked_at.map(|at| at * 1e3),
        solved_on_host: route.solved_on_host,
        target: goal,
        quaternion_wxyz: target.orientation,
        reached,
        error_mm,
        orientation_error_deg,
        time_s: f64::from(status.time - start.time),
        joints: status.measured.to_vec(),
        why: outcome.why,
    })
}

/// Angle between the rotations of two unit quaternions w, x, y, z (q and -q are one rotation).
/// The angle between the base's z seen from a tool at `rotation` and from one at the quaternion
/// `target` (w first): zero when the two are tilted alike, whatever their turn about the base's z.
fn tilt_angle(target: &[f64; 4], rotation: &kinematics::nalgebra::Matrix3<f64>) -> f64 {
    let Some(t) = kinematics::Pose::rotation_from_quaternion_wxyz(*target) else { return f64::NAN };
    let (a, b) = (rotation.row(2).transpose(), t.row(2).transpose());
    a.cross(&b).norm().atan2(a.dot(&b))
}

fn angle(a: &[f64; 4], b: &[f64; 4]) -> f64 {
    let dot = a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>().abs().min(1.0);
    2.0 * dot.acos()
}
