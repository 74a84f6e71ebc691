//! The IK preview of a target, solved on this PC from the measured joints so the page shows where
//! the arm would go before anything is sent: by the closed form where the arm's geometry has one
//! (the solution nearest the joints, a few microseconds, where the arm ends when it follows the
//! line from there), else with the firmware's method and scalar (damped least squares in f32).

use kinematics::ik::{IkConfig, IkStatus};
use serde_json::{json, Value};

use super::api::ApiError;
use super::telemetry::{frames, Placement};
use crate::arm::dof::{DynArm, IkRequest, Scalar, SolverName};

/// Solves for `position` (and `orientation`, w first), both in the arm's base frame, from `seed`:
/// the joints and frames (in `placement`'s frame) of the solution, or a 422 saying why there is
/// none (with the closest joints found).
pub fn solve(
    arm: &dyn DynArm,
    position: [f64; 3],
    orientation: Option<[f64; 4]>,
    seed: Option<Vec<f64>>,
    placement: &Placement,
) -> Result<Value, ApiError> {
    if orientation.is_some() && arm.spec().dof() < 6 {
        return Err(ApiError::bad(format!(
            "orientation: the arm {} has {} joints, too few to choose the tool's orientation; send a position only",
            arm.spec().name,
            arm.spec().dof()
        )));
    }
    let closed_form = arm.closed_form_answers(orientation.is_some());
    let request = IkRequest {
        position,
        quaternion_wxyz: orientation,
        seed: seed.filter(|s| s.len() == arm.spec().dof() && arm.admits(s)),
        solver: if closed_form { SolverName::Analytic } else { SolverName::Dls },
        config: IkConfig::default(),
        scalar: if closed_form { Scalar::F64 } else { Scalar::F32 },
        tilt_only: false,
    };
    let outcome = arm.solve(&request).map_err(|e| ApiError::bad(format!("{e:#}")))?;
    let drawn = frames(arm, &outcome.q, placement).map_err(|e| ApiError::new(500, format!("{e:#}")))?;
    let error_mm = outcome.position_error * 1e3;
    match outcome.status {
        IkStatus::Converged => {
            Ok(json!({"reachable": true, "q": outcome.q, "frames": drawn, "position_error_mm": error_mm}))
        }
        IkStatus::InvalidInput(reason) => Err(ApiError::bad(format!("the solver refused the target: {reason}"))),
        _ => Err(ApiError {
            detail: Some(json!({"reachable": false, "q": outcome.q, "frames": drawn})),
            ..ApiError::new(
                422,
                format!(
                    "unreachable: the closest pose within the joint limits is {error_mm:.1} mm from the target{}",
                    if orientation.is_some() {
                        format!(" and {:.1} degrees off", outcome.orientation_error.to_degrees())
                    } else {
                        String::new()
                    }
                ),
            )
        }),
    }
}
