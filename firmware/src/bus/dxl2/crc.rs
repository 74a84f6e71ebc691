//! The CRC-16 of Protocol 2.0.
//!
//! The e-manual ("CRC Calculation", linked from the Protocol 2.0 page) calls it "CRC-16 (IBM/ANSI)"
//! and gives the polynomial x^16 + x^15 + x^2 + 1 (0x8005) with initial value 0. Its reference code
//! shifts left and does not reflect, so the catalogue name is CRC-16/BUYPASS (check value of
//! "123456789": 0xFEE8), not the reflected CRC-16/ARC that "IBM" usually means.

/// The generator polynomial, x^16 + x^15 + x^2 + 1.
const POLY: u16 = 0x8005;

/// One entry per value of the nibble entering the register (see [`crate::crc16`]).
static TABLE: [u16; 16] = crate::crc16::msb_first_table(POLY);

/// Continues a CRC over more bytes: `crc16_update(crc16(a), b) == crc16(a ++ b)`. Fast sync read
/// replies need the running value, since every servo appends the CRC of the packet so far.
pub fn crc16_update(crc: u16, bytes: &[u8]) -> u16 {
    crate::crc16::update(&TABLE, crc, bytes)
}

/// The Protocol 2.0 CRC of `bytes` (header through last parameter, as sent, i.e. after stuffing).
pub fn crc16(bytes: &[u8]) -> u16 {
    crc16_update(0, bytes)
}
