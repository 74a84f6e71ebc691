//! Values people type, on the command line and in files: lists of numbers, CSV rows, JSON lines,
//! and the names of the servo-bus protocols and models. Uses no other module of this crate.

pub mod bus;
pub mod json_lines;
pub mod numbers;
