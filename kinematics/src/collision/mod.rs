//! Collision geometry: an arm's links as capsules and spheres in their own frames, the
//! surroundings as capsules, boxes and half-spaces (a table), signed distances between them, and
//! the scene a configuration is checked against (bodies, obstacles, the pairs never checked, a
//! margin). No heap, no panics: the firmware core checks every goal with it.

pub mod distance;
pub mod scene;
pub mod shape;

pub use scene::{Body, Contact, Part, Scene, SceneError};
pub use shape::{Capsule, Shape};
