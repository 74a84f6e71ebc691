//! Ctrl-C while an arm moves: the handler only sets a flag; the waiting loops check it between
//! requests, so a request is never cut in half and the arm is stopped through the link.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::OnceLock;

static REQUESTED: AtomicBool = AtomicBool::new(false);
static INSTALLED: OnceLock<bool> = OnceLock::new();

/// The exit code after a Ctrl-C (128 + SIGINT, as shells report it).
pub const EXIT_CODE: i32 = 130;

/// Installs the handler (once per process) and clears an earlier request. Returns whether Ctrl-C
/// is caught; when another handler was installed first, the default action (ending the process)
/// stays, which stops nothing on the arm: the firmware's watchdog brakes it when the host falls
/// silent.
pub fn catch() -> bool {
    REQUESTED.store(false, Ordering::SeqCst);
    *INSTALLED.get_or_init(|| ctrlc::set_handler(|| REQUESTED.store(true, Ordering::SeqCst)).is_ok())
}

/// Whether Ctrl-C was pressed since [`catch`].
pub fn requested() -> bool {
    REQUESTED.load(Ordering::SeqCst)
}
