//! The Feetech checksum: the complement of the low byte of a plain sum.
//!
//! Feetech SCS communication protocol manual, section 2 (instruction frame): "Check Sum = ~(ID +
//! Length + Instruction + Parameter1 + ... Parameter N). If the sum ... exceeds 255, take the
//! lowest byte". The status frame uses the same rule with the error byte in the instruction's
//! place; the SCServo SDK's `txPacket`/`rxPacket` sum bytes 2 to `LEN + 2` the same way.
//!
//! Because the sum is taken modulo 256 and then complemented, flipping any single bit of the
//! covered bytes changes the sum by `±2^k (mod 256)`, which is never 0, so a one-bit error in ID,
//! INST/ERR, a parameter or the checksum itself is always detected. A flip in LEN is not covered by
//! that argument (it moves the checksum byte); [`super::verify`] catches it because a frame must be
//! exactly as long as its LEN says, and a flip in the header is caught as a bad header. Two-bit
//! errors can cancel (`+1` in one byte, `-1` in another): the checksum is weak.

/// The checksum of the covered bytes: everything between the `FF FF` header and the checksum byte.
pub fn checksum(covered: &[u8]) -> u8 {
    !sum(covered)
}

/// The modulo-256 sum of `bytes` (the part of the checksum before the complement).
pub(super) fn sum(bytes: &[u8]) -> u8 {
    bytes.iter().fold(0u8, |acc, b| acc.wrapping_add(*b))
}

/// Whether a received checksum matches the computed one.
///
/// Under `cfg(fuzzing)` every checksum matches, so that cargo-fuzz reaches the parsers instead of
/// spending its effort on guessing checksums (smoltcp `fuzz/` does the same).
#[cfg(not(fuzzing))]
pub(super) fn matches(received: u8, computed: u8) -> bool {
    received == computed
}

/// Whether a received checksum matches the computed one: always, in fuzzing builds.
#[cfg(fuzzing)]
pub(super) fn matches(_received: u8, _computed: u8) -> bool {
    true
}
