//! Joint trajectories: interpolation between keyframes (the Hermite family, natural and clamped
//! cubic splines, stepped, linear, B-spline), rotations (SLERP, SQUAD), limits and time scaling,
//! and the streaming player the firmware runs. No heap: keyframe sets have a fixed capacity.

mod curve;
mod hermite;
mod rotation;

pub use curve::{Curve, Interpolation, Keyframe, TrajectoryError};
pub use hermite::{basis, HermiteSegment, Sample};
pub use rotation::{OrientationKeyframe, Quaternion, RotationError, Squad};
mod limits;
mod player;

pub use limits::{time_scale, JointLimits, Limit, LimitError, Location, Retimed, Violation, MAX_SWEEPS};
pub use player::{Player, PlayerKeyframe, PushError, State, Tick};
mod bezier;
mod bspline;
mod spline;
mod tangents;

pub use bezier::bezier_point;
pub use bspline::bspline_sample;
pub use tangents::{EndCondition, KochanekBartels};
