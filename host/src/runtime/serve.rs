//! `armctl serve`'s transport: the host link of a firmware core running in this process, served
//! on a pseudo-terminal, so that consecutive `armctl --port PTY` commands, scripts and other
//! programs drive one arm whose state persists between them.
//!
//! Two threads forward bytes, one each way, between the pty's master end and the core's link
//! channel; the core's control loop never waits on them. The slave end is held open here too, so
//! a client closing the path does not hang up the master end for the next one.
//!
//! The pty is its owner's alone (mode 0600, [`crate::support::pty_owner`]) from before its path is printed:
//! the programs that drive the arm through it run as the user who started `armctl serve`.

use std::io::{ErrorKind, Read, Write};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::RecvTimeoutError;
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::Duration;

use anyhow::{Context, Result};
use serialport::{SerialPort, TTYPort};

use crate::link::channel::ChannelLink;

/// How often the forwarding threads look at the stop flag.
const POLL: Duration = Duration::from_millis(20);

/// A core's link on a pty; dropping it stops the forwarding.
#[derive(Debug)]
pub struct PtyLink {
    path: String,
    stop: Arc<AtomicBool>,
    threads: Vec<JoinHandle<()>>,
}

impl PtyLink {
    /// Opens a pty pair, makes it its owner's alone ([`crate::support::pty_owner::make_private`]) and
    /// forwards `link` over it.
    pub fn spawn(link: ChannelLink) -> Result<Self> {
        let (master, slave) = TTYPort::pair().context("cannot open a pseudo-terminal")?;
        let path = slave.name().context("the pseudo-terminal has no path")?;
        // It takes commands for the arm: its owner's alone before anyone learns its path.
        crate::support::pty_owner::make_private(&path)?;
        let mut reader = master;
        reader.set_timeout(POLL).context("cannot set the pseudo-terminal's timeout")?;
        let mut writer = reader.try_clone_native().context("cannot share the pseudo-terminal between threads")?;
        let (to_core, from_core) = link.split();
        let stop = Arc::new(AtomicBool::new(false));
        let inbound = {
            let stop = stop.clone();
            std::thread::Builder::new().name("serve-in".into()).spawn(move || {
                // Held open for as long as the server runs (see the module doc).
                let _slave = slave;
                let mut buf = [0u8; 512];
                while !stop.load(Ordering::SeqCst) {
                    match reader.read(&mut buf) {
                        Ok(0) => {}
                        Ok(n) => {
                            if to_core.send(buf[..n].to_vec()).is_err() {
                                return;
                            }
                        }
                        Err(e)
                            if matches!(
                                e.kind(),
                                ErrorKind::TimedOut | ErrorKind::WouldBlock | ErrorKind::Interrupted
                            ) => {}
                        // No client has the slave open: wait for the next one.
                        Err(_) => std::thread::sleep(POLL),
                    }
                }
            })?
        };
        let outbound = {
            let stop = stop.clone();
            std::thread::Builder::new().name("serve-out".into()).spawn(move || {
                while !stop.load(Ordering::SeqCst) {
                    match from_core.recv_timeout(POLL) {
                        // A reply nobody reads is lost like one on an unplugged cable: the
                        // client retransmits, and the core answers a repeat once.
                        Ok(bytes) => {
                            let _ = writer.write_all(&bytes).and_then(|()| writer.flush());
                        }
                        Err(RecvTimeoutError::Timeout) => {}
                        Err(RecvTimeoutError::Disconnected) => return,
                    }
                }
            })?
        };
        Ok(Self { path, stop, threads: vec![inbound, outbound] })
    }

    /// The slave end's path, for `armctl --port`.
    pub fn path(&self) -> &str {
        &self.path
    }
}

impl Drop for PtyLink {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        for t in self.threads.drain(..) {
            let _ = t.join();
        }
    }
}
