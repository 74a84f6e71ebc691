//! Every keyframe of a Cartesian file solved on the host before anything is sent, by the closed
//! form where the arm's geometry has one (the numerical solver elsewhere), each seeded from the
//! one before: the firmware solves each again at its push and refuses one it cannot reach, but it
//! stops at the first. Here the user hears of all of them at once, with how far each is.

use anyhow::{bail, Result};
use kinematics::ik::{IkConfig, IkStatus};

use super::CartesianKeyframes;
use crate::arm::dof::{DynArm, IkOutcome, IkRequest, Scalar, SolverName};

/// At most this many unreachable keyframes are named in the message; the rest are counted.
const NAMED: usize = 5;

/// A tool target solved on the host as the firmware would accept it: the closed form nearest
/// `seed` where the arm has one, else damped least squares with restarts, in f64 at the
/// firmware's tolerances (it solves in f32), so that a target reached here is one the firmware
/// accepts too. `seed` `None` is the middle of the limits.
pub fn solve(
    arm: &dyn DynArm,
    position: [f64; 3],
    quaternion_wxyz: Option<[f64; 4]>,
    seed: Option<Vec<f64>>,
) -> Result<IkOutcome> {
    let (position_tolerance, orientation_tolerance) = Scalar::F32.default_tolerances();
    arm.solve(&IkRequest {
        position,
        quaternion_wxyz,
        seed,
        solver: SolverName::Auto,
        config: IkConfig { position_tolerance, orientation_tolerance, ..IkConfig::default() },
        scalar: Scalar::F64,
        tilt_only: true,
    })
}

/// Fails, naming the file lines, if any keyframe is out of reach; `at(line)` says where a line is.
/// Returns the joints of each keyframe, as solved.
pub fn check(arm: &dyn DynArm, k: &CartesianKeyframes, at: &dyn Fn(usize) -> String) -> Result<Vec<Vec<f64>>> {
    let mut seed: Option<Vec<f64>> = None;
    let mut missed = Vec::new();
    let mut solved = Vec::with_capacity(k.positions.len());
    for (i, position) in k.positions.iter().enumerate() {
        let outcome = solve(arm, *position, k.orientations.as_ref().map(|o| o[i]), seed.clone())?;
        if outcome.status == IkStatus::Converged {
            solved.push(outcome.q.clone());
            seed = Some(outcome.q);
        } else {
            let angle = match k.orientations {
                Some(_) => format!(" and {:.1} degrees", outcome.orientation_error.to_degrees()),
                None => String::new(),
            };
            missed.push(format!(
                "{} (the closest pose is {:.1} mm{angle} away)",
                at(k.lines[i]),
                outcome.position_error * 1e3
            ));
        }
    }
    if missed.is_empty() {
        return Ok(solved);
    }
    let more = match missed.len().saturating_sub(NAMED) {
        0 => String::new(),
        n => format!(", and {n} more"),
    };
    let named: Vec<&str> = missed.iter().take(NAMED).map(String::as_str).collect();
    bail!(
        "{} of {} Cartesian keyframes are unreachable for the arm {}: {}{more}; nothing was sent, nothing moved",
        missed.len(),
        k.positions.len(),
        arm.spec().name,
        named.join("; ")
    )
}
