//! Firmware core for a servo-arm controller board: the parts that run on the microcontroller and
//! compile unchanged for the host, where they are tested.
//!
//! It holds the application ([`app`]: the host link in front of the controller), the built-in arm, the control tick's Cartesian tracking step (warm-started f32 IK under
//! a fixed iteration budget) and the servo bus ([`bus`]: Dynamixel Protocol 2.0 and Feetech
//! codecs, a streaming decoder, master transactions, control tables).
#![cfg_attr(not(test), no_std)]
#![deny(unsafe_code)]
#![warn(missing_docs)]

pub mod app;
pub mod board;
pub mod builtin;
pub mod bus;
pub mod controller;
mod crc16;
pub mod link;
mod place;
pub mod tracking;
