//! Status packets: a servo's reply, `FF FF FD 00 | ID | LEN | 55 | ERR | params | CRC`
//! (e-manual, Protocol 2.0, "Status Packet").

use super::frame::{self, CRC_LEN, PREFIX};
use super::stuffing::unstuff_in_place;
use super::INST_STATUS;
use crate::bus::{EncodeError, ParseError, Status, BROADCAST};

/// Whether a status from `id` is stuffed. Only a fast sync read reply comes from the broadcast id,
/// and the e-manual (Protocol 2.0, "Fast Sync Read") says it "does not perform Byte Stuffing",
/// since each servo appends its part (with a running CRC) to a packet already on the wire.
pub(super) fn stuffed(id: u8) -> bool {
    id != BROADCAST
}

/// See [`super::encode_status`].
pub(super) fn encode(status: &Status<'_>, out: &mut [u8]) -> Result<usize, EncodeError> {
    if !frame::valid_packet_id(status.id) {
        return Err(EncodeError::BadParameter { reason: "status id must be 0..=252 or 0xFE (fast sync read)" });
    }
    let body = [INST_STATUS, status.error].into_iter().chain(status.params.iter().copied());
    frame::write_packet(status.id, body, stuffed(status.id), out)
}

/// See [`super::parse_status`].
pub(super) fn parse(frame: &mut [u8]) -> Result<Status<'_>, ParseError> {
    let total = frame::verify(frame)?;
    let length = frame::length_field(frame);
    let id = frame.get(4).copied().unwrap_or(0);
    let region = frame.get_mut(PREFIX..total.saturating_sub(CRC_LEN)).unwrap_or(&mut []);
    if region.first() != Some(&INST_STATUS) {
        return Err(ParseError::WrongKind);
    }
    let unstuffed = if stuffed(id) { unstuff_in_place(region) } else { region.len() };
    let region: &[u8] = region;
    match region.get(..unstuffed) {
        // Unstuffing never removes one of the first three bytes, so the error byte survives it.
        Some([_, error, params @ ..]) => Ok(Status { id, error: *error, params }),
        _ => Err(ParseError::BadLength { length }),
    }
}
