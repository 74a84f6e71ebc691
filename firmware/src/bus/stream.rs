//! A streaming frame decoder: bytes arrive from a UART one at a time or in bursts, with line noise,
//! bytes lost mid-packet and packets cut short; complete, checksum-valid frames come out.
//!
//! The decoder keeps at most `CAP` bytes. It looks for a header, asks the codec how long the frame
//! is ([`Protocol::frame_len`]), and when all of it is there checks the checksum. Whatever cannot
//! be a frame is dropped one byte at a time and the rest rescanned, so a header hidden in the
//! bytes of a broken packet is still found. A length field promising more than `CAP` bytes is
//! treated the same way. Every dropped candidate is counted in [`DecoderStats`].
//!
//! A candidate whose length field promises more bytes than have come (a packet cut short, or a
//! header-like pattern in line noise) holds back the bytes behind it while the line is busy: they
//! could be its data. Once the line has been idle longer than a packet's bytes may be apart, that
//! candidate is dead: [`StreamDecoder::expire`] drops every incomplete candidate and rescans, so
//! an intact packet received behind one is delivered then. The bus master and the simulated
//! servos call it when the line goes quiet; without that call, a false header in noise would
//! delay the frames behind it until its announced length had arrived.

use super::{FrameLen, Protocol};

/// What the decoder has seen, for error reports and link statistics.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct DecoderStats {
    /// Frames delivered.
    pub frames: u32,
    /// Complete frames dropped for a bad checksum.
    pub bad_checksums: u32,
    /// Bytes dropped because no frame could start there.
    pub garbage_bytes: u32,
    /// Frames dropped because their length field exceeds the buffer.
    pub oversized: u32,
    /// Incomplete candidates dropped after [`StreamDecoder::expire`].
    pub expired: u32,
    /// Bytes refused because the buffer was full of frames not taken.
    pub overflow: u32,
}

/// A bounded streaming decoder for one protocol.
#[derive(Clone, Debug)]
pub struct StreamDecoder<const CAP: usize> {
    protocol: Protocol,
    buf: [u8; CAP],
    /// The bytes held are `buf[start..end]`. Dropping bytes from the front moves `start`; the
    /// held bytes are moved back to the front only when an append would not fit behind them, so a
    /// dropped byte costs nothing and the bytes are copied at most once per buffer's worth.
    start: usize,
    end: usize,
    /// Bytes of the frame last returned, dropped at the next call (the frame borrows them).
    delivered: usize,
    /// The line has been idle since the last byte: incomplete candidates are dead.
    idle: bool,
    stats: DecoderStats,
}

impl<const CAP: usize> StreamDecoder<CAP> {
    /// An empty decoder.
    pub const fn new(protocol: Protocol) -> Self {
        Self {
            protocol,
            buf: [0; CAP],
            start: 0,
            end: 0,
            delivered: 0,
            idle: false,
            stats: DecoderStats {
                frames: 0,
                bad_checksums: 0,
                garbage_bytes: 0,
                oversized: 0,
                expired: 0,
                overflow: 0,
            },
        }
    }

    /// The protocol decoded.
    pub fn protocol(&self) -> Protocol {
        self.protocol
    }

    /// Counters since creation.
    pub fn stats(&self) -> DecoderStats {
        self.stats
    }

    /// Bytes held (a partial frame, or frames not yet taken).
    pub fn buffered(&self) -> usize {
        self.end - self.start - self.delivered
    }

    /// Forgets every buffered byte (e.g. before a new transaction: nothing before it belongs to it).
    pub fn clear(&mut self) {
        self.start = 0;
        self.end = 0;
        self.delivered = 0;
    }

    /// Declares the line idle: call when no byte has come for longer than the protocol allows
    /// between the bytes of one packet, which proves that an incomplete frame will never be
    /// completed. Every incomplete candidate is then dropped (one byte at a time, rescanning), and
    /// complete frames behind them are delivered by [`StreamDecoder::next_frame`]. The next byte
    /// appended ends the idle state.
    pub fn expire(&mut self) {
        self.idle = true;
    }

    /// Whether bytes are held that are not yet a frame (the line is mid-packet, or noise waits
    /// for [`StreamDecoder::expire`]).
    pub fn holds_partial(&mut self) -> bool {
        self.release();
        self.end > self.start
    }

    fn release(&mut self) {
        if self.delivered > 0 {
            self.drop_front(self.delivered);
            self.delivered = 0;
        }
    }

    fn drop_front(&mut self, n: usize) {
        self.start = self.end.min(self.start + n);
        if self.start == self.end {
            self.start = 0;
            self.end = 0;
        }
    }

    /// Moves the held bytes to the front of the buffer. In chunks no longer than the gap, so that
    /// source and destination never overlap: a plain copy (`memcpy`, which the firmware links
    /// anyway) rather than `copy_within`, whose `memmove` would add 1.5 KB of flash.
    fn compact(&mut self) {
        let gap = self.start;
        let mut to = 0;
        while gap > 0 && to + gap < self.end {
            let n = (self.end - to - gap).min(gap);
            let Some((front, back)) = self.buf.split_at_mut_checked(to + gap) else { break };
            if let (Some(dst), Some(src)) = (front.get_mut(to..to + n), back.get(..n)) {
                dst.copy_from_slice(src);
            }
            to += n;
        }
        self.end -= gap;
        self.start = 0;
    }

    /// The bytes held.
    fn held(&self) -> &[u8] {
        self.buf.get(self.start..self.end).unwrap_or_default()
    }

    /// Appends as many of `bytes` as fit; returns how many were taken. Fewer than all means the
    /// buffer is full of complete frames: take them with [`StreamDecoder::next_frame`] and append
    /// the rest. After `next_frame` returns `None` there is always room for one more byte.
    pub fn extend(&mut self, bytes: &[u8]) -> usize {
        self.release();
        if bytes.len() > CAP - self.end {
            self.compact();
        }
        let n = bytes.len().min(CAP - self.end);
        if n > 0 {
            self.idle = false;
        }
        let free = self.buf.iter_mut().skip(self.end);
        let taken = free.zip(bytes).map(|(slot, &b)| *slot = b).count();
        self.end += taken;
        taken
    }

    /// Appends one byte and returns the frame it completes, if any. Used alone, `push` always has
    /// room (each call takes out what completes); a byte that finds the buffer full because
    /// [`StreamDecoder::extend`] filled it without draining is counted in `overflow`.
    pub fn push(&mut self, byte: u8) -> Option<&mut [u8]> {
        if self.extend(&[byte]) == 0 {
            self.stats.overflow = self.stats.overflow.wrapping_add(1);
        }
        self.next_frame()
    }

    /// The next complete frame with a valid checksum among the buffered bytes, if there is one.
    /// The frame stays valid until the next call on the decoder; parse it with the codec.
    pub fn next_frame(&mut self) -> Option<&mut [u8]> {
        self.release();
        let n = self.next_frame_len()?;
        self.buf.get_mut(self.start..self.start + n)
    }

    /// Scans for a frame; on success marks its bytes as delivered and returns its length.
    fn next_frame_len(&mut self) -> Option<usize> {
        loop {
            // Skip to the first byte that can start a header (both protocols start with 0xFF).
            let garbage = self.held().iter().position(|&b| b == 0xFF).unwrap_or(self.held().len());
            if garbage > 0 {
                self.stats.garbage_bytes = self.stats.garbage_bytes.wrapping_add(garbage as u32);
                self.drop_front(garbage);
            }
            if self.start == self.end {
                return None;
            }
            match self.protocol.frame_len(self.held()) {
                FrameLen::NotAFrame => {
                    self.stats.garbage_bytes = self.stats.garbage_bytes.wrapping_add(1);
                    self.drop_front(1);
                }
                FrameLen::NeedMore(n) if n > CAP => {
                    self.stats.oversized = self.stats.oversized.wrapping_add(1);
                    self.drop_front(1);
                }
                FrameLen::NeedMore(_) if self.idle => {
                    self.stats.expired = self.stats.expired.wrapping_add(1);
                    self.drop_front(1);
                }
                FrameLen::NeedMore(_) => return None,
                FrameLen::Complete(n) => match self.protocol.verify(self.held().get(..n).unwrap_or(self.held())) {
                    Ok(()) => {
                        self.stats.frames = self.stats.frames.wrapping_add(1);
                        self.delivered = n.min(self.end - self.start);
                        return Some(self.delivered);
                    }
                    Err(_) => {
                        self.stats.bad_checksums = self.stats.bad_checksums.wrapping_add(1);
                        self.drop_front(1);
                    }
                },
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const PING: [u8; 10] = [0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x03, 0x00, 0x01, 0x19, 0x4E];
    const STATUS: [u8; 14] = [0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x07, 0x00, 0x55, 0x00, 0x06, 0x04, 0x26, 0x65, 0x5D];

    fn frames(decoder: &mut StreamDecoder<64>, bytes: &[u8]) -> Vec<Vec<u8>> {
        let mut out = Vec::new();
        for &b in bytes {
            if let Some(f) = decoder.push(b) {
                out.push(f.to_vec());
            }
        }
        while let Some(f) = decoder.next_frame() {
            out.push(f.to_vec());
        }
        out
    }

    #[test]
    fn byte_by_byte_and_in_a_burst() {
        let mut d = StreamDecoder::<64>::new(Protocol::Dxl2);
        let stream = [&PING[..], &STATUS[..]].concat();
        assert_eq!(frames(&mut d, &stream), [PING.to_vec(), STATUS.to_vec()]);
        let mut d = StreamDecoder::<64>::new(Protocol::Dxl2);
        assert_eq!(d.extend(&stream), stream.len());
        assert_eq!(d.next_frame().map(|f| f.to_vec()), Some(PING.to_vec()));
        assert_eq!(d.next_frame().map(|f| f.to_vec()), Some(STATUS.to_vec()));
        assert_eq!(d.next_frame(), None);
    }

    #[test]
    fn resynchronises_after_garbage_partial_packets_and_bad_checksums() {
        let mut d = StreamDecoder::<64>::new(Protocol::Dxl2);
        let mut corrupt = STATUS;
        corrupt[9] ^= 0x10;
        let stream = [&[0x00, 0xFF, 0x13, 0xFF, 0xFF][..], &PING[..6], &corrupt[..], &PING[..], &STATUS[..]].concat();
        assert_eq!(frames(&mut d, &stream), [PING.to_vec(), STATUS.to_vec()]);
        let stats = d.stats();
        assert_eq!(stats.frames, 2);
        assert!(stats.bad_checksums >= 1, "{stats:?}");
    }

    #[test]
    fn oversized_length_fields_are_dropped_without_waiting() {
        // A header announcing 0xFFF0 bytes can never fit 64: the decoder moves on at once.
        let mut d = StreamDecoder::<64>::new(Protocol::Dxl2);
        let stream = [&[0xFF, 0xFF, 0xFD, 0x00, 0x01, 0xF0, 0xFF][..], &PING[..]].concat();
        assert_eq!(frames(&mut d, &stream), [PING.to_vec()]);
        assert_eq!(d.stats().oversized, 1);
    }

    #[test]
    fn expire_drops_a_partial_frame() {
        let mut d = StreamDecoder::<64>::new(Protocol::Feetech);
        assert_eq!(frames(&mut d, &[0xFF, 0xFF, 0x01, 0x02]), Vec::<Vec<u8>>::new());
        d.expire();
        assert_eq!(d.next_frame(), None);
        assert!(d.stats().expired >= 1);
        assert!(!d.holds_partial());
        assert_eq!(frames(&mut d, &[0xFF, 0xFF, 0x01, 0x02, 0x01, 0xFB]), [vec![0xFF, 0xFF, 0x01, 0x02, 0x01, 0xFB]]);
    }

    /// Garbage dropped from the front leaves a gap; a later append that does not fit behind the
    /// held bytes moves them to the front in chunks (here 9 bytes through a 5-byte gap), intact.
    #[test]
    fn held_bytes_survive_being_moved_to_the_front() {
        let write = [0xFF, 0xFF, 0x01, 0x06, 0x03, 0x2A, 0x00, 0x01, 0x02, 0xC8];
        let ping = [0xFF, 0xFF, 0x01, 0x02, 0x01, 0xFB];
        let mut d = StreamDecoder::<16>::new(Protocol::Feetech);
        let first = [&[0x00; 5][..], &write[..9]].concat();
        assert_eq!(d.extend(&first), 14);
        assert_eq!(d.next_frame(), None);
        assert_eq!(d.buffered(), 9);
        let second = [&write[9..], &ping[..]].concat();
        assert_eq!(d.extend(&second), 7);
        assert_eq!(d.next_frame().map(|f| f.to_vec()), Some(write.to_vec()));
        assert_eq!(d.next_frame().map(|f| f.to_vec()), Some(ping.to_vec()));
        assert_eq!(d.next_frame(), None);
        assert_eq!(d.stats().garbage_bytes, 5);
    }

    /// A header-like pattern in noise announcing more bytes than come holds back the intact
    /// packet behind it only until the line goes idle.
    #[test]
    fn a_false_header_in_noise_delays_but_never_loses_the_packet_behind_it() {
        for (protocol, noise, packet) in [
            (Protocol::Dxl2, &[0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x30, 0x00][..], &STATUS[..]),
            (Protocol::Feetech, &[0xFF, 0xFF, 0x00, 0x20][..], &[0xFF, 0xFF, 0x01, 0x02, 0x00, 0xFC][..]),
        ] {
            let mut d = StreamDecoder::<64>::new(protocol);
            let stream = [noise, packet].concat();
            assert_eq!(frames(&mut d, &stream), Vec::<Vec<u8>>::new(), "{protocol:?}: still mid-packet");
            assert!(d.holds_partial());
            d.expire();
            assert_eq!(d.next_frame().map(|f| f.to_vec()), Some(packet.to_vec()), "{protocol:?}");
            assert!(!d.holds_partial());
        }
    }
}
