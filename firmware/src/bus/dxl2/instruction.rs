//! Instruction packets: encoding every Protocol 2.0 instruction, and parsing them back (for the
//! servo simulator and the fuzzer).
//!
//! Parameter layouts are those of the e-manual, Protocol 2.0, "Instruction Details"; addresses and
//! lengths are 16-bit little-endian.

use super::frame::{self, CRC_LEN, PREFIX};
use super::stuffing::unstuff_in_place;
use super::*;
use crate::bus::instruction::{bulk_read_records, bulk_write_records, sync_write_records};
use crate::bus::{EncodeError, Instruction, InstructionPacket, ParseError};

/// An instruction's wire form: its code, up to five fixed parameter bytes, then a borrowed tail.
struct Params<'a> {
    code: u8,
    head: [u8; 5],
    head_len: usize,
    tail: &'a [u8],
}

impl<'a> Params<'a> {
    fn new(code: u8, head: &[u8], tail: &'a [u8]) -> Self {
        let mut fixed = [0u8; 5];
        for (slot, byte) in fixed.iter_mut().zip(head) {
            *slot = *byte;
        }
        Self { code, head: fixed, head_len: head.len().min(5), tail }
    }

    /// Address then length, both little-endian, as Read, Sync Read and Sync Write start.
    fn address_length(code: u8, address: u16, length: u16, tail: &'a [u8]) -> Self {
        let [a0, a1] = address.to_le_bytes();
        let [l0, l1] = length.to_le_bytes();
        Self::new(code, &[a0, a1, l0, l1], tail)
    }

    fn bytes(&self) -> impl Iterator<Item = u8> + Clone + '_ {
        let head = self.head.get(..self.head_len).unwrap_or(&[]);
        core::iter::once(self.code).chain(head.iter().copied()).chain(self.tail.iter().copied())
    }
}

/// Refuses ids inside records that no servo can have (the broadcast id included: a record names
/// one servo).
fn servo_ids(mut ids: impl Iterator<Item = u8>, reason: &'static str) -> Result<(), EncodeError> {
    if ids.all(|id| id <= MAX_ID) {
        Ok(())
    } else {
        Err(EncodeError::BadParameter { reason })
    }
}

fn params<'a>(instruction: &Instruction<'a>) -> Result<Params<'a>, EncodeError> {
    Ok(match *instruction {
        Instruction::Ping => Params::new(INST_PING, &[], &[]),
        Instruction::Read { address, length } => Params::address_length(INST_READ, address, length, &[]),
        Instruction::Write { address, data } => Params::new(INST_WRITE, &address.to_le_bytes(), data),
        Instruction::RegWrite { address, data } => Params::new(INST_REG_WRITE, &address.to_le_bytes(), data),
        Instruction::Action => Params::new(INST_ACTION, &[], &[]),
        Instruction::FactoryReset { mode } => Params::new(INST_FACTORY_RESET, &[mode], &[]),
        Instruction::Reboot => Params::new(INST_REBOOT, &[], &[]),
        Instruction::Clear { params } => Params::new(INST_CLEAR, &params, &[]),
        Instruction::SyncRead { address, length, ids } => {
            servo_ids(ids.iter().copied(), "sync read ids must be 0..=252")?;
            Params::address_length(INST_SYNC_READ, address, length, ids)
        }
        Instruction::FastSyncRead { address, length, ids } => {
            servo_ids(ids.iter().copied(), "fast sync read ids must be 0..=252")?;
            Params::address_length(INST_FAST_SYNC_READ, address, length, ids)
        }
        Instruction::SyncWrite { address, length, data } => {
            let records = sync_write_records(length, data)
                .ok_or(EncodeError::BadParameter { reason: "sync write data is not a whole number of records" })?;
            servo_ids(records.map(|r| r.id), "sync write ids must be 0..=252")?;
            Params::address_length(INST_SYNC_WRITE, address, length, data)
        }
        Instruction::BulkRead { records } => {
            let parsed = bulk_read_records(records)
                .ok_or(EncodeError::BadParameter { reason: "bulk read records are not whole 5-byte records" })?;
            servo_ids(parsed.map(|r| r.id), "bulk read ids must be 0..=252")?;
            Params::new(INST_BULK_READ, &[], records)
        }
        Instruction::BulkWrite { records } => {
            for record in bulk_write_records(records) {
                match record {
                    Err(()) => return Err(EncodeError::BadParameter { reason: "bulk write record cut short" }),
                    Ok(r) if r.id > MAX_ID => {
                        return Err(EncodeError::BadParameter { reason: "bulk write ids must be 0..=252" })
                    }
                    Ok(_) => {}
                }
            }
            Params::new(INST_BULK_WRITE, &[], records)
        }
        Instruction::Reset => return Err(EncodeError::Unsupported { instruction: instruction.name() }),
    })
}

/// See [`super::encode_instruction`].
pub(super) fn encode(packet: &InstructionPacket<'_>, out: &mut [u8]) -> Result<usize, EncodeError> {
    if !frame::valid_packet_id(packet.id) {
        return Err(EncodeError::BadParameter { reason: "packet id must be 0..=252 or 0xFE (broadcast)" });
    }
    let params = params(&packet.instruction)?;
    frame::write_packet(packet.id, params.bytes(), true, out)
}

/// Decodes an unstuffed instruction code and its parameters.
fn decode(code: u8, p: &[u8]) -> Result<Instruction<'_>, ParseError> {
    let bad = ParseError::BadParameters { code };
    let le = |low: &u8, high: &u8| u16::from_le_bytes([*low, *high]);
    match code {
        INST_PING => p.is_empty().then_some(Instruction::Ping).ok_or(bad),
        INST_READ => match p {
            [a0, a1, l0, l1] => Ok(Instruction::Read { address: le(a0, a1), length: le(l0, l1) }),
            _ => Err(bad),
        },
        INST_WRITE | INST_REG_WRITE => match p {
            [a0, a1, data @ ..] if code == INST_WRITE => Ok(Instruction::Write { address: le(a0, a1), data }),
            [a0, a1, data @ ..] => Ok(Instruction::RegWrite { address: le(a0, a1), data }),
            _ => Err(bad),
        },
        INST_ACTION => p.is_empty().then_some(Instruction::Action).ok_or(bad),
        INST_FACTORY_RESET => match p {
            [mode] => Ok(Instruction::FactoryReset { mode: *mode }),
            _ => Err(bad),
        },
        INST_REBOOT => p.is_empty().then_some(Instruction::Reboot).ok_or(bad),
        INST_CLEAR => match p {
            [a, b, c, d, e] => Ok(Instruction::Clear { params: [*a, *b, *c, *d, *e] }),
            _ => Err(bad),
        },
        INST_SYNC_READ | INST_FAST_SYNC_READ => match p {
            [a0, a1, l0, l1, ids @ ..] if code == INST_SYNC_READ => {
                Ok(Instruction::SyncRead { address: le(a0, a1), length: le(l0, l1), ids })
            }
            [a0, a1, l0, l1, ids @ ..] => {
                Ok(Instruction::FastSyncRead { address: le(a0, a1), length: le(l0, l1), ids })
            }
            _ => Err(bad),
        },
        INST_SYNC_WRITE => match p {
            [a0, a1, l0, l1, data @ ..] if sync_write_records(le(l0, l1), data).is_some() => {
                Ok(Instruction::SyncWrite { address: le(a0, a1), length: le(l0, l1), data })
            }
            _ => Err(bad),
        },
        INST_BULK_READ => bulk_read_records(p).map(|_| Instruction::BulkRead { records: p }).ok_or(bad),
        INST_BULK_WRITE => {
            bulk_write_records(p).all(|r| r.is_ok()).then_some(Instruction::BulkWrite { records: p }).ok_or(bad)
        }
        INST_STATUS => Err(ParseError::WrongKind),
        _ => Err(ParseError::UnknownInstruction { code }),
    }
}

/// See [`super::parse_instruction`].
pub(super) fn parse(frame: &mut [u8]) -> Result<InstructionPacket<'_>, ParseError> {
    let total = frame::verify(frame)?;
    let id = frame.get(4).copied().unwrap_or(0);
    let region = frame.get_mut(PREFIX..total.saturating_sub(CRC_LEN)).unwrap_or(&mut []);
    let unstuffed = unstuff_in_place(region);
    let region: &[u8] = region;
    let Some((&code, params)) = region.get(..unstuffed).and_then(<[u8]>::split_first) else {
        return Err(ParseError::BadLength { length: 0 });
    };
    Ok(InstructionPacket { id, instruction: decode(code, params)? })
}
