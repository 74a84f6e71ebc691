//! The firmware's defmt log, decoded on the host: the firmware writes defmt frames over semihosting
//! to a file in QEMU's working directory, and a thread here follows the file as it grows and turns
//! each frame into a line with the ELF's defmt table (what `defmt-print -e ELF` does).

use std::fs::File;
use std::io::Read;
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use anyhow::{anyhow, Context, Result};
use defmt_decoder::{DecodeError, Table};

/// How often the file is checked for new bytes.
const POLL: Duration = Duration::from_millis(10);

/// The decoded lines so far, shared with the following thread.
#[derive(Debug)]
pub struct DefmtLog {
    lines: Arc<Mutex<Vec<String>>>,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl DefmtLog {
    /// Follows `file` (which need not exist yet), decoding with the defmt table of the ELF at `elf`.
    pub fn follow(file: &Path, elf: &Path) -> Result<DefmtLog> {
        let bytes = std::fs::read(elf).with_context(|| format!("cannot read {}", elf.display()))?;
        let table = Table::parse(&bytes)
            .map_err(|e| anyhow!("{}: bad defmt table: {e}", elf.display()))?
            .ok_or_else(|| anyhow!("{} has no defmt table (built without defmt?)", elf.display()))?;
        let lines = Arc::new(Mutex::new(Vec::new()));
        let stop = Arc::new(AtomicBool::new(false));
        let (sink, flag, path) = (lines.clone(), stop.clone(), file.to_path_buf());
        let thread =
            std::thread::Builder::new().name("defmt-log".into()).spawn(move || follow(&path, &table, &sink, &flag))?;
        Ok(DefmtLog { lines, stop, thread: Some(thread) })
    }

    /// The lines decoded so far.
    pub fn lines(&self) -> Vec<String> {
        self.lines_from(0)
    }

    /// The lines decoded so far after the first `seen` (to print them as they come).
    pub fn lines_from(&self, seen: usize) -> Vec<String> {
        self.lines.lock().map(|l| l.get(seen..).unwrap_or_default().to_vec()).unwrap_or_default()
    }

    /// Waits up to `timeout` for a line containing `text`; returns it.
    pub fn wait_for(&self, text: &str, timeout: Duration) -> Option<String> {
        let start = Instant::now();
        loop {
            if let Some(line) = self.lines().into_iter().rev().find(|l| l.contains(text)) {
                return Some(line);
            }
            if start.elapsed() > timeout {
                return None;
            }
            std::thread::sleep(POLL);
        }
    }

    /// Stops following after reading what the file holds now; returns all lines.
    pub fn finish(mut self) -> Vec<String> {
        self.halt();
        self.lines()
    }

    fn halt(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
    }
}

impl Drop for DefmtLog {
    fn drop(&mut self) {
        self.halt();
    }
}

fn follow(path: &Path, table: &Table, lines: &Mutex<Vec<String>>, stop: &AtomicBool) {
    let mut decoder = table.new_stream_decoder();
    let mut file: Option<File> = None;
    let mut buf = [0u8; 4096];
    loop {
        // Read once more after a stop request, so a log finished before it is complete.
        let stopping = stop.load(Ordering::Relaxed);
        if file.is_none() {
            file = File::open(path).ok();
        }
        let n = file.as_mut().and_then(|f| f.read(&mut buf).ok()).unwrap_or(0);
        if n > 0 {
            decoder.received(&buf[..n]);
            loop {
                let line = match decoder.decode() {
                    Ok(frame) => {
                        let level = frame.level().map_or("", |l| l.as_str());
                        format!("{level:<5} {}", frame.display_message())
                    }
                    Err(DecodeError::UnexpectedEof) => break,
                    Err(DecodeError::Malformed) => "ERROR (a malformed defmt frame was skipped)".to_string(),
                };
                if let Ok(mut all) = lines.lock() {
                    all.push(line);
                }
            }
            continue;
        }
        if stopping {
            return;
        }
        std::thread::sleep(POLL);
    }
}
