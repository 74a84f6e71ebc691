//! [`DriveError`]: how a drive operation fails, told apart for the front ends. The command line
//! prints the one line after `error:` (or, after Ctrl-C, where the arm stopped) and exits with its
//! code; Python raises `ArmctlError` with the same line, or `KeyboardInterrupt`.

use firmware::link::message::Status;

use crate::runtime::driver::{Driver, Waited};

/// Why an operation did not finish.
#[derive(Debug)]
pub enum DriveError {
    /// What was asked is wrong (a value out of range, a file that does not parse): nothing was
    /// sent.
    Input(anyhow::Error),
    /// The operation failed: refused by the firmware (nothing moved, as the message says) or
    /// while the arm moved (the link, a timeout, the arm going limp).
    Failed(anyhow::Error),
    /// Ctrl-C: the arm was stopped (decelerating within its limits) and is at rest; `said` tells
    /// where, on one or more lines.
    Interrupted {
        /// Where the arm stopped, or what was dropped before it moved.
        said: String,
    },
}

impl DriveError {
    /// A failure with this message.
    pub fn failed(message: impl std::fmt::Display) -> Self {
        DriveError::Failed(anyhow::anyhow!("{message}"))
    }
}

impl std::fmt::Display for DriveError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            DriveError::Input(e) | DriveError::Failed(e) => write!(f, "{e:#}"),
            DriveError::Interrupted { said } => write!(f, "{said}"),
        }
    }
}

impl std::error::Error for DriveError {}

/// Anything the operations' helpers fail with (`?` on the link, the kinematics) is a failure.
impl From<anyhow::Error> for DriveError {
    fn from(e: anyhow::Error) -> Self {
        DriveError::Failed(e)
    }
}

impl From<crate::link::client::LinkError> for DriveError {
    fn from(e: crate::link::client::LinkError) -> Self {
        DriveError::Failed(e.into())
    }
}

impl From<std::io::Error> for DriveError {
    fn from(e: std::io::Error) -> Self {
        DriveError::Failed(e.into())
    }
}

/// An operation's result.
pub type DriveResult<T> = Result<T, DriveError>;

/// After Ctrl-C: the arm stopped ([`Driver::stop_for_interrupt`]), and where, after `before`.
pub(crate) fn interrupted(driver: &mut Driver, before: &str) -> DriveError {
    match driver.stop_for_interrupt(before) {
        Ok(said) => DriveError::Interrupted { said },
        Err(e) => DriveError::Failed(e),
    }
}

/// Waits until the arm is at rest ([`Driver::wait_until_rest`]); after Ctrl-C, stops it and
/// fails with where it stopped; a joint resting far from its setpoint fails the move by name
/// ([`super::blocked::check_at_rest`]).
pub(crate) fn rest(driver: &mut Driver, timeout: f64) -> DriveResult<Status> {
    match driver.wait_until_rest(timeout)? {
        Waited::Done(status) => super::blocked::check_at_rest(driver, *status).map_err(DriveError::Failed),
        Waited::Interrupted => Err(interrupted(driver, "")),
    }
}
