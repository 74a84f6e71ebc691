//! Driving an arm through the host link: `armctl --port PORT ...` for a board running the
//! firmware, `armctl --sim ...` for the same firmware core simulated on this PC (software in the
//! loop).
//!
//! The commands: `move` (tool to a point or pose, IK on the firmware), `joints` (to joint values),
//! `play` (a keyframe file, joint or Cartesian, streamed with flow control), `status`, `stop`,
//! `torque on|off` and `gripper open|close|set PERCENT`. Every command checks what the user typed before anything is sent, so bad input
//! changes nothing; a request the firmware refuses changes nothing either (the link's contract).
//! `move`, `joints` and `play` wait until the arm is at rest again; Ctrl-C while they wait stops
//! the arm (decelerating within its limits) and exits with code 130.

pub mod args;
pub mod commands;
pub mod connection;
mod gripper;
pub mod interrupt;
pub(crate) mod path;
pub mod play;
mod progress;
pub mod session;

use std::io::Write;

use anyhow::Result;

use args::{DriveCommand, LinkArgs};

/// Runs an arm-driving command; returns the exit code.
pub fn run(link: &LinkArgs, command: DriveCommand, out: &mut dyn Write, err: &mut dyn Write) -> Result<i32> {
    // Everything the user typed is checked before connecting, so bad input changes nothing.
    let link = link.merged(command.link())?;
    let request = commands::Request::parse(&command)?;
    let (target, arm) = link.target()?;
    let mut driver = session::Driver::open(target, arm, err)?;
    let code = commands::run(&mut driver, request, link.json, out, err)?;
    driver.close(err)?;
    Ok(code)
}
