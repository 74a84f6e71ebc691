//! Waiting on the firmware through the link: requests it refuses with `NotReady` until its next
//! ticks (torque on before every servo was read, a new arm before torque off took effect), and
//! polling until the arm is at rest. Shared by the drive commands, `armctl footprint`'s QEMU
//! session and the HIL tests.

use anyhow::{bail, Result};
use firmware::link::message::{FirmwareMessage, HostMessage, NakReason, RunState, Status};

use super::client::{LinkClient, LinkError};
use super::Transport;

/// Sends `message`, again after each `NotReady` for up to `waits` wait slots (a read timeout
/// each); returns the firmware's reply, or its last refusal.
pub fn request_when_ready<T: Transport>(
    c: &mut LinkClient<T>,
    message: &HostMessage,
    waits: usize,
) -> Result<FirmwareMessage, LinkError> {
    let mut waited = 0;
    loop {
        match c.request(message) {
            Err(LinkError::Nak(NakReason::NotReady)) if waited < waits => {
                waited += 1;
                c.wait_once()?;
            }
            other => return other,
        }
    }
}

/// Polls status until the arm is at rest; fails if it is still moving after `polls` requests.
pub fn wait_idle<T: Transport>(c: &mut LinkClient<T>, polls: usize) -> Result<Status> {
    let mut status = c.status()?;
    for _ in 0..polls {
        if status.state == RunState::Idle {
            return Ok(status);
        }
        c.wait_once()?;
        status = c.status()?;
    }
    if status.state != RunState::Idle {
        bail!("the arm did not come to rest after {polls} status polls");
    }
    Ok(status)
}
