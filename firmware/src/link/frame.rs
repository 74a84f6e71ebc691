//! Link frames: `COBS(seq, kind, payload, CRC) 0x00`.
//!
//! ```text
//! raw:   seq u8 | kind u8 | postcard payload (0..=250 bytes) | CRC-16/CCITT-FALSE, big-endian
//! wire:  COBS(raw) (one code byte of overhead below 254 raw bytes) | 0x00
//! ```
//!
//! The CRC covers seq, kind and payload. A frame is at most [`MAX_FRAME`] = 256 bytes on the wire,
//! delimiter included, so a receiver needs one fixed buffer. Kinds: [`FrameKind::Request`] (host to
//! firmware, sequenced, answered by exactly one [`FrameKind::Reply`] with the same seq) and
//! [`FrameKind::Event`] (firmware to host, unrequested: telemetry, and naks of frames too damaged
//! to have a trustworthy seq; its seq counts events, so lost ones show).
//!
//! [`FrameDecoder`] splits received bytes at each 0x00 and drops what is not a frame, counting why.
//!
//! # Panics
//! Never, on any bytes: every length is checked, and a buffer too small is an error value. Under
//! `cfg(fuzzing)` the CRC is not checked, so that the fuzzer reaches the message decoder.

use serde::{de::DeserializeOwned, Serialize};

use super::cobs::{self, CobsError};
use super::crc::crc16;

/// Largest frame on the wire, delimiter included.
pub const MAX_FRAME: usize = 256;
/// Largest COBS-encoded frame without its delimiter: what a [`FrameDecoder`] must hold.
pub const MAX_ENCODED: usize = MAX_FRAME - 1;
/// Largest frame before COBS: 254 bytes encode with one byte of overhead to 255.
pub const MAX_RAW: usize = 254;
/// Bytes of seq and kind.
pub const HEADER_LEN: usize = 2;
/// Bytes of CRC.
pub const CRC_LEN: usize = 2;
/// Largest payload.
pub const MAX_PAYLOAD: usize = MAX_RAW - HEADER_LEN - CRC_LEN;
/// Wire bytes a frame adds to its payload (header, CRC, COBS code byte, delimiter).
pub const OVERHEAD: usize = HEADER_LEN + CRC_LEN + 2;

/// What a frame carries.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FrameKind {
    /// Host to firmware: a [`super::message::HostMessage`], to be answered.
    Request = 0x01,
    /// Firmware to host: the [`super::message::FirmwareMessage`] answering the request of the same seq.
    Reply = 0x02,
    /// Firmware to host: an unrequested [`super::message::FirmwareMessage`].
    Event = 0x03,
}

impl FrameKind {
    /// The kind of a kind byte, if there is one.
    pub fn from_byte(byte: u8) -> Option<Self> {
        match byte {
            0x01 => Some(Self::Request),
            0x02 => Some(Self::Reply),
            0x03 => Some(Self::Event),
            _ => None,
        }
    }
}

/// A checked frame, borrowing its payload from the decoder.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Frame<'a> {
    /// Sequence number.
    pub seq: u8,
    /// Kind.
    pub kind: FrameKind,
    /// The postcard payload.
    pub payload: &'a [u8],
    /// The frame's CRC: with the seq, it tells a repeated request from a new one.
    pub crc: u16,
}

/// Why bytes are not a frame, or a frame cannot be built.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FrameError {
    /// More bytes between delimiters than [`MAX_ENCODED`] (or the decoder's capacity).
    Oversized {
        /// Bytes received before the delimiter.
        len: usize,
    },
    /// Not valid COBS.
    Cobs(CobsError),
    /// Fewer raw bytes than header and CRC.
    Truncated {
        /// Raw bytes there are.
        len: usize,
    },
    /// The CRC does not match.
    Crc {
        /// CRC carried by the frame.
        received: u16,
        /// CRC computed over the frame.
        computed: u16,
    },
    /// A kind byte this protocol does not define.
    UnknownKind {
        /// The byte.
        kind: u8,
    },
    /// The payload does not decode as a message of this protocol.
    UnknownMessage,
    /// A message does not fit a frame, or the output buffer is too small.
    BufferTooSmall,
}

impl core::fmt::Display for FrameError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Oversized { len } => write!(f, "frame of {len} bytes exceeds {MAX_ENCODED}"),
            Self::Cobs(e) => write!(f, "{e}"),
            Self::Truncated { len } => write!(f, "frame of {len} bytes is shorter than header and CRC"),
            Self::Crc { received, computed } => {
                write!(f, "bad frame CRC: received {received:#06x}, computed {computed:#06x}")
            }
            Self::UnknownKind { kind } => write!(f, "unknown frame kind {kind:#04x}"),
            Self::UnknownMessage => write!(f, "payload is not a known message"),
            Self::BufferTooSmall => write!(f, "message does not fit a frame"),
        }
    }
}

/// Builds a wire frame (COBS and delimiter) around `payload`; returns its length.
pub fn encode_frame(seq: u8, kind: FrameKind, payload: &[u8], out: &mut [u8]) -> Result<usize, FrameError> {
    let mut raw = [0u8; MAX_RAW];
    let end = HEADER_LEN + payload.len();
    let body = raw.get_mut(HEADER_LEN..end).ok_or(FrameError::BufferTooSmall)?;
    body.copy_from_slice(payload);
    finish(seq, kind, &mut raw, end, out)
}

/// Serialises `message` with postcard and builds a wire frame around it; returns its length.
pub fn encode_message<M: Serialize>(
    seq: u8,
    kind: FrameKind,
    message: &M,
    out: &mut [u8],
) -> Result<usize, FrameError> {
    let mut raw = [0u8; MAX_RAW];
    let payload_len = postcard::to_slice(message, &mut raw[HEADER_LEN..MAX_RAW - CRC_LEN])
        .map_err(|_| FrameError::BufferTooSmall)?
        .len();
    finish(seq, kind, &mut raw, HEADER_LEN + payload_len, out)
}

/// Header and CRC into `raw[..end + CRC_LEN]`, then COBS and the delimiter into `out`.
fn finish(seq: u8, kind: FrameKind, raw: &mut [u8; MAX_RAW], end: usize, out: &mut [u8]) -> Result<usize, FrameError> {
    // Written so that no addition can wrap: the bound is then known to the slicing below.
    if end > MAX_RAW - CRC_LEN {
        return Err(FrameError::BufferTooSmall);
    }
    raw[0] = seq;
    raw[1] = kind as u8;
    let crc = crc16(&raw[..end]);
    raw[end..end + CRC_LEN].copy_from_slice(&crc.to_be_bytes());
    let n = cobs::encode(&raw[..end + CRC_LEN], out).map_err(|_| FrameError::BufferTooSmall)?;
    *out.get_mut(n).ok_or(FrameError::BufferTooSmall)? = 0;
    Ok(n + 1)
}

/// Checks a COBS-decoded frame: length, CRC, kind.
pub fn parse_raw(raw: &[u8]) -> Result<Frame<'_>, FrameError> {
    if raw.len() < HEADER_LEN + CRC_LEN {
        return Err(FrameError::Truncated { len: raw.len() });
    }
    let (body, tail) = raw.split_at(raw.len() - CRC_LEN);
    let received = u16::from_be_bytes([tail[0], tail[1]]);
    let computed = crc16(body);
    if received != computed && !cfg!(fuzzing) {
        return Err(FrameError::Crc { received, computed });
    }
    let kind = FrameKind::from_byte(body[1]).ok_or(FrameError::UnknownKind { kind: body[1] })?;
    Ok(Frame { seq: body[0], kind, payload: &body[HEADER_LEN..], crc: received })
}

/// Decodes a frame's payload as one message; trailing bytes make it unknown, so that a message
/// from a newer protocol with extra fields is refused rather than half-read.
pub fn decode_payload<M: DeserializeOwned>(payload: &[u8]) -> Result<M, FrameError> {
    match postcard::take_from_bytes::<M>(payload) {
        Ok((message, [])) => Ok(message),
        _ => Err(FrameError::UnknownMessage),
    }
}

/// What a [`FrameDecoder`] has seen.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FrameStats {
    /// Frames delivered.
    pub frames: u32,
    /// Frames dropped for bad COBS, a bad CRC or too few bytes.
    pub corrupt: u32,
    /// Frames dropped as oversized.
    pub oversized: u32,
    /// Frames dropped for an unknown kind.
    pub unknown_kind: u32,
}

/// A streaming frame splitter: bytes in, checked frames out. Holds at most `CAP` encoded bytes;
/// `CAP` is normally [`MAX_ENCODED`], and anything longer than `min(CAP, MAX_ENCODED)` between
/// delimiters is dropped as oversized when its delimiter comes.
#[derive(Clone, Debug)]
pub struct FrameDecoder<const CAP: usize> {
    encoded: [u8; CAP],
    len: usize,
    /// Bytes of the current frame that did not fit (it is dropped at its delimiter).
    excess: usize,
    raw: [u8; CAP],
    stats: FrameStats,
}

impl<const CAP: usize> Default for FrameDecoder<CAP> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const CAP: usize> FrameDecoder<CAP> {
    /// An empty decoder.
    pub const fn new() -> Self {
        Self {
            encoded: [0; CAP],
            len: 0,
            excess: 0,
            raw: [0; CAP],
            stats: FrameStats { frames: 0, corrupt: 0, oversized: 0, unknown_kind: 0 },
        }
    }

    /// Counters since creation.
    pub fn stats(&self) -> FrameStats {
        self.stats
    }

    /// Forgets a partial frame.
    pub fn clear(&mut self) {
        self.len = 0;
        self.excess = 0;
    }

    /// Takes one byte; at a delimiter returns the frame it ends, or why that was no frame. Empty
    /// frames (delimiters in a row, which a sender may use to flush the line) return `None`.
    pub fn push(&mut self, byte: u8) -> Option<Result<Frame<'_>, FrameError>> {
        if byte != 0 {
            if self.len < CAP.min(MAX_ENCODED) {
                self.encoded[self.len] = byte;
                self.len += 1;
            } else {
                self.excess = self.excess.saturating_add(1);
            }
            return None;
        }
        let (len, excess) = (self.len, self.excess);
        self.clear();
        if excess > 0 {
            self.stats.oversized = self.stats.oversized.wrapping_add(1);
            return Some(Err(FrameError::Oversized { len: len.saturating_add(excess) }));
        }
        if len == 0 {
            return None;
        }
        let encoded = self.encoded.get(..len).unwrap_or_default();
        let result = match cobs::decode(encoded, &mut self.raw) {
            Ok(n) => parse_raw(self.raw.get(..n).unwrap_or_default()),
            Err(e) => Err(FrameError::Cobs(e)),
        };
        match &result {
            Ok(_) => self.stats.frames = self.stats.frames.wrapping_add(1),
            Err(FrameError::UnknownKind { .. }) => self.stats.unknown_kind = self.stats.unknown_kind.wrapping_add(1),
            Err(_) => self.stats.corrupt = self.stats.corrupt.wrapping_add(1),
        }
        Some(result)
    }
}
