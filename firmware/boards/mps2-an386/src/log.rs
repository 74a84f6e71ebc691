//! defmt's global logger over Arm semihosting: frames are written to the host file [`LOG_FILE`] in
//! QEMU's working directory (`-semihosting-config enable=on,target=native`), and `armctl` decodes
//! them with the ELF's defmt table (`armctl::qemu`). A file rather than the semihosting console,
//! because QEMU 7.2 writes the console to its own stdout, mixed with its messages. Written here rather
//! than taken from `defmt-semihosting` because that crate panics on re-entry, and the firmware must
//! reach no panic: the frames are held as the STM32's RTT logger holds them
//! ([`board_support::frames`]), a re-entrant frame (from a fault handler) dropped instead.
//!
//! Semihosting traps into the debugger (QEMU): on a board without one it would fault, so this
//! logger belongs to the QEMU board only.

use board_support::frames::{Frames, Sink};
use cortex_m_semihosting::{nr, syscall};

/// The log file's name (NUL-terminated for the semihosting call), relative to QEMU's directory.
pub const LOG_FILE: &str = "defmt.bin\0";

/// The log file as the frames' sink, opened on first use.
struct LogFile {
    /// The semihosting handle of the log file, once opened (`None` also when opening failed).
    handle: Option<usize>,
    opened: bool,
}

static FRAMES: Frames<LogFile> = Frames::new(LogFile { handle: None, opened: false });

board_support::global_logger!(FRAMES);

/// Opens the log file on the host (binary) at its end, or `None` if the host refuses. After a reset
/// (QEMU keeps running) the firmware opens it again, and the host, following the file, reads on
/// where it was: so the file is opened for update and written from its end, and only created
/// (truncated) when it is not there yet (each QEMU starts in a new directory). Not the append mode:
/// with it, Debian's QEMU 7.2 put a restarted firmware's first frame over the old log's start
/// (seen in `tests/hil_qemu.rs`: the host decoded a malformed frame).
fn open_log() -> Option<usize> {
    let name = LOG_FILE.as_bytes();
    // SAFETY: SYS_OPEN reads `name.len() - 1` bytes of the NUL-terminated name, which lives for the
    // whole call (a static string).
    let open = |mode| unsafe { syscall!(OPEN, name.as_ptr(), mode, name.len() - 1) };
    let mut handle = open(nr::open::RW_BINARY);
    if handle as isize >= 0 {
        // SAFETY: SYS_FLEN and SYS_SEEK take the handle just opened and a number.
        unsafe {
            let length = syscall!(FLEN, handle);
            if length as isize > 0 {
                let _ = syscall!(SEEK, handle, length);
            }
        }
    } else {
        handle = open(nr::open::W_TRUNC_BINARY);
    }
    (handle as isize >= 0).then_some(handle)
}

impl Sink for LogFile {
    /// Writes encoded bytes to the log file, opening it on first use. A host that refuses writes
    /// loses log bytes, never the control loop's time: nothing is retried.
    fn write(&mut self, bytes: &[u8]) {
        if !self.opened {
            self.opened = true;
            self.handle = open_log();
            // A frame separator first: a frame cut short by a reset ends here, so that it costs
            // the host one frame it reports malformed, not this start's first line too. (The
            // host's decoder skips runs of separators.)
            if let Some(handle) = self.handle {
                // SAFETY: SYS_WRITE reads the one byte of a static array for the whole call.
                let _ = unsafe { syscall!(WRITE, handle, [0u8].as_ptr(), 1) };
            }
        }
        if let Some(handle) = self.handle {
            // SAFETY: SYS_WRITE reads `bytes.len()` bytes from `bytes`, borrowed for the whole call.
            let _ = unsafe { syscall!(WRITE, handle, bytes.as_ptr(), bytes.len()) };
        }
    }
}
