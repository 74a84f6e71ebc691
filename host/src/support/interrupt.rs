//! Ctrl-C (or SIGTERM) while an arm moves: the handler only sets a flag and counts; the waiting
//! loops check it between requests, so a request is never cut in half and the arm is stopped
//! through the link.

use std::sync::atomic::{AtomicBool, AtomicU32, Ordering};
use std::sync::OnceLock;

static REQUESTED: AtomicBool = AtomicBool::new(false);
static COUNT: AtomicU32 = AtomicU32::new(0);
static INSTALLED: OnceLock<bool> = OnceLock::new();
/// Asked by [`requested`] in a process that keeps its own signal handling ([`delegate`]).
static CHECK: OnceLock<fn() -> bool> = OnceLock::new();

/// The exit code after a Ctrl-C (128 + SIGINT, as shells report it).
pub const EXIT_CODE: i32 = 130;

/// Installs the handler (once per process) and clears an earlier request. Returns whether Ctrl-C
/// is caught; when another handler was installed first, the default action (ending the process)
/// stays, which stops nothing on the arm: the firmware's watchdog brakes it when the host falls
/// silent.
pub fn catch() -> bool {
    REQUESTED.store(false, Ordering::SeqCst);
    COUNT.store(0, Ordering::SeqCst);
    *INSTALLED.get_or_init(|| {
        ctrlc::set_handler(|| {
            REQUESTED.store(true, Ordering::SeqCst);
            COUNT.fetch_add(1, Ordering::SeqCst);
        })
        .is_ok()
    })
}

/// Signals received since [`catch`] (`armctl serve` stops the arm on the first and switches the
/// torque off on the second).
pub fn count() -> u32 {
    COUNT.load(Ordering::SeqCst)
}

/// Whether Ctrl-C was pressed since [`catch`].
pub fn requested() -> bool {
    if REQUESTED.load(Ordering::SeqCst) {
        return true;
    }
    let asked = CHECK.get().is_some_and(|check| check());
    if asked {
        REQUESTED.store(true, Ordering::SeqCst);
        COUNT.fetch_add(1, Ordering::SeqCst);
    }
    asked
}

/// For a process that keeps its own signal handling (the Python interpreter, whose Ctrl-C raises
/// `KeyboardInterrupt`): no handler is ever installed, and the waiting loops ask `check` instead,
/// which says whether Ctrl-C was pressed. Call it before anything else here; later calls change
/// nothing.
pub fn delegate(check: fn() -> bool) {
    let _ = INSTALLED.set(true);
    let _ = CHECK.set(check);
}
