//! `armctl gripper open|close|set PERCENT [--effort PERCENT]`: drives the arm's gripper and waits
//! until it has arrived or closed on something.
//!
//! Openings are percentages, 0 closed to 100 open (LeRobot's `RANGE_0_100`); the firmware ramps the
//! gripper there at its speed. The effort is the servo's torque limit (STS3215) or goal current
//! (Dynamixel, in current-based position mode), in percent of its full value; it stays until the
//! next `--effort`.

use std::io::Write;

use anyhow::{bail, Result};
use firmware::link::message::{GripperStatus, Status};
use serde::Serialize;

use super::error::{interrupted, DriveError, DriveResult};
use crate::runtime::driver::Driver;
use crate::support::interrupt;

/// How close to its goal (percent) the gripper counts as arrived.
const ARRIVED: f32 = 1.5;
/// How little it may move between two polls (percent) to count as standing still.
const STILL: f32 = 0.2;
/// Polls standing still short of the goal after which the wait ends.
const STILL_POLLS: u32 = 15;
/// How long a grasp must have held (s of controller time) before the command ends: the firmware
/// backs the goal off from wherever closing took it to the small squeeze past the contact, at the
/// gripper's speed, and a PC-hosted core that ended sooner would leave the servo pushing with its
/// whole effort limit. Closing runs at most 5 reads (with the load read every fourth tick) past
/// the contact before the grasp is seen: under 0.1 s of travel at the default speed.
const HOLD_SETTLE_S: f32 = 0.15;

/// Where the jaws go.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum GripperGoal {
    /// Fully open (100 %).
    Open,
    /// Closed (0 %), stopping on whatever is between the jaws.
    Close,
    /// To an opening, percent (0 closed to 100 open).
    Set(f64),
}

impl GripperGoal {
    /// As the command line and Python name it.
    pub fn name(self) -> &'static str {
        match self {
            Self::Open => "open",
            Self::Close => "close",
            Self::Set(_) => "set",
        }
    }
}

/// A checked gripper request.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GripperRequest {
    /// The opening, percent.
    pub opening: f32,
    /// The effort limit, percent (`None` keeps it).
    pub effort: Option<f32>,
    /// Seconds of controller time to wait.
    pub timeout: f64,
}

/// A percentage: finite, within `0..=100` (above 0 for an effort).
fn percent(value: f64, what: &str, above_zero: bool) -> anyhow::Result<f32> {
    if !value.is_finite() || !(0.0..=100.0).contains(&value) || (above_zero && value == 0.0) {
        let range = if above_zero { "above 0 and at most 100" } else { "from 0 (closed) to 100 (open)" };
        bail!("{what}: {value} is not a percent {range}");
    }
    Ok(value as f32)
}

impl GripperRequest {
    /// Checks the values (nothing is connected yet).
    pub fn new(goal: GripperGoal, effort: Option<f64>, timeout: f64) -> DriveResult<Self> {
        let check = || -> anyhow::Result<Self> {
            let opening = match goal {
                GripperGoal::Open => 100.0,
                GripperGoal::Close => 0.0,
                GripperGoal::Set(p) => percent(p, "gripper set", false)?,
            };
            let effort = effort.map(|e| percent(e, "--effort", true)).transpose()?;
            if !(timeout.is_finite() && timeout > 0.0) {
                bail!("--timeout: {timeout} s must be a positive number");
            }
            Ok(Self { opening, effort, timeout })
        };
        check().map_err(DriveError::Input)
    }
}

/// What `gripper` did.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct GripperReport {
    /// Always "gripper".
    pub command: &'static str,
    /// Where the jaws stopped (opening), their goal, the load, whether they hold something.
    #[serde(flatten)]
    pub jaws: GripperStatus,
    /// The opening in mm, if the arm's gripper span is known.
    pub opening_mm: Option<f64>,
    /// The effort limit sent, percent.
    pub effort: Option<f32>,
}

/// The gripper of a status, or the error that the arm has none.
fn of(driver: &Driver, status: &Status) -> Result<GripperStatus> {
    status.gripper.ok_or_else(|| {
        anyhow::anyhow!("the arm {} has no gripper (name one in its arm file's [gripper] table)", driver.arm().name)
    })
}

impl GripperReport {
    /// The report as `armctl gripper` prints it.
    pub fn text(&self) -> String {
        format!("gripper: {}", describe(&self.jaws, self.opening_mm))
    }
}

/// Sends the request and waits until the gripper is at its goal, has held something for
/// [`HOLD_SETTLE_S`] or stands still. Torque is switched on if it is off (said on `notes`).
pub fn gripper(driver: &mut Driver, request: &GripperRequest, notes: &mut dyn Write) -> DriveResult<GripperReport> {
    let status = driver.status()?;
    of(driver, &status)?;
    let (start, switched) = driver.ready_to_move()?;
    interrupt::catch();
    if let Err(e) = driver.session().gripper(request.opening, request.effort) {
        let undone = driver.undo_torque(switched);
        return Err(DriveError::failed(format!("gripper to {} %: {e}; nothing moved{undone}", request.opening)));
    }
    Driver::note_torque(switched, notes)?;
    let mut last = of(driver, &start)?;
    let mut still = 0;
    let mut held_since = None;
    let first = start.time;
    let status = loop {
        if interrupt::requested() {
            return Err(interrupted(driver, ""));
        }
        driver.pause()?;
        let status = driver.status()?;
        let g = of(driver, &status)?;
        let arrived = (g.opening - g.goal).abs() <= ARRIVED;
        still = if (g.opening - last.opening).abs() <= STILL { still + 1 } else { 0 };
        last = g;
        held_since = if g.holding { held_since.or(Some(status.time)) } else { None };
        let settled = held_since.is_some_and(|t| status.time - t >= HOLD_SETTLE_S);
        if (arrived && !g.holding) || settled || still >= STILL_POLLS {
            break status;
        }
        if f64::from(status.time - first) > request.timeout {
            return Err(DriveError::failed(format!(
                "gripper: timed out after {} s at {:.1} % (goal {:.1} %)",
                request.timeout, g.opening, g.goal
            )));
        }
    };
    let g = of(driver, &status)?;
    let mm = driver.gripper().map(|spec| f64::from(g.opening).clamp(0.0, 100.0) / 100.0 * spec.opening_mm);
    Ok(GripperReport { command: "gripper", jaws: g, opening_mm: mm, effort: request.effort })
}

/// One line about the gripper: `at 41.2 % (37.1 mm), goal 0.0 %, load 48 %, holding something`.
pub fn describe(g: &GripperStatus, mm: Option<f64>) -> String {
    let mm = mm.map(|mm| format!(" ({mm:.1} mm)")).unwrap_or_default();
    let holding = if g.holding { ", holding something" } else { "" };
    format!("at {:.1} %{mm}, goal {:.1} %, load {:.0} %{holding}", g.opening, g.goal, g.load.abs())
}
