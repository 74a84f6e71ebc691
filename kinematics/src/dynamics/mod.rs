//! Rigid-body dynamics of a chain: the joint torques a motion takes (inverse dynamics, by the
//! recursive Newton-Euler algorithm), the torques gravity alone asks for, and the joint-space mass
//! matrix. Fixed size, no heap, f32 and f64 like the chain, for the simulator's servos and the
//! firmware's gravity compensation.

mod inertia;
mod rnea;

pub use inertia::{Inertia, InertiaError};
pub use rnea::{Dynamics, Linkage, STANDARD_GRAVITY};
