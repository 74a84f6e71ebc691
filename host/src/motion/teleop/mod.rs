//! Teleoperation's keyframe source, the one LeRobot's stream uses too: a leader arm's joints read
//! on a bus of their own, passed through both arms' calibrations and streamed to the follower's
//! firmware as timed keyframes (the command, `armctl teleop`, is [`crate::commands::teleop`]).
//!
//! - [`leader`]: the leader's servos, read as joint angles and a gripper opening;
//! - [`hand`]: a simulated leader, turned by a scripted hand, to try it without an arm;
//! - [`stream`]: the loop: its rate, the safety clamp, keyframes timed by the follower's playback
//!   clock, and the figures;
//! - [`record`]: the session as a keyframe file for `armctl play`.

pub mod hand;
pub mod leader;
pub mod record;
pub mod stream;
