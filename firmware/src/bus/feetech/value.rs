//! Multi-byte control-table values: byte order and sign-magnitude numbers.
//!
//! Byte order is a property of the servo model, not of the packet: "for potentiometer-type servos
//! (SCS) it is big-endian (high byte first), for magnetic encoder-type servos (STS/SMS) it is
//! little-endian (low byte first)" (Feetech SCS communication protocol manual, section 1; the
//! SCServo SDK's `scs_end` flag: 0 for STS/SMS, 1 for SCS, used by `scs_makeword`/`scs_lobyte`).
//!
//! Signed values (STS goal and present position and velocity, the homing offset) are
//! sign-magnitude, not two's complement: a sign bit and the magnitude below it. The SDK converts
//! with `scs_toscs(a, b)` (`-a | 1 << b` for negative `a`) and `scs_tohost(a, b)` (`-(a & !(1 << b))`
//! when bit `b` is set); bit 15 for position and velocity, bit 11 for the homing offset.

/// The byte order of 2-byte control-table values.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Endian {
    /// Low byte first: STS and SMS (magnetic encoder) servos, e.g. the STS3215.
    Little,
    /// High byte first: SCS (potentiometer) servos, e.g. the SCS0009.
    Big,
}

/// The two wire bytes of `v`, in the servo's byte order.
pub fn encode_u16(v: u16, e: Endian) -> [u8; 2] {
    match e {
        Endian::Little => v.to_le_bytes(),
        Endian::Big => v.to_be_bytes(),
    }
}

/// The value of two wire bytes, in the servo's byte order.
pub fn decode_u16(b: [u8; 2], e: Endian) -> u16 {
    match e {
        Endian::Little => u16::from_le_bytes(b),
        Endian::Big => u16::from_be_bytes(b),
    }
}

/// `v` as a sign-magnitude number with its sign at bit `sign_bit` (15 for STS position and
/// velocity, 11 for the homing offset), like the SDK's `scs_toscs`.
///
/// `None` when `|v|` does not fit below the sign bit (`|v| >= 1 << sign_bit`), or when `sign_bit`
/// is above 15. Unlike the SDK, which would let a large magnitude spill into the sign bit and
/// above, nothing is silently changed.
pub fn to_sign_magnitude(v: i32, sign_bit: u8) -> Option<u16> {
    if sign_bit > 15 {
        return None;
    }
    let sign = 1u16 << sign_bit;
    let magnitude = u16::try_from(v.unsigned_abs()).ok().filter(|m| *m < sign)?;
    Some(if v < 0 { magnitude | sign } else { magnitude })
}

/// The value of a sign-magnitude number with its sign at bit `sign_bit`, like the SDK's
/// `scs_tohost`.
///
/// Negative zero (only the sign bit set, e.g. `0x8000`) decodes to 0. Bits above the sign bit are
/// not part of the number and are ignored (the SDK would count them into the magnitude); a
/// `sign_bit` above 15 means no sign bit, and `raw` is returned unsigned.
pub fn from_sign_magnitude(raw: u16, sign_bit: u8) -> i32 {
    if sign_bit > 15 {
        return i32::from(raw);
    }
    let sign = 1u16 << sign_bit;
    let magnitude = i32::from(raw & (sign - 1));
    if raw & sign != 0 {
        -magnitude
    } else {
        magnitude
    }
}
