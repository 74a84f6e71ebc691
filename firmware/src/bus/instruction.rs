//! The contents of an instruction packet, protocol-neutral: what the master asks of a servo.
//!
//! The variable parts of the multi-servo instructions stay raw byte records, exactly as they travel,
//! so that a received packet is parsed without copying; the iterators below walk them and
//! [`RecordWriter`] builds them.

use super::{EncodeError, Id};

/// An instruction and its parameters, borrowed. Addresses and lengths are 16-bit as on Dynamixel;
/// Feetech carries 8-bit ones and refuses larger values when encoding.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Instruction<'a> {
    /// Is a servo there? (The reply carries model and firmware on Dynamixel.)
    Ping,
    /// Read `length` bytes of the control table from `address`.
    Read {
        /// First control-table address.
        address: u16,
        /// Bytes to read.
        length: u16,
    },
    /// Write `data` to the control table from `address`.
    Write {
        /// First control-table address.
        address: u16,
        /// The bytes written.
        data: &'a [u8],
    },
    /// Like [`Instruction::Write`], but held until an [`Instruction::Action`].
    RegWrite {
        /// First control-table address.
        address: u16,
        /// The bytes written.
        data: &'a [u8],
    },
    /// Apply the registered writes.
    Action,
    /// Dynamixel: restore factory settings. `mode`: 0xFF everything, 0x01 all but the id, 0x02 all
    /// but id and baud rate.
    FactoryReset {
        /// What to keep.
        mode: u8,
    },
    /// Dynamixel: restart the servo.
    Reboot,
    /// Dynamixel: clear the multi-turn position (`0x01`) or the errors (`0x02`); the four key bytes
    /// follow the mode on the wire (see the e-manual).
    Clear {
        /// The mode byte followed by the four key bytes.
        params: [u8; 5],
    },
    /// Read the same item of several servos; each answers in turn, in the order of `ids`.
    SyncRead {
        /// First control-table address.
        address: u16,
        /// Bytes per servo.
        length: u16,
        /// The servos asked.
        ids: &'a [u8],
    },
    /// Write the same item of several servos: `data` is records of an id followed by `length` bytes.
    SyncWrite {
        /// First control-table address.
        address: u16,
        /// Bytes per servo.
        length: u16,
        /// Records `id, data[length]`; see [`sync_write_records`].
        data: &'a [u8],
    },
    /// Dynamixel: a sync read answered by one combined status packet.
    FastSyncRead {
        /// First control-table address.
        address: u16,
        /// Bytes per servo.
        length: u16,
        /// The servos asked.
        ids: &'a [u8],
    },
    /// Dynamixel: read different items of several servos: records `id, address (2), length (2)`.
    BulkRead {
        /// Records; see [`bulk_read_records`].
        records: &'a [u8],
    },
    /// Dynamixel: write different items of several servos: records `id, address (2), length (2),
    /// data[length]`.
    BulkWrite {
        /// Records; see [`bulk_write_records`].
        records: &'a [u8],
    },
    /// Feetech RESET (0x0A): resets the servo's running state (e.g. its turn count); it does not
    /// restore factory settings.
    Reset,
}

impl Instruction<'_> {
    /// A short name for messages.
    pub fn name(&self) -> &'static str {
        match self {
            Self::Ping => "ping",
            Self::Read { .. } => "read",
            Self::Write { .. } => "write",
            Self::RegWrite { .. } => "reg write",
            Self::Action => "action",
            Self::FactoryReset { .. } => "factory reset",
            Self::Reboot => "reboot",
            Self::Clear { .. } => "clear",
            Self::SyncRead { .. } => "sync read",
            Self::SyncWrite { .. } => "sync write",
            Self::FastSyncRead { .. } => "fast sync read",
            Self::BulkRead { .. } => "bulk read",
            Self::BulkWrite { .. } => "bulk write",
            Self::Reset => "reset",
        }
    }
}

/// An instruction addressed to a servo (or to [`super::BROADCAST`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct InstructionPacket<'a> {
    /// The addressed servo.
    pub id: Id,
    /// What it is asked to do.
    pub instruction: Instruction<'a>,
}

/// One record of a sync write: a servo and its bytes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SyncWriteRecord<'a> {
    /// The servo.
    pub id: Id,
    /// Its `length` bytes.
    pub data: &'a [u8],
}

/// One record of a bulk read.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BulkReadRecord {
    /// The servo.
    pub id: Id,
    /// First control-table address.
    pub address: u16,
    /// Bytes to read.
    pub length: u16,
}

/// One record of a bulk write.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BulkWriteRecord<'a> {
    /// The servo.
    pub id: Id,
    /// First control-table address.
    pub address: u16,
    /// The bytes written.
    pub data: &'a [u8],
}

/// The records of a sync write's `data`, or `None` when it is not a whole number of records.
pub fn sync_write_records(length: u16, data: &[u8]) -> Option<impl Iterator<Item = SyncWriteRecord<'_>> + '_> {
    let record = usize::from(length) + 1;
    if !data.len().is_multiple_of(record) {
        return None;
    }
    Some(data.chunks_exact(record).map(|r| SyncWriteRecord { id: r[0], data: &r[1..] }))
}

/// The records of a bulk read, or `None` when `records` is not a whole number of 5-byte records.
pub fn bulk_read_records(records: &[u8]) -> Option<impl Iterator<Item = BulkReadRecord> + '_> {
    let (whole, rest) = records.as_chunks::<5>();
    if !rest.is_empty() {
        return None;
    }
    Some(whole.iter().map(|&[id, a0, a1, l0, l1]| BulkReadRecord {
        id,
        address: u16::from_le_bytes([a0, a1]),
        length: u16::from_le_bytes([l0, l1]),
    }))
}

/// Walks bulk-write records; yields `Err(())` once, then stops, when a record is cut short.
#[derive(Clone, Debug)]
pub struct BulkWriteRecords<'a> {
    rest: &'a [u8],
}

impl<'a> Iterator for BulkWriteRecords<'a> {
    type Item = Result<BulkWriteRecord<'a>, ()>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.rest.is_empty() {
            return None;
        }
        let rest = core::mem::take(&mut self.rest);
        let [id, a0, a1, l0, l1, tail @ ..] = rest else { return Some(Err(())) };
        let length = usize::from(u16::from_le_bytes([*l0, *l1]));
        if tail.len() < length {
            return Some(Err(()));
        }
        let (data, rest) = tail.split_at(length);
        self.rest = rest;
        Some(Ok(BulkWriteRecord { id: *id, address: u16::from_le_bytes([*a0, *a1]), data }))
    }
}

/// The records of a bulk write (each `Err(())` marks a record cut short).
pub fn bulk_write_records(records: &[u8]) -> BulkWriteRecords<'_> {
    BulkWriteRecords { rest: records }
}

/// Builds the record bytes of a sync write, bulk read or bulk write in a caller's buffer, with
/// length checks instead of panics.
#[derive(Debug)]
pub struct RecordWriter<'b> {
    out: &'b mut [u8],
    len: usize,
}

impl<'b> RecordWriter<'b> {
    /// An empty record list in `out`.
    pub fn new(out: &'b mut [u8]) -> Self {
        Self { out, len: 0 }
    }

    fn put(&mut self, bytes: &[u8]) -> Result<(), EncodeError> {
        let end = self.len + bytes.len();
        let available = self.out.len();
        let slot = self.out.get_mut(self.len..end).ok_or(EncodeError::BufferTooSmall { required: end, available })?;
        slot.copy_from_slice(bytes);
        self.len = end;
        Ok(())
    }

    /// Appends a sync-write record: `id` then `data` (which must be the sync write's `length`).
    pub fn sync_write(&mut self, id: Id, data: &[u8]) -> Result<(), EncodeError> {
        self.put(&[id])?;
        self.put(data)
    }

    /// Appends a bulk-read record.
    pub fn bulk_read(&mut self, id: Id, address: u16, length: u16) -> Result<(), EncodeError> {
        let [a0, a1] = address.to_le_bytes();
        let [l0, l1] = length.to_le_bytes();
        self.put(&[id, a0, a1, l0, l1])
    }

    /// Appends a bulk-write record.
    pub fn bulk_write(&mut self, id: Id, address: u16, data: &[u8]) -> Result<(), EncodeError> {
        let length = u16::try_from(data.len()).map_err(|_| EncodeError::TooLong { length: data.len() })?;
        let [a0, a1] = address.to_le_bytes();
        let [l0, l1] = length.to_le_bytes();
        self.put(&[id, a0, a1, l0, l1])?;
        self.put(data)
    }

    /// The records written so far.
    pub fn records(&self) -> &[u8] {
        // `len` never passes the buffer's end (`put` checks); `get` says so without a panic path.
        self.out.get(..self.len).unwrap_or_default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn records_round_trip_through_the_writer() {
        let mut buf = [0u8; 32];
        let mut w = RecordWriter::new(&mut buf);
        w.bulk_write(1, 116, &[0, 2, 0, 0]).unwrap();
        w.bulk_write(2, 65, &[1]).unwrap();
        let records: Vec<_> = bulk_write_records(w.records()).collect();
        assert_eq!(
            records,
            [
                Ok(BulkWriteRecord { id: 1, address: 116, data: &[0, 2, 0, 0] }),
                Ok(BulkWriteRecord { id: 2, address: 65, data: &[1] })
            ]
        );
    }

    #[test]
    fn cut_records_are_refused() {
        assert!(sync_write_records(4, &[1, 0, 0, 0]).is_none());
        assert!(bulk_read_records(&[1, 0, 0, 4]).is_none());
        let records: Vec<_> = bulk_write_records(&[1, 116, 0, 4, 0, 9, 9]).collect();
        assert_eq!(records, [Err(())]);
        let mut small = [0u8; 3];
        let mut w = RecordWriter::new(&mut small);
        assert_eq!(w.sync_write(1, &[1, 2, 3]), Err(EncodeError::BufferTooSmall { required: 4, available: 3 }));
    }
}
