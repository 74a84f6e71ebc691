//! `joints`: every joint to values, arriving together; waits until the arm is at rest. Checked
//! against the arm's collision geometry first ([`super::avoid`]): a target in collision is refused,
//! and one whose straight joint path is blocked is reached by a planned path.

use std::io::Write;

use firmware::link::message::{Timing, MAX_SPEED, MAX_TIME};
use serde::Serialize;

use super::avoid;
use super::error::{rest, DriveError, DriveResult};
use super::move_to::{check_finite, positive};
use crate::runtime::driver::{check_joints, fmt3, fmt_list, Driver};
use crate::support::interrupt;

/// A checked `joints` (the count and the limits are checked against the arm once connected).
#[derive(Clone, Debug, PartialEq)]
pub struct JointsRequest {
    /// Joint values (rad, m for prismatic joints).
    pub q: Vec<f64>,
    /// How fast.
    pub timing: Timing,
    /// Controller seconds to wait.
    pub timeout: f64,
}

impl JointsRequest {
    /// Checks the values: finite, at least one; a duration (s) or a joint speed limit (rad/s),
    /// else as fast as the joint limits allow; the wait.
    pub fn new(q: Vec<f64>, speed: Option<f64>, duration: Option<f64>, timeout: f64) -> DriveResult<Self> {
        let check = || -> anyhow::Result<Self> {
            check_finite(&q, "--q")?;
            if q.is_empty() {
                anyhow::bail!("--q: no joint values given");
            }
            let timing = match (duration, speed) {
                (Some(_), Some(_)) => anyhow::bail!("give speed or duration, not both (nothing was sent)"),
                (Some(d), None) => Timing::Duration(positive(d, f64::from(MAX_TIME), "--duration", "s")?),
                (None, Some(s)) => Timing::MaxSpeed(positive(s, f64::from(MAX_SPEED), "--speed", "rad/s")?),
                // As fast as the joint limits allow: they are far below this.
                (None, None) => Timing::MaxSpeed(MAX_SPEED),
            };
            positive(timeout, f64::from(MAX_TIME), "--timeout", "s")?;
            Ok(Self { q: q.clone(), timing, timeout })
        };
        check().map_err(DriveError::Input)
    }
}

/// What `joints` did.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct JointsReport {
    /// Always "joints".
    pub command: &'static str,
    /// The way the arm went: "joint" (straight in joint space) or "planned" (around what was in
    /// the way of the straight path).
    pub path: &'static str,
    /// Keyframes of the planned path (0 for a straight move).
    pub planned_keyframes: usize,
    /// The joint values sent.
    pub target: Vec<f32>,
    /// The measured joints at rest.
    pub reached: Vec<f32>,
    /// The largest difference between the two (rad or m).
    pub max_error: f32,
    /// The tool's position at rest (m).
    #[serde(serialize_with = "super::as_list")]
    pub tool: [f64; 3],
    /// Controller seconds from the request to rest.
    pub time_s: f64,
    /// Why the arm went by a planned path, in words.
    #[serde(skip)]
    pub why: Option<String>,
}

impl JointsReport {
    /// The report as `armctl joints` prints it.
    pub fn text(&self) -> String {
        let how = self.why.as_ref().map(|why| format!("; {why}")).unwrap_or_default();
        format!(
            "joints: target {}, reached {} (largest error {:.4}), tool at {} m, took {:.2} s{how}",
            fmt_list(&self.target),
            fmt_list(&self.reached),
            self.max_error,
            fmt3(&self.tool),
            self.time_s
        )
    }
}

/// Moves every joint to the request's values and waits until the arm is at rest. Torque is
/// switched on if it is off (said on `notes`), and off again if the move is refused.
pub fn joints(driver: &mut Driver, request: &JointsRequest, notes: &mut dyn Write) -> DriveResult<JointsReport> {
    let positions = check_joints(driver, &request.q, "--q").map_err(DriveError::Input)?;
    let (start, switched) = driver.ready_to_move()?;
    interrupt::catch();
    let from: Vec<f64> = start.measured.iter().map(|&x| f64::from(x)).collect();
    let sent = match avoid::send(driver, &from, &request.q, request.timing) {
        Ok(sent) => sent,
        Err(e) => {
            let undone = driver.undo_torque(switched);
            // A firmware's refusal names the pair from the arm's geometry.
            let named = match &e {
                avoid::NotSent::Link(crate::link::client::LinkError::Nak(reason)) => {
                    super::collision::refusal(driver.arm(), reason)
                }
                _ => None,
            };
            let why = named.unwrap_or_else(|| e.to_string());
            return Err(DriveError::failed(format!("joints {}: {why}; nothing moved{undone}", fmt_list(&positions))));
        }
    };
    Driver::note_torque(switched, notes)?;
    let status = rest(driver, request.timeout)?;
    if let Some(why) = super::collision::stopped(driver.arm(), &status) {
        return Err(DriveError::failed(format!("joints {}: {why}", fmt_list(&positions))));
    }
    let max_error = positions.iter().zip(&status.measured).map(|(a, b)| (a - b).abs()).fold(0.0f32, f32::max);
    Ok(JointsReport {
        command: "joints",
        path: sent.path,
        planned_keyframes: sent.keyframes,
        target: positions.to_vec(),
        reached: status.measured.to_vec(),
        max_error,
        tool: driver.tool_position(&status.measured)?,
        time_s: f64::from(status.time - start.time),
        why: sent.why,
    })
}
