//! An in-process byte transport: the host link to a firmware core running on another thread of
//! this process (the PC as the board), through two channels of byte chunks. Reads wait at most the
//! read timeout, like a serial port's, so the link client's retransmission works unchanged.

use std::io::{self, ErrorKind, Read, Write};
use std::sync::mpsc::{channel, Receiver, RecvTimeoutError, Sender};
use std::time::Duration;

/// The host's end: writes go to the core, reads return what the core sent.
#[derive(Debug)]
pub struct ChannelLink {
    to_core: Sender<Vec<u8>>,
    from_core: Receiver<Vec<u8>>,
    /// Bytes of a chunk that did not fit the last read.
    pending: Vec<u8>,
    read_timeout: Duration,
}

/// The core's end.
#[derive(Debug)]
pub struct CoreEnd {
    /// Bytes from the host, chunk by chunk.
    pub from_host: Receiver<Vec<u8>>,
    /// Bytes to the host.
    pub to_host: Sender<Vec<u8>>,
}

/// A connected pair: the host's end with `read_timeout`, and the core's.
pub fn pair(read_timeout: Duration) -> (ChannelLink, CoreEnd) {
    let (to_core, from_host) = channel();
    let (to_host, from_core) = channel();
    (ChannelLink { to_core, from_core, pending: Vec::new(), read_timeout }, CoreEnd { from_host, to_host })
}

impl ChannelLink {
    /// The two channels, for a server that forwards them to another transport (a pty): bytes for
    /// the core go into the sender, the core's bytes come out of the receiver.
    pub fn split(self) -> (Sender<Vec<u8>>, Receiver<Vec<u8>>) {
        (self.to_core, self.from_core)
    }
}

impl Read for ChannelLink {
    /// The bytes the core sent; `TimedOut` when none came within the read timeout, `BrokenPipe`
    /// once the core has ended.
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        if buf.is_empty() {
            return Ok(0);
        }
        if self.pending.is_empty() {
            self.pending = match self.from_core.recv_timeout(self.read_timeout) {
                Ok(chunk) => chunk,
                Err(RecvTimeoutError::Timeout) => {
                    return Err(io::Error::new(ErrorKind::TimedOut, "no bytes from the firmware core"))
                }
                Err(RecvTimeoutError::Disconnected) => {
                    return Err(io::Error::new(ErrorKind::BrokenPipe, "the firmware core has stopped"))
                }
            };
        }
        let n = buf.len().min(self.pending.len());
        buf[..n].copy_from_slice(&self.pending[..n]);
        self.pending.drain(..n);
        Ok(n)
    }
}

impl Write for ChannelLink {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        self.to_core
            .send(buf.to_vec())
            .map_err(|_| io::Error::new(ErrorKind::BrokenPipe, "the firmware core has stopped"))?;
        Ok(buf.len())
    }

    fn flush(&mut self) -> io::Result<()> {
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bytes_cross_both_ways_and_a_silent_core_times_out() {
        let (mut host, core) = pair(Duration::from_millis(5));
        host.write_all(b"ping").unwrap();
        assert_eq!(core.from_host.recv().unwrap(), b"ping");
        core.to_host.send(b"pong!".to_vec()).unwrap();
        let mut buf = [0u8; 3];
        assert_eq!(host.read(&mut buf).unwrap(), 3);
        assert_eq!(&buf, b"pon");
        assert_eq!(host.read(&mut buf).unwrap(), 2);
        assert_eq!(&buf[..2], b"g!");
        assert_eq!(host.read(&mut buf).unwrap_err().kind(), ErrorKind::TimedOut);
        drop(core);
        assert_eq!(host.read(&mut buf).unwrap_err().kind(), ErrorKind::BrokenPipe);
        assert_eq!(host.write(b"x").unwrap_err().kind(), ErrorKind::BrokenPipe);
    }
}
