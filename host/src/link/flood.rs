//! Requests written back to back without waiting for a reply: what a host that floods the link
//! sends (a runaway script, a misbehaving client), for load measurements of the firmware
//! (`armctl bench loop-pass`). The product's own requests go through [`super::session`], which
//! waits on the firmware; this is the one other place that encodes requests, and nothing here reads
//! a reply.

use firmware::link::frame::{encode_message, FrameKind, MAX_FRAME};
use firmware::link::message::HostMessage;

/// One in this many of the flood's requests is a torque off (see [`flood_frame`]).
pub const TORQUE_OFF_EVERY: usize = 512;

/// The flood's `i`-th request frame, as the host's link client encodes it (sequence number `i`
/// modulo 256, so that no request repeats the one before): a `GetStatus`, or one in
/// [`TORQUE_OFF_EVERY`] (about every seventh pass) a torque off. A torque off makes the firmware
/// write the torque on its next tick and then read it back from every servo on up to ten ticks
/// (its `CONFIRM_TRIES`), which with every servo silent waits out a second sync read: the longest
/// tick there is, the kind every reset starts with. Without them the flood would meet only the
/// shorter ticks that follow (QEMU takes up to a second to notice that the link's pty was opened,
/// and the firmware's first ten ticks are over by then).
pub fn flood_frame(i: usize) -> Vec<u8> {
    let message =
        if i.is_multiple_of(TORQUE_OFF_EVERY) { HostMessage::Torque { on: false } } else { HostMessage::GetStatus };
    let mut frame = [0u8; MAX_FRAME];
    let n = encode_message(i as u8, FrameKind::Request, &message, &mut frame).unwrap_or(0);
    frame[..n].to_vec()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_status_request_is_seven_bytes_and_a_torque_off_eight() {
        assert_eq!(flood_frame(1).len(), 7);
        assert_eq!(flood_frame(300).len(), 7);
        assert_eq!(flood_frame(0).len(), 8);
        assert_eq!(flood_frame(TORQUE_OFF_EVERY).len(), 8);
        // Successive requests differ in their sequence number.
        assert_ne!(flood_frame(1), flood_frame(2));
    }
}
