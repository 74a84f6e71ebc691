//! defmt's global logger over Arm semihosting: frames are written to the host file [`LOG_FILE`] in
//! QEMU's working directory (`-semihosting-config enable=on,target=native`), and `armctl` decodes
//! them with the ELF's defmt table (`armctl::qemu`). A file rather than the semihosting console,
//! because QEMU 7.2 writes the console to its own stdout, mixed with its messages. Written here rather than taken from
//! `defmt-semihosting` because that crate panics on re-entry, and the firmware's control loop must
//! reach no panic: a re-entrant frame (impossible here: only the main loop logs) is dropped instead.
//!
//! Semihosting traps into the debugger (QEMU): on a board without one it would fault, so this
//! logger belongs to the QEMU board only.

use core::cell::UnsafeCell;
use core::sync::atomic::{AtomicBool, Ordering};

use cortex_m_semihosting::{nr, syscall};

/// The log file's name (NUL-terminated for the semihosting call), relative to QEMU's directory.
pub const LOG_FILE: &str = "defmt.bin\0";

#[defmt::global_logger]
struct SemihostingLogger;

/// The logger's state, touched only between `acquire` and `release`, inside a critical section.
struct State {
    encoder: defmt::Encoder,
    /// The semihosting handle of the log file, once opened (`None` also when opening failed).
    console: Option<usize>,
    opened: bool,
    restore: critical_section::RestoreState,
}

struct Shared(UnsafeCell<State>);

// SAFETY: `State` is only reached through `SemihostingLogger`'s methods, which defmt calls in
// acquire/write/flush/release order, and `acquire` enters a critical section (interrupts off on this
// single core) and claims `TAKEN` before any access, so there is never more than one user.
unsafe impl Sync for Shared {}

static STATE: Shared = Shared(UnsafeCell::new(State {
    encoder: defmt::Encoder::new(),
    console: None,
    opened: false,
    restore: critical_section::RestoreState::invalid(),
}));
static TAKEN: AtomicBool = AtomicBool::new(false);
/// Whether this frame is being dropped (the logger was entered again before `release`).
static REENTERED: AtomicBool = AtomicBool::new(false);

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

/// Writes encoded bytes to the log file, opening it on first use. A host that refuses writes
/// loses log bytes, never the control loop's time: nothing is retried.
fn write_console(console: &mut Option<usize>, opened: &mut bool, bytes: &[u8]) {
    if !*opened {
        *opened = true;
        *console = open_log();
        // A frame separator first: a frame cut short by a reset ends here, so that it costs the
        // host one frame it reports malformed, not this start's first line too. (The host's
        // decoder skips runs of separators.)
        if let Some(handle) = *console {
            // SAFETY: SYS_WRITE reads the one byte of a static array for the whole call.
            let _ = unsafe { syscall!(WRITE, handle, [0u8].as_ptr(), 1) };
        }
    }
    if let Some(handle) = *console {
        // SAFETY: SYS_WRITE reads `bytes.len()` bytes from `bytes`, borrowed for the whole call.
        let _ = unsafe { syscall!(WRITE, handle, bytes.as_ptr(), bytes.len()) };
    }
}

// SAFETY: defmt requires the logger to be exclusive between acquire and release and not to be
// entered re-entrantly; the critical section and the TAKEN flag give the first, and a re-entrant
// call is turned into a dropped frame instead of touching the state.
unsafe impl defmt::Logger for SemihostingLogger {
    fn acquire() {
        // SAFETY: paired with `critical_section::release` in `release` (or just below).
        let restore = unsafe { critical_section::acquire() };
        if TAKEN.swap(true, Ordering::Acquire) {
            REENTERED.store(true, Ordering::Relaxed);
            // SAFETY: leaves the section this call entered; the outer frame's stays held.
            unsafe { critical_section::release(restore) };
            return;
        }
        // SAFETY: TAKEN was false and is now ours, inside the critical section: sole access.
        let state = unsafe { &mut *STATE.0.get() };
        state.restore = restore;
        let State { encoder, console, opened, .. } = state;
        encoder.start_frame(|bytes| write_console(console, opened, bytes));
    }

    unsafe fn flush() {}

    unsafe fn release() {
        if REENTERED.swap(false, Ordering::Relaxed) {
            return;
        }
        // SAFETY: between acquire and release the state is ours (see `acquire`).
        let state = unsafe { &mut *STATE.0.get() };
        let State { encoder, console, opened, restore } = state;
        encoder.end_frame(|bytes| write_console(console, opened, bytes));
        let restore = *restore;
        TAKEN.store(false, Ordering::Release);
        // SAFETY: leaves the critical section `acquire` entered.
        unsafe { critical_section::release(restore) };
    }

    unsafe fn write(bytes: &[u8]) {
        if REENTERED.load(Ordering::Relaxed) {
            return;
        }
        // SAFETY: between acquire and release the state is ours (see `acquire`).
        let state = unsafe { &mut *STATE.0.get() };
        let State { encoder, console, opened, .. } = state;
        encoder.write(bytes, |out| write_console(console, opened, out));
    }
}
