//! The combined reply to a Fast Sync Read (e-manual, Protocol 2.0, "Fast Sync Read (0x8A)").
//!
//! The servos answer with one status packet from the broadcast id, each appending its part in the
//! order of the instruction's ids:
//!
//! ```text
//! FF FF FD 00 FE LEN_L LEN_H 55 | ERR ID data[X] CRC_L CRC_H | ERR ID data[X] CRC_L CRC_H | ...
//! ```
//!
//! Each part's CRC is the CRC of the packet from its header up to that point (the e-manual's
//! example checks out that way), so the last part's CRC is the packet's own CRC and the first
//! servo writes a length field that already counts every part. The reply is not byte-stuffed. Parsed
//! as a [`Status`], `error` is the first part's error byte and `params` the rest up to, not
//! including, the packet CRC.

use super::crc::crc16_update;
use super::frame::{self, PREFIX};
use super::{INST_STATUS, MAX_ID};
use crate::bus::{EncodeError, Id, Status, BROADCAST};

/// Bytes each servo adds beyond its data: error, id and CRC.
const OVERHEAD: usize = 4;

/// One servo's part of a fast sync read reply.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FastSyncPart<'a> {
    /// The servo's status error byte (see [`super::StatusError`]).
    pub error: u8,
    /// The servo.
    pub id: Id,
    /// The bytes it read.
    pub data: &'a [u8],
}

/// The parts of a fast sync read reply, in the order of the instruction's ids; see
/// [`fast_sync_read_parts`].
#[derive(Clone, Debug)]
pub struct FastSyncParts<'a> {
    /// The error byte of the next part (`None` when done).
    error: Option<u8>,
    /// From the next part's id on.
    rest: &'a [u8],
    length: usize,
}

impl<'a> Iterator for FastSyncParts<'a> {
    type Item = FastSyncPart<'a>;

    fn next(&mut self) -> Option<FastSyncPart<'a>> {
        let error = self.error.take()?;
        let (&id, after_id) = self.rest.split_first()?;
        let data = after_id.get(..self.length)?;
        // The CRC of this part (2 bytes), then the next part's error byte, if there is a next part.
        let after_data = after_id.get(self.length..).unwrap_or(&[]);
        if let [_, _, next_error, rest @ ..] = after_data {
            self.error = Some(*next_error);
            self.rest = rest;
        } else {
            self.rest = &[];
        }
        Some(FastSyncPart { error, id, data })
    }

    fn size_hint(&self) -> (usize, Option<usize>) {
        let stride = self.length.saturating_add(OVERHEAD);
        let n = if self.error.is_some() { self.rest.len().saturating_add(3) / stride } else { 0 };
        (n, Some(n))
    }
}

impl ExactSizeIterator for FastSyncParts<'_> {}

/// The servos' parts of a fast sync read reply that read `length` bytes from each, or `None` when
/// `status` is not such a reply: not from the broadcast id, or not a whole number of parts.
///
/// The intermediate CRCs are skipped, not checked: the e-manual says they serve the servos
/// ("You can let the main controller check CRC only at the end of Status Packet"), and
/// [`super::verify`] has covered them along with the whole packet.
pub fn fast_sync_read_parts<'a>(status: &Status<'a>, length: usize) -> Option<FastSyncParts<'a>> {
    let stride = length.checked_add(OVERHEAD)?;
    // A reply of n parts carries n * stride bytes after the instruction byte; `params` lacks the
    // first error byte and the packet CRC.
    let carried = status.params.len().checked_add(3)?;
    if status.id != BROADCAST || !carried.is_multiple_of(stride) {
        return None;
    }
    Some(FastSyncParts { error: Some(status.error), rest: status.params, length })
}

/// Encodes the combined reply of a fast sync read, as the chained servos would put it on the wire
/// (for the simulator and tests). `parts` are `(error, id, data)`; every `data` must have the same
/// length, every id be 0..=252, and there must be at least one part.
pub fn encode_fast_sync_read_status(parts: &[(u8, u8, &[u8])], out: &mut [u8]) -> Result<usize, EncodeError> {
    let Some(&(_, _, first)) = parts.first() else {
        return Err(EncodeError::BadParameter { reason: "a fast sync read reply needs at least one part" });
    };
    if parts.iter().any(|&(_, _, data)| data.len() != first.len()) {
        return Err(EncodeError::BadParameter { reason: "fast sync read parts must have the same length" });
    }
    if parts.iter().any(|&(_, id, _)| id > MAX_ID) {
        return Err(EncodeError::BadParameter { reason: "fast sync read ids must be 0..=252" });
    }
    let too_long = EncodeError::TooLong { length: usize::MAX };
    let stride = first.len().checked_add(OVERHEAD).ok_or(too_long)?;
    // The instruction byte, then every part (the last part's CRC being the packet CRC).
    let length = parts.len().checked_mul(stride).and_then(|n| n.checked_add(1)).ok_or(too_long)?;
    let total = length.checked_add(PREFIX).ok_or(too_long)?;
    let length_field = u16::try_from(length).map_err(|_| EncodeError::TooLong { length: total })?;
    let available = out.len();
    let packet = out.get_mut(..total).ok_or(EncodeError::BufferTooSmall { required: total, available })?;

    frame::write_prefix(packet, BROADCAST, length_field);
    let mut cursor = Cursor { packet, at: PREFIX };
    cursor.put(&[INST_STATUS]);
    // The running CRC covers `packet[..crc_end]`.
    let (mut crc, mut crc_end) = (0, 0);
    for &(error, id, data) in parts {
        cursor.put(&[error, id]);
        cursor.put(data);
        crc = crc16_update(crc, cursor.packet.get(crc_end..cursor.at).unwrap_or(&[]));
        crc_end = cursor.at;
        // The next servo continues the CRC over these two bytes too.
        cursor.put(&crc.to_le_bytes());
    }
    Ok(total)
}

/// Writes consecutive bytes into a slice already known to be long enough.
struct Cursor<'b> {
    packet: &'b mut [u8],
    at: usize,
}

impl Cursor<'_> {
    fn put(&mut self, bytes: &[u8]) {
        let end = self.at.saturating_add(bytes.len());
        if let Some(slot) = self.packet.get_mut(self.at..end) {
            slot.copy_from_slice(bytes);
        }
        self.at = end;
    }
}
