//! The fuzz targets' bodies, shared by the binaries in `fuzz_targets/`.
//!
//! Built by cargo-fuzz, which sets `cfg(fuzzing)`: the codecs then accept any checksum, so random
//! inputs reach the parsers. Every check below holds with or without that, except where noted.

use std::cell::{Cell, RefCell};
use std::collections::VecDeque;
use std::rc::Rc;

use firmware::bus::dxl2::{self, fast_sync_read_parts, FastSyncPart};
use firmware::bus::instruction::{bulk_read_records, bulk_write_records, sync_write_records, BulkReadRecord};
use firmware::bus::master::{BusConfig, Clock, GroupReport, Master, NoDirectionPin};
use firmware::bus::stream::StreamDecoder;
use firmware::bus::{feetech, EncodeError, FrameLen, Instruction, Protocol, Status, BROADCAST};

/// The stream targets' decoder size: small, so that oversized length fields and a full buffer
/// happen often.
pub const CAP: usize = 64;

/// A tiny deterministic generator (burst sizes, when to expire), seeded from the input.
struct Lcg(u32);

impl Lcg {
    fn next(&mut self) -> u32 {
        self.0 = self.0.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
        self.0 >> 16
    }

    /// 1..=max.
    fn size(&mut self, max: usize) -> usize {
        (self.next() as usize % max) + 1
    }
}

/// Checks one delivered frame and returns a copy of it.
fn check_frame<const N: usize>(protocol: Protocol, frame: &[u8]) -> Vec<u8> {
    assert!(!frame.is_empty() && frame.len() <= N, "frame of {} bytes from a {N}-byte decoder", frame.len());
    assert_eq!(protocol.frame_len(frame), FrameLen::Complete(frame.len()), "delivered frame {frame:02x?}");
    assert_eq!(protocol.verify(frame), Ok(()), "delivered frame {frame:02x?}");
    // Whatever the frame holds, both parsers must return without panicking.
    let _ = protocol.parse_instruction(&mut frame.to_vec());
    let _ = protocol.parse_status(&mut frame.to_vec());
    frame.to_vec()
}

/// Feeds `bytes` one at a time with `push` (and drains what is left at the end).
fn by_push<const N: usize>(protocol: Protocol, bytes: &[u8]) -> Vec<Vec<u8>> {
    let mut d = StreamDecoder::<N>::new(protocol);
    let mut frames = Vec::new();
    for &b in bytes {
        if let Some(f) = d.push(b) {
            frames.push(check_frame::<N>(protocol, f));
        }
        assert!(d.buffered() <= N);
    }
    while let Some(f) = d.next_frame() {
        frames.push(check_frame::<N>(protocol, f));
    }
    assert!(d.buffered() <= N);
    let stats = d.stats();
    // `push` used alone always has room.
    assert_eq!(stats.overflow, 0, "{stats:?}");
    assert_eq!(stats.frames as usize, frames.len(), "{stats:?}");
    frames
}

/// Feeds `bytes` in bursts with `extend`, draining with `next_frame` after each.
fn by_bursts<const N: usize>(protocol: Protocol, bytes: &[u8], rng: &mut Lcg, max_burst: usize) -> Vec<Vec<u8>> {
    let mut d = StreamDecoder::<N>::new(protocol);
    let mut frames = Vec::new();
    let mut rest = bytes;
    while !rest.is_empty() {
        let burst = rng.size(max_burst).min(rest.len());
        let mut chunk = &rest[..burst];
        rest = &rest[burst..];
        while !chunk.is_empty() {
            let taken = d.extend(chunk);
            assert!(taken <= chunk.len());
            assert!(d.buffered() <= N);
            chunk = &chunk[taken..];
            let before = frames.len();
            while let Some(f) = d.next_frame() {
                frames.push(check_frame::<N>(protocol, f));
            }
            // After `next_frame` returns `None` there is always room for one more byte.
            assert!(
                taken > 0 || frames.len() > before || chunk.is_empty(),
                "extend took nothing from an empty-handed decoder"
            );
        }
    }
    let stats = d.stats();
    assert_eq!(stats.overflow, 0, "{stats:?}");
    assert_eq!(stats.frames as usize, frames.len(), "{stats:?}");
    frames
}

/// Mixed `push`, `extend`, `next_frame`, `expire` and `clear`: only the invariants are checked.
fn mixed<const N: usize>(protocol: Protocol, bytes: &[u8], rng: &mut Lcg) {
    let mut d = StreamDecoder::<N>::new(protocol);
    let mut rest = bytes;
    let mut delivered = 0usize;
    while !rest.is_empty() {
        match rng.next() % 16 {
            0 => d.expire(),
            1 => d.clear(),
            2..=7 => {
                let b = rest[0];
                rest = &rest[1..];
                if let Some(f) = d.push(b) {
                    check_frame::<N>(protocol, f);
                    delivered += 1;
                }
            }
            8..=11 => {
                let burst = rng.size(2 * N).min(rest.len());
                let taken = d.extend(&rest[..burst]);
                rest = &rest[taken..];
            }
            _ => {
                if let Some(f) = d.next_frame() {
                    check_frame::<N>(protocol, f);
                    delivered += 1;
                }
            }
        }
        assert!(d.buffered() <= N);
        if d.buffered() == N {
            // A full buffer is drained before more is offered (as `Master` does).
            while let Some(f) = d.next_frame() {
                check_frame::<N>(protocol, f);
                delivered += 1;
            }
        }
    }
    assert_eq!(d.stats().frames as usize, delivered);
}

/// The stream targets: the first byte seeds the burst sizes; the rest is the received stream.
///
/// The frames delivered must not depend on how the bytes were split: byte by byte with `push`
/// and in bursts with `extend` give the same frames, in the same order.
pub fn stream(protocol: Protocol, data: &[u8]) {
    let Some((&control, bytes)) = data.split_first() else { return };
    let mut rng = Lcg(u32::from(control));
    let max_burst = usize::from(control % 96) + 1;
    let pushed = by_push::<CAP>(protocol, bytes);
    let burst = by_bursts::<CAP>(protocol, bytes, &mut rng, max_burst);
    assert_eq!(pushed, burst, "push and extend delivered different frames");
    // A decoder big enough for every Feetech frame (259 bytes at most): the same with it.
    let pushed = by_push::<300>(protocol, bytes);
    let burst = by_bursts::<300>(protocol, bytes, &mut rng, 300);
    assert_eq!(pushed, burst, "push and extend delivered different frames");
    mixed::<CAP>(protocol, bytes, &mut rng);
}

/// Whether a Dynamixel instruction names a servo id above 252 inside its records, which the
/// parser accepts and the encoder refuses.
fn dxl2_bad_record_id(instruction: &Instruction<'_>) -> bool {
    let bad = |id: u8| id > dxl2::MAX_ID;
    match *instruction {
        Instruction::SyncRead { ids, .. } | Instruction::FastSyncRead { ids, .. } => ids.iter().any(|&id| bad(id)),
        Instruction::SyncWrite { length, data, .. } => {
            sync_write_records(length, data).is_some_and(|mut records| records.any(|r| bad(r.id)))
        }
        Instruction::BulkRead { records } => bulk_read_records(records).is_some_and(|mut r| r.any(|r| bad(r.id))),
        Instruction::BulkWrite { records } => bulk_write_records(records).any(|r| r.is_ok_and(|r| bad(r.id))),
        _ => false,
    }
}

/// Checks that `bytes` carry the real CRC (the encoders always write it, even when fuzzing).
fn assert_dxl2_crc(bytes: &[u8]) {
    let n = bytes.len();
    assert_eq!(dxl2::crc16(&bytes[..n - 2]).to_le_bytes(), [bytes[n - 2], bytes[n - 1]], "{bytes:02x?}");
}

/// The `roundtrip_dxl2` target: byte 0 is a fast-sync-read part length, the rest one frame.
///
/// A frame the parser accepts is encoded and parsed again: the second parse equals the first,
/// and encoding is canonical (encoding the second parse gives the same bytes). The input itself
/// may differ from its encoding: bytes after the frame are ignored, a missing stuffing byte is
/// tolerated, and under `cfg(fuzzing)` the CRC is not checked.
pub fn roundtrip_dxl2(data: &[u8]) {
    let Some((&part_length, frame)) = data.split_first() else { return };
    let mut out = vec![0u8; frame.len() * 2 + 64];

    let mut first = frame.to_vec();
    if let Ok(parsed) = dxl2::parse_instruction(&mut first) {
        match dxl2::encode_instruction(&parsed, &mut out) {
            Ok(n) => {
                let encoded = out[..n].to_vec();
                assert_eq!(dxl2::frame_len(&encoded), FrameLen::Complete(n));
                assert_dxl2_crc(&encoded);
                let mut second = encoded.clone();
                let reparsed = dxl2::parse_instruction(&mut second).expect("an encoded instruction parses");
                assert_eq!(parsed, reparsed);
                let mut again = vec![0u8; n];
                assert_eq!(dxl2::encode_instruction(&reparsed, &mut again), Ok(n));
                assert_eq!(again, encoded, "encoding is not canonical");
            }
            // The parser does not check the ids inside sync and bulk records; the encoder does.
            Err(EncodeError::BadParameter { .. }) if dxl2_bad_record_id(&parsed.instruction) => {}
            Err(EncodeError::TooLong { .. }) if frame.len() > 0xFFFF / 2 => {}
            Err(e) => panic!("parsed instruction {parsed:?} does not encode: {e:?}"),
        }
    }

    let mut first = frame.to_vec();
    if let Ok(status) = dxl2::parse_status(&mut first) {
        match dxl2::encode_status(&status, &mut out) {
            Ok(n) => {
                let encoded = out[..n].to_vec();
                assert_eq!(dxl2::frame_len(&encoded), FrameLen::Complete(n));
                assert_dxl2_crc(&encoded);
                let mut second = encoded.clone();
                let reparsed = dxl2::parse_status(&mut second).expect("an encoded status parses");
                assert_eq!(status, reparsed);
                let mut again = vec![0u8; n];
                assert_eq!(dxl2::encode_status(&reparsed, &mut again), Ok(n));
                assert_eq!(again, encoded, "encoding is not canonical");
                if status.id == BROADCAST {
                    // Not stuffed: the encoding is the input's frame, CRC aside.
                    assert_eq!(&encoded[..n - 2], &frame[..n - 2]);
                }
            }
            Err(EncodeError::TooLong { .. }) if frame.len() > 0xFFFF / 2 => {}
            Err(e) => panic!("parsed status {status:?} does not encode: {e:?}"),
        }
        if status.id == BROADCAST {
            check_fast_sync_parts(&status, usize::from(part_length));
            // Every length that splits the reply into whole parts.
            let carried = status.params.len() + 3;
            for length in (0..=carried.saturating_sub(4)).filter(|l| carried.is_multiple_of(l + 4)) {
                check_fast_sync_parts(&status, length);
            }
        }
    }
}

/// Checks `fast_sync_read_parts` against the layout of the e-manual, and the parts' round trip.
fn check_fast_sync_parts(status: &Status<'_>, length: usize) {
    let stride = length + 4;
    let carried = status.params.len() + 3;
    let Some(parts) = fast_sync_read_parts(status, length) else {
        assert!(!carried.is_multiple_of(stride), "whole parts of {length} bytes refused");
        return;
    };
    assert!(carried.is_multiple_of(stride), "parts of {length} bytes accepted from {carried} bytes");
    let count = carried / stride;
    assert_eq!(parts.len(), count);
    let parts: Vec<FastSyncPart<'_>> = parts.collect();
    assert_eq!(parts.len(), count);
    // The bytes after the instruction: the first error byte, the parameters, then the packet CRC
    // (not in `params`; its two bytes are the last part's CRC, never looked at here).
    let wire: Vec<u8> = std::iter::once(status.error).chain(status.params.iter().copied()).collect();
    for (k, part) in parts.iter().enumerate() {
        let at = k * stride;
        assert_eq!(part.error, wire[at]);
        assert_eq!(part.id, wire[at + 1]);
        assert_eq!(part.data, &wire[at + 2..at + 2 + length]);
    }
    if parts.iter().all(|p| p.id <= dxl2::MAX_ID) {
        let owned: Vec<(u8, u8, &[u8])> = parts.iter().map(|p| (p.error, p.id, p.data)).collect();
        let mut out = vec![0u8; 8 + count * stride + 8];
        let n = dxl2::encode_fast_sync_read_status(&owned, &mut out).expect("parts re-encode");
        let mut frame = out[..n].to_vec();
        assert_dxl2_crc(&frame);
        let reparsed = dxl2::parse_status(&mut frame).expect("an encoded fast sync reply parses");
        assert_eq!(reparsed.id, BROADCAST);
        let again: Vec<FastSyncPart<'_>> =
            fast_sync_read_parts(&reparsed, length).expect("re-encoded parts split").collect();
        assert_eq!(again, parts);
    }
}

/// The `roundtrip_feetech` target: the input is one frame.
///
/// Feetech frames have no stuffing and must be exactly as long as LEN says, so an accepted frame
/// encodes back to the same bytes; only the checksum byte may differ under `cfg(fuzzing)`, where
/// it is not checked.
pub fn roundtrip_feetech(frame: &[u8]) {
    let mut out = [0u8; 300];
    let mut first = frame.to_vec();
    if let Ok(parsed) = feetech::parse_instruction(&mut first) {
        let n = feetech::encode_instruction(&parsed, &mut out)
            .unwrap_or_else(|e| panic!("parsed instruction {parsed:?} does not encode: {e:?}"));
        check_feetech_bytes(frame, &out[..n]);
        let mut second = out[..n].to_vec();
        assert_eq!(feetech::parse_instruction(&mut second), Ok(parsed));
    }
    let mut first = frame.to_vec();
    if let Ok(status) = feetech::parse_status(&mut first) {
        match feetech::encode_status(&status, &mut out) {
            Ok(n) => {
                check_feetech_bytes(frame, &out[..n]);
                let mut second = out[..n].to_vec();
                assert_eq!(feetech::parse_status(&mut second), Ok(status));
            }
            // Documented: a status parses from any id (a broadcast echo), a servo's encodes only.
            Err(EncodeError::BadParameter { .. }) if status.id > feetech::MAX_ID => {}
            Err(e) => panic!("parsed status {status:?} does not encode: {e:?}"),
        }
    }
}

fn check_feetech_bytes(input: &[u8], encoded: &[u8]) {
    let n = encoded.len();
    assert_eq!(n, input.len(), "{input:02x?} re-encoded as {encoded:02x?}");
    assert_eq!(&encoded[..n - 1], &input[..n - 1], "{input:02x?} re-encoded as {encoded:02x?}");
    assert_eq!(encoded[n - 1], feetech::checksum::checksum(&encoded[2..n - 1]));
    if !cfg!(fuzzing) {
        assert_eq!(encoded, input);
    }
}

/// Microseconds the fake clock advances at every reading.
const TICK_US: u64 = 20;
/// Clock readings after which one master call is taken to hang (its timeouts are a few hundred
/// readings at most).
const HANG: u64 = 1_000_000;

/// A clock that advances at every reading, shared with the port (which must not advance it).
#[derive(Clone)]
struct FakeClock {
    now: Rc<Cell<u64>>,
    readings: Rc<Cell<u64>>,
}

impl Clock for FakeClock {
    fn now_us(&mut self) -> u64 {
        let readings = self.readings.get() + 1;
        self.readings.set(readings);
        assert!(readings < HANG, "a master call did not end after {HANG} clock readings");
        self.now.set(self.now.get() + TICK_US);
        self.now.get()
    }
}

/// A serial port: every flushed packet is parsed back as an instruction and releases the next
/// reply segment of the fuzz input, `[len, delay, bytes[len]]`, readable `delay` ticks later.
struct FakePort<'a> {
    protocol: Protocol,
    input: &'a [u8],
    now: Rc<Cell<u64>>,
    /// Bytes released, with the time from which they can be read.
    queue: VecDeque<(u64, u8)>,
    /// Most bytes one `read` returns.
    burst: usize,
    sent: Vec<u8>,
    packets: Rc<RefCell<usize>>,
}

impl embedded_io::ErrorType for FakePort<'_> {
    type Error = embedded_io::ErrorKind;
}

impl embedded_io::Write for FakePort<'_> {
    fn write(&mut self, buf: &[u8]) -> Result<usize, Self::Error> {
        self.sent.extend_from_slice(buf);
        Ok(buf.len())
    }

    fn flush(&mut self) -> Result<(), Self::Error> {
        if self.sent.is_empty() {
            return Ok(());
        }
        let mut packet = core::mem::take(&mut self.sent);
        let mut copy = packet.clone();
        let parsed = self.protocol.parse_instruction(&mut copy);
        assert!(parsed.is_ok(), "the master sent {packet:02x?}, which does not parse: {parsed:?}");
        packet.clear();
        self.sent = packet;
        *self.packets.borrow_mut() += 1;
        if let [len, delay, rest @ ..] = self.input {
            let len = usize::from(*len).min(rest.len());
            let at = self.now.get() + u64::from(*delay) * TICK_US;
            self.queue.extend(rest[..len].iter().map(|&b| (at, b)));
            self.input = &rest[len..];
        } else {
            self.input = &[];
        }
        Ok(())
    }
}

impl embedded_io::ReadReady for FakePort<'_> {
    fn read_ready(&mut self) -> Result<bool, Self::Error> {
        Ok(self.queue.front().is_some_and(|&(at, _)| at <= self.now.get()))
    }
}

impl embedded_io::Read for FakePort<'_> {
    fn read(&mut self, buf: &mut [u8]) -> Result<usize, Self::Error> {
        let now = self.now.get();
        let mut n = 0;
        while n < buf.len().min(self.burst) {
            match self.queue.front() {
                Some(&(at, b)) if at <= now => {
                    buf[n] = b;
                    n += 1;
                    self.queue.pop_front();
                }
                _ => break,
            }
        }
        Ok(n)
    }
}

fn check_report(report: &GroupReport, count: usize, retries: u8) {
    let all = if count >= 32 { u32::MAX } else { (1u32 << count) - 1 };
    assert_eq!(report.count, count);
    assert_eq!(report.answered & !all, 0, "{report:?}");
    assert_eq!(report.failed & !all, 0, "{report:?}");
    assert_eq!(report.alerts & !report.answered, 0, "{report:?}");
    assert!(report.attempts <= retries + 1, "{report:?}");
}

/// The `master_replies` target: byte 0 picks baud rate, retries, echo and the read burst; the rest
/// are reply segments (see [`FakePort`]). Ping, read, sync read, bulk read and fast sync read run
/// on both protocols; every call must end and nothing may panic.
pub fn master_replies(data: &[u8]) {
    let Some((&control, input)) = data.split_first() else { return };
    for protocol in [Protocol::Dxl2, Protocol::Feetech] {
        let now = Rc::new(Cell::new(0));
        let readings = Rc::new(Cell::new(0));
        let packets = Rc::new(RefCell::new(0));
        let port = FakePort {
            protocol,
            input,
            now: now.clone(),
            queue: VecDeque::new(),
            burst: usize::from(control >> 5) * 5 + 1,
            sent: Vec::new(),
            packets: packets.clone(),
        };
        let clock = FakeClock { now, readings: readings.clone() };
        let mut config = BusConfig::new(protocol, [9_600, 57_600, 1_000_000, 4_000_000][usize::from(control & 3)]);
        config.retries = (control >> 2) & 3;
        config.echo = control & 0x10 != 0;
        let retries = config.retries;
        let mut master: Master<_, _, _, 256> = Master::new(port, NoDirectionPin, clock, config);
        let ids = [1u8, 2, 3, 4, 5, 6];
        let mut out = [0u8; 6 * 4];
        let mut call = |name: &str, f: &mut dyn FnMut(&mut Master<FakePort<'_>, NoDirectionPin, FakeClock, 256>)| {
            readings.set(0);
            f(&mut master);
            assert!(readings.get() < HANG, "{name} did not end");
        };
        call("ping", &mut |m| {
            let _ = m.ping(1);
        });
        call("read", &mut |m| {
            let _ = m.read(2, 132, &mut [0u8; 4]);
        });
        call("sync read", &mut |m| {
            if let Ok(report) = m.sync_read(132, 4, &ids, &mut out) {
                check_report(&report, ids.len(), retries);
            }
        });
        let records = [
            BulkReadRecord { id: 1, address: 132, length: 4 },
            BulkReadRecord { id: 2, address: 126, length: 2 },
            BulkReadRecord { id: 3, address: 146, length: 1 },
        ];
        call("bulk read", &mut |m| {
            if let Ok(report) = m.bulk_read(&records, &mut out) {
                check_report(&report, records.len(), 0);
            }
        });
        call("fast sync read", &mut |m| {
            if let Ok(report) = m.fast_sync_read(132, 4, &ids, &mut out) {
                check_report(&report, ids.len(), retries);
            }
        });
        call("sync read of nothing", &mut |m| {
            let _ = m.sync_read(132, 0, &ids, &mut []);
        });
        assert!(*packets.borrow() > 0);
    }
}

/// Checks that a payload, if it decodes as a message of type `M`, re-encodes into a frame that
/// decodes again to the same value. Values are compared by their encoding, since NaN != NaN.
fn link_payload<M>(payload: &[u8])
where
    M: serde::Serialize + serde::de::DeserializeOwned + std::fmt::Debug,
{
    use firmware::link::frame::{decode_payload, encode_message, FrameDecoder, FrameKind, MAX_ENCODED, MAX_FRAME};
    let Ok(message) = decode_payload::<M>(payload) else { return };
    let mut wire = [0u8; MAX_FRAME];
    // Every message type fits a frame by construction, whatever its field values.
    let n = encode_message(3, FrameKind::Reply, &message, &mut wire).unwrap_or_else(|e| panic!("{message:?}: {e}"));
    let mut decoder = FrameDecoder::<MAX_ENCODED>::new();
    let mut again = None;
    for &b in &wire[..n] {
        if let Some(frame) = decoder.push(b) {
            let frame = frame.unwrap_or_else(|e| panic!("{message:?}: {e}"));
            assert_eq!((frame.seq, frame.kind), (3, FrameKind::Reply));
            again = Some(decode_payload::<M>(frame.payload).unwrap_or_else(|e| panic!("{message:?}: {e}")));
        }
    }
    let again = again.expect("the frame is delivered at its delimiter");
    let mut wire2 = [0u8; MAX_FRAME];
    let n2 = encode_message(3, FrameKind::Reply, &again, &mut wire2).unwrap();
    assert_eq!(&wire[..n], &wire2[..n2], "{message:?} vs {again:?}");
}

/// Arbitrary bytes into the host link's frame decoder (full size and a small one), and every
/// delivered payload, and the input itself, through the message decoders: no panic, and decoded
/// messages survive a re-encode. Host messages are also validated (which must not panic either).
pub fn link_frames(data: &[u8]) {
    use firmware::link::frame::{FrameDecoder, MAX_ENCODED};
    use firmware::link::message::{FirmwareMessage, HostMessage};
    let mut full = FrameDecoder::<MAX_ENCODED>::new();
    let mut small = FrameDecoder::<16>::new();
    for &b in data {
        if let Some(Ok(frame)) = full.push(b) {
            assert!(frame.payload.len() <= firmware::link::frame::MAX_PAYLOAD);
            let payload = frame.payload.to_vec();
            link_payload::<HostMessage>(&payload);
            link_payload::<FirmwareMessage>(&payload);
        }
        let _ = small.push(b);
    }
    if let Ok(m) = firmware::link::frame::decode_payload::<HostMessage>(data) {
        let _ = m.validate();
    }
    link_payload::<HostMessage>(data);
    link_payload::<FirmwareMessage>(data);
}

/// The `firmware_app` target: the whole firmware application of the built-in arm. The input is
/// split in two: link bytes from the host (fed in chunks, a control tick after each) and reply
/// segments for the servo bus (see [`FakePort`]). Every request must be answered without a panic,
/// every tick must end, and while the torque is on the setpoint must stay inside the joint limits
/// whatever was asked and whatever the servos reported.
pub fn firmware_app(data: &[u8]) {
    use firmware::app::{Board, Firmware};
    use firmware::bus::table::STS3215;
    use firmware::controller::Config;
    let Some((&split, rest)) = data.split_first() else { return };
    let at = (usize::from(split) * rest.len()) / 255;
    let (link, replies) = rest.split_at(at.min(rest.len()));
    let now = Rc::new(Cell::new(0));
    let readings = Rc::new(Cell::new(0));
    let port = FakePort {
        protocol: Protocol::Feetech,
        input: replies,
        now: now.clone(),
        queue: VecDeque::new(),
        burst: 8,
        sent: Vec::new(),
        packets: Rc::new(RefCell::new(0)),
    };
    let clock = FakeClock { now: now.clone(), readings: readings.clone() };
    let bus = BusConfig::new(Protocol::Feetech, 1_000_000);
    let mut master: Master<_, _, _, 256> = Master::new(port, NoDirectionPin, clock, bus);
    let board = Board { bus, model: &STS3215, control: Config::default(), max_bus_baud: u32::MAX };
    let mut app =
        Firmware::<{ firmware::builtin::JOINTS }, 32>::new(board, Some(&firmware::builtin::SO101)).expect("the board is valid");
    let mut tx = Vec::new();
    for chunk in link.chunks(24) {
        let _ = app.receive(chunk, now.get(), &mut tx);
        readings.set(0);
        let _ = app.tick(&mut master, now.get(), &mut tx);
        assert!(readings.get() < HANG, "a tick did not end");
        now.set(now.get() + 10_000);
        let c = app.controller().expect("the built-in arm runs");
        if !c.torque() {
            // Limp, the setpoint follows whatever the servos report.
            continue;
        }
        let limits = c.limits();
        for j in 0..firmware::builtin::JOINTS {
            let p = c.setpoint().position[j];
            assert!(p >= limits.lower[j] && p <= limits.upper[j], "joint {j}: setpoint {p} outside the limits");
        }
    }
    // Every byte written back is a whole frame of at most MAX_FRAME bytes.
    for frame in tx.split(|&b| b == 0).filter(|f| !f.is_empty()) {
        assert!(frame.len() < firmware::link::frame::MAX_FRAME, "reply frame of {} bytes", frame.len());
    }
}
