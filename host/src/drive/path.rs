//! The path of a Cartesian move, decided on the host before anything is sent: the straight line is
//! checked by IK as the firmware will track it, and where it is blocked the move goes by joints
//! (or, with `--path line`, is refused), with the reason in words. `armctl move` and the live
//! target of `armctl view` decide alike.

use anyhow::Result;
use firmware::link::message::{CartesianTarget, HostMessage, MovePath, NakReason, Status, Timing, MAX_SPEED};
use kinematics::ik::IkStatus;

use super::session::{check_joints, Driver};
use crate::link::client::LinkError;
use crate::motion::line::{Blocked, Line};
use crate::motion::reach;

/// The path to send for a move asked to go by `asked`, and where the line is blocked if it is:
/// a blocked line goes by joints (for `Line` too: the caller refuses it instead, with the reason).
pub(crate) fn decide(
    driver: &Driver,
    start: &Status,
    target: &CartesianTarget,
    asked: MovePath,
) -> Result<(MovePath, Option<Blocked>)> {
    if asked == MovePath::Joint {
        return Ok((MovePath::Joint, None));
    }
    match check_line(driver, start, target)? {
        Ok(_) => Ok((asked, None)),
        Err(blocked) => Ok((MovePath::Joint, Some(blocked))),
    }
}

/// Sends the move to `target` by `path` (as [`decide`] chose it). The firmware's IK (f32, a budget
/// sized for its loop) can miss a solution that exists: where it refuses the target as unreachable
/// (but for `Line`, which asks for the firmware's tracking), the host's solution is tried, and the
/// arm goes there by a joint move. `Ok(Ok(true))` if the host's solution was sent, `Ok(Err(_))`
/// with the firmware's refusal if not even the host finds one, `Err` for a host-side failure.
pub(crate) fn send(
    driver: &mut Driver,
    start: &Status,
    target: CartesianTarget,
    timing: Timing,
    path: MovePath,
) -> Result<Result<bool, LinkError>> {
    match driver.request(&HostMessage::MoveTo { target, timing, path }) {
        Ok(_) => Ok(Ok(false)),
        Err(LinkError::Nak(NakReason::Unreachable)) if path != MovePath::Line => {
            let Some(q) = host_solution(driver, start, &target)? else {
                return Ok(Err(LinkError::Nak(NakReason::Unreachable)));
            };
            let positions = check_joints(driver, &q, "the host's solution")?;
            // A tool speed means nothing to a joint move: as fast as the limits allow, as
            // `armctl joints` goes by default; a duration is kept.
            let timing = match timing {
                Timing::MaxSpeed(_) => Timing::MaxSpeed(MAX_SPEED),
                other => other,
            };
            Ok(driver.request(&HostMessage::MoveJoints { positions, timing }).map(|_| true))
        }
        Err(e) => Ok(Err(e)),
    }
}

/// Said where the host's solution was sent: why the arm went by joints.
pub(crate) const SOLVED_ON_HOST: &str =
    "the firmware's IK found no solution from here, so the arm went by joints to the host's";

/// The joints that put the tool on `target`, solved on the host from where the arm is
/// ([`reach::solve`]), or `None` if it finds none within the limits.
pub(crate) fn host_solution(driver: &Driver, start: &Status, target: &CartesianTarget) -> Result<Option<Vec<f64>>> {
    let seed = start.measured.iter().map(|&x| f64::from(x)).collect();
    let position = target.position.map(f64::from);
    let solved = reach::solve(driver.model(), position, target.orientation.map(|o| o.map(f64::from)), Some(seed))?;
    Ok((solved.status == IkStatus::Converged).then_some(solved.q))
}

/// The straight line from the tool (at the joints of `start`) to `target`, checked by IK as the
/// firmware will track it ([`Line::follow`]).
pub(crate) fn check_line(
    driver: &Driver,
    start: &Status,
    target: &CartesianTarget,
) -> Result<Result<Vec<f64>, Blocked>> {
    let q: Vec<f64> = start.measured.iter().map(|&x| f64::from(x)).collect();
    let line = Line {
        from: driver.tool_position(&start.measured)?,
        to: target.position.map(f64::from),
        orientation: target.orientation.map(|o| o.map(f64::from)),
    };
    line.follow(driver.model(), &q, line.points())
}

/// Where the host's check found the line blocked, in words ("the straight line is blocked 75 mm
/// along its 145 mm, joint 1 (shoulder_pan) at its upper limit 1.920").
pub(crate) fn where_blocked(arm: &crate::arm::ArmSpec, b: &Blocked) -> String {
    format!(
        "the straight line is blocked {:.0} mm along its {:.0} mm{}",
        b.along * 1e3,
        b.length * 1e3,
        at_limits(arm, b.q.iter().copied())
    )
}

/// The joints within 0.02 rad (or m) of a limit at `q`, in words (", joint 2 (shoulder_lift) at its
/// upper limit 1.745"), or nothing.
pub(crate) fn at_limits(arm: &crate::arm::ArmSpec, q: impl IntoIterator<Item = f64>) -> String {
    const NEAR: f64 = 0.02;
    let words: Vec<String> = arm
        .joints
        .iter()
        .zip(q)
        .enumerate()
        .filter(|(_, (spec, _))| spec.kind != kinematics::JointKind::Continuous)
        .filter_map(|(j, (spec, x))| {
            let (which, limit) = if x - spec.lower < NEAR {
                ("lower", spec.lower)
            } else if spec.upper - x < NEAR {
                ("upper", spec.upper)
            } else {
                return None;
            };
            Some(format!("joint {} ({}) at its {which} limit {limit:.3}", j + 1, spec.name))
        })
        .collect();
    match words.is_empty() {
        true => String::new(),
        false => format!(", {}", words.join(", ")),
    }
}
