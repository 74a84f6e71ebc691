//! A debugger on QEMU's gdb stub (the GDB remote serial protocol over a unix socket): what the
//! HIL tests need to do to the running firmware from outside, as a probe would on a board —
//! write memory, move the program counter, run a monitor command (`system_reset`), stop at a
//! breakpoint, resume. Connecting stops the emulated machine; [`Gdb::resume`] lets it run again.

use std::io::{Read, Write};
use std::os::unix::net::UnixStream;
use std::path::Path;
use std::time::{Duration, Instant};

use anyhow::{bail, Context, Result};

/// How long a reply may take.
const REPLY: Duration = Duration::from_secs(10);

/// A connection to QEMU's gdb stub.
#[derive(Debug)]
pub struct Gdb {
    stream: UnixStream,
}

impl Gdb {
    /// Connects to the stub at `socket` (waiting up to 10 s for QEMU to open it); the machine
    /// stops.
    pub fn connect(socket: &Path) -> Result<Gdb> {
        let start = Instant::now();
        let stream = loop {
            match UnixStream::connect(socket) {
                Ok(stream) => break stream,
                Err(e) if start.elapsed() > REPLY => {
                    return Err(e).with_context(|| format!("QEMU's gdb stub at {}", socket.display()))
                }
                Err(_) => std::thread::sleep(Duration::from_millis(20)),
            }
        };
        stream.set_read_timeout(Some(REPLY))?;
        let mut gdb = Gdb { stream };
        // The stop reason: also proves the stub answers.
        gdb.send("?")?;
        gdb.receive()?;
        Ok(gdb)
    }

    /// Writes `bytes` to guest memory at `address`.
    pub fn write_memory(&mut self, address: u32, bytes: &[u8]) -> Result<()> {
        let data: String = bytes.iter().map(|b| format!("{b:02x}")).collect();
        self.expect_ok(&format!("M{address:x},{:x}:{data}", bytes.len()))
    }

    /// Sets the program counter (register 15; Thumb code: give the address with bit 0 set). The
    /// registers are read whole (`g`) and written back whole (`G`): QEMU answers the one-register
    /// write (`P`) only to a debugger that has read its target description.
    pub fn set_pc(&mut self, pc: u32) -> Result<()> {
        let mut registers = self.request("g")?;
        // r0 to r15, four bytes each, in hex: the PC is the 16th.
        let at = 15 * 8..16 * 8;
        if registers.len() < at.end || !registers.is_ascii() {
            bail!("gdb stub: the registers read back as {registers:?}");
        }
        let data: String = pc.to_le_bytes().iter().map(|b| format!("{b:02x}")).collect();
        registers.replace_range(at, &data);
        self.expect_ok(&format!("G{registers}"))
    }

    /// Runs a QEMU monitor command (`qRcmd`), e.g. `system_reset`; returns what it printed.
    pub fn monitor(&mut self, command: &str) -> Result<String> {
        let hex: String = command.bytes().map(|b| format!("{b:02x}")).collect();
        self.send(&format!("qRcmd,{hex}"))?;
        let mut printed = Vec::new();
        loop {
            let reply = self.reply()?;
            match reply.strip_prefix('O') {
                Some(out) if reply != "OK" => printed.extend(unhex(out)),
                _ if reply == "OK" || reply.is_empty() => return Ok(String::from_utf8_lossy(&printed).into_owned()),
                _ => bail!("monitor {command}: {reply}"),
            }
        }
    }

    /// Sets a hardware breakpoint at `address` (a Thumb instruction's, without the Thumb bit): the
    /// machine stops when it is about to run it ([`Gdb::run_to_stop`]). QEMU keeps it through a
    /// `system_reset`.
    pub fn set_breakpoint(&mut self, address: u32) -> Result<()> {
        // The kind is the instruction's size: 2 for Thumb (QEMU does not look at it).
        self.expect_ok(&format!("Z1,{address:x},2"))
    }

    /// Removes the breakpoint [`Gdb::set_breakpoint`] set at `address`.
    pub fn remove_breakpoint(&mut self, address: u32) -> Result<()> {
        self.expect_ok(&format!("z1,{address:x},2"))
    }

    /// Lets the machine run until it stops again (a breakpoint), waiting up to `timeout`; returns
    /// the stop reply (`T05...`: stopped by a trap). The session stays open.
    pub fn run_to_stop(&mut self, timeout: Duration) -> Result<String> {
        self.send("c")?;
        self.stream.set_read_timeout(Some(timeout))?;
        let stop = loop {
            match self.receive() {
                Ok(packet) if packet.starts_with('T') || packet.starts_with('S') => break Ok(packet),
                Ok(packet) if packet.starts_with('W') || packet.starts_with('X') => {
                    break Err(anyhow::anyhow!("gdb stub: the machine ended ({packet}) instead of stopping"))
                }
                Ok(_) => {}
                Err(e) => break Err(e.context(format!("the machine did not stop within {timeout:?}"))),
            }
        };
        self.stream.set_read_timeout(Some(REPLY))?;
        stop
    }

    /// Lets the machine run again and ends the session (the stub's reply comes only at the next
    /// stop, which nobody waits for).
    pub fn resume(mut self) -> Result<()> {
        self.send("c")
    }

    fn expect_ok(&mut self, body: &str) -> Result<()> {
        match self.request(body)?.as_str() {
            "OK" => Ok(()),
            other => bail!("gdb stub: {body} answered {other}"),
        }
    }

    fn request(&mut self, body: &str) -> Result<String> {
        self.send(body)?;
        self.reply()
    }

    /// The reply to the last request: the next packet that is not a stop notification (`T..`,
    /// `S..`: the stub may send one for the stop that connecting caused, besides the answer to `?`).
    fn reply(&mut self) -> Result<String> {
        loop {
            let packet = self.receive()?;
            if !(packet.starts_with('T') || packet.starts_with('S')) {
                return Ok(packet);
            }
        }
    }

    /// Sends one packet (its acknowledgement, a `+`, is skipped by [`Gdb::receive`]).
    fn send(&mut self, body: &str) -> Result<()> {
        let sum = body.bytes().fold(0u8, |s, b| s.wrapping_add(b));
        self.stream.write_all(format!("${body}#{sum:02x}").as_bytes())?;
        Ok(())
    }

    /// Receives one packet (acknowledged) and returns its body; a `-` (a packet the stub received
    /// damaged) fails.
    fn receive(&mut self) -> Result<String> {
        loop {
            match self.byte()? {
                b'$' => break,
                b'-' => bail!("gdb stub: a packet was received damaged"),
                _ => {}
            }
        }
        let mut body = Vec::new();
        loop {
            match self.byte()? {
                b'#' => break,
                b => body.push(b),
            }
        }
        let _checksum = [self.byte()?, self.byte()?];
        self.stream.write_all(b"+")?;
        Ok(String::from_utf8_lossy(&body).into_owned())
    }

    fn byte(&mut self) -> Result<u8> {
        let mut b = [0u8];
        self.stream.read_exact(&mut b).context("gdb stub: no reply")?;
        Ok(b[0])
    }
}

fn unhex(text: &str) -> Vec<u8> {
    text.as_bytes()
        .chunks(2)
        .filter_map(|pair| std::str::from_utf8(pair).ok().and_then(|p| u8::from_str_radix(p, 16).ok()))
        .collect()
}
