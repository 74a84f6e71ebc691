//! A serial port of the operating system as the firmware bus master's byte stream.
//!
//! The master ([`firmware::bus::master::Master`]) talks `embedded-io`: it polls
//! [`ReadReady::read_ready`] against its own deadline and reads only what is already there, so a
//! read here never waits for more bytes than the driver holds.

use std::io::{self, Read as _, Write as _};
use std::time::{Duration, Instant};

use embedded_io::{ErrorType, Read, ReadReady, Write};
use firmware::bus::master::Clock;

/// How long the operating system may block one read or write. The master reads only after
/// `read_ready`, so reads do not wait on it; it bounds a write to an adapter that stopped draining.
const PORT_TIMEOUT: Duration = Duration::from_millis(100);

/// A serial port failure during a transaction.
#[derive(Clone, PartialEq, Eq)]
pub struct TransportError {
    /// The kind of failure.
    pub kind: io::ErrorKind,
    /// The operating system's description.
    pub message: String,
}

// The master's one-line errors print the port error with `{:?}`: print the description alone.
impl std::fmt::Debug for TransportError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.message)
    }
}

impl std::fmt::Display for TransportError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.message)
    }
}

impl From<io::Error> for TransportError {
    fn from(e: io::Error) -> Self {
        Self { kind: e.kind(), message: e.to_string() }
    }
}

impl From<serialport::Error> for TransportError {
    fn from(e: serialport::Error) -> Self {
        let kind = match e.kind {
            serialport::ErrorKind::Io(kind) => kind,
            serialport::ErrorKind::NoDevice => io::ErrorKind::NotConnected,
            serialport::ErrorKind::InvalidInput => io::ErrorKind::InvalidInput,
            serialport::ErrorKind::Unknown => io::ErrorKind::Other,
        };
        Self { kind, message: e.description }
    }
}

impl embedded_io::Error for TransportError {
    fn kind(&self) -> embedded_io::ErrorKind {
        use embedded_io::ErrorKind as K;
        match self.kind {
            io::ErrorKind::NotFound => K::NotFound,
            io::ErrorKind::PermissionDenied => K::PermissionDenied,
            io::ErrorKind::InvalidInput => K::InvalidInput,
            io::ErrorKind::TimedOut => K::TimedOut,
            io::ErrorKind::Interrupted => K::Interrupted,
            _ => K::Other,
        }
    }
}

/// Why a port could not be opened; the message names the path.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum OpenError {
    /// There is no such device.
    NotFound {
        /// The path given.
        path: String,
    },
    /// Another program has the port open (serialport opens ports exclusively).
    Busy {
        /// The path given.
        path: String,
    },
    /// The user may not open the device.
    PermissionDenied {
        /// The path given.
        path: String,
    },
    /// Anything else the operating system reported (not a serial device, a baud rate the driver
    /// refuses).
    Other {
        /// The path given.
        path: String,
        /// The operating system's description.
        message: String,
    },
}

impl std::fmt::Display for OpenError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::NotFound { path } => write!(f, "{path}: no such serial port"),
            Self::Busy { path } => write!(f, "{path}: port busy (is another program using it?)"),
            Self::PermissionDenied { path } => {
                write!(f, "{path}: permission denied (on Linux, add yourself to the dialout group)")
            }
            Self::Other { path, message } => write!(f, "{path}: cannot open the port: {message}"),
        }
    }
}

impl std::error::Error for OpenError {}

/// An open serial port: the master's byte stream.
pub struct SerialTransport {
    port: Box<dyn serialport::SerialPort>,
}

impl std::fmt::Debug for SerialTransport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SerialTransport").field("port", &self.port.name()).finish()
    }
}

impl SerialTransport {
    /// Opens `path` at `baud`, 8 data bits, no parity, one stop bit (both protocols' framing).
    pub fn open(path: &str, baud: u32) -> Result<Self, OpenError> {
        let port = serialport::new(path, baud).timeout(PORT_TIMEOUT).open().map_err(|e| open_error(path, e))?;
        Ok(Self { port })
    }

    /// Wraps a port opened elsewhere.
    pub fn from_port(port: Box<dyn serialport::SerialPort>) -> Self {
        Self { port }
    }
}

pub(crate) fn open_error(path: &str, e: serialport::Error) -> OpenError {
    let path = path.to_string();
    match e.kind {
        serialport::ErrorKind::Io(io::ErrorKind::NotFound) => OpenError::NotFound { path },
        serialport::ErrorKind::Io(io::ErrorKind::PermissionDenied) => OpenError::PermissionDenied { path },
        // serialport reports EBUSY (the port is locked by another process) as NoDevice.
        serialport::ErrorKind::NoDevice => OpenError::Busy { path },
        _ if e.description.contains("busy") => OpenError::Busy { path },
        _ => OpenError::Other { path, message: e.description },
    }
}

impl ErrorType for SerialTransport {
    type Error = TransportError;
}

impl Read for SerialTransport {
    fn read(&mut self, buf: &mut [u8]) -> Result<usize, TransportError> {
        if buf.is_empty() {
            return Ok(0);
        }
        // No more than the driver holds, so the call returns at once; nothing there is not an
        // error for the master, which keeps its own deadline.
        let waiting = usize::try_from(self.port.bytes_to_read()?).unwrap_or(usize::MAX);
        if waiting == 0 {
            return Ok(0);
        }
        let n = waiting.min(buf.len());
        match self.port.read(&mut buf[..n]) {
            Ok(got) => Ok(got),
            Err(e) if matches!(e.kind(), io::ErrorKind::TimedOut | io::ErrorKind::WouldBlock) => Ok(0),
            Err(e) if e.kind() == io::ErrorKind::Interrupted => Ok(0),
            Err(e) => Err(e.into()),
        }
    }
}

impl ReadReady for SerialTransport {
    fn read_ready(&mut self) -> Result<bool, TransportError> {
        let ready = self.port.bytes_to_read()? > 0;
        if !ready {
            // The master polls in a loop until its deadline: yield the core for a moment instead
            // of spinning. 50 µs is 5 bytes at 1 Mbps, far below any reply timeout.
            std::thread::sleep(Duration::from_micros(50));
        }
        Ok(ready)
    }
}

impl Write for SerialTransport {
    fn write(&mut self, buf: &[u8]) -> Result<usize, TransportError> {
        Ok(self.port.write(buf)?)
    }

    /// Waits until the bytes have left (`tcdrain` on POSIX), as the master requires before it
    /// starts timing the reply.
    fn flush(&mut self) -> Result<(), TransportError> {
        Ok(self.port.flush()?)
    }
}

/// A byte stream the bus master runs on: a serial port, or the simulator's in-memory line in
/// tests. Its errors go into `anyhow` errors, hence `Send + Sync + 'static`.
pub trait Port: Read + Write + ReadReady<Error = <Self as Port>::Fault> {
    /// The port's error type.
    type Fault: embedded_io::Error + Send + Sync + 'static;
}

impl<P> Port for P
where
    P: Read + Write + ReadReady,
    P::Error: Send + Sync + 'static,
{
    type Fault = P::Error;
}

/// The bus master on a port.
pub type Bus<P = SerialTransport, C = StdClock> =
    firmware::bus::master::Master<P, firmware::bus::master::NoDirectionPin, C>;

/// Time since the clock was made, from [`std::time::Instant`].
#[derive(Clone, Copy, Debug)]
pub struct StdClock {
    start: Instant,
}

impl StdClock {
    /// A clock starting now.
    pub fn new() -> Self {
        Self { start: Instant::now() }
    }
}

impl Default for StdClock {
    fn default() -> Self {
        Self::new()
    }
}

impl Clock for StdClock {
    fn now_us(&mut self) -> u64 {
        u64::try_from(self.start.elapsed().as_micros()).unwrap_or(u64::MAX)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_missing_port_names_its_path() {
        let e = SerialTransport::open("/dev/armctl-no-such-port", 57_600).unwrap_err();
        assert_eq!(e.to_string(), "/dev/armctl-no-such-port: no such serial port");
    }

    #[test]
    fn the_clock_does_not_go_back() {
        let mut clock = StdClock::new();
        let a = clock.now_us();
        assert!(clock.now_us() >= a);
    }
}
