//! The firmware binary for the MPS2 AN386 (Cortex-M4F) under `qemu-system-arm`: building it,
//! starting QEMU with UART0 (host link) on a pseudo-terminal (made its owner's alone as soon as
//! QEMU names it) and UART1 on the simulated servo bus, and following its defmt log. Used by
//! `armctl sim --qemu`, `armctl bench mcu`, `armctl bench loop-pass`, `armctl footprint` and the
//! HIL tests.
//! ([`super::board::build`] builds any board crate, the STM32 one too.)

pub mod gdb;
pub mod log;

use std::io::{BufRead, BufReader, Read};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

use anyhow::{bail, Context, Result};
use object::{Object, ObjectSymbol};

use crate::support::rust_symbols::legacy_path;

pub use gdb::Gdb;
pub use log::DefmtLog;

/// The board crate (its own cargo workspace), found from this crate's source directory.
pub fn board_dir() -> PathBuf {
    super::board::boards_dir().join("mps2-an386")
}

/// The firmware binary's name (the board crate's main binary).
pub const FIRMWARE_BIN: &str = "board-mps2-an386";

/// The log file the firmware writes over semihosting, in QEMU's working directory (the board
/// crate's `log::LOG_FILE`).
const LOG_FILE: &str = "defmt.bin";

/// QEMU's gdb stub's socket in its working directory ([`Qemu::start_with_debugger`]).
const GDB_SOCKET: &str = "gdb.sock";

/// The start of the line the board binary's `main` logs just before it enters the control loop.
const STARTED_LINE: &str = "static state:";

/// How long the firmware may take to start under QEMU: a fraction of a second unloaded; the margin
/// is for a machine busy with other work.
pub const START_TIMEOUT: Duration = Duration::from_secs(60);

/// Whether `qemu-system-arm` can be started.
pub fn available() -> bool {
    Command::new("qemu-system-arm").arg("--version").stdout(Stdio::null()).stderr(Stdio::null()).status().is_ok()
}

/// Builds the MPS2 board crate's binary `bin` (release) and returns the ELF's path.
pub fn build(bin: &str) -> Result<PathBuf> {
    super::board::build(&board_dir(), bin)
}

/// The board crate's profile with debug assertions: the release build, but its panic handler logs
/// where and lets the watchdog reset the board, and it has `injected_panic` for a test to jump to
/// (the release build has no panic path at all).
pub const PANIC_TEST_PROFILE: &str = "panic-test";

/// As [`build`], with the board crate's cargo profile `profile` (e.g. [`PANIC_TEST_PROFILE`]); the
/// ELF is in the profile's own folder, so the release ELF stays as it was.
pub fn build_with_profile(bin: &str, profile: &str) -> Result<PathBuf> {
    super::board::build_with_profile(&board_dir(), bin, profile)
}

/// Where the function `path` is in the firmware ELF at `elf`, for a breakpoint or a jump
/// (without the Thumb bit): a `#[no_mangle]` function's name, or a Rust path without the hash
/// (`board_mps2_an386::start`, [`legacy_path`]). Fails if no function or more than one has it.
pub fn function_address(elf: &Path, path: &str) -> Result<u32> {
    let bytes = std::fs::read(elf).with_context(|| format!("cannot read {}", elf.display()))?;
    let address = address_in(&bytes, path).with_context(|| format!("in {}", elf.display()))?;
    u32::try_from(address).with_context(|| format!("{path} at {address:#x}, beyond 32 bits"))
}

/// The address of the function `path` in the ELF in `bytes`, its Thumb bit cleared: `path` is a
/// symbol's own name (`injected_panic`, a `#[no_mangle]` function) or the Rust path of a mangled
/// one without its hash (`board_mps2_an386::start`). Fails if no function or more than one has it.
fn address_in(bytes: &[u8], path: &str) -> Result<u64> {
    let file = object::File::parse(bytes).map_err(|e| anyhow::anyhow!("not an ELF file: {e}"))?;
    let mut found = file
        .symbols()
        .filter(|s| s.kind() == object::SymbolKind::Text)
        .filter(|s| s.name().is_ok_and(|name| name == path || legacy_path(name).as_deref() == Some(path)))
        .map(|s| s.address() & !1);
    match (found.next(), found.next()) {
        (Some(address), None) => Ok(address),
        (None, _) => Err(anyhow::anyhow!("no function {path} in the ELF")),
        (Some(_), Some(_)) => Err(anyhow::anyhow!("more than one function {path} in the ELF")),
    }
}

/// What to start.
#[derive(Clone, Debug)]
pub struct QemuConfig {
    /// The firmware ELF.
    pub elf: PathBuf,
    /// The serial device for UART1 (the servo bus), e.g. a simulated bus's pty; `None` leaves it
    /// unconnected.
    pub bus: Option<String>,
    /// QEMU's `-icount shift=S`: every guest instruction advances virtual time by 2^S ns. 0 (one
    /// instruction per virtual nanosecond) unless a measurement separates instructions from
    /// fixed waits by running at two shifts (`armctl bench loop-pass`).
    pub icount_shift: u8,
}

impl QemuConfig {
    /// `elf` with UART1 on `bus`, at `-icount shift=0`.
    pub fn new(elf: PathBuf, bus: Option<String>) -> Self {
        Self { elf, bus, icount_shift: 0 }
    }
}

/// A running QEMU; dropping it kills QEMU and removes its working directory.
#[derive(Debug)]
pub struct Qemu {
    child: Child,
    dir: PathBuf,
    link: String,
    log: Option<DefmtLog>,
}

impl Qemu {
    /// Starts QEMU with instruction counting (`-icount shift=0`, unless
    /// [`QemuConfig::icount_shift`] says otherwise: one instruction per virtual nanosecond, so
    /// timing inside the guest is repeatable) and waits for it to name UART0's pty, which it then
    /// makes its owner's alone. Fails in one line if it cannot.
    pub fn start(config: &QemuConfig) -> Result<Qemu> {
        Self::spawn(config, false)
    }

    /// As [`Qemu::start`], with QEMU's gdb stub listening on a unix socket in its working
    /// directory, for [`Qemu::debugger`]: tests that act on the firmware from outside, as a probe
    /// does on a board.
    pub fn start_with_debugger(config: &QemuConfig) -> Result<Qemu> {
        Self::spawn(config, true)
    }

    /// Connects to the gdb stub of a QEMU started with [`Qemu::start_with_debugger`]; the machine
    /// stops until [`Gdb::resume`].
    pub fn debugger(&self) -> Result<Gdb> {
        Gdb::connect(&self.dir.join(GDB_SOCKET))
    }

    fn spawn(config: &QemuConfig, debugger: bool) -> Result<Qemu> {
        static RUNS: AtomicUsize = AtomicUsize::new(0);
        let dir = std::env::temp_dir().join(format!(
            "armctl-qemu-{}-{}",
            std::process::id(),
            RUNS.fetch_add(1, Ordering::Relaxed)
        ));
        std::fs::create_dir_all(&dir).with_context(|| format!("cannot create {}", dir.display()))?;
        let elf =
            std::fs::canonicalize(&config.elf).with_context(|| format!("no firmware at {}", config.elf.display()))?;
        let mut command = Command::new("qemu-system-arm");
        command
            .args(["-machine", "mps2-an386", "-display", "none", "-monitor", "none", "-icount"])
            .arg(format!("shift={}", config.icount_shift))
            .args(["-semihosting-config", "enable=on,target=native", "-kernel"])
            .arg(&elf)
            .args(["-serial", "pty", "-serial", config.bus.as_deref().unwrap_or("null")])
            .current_dir(&dir)
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped());
        if debugger {
            command.arg("-gdb").arg(format!("unix:{},server=on,wait=off", dir.join(GDB_SOCKET).display()));
        }
        let child = command.spawn().context("cannot start qemu-system-arm (apt-get install qemu-system-arm)")?;
        let log = DefmtLog::follow(&dir.join(LOG_FILE), &elf);
        let mut qemu = Qemu { child, dir, link: String::new(), log: None };
        qemu.log = Some(log?);
        qemu.link = qemu.read_link_path(&pty_labels(config))?;
        Ok(qemu)
    }

    /// Reads QEMU's stdout until it has named the ptys of `labels` (UART0's first), each made its
    /// owner's alone as it is named ([`take_ptys`]); returns UART0's.
    fn read_link_path(&mut self, labels: &[&str]) -> Result<String> {
        let stdout = self.child.stdout.take().context("QEMU's stdout")?;
        let mut lines = BufReader::new(stdout);
        let Some(paths) = take_ptys(&mut lines, labels)? else {
            let mut why = String::new();
            if let Some(mut stderr) = self.child.stderr.take() {
                let _ = stderr.read_to_string(&mut why);
            }
            bail!("qemu-system-arm ended before opening the link's pty: {}", why.trim());
        };
        // QEMU prints nothing else of interest; keep its stdout drained.
        std::thread::spawn(move || std::io::copy(&mut lines, &mut std::io::sink()));
        Ok(paths.into_iter().next().unwrap_or_default())
    }

    /// The pty of the host link (UART0), its owner's alone (mode 0600), for `armctl --port`.
    pub fn link_path(&self) -> &str {
        &self.link
    }

    /// Waits up to `timeout` for the board binary to log that its control loop starts (the line
    /// its `main` logs once the hardware and the firmware core are up). The host link is served
    /// from then on; a handshake sent earlier, while a loaded machine still boots the emulator,
    /// could spend its retries before the firmware listens.
    pub fn wait_started(&self, timeout: Duration) -> Result<()> {
        match self.log().wait_for(STARTED_LINE, timeout) {
            Some(_) => Ok(()),
            None => bail!(
                "the firmware under QEMU did not start within {} s (no \"{STARTED_LINE}\" in its log)",
                timeout.as_secs()
            ),
        }
    }

    /// The firmware's log.
    pub fn log(&self) -> &DefmtLog {
        self.log.as_ref().expect("the log is set in start")
    }

    /// QEMU's exit status if it has ended.
    pub fn exited(&mut self) -> Result<Option<ExitStatus>> {
        Ok(self.child.try_wait()?)
    }

    /// Waits up to `timeout` for the firmware to end QEMU (a semihosting exit, as `opcount` does);
    /// returns its exit status and the whole log.
    pub fn wait(mut self, timeout: Duration) -> Result<(ExitStatus, Vec<String>)> {
        let start = Instant::now();
        loop {
            if let Some(status) = self.child.try_wait()? {
                let lines = self.log.take().map(DefmtLog::finish).unwrap_or_default();
                return Ok((status, lines));
            }
            if start.elapsed() > timeout {
                bail!("the firmware did not end within {timeout:?}");
            }
            std::thread::sleep(Duration::from_millis(20));
        }
    }
}

/// The ptys QEMU opens itself, by their labels: UART0's (`-serial pty`), and UART1's only if the
/// bus is given as `pty` too. A path given for the bus, such as a [`crate::sim::PtyServer`]'s, is a
/// device that QEMU opens and does not make: its server has made it private already.
fn pty_labels(config: &QemuConfig) -> Vec<&'static str> {
    let mut labels = vec!["serial0"];
    if config.bus.as_deref() == Some("pty") {
        labels.push("serial1");
    }
    labels
}

/// Reads QEMU's stdout until it has named the pty of each of `labels`; returns their paths in
/// that order, or `None` if the output ended first. QEMU names each pty it opens in a line
/// "char device redirected to /dev/pts/N (label serial0)", and each is made its owner's alone
/// ([`crate::support::pty_owner::make_private`]) as soon as it is named, before anyone is told its path:
/// it takes commands for the board (a desktop's devpts would leave it writable by group tty).
fn take_ptys(stdout: &mut impl BufRead, labels: &[&str]) -> Result<Option<Vec<String>>> {
    let mut paths: Vec<Option<String>> = vec![None; labels.len()];
    let mut line = String::new();
    while paths.iter().any(Option::is_none) {
        line.clear();
        if stdout.read_line(&mut line)? == 0 {
            return Ok(None);
        }
        let named = line.strip_prefix("char device redirected to ").and_then(|rest| rest.trim().split_once(' '));
        let Some((path, label)) = named else { continue };
        let label = label.strip_prefix("(label ").and_then(|l| l.strip_suffix(')')).unwrap_or(label);
        // Every pty QEMU names, whether or not it is one of `labels`.
        crate::support::pty_owner::make_private(path).with_context(|| format!("qemu-system-arm's {label}"))?;
        if let Some(i) = labels.iter().position(|l| *l == label) {
            paths[i] = Some(path.to_string());
        }
    }
    Ok(Some(paths.into_iter().flatten().collect()))
}

impl Drop for Qemu {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
        self.log.take();
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serialport::{SerialPort, TTYPort};
    use std::os::unix::fs::{MetadataExt, PermissionsExt};

    fn mode(path: &str) -> u32 {
        std::fs::metadata(path).unwrap().mode() & 0o7777
    }

    /// What QEMU prints, with two ptys handed out as a desktop's devpts mount (`mode=620`) hands
    /// them out: each is private by the time its path is returned, the one not asked for too.
    #[test]
    fn every_pty_qemu_names_is_made_its_owners_alone() {
        let ends: Vec<(TTYPort, TTYPort)> = (0..2).map(|_| TTYPort::pair().unwrap()).collect();
        let paths: Vec<String> = ends.iter().map(|(_, slave)| slave.name().unwrap()).collect();
        for path in &paths {
            std::fs::set_permissions(path, std::fs::Permissions::from_mode(0o620)).unwrap();
        }
        let stdout = format!(
            "QEMU 7.2.22 monitor - type 'help' for more information\n\
             char device redirected to {} (label serial1)\n\
             char device redirected to {} (label serial0)\n\
             later output\n",
            paths[1], paths[0]
        );
        let named = take_ptys(&mut stdout.as_bytes(), &["serial0"]).unwrap();
        assert_eq!(named, Some(vec![paths[0].clone()]));
        for path in &paths {
            assert_eq!(mode(path), 0o600, "{path}");
        }
        let both = take_ptys(&mut stdout.as_bytes(), &["serial0", "serial1"]).unwrap();
        assert_eq!(both, Some(vec![paths[0].clone(), paths[1].clone()]));
    }

    #[test]
    fn a_pty_that_cannot_be_made_private_fails_in_one_line_naming_it() {
        let stdout = "char device redirected to /nonexistent/pts/9 (label serial0)\n";
        let message = format!("{:#}", take_ptys(&mut stdout.as_bytes(), &["serial0"]).unwrap_err());
        assert_eq!(message.lines().count(), 1, "{message}");
        assert!(message.contains("/nonexistent/pts/9") && message.contains("serial0"), "{message}");
        // Output that ends before the pty is named: QEMU ended.
        assert_eq!(take_ptys(&mut "qemu-system-arm: bad option\n".as_bytes(), &["serial0"]).unwrap(), None);
    }

    #[test]
    fn qemu_opens_a_pty_of_its_own_for_the_link_only() {
        let config = |bus: Option<&str>| QemuConfig::new(PathBuf::new(), bus.map(str::to_string));
        assert_eq!(pty_labels(&config(None)), ["serial0"]);
        assert_eq!(pty_labels(&config(Some("/dev/pts/7"))), ["serial0"]);
        assert_eq!(pty_labels(&config(Some("pty"))), ["serial0", "serial1"]);
    }
}
