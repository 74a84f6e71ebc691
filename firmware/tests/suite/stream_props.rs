//! Property tests of the streaming decoder ([`StreamDecoder`]) on both protocols: valid packets from
//! the codecs' encoders, mixed with garbage, cut short or with a bit flipped, split into random
//! bursts fed with `push` and `extend`.
//!
//! The claims are exact, so the generators are built for them:
//! - Garbage without 0xFF cannot start a frame (both headers start with 0xFF), so packets separated
//!   by it are delivered exactly, in order.
//! - Arbitrary garbage can hold a header whose length field swallows what follows, but never more
//!   than `CAP` bytes: after a gap of `CAP` bytes without 0xFF, the packets are the last frames.
//! - A corrupted packet (cut short, or one bit flipped) is dropped and the intact packets after it
//!   are delivered, unless some candidate frame starting inside the corrupted bytes has a valid
//!   checksum (a Feetech checksum matches by chance one time in 256): such cases are discarded
//!   with `prop_assume!`, after computing it with the codec's own `frame_len` and `verify`.

use firmware::bus::instruction::Instruction;
use firmware::bus::stream::StreamDecoder;
use firmware::bus::{FrameLen, InstructionPacket, Protocol, Status};
use proptest::prelude::*;

/// Decoder size: above the longest generated packet (about 100 bytes), small enough that
/// oversized length fields in garbage are common.
const CAP: usize = 128;

fn protocol() -> impl Strategy<Value = Protocol> {
    prop_oneof![Just(Protocol::Dxl2), Just(Protocol::Feetech)]
}

fn bytes(max: usize) -> impl Strategy<Value = Vec<u8>> {
    // Biased towards 0xFF and 0xFD, so that Dynamixel stuffing and header-like bytes are common.
    prop::collection::vec(prop_oneof![3 => any::<u8>(), 1 => Just(0xFF), 1 => Just(0xFD)], 0..=max)
}

/// A valid packet of `protocol`, encoded by its codec: an instruction or a status.
fn packet(protocol: Protocol) -> BoxedStrategy<Vec<u8>> {
    let (max_id, broadcast_status) = match protocol {
        Protocol::Dxl2 => (252u8, true),
        Protocol::Feetech => (253u8, false),
    };
    let id = prop_oneof![0..=max_id, Just(0xFE)];
    let status_id = if broadcast_status { id.clone().boxed() } else { (0..=max_id).boxed() };
    let instruction = (id, 0u8..5, any::<u8>(), 1u8..=40, bytes(40), prop::collection::vec(0..=max_id, 0..8))
        .prop_filter_map("encodable", move |(id, kind, address, length, data, ids)| {
            let (address, length) = (u16::from(address), u16::from(length));
            let instruction = match kind {
                0 => Instruction::Ping,
                1 => Instruction::Read { address, length },
                2 if !data.is_empty() => Instruction::Write { address, data: &data },
                3 => Instruction::SyncRead { address, length, ids: &ids },
                _ => Instruction::Action,
            };
            let mut out = [0u8; 256];
            let n = protocol.encode_instruction(&InstructionPacket { id, instruction }, &mut out).ok()?;
            Some(out[..n].to_vec())
        });
    let status = (status_id, any::<u8>(), bytes(40)).prop_map(move |(id, error, params)| {
        let mut out = [0u8; 256];
        let n = protocol.encode_status(&Status { id, error, params: &params }, &mut out).unwrap();
        out[..n].to_vec()
    });
    prop_oneof![instruction, status].boxed()
}

/// Garbage that cannot start a frame: no 0xFF.
fn clean_garbage(max: usize) -> impl Strategy<Value = Vec<u8>> {
    prop::collection::vec(0u8..0xFF, 0..=max)
}

/// Burst sizes; 1 is fed with `push`, larger ones with `extend` and `next_frame`.
fn bursts() -> impl Strategy<Value = Vec<usize>> {
    prop::collection::vec(prop_oneof![1 => Just(1usize), 2 => 1usize..20, 1 => 20usize..200], 1..40)
}

/// Feeds `stream` in the given bursts (cycled), checks the decoder's invariants, and returns the
/// frames delivered.
fn feed(protocol: Protocol, stream: &[u8], bursts: &[usize]) -> Vec<Vec<u8>> {
    let mut d = StreamDecoder::<CAP>::new(protocol);
    let mut frames = Vec::new();
    let take = |frame: &mut [u8], frames: &mut Vec<Vec<u8>>| {
        assert!(!frame.is_empty() && frame.len() <= CAP);
        assert_eq!(protocol.frame_len(frame), FrameLen::Complete(frame.len()));
        assert_eq!(protocol.verify(frame), Ok(()));
        let _ = protocol.parse_instruction(&mut frame.to_vec());
        let _ = protocol.parse_status(&mut frame.to_vec());
        frames.push(frame.to_vec());
    };
    let mut rest = stream;
    for &burst in bursts.iter().cycle() {
        if rest.is_empty() {
            break;
        }
        let burst = burst.min(rest.len());
        if burst == 1 {
            if let Some(frame) = d.push(rest[0]) {
                take(frame, &mut frames);
            }
            rest = &rest[1..];
        } else {
            let mut chunk = &rest[..burst];
            rest = &rest[burst..];
            while !chunk.is_empty() {
                let taken = d.extend(chunk);
                chunk = &chunk[taken..];
                let before = frames.len();
                while let Some(frame) = d.next_frame() {
                    take(frame, &mut frames);
                }
                // Room for at least one byte once `next_frame` has returned `None`.
                assert!(taken > 0 || frames.len() > before);
            }
        }
        assert!(d.buffered() <= CAP);
    }
    while let Some(frame) = d.next_frame() {
        take(frame, &mut frames);
    }
    // The line goes quiet after the stream: what waits for more bytes is dead, and the frames it
    // held back come out.
    d.expire();
    while let Some(frame) = d.next_frame() {
        take(frame, &mut frames);
    }
    assert!(!d.holds_partial());
    let stats = d.stats();
    assert_eq!(stats.frames as usize, frames.len());
    assert_eq!(stats.overflow, 0, "push and drained extend never overflow: {stats:?}");
    frames
}

/// Whether a candidate frame starting at a 0xFF inside `stream[region]` would be delivered: it
/// fits the decoder and its checksum is valid (the bytes after the region included).
fn spurious_frame(protocol: Protocol, stream: &[u8], region: core::ops::Range<usize>) -> bool {
    region.filter(|&s| stream[s] == 0xFF).any(|s| match protocol.frame_len(&stream[s..]) {
        FrameLen::Complete(n) if n <= CAP => protocol.verify(&stream[s..s + n]).is_ok(),
        _ => false,
    })
}

/// `(protocol, [(garbage before, packet)], garbage after)`.
type CleanStream = (Protocol, Vec<(Vec<u8>, Vec<u8>)>, Vec<u8>);

fn clean_stream() -> impl Strategy<Value = CleanStream> {
    protocol()
        .prop_flat_map(|p| (Just(p), prop::collection::vec((clean_garbage(30), packet(p)), 0..8), clean_garbage(30)))
}

/// A corrupted copy of `packet` and, for a bit flip, which byte was flipped.
#[derive(Clone, Debug)]
enum Damage {
    /// Cut to its first `n` bytes (`n` below its length).
    Truncated(usize),
    /// Bit `bit` (0..8 * len) flipped.
    Flipped(usize),
}

/// `(protocol, [(packet, its damage)], intact packets)`: intact packet `i` follows damaged packet `i`.
type DamagedStream = (Protocol, Vec<(Vec<u8>, Damage)>, Vec<Vec<u8>>);

fn damaged_stream() -> impl Strategy<Value = DamagedStream> {
    protocol().prop_flat_map(|p| {
        let damaged = (packet(p), any::<prop::sample::Index>(), any::<bool>()).prop_map(|(packet, at, cut)| {
            let damage = if cut {
                Damage::Truncated(at.index(packet.len()))
            } else {
                Damage::Flipped(at.index(packet.len() * 8))
            };
            (packet, damage)
        });
        (Just(p), prop::collection::vec(damaged, 1..5), prop::collection::vec(packet(p), 1..5))
    })
}

/// The length field's bytes: Dynamixel `LEN_L LEN_H`, Feetech `LEN`.
fn length_field(protocol: Protocol) -> core::ops::Range<usize> {
    match protocol {
        Protocol::Dxl2 => 5..7,
        Protocol::Feetech => 3..4,
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    /// Valid packets with garbage free of 0xFF between them: each delivered exactly once, in order,
    /// whatever the bursts.
    #[test]
    fn packets_between_clean_garbage_are_delivered_exactly((protocol, items, tail) in clean_stream(), bursts in bursts()) {
        let mut stream = Vec::new();
        for (garbage, packet) in &items {
            stream.extend_from_slice(garbage);
            stream.extend_from_slice(packet);
        }
        stream.extend_from_slice(&tail);
        let frames = feed(protocol, &stream, &bursts);
        let packets: Vec<Vec<u8>> = items.iter().map(|(_, p)| p.clone()).collect();
        prop_assert_eq!(frames, packets);
    }

    /// Arbitrary bytes: no panic, the invariants of `feed` hold.
    #[test]
    fn arbitrary_bytes_keep_the_invariants(protocol in protocol(), stream in bytes(600), bursts in bursts()) {
        feed(protocol, &stream, &bursts);
    }

    /// Arbitrary garbage, then a gap of `CAP` bytes without 0xFF, then packets: whatever the
    /// garbage delivered, the packets are the last frames, each once and in order.
    #[test]
    fn packets_after_a_clean_gap_are_the_last_frames(
        (protocol, garbage, gap, packets) in protocol().prop_flat_map(|p| (
            Just(p),
            bytes(300),
            prop::collection::vec(0u8..0xFF, CAP..CAP + 20),
            prop::collection::vec(packet(p), 1..6),
        )),
        bursts in bursts(),
    ) {
        let stream = [garbage, gap, packets.concat()].concat();
        let frames = feed(protocol, &stream, &bursts);
        prop_assert!(frames.len() >= packets.len());
        prop_assert_eq!(&frames[frames.len() - packets.len()..], &packets[..]);
    }

    /// Packets cut short or with one bit flipped, each followed by an intact packet: the intact
    /// ones are delivered, in order, and nothing else (unless a candidate frame inside the
    /// corrupted bytes happens to have a valid checksum: discarded).
    #[test]
    fn intact_packets_after_damaged_ones_are_delivered(
        (protocol, damaged, intact) in damaged_stream(),
        bursts in bursts(),
    ) {
        let mut stream = Vec::new();
        let mut regions = Vec::new();
        let mut expected = Vec::new();
        for (i, (packet, damage)) in damaged.iter().enumerate() {
            let start = stream.len();
            let mut bad = packet.clone();
            match *damage {
                Damage::Truncated(n) => bad.truncate(n),
                Damage::Flipped(bit) => {
                    bad[bit / 8] ^= 1 << (bit % 8);
                    // The codecs' guarantee: one flipped bit outside the length field never leaves
                    // a valid frame at the packet's start (Feetech: the complement sum changes by
                    // ±2^k; Dynamixel: CRC-16 detects every single-bit error; a flipped header or
                    // id byte is no frame).
                    if !length_field(protocol).contains(&(bit / 8)) {
                        let ok = match protocol.frame_len(&bad) {
                            FrameLen::Complete(n) => protocol.verify(&bad[..n]).is_ok(),
                            _ => false,
                        };
                        prop_assert!(!ok, "flipping bit {} of {:02x?} left a valid frame", bit, packet);
                    }
                }
            }
            stream.extend_from_slice(&bad);
            regions.push(start..stream.len());
            if let Some(good) = intact.get(i) {
                stream.extend_from_slice(good);
                expected.push(good.clone());
            }
        }
        for good in intact.iter().skip(damaged.len()) {
            stream.extend_from_slice(good);
            expected.push(good.clone());
        }
        // `feed` ends with the line going quiet (`expire`): a candidate from a cut packet that
        // still waits for bytes is dropped then, and the packets it held back are delivered.
        for region in &regions {
            prop_assume!(!spurious_frame(protocol, &stream, region.clone()));
        }
        let frames = feed(protocol, &stream, &bursts);
        prop_assert_eq!(frames, expected);
    }

    /// The same decoder output whether the bytes come one by one or in one burst.
    #[test]
    fn bursts_do_not_change_the_frames(protocol in protocol(), stream in bytes(600), bursts in bursts()) {
        prop_assert_eq!(feed(protocol, &stream, &[1]), feed(protocol, &stream, &bursts));
    }
}
