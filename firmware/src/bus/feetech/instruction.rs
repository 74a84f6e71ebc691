//! Instruction packets: encoding and parsing, with the parameter checks of each instruction.
//!
//! Codes and parameter layouts: Feetech SCS communication protocol manual, section 4 ("Instruction
//! Types"), and the SCServo SDK (`INST_*` in `scservo_def.py`, `syncReadTx`/`syncWriteTxOnly` in
//! `protocol_packet_handler.py`).
//!
//! What is refused, and why:
//! - Addresses and lengths are one byte on the wire; values above 255 are refused.
//! - A read or sync-read length above 253 is refused: the reply's LEN (`length + 2`) would not fit
//!   its byte. A length of 0 is refused too (a read of nothing, a sync write of bare ids).
//! - A write or reg write needs at least one data byte.
//! - The packet id is a servo (0..=253) or broadcast (0xFE); ids inside a sync read or sync write
//!   must be servos, since broadcast or 0xFF name no single servo that could answer or be written.
//! - Sync write data must be whole records of `id, data[length]`.
//!
//! The parser applies the same rules to received packets, so that every packet it accepts encodes
//! back to the same bytes. Sync instructions are not forced to the broadcast id, although the
//! manual only shows them broadcast: a servo ignores what is not addressed to it.

use super::frame::{self, Frame};
use crate::bus::{EncodeError, Id, Instruction, InstructionPacket, ParseError, BROADCAST};

/// PING: is the servo there? Answered even when broadcast (manual 4.1).
pub const PING: u8 = 0x01;
/// READ: `address, length` (manual 4.2).
pub const READ: u8 = 0x02;
/// WRITE: `address, data...` (manual 4.3).
pub const WRITE: u8 = 0x03;
/// REG WRITE: like WRITE, held until ACTION (manual 4.4).
pub const REG_WRITE: u8 = 0x04;
/// ACTION: apply the registered writes, usually broadcast (manual 4.5).
pub const ACTION: u8 = 0x05;
/// RESET: reset the servo's state, i.e. its rotation count (manual 4.8). Not a factory reset: that
/// is "parameter restoration", 0x06, which this codec does not send.
pub const RESET: u8 = 0x0A;
/// SYNC READ: `address, length, ids...`; each servo answers in the order of the ids (manual 4.7).
pub const SYNC_READ: u8 = 0x82;
/// SYNC WRITE: `address, length, (id, data[length])...` (manual 4.6).
pub const SYNC_WRITE: u8 = 0x83;

/// The largest servo id; 0xFE is [`BROADCAST`] (manual section 2).
pub const MAX_ID: Id = 253;

/// The largest read length: the reply's LEN is `length + 2` and is one byte.
pub const MAX_READ_LENGTH: u8 = 253;

/// Encodes an instruction packet into `out`; returns the bytes written.
///
/// The Dynamixel-only instructions (factory reset with a mode, reboot, clear, fast sync read, bulk
/// read and write) are [`EncodeError::Unsupported`]. Feetech's own 0x06 (parameter restoration),
/// 0x08 (reboot), 0x09 (parameter backup) and 0x0B (position calibration) have no
/// [`Instruction`] variant and cannot be sent. See the module doc for the parameter checks.
pub fn encode_instruction(packet: &InstructionPacket<'_>, out: &mut [u8]) -> Result<usize, EncodeError> {
    let id = packet.id;
    if id > MAX_ID && id != BROADCAST {
        return Err(EncodeError::BadParameter { reason: "feetech ids are 0..=253 or broadcast 0xFE" });
    }
    match packet.instruction {
        Instruction::Ping => frame::emit(id, PING, &[], out),
        Instruction::Action => frame::emit(id, ACTION, &[], out),
        Instruction::Reset => frame::emit(id, RESET, &[], out),
        Instruction::Read { address, length } => {
            let head = [byte(address)?, read_length(length)?];
            frame::emit(id, READ, &[&head], out)
        }
        Instruction::Write { address, data } => frame::emit(id, WRITE, &[&[byte(address)?], write_data(data)?], out),
        Instruction::RegWrite { address, data } => {
            frame::emit(id, REG_WRITE, &[&[byte(address)?], write_data(data)?], out)
        }
        Instruction::SyncRead { address, length, ids } => {
            let head = [byte(address)?, read_length(length)?];
            if !ids.iter().all(|id| *id <= MAX_ID) {
                return Err(EncodeError::BadParameter { reason: "sync read ids must be servos (0..=253)" });
            }
            frame::emit(id, SYNC_READ, &[&head, ids], out)
        }
        Instruction::SyncWrite { address, length, data } => {
            let head = [byte(address)?, byte(length)?];
            match sync_write_data(head[1], data) {
                Ok(()) => frame::emit(id, SYNC_WRITE, &[&head, data], out),
                Err(reason) => Err(EncodeError::BadParameter { reason }),
            }
        }
        Instruction::FactoryReset { .. }
        | Instruction::Reboot
        | Instruction::Clear { .. }
        | Instruction::FastSyncRead { .. }
        | Instruction::BulkRead { .. }
        | Instruction::BulkWrite { .. } => Err(EncodeError::Unsupported { instruction: packet.instruction.name() }),
    }
}

/// Bytes of an instruction packet with `params` parameter bytes: header, id, LEN, instruction,
/// parameters and checksum.
pub fn instruction_len(params: usize) -> usize {
    params.saturating_add(frame::MIN_FRAME)
}

/// Parses a complete frame (as delimited by [`super::frame_len`]) as an instruction packet.
///
/// Header, length and checksum first ([`super::verify`]), then the instruction and its parameters
/// by the rules of the module doc: an unknown code is [`ParseError::UnknownInstruction`], wrong
/// parameters [`ParseError::BadParameters`]. A status packet looks like an instruction on Feetech
/// (there is no marker byte), so a status arriving here is reported by its error byte: usually
/// `UnknownInstruction` (error 0x00, 0x20...), or a misread instruction when the error byte
/// happens to be a valid code. The `&mut` mirrors the Dynamixel codec; nothing is changed.
pub fn parse_instruction(frame: &mut [u8]) -> Result<InstructionPacket<'_>, ParseError> {
    let Frame { id, kind: code, params } = frame::split(frame)?;
    let bad = ParseError::BadParameters { code };
    let instruction = match (code, params) {
        (PING, []) => Instruction::Ping,
        (ACTION, []) => Instruction::Action,
        (RESET, []) => Instruction::Reset,
        (PING | ACTION | RESET, _) => return Err(bad),
        (READ, &[address, length]) if (1..=MAX_READ_LENGTH).contains(&length) => {
            Instruction::Read { address: address.into(), length: length.into() }
        }
        (WRITE, [address, data @ ..]) if !data.is_empty() => Instruction::Write { address: (*address).into(), data },
        (REG_WRITE, [address, data @ ..]) if !data.is_empty() => {
            Instruction::RegWrite { address: (*address).into(), data }
        }
        (SYNC_READ, [address, length, ids @ ..])
            if (1..=MAX_READ_LENGTH).contains(length) && ids.iter().all(|id| *id <= MAX_ID) =>
        {
            Instruction::SyncRead { address: (*address).into(), length: (*length).into(), ids }
        }
        (SYNC_WRITE, [address, length, data @ ..]) if sync_write_data(*length, data).is_ok() => {
            Instruction::SyncWrite { address: (*address).into(), length: (*length).into(), data }
        }
        (READ | WRITE | REG_WRITE | SYNC_READ | SYNC_WRITE, _) => return Err(bad),
        _ => return Err(ParseError::UnknownInstruction { code }),
    };
    Ok(InstructionPacket { id, instruction })
}

/// An address or length as its one wire byte.
fn byte(value: u16) -> Result<u8, EncodeError> {
    u8::try_from(value).map_err(|_| EncodeError::BadParameter { reason: "feetech addresses and lengths are 0..=255" })
}

/// A read length: 1..=253, so that the reply's LEN fits its byte.
fn read_length(length: u16) -> Result<u8, EncodeError> {
    match byte(length)? {
        0 => Err(EncodeError::BadParameter { reason: "read length must be at least 1" }),
        n if n > MAX_READ_LENGTH => Err(EncodeError::BadParameter { reason: "read length above 253: reply too long" }),
        n => Ok(n),
    }
}

/// The data of a write: at least one byte.
fn write_data(data: &[u8]) -> Result<&[u8], EncodeError> {
    if data.is_empty() {
        return Err(EncodeError::BadParameter { reason: "write without data" });
    }
    Ok(data)
}

/// Checks sync-write records: `length` at least 1, whole records, servo ids.
fn sync_write_data(length: u8, data: &[u8]) -> Result<(), &'static str> {
    if length == 0 {
        return Err("sync write length must be at least 1");
    }
    let record = usize::from(length) + 1;
    let records = data.chunks_exact(record);
    if !records.remainder().is_empty() {
        return Err("sync write data is not whole records of id and length bytes");
    }
    if records.filter_map(|r| r.first()).any(|id| *id > MAX_ID) {
        return Err("sync write ids must be servos (0..=253)");
    }
    Ok(())
}
