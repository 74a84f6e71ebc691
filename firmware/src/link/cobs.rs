//! Consistent Overhead Byte Stuffing (Cheshire and Baker, "Consistent Overhead Byte Stuffing",
//! IEEE/ACM Transactions on Networking, 1999): the link's framing. Encoded data holds no 0x00, so
//! 0x00 delimits frames and a receiver resynchronises at the next one after any loss.
//!
//! The encoding is the one tabulated on Wikipedia ("Consistent Overhead Byte Stuffing", encoding
//! examples): a block of 254 non-zero bytes that ends the input is not followed by an empty block.
//! Overhead: one byte, plus one per 254 bytes. Neither function writes the 0x00 delimiter.
//!
//! # Panics
//! Never: every index into the caller's buffers is checked; a buffer too small or bad input is an
//! error value.

/// Why bytes could not be encoded or decoded.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CobsError {
    /// The output buffer is too small.
    BufferTooSmall {
        /// Bytes needed (for decoding: at least this many).
        required: usize,
        /// Bytes the buffer has.
        available: usize,
    },
    /// A 0x00 inside encoded data (where the delimiter was lost or a bit flipped).
    ZeroByte {
        /// Its index in the encoded bytes.
        index: usize,
    },
    /// A code byte announces more bytes than follow.
    Truncated {
        /// Bytes the last block needs.
        required: usize,
        /// Bytes there are.
        available: usize,
    },
}

impl core::fmt::Display for CobsError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::BufferTooSmall { required, available } => {
                write!(f, "COBS output needs {required} bytes, buffer has {available}")
            }
            Self::ZeroByte { index } => write!(f, "0x00 inside COBS data at byte {index}"),
            Self::Truncated { required, available } => {
                write!(f, "COBS block truncated: {available} of {required} bytes")
            }
        }
    }
}

/// The largest encoded length of `len` input bytes (without the delimiter).
pub const fn max_encoded_len(len: usize) -> usize {
    len + len / 254 + 1
}

fn put(dst: &mut [u8], index: usize, byte: u8, required: usize) -> Result<(), CobsError> {
    let available = dst.len();
    match dst.get_mut(index) {
        Some(slot) => {
            *slot = byte;
            Ok(())
        }
        None => Err(CobsError::BufferTooSmall { required: required.max(index + 1), available }),
    }
}

/// Encodes `src` into `dst`; returns the encoded length (no delimiter written).
pub fn encode(src: &[u8], dst: &mut [u8]) -> Result<usize, CobsError> {
    let required = max_encoded_len(src.len());
    let mut code_at = 0;
    let mut out = 1;
    let mut code: u8 = 1;
    for (i, &byte) in src.iter().enumerate() {
        if byte == 0 {
            put(dst, code_at, code, required)?;
            code_at = out;
            out += 1;
            code = 1;
        } else {
            put(dst, out, byte, required)?;
            out += 1;
            code += 1;
            if code == 0xFF {
                put(dst, code_at, code, required)?;
                if i + 1 == src.len() {
                    // A full block that ends the input needs no empty block after it.
                    return Ok(out);
                }
                code_at = out;
                out += 1;
                code = 1;
            }
        }
    }
    put(dst, code_at, code, required)?;
    Ok(out)
}

/// Decodes `src` (without its delimiter) into `dst`; returns the decoded length.
pub fn decode(src: &[u8], dst: &mut [u8]) -> Result<usize, CobsError> {
    let mut i = 0;
    let mut out = 0;
    while let Some(&code) = src.get(i) {
        if code == 0 {
            return Err(CobsError::ZeroByte { index: i });
        }
        let end = i + usize::from(code);
        let Some(block) = src.get(i + 1..end) else {
            return Err(CobsError::Truncated { required: end, available: src.len() });
        };
        for (k, &byte) in block.iter().enumerate() {
            if byte == 0 {
                return Err(CobsError::ZeroByte { index: i + 1 + k });
            }
            put(dst, out, byte, out + 1)?;
            out += 1;
        }
        i = end;
        // A block shorter than 254 bytes stands for its bytes and a zero, except the last one.
        if code != 0xFF && i < src.len() {
            put(dst, out, 0, out + 1)?;
            out += 1;
        }
    }
    Ok(out)
}
