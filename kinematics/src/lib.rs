//! Fixed-size kinematics for serial arms: chains, forward kinematics, geometric Jacobians and
//! inverse kinematics, with no heap and no panics on any input; and kinematic trees ([`tree`]):
//! several end effectors on one body, solved together.
//!
//! Generic over the scalar (`f32` on the microcontroller, `f64` on the host) and the joint count
//! `N` (a const generic). Units are SI: metres and radians. Bad input is an error value:
//! [`ChainError`] when a chain is built, [`ik::IkStatus::InvalidInput`] when a problem is posed.
//!
//! ```
//! use kinematics::{presets, ik::{IkConfig, IkProblem, IkStatus, Target}};
//! use nalgebra::SVector;
//!
//! let arm = presets::ur5e::<f64>().unwrap();
//! let goal = arm.tool_pose(&SVector::from([0.3, -1.2, 1.0, -0.5, 1.1, 0.2]));
//! let problem = IkProblem { target: Target::Pose(goal), seed: arm.middle(), config: IkConfig::default() };
//! let solution = arm.solve(&problem);
//! assert_eq!(solution.status, IkStatus::Converged);
//! assert!(solution.position_error <= 1e-5);
//! ```
#![cfg_attr(not(test), no_std)]
#![deny(unsafe_code)]
#![warn(missing_docs)]

mod angle;
mod chain;
pub mod collision;
pub mod dynamics;
mod fk;
pub mod ik;
mod joint;
pub mod linalg;
mod pose;
pub mod presets;
mod real;
mod rng;
pub mod trajectory;
pub mod tree;
pub mod trig;

pub use angle::wrap_angle;
pub use chain::{Chain, ChainError, DhRow};
pub use fk::Frames;
pub use joint::{Joint, JointKind, Limits};
pub use pose::{axis_angle_matrix, quaternion_wxyz, rotation_error, Pose};
pub use real::Real;
pub use rng::SplitMix64;

pub use nalgebra;
