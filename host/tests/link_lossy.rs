//! The link client against a toy firmware over a lossy in-memory line: every keyframe applied
//! exactly once and in order, the queue never overrun, and the losses really cost retransmissions.
//!
//! The toy firmware is the real `firmware::link` session and frame decoder in front of a plain
//! keyframe queue of capacity 16 that plays one keyframe per read timeout of the host; the
//! controller proper is not needed to test the link.

use std::collections::VecDeque;
use std::io::{self, Read, Write};

use armctl::link::client::{LinkClient, LinkConfig};
use firmware::link::frame::{FrameDecoder, MAX_ENCODED, MAX_FRAME};
use firmware::link::message::{
    ErrorCounters, FirmwareMessage, HostMessage, IkStatus, Info, JointKeyframe, LoopTiming, NakReason, RunState,
    Status, PROTOCOL_VERSION,
};
use firmware::link::session::Session;

const CAPACITY: usize = 16;
const KEYFRAMES: usize = 500;

/// SplitMix64: a deterministic generator, so the test sees the same losses every run.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// True with probability `p`.
    fn chance(&mut self, p: f64) -> bool {
        (self.next() >> 11) as f64 / (1u64 << 53) as f64 <= p
    }
}

/// One direction of the line: drops bytes and flips bits.
struct Lossy {
    rng: Rng,
    drop: f64,
    flip_per_bit: f64,
    dropped: u32,
    flipped: u32,
}

impl Lossy {
    fn new(seed: u64) -> Self {
        Self { rng: Rng(seed), drop: 0.01, flip_per_bit: 0.001, dropped: 0, flipped: 0 }
    }

    fn pass(&mut self, mut byte: u8) -> Option<u8> {
        if self.rng.chance(self.drop) {
            self.dropped += 1;
            return None;
        }
        for bit in 0..8 {
            if self.rng.chance(self.flip_per_bit) {
                byte ^= 1 << bit;
                self.flipped += 1;
            }
        }
        Some(byte)
    }
}

/// The application behind the session: a keyframe queue.
#[derive(Default)]
struct Toy {
    queue: VecDeque<JointKeyframe>,
    started: bool,
    /// Times of the keyframes accepted, in order.
    applied: Vec<f32>,
    /// Times of the keyframes played, in order.
    played: Vec<f32>,
    /// Pushes that found the queue full.
    overruns: u32,
    max_queued: usize,
    ticks: u64,
}

impl Toy {
    fn free(&self) -> u16 {
        (CAPACITY - self.queue.len()) as u16
    }

    fn status(&self) -> Status {
        Status {
            time: self.ticks as f32 * 0.01,
            play_time: 0.0,
            state: if self.started { RunState::Moving } else { RunState::Idle },
            measured: Default::default(),
            setpoints: Default::default(),
            queued: self.queue.len() as u16,
            free_slots: self.free(),
            ik: IkStatus { converged: true, iterations: 0, position_error: 0.0, orientation_error: 0.0 },
            timing: LoopTiming { mean_us: 0, max_us: 0, overruns: 0 },
            errors: ErrorCounters::default(),
            lost_servos: 0,
            gripper: None,
            last_move: None,
            largest_pass: 0.0,
            collision_check: firmware::link::message::CollisionCheck::NoGeometry,
            last_collision: None,
        }
    }

    fn apply(&mut self, message: &HostMessage) -> FirmwareMessage {
        match message {
            HostMessage::Hello { .. } => FirmwareMessage::Info(Info {
                protocol_version: PROTOCOL_VERSION,
                firmware_version: [0, 1, 0],
                joints: 6,
                arm_name: "toy".try_into().unwrap(),
                queue_capacity: CAPACITY as u16,
                control_rate_hz: 100,
                arm_digest: 0,
            }),
            HostMessage::GetStatus => FirmwareMessage::Status(self.status()),
            HostMessage::Start => {
                self.started = true;
                FirmwareMessage::Ack { free_slots: self.free() }
            }
            HostMessage::PushKeyframe(k) => {
                if self.queue.len() >= CAPACITY {
                    self.overruns += 1;
                    return FirmwareMessage::Nak { reason: NakReason::QueueFull };
                }
                self.queue.push_back(k.clone());
                self.applied.push(k.time);
                self.max_queued = self.max_queued.max(self.queue.len());
                FirmwareMessage::Ack { free_slots: self.free() }
            }
            _ => FirmwareMessage::Ack { free_slots: self.free() },
        }
    }

    /// One control period: play a keyframe.
    fn tick(&mut self) {
        self.ticks += 1;
        if self.started {
            if let Some(k) = self.queue.pop_front() {
                self.played.push(k.time);
            }
        }
    }
}

struct ToyFirmware {
    decoder: FrameDecoder<MAX_ENCODED>,
    session: Session,
    toy: Toy,
}

impl ToyFirmware {
    /// Takes one byte from the line; returns the reply frame it completes, if any.
    fn receive(&mut self, byte: u8, out: &mut Vec<u8>) {
        let mut buf = [0u8; MAX_FRAME];
        let toy = &mut self.toy;
        let n = match self.decoder.push(byte) {
            None => return,
            Some(Ok(frame)) => self.session.handle(&frame, &mut buf, |m| toy.apply(m)),
            Some(Err(e)) => self.session.nak_broken(&e, &mut buf),
        };
        out.extend_from_slice(&buf[..n.expect("replies fit a frame")]);
    }
}

/// The host's end of the line: writes go through the lossy line to the firmware at once, its
/// replies come back through the other lossy line; a read with nothing to read is a timeout, during
/// which the firmware runs a control period (and every fifth one sends telemetry).
struct Line {
    fw: ToyFirmware,
    up: Lossy,
    down: Lossy,
    inbox: VecDeque<u8>,
}

impl Write for Line {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        let mut replies = Vec::new();
        for &b in buf {
            if let Some(b) = self.up.pass(b) {
                self.fw.receive(b, &mut replies);
            }
        }
        self.send_down(&replies);
        Ok(buf.len())
    }

    fn flush(&mut self) -> io::Result<()> {
        Ok(())
    }
}

impl Line {
    fn send_down(&mut self, bytes: &[u8]) {
        for &b in bytes {
            if let Some(b) = self.down.pass(b) {
                self.inbox.push_back(b);
            }
        }
    }
}

impl Read for Line {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        if self.inbox.is_empty() {
            self.fw.toy.tick();
            if self.fw.toy.ticks.is_multiple_of(5) {
                let mut frame = [0u8; MAX_FRAME];
                let status = FirmwareMessage::Telemetry(self.fw.toy.status());
                let n = self.fw.session.event(&status, &mut frame).unwrap();
                self.send_down(&frame[..n]);
            }
            return Err(io::ErrorKind::TimedOut.into());
        }
        let n = buf.len().min(self.inbox.len());
        for (slot, b) in buf.iter_mut().zip(self.inbox.drain(..n)) {
            *slot = b;
        }
        Ok(n)
    }
}

#[test]
fn keyframes_cross_a_lossy_line_exactly_once_in_order() {
    let line = Line {
        fw: ToyFirmware { decoder: FrameDecoder::new(), session: Session::new(), toy: Toy::default() },
        up: Lossy::new(0x5EED_0001),
        down: Lossy::new(0x5EED_0002),
        inbox: VecDeque::new(),
    };
    // A line this bad fails about half the exchanges of a 62-byte frame and its reply, so a run of
    // 12 failures (the default's limit) is likely among a thousand requests; 40 attempts make
    // giving up negligible (0.55^40 ~ 4e-11) while the backoff stays capped.
    let config = LinkConfig { max_attempts: 40, ..LinkConfig::default() };
    let mut client = LinkClient::new(line, config);
    let info = client.hello().unwrap();
    assert_eq!(info.queue_capacity as usize, CAPACITY);
    client.request(&HostMessage::Start).unwrap();

    let times: Vec<f32> = (0..KEYFRAMES).map(|i| i as f32 * 0.01).collect();
    for (i, &time) in times.iter().enumerate() {
        let positions = (0..6).map(|j| (i * 6 + j) as f32 * 1e-3).collect();
        let push = HostMessage::PushKeyframe(JointKeyframe { time, positions, velocities: None, gripper: None });
        client.push(&push).unwrap_or_else(|e| panic!("keyframe {i}: {e}"));
    }
    // Play out what is queued.
    for _ in 0..CAPACITY {
        client.transport().fw.toy.tick();
    }

    let stats = client.stats();
    let line = client.transport();
    let toy = &line.fw.toy;
    let session = line.fw.session.stats();
    println!(
        "link stats {stats:?}\nsession {session:?}\nup: {} bytes dropped, {} bits flipped; down: {} dropped, {} flipped",
        line.up.dropped, line.up.flipped, line.down.dropped, line.down.flipped
    );
    assert_eq!(toy.applied, times, "every keyframe applied exactly once, in order");
    assert_eq!(toy.played, times);
    assert_eq!(toy.overruns, 0, "the host overran the queue");
    assert!(toy.max_queued <= CAPACITY);
    assert_eq!(toy.max_queued, CAPACITY, "flow control let the queue fill");
    assert!(stats.retransmissions > 0 && stats.nak_retransmissions > 0, "{stats:?}");
    assert!(session.repeats > 0, "some acks were lost and the repeat was not applied again: {session:?}");
    assert!(line.up.dropped > 0 && line.up.flipped > 0 && line.down.dropped > 0 && line.down.flipped > 0);
    assert!(stats.full_polls > 0);
}
