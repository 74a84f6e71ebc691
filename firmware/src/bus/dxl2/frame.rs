//! Framing: header, id, length field and CRC, shared by instruction and status packets.
//!
//! e-manual, Protocol 2.0, "Instruction Packet": `FF FF FD 00 | ID | LEN_L LEN_H | INST | params |
//! CRC_L CRC_H`, where LEN counts INST, the (stuffed) parameters and the CRC.

use super::crc::crc16;
use super::stuffing::Stuffer;
use super::{HEADER, MAX_ID};
use crate::bus::{EncodeError, FrameLen, Id, ParseError, BROADCAST};

/// Bytes before the instruction field: header (4), id, length (2).
pub(super) const PREFIX: usize = 7;
/// Bytes of the CRC field.
pub(super) const CRC_LEN: usize = 2;
/// The smallest length field: an instruction and the CRC.
const MIN_LEN_FIELD: usize = 3;

/// Whether `id` may appear in a packet's id field: a servo (0..=252) or the broadcast id. 0xFD and
/// 0xFF are never used, "to avoid duplicate use with Header" (e-manual, "Packet ID").
pub(super) fn valid_packet_id(id: Id) -> bool {
    id <= MAX_ID || id == BROADCAST
}

/// See [`super::frame_len`].
pub(super) fn frame_len(buf: &[u8]) -> FrameLen {
    // Compare only the bytes present; a short prefix that matches may still become a frame.
    if buf.iter().zip(HEADER.iter()).any(|(got, want)| got != want) {
        return FrameLen::NotAFrame;
    }
    if buf.get(4).is_some_and(|&id| !valid_packet_id(id)) {
        return FrameLen::NotAFrame;
    }
    let (Some(&low), Some(&high)) = (buf.get(5), buf.get(6)) else { return FrameLen::NeedMore(PREFIX) };
    let length = usize::from(u16::from_le_bytes([low, high]));
    if length < MIN_LEN_FIELD {
        return FrameLen::NotAFrame;
    }
    // At most 7 + 65535: no overflow.
    let total = PREFIX + length;
    if buf.len() >= total {
        FrameLen::Complete(total)
    } else {
        FrameLen::NeedMore(total)
    }
}

/// The frame's total length, or why it is not a complete frame. Bytes after the frame are ignored.
pub(super) fn check(frame: &[u8]) -> Result<usize, ParseError> {
    match frame_len(frame) {
        FrameLen::Complete(total) => Ok(total),
        FrameLen::NeedMore(required) => Err(ParseError::Truncated { required, available: frame.len() }),
        // With a valid header and id, the only other reason is a length field below the minimum.
        FrameLen::NotAFrame if frame.get(..5).is_some_and(|head| frame_len(head) == FrameLen::NeedMore(PREFIX)) => {
            Err(ParseError::BadLength { length: length_field(frame) })
        }
        FrameLen::NotAFrame => Err(ParseError::BadHeader),
    }
}

/// The length field of a checked frame.
pub(super) fn length_field(frame: &[u8]) -> usize {
    match (frame.get(5), frame.get(6)) {
        (Some(&low), Some(&high)) => usize::from(u16::from_le_bytes([low, high])),
        _ => 0,
    }
}

/// The received and computed CRC of the first `total` bytes of `frame` (`total` from [`check`]).
pub(super) fn crcs(frame: &[u8], total: usize) -> (u16, u16) {
    let body_end = total.saturating_sub(CRC_LEN);
    let computed = crc16(frame.get(..body_end).unwrap_or(&[]));
    let received = match (frame.get(body_end), frame.get(body_end + 1)) {
        (Some(&low), Some(&high)) => u16::from_le_bytes([low, high]),
        _ => !computed,
    };
    (received, computed)
}

/// Whether the CRC matches. Under `cfg(fuzzing)` (cargo-fuzz) it always does, so that random
/// inputs reach the parsers instead of stopping here, as smoltcp's fuzz targets do.
#[cfg(not(fuzzing))]
pub(super) fn crc_matches(received: u16, computed: u16) -> bool {
    received == computed
}

/// Whether the CRC matches: always, because this build is for the fuzzer.
#[cfg(fuzzing)]
pub(super) fn crc_matches(_received: u16, _computed: u16) -> bool {
    true
}

/// See [`super::verify`]. Returns the frame's total length.
pub(super) fn verify(frame: &[u8]) -> Result<usize, ParseError> {
    let total = check(frame)?;
    let (received, computed) = crcs(frame, total);
    if crc_matches(received, computed) {
        Ok(total)
    } else {
        Err(ParseError::Checksum { received, computed })
    }
}

/// Writes header, id and length field into the first [`PREFIX`] bytes of `packet`.
pub(super) fn write_prefix(packet: &mut [u8], id: Id, length_field: u16) {
    let [h0, h1, h2, h3] = HEADER;
    let [len_low, len_high] = length_field.to_le_bytes();
    for (slot, byte) in packet.iter_mut().zip([h0, h1, h2, h3, id, len_low, len_high]) {
        *slot = byte;
    }
}

/// Writes a whole packet: prefix, `body` (instruction field onwards, stuffed when `stuff`), CRC.
///
/// The stuffed length is counted before anything is written, so a short `out` is reported with
/// the exact size it needs and left untouched.
pub(super) fn write_packet<I>(id: Id, body: I, stuff: bool, out: &mut [u8]) -> Result<usize, EncodeError>
where
    I: Iterator<Item = u8> + Clone,
{
    let body_len = Stuffer::new(body.clone(), stuff).count();
    let length = body_len.checked_add(CRC_LEN).ok_or(EncodeError::TooLong { length: usize::MAX })?;
    let total = length.checked_add(PREFIX).ok_or(EncodeError::TooLong { length: usize::MAX })?;
    let length_field = u16::try_from(length).map_err(|_| EncodeError::TooLong { length: total })?;
    let available = out.len();
    let packet = out.get_mut(..total).ok_or(EncodeError::BufferTooSmall { required: total, available })?;
    write_prefix(packet, id, length_field);
    for (slot, byte) in packet.iter_mut().skip(PREFIX).zip(Stuffer::new(body, stuff)) {
        *slot = byte;
    }
    let body_end = PREFIX + body_len;
    let [crc_low, crc_high] = crc16(packet.get(..body_end).unwrap_or(&[])).to_le_bytes();
    if let Some(crc) = packet.get_mut(body_end..) {
        for (slot, byte) in crc.iter_mut().zip([crc_low, crc_high]) {
            *slot = byte;
        }
    }
    Ok(total)
}
