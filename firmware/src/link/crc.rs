//! CRC-16/CCITT-FALSE, the per-frame check of the host link.
//!
//! Parameters (the Rocksoft/Williams model as catalogued by Greg Cook's "Catalogue of parametrised
//! CRC algorithms"): width 16, poly 0x1021, init 0xFFFF, no reflection, xorout 0x0000, check 0x29B1.
//! Sixteen bits detect every burst error up to 16 bits and every odd number of flipped bits (the
//! polynomial has the factor x + 1) in frames far longer than the 254 bytes a link frame holds, at
//! two bytes of overhead; CRC-32 would cost four.
//!
//! Nothing here panics.

/// The table for one nibble at a time (see [`crate::crc16`]).
const TABLE: [u16; 16] = crate::crc16::msb_first_table(0x1021);

/// The initial register value.
pub const INIT: u16 = 0xFFFF;

/// Continues a CRC over `bytes` from the register value `crc` (start with [`INIT`]).
pub fn update(crc: u16, bytes: &[u8]) -> u16 {
    crate::crc16::update(&TABLE, crc, bytes)
}

/// The CRC-16/CCITT-FALSE of `bytes`.
pub fn crc16(bytes: &[u8]) -> u16 {
    update(INIT, bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn check_value() {
        assert_eq!(crc16(b"123456789"), 0x29B1);
    }

    #[test]
    fn empty_is_init() {
        assert_eq!(crc16(&[]), 0xFFFF);
    }

    #[test]
    fn split_updates_agree() {
        assert_eq!(update(update(INIT, b"1234"), b"56789"), 0x29B1);
    }
}
