//! The host side of the link protocol ([`firmware::link`]): a client that sends requests with
//! retransmission and keyframe flow control over any byte transport, and the arm configuration
//! messages built from the host's arm description, and [`serial`]: a real serial port as a byte
//! stream.

pub mod arm_config;
pub mod client;
pub mod ready;
pub mod serial;

use std::io::{Read, Write};

/// A byte transport to a board: a serial port, or the SIL harness (`places::sil`).
pub trait Transport: Read + Write {}

impl<T: Read + Write> Transport for T {}
