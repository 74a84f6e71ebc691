//! The kinematics crate's integration tests, one module per file, in one test binary: each
//! binary of its own linked the crate and instantiated its generic code again, which made these
//! tests a fifth of the test build.

mod collision;
mod dynamics;
mod fk;
mod ik;
mod interpolation;
mod jacobian;
mod limits;
mod methods;
mod player;
mod rotation;
mod tilt;
mod tree;
