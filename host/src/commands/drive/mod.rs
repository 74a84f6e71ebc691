//! Driving an arm through the host link: one typed operation per command, over a [`Driver`]
//! (a connection to the firmware core, wherever it runs: a board on a port, `--sim`, `--bus`).
//!
//! Each operation takes a checked request and returns a report (`serde::Serialize`: the
//! command line's `--json` line, Python's dict) or a [`DriveError`]: [`move_to`] (the tool to a
//! point or pose, IK on the firmware, by the path [`path`] decides), [`joints`], [`play`] (a
//! keyframe file, joint or Cartesian, streamed with flow control), [`state`] (`status`, `stop`,
//! `torque`) and [`gripper`]. Each request's constructor checks its values before anything is
//! sent, so bad input changes nothing; a request the firmware refuses changes nothing either
//! (the link's contract). The moves wait until the arm is at rest; Ctrl-C while they wait stops
//! the arm (decelerating within its limits) and ends in [`DriveError::Interrupted`].
//!
//! The command line (`cli::drive`), the Python binding, the view and a rig call these same
//! operations.
//!
//! [`Driver`]: crate::runtime::driver::Driver

pub mod avoid;
pub mod blocked;
pub mod collision;
pub mod error;
pub mod gripper;
pub mod joints;
pub mod move_to;
pub mod path;
pub mod play;
mod progress;
pub mod state;

use std::io::Write;

use serde::Serialize;

use crate::runtime::connection::Place;
use crate::runtime::driver::Driver;
pub use error::{DriveError, DriveResult};

/// A fixed-size array serialised as a sequence (what it is in JSON anyway), so that front ends
/// that tell tuples from lists (Python) get a list, as they would from the JSON line.
pub(crate) fn as_list<S: serde::Serializer, T: Serialize, const N: usize>(
    values: &[T; N],
    serializer: S,
) -> Result<S::Ok, S::Error> {
    serializer.collect_seq(values)
}

/// [`as_list`] for an optional array.
pub(crate) fn as_optional_list<S: serde::Serializer, T: Serialize, const N: usize>(
    values: &Option<[T; N]>,
    serializer: S,
) -> Result<S::Ok, S::Error> {
    match values {
        Some(values) => serializer.collect_seq(values),
        None => serializer.serialize_none(),
    }
}

/// A drive operation with its request checked.
pub enum Operation {
    /// `move`.
    Move(move_to::MoveRequest),
    /// `joints`.
    Joints(joints::JointsRequest),
    /// `play`.
    Play(play::Plan),
    /// `status`.
    Status,
    /// `stop`.
    Stop,
    /// `torque on|off`.
    Torque(bool),
    /// `gripper`.
    Gripper(gripper::GripperRequest),
}

/// An operation's report.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(untagged)]
pub enum Report {
    /// `move`.
    Move(move_to::MoveReport),
    /// `joints`.
    Joints(joints::JointsReport),
    /// `play`.
    Play(play::PlayReport),
    /// `status`.
    Status(state::StatusReport),
    /// `stop`.
    Stop(state::StopReport),
    /// `torque`.
    Torque(state::TorqueReport),
    /// `gripper`.
    Gripper(gripper::GripperReport),
}

impl Report {
    /// The report as the command line prints it without `--json`.
    pub fn text(&self) -> String {
        match self {
            Report::Move(r) => r.text(),
            Report::Joints(r) => r.text(),
            Report::Play(r) => r.text(),
            Report::Status(r) => r.text(),
            Report::Stop(r) => r.text(),
            Report::Torque(r) => r.text(),
            Report::Gripper(r) => r.text(),
        }
    }
}

/// Connects to the arm at `place`, carries out `operation`, and prints its report (`json`: one
/// line of JSON; else its text) on `out`, notes and what connecting said on `err`. Returns the
/// exit code: 0, or 130 after Ctrl-C stopped the arm (said on `err`).
pub fn run(
    place: &Place,
    json: bool,
    operation: &Operation,
    out: &mut dyn Write,
    err: &mut dyn Write,
) -> anyhow::Result<i32> {
    let (target, arm) = place.target_and_arm()?;
    let mut driver = Driver::open(target, arm, err)?;
    let code = match carry_out(&mut driver, operation, err) {
        Ok(report) if json => {
            writeln!(out, "{}", serde_json::to_string(&report)?)?;
            0
        }
        Ok(report) => {
            writeln!(out, "{}", report.text())?;
            0
        }
        Err(DriveError::Interrupted { said }) => {
            writeln!(err, "{said}")?;
            crate::support::interrupt::EXIT_CODE
        }
        Err(e) => return Err(e.into()),
    };
    driver.close(err)?;
    Ok(code)
}

/// Carries out `operation` on the connected firmware; notes on the way (torque switched on, a
/// progress bar, warnings) go to `notes`.
pub fn carry_out(driver: &mut Driver, operation: &Operation, notes: &mut dyn Write) -> DriveResult<Report> {
    Ok(match operation {
        Operation::Move(request) => Report::Move(move_to::move_to(driver, request, notes)?),
        Operation::Joints(request) => Report::Joints(joints::joints(driver, request, notes)?),
        Operation::Play(plan) => Report::Play(play::play(driver, plan, notes)?),
        Operation::Status => Report::Status(state::status(driver)?),
        Operation::Stop => Report::Stop(state::stop(driver)?),
        Operation::Torque(on) => Report::Torque(state::torque(driver, *on)?),
        Operation::Gripper(request) => Report::Gripper(gripper::gripper(driver, request, notes)?),
    })
}
