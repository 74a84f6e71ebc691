//! Byte stuffing, so that a header never appears inside a packet.
//!
//! e-manual, Protocol 2.0, "Packet Process": from the instruction field to the last parameter
//! (not the CRC), after every `FF FF FD` an extra `FD` is inserted; the length field counts the
//! stuffed bytes and the CRC covers them. The receiver checks the CRC first, then removes the `FD`
//! that follows each `FF FF FD`.
//!
//! The pattern cannot overlap itself (no proper suffix of `FF FF FD` is a prefix of it), so both
//! directions restart their search after each match and stay in step.

/// The three bytes that must not reach the wire unmarked.
const PATTERN: [u8; 3] = [0xFF, 0xFF, 0xFD];
/// The byte added after the pattern.
const STUFF: u8 = 0xFD;

/// Inserts the stuffing byte into a byte stream, lazily, so the encoders can count the stuffed
/// length before writing anything. With `enabled` false the stream passes unchanged (fast sync
/// read replies are not stuffed).
#[derive(Clone, Debug)]
pub(super) struct Stuffer<I> {
    inner: I,
    enabled: bool,
    window: [u8; 3],
    pending: bool,
}

impl<I: Iterator<Item = u8>> Stuffer<I> {
    pub(super) fn new(inner: I, enabled: bool) -> Self {
        Self { inner, enabled, window: [0; 3], pending: false }
    }
}

impl<I: Iterator<Item = u8>> Iterator for Stuffer<I> {
    type Item = u8;

    fn next(&mut self) -> Option<u8> {
        if self.pending {
            self.pending = false;
            return Some(STUFF);
        }
        let byte = self.inner.next()?;
        let [_, a, b] = self.window;
        self.window = [a, b, byte];
        if self.enabled && self.window == PATTERN {
            self.pending = true;
            self.window = [0; 3];
        }
        Some(byte)
    }
}

/// Removes the stuffing byte in place; returns the unstuffed length (the bytes from 0 to it).
///
/// An `FF FF FD` followed by something other than `FD` is kept as it is: the CRC already vouched
/// for the bytes, and the ROBOTIS SDK is as lenient.
pub(super) fn unstuff_in_place(region: &mut [u8]) -> usize {
    let mut written = 0;
    let mut window = [0u8; 3];
    for read in 0..region.len() {
        let byte = region.get(read).copied().unwrap_or(0);
        if window == PATTERN && byte == STUFF {
            window = [0; 3];
            continue;
        }
        let [_, a, b] = window;
        window = [a, b, byte];
        // `written <= read < region.len()`: the slot exists and the count cannot overflow.
        if let Some(slot) = region.get_mut(written) {
            *slot = byte;
        }
        written += 1;
    }
    written
}

#[cfg(test)]
mod tests {
    use super::*;

    fn stuffed(bytes: &[u8]) -> Vec<u8> {
        Stuffer::new(bytes.iter().copied(), true).collect()
    }

    #[test]
    fn stuffs_and_unstuffs() {
        let cases: [(&[u8], &[u8]); 5] = [
            (&[1, 2, 3], &[1, 2, 3]),
            (&[0xFF, 0xFF, 0xFD], &[0xFF, 0xFF, 0xFD, 0xFD]),
            (&[0xFF, 0xFF, 0xFD, 0xFD], &[0xFF, 0xFF, 0xFD, 0xFD, 0xFD]),
            (&[0xFF, 0xFF, 0xFF, 0xFD, 0x00], &[0xFF, 0xFF, 0xFF, 0xFD, 0xFD, 0x00]),
            (&[0xFF, 0xFF, 0xFD, 0xFF, 0xFF, 0xFD], &[0xFF, 0xFF, 0xFD, 0xFD, 0xFF, 0xFF, 0xFD, 0xFD]),
        ];
        for (plain, wire) in cases {
            assert_eq!(stuffed(plain), wire);
            let mut buf = wire.to_vec();
            let n = unstuff_in_place(&mut buf);
            assert_eq!(&buf[..n], plain);
        }
    }

    #[test]
    fn disabled_passes_through() {
        let plain = [0xFF, 0xFF, 0xFD, 7];
        assert_eq!(Stuffer::new(plain.iter().copied(), false).collect::<Vec<_>>(), plain);
    }
}
