//! What armctl does, one folder per verb family: the typed operations that [`crate::cli`], the
//! view, a rig and the Python binding call.
//!
//! - [`drive`]: move, joints, play, status, stop, torque, gripper over a connection to the
//!   firmware;
//! - [`servo`]: `armctl servo`, `calibrate`, `ports`;
//! - [`doctor`]: what is wrong with a servo bus;
//! - [`collision`]: `armctl collision fit|check`, an arm's collision geometry made and checked;
//! - [`bench`]: `armctl bench ik|bus|rate|mcu|pc`;
//! - [`footprint`]: the board binaries' flash, RAM, panic sites and stack;
//! - [`demo`]: the whole product in software in the loop;
//! - [`teleop`]: a leader arm driving the follower;
//! - [`retarget`]: BVH motion capture onto the arm, and `--play`;

pub mod bench;
pub mod collision;
pub mod demo;
pub mod doctor;
pub mod drive;
pub mod footprint;
pub mod retarget;
pub mod servo;
pub mod teleop;
