//! Dynamixel Protocol 2.0 (ROBOTIS e-manual, "DYNAMIXEL Protocol 2.0"): encoding of instruction
//! and status packets, frame boundaries in received bytes, CRC check and in-place parsing.
//!
//! ```text
//! FF FF FD 00 | ID | LEN_L LEN_H | INST | params...        | CRC_L CRC_H   instruction
//! FF FF FD 00 | ID | LEN_L LEN_H | 55   | ERR | params...  | CRC_L CRC_H   status
//! ```
//!
//! LEN counts the instruction byte, the parameters after byte stuffing and the CRC. The CRC is
//! CRC-16/BUYPASS over everything before it, as sent ([`crc16`]).
//!
//! Parsing checks, in order: header and id ([`ParseError::BadHeader`]), the length field
//! ([`ParseError::BadLength`], [`ParseError::Truncated`]), the CRC over the stuffed bytes
//! ([`ParseError::Checksum`]); then it removes the stuffing in place and decodes the parameters.
//! Bytes after the frame's end are ignored, like smoltcp's `new_checked`.
//!
//! # Panics
//! Nothing here panics, on any bytes or arguments: every access is a checked `get`, every sum that
//! could grow is a checked one, and buffers that are too small are errors.

mod crc;
mod error;
mod fast_sync;
mod frame;
mod instruction;
mod status;
mod stuffing;

pub use crc::{crc16, crc16_update};
pub use error::StatusError;
pub use fast_sync::{encode_fast_sync_read_status, fast_sync_read_parts, FastSyncPart, FastSyncParts};

use super::{EncodeError, FrameLen, InstructionPacket, ParseError, Status};

/// The packet header: `FF FF FD` and the reserved `00` (which is never `FD`, so a stuffed
/// `FF FF FD FD` is not a header).
pub const HEADER: [u8; 4] = [0xFF, 0xFF, 0xFD, 0x00];
/// The highest id a servo can have; 253 (0xFD) and 255 (0xFF) are never ids, 254 is broadcast.
pub const MAX_ID: u8 = 252;

/// Ping: is a servo there? Its status carries model number (2 bytes) and firmware version.
pub const INST_PING: u8 = 0x01;
/// Read: address (2), length (2).
pub const INST_READ: u8 = 0x02;
/// Write: address (2), data.
pub const INST_WRITE: u8 = 0x03;
/// Reg Write: like Write, executed on Action.
pub const INST_REG_WRITE: u8 = 0x04;
/// Action: execute the registered writes.
pub const INST_ACTION: u8 = 0x05;
/// Factory Reset: one option byte (0xFF all, 0x01 all but id, 0x02 all but id and baud rate).
pub const INST_FACTORY_RESET: u8 = 0x06;
/// Reboot.
pub const INST_REBOOT: u8 = 0x08;
/// Clear: a mode byte and four key bytes (0x01 `44 58 4C 22` clears the multi-turn position).
pub const INST_CLEAR: u8 = 0x10;
/// Control Table Backup (not supported by this codec: parsed as an unknown instruction).
pub const INST_CONTROL_TABLE_BACKUP: u8 = 0x20;
/// The instruction byte of every status packet.
pub const INST_STATUS: u8 = 0x55;
/// Sync Read: address (2), length (2), ids; one status per servo.
pub const INST_SYNC_READ: u8 = 0x82;
/// Sync Write: address (2), length (2), records of an id and `length` bytes.
pub const INST_SYNC_WRITE: u8 = 0x83;
/// Fast Sync Read: as Sync Read, answered by one combined status (see [`fast_sync_read_parts`]).
pub const INST_FAST_SYNC_READ: u8 = 0x8A;
/// Bulk Read: records of id, address (2), length (2).
pub const INST_BULK_READ: u8 = 0x92;
/// Bulk Write: records of id, address (2), length (2), data.
pub const INST_BULK_WRITE: u8 = 0x93;
/// Fast Bulk Read (not supported by this codec: parsed as an unknown instruction).
pub const INST_FAST_BULK_READ: u8 = 0x9A;

/// Bytes of an instruction packet with `params` parameter bytes before stuffing: header (4), id,
/// length (2), instruction, parameters, CRC (2). Saturates instead of overflowing.
pub fn instruction_len(params: usize) -> usize {
    params.saturating_add(10)
}

/// Bytes of a status packet carrying `data` bytes before stuffing (one more than an instruction
/// packet: the error byte). Saturates instead of overflowing.
pub fn status_len(data: usize) -> usize {
    data.saturating_add(11)
}

/// Encodes an instruction packet into `out`, stuffed and with its CRC; returns the bytes written.
///
/// Refused: ids other than 0..=252 and 0xFE, record ids other than 0..=252, sync-write data or
/// bulk records that are not whole records ([`EncodeError::BadParameter`]), packets too long for
/// the 16-bit length field ([`EncodeError::TooLong`]), the Feetech-only
/// [`crate::bus::Instruction::Reset`] ([`EncodeError::Unsupported`]). The e-manual wants sync and
/// bulk instructions sent to the broadcast id; that is left to the caller. Nothing is written
/// when `out` is too small ([`EncodeError::BufferTooSmall`] gives the exact size).
pub fn encode_instruction(packet: &InstructionPacket<'_>, out: &mut [u8]) -> Result<usize, EncodeError> {
    instruction::encode(packet, out)
}

/// Encodes a status packet into `out`; returns the bytes written. A status from the broadcast id
/// is a fast sync read reply and is not stuffed (see [`encode_fast_sync_read_status`] to build
/// one from its parts).
pub fn encode_status(status: &Status<'_>, out: &mut [u8]) -> Result<usize, EncodeError> {
    status::encode(status, out)
}

/// Where the frame starting at `buf[0]` ends, from header, id and length field.
///
/// [`FrameLen::NeedMore`] carries the total needed: 7 while the length field is missing, the
/// frame's length once it is known. [`FrameLen::NotAFrame`] when the bytes present cannot start a
/// frame: not `FF FF FD 00`, an id of 0xFD or 0xFF (or 253), a length field below 3.
pub fn frame_len(buf: &[u8]) -> FrameLen {
    frame::frame_len(buf)
}

/// Checks the CRC of a complete frame (the stuffed bytes as received). Under `cfg(fuzzing)` any
/// CRC is accepted, so that a fuzzer reaches the parsers.
pub fn verify(frame: &[u8]) -> Result<(), ParseError> {
    frame::verify(frame).map(|_| ())
}

/// Parses a complete frame as an instruction packet: checks framing and CRC, unstuffs in place
/// (the frame's bytes change), then decodes the parameters.
///
/// [`ParseError::WrongKind`] for a status packet, [`ParseError::UnknownInstruction`] for an
/// instruction this codec does not know (Control Table Backup, Fast Bulk Read included),
/// [`ParseError::BadParameters`] when the parameters do not fit the instruction.
pub fn parse_instruction(frame: &mut [u8]) -> Result<InstructionPacket<'_>, ParseError> {
    instruction::parse(frame)
}

/// Parses a complete frame as a status packet: checks framing and CRC, unstuffs in place (except a
/// fast sync read reply, from the broadcast id, which is never stuffed), then splits the error
/// byte from the parameters. [`ParseError::WrongKind`] when the instruction byte is not 0x55.
pub fn parse_status(frame: &mut [u8]) -> Result<Status<'_>, ParseError> {
    status::parse(frame)
}
