//! The host side of the link protocol ([`firmware::link`]): a client that sends requests with
//! retransmission and keyframe flow control over any byte transport, and the arm configuration
//! messages built from the host's arm description, and [`serial`]: a real serial port as a byte
//! stream.

pub mod arm_config;
pub mod channel;
pub mod client;
pub mod ready;
pub mod serial;

use std::io::{Read, Write};
use std::time::Duration;

/// How long a read of the link waits (real time on a port or in process, virtual time in SIL);
/// the client's backoff counts in these.
pub const READ_TIMEOUT: Duration = Duration::from_millis(20);

/// A byte transport to a board: a serial port, or the SIL harness (`places::sil`).
pub trait Transport: Read + Write {}

impl<T: Read + Write> Transport for T {}
