//! Host link framing: COBS and CRC against published vectors, every message through a frame and
//! back, and broken frames refused with the right reason.

use firmware::link::cobs::{self, CobsError};
use firmware::link::crc::crc16;
use firmware::link::frame::{
    decode_payload, encode_frame, encode_message, parse_raw, FrameDecoder, FrameError, FrameKind, MAX_ENCODED,
    MAX_FRAME, MAX_PAYLOAD, OVERHEAD,
};
use firmware::link::message::*;
use heapless::{String, Vec};
use proptest::prelude::*;

/// Wikipedia's table of COBS encoding examples ("Consistent Overhead Byte Stuffing"), with the
/// delimiter. The long ones are built from ranges.
fn wikipedia_examples() -> std::vec::Vec<(std::vec::Vec<u8>, std::vec::Vec<u8>)> {
    let r = |a: u8, b: u8| (a..=b).collect::<std::vec::Vec<u8>>();
    let cat = |parts: &[&[u8]]| parts.concat();
    vec![
        (vec![0x00], vec![0x01, 0x01, 0x00]),
        (vec![0x00, 0x00], vec![0x01, 0x01, 0x01, 0x00]),
        (vec![0x00, 0x11, 0x00], vec![0x01, 0x02, 0x11, 0x01, 0x00]),
        (vec![0x11, 0x22, 0x00, 0x33], vec![0x03, 0x11, 0x22, 0x02, 0x33, 0x00]),
        (vec![0x11, 0x22, 0x33, 0x44], vec![0x05, 0x11, 0x22, 0x33, 0x44, 0x00]),
        (vec![0x11, 0x00, 0x00, 0x00], vec![0x02, 0x11, 0x01, 0x01, 0x01, 0x00]),
        (r(0x01, 0xFE), cat(&[&[0xFF], &r(0x01, 0xFE), &[0x00]])),
        (cat(&[&[0x00], &r(0x01, 0xFE)]), cat(&[&[0x01, 0xFF], &r(0x01, 0xFE), &[0x00]])),
        (r(0x01, 0xFF), cat(&[&[0xFF], &r(0x01, 0xFE), &[0x02, 0xFF, 0x00]])),
        (cat(&[&r(0x02, 0xFF), &[0x00]]), cat(&[&[0xFF], &r(0x02, 0xFF), &[0x01, 0x01, 0x00]])),
        (cat(&[&r(0x03, 0xFF), &[0x00, 0x01]]), cat(&[&[0xFE], &r(0x03, 0xFF), &[0x02, 0x01, 0x00]])),
    ]
}

#[test]
fn cobs_wikipedia_examples_byte_for_byte() {
    for (i, (plain, wire)) in wikipedia_examples().into_iter().enumerate() {
        let mut out = [0xAAu8; 300];
        let n = cobs::encode(&plain, &mut out).unwrap();
        assert_eq!(&out[..n], &wire[..wire.len() - 1], "example {}", i + 1);
        assert!(n <= cobs::max_encoded_len(plain.len()));
        let mut back = [0u8; 300];
        let m = cobs::decode(&wire[..wire.len() - 1], &mut back).unwrap();
        assert_eq!(&back[..m], &plain[..], "example {}", i + 1);
    }
}

#[test]
fn cobs_errors_carry_data() {
    let mut out = [0u8; 3];
    assert_eq!(cobs::encode(&[1, 2, 3, 4], &mut out), Err(CobsError::BufferTooSmall { required: 5, available: 3 }));
    let mut back = [0u8; 16];
    assert_eq!(cobs::decode(&[0x03, 0x11, 0x00], &mut back), Err(CobsError::ZeroByte { index: 2 }));
    assert_eq!(cobs::decode(&[0x05, 0x11, 0x22], &mut back), Err(CobsError::Truncated { required: 5, available: 3 }));
}

#[test]
fn crc16_ccitt_false_check_value() {
    assert_eq!(crc16(b"123456789"), 0x29B1);
}

/// An exact frame: seq 7, request, payload `Start` (postcard variant index 10).
#[test]
fn frame_bytes() {
    let mut out = [0u8; MAX_FRAME];
    let n = encode_message(7, FrameKind::Request, &HostMessage::Start, &mut out).unwrap();
    let crc = crc16(&[0x07, 0x01, 0x0A]).to_be_bytes();
    assert!(crc.iter().all(|&b| b != 0), "the vector below assumes a CRC without zero bytes");
    assert_eq!(&out[..n], &[0x06, 0x07, 0x01, 0x0A, crc[0], crc[1], 0x00]);
    let mut decoder = FrameDecoder::<MAX_ENCODED>::new();
    let frames: std::vec::Vec<_> = out[..n]
        .iter()
        .filter_map(|&b| decoder.push(b).map(|r| r.map(|f| (f.seq, f.kind, f.payload.to_vec()))))
        .collect();
    assert_eq!(frames, vec![Ok((7, FrameKind::Request, vec![0x0A]))]);
}

fn joints(n: usize, x: f32) -> Joints {
    (0..n).map(|i| x + i as f32 * 0.1).collect()
}

fn name(s: &str) -> String<MAX_NAME> {
    String::try_from(s).unwrap()
}

fn status(n: usize) -> Status {
    Status {
        time: 12.5,
        play_time: 3.25,
        state: RunState::Moving,
        measured: joints(n, 0.5),
        setpoints: joints(n, 0.51),
        queued: 3,
        free_slots: 13,
        ik: IkStatus { converged: true, iterations: 7, position_error: 1e-5, orientation_error: 2e-4 },
        timing: LoopTiming { mean_us: 180, max_us: 420, overruns: 1 },
        errors: ErrorCounters {
            link_corrupt: 2,
            link_oversized: 0,
            naks: 1,
            bus_timeouts: u32::MAX,
            bus_errors: 5,
            underruns: 0,
            watchdog_trips: u32::MAX,
            ik_failures: u32::MAX,
            line_fallbacks: u32::MAX,
            link_dropped: u32::MAX,
            link_overruns: u32::MAX,
        },
        lost_servos: u32::MAX,
        gripper: Some(GripperStatus { opening: 41.5, goal: 0.0, load: -35.2, holding: true }),
        // The largest outcome: a line given up, with both lengths (protocol 7).
        last_move: Some(MoveOutcome { path: PathTaken::LineThenJoints, blocked_at: Some(0.075), line_length: 0.145 }),
        // 3 degrees past the last keyframe (protocol 8).
        largest_pass: 0.05236,
        // The largest collision report (protocol 9): the count at its longest varint.
        collision_check: CollisionCheck::On { bodies: MAX_BODIES as u8, obstacles: MAX_OBSTACLES as u8 },
        last_collision: Some(CollisionStop {
            body: 23,
            other: CollisionPart::Obstacle(7),
            distance: -0.0032,
            count: u32::MAX,
        }),
    }
}

fn body_config() -> BodyConfig {
    BodyConfig { frame: Some(5), a: [0.0; 3], b: [0.0, 0.0, 0.1], radius: 0.02 }
}

fn joint_config() -> JointConfig {
    JointConfig {
        kind: JointType::Revolute,
        origin_xyz: [0.0, 0.0, 0.1],
        origin_rpy: [0.0, 1.5707964, 0.0],
        axis: [0.0, 0.0, 1.0],
        lower: -2.0,
        upper: 2.0,
        max_velocity: 3.0,
        max_acceleration: 10.0,
        servo: ServoConfig {
            id: 3,
            ticks_per_revolution: i32::MAX as u32,
            zero: i32::MIN,
            reversed: true,
            min_ticks: i32::MIN,
            max_ticks: i32::MAX,
            zero_half: true,
            truncate: true,
        },
    }
}

/// Every host message variant, at its largest where it has a size.
fn host_messages() -> std::vec::Vec<HostMessage> {
    let target = CartesianTarget { position: [0.2, -0.1, 0.3], orientation: Some([1.0, 0.0, 0.0, 0.0]) };
    vec![
        HostMessage::Hello { protocol_version: PROTOCOL_VERSION },
        HostMessage::ConfigureBegin {
            name: name("so101-follower-left-arm!"),
            joints: 6,
            tool_xyz: [0.0, 0.0, 0.05],
            tool_rpy: [0.1, 0.2, 0.3],
            model: u16::MAX,
        },
        HostMessage::ConfigureJoint { index: 5, joint: joint_config() },
        HostMessage::ConfigureCommit,
        HostMessage::UseBuiltinArm,
        HostMessage::Torque { on: true },
        HostMessage::MoveTo { path: firmware::link::message::MovePath::Auto, target, timing: Timing::Duration(2.0) },
        HostMessage::MoveTo {
            path: firmware::link::message::MovePath::Auto,
            target: CartesianTarget { orientation: None, ..target },
            timing: Timing::MaxSpeed(0.1),
        },
        HostMessage::MoveJoints { positions: joints(MAX_JOINTS, -1.0), timing: Timing::MaxSpeed(1.0) },
        HostMessage::PushKeyframe(JointKeyframe {
            time: 1.25,
            positions: joints(MAX_JOINTS, 0.0),
            velocities: Some(joints(MAX_JOINTS, -0.3)),
            gripper: Some(55.5),
        }),
        HostMessage::ConfigureGripper(GripperConfig { id: 6, closed: 1934, open: 3186, effort: 50.0, speed: 100.0 }),
        HostMessage::Gripper { opening: 100.0, effort: Some(30.0) },
        HostMessage::Gripper { opening: 0.0, effort: None },
        HostMessage::ConfigureBus { protocol: firmware::link::message::BusProtocol::Dynamixel2, baud: 4_500_000 },
        HostMessage::ConfigureDigest { digest: 0xb24a_4ff4 },
        HostMessage::ConfigureCollision { margin: 0.01, check: false },
        HostMessage::ConfigureBody { index: 23, body: body_config() },
        HostMessage::ConfigureObstacle {
            index: 7,
            shape: ObstacleShape::Box { centre: [0.3, 0.0, 0.1], rotation: [1.0, 0.0, 0.0, 0.0], half: [0.1; 3] },
        },
        HostMessage::ConfigureObstacle {
            index: 0,
            shape: ObstacleShape::Capsule { a: [0.3, 0.0, 0.1], b: [0.3, 0.0, 0.3], radius: 0.05 },
        },
        HostMessage::ConfigureObstacle {
            index: 1,
            shape: ObstacleShape::HalfSpace { normal: [0.0, 0.0, 1.0], offset: 0.0 },
        },
        HostMessage::ConfigureAllowed { body: 0, other: CollisionPart::Obstacle(0) },
        HostMessage::SetGravity { joint: 1, mass: 0.15, com: [0.0, 0.1, 0.02], compliance: 0.11 },
        HostMessage::PushKeyframe(JointKeyframe {
            time: 0.0,
            positions: joints(1, 0.0),
            velocities: None,
            gripper: None,
        }),
        HostMessage::PushCartesianKeyframe(CartesianKeyframe { time: 3.0, target, gripper: None }),
        HostMessage::Start,
        HostMessage::Pause,
        HostMessage::Stop,
        HostMessage::EStop { mode: EStopMode::Hold },
        HostMessage::EStop { mode: EStopMode::TorqueOff },
        HostMessage::GetStatus,
        HostMessage::Ping,
        HostMessage::SetTelemetry { rate_hz: 50 },
    ]
}

/// Every firmware message variant, at its largest where it has a size.
fn firmware_messages() -> std::vec::Vec<FirmwareMessage> {
    let bad = ValueError { field: Field::Orientation, problem: Problem::NotUnit };
    let mut out = vec![FirmwareMessage::Ack { free_slots: 16 }];
    for reason in [
        NakReason::Corrupt,
        NakReason::Oversized,
        NakReason::UnknownMessage,
        NakReason::BadValue(bad),
        NakReason::QueueFull,
        NakReason::NotReady,
        NakReason::Unreachable,
        NakReason::Collision { body: 23, other: CollisionPart::Body(22), distance: -0.5 },
        NakReason::BadCollision,
    ] {
        out.push(FirmwareMessage::Nak { reason });
    }
    out.push(FirmwareMessage::Info(Info {
        protocol_version: PROTOCOL_VERSION,
        firmware_version: [0, 1, 0],
        joints: 6,
        arm_name: name("abcdefghijklmnopqrstuvwx"),
        queue_capacity: 16,
        control_rate_hz: 200,
        arm_digest: u32::MAX,
    }));
    out.push(FirmwareMessage::Status(status(MAX_JOINTS)));
    out.push(FirmwareMessage::Telemetry(status(6)));
    out
}

fn round_trip<M>(seq: u8, kind: FrameKind, message: &M) -> usize
where
    M: serde::Serialize + serde::de::DeserializeOwned + PartialEq + std::fmt::Debug,
{
    let mut wire = [0u8; MAX_FRAME];
    let n = encode_message(seq, kind, message, &mut wire).unwrap();
    assert!(n <= MAX_FRAME);
    assert_eq!(wire[..n - 1].iter().position(|&b| b == 0), None, "no 0x00 inside a frame");
    let mut decoder = FrameDecoder::<MAX_ENCODED>::new();
    let mut got = None;
    for &b in &wire[..n] {
        if let Some(frame) = decoder.push(b) {
            let frame = frame.unwrap();
            assert_eq!((frame.seq, frame.kind), (seq, kind));
            got = Some(decode_payload::<M>(frame.payload).unwrap());
        }
    }
    assert_eq!(got.as_ref(), Some(message));
    n
}

#[test]
fn every_message_round_trips_within_a_frame() {
    for (i, m) in host_messages().iter().enumerate() {
        assert_eq!(m.validate(), Ok(()), "{m:?}");
        round_trip(i as u8, FrameKind::Request, m);
    }
    for (i, m) in firmware_messages().iter().enumerate() {
        round_trip(200 + i as u8, FrameKind::Reply, m);
        round_trip(i as u8, FrameKind::Event, m);
    }
}

/// The largest status (8 joints, the gripper, every counter at u32::MAX, the link's receive
/// losses of protocol 6 and the last move's outcome of protocol 7 included) fits a frame, and the
/// margin is printed.
#[test]
fn the_largest_status_fits_a_frame() {
    let largest = FirmwareMessage::Telemetry(status(MAX_JOINTS));
    let mut buf = [0u8; MAX_PAYLOAD];
    let payload = postcard::to_slice(&largest, &mut buf).unwrap().len();
    let wire = round_trip(255, FrameKind::Event, &largest);
    assert_eq!(wire, payload + OVERHEAD);
    assert!(wire <= MAX_FRAME);
    let mut five = status(5);
    five.errors = ErrorCounters::default();
    let typical = round_trip(1, FrameKind::Reply, &FirmwareMessage::Status(five));
    println!("largest status: payload {payload} of {MAX_PAYLOAD} bytes, frame {wire} of {MAX_FRAME}; 5 joints, counters 0: frame {typical}");
}

/// The last move's outcome, byte for byte: postcard writes an `Option` as a 0 or 1 byte before
/// its value, an enum as its variant's index (a varint: one byte here), an f32 as its four
/// little-endian bytes. Each way a move can go, at the end of a status, and decoded back.
#[test]
fn the_last_move_bytes() {
    // 0.145 is E1 7A 14 3E as an f32, 0.075 9A 99 99 3D, 0.5 00 00 00 3F.
    let cases: [(Option<MoveOutcome>, &[u8]); 5] = [
        (None, &[0x00]),
        (
            Some(MoveOutcome { path: PathTaken::Line, blocked_at: None, line_length: 0.145 }),
            &[0x01, 0x00, 0x00, 0xE1, 0x7A, 0x14, 0x3E],
        ),
        (
            Some(MoveOutcome { path: PathTaken::LineThenJoints, blocked_at: Some(0.075), line_length: 0.145 }),
            &[0x01, 0x01, 0x01, 0x9A, 0x99, 0x99, 0x3D, 0xE1, 0x7A, 0x14, 0x3E],
        ),
        (
            Some(MoveOutcome { path: PathTaken::Joints, blocked_at: None, line_length: 0.0 }),
            &[0x01, 0x02, 0x00, 0x00, 0x00, 0x00, 0x00],
        ),
        (
            Some(MoveOutcome { path: PathTaken::LineStopped, blocked_at: Some(0.0), line_length: 0.5 }),
            &[0x01, 0x03, 0x01, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x3F],
        ),
    ];
    let mut without = status(5);
    without.last_move = None;
    // Protocol 9's collision fields at their shortest (two bytes) after protocol 8's pass.
    without.collision_check = CollisionCheck::NoGeometry;
    without.last_collision = None;
    let mut buf = [0u8; MAX_PAYLOAD];
    let before = postcard::to_slice(&FirmwareMessage::Status(without.clone()), &mut buf).unwrap().to_vec();
    for (outcome, bytes) in cases {
        let mut out = [0u8; 16];
        assert_eq!(postcard::to_slice(&outcome, &mut out).unwrap(), bytes, "{outcome:?}");
        assert_eq!(postcard::from_bytes::<Option<MoveOutcome>>(bytes), Ok(outcome));
        // The field follows those of a status as protocol 6 had it (protocol 8's four bytes of
        // `largest_pass` come after it).
        let status = Status { last_move: outcome, ..without.clone() };
        let encoded = postcard::to_slice(&FirmwareMessage::Status(status.clone()), &mut buf).unwrap().to_vec();
        let (head, pass) = (&before[..before.len() - 7], &before[before.len() - 6..]);
        assert_eq!(encoded, [head, bytes, pass].concat(), "{outcome:?}");
        assert_eq!(round_trip(3, FrameKind::Reply, &FirmwareMessage::Status(status)), encoded.len() + OVERHEAD);
    }
}

/// The largest pass (protocol 8) is the status's last field: an f32's four little-endian bytes
/// after everything protocol 7 had.
#[test]
fn the_largest_pass_bytes() {
    let mut buf = [0u8; MAX_PAYLOAD];
    let status =
        Status { largest_pass: 0.5, collision_check: CollisionCheck::NoGeometry, last_collision: None, ..status(5) };
    let encoded = postcard::to_slice(&FirmwareMessage::Status(status.clone()), &mut buf).unwrap().to_vec();
    // Then protocol 9's two collision fields, at their shortest.
    assert_eq!(encoded[encoded.len() - 6..], [0x00, 0x00, 0x00, 0x3F, 0x00, 0x00]);
    let zero = Status { largest_pass: 0.0, ..status.clone() };
    let zero = postcard::to_slice(&FirmwareMessage::Status(zero), &mut buf).unwrap().to_vec();
    assert_eq!(zero[..zero.len() - 6], encoded[..encoded.len() - 6]);
    assert_eq!(round_trip(3, FrameKind::Reply, &FirmwareMessage::Status(status)), encoded.len() + OVERHEAD);
}

/// The collision messages of protocol 9, byte for byte: each a new variant index after the
/// others (ConfigureCollision is 21, ConfigureBody 22, ConfigureObstacle 23, ConfigureAllowed 24),
/// then its fields in order: f32s as four little-endian bytes, `bool` and `u8` as one byte, an
/// `Option` as 0 or 1 before its value, an enum as its variant's index.
#[test]
fn the_collision_configure_bytes() {
    // 0.01 is 0A D7 23 3C; 0.1 CD CC CC 3D; 0.02 0A D7 A3 3C; 1.0 00 00 80 3F; 0.25 00 00 80 3E.
    let cases: [(HostMessage, &[u8]); 6] = [
        (HostMessage::ConfigureCollision { margin: 0.01, check: true }, &[21, 0x0A, 0xD7, 0x23, 0x3C, 0x01]),
        (HostMessage::ConfigureCollision { margin: 0.0, check: false }, &[21, 0, 0, 0, 0, 0x00]),
        (
            HostMessage::ConfigureBody { index: 2, body: body_config() },
            &[
                22, 2, 1, 5, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0xCD, 0xCC, 0xCC, 0x3D, 0x0A,
                0xD7, 0xA3, 0x3C,
            ],
        ),
        (
            HostMessage::ConfigureObstacle {
                index: 1,
                shape: ObstacleShape::HalfSpace { normal: [0.0, 0.0, 1.0], offset: 0.25 },
            },
            &[23, 1, 2, 0, 0, 0, 0, 0, 0, 0, 0, 0x00, 0x00, 0x80, 0x3F, 0x00, 0x00, 0x80, 0x3E],
        ),
        (HostMessage::ConfigureAllowed { body: 0, other: CollisionPart::Obstacle(1) }, &[24, 0, 1, 1]),
        (HostMessage::ConfigureAllowed { body: 3, other: CollisionPart::Body(4) }, &[24, 3, 0, 4]),
    ];
    for (message, bytes) in cases {
        let mut out = [0u8; 64];
        assert_eq!(postcard::to_slice(&message, &mut out).unwrap(), bytes, "{message:?}");
        assert_eq!(postcard::from_bytes::<HostMessage>(bytes), Ok(message.clone()));
        assert_eq!(message.validate(), Ok(()), "{message:?}");
        round_trip(9, FrameKind::Request, &message);
    }
    // A box: its quaternion between the centre and the half sizes.
    let boxed = HostMessage::ConfigureObstacle {
        index: 0,
        shape: ObstacleShape::Box { centre: [0.0; 3], rotation: [1.0, 0.0, 0.0, 0.0], half: [0.25; 3] },
    };
    let mut out = [0u8; 64];
    let encoded = postcard::to_slice(&boxed, &mut out).unwrap();
    assert_eq!(encoded.len(), 3 + 4 * 10);
    assert_eq!(encoded[..3], [23, 0, 1]);
    assert_eq!(encoded[15..19], [0x00, 0x00, 0x80, 0x3F]);
    assert_eq!(encoded[31..], [0x00, 0x00, 0x80, 0x3E, 0x00, 0x00, 0x80, 0x3E, 0x00, 0x00, 0x80, 0x3E]);
}

/// Protocol 10's gravity message, byte for byte: variant index 25, the joint as one byte, then
/// the mass, the centre's three coordinates and the compliance as little-endian f32s; and each of
/// its values refused on its own.
#[test]
fn the_gravity_bytes() {
    // 0.5 is 00 00 00 3F; 0.25 00 00 80 3E; -1.0 00 00 80 BF; 0.125 00 00 00 3E.
    let message = HostMessage::SetGravity { joint: 2, mass: 0.5, com: [0.25, 0.0, -1.0], compliance: 0.125 };
    let bytes: &[u8] = &[
        25, 2, 0x00, 0x00, 0x00, 0x3F, 0x00, 0x00, 0x80, 0x3E, 0, 0, 0, 0, 0x00, 0x00, 0x80, 0xBF, 0x00, 0x00, 0x00,
        0x3E,
    ];
    let mut out = [0u8; 64];
    assert_eq!(postcard::to_slice(&message, &mut out).unwrap(), bytes);
    assert_eq!(postcard::from_bytes::<HostMessage>(bytes), Ok(message.clone()));
    assert_eq!(message.validate(), Ok(()));
    round_trip(10, FrameKind::Request, &message);
    let err = |field, problem| Err(ValueError { field, problem });
    let with = |joint, mass, com, compliance| HostMessage::SetGravity { joint, mass, com, compliance };
    assert_eq!(with(8, 0.5, [0.0; 3], 0.1).validate(), err(Field::JointIndex, Problem::OutOfRange));
    assert_eq!(with(0, f32::NAN, [0.0; 3], 0.1).validate(), err(Field::Gravity, Problem::NotFinite));
    assert_eq!(with(0, -0.1, [0.0; 3], 0.1).validate(), err(Field::Gravity, Problem::OutOfRange));
    assert_eq!(with(0, 0.5, [0.0, 9.0, 0.0], 0.1).validate(), err(Field::Gravity, Problem::OutOfRange));
    assert_eq!(with(0, 0.5, [0.0; 3], f32::INFINITY).validate(), err(Field::Gravity, Problem::NotFinite));
    assert_eq!(with(0, 0.5, [0.0; 3], -0.1).validate(), err(Field::Gravity, Problem::OutOfRange));
    assert_eq!(with(0, 0.5, [0.0; 3], 3.0).validate(), err(Field::Gravity, Problem::OutOfRange));
}

/// Every collision value is checked on its own, the nak naming the field.
#[test]
fn collision_values_are_refused_naming_the_field() {
    let err = |field, problem| Err(ValueError { field, problem });
    let margin = |m| HostMessage::ConfigureCollision { margin: m, check: true };
    assert_eq!(margin(f32::NAN).validate(), err(Field::Margin, Problem::NotFinite));
    assert_eq!(margin(-0.01).validate(), err(Field::Margin, Problem::OutOfRange));
    assert_eq!(margin(2.0).validate(), err(Field::Margin, Problem::OutOfRange));
    let body = |b: BodyConfig| HostMessage::ConfigureBody { index: 0, body: b };
    assert_eq!(body(BodyConfig { radius: -0.01, ..body_config() }).validate(), err(Field::Body, Problem::OutOfRange));
    assert_eq!(body(BodyConfig { radius: f32::NAN, ..body_config() }).validate(), err(Field::Body, Problem::NotFinite));
    assert_eq!(
        body(BodyConfig { a: [0.0, f32::INFINITY, 0.0], ..body_config() }).validate(),
        err(Field::Body, Problem::NotFinite)
    );
    assert_eq!(
        body(BodyConfig { frame: Some(MAX_JOINTS as u8), ..body_config() }).validate(),
        err(Field::Body, Problem::OutOfRange)
    );
    assert_eq!(
        HostMessage::ConfigureBody { index: MAX_BODIES as u8, body: body_config() }.validate(),
        err(Field::Body, Problem::OutOfRange)
    );
    let obstacle = |shape| HostMessage::ConfigureObstacle { index: 0, shape };
    let boxed = |rotation, half| obstacle(ObstacleShape::Box { centre: [0.0; 3], rotation, half });
    assert_eq!(boxed([1.0, 0.0, 0.0, 0.0], [0.1, 0.0, 0.1]).validate(), err(Field::Obstacle, Problem::OutOfRange));
    assert_eq!(boxed([1.0, 0.0, 0.0, 0.0], [0.1, -0.1, 0.1]).validate(), err(Field::Obstacle, Problem::OutOfRange));
    assert_eq!(boxed([1.0, 0.0, 0.0, 0.0], [f32::NAN; 3]).validate(), err(Field::Obstacle, Problem::NotFinite));
    assert_eq!(boxed([0.5, 0.0, 0.0, 0.0], [0.1; 3]).validate(), err(Field::Obstacle, Problem::NotUnit));
    let sphere = ObstacleShape::Capsule { a: [0.0; 3], b: [0.0; 3], radius: -1.0 };
    assert_eq!(obstacle(sphere).validate(), err(Field::Obstacle, Problem::OutOfRange));
    let plane = ObstacleShape::HalfSpace { normal: [0.0, 0.0, 2.0], offset: 0.0 };
    assert_eq!(obstacle(plane).validate(), err(Field::Obstacle, Problem::NotUnit));
    assert_eq!(
        HostMessage::ConfigureObstacle { index: MAX_OBSTACLES as u8, shape: sphere }.validate(),
        err(Field::Obstacle, Problem::OutOfRange)
    );
    let allowed = |body, other| HostMessage::ConfigureAllowed { body, other };
    assert_eq!(allowed(24, CollisionPart::Body(0)).validate(), err(Field::Allowed, Problem::OutOfRange));
    assert_eq!(allowed(0, CollisionPart::Obstacle(8)).validate(), err(Field::Allowed, Problem::OutOfRange));
}

/// The figure for the report: a 6-joint keyframe push with velocities.
#[test]
fn six_joint_keyframe_overhead() {
    let push = HostMessage::PushKeyframe(JointKeyframe {
        time: 1.0,
        positions: joints(6, 0.2),
        velocities: Some(joints(6, 0.0)),
        gripper: None,
    });
    let mut buf = [0u8; MAX_PAYLOAD];
    let payload = postcard::to_slice(&push, &mut buf).unwrap();
    let wire = round_trip(1, FrameKind::Request, &push);
    assert_eq!(wire - payload.len(), OVERHEAD);
    println!("6-joint keyframe push: payload {} bytes, frame {} bytes, overhead {}", payload.len(), wire, OVERHEAD);
}

fn feed(bytes: &[u8]) -> std::vec::Vec<Result<(u8, FrameKind), FrameError>> {
    let mut decoder = FrameDecoder::<MAX_ENCODED>::new();
    bytes.iter().filter_map(|&b| decoder.push(b).map(|r| r.map(|f| (f.seq, f.kind)))).collect()
}

fn start_frame() -> std::vec::Vec<u8> {
    let mut wire = [0u8; MAX_FRAME];
    let n = encode_message(9, FrameKind::Request, &HostMessage::Start, &mut wire).unwrap();
    wire[..n].to_vec()
}

#[test]
fn oversized_frame_dropped_and_next_one_decoded() {
    let mut bytes = vec![0x55u8; MAX_ENCODED + 1];
    bytes.push(0);
    bytes.extend(start_frame());
    assert_eq!(feed(&bytes), vec![Err(FrameError::Oversized { len: MAX_ENCODED + 1 }), Ok((9, FrameKind::Request))]);
    // A payload too large for a frame is refused when encoding.
    let mut wire = [0u8; 400];
    assert_eq!(
        encode_frame(0, FrameKind::Request, &[1u8; MAX_PAYLOAD + 1], &mut wire),
        Err(FrameError::BufferTooSmall)
    );
    // The largest payload makes exactly MAX_FRAME bytes.
    assert_eq!(encode_frame(0, FrameKind::Request, &[1u8; MAX_PAYLOAD], &mut wire), Ok(MAX_FRAME));
}

#[test]
fn every_flipped_bit_is_caught() {
    let frame = start_frame();
    for byte in 0..frame.len() - 1 {
        for bit in 0..8 {
            let mut bad = frame.clone();
            bad[byte] ^= 1 << bit;
            let got = feed(&bad);
            assert!(got.iter().all(|r| r.is_err()), "flip {byte}:{bit} gave {got:?}");
            for r in got {
                let reason = NakReason::from(r.unwrap_err());
                assert!(matches!(reason, NakReason::Corrupt), "flip {byte}:{bit}: {reason:?}");
            }
        }
    }
    // The flipped bit of the CRC, reported with both values.
    let mut bad = frame.clone();
    bad[5] ^= 0x01;
    let [Err(FrameError::Crc { received, computed })] = feed(&bad)[..] else { panic!("{:?}", feed(&bad)) };
    assert_eq!(received ^ computed, 0x0001);
}

#[test]
fn truncated_frames_rejected() {
    let frame = start_frame();
    // Losing the last data byte makes the COBS block short.
    let mut cut = frame[..frame.len() - 2].to_vec();
    cut.push(0);
    assert!(matches!(feed(&cut)[..], [Err(FrameError::Cobs(CobsError::Truncated { .. }))]));
    // A valid COBS frame of fewer bytes than header and CRC.
    assert_eq!(feed(&[0x03, 0x07, 0x01, 0x00]), vec![Err(FrameError::Truncated { len: 2 })]);
    assert_eq!(parse_raw(&[]), Err(FrameError::Truncated { len: 0 }));
}

#[test]
fn unknown_kind_and_unknown_message_rejected() {
    let mut raw = vec![0x05, 0x7F, 0x0A];
    raw.extend(crc16(&raw).to_be_bytes());
    assert_eq!(parse_raw(&raw), Err(FrameError::UnknownKind { kind: 0x7F }));
    assert_eq!(NakReason::from(FrameError::UnknownKind { kind: 0x7F }), NakReason::UnknownMessage);
    // Variant 200 does not exist; a known variant with trailing bytes is refused as well.
    assert_eq!(decode_payload::<HostMessage>(&[200, 1]), Err(FrameError::UnknownMessage));
    assert_eq!(decode_payload::<HostMessage>(&[0x0A, 0x00]), Err(FrameError::UnknownMessage));
    assert_eq!(decode_payload::<HostMessage>(&[]), Err(FrameError::UnknownMessage));
}

#[test]
fn validate_refuses_bad_values_with_the_field() {
    let target = |p: [f32; 3], q: Option<[f32; 4]>| HostMessage::MoveTo {
        path: firmware::link::message::MovePath::Auto,
        target: CartesianTarget { position: p, orientation: q },
        timing: Timing::Duration(1.0),
    };
    let err = |field, problem| Err(ValueError { field, problem });
    assert_eq!(target([f32::NAN, 0.0, 0.0], None).validate(), err(Field::Position, Problem::NotFinite));
    assert_eq!(target([0.0, f32::INFINITY, 0.0], None).validate(), err(Field::Position, Problem::NotFinite));
    assert_eq!(target([0.0, 0.0, 11.0], None).validate(), err(Field::Position, Problem::OutOfRange));
    assert_eq!(target([0.0; 3], Some([0.9, 0.0, 0.0, 0.0])).validate(), err(Field::Orientation, Problem::NotUnit));
    assert_eq!(
        target([0.0; 3], Some([f32::NAN, 0.0, 0.0, 0.0])).validate(),
        err(Field::Orientation, Problem::NotFinite)
    );
    let timed = |timing| HostMessage::MoveJoints { positions: joints(6, 0.0), timing };
    assert_eq!(timed(Timing::Duration(0.0)).validate(), err(Field::Duration, Problem::OutOfRange));
    assert_eq!(timed(Timing::Duration(-1.0)).validate(), err(Field::Duration, Problem::OutOfRange));
    assert_eq!(timed(Timing::MaxSpeed(f32::NAN)).validate(), err(Field::Speed, Problem::NotFinite));
    let push = |positions, velocities| {
        HostMessage::PushKeyframe(JointKeyframe { time: 1.0, positions, velocities, gripper: None })
    };
    assert_eq!(push(Vec::new(), None).validate(), err(Field::Joints, Problem::Count));
    assert_eq!(push(joints(6, 0.0), Some(joints(5, 0.0))).validate(), err(Field::Velocities, Problem::Count));
    assert_eq!(
        push(joints(6, 0.0), Some(joints(6, f32::NEG_INFINITY))).validate(),
        err(Field::Velocities, Problem::NotFinite)
    );
    let mut j = joint_config();
    j.lower = 3.0;
    assert_eq!(HostMessage::ConfigureJoint { index: 0, joint: j }.validate(), err(Field::Limits, Problem::OutOfRange));
    assert_eq!(
        HostMessage::ConfigureBegin { name: name("x"), joints: 9, tool_xyz: [0.0; 3], tool_rpy: [0.0; 3], model: 777 }
            .validate(),
        err(Field::JointCount, Problem::OutOfRange)
    );
    assert_eq!(HostMessage::SetTelemetry { rate_hz: 5000 }.validate(), err(Field::Rate, Problem::OutOfRange));
}

fn finite() -> impl Strategy<Value = f32> {
    -5.0f32..5.0
}

fn joint_vec() -> impl Strategy<Value = Joints> {
    prop::collection::vec(finite(), 1..=MAX_JOINTS).prop_map(|v| v.into_iter().collect())
}

proptest! {
    #[test]
    fn keyframes_round_trip(seq: u8, time in 0.0f32..100.0, p in joint_vec(), with_v: bool) {
        let velocities = with_v.then(|| p.iter().map(|x| -x).collect());
        let m = HostMessage::PushKeyframe(JointKeyframe { time, positions: p, velocities, gripper: None });
        prop_assert_eq!(m.validate(), Ok(()));
        round_trip(seq, FrameKind::Request, &m);
    }

    #[test]
    fn cartesian_keyframes_round_trip(seq: u8, time in 0.0f32..100.0, x in finite(), y in finite(), z in finite(),
                                      angle in -3.0f32..3.0, with_q: bool) {
        let q = [libm::cosf(angle / 2.0), 0.0, libm::sinf(angle / 2.0), 0.0];
        let target = CartesianTarget { position: [x, y, z], orientation: with_q.then_some(q) };
        let m = HostMessage::PushCartesianKeyframe(CartesianKeyframe { time, target, gripper: None });
        prop_assert_eq!(m.validate(), Ok(()));
        round_trip(seq, FrameKind::Request, &m);
    }

    #[test]
    fn status_round_trips(seq: u8, m in joint_vec(), s in joint_vec(), queued: u16, free: u16, overruns: u32) {
        let mut st = status(1);
        st.measured = m;
        st.setpoints = s;
        st.queued = queued;
        st.free_slots = free;
        st.timing.overruns = overruns;
        round_trip(seq, FrameKind::Event, &FirmwareMessage::Telemetry(st));
    }

    /// Arbitrary payloads, CRC made valid, never panic and decode (if at all) to messages that
    /// re-encode to the same value.
    #[test]
    fn arbitrary_payloads_never_panic(payload in prop::collection::vec(any::<u8>(), 0..MAX_PAYLOAD)) {
        let mut wire = [0u8; MAX_FRAME];
        let n = encode_frame(1, FrameKind::Request, &payload, &mut wire).unwrap();
        let mut decoder = FrameDecoder::<MAX_ENCODED>::new();
        for &b in &wire[..n] {
            if let Some(Ok(frame)) = decoder.push(b) {
                if let Ok(m) = decode_payload::<HostMessage>(frame.payload) {
                    let _ = m.validate();
                    round_trip(1, FrameKind::Request, &m);
                }
            }
        }
    }

    #[test]
    fn cobs_round_trips(data in prop::collection::vec(any::<u8>(), 0..600)) {
        let mut enc = vec![0u8; cobs::max_encoded_len(data.len())];
        let n = cobs::encode(&data, &mut enc).unwrap();
        prop_assert!(!enc[..n].contains(&0));
        let mut dec = vec![0u8; data.len()];
        let m = cobs::decode(&enc[..n], &mut dec).unwrap();
        prop_assert_eq!(&dec[..m], &data[..]);
    }
}

/// Runs one request frame through a session; returns the reply frame's seq, kind and message.
fn exchange(
    session: &mut firmware::link::session::Session,
    applied: &mut std::vec::Vec<HostMessage>,
    wire: &[u8],
) -> (u8, FrameKind, FirmwareMessage) {
    let mut decoder = FrameDecoder::<MAX_ENCODED>::new();
    let mut out = [0u8; MAX_FRAME];
    let mut n = 0;
    for &b in wire {
        match decoder.push(b) {
            Some(Ok(frame)) => {
                n = session
                    .handle(&frame, &mut out, |m| {
                        applied.push(m.clone());
                        FirmwareMessage::Ack { free_slots: 16 - applied.len() as u16 }
                    })
                    .unwrap()
            }
            Some(Err(e)) => n = session.nak_broken(&e, &mut out).unwrap(),
            None => {}
        }
    }
    let mut decoder = FrameDecoder::<MAX_ENCODED>::new();
    out[..n]
        .iter()
        .find_map(|&b| decoder.push(b).map(|r| r.map(|f| (f.seq, f.kind, decode_payload(f.payload).unwrap()))))
        .unwrap()
        .unwrap()
}

fn request(seq: u8, m: &HostMessage) -> std::vec::Vec<u8> {
    let mut wire = [0u8; MAX_FRAME];
    let n = encode_message(seq, FrameKind::Request, m, &mut wire).unwrap();
    wire[..n].to_vec()
}

#[test]
fn session_applies_a_repeat_once_and_acks_it_again() {
    let mut session = firmware::link::session::Session::new();
    let mut applied = vec![];
    let push = HostMessage::PushKeyframe(JointKeyframe {
        time: 1.0,
        positions: joints(6, 0.0),
        velocities: None,
        gripper: None,
    });
    let ack = |free| (4, FrameKind::Reply, FirmwareMessage::Ack { free_slots: free });
    assert_eq!(exchange(&mut session, &mut applied, &request(4, &push)), ack(15));
    assert_eq!(exchange(&mut session, &mut applied, &request(4, &push)), ack(15));
    assert_eq!(applied.len(), 1);
    // Same seq, different message (a restarted host): applied.
    let other = HostMessage::PushKeyframe(JointKeyframe {
        time: 2.0,
        positions: joints(6, 0.0),
        velocities: None,
        gripper: None,
    });
    assert_eq!(exchange(&mut session, &mut applied, &request(4, &other)), ack(14));
    assert_eq!(applied.len(), 2);
    assert_eq!(session.stats().repeats, 1);
}

#[test]
fn session_naks_bad_input_and_changes_nothing() {
    let mut session = firmware::link::session::Session::new();
    let mut applied = vec![];
    let nak = |seq, kind, reason| (seq, kind, FirmwareMessage::Nak { reason });
    let nan = HostMessage::MoveTo {
        path: firmware::link::message::MovePath::Auto,
        target: CartesianTarget { position: [f32::NAN, 0.0, 0.0], orientation: None },
        timing: Timing::Duration(1.0),
    };
    let bad = NakReason::BadValue(ValueError { field: Field::Position, problem: Problem::NotFinite });
    assert_eq!(exchange(&mut session, &mut applied, &request(1, &nan)), nak(1, FrameKind::Reply, bad));
    // Unknown message: a valid frame around a variant that does not exist.
    let mut wire = [0u8; MAX_FRAME];
    let n = encode_frame(2, FrameKind::Request, &[0x7F], &mut wire).unwrap();
    assert_eq!(exchange(&mut session, &mut applied, &wire[..n]), nak(2, FrameKind::Reply, NakReason::UnknownMessage));
    // Corrupt: a flipped bit; the nak is an event, since the seq cannot be trusted.
    let mut flipped = request(3, &HostMessage::Start);
    flipped[2] ^= 0x10;
    assert_eq!(exchange(&mut session, &mut applied, &flipped), nak(0, FrameKind::Event, NakReason::Corrupt));
    // Oversized.
    let mut long = vec![1u8; MAX_FRAME + 10];
    long.push(0);
    assert_eq!(exchange(&mut session, &mut applied, &long), nak(1, FrameKind::Event, NakReason::Oversized));
    assert!(applied.is_empty());
    assert_eq!(session.stats().naks, 4);
}
