//! The host side of the servo-arm project: the `armctl` command-line tool as a library, so that
//! integration tests run exactly the code the binary runs.
//!
//! The modules, top to bottom (a module uses only those below it):
//! - [`cli`]: the command line, which uses everything;
//! - [`demo`], [`bench`], [`footprint`], [`teleop`], [`rig`], [`drive`], [`mocap`], [`motion`], [`servo`]: what armctl
//!   does;
//! - [`places`]: where the firmware core runs on this PC (SIL, QEMU);
//! - [`link`] and [`sim`]: the host link and its transports, the servo-bus simulator;
//! - [`arm`], [`args`], [`plot`] and [`pty_owner`]: arm descriptions, typed values, PNG drawing,
//!   pseudo-terminals kept to their owner;
//! - [`untested`]: tests that cannot run on this machine say so (used by the tests only).
#![warn(missing_docs)]

pub mod args;
/// Arm descriptions and the joint-count dispatch: the `armctl-arm` crate (`host/arm`), under the
/// name the modules use.
pub use armctl_arm as arm;
pub mod bench;
pub mod cli;
pub mod demo;
pub mod doctor;
pub mod drive;
pub mod footprint;
pub mod link;
pub mod mocap;
pub mod motion;
pub mod places;
pub mod plot;
pub mod pty_owner;
pub mod rig;
pub mod servo;
pub mod sim;
pub mod teleop;
pub mod untested;
pub mod view;
