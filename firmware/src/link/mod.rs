//! The host link: the protocol between `armctl` on the PC and the firmware, over a serial line.
//!
//! Layers, bottom up:
//! - [`cobs`] and [`crc`]: byte stuffing (0x00 delimits frames) and CRC-16/CCITT-FALSE.
//! - [`frame`]: `COBS(seq, kind, postcard payload, CRC) 0x00`, at most [`frame::MAX_FRAME`] bytes on
//!   the wire, and a streaming [`frame::FrameDecoder`] that drops broken frames with counted reasons.
//! - [`message`]: [`message::HostMessage`] and [`message::FirmwareMessage`], fixed-size and
//!   serde-derived, with value validation.
//! - [`session`]: the firmware's request handling: a repeated request is acknowledged again but
//!   applied once; acks carry the free keyframe slots for the host's flow control.
//!
//! The host retransmits a request (same seq) until its reply comes, so over a lossy line every
//! request is applied exactly once as long as the host does not give up.
//!
//! # Panics
//! No function in this module panics on any input bytes or argument.

pub mod cobs;
pub mod crc;
pub mod frame;
pub mod message;
pub mod session;
