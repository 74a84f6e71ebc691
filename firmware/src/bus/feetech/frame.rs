//! Frame boundaries and the checks every frame passes before its contents are looked at.
//!
//! A Feetech frame is `FF FF ID LEN X params CHK` where `X` is the instruction (master to servo) or
//! the error byte (servo to master) and `LEN = params + 2` counts `X`, the parameters and `CHK`
//! (Feetech SCS communication protocol manual, sections 2 and 3). There is no byte stuffing, so a
//! frame is exactly `4 + LEN` bytes.

use super::checksum;
use crate::bus::{EncodeError, FrameLen, Id, ParseError};

/// The two header bytes that start every frame.
pub const HEADER: [u8; 2] = [0xFF, 0xFF];

/// Bytes before the first byte counted by LEN: the header, the id and LEN itself.
pub(super) const PREFIX: usize = 4;

/// The smallest frame: no parameters (`FF FF ID 02 X CHK`).
pub const MIN_FRAME: usize = 6;

/// The smallest valid LEN: the instruction or error byte plus the checksum.
pub(super) const MIN_LEN_FIELD: u8 = 2;

/// The id byte that can never start a frame: `FF FF FF` is the header one byte later.
const NOT_AN_ID: u8 = 0xFF;

/// The fields of a frame that passed the header, length and checksum checks.
#[derive(Debug)]
pub(super) struct Frame<'a> {
    /// The id byte.
    pub id: Id,
    /// The instruction (instruction packet) or error byte (status packet).
    pub kind: u8,
    /// The parameters (instruction) or data (status).
    pub params: &'a [u8],
}

/// Where the frame starting at `buf[0]` ends; see [`crate::bus::Protocol::frame_len`].
///
/// Judged by the header (`FF FF`), the id (anything but `0xFF`, which would make `FF FF FF` a
/// header one byte later) and LEN (at least 2). Never panics, whatever the slice.
pub fn frame_len(buf: &[u8]) -> FrameLen {
    for (position, byte) in buf.iter().take(PREFIX).enumerate() {
        let plausible = match position {
            0 | 1 => *byte == 0xFF,
            2 => *byte != NOT_AN_ID,
            _ => *byte >= MIN_LEN_FIELD,
        };
        if !plausible {
            return FrameLen::NotAFrame;
        }
    }
    let Some(&len_field) = buf.get(PREFIX - 1) else { return FrameLen::NeedMore(PREFIX) };
    let total = PREFIX + usize::from(len_field);
    if buf.len() >= total {
        FrameLen::Complete(total)
    } else {
        FrameLen::NeedMore(total)
    }
}

/// Checks header, length and checksum of a complete frame (as delimited by [`frame_len`]).
///
/// The frame must be exactly `4 + LEN` bytes: a longer slice is refused with
/// [`ParseError::BadLength`] rather than its tail ignored, so that a corrupted LEN can never make a
/// shorter frame out of a longer one and move the checksum onto a parameter byte.
pub fn verify(frame: &[u8]) -> Result<(), ParseError> {
    split(frame).map(|_| ())
}

/// [`verify`], returning the fields.
pub(super) fn split(frame: &[u8]) -> Result<Frame<'_>, ParseError> {
    let available = frame.len();
    let [h0, h1, id, len_field, body @ ..] = frame else {
        if frame.iter().zip(HEADER).any(|(byte, expected)| *byte != expected) {
            return Err(ParseError::BadHeader);
        }
        return Err(ParseError::Truncated { required: MIN_FRAME, available });
    };
    if [*h0, *h1] != HEADER || *id == NOT_AN_ID {
        return Err(ParseError::BadHeader);
    }
    let length = usize::from(*len_field);
    if *len_field < MIN_LEN_FIELD {
        return Err(ParseError::BadLength { length });
    }
    let required = PREFIX + length;
    if available < required {
        return Err(ParseError::Truncated { required, available });
    }
    if available > required {
        return Err(ParseError::BadLength { length });
    }
    // LEN >= 2 and the body is exactly LEN bytes, so both splits succeed.
    let Some((&received, covered)) = body.split_last() else { return Err(ParseError::BadLength { length }) };
    let Some((&kind, params)) = covered.split_first() else { return Err(ParseError::BadLength { length }) };
    let computed = !checksum::sum(&[*id, *len_field, checksum::sum(covered)]);
    if !checksum::matches(received, computed) {
        return Err(ParseError::Checksum { received: received.into(), computed: computed.into() });
    }
    Ok(Frame { id: *id, kind, params })
}

/// Writes the frame `FF FF id LEN kind parts... CHK` into `out`; returns its length.
///
/// `parts` are the parameters in pieces (e.g. address and length, then the ids of a sync read), so
/// callers need no buffer of their own. Writes nothing unless the whole frame fits.
pub(super) fn emit(id: Id, kind: u8, parts: &[&[u8]], out: &mut [u8]) -> Result<usize, EncodeError> {
    let params = parts.iter().fold(0usize, |n, part| n.saturating_add(part.len()));
    let total = params.saturating_add(MIN_FRAME);
    // LEN counts kind, params and CHK and is one byte.
    let len_field = u8::try_from(params.saturating_add(usize::from(MIN_LEN_FIELD)))
        .map_err(|_| EncodeError::TooLong { length: total })?;
    let available = out.len();
    let Some(frame) = out.get_mut(..total) else {
        return Err(EncodeError::BufferTooSmall { required: total, available });
    };
    let mut sum = checksum::sum(&[id, len_field, kind]);
    let mut cursor = frame.iter_mut();
    for byte in HEADER.iter().chain(&[id, len_field, kind]) {
        if let Some(slot) = cursor.next() {
            *slot = *byte;
        }
    }
    for part in parts {
        sum = sum.wrapping_add(checksum::sum(part));
        // The part first: `zip` stops on it without taking a slot from the cursor.
        for (byte, slot) in part.iter().zip(cursor.by_ref()) {
            *slot = *byte;
        }
    }
    if let Some(slot) = cursor.next() {
        *slot = !sum;
    }
    Ok(total)
}
