//! Keyframe sources and joint trajectories: joint and Cartesian keyframe files, straight lines of
//! the tool checked by IK ([`line`]), Cartesian keyframes checked by IK ([`reach`]), and `armctl trajectory sample` (interpolation, limits,
//! sampling, its plot).

pub mod cartesian_file;
pub mod collision;
pub mod line;
pub mod plan;
#[cfg(test)]
mod plan_property;
pub mod reach;
pub mod sample;
pub mod trajectory;
pub mod trajectory_plot;

pub use cartesian_file::{parse_cartesian_keyframes, CartesianKeyframes};
pub mod mocap;
pub mod teleop;
