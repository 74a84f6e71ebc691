//! The table-driven engine of the two CRC-16s in the firmware: Dynamixel Protocol 2.0's
//! (CRC-16/BUYPASS, poly 0x8005) and the host link's (CRC-16/CCITT-FALSE, poly 0x1021). Both shift
//! left without reflection and without a final xor, so they differ only in polynomial and initial
//! value; each keeps its own module with its parameters, check value and reasons.
//!
//! Nothing here panics: a table index is masked to four bits.

/// The table for four bits at a time of an MSB-first CRC-16 with `poly`, built at compile time: 32
/// bytes of flash, where a byte-at-a-time table takes 512 (two of them would be 1.5 % of the
/// firmware's 64 KiB budget) for a few more instructions per byte.
pub(crate) const fn msb_first_table(poly: u16) -> [u16; 16] {
    let mut table = [0u16; 16];
    let mut i = 0;
    while i < 16 {
        // `i < 16`, so the shift cannot lose bits and the cast is exact.
        let mut crc = (i as u16) << 12;
        let mut bit = 0;
        while bit < 4 {
            crc = if crc & 0x8000 != 0 { (crc << 1) ^ poly } else { crc << 1 };
            bit += 1;
        }
        table[i] = crc;
        i += 1;
    }
    table
}

/// Continues the CRC of `table` over `bytes` from the register value `crc`, high nibble first.
pub(crate) fn update(table: &[u16; 16], crc: u16, bytes: &[u8]) -> u16 {
    let step = |crc: u16, nibble: u8| (crc << 4) ^ table[usize::from(((crc >> 12) as u8 ^ nibble) & 0x0F)];
    bytes.iter().fold(crc, |crc, &byte| step(step(crc, byte >> 4), byte & 0x0F))
}
