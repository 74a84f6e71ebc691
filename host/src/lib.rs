//! The host side of the servo-arm project: the `armctl` command-line tool as a library, so that
//! integration tests run exactly the code the binary runs.
//!
//! The modules, top to bottom (a module uses only those on the rows below it; tests/layers.rs
//! checks it, and docs/developing.md, "The host crate's layout", says what each holds):
//! - [`cli`]: the command line (clap's parser, dispatch, rendering); nothing imports it;
//! - [`view`] and [`rig`]: the browser's front end, several arms as one;
//! - [`commands`]: one folder per verb family (drive, servo, doctor, bench, footprint, demo,
//!   teleop, retarget);
//! - [`motion`]: keyframe sources and checks (files, lines, teleoperation's stream, motion capture);
//! - [`runtime`]: where the firmware core runs on this PC (SIL, PC, serve, QEMU, board builds) and
//!   the connection and session to it;
//! - [`link`] and [`sim`]: the host link and its transports, the servo-bus simulator;
//! - [`support`]: values people type, PNG drawing, pseudo-terminals kept to their owner, Ctrl-C;
//! - [`arm`]: the `armctl-arm` crate beneath all of them.
#![warn(missing_docs)]

/// Arm descriptions and the joint-count dispatch: the `armctl-arm` crate (`host/arm`), under the
/// name the modules use.
pub use armctl_arm as arm;
pub mod cli;
pub mod commands;
pub mod link;
pub mod motion;
pub mod rig;
pub mod runtime;
pub mod sim;
pub mod support;
pub mod view;
