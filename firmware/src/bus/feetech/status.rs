//! Status packets (a servo's reply): `FF FF ID LEN ERR data CHK`, LEN = data + 2 (Feetech SCS
//! communication protocol manual, section 3). Unlike Dynamixel there is no marker byte: the error
//! byte sits where an instruction packet has its instruction.

use super::frame::{self, Frame};
use super::instruction::MAX_ID;
use crate::bus::{EncodeError, ParseError, Status};

/// Encodes a status packet into `out`; returns the bytes written.
///
/// The id must be a servo's (0..=253): a servo never answers as broadcast. Any error byte is
/// carried as is. At most 253 data bytes fit LEN.
pub fn encode_status(status: &Status<'_>, out: &mut [u8]) -> Result<usize, EncodeError> {
    if status.id > MAX_ID {
        return Err(EncodeError::BadParameter { reason: "a feetech status comes from a servo id (0..=253)" });
    }
    frame::emit(status.id, status.error, &[status.params], out)
}

/// Bytes of a status packet carrying `data` bytes.
pub fn status_len(data: usize) -> usize {
    data.saturating_add(frame::MIN_FRAME)
}

/// Parses a complete frame (as delimited by [`super::frame_len`]) as a status packet.
///
/// Header, length and checksum are checked ([`super::verify`]); the contents cannot be: any error
/// byte and any data are a valid status, and an instruction packet parses as a status too (its
/// instruction read as the error byte). The caller matches the reply to its request by id and
/// length. The id is not checked against 0..=253, so a broadcast instruction echoed on a
/// half-duplex line parses with id 0xFE, which the caller can recognise.
pub fn parse_status(frame: &mut [u8]) -> Result<Status<'_>, ParseError> {
    let Frame { id, kind: error, params } = frame::split(frame)?;
    Ok(Status { id, error, params })
}
