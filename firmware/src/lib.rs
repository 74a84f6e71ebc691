//! Firmware core for a servo-arm controller board: the parts that run on the microcontroller and
//! compile unchanged for the host, where they are tested.
//!
//! So far this holds the built-in arm and the control tick's Cartesian tracking step (warm-started
//! f32 IK under a fixed iteration budget). The servo bus protocols, the host link and the
//! controller state machine are built on it by the issues that follow.
#![cfg_attr(not(test), no_std)]
#![deny(unsafe_code)]
#![warn(missing_docs)]

pub mod builtin;
pub mod tracking;
