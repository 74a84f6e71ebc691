//! A joint that ends its move far from its setpoint: something blocks it (an obstacle nobody
//! declared, a hand, the table with the collision check off) or its load is more than its servo
//! carries. Looked at once the arm is at rest after `joints`, `move` and `play`: the move fails
//! naming the joint, and every setpoint is moved back to where its joint stands, so that no servo
//! keeps pushing (a stalled STS3215 heats up and trips its overload within seconds).
//!
//! The bound is far above what a servo leaves at rest: ideal servos stand on their goals, and
//! physical ones within 0.095 rad with 200 g at the tool and no gravity compensation (the largest
//! over 1000 random moves), within millimetres with it (docs/servo-model.md).

use firmware::link::message::{Joints, Status, Timing};
use kinematics::JointKind;

use crate::runtime::driver::Driver;

/// The largest distance from its setpoint a revolute joint may rest at (rad).
pub const BLOCKED_RAD: f32 = 0.2;
/// The same for a prismatic joint (m).
pub const BLOCKED_M: f32 = 0.02;

/// Settles after the first that a joint found short of its setpoint is given while the bus times
/// out (each about 0.2 s of the controller's time when the joint stands still).
const MAX_SETTLES: usize = 5;

/// Joint `j`'s bound at rest and its unit: [`BLOCKED_M`] m for a prismatic joint, else
/// [`BLOCKED_RAD`] rad.
fn bound(driver: &Driver, j: usize) -> (f32, &'static str) {
    match driver.arm().joints.get(j) {
        Some(x) if x.kind == JointKind::Prismatic => (BLOCKED_M, "m"),
        _ => (BLOCKED_RAD, "rad"),
    }
}

/// The joint furthest beyond its bound at rest in `status`, with its name: `(index, name)`.
pub fn blocked_joint(driver: &Driver, status: &Status) -> Option<(usize, String)> {
    let joints = &driver.arm().joints;
    let over = |j: usize| (status.measured[j] - status.setpoints[j]).abs() / bound(driver, j).0;
    (0..status.measured.len().min(status.setpoints.len()))
        .filter(|&j| over(j) > 1.0)
        .max_by(|&a, &b| over(a).total_cmp(&over(b)))
        .map(|j| (j, joints.get(j).map_or_else(|| format!("joint {}", j + 1), |x| x.name.clone())))
}

/// `status` at rest if every joint stands near its setpoint; else the move fails naming the
/// joint that stopped furthest short, after the setpoints are moved to where the joints stand.
pub fn check_at_rest(driver: &mut Driver, status: Status) -> anyhow::Result<Status> {
    if blocked_joint(driver, &status).is_none() {
        return Ok(status);
    }
    // Looked at again after another settle, and again while the bus timed out meanwhile: on a
    // loaded PC the reads can time out for a while, and positions that were not refreshed look
    // like a joint standing still short of its goal when it is still on its way (false stops of
    // wrist_roll and wrist_flex, 0.3 to 0.4 rad short, under busy loops).
    let mut status = status;
    for _ in 0..MAX_SETTLES {
        let timeouts = status.errors.bus_timeouts;
        status = driver.settle(status)?;
        if blocked_joint(driver, &status).is_none() || status.errors.bus_timeouts == timeouts {
            break;
        }
    }
    let Some((j, name)) = blocked_joint(driver, &status) else { return Ok(status) };
    let (at, sent) = (status.measured[j], status.setpoints[j]);
    let unit = bound(driver, j).1;
    let held = Joints::from_slice(&status.measured)
        .ok()
        .and_then(|here| driver.session().move_joints(here, Timing::Duration(0.1)).ok())
        .and_then(|()| driver.wait_until_rest(5.0).ok());
    let after = match held {
        Some(_) => "every joint is now held where it stands",
        None => "holding the joints where they stand was refused: stop the arm or switch its torque off",
    };
    anyhow::bail!(
        "{name} stopped {:.3} {unit} short of its setpoint (at {at:.3}, sent to {sent:.3}): something blocks it, or its \
         load is more than its servo carries; {after}",
        (sent - at).abs()
    )
}
