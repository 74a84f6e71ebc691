//! `status`, `stop` and `torque`: the controller's state, and the two requests that change it
//! without a target.

use firmware::link::message::{MoveOutcome, PathTaken, RunState, Status};
use serde::Serialize;

use super::error::{DriveError, DriveResult};
use crate::runtime::driver::{fmt3, fmt_list, Driver};

/// `status`: the controller's status with the arm's name and the tool position of the measured
/// joints.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct StatusReport {
    /// The status, as the firmware sent it.
    #[serde(flatten)]
    pub status: Status,
    /// The arm's name.
    pub arm: String,
    /// The tool position (m), by forward kinematics of the measured joints.
    #[serde(serialize_with = "super::as_list")]
    pub tool: [f64; 3],
    /// The gripper's opening in mm, if the arm has a gripper whose span is known.
    #[serde(skip)]
    pub gripper_mm: Option<f64>,
    /// The collision check and its last stop in words, the parts named from the arm's geometry.
    pub collision: String,
}

impl StatusReport {
    /// The status as `armctl status` prints it, a line per part.
    pub fn text(&self) -> String {
        let s = &self.status;
        let ik = &s.ik;
        let e = &s.errors;
        let state = match s.state {
            RunState::Idle => "Idle (holding)".to_string(),
            other => format!("{other:?}"),
        };
        let mut lines = vec![
            format!("arm        {} ({} joints)", self.arm, s.measured.len()),
            format!("state      {state}"),
            format!("time       {:.3} s", s.time),
            format!("measured   {}", fmt_list(&s.measured)),
            format!("setpoints  {}", fmt_list(&s.setpoints)),
            format!("tool       {} m (measured)", fmt3(&self.tool)),
            format!("queue      {} queued, {} free", s.queued, s.free_slots),
            format!("last move  {}", last_move(s.last_move.as_ref())),
            format!("collision  {}", self.collision),
        ];
        // Only once it happened: keyframes that ran out while moving, braked past, then back.
        if s.largest_pass > 0.0 {
            lines.push(format!(
                "stream end braked {:.2} deg past the last keyframe, then went back to it",
                f64::from(s.largest_pass).to_degrees()
            ));
        }
        if let Some(g) = &s.gripper {
            lines.push(format!("gripper    {}", super::gripper::describe(g, self.gripper_mm)));
        }
        lines.push(format!(
            "ik         {}, {} iterations, position error {:.3e} m, orientation error {:.3e} rad",
            if ik.converged { "converged" } else { "not converged" },
            ik.iterations,
            ik.position_error,
            ik.orientation_error
        ));
        lines.push(format!(
            "loop       mean {} us, max {} us, {} overruns",
            s.timing.mean_us, s.timing.max_us, s.timing.overruns
        ));
        lines.push(format!(
            "errors     link corrupt {}, oversized {}, naks {}, bus timeouts {}, bus errors {}, underruns {}",
            e.link_corrupt, e.link_oversized, e.naks, e.bus_timeouts, e.bus_errors, e.underruns
        ));
        // Bytes lost before the firmware could read them: a board's receive ring full, its UART
        // overrun (0 where the core runs on this PC).
        lines.push(format!(
            "link rx    {} bytes dropped (receive ring full), {} UART overruns",
            e.link_dropped, e.link_overruns
        ));
        lines.join("\n")
    }
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
        (PathTaken::CollisionStopped, _) => "stopped short of a collision (see collision)".to_string(),
    }
}

/// The report of a status already read (a stream's observation reads it between keyframes).
pub fn report(driver: &Driver, status: Status) -> DriveResult<StatusReport> {
    let tool = driver.tool_position(&status.measured)?;
    let gripper_mm = status
        .gripper
        .and_then(|g| driver.gripper().map(|spec| f64::from(g.opening).clamp(0.0, 100.0) / 100.0 * spec.opening_mm));
    let collision = super::collision::status_line(driver.arm(), &status);
    Ok(StatusReport { status, arm: driver.arm().name.clone(), tool, gripper_mm, collision })
}

/// Reads the controller's status.
pub fn status(driver: &mut Driver) -> DriveResult<StatusReport> {
    let status = driver.status()?;
    report(driver, status)
}

/// What `stop` did.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct StopReport {
    /// Always "stop".
    pub command: &'static str,
    /// The state it came to rest in.
    pub state: RunState,
    /// The tool position at rest (m).
    #[serde(serialize_with = "super::as_list")]
    pub tool: [f64; 3],
    /// The measured joints at rest.
    pub joints: Vec<f32>,
}

impl StopReport {
    /// The report as `armctl stop` prints it.
    pub fn text(&self) -> String {
        format!("stopped: {:?} at {} m (joints {})", self.state, fmt3(&self.tool), fmt_list(&self.joints))
    }
}

/// Stops the arm (decelerating within its limits, dropping the queue) and waits until it is at
/// rest.
pub fn stop(driver: &mut Driver) -> DriveResult<StopReport> {
    let status = driver.stop()?;
    let tool = driver.tool_position(&status.measured)?;
    Ok(StopReport { command: "stop", state: status.state, tool, joints: status.measured.to_vec() })
}

/// What `torque` did.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct TorqueReport {
    /// Always "torque".
    pub command: &'static str,
    /// Whether it was switched on.
    pub on: bool,
    /// The state after it.
    pub state: RunState,
}

impl TorqueReport {
    /// The report as `armctl torque` prints it.
    pub fn text(&self) -> String {
        format!("torque {}: state {:?}", if self.on { "on" } else { "off" }, self.state)
    }
}

/// Switches torque on (holding where the arm stands; also leaving an emergency stop) or off.
pub fn torque(driver: &mut Driver, on: bool) -> DriveResult<TorqueReport> {
    let result = if on { driver.torque_on() } else { driver.session().torque_off() };
    result.map_err(|e| DriveError::failed(format!("torque {}: {e}", if on { "on" } else { "off" })))?;
    let state = driver.status()?.state;
    Ok(TorqueReport { command: "torque", on, state })
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
