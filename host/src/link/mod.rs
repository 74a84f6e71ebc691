//! The host side of the link protocol ([`firmware::link`]): a client that sends requests with
//! retransmission and keyframe flow control over any byte transport, the arm configuration
//! messages built from the host's arm description, [`collision`]: the firmware's collision
//! reports named from the arm's geometry, [`session`]: the one session that builds every
//! request the product sends and waits on the firmware, [`flood`]: the requests of a host that
//! floods the link, for load measurements, and [`serial`]: a real serial port as a byte stream.

pub mod arm_config;
pub mod channel;
pub mod client;
pub mod collision;
pub mod flood;
pub mod serial;
pub mod session;

use std::any::Any;
use std::io::{Read, Write};
use std::time::Duration;

/// How long a read of the link waits (real time on a port or in process, virtual time in SIL);
/// the client's backoff counts in these.
pub const READ_TIMEOUT: Duration = Duration::from_millis(20);

/// A byte transport to a board: a serial port, or the SIL harness (`runtime::sil`).
pub trait Transport: Read + Write + Any {
    /// The transport as `Any`: behind a `Box<dyn Transport>`, a simulated board's clock, trace and
    /// scene stay reachable (the demo records them).
    fn as_any_mut(&mut self) -> &mut dyn Any;
}

impl<T: Read + Write + Any> Transport for T {
    fn as_any_mut(&mut self) -> &mut dyn Any {
        self
    }
}
