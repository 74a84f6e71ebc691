//! Errors as Python sees them: every failure of the project's code is an `ArmctlError` with the
//! one line the command line prints after `error:`; Ctrl-C during a wait stops the arm and raises
//! `KeyboardInterrupt`, as Python's own Ctrl-C does.

use std::sync::Mutex;

use pyo3::prelude::*;

pyo3::create_exception!(
    armctl,
    ArmctlError,
    pyo3::exceptions::PyException,
    "A request armctl refused or could not carry out; the message is the command line's."
);

/// The error for `e`, with its causes on one line as `armctl` prints them.
pub fn to_py(e: anyhow::Error) -> PyErr {
    ArmctlError::new_err(format!("{e:#}"))
}

/// `?` for the project's results.
pub trait OrRaise<T> {
    /// The value, or the error as an [`ArmctlError`].
    fn or_raise(self) -> PyResult<T>;
}

impl<T> OrRaise<T> for anyhow::Result<T> {
    fn or_raise(self) -> PyResult<T> {
        self.map_err(to_py)
    }
}

/// The exception Python's signal handler raised while the project's code waited (Ctrl-C).
static INTERRUPTED: Mutex<Option<PyErr>> = Mutex::new(None);

/// Asked by the waiting loops between requests: runs Python's signal handlers (the GIL is taken
/// for the moment), and keeps what they raise for [`interrupted`].
fn python_signal() -> bool {
    Python::attach(|py| match py.check_signals() {
        Ok(()) => false,
        Err(e) => {
            *INTERRUPTED.lock().unwrap_or_else(|p| p.into_inner()) = Some(e);
            true
        }
    })
}

/// Leaves SIGINT to Python: the project's code never installs a handler in this process, and its
/// waiting loops ask Python whether Ctrl-C was pressed.
pub fn keep_python_signal_handling() {
    armctl::support::interrupt::delegate(python_signal);
}

/// The exception of a Ctrl-C taken while waiting, if there was one (the arm has been stopped).
pub fn interrupted() -> Option<PyErr> {
    INTERRUPTED.lock().unwrap_or_else(|p| p.into_inner()).take()
}
