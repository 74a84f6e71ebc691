//! Human motion capture onto the arm: BVH files read, their skeleton moved, the arm's motion
//! carried to a T-pose rest and retargeted onto a robot arm as joint keyframes for `armctl play`.
//!
//! - [`bvh`]: the file (hierarchy, channels, frames), with line numbers in every error.
//! - [`skeleton`]: forward kinematics of the skeleton, the root's OFFSET a setting.
//! - [`chain`]: which joints are the arm (shoulder, elbow, wrist).
//! - [`rest`]: T-pose, A-pose or arms down, and rotations carried between rests.
//! - [`hand`]: the hand relative to the shoulder, smoothed and sampled.
//! - [`workspace`]: how far the arm reaches and where its workspace is.
//! - [`retarget`]: scale, placement, IK per keyframe, tracking figures; several arms (a rig's)
//!   from one file on one scale and one time base ([`retarget::timebase`]).
//! - [`solve`]: the IK requests, warm and afresh, and the way toward a target out of reach.
//! - [`densify`]: keyframes added where a joint would move far between two.
//! - [`timing`]: keyframe times within the arm's velocity and acceleration limits.
//! - [`plot`]: the hand's path against the tool's.

pub mod bvh;
pub mod chain;
pub mod densify;
pub mod hand;
pub mod plot;
pub mod rest;
pub mod retarget;
pub mod skeleton;
pub mod solve;
pub mod timing;
pub mod workspace;
