//! The firmware binary for the MPS2 AN386 (Cortex-M4F) under `qemu-system-arm`: building it,
//! starting QEMU with UART0 (host link) on a pseudo-terminal and UART1 on the simulated servo bus,
//! and following its defmt log. Used by `armctl sim --qemu`, `armctl bench mcu`, `armctl footprint`
//! and the HIL tests. ([`super::board::build`] builds any board crate, the STM32 one too.)

pub mod log;

use std::io::{BufRead, BufReader, Read};
use std::path::PathBuf;
use std::process::{Child, Command, ExitStatus, Stdio};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

use anyhow::{bail, Context, Result};

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

/// Whether `qemu-system-arm` can be started.
pub fn available() -> bool {
    Command::new("qemu-system-arm").arg("--version").stdout(Stdio::null()).stderr(Stdio::null()).status().is_ok()
}

/// Builds the MPS2 board crate's binary `bin` (release) and returns the ELF's path.
pub fn build(bin: &str) -> Result<PathBuf> {
    super::board::build(&board_dir(), bin)
}

/// What to start.
#[derive(Clone, Debug)]
pub struct QemuConfig {
    /// The firmware ELF.
    pub elf: PathBuf,
    /// The serial device for UART1 (the servo bus), e.g. a simulated bus's pty; `None` leaves it
    /// unconnected.
    pub bus: Option<String>,
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
    /// Starts QEMU with instruction counting (`-icount shift=0`: one instruction per virtual
    /// nanosecond, so timing inside the guest is repeatable) and waits for it to name UART0's pty.
    pub fn start(config: &QemuConfig) -> Result<Qemu> {
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
            .args(["-machine", "mps2-an386", "-display", "none", "-monitor", "none", "-icount", "shift=0"])
            .args(["-semihosting-config", "enable=on,target=native", "-kernel"])
            .arg(&elf)
            .args(["-serial", "pty", "-serial", config.bus.as_deref().unwrap_or("null")])
            .current_dir(&dir)
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped());
        let child = command.spawn().context("cannot start qemu-system-arm (apt-get install qemu-system-arm)")?;
        let log = DefmtLog::follow(&dir.join(LOG_FILE), &elf);
        let mut qemu = Qemu { child, dir, link: String::new(), log: None };
        qemu.log = Some(log?);
        qemu.link = qemu.read_link_path()?;
        Ok(qemu)
    }

    /// QEMU names each pty it opens on stdout: "char device redirected to /dev/pts/N (label serial0)".
    fn read_link_path(&mut self) -> Result<String> {
        let stdout = self.child.stdout.take().context("QEMU's stdout")?;
        let mut lines = BufReader::new(stdout);
        let mut line = String::new();
        loop {
            line.clear();
            if lines.read_line(&mut line)? == 0 {
                let mut why = String::new();
                if let Some(mut stderr) = self.child.stderr.take() {
                    let _ = stderr.read_to_string(&mut why);
                }
                bail!("qemu-system-arm ended before opening the link's pty: {}", why.trim());
            }
            if let Some(path) = line.strip_prefix("char device redirected to ") {
                if let Some((path, "(label serial0)")) = path.trim().split_once(' ') {
                    let path = path.to_string();
                    // QEMU prints nothing else of interest; keep its stdout drained.
                    std::thread::spawn(move || std::io::copy(&mut lines, &mut std::io::sink()));
                    return Ok(path);
                }
            }
        }
    }

    /// The pty of the host link (UART0), for `armctl --port`.
    pub fn link_path(&self) -> &str {
        &self.link
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

impl Drop for Qemu {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
        self.log.take();
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}
