//! The table-driven engine of the two CRC-16s in the firmware: Dynamixel Protocol 2.0's
//! (CRC-16/BUYPASS, poly 0x8005) and the host link's (CRC-16/CCITT-FALSE, poly 0x1021). Both shift
//! left without reflection and without a final xor, so they differ only in polynomial and initial
//! value; each keeps its own module with its parameters, check value and reasons.
//!
//! Nothing here panics: a table index is a `u8`.

/// The table for one byte at a time of an MSB-first CRC-16 with `poly`, built at compile time:
/// 512 bytes of flash instead of eight shifts per byte.
pub(crate) const fn msb_first_table(poly: u16) -> [u16; 256] {
    let mut table = [0u16; 256];
    let mut i = 0;
    while i < 256 {
        // `i < 256`, so the shift cannot lose bits and the cast is exact.
        let mut crc = (i as u16) << 8;
        let mut bit = 0;
        while bit < 8 {
            crc = if crc & 0x8000 != 0 { (crc << 1) ^ poly } else { crc << 1 };
            bit += 1;
        }
        table[i] = crc;
        i += 1;
    }
    table
}

/// Continues the CRC of `table` over `bytes` from the register value `crc`.
pub(crate) fn update(table: &[u16; 256], crc: u16, bytes: &[u8]) -> u16 {
    bytes.iter().fold(crc, |crc, &byte| (crc << 8) ^ table[usize::from((crc >> 8) as u8 ^ byte)])
}
