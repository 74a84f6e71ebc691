//! Driving an arm through the host link: `armctl --port PORT ...` for a board running the
//! firmware, `armctl --sim ...` for the same firmware core simulated on this PC (software in the
//! loop).
//!
//! The commands: `move` (tool to a point or pose, IK on the firmware), `joints` (to joint values),
//! `play` (a keyframe file, joint or Cartesian, streamed with flow control), `status`, `stop` and
//! `torque on|off`. Every command checks what the user typed before anything is sent, so bad input
//! changes nothing; a request the firmware refuses changes nothing either (the link's contract).
//! `move`, `joints` and `play` wait until the arm is at rest again; Ctrl-C while they wait stops
//! the arm (decelerating within its limits) and exits with code 130.

mod cartesian_file;
pub mod cli;
mod commands;
pub mod connection;
pub(crate) mod interrupt;
mod play;
mod progress;
mod session;

pub use cartesian_file::{parse_cartesian_keyframes, CartesianKeyframes};
