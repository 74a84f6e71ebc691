//! The firmware's side of the link: answers each request frame exactly once in effect.
//!
//! The host sends one request at a time and retransmits it, with the same seq, until a reply
//! arrives. So a request whose reply was lost comes again: [`Session::handle`] then sends the
//! reply it sent before without applying the request a second time. A repeat is recognised by its
//! seq and its CRC together, so a host that restarted and reuses a seq with a different message is
//! not mistaken for a repeat; [`HostMessage::Hello`] is always applied (it is idempotent and starts
//! a session).
//!
//! Only applied requests are remembered: a refused request changed nothing, so a repeat of it is
//! judged afresh. The cached reply of an ack reports the free slots when it was first sent; the
//! queue can only have drained since (no other request came between), so the count is never too
//! high for flow control.
//!
//! # Panics
//! Never, on any frame.

use super::frame::{decode_payload, encode_message, Frame, FrameError, FrameKind};
use super::message::{FirmwareMessage, HostMessage, NakReason};

/// What a session has done.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SessionStats {
    /// Requests applied.
    pub applied: u32,
    /// Repeated requests answered from the cache.
    pub repeats: u32,
    /// Naks sent (for requests and for broken frames).
    pub naks: u32,
}

/// Sequence tracking and replies for one host link.
#[derive(Clone, Debug, Default)]
pub struct Session {
    /// Seq and CRC of the last applied request, and the reply sent for it.
    last: Option<(u8, u16, FirmwareMessage)>,
    /// Seq of the next event frame.
    event_seq: u8,
    stats: SessionStats,
}

impl Session {
    /// A session that has seen nothing.
    pub const fn new() -> Self {
        Self { last: None, event_seq: 0, stats: SessionStats { applied: 0, repeats: 0, naks: 0 } }
    }

    /// Counters since creation.
    pub fn stats(&self) -> SessionStats {
        self.stats
    }

    /// Answers a request frame: decodes and validates its message, calls `apply` for a new one
    /// (which returns the reply: an ack with the free slots, info, status, or a nak if it refused
    /// the request and changed nothing) or reuses the reply of a repeat, and writes the reply
    /// frame into `out` (at least [`super::frame::MAX_FRAME`] bytes). Returns the bytes written.
    pub fn handle<F>(&mut self, frame: &Frame<'_>, out: &mut [u8], apply: F) -> Result<usize, FrameError>
    where
        F: FnOnce(&HostMessage) -> FirmwareMessage,
    {
        if frame.kind != FrameKind::Request {
            return self.reply_nak(frame.seq, NakReason::UnknownMessage, out);
        }
        let message = match decode_payload::<HostMessage>(frame.payload) {
            Ok(m) => m,
            Err(e) => return self.reply_nak(frame.seq, NakReason::from(e), out),
        };
        let hello = matches!(message, HostMessage::Hello { .. });
        if let Some((seq, crc, reply)) = &self.last {
            if !hello && *seq == frame.seq && *crc == frame.crc {
                self.stats.repeats = self.stats.repeats.wrapping_add(1);
                return encode_message(frame.seq, FrameKind::Reply, reply, out);
            }
        }
        if let Err(e) = message.validate() {
            return self.reply_nak(frame.seq, NakReason::BadValue(e), out);
        }
        let reply = apply(&message);
        if let FirmwareMessage::Nak { .. } = reply {
            self.stats.naks = self.stats.naks.wrapping_add(1);
        } else {
            self.stats.applied = self.stats.applied.wrapping_add(1);
        }
        let n = encode_message(frame.seq, FrameKind::Reply, &reply, out)?;
        if !matches!(reply, FirmwareMessage::Nak { .. }) {
            self.last = Some((frame.seq, frame.crc, reply));
        }
        Ok(n)
    }

    /// Answers bytes that were no frame (from [`super::frame::FrameDecoder`]): a nak event with
    /// the reason, so the host retransmits at once instead of waiting out its timeout.
    pub fn nak_broken(&mut self, error: &FrameError, out: &mut [u8]) -> Result<usize, FrameError> {
        self.stats.naks = self.stats.naks.wrapping_add(1);
        self.event(&FirmwareMessage::Nak { reason: NakReason::from(*error) }, out)
    }

    /// Builds an event frame (telemetry) with the next event seq.
    pub fn event(&mut self, message: &FirmwareMessage, out: &mut [u8]) -> Result<usize, FrameError> {
        let seq = self.event_seq;
        self.event_seq = self.event_seq.wrapping_add(1);
        encode_message(seq, FrameKind::Event, message, out)
    }

    fn reply_nak(&mut self, seq: u8, reason: NakReason, out: &mut [u8]) -> Result<usize, FrameError> {
        self.stats.naks = self.stats.naks.wrapping_add(1);
        encode_message(seq, FrameKind::Reply, &FirmwareMessage::Nak { reason }, out)
    }
}
