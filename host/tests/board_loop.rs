//! The main loop every board runs ([`firmware::board::MainLoop`]) on the host, against simulated
//! servos on the virtual clock: the host link is read only between ticks, as on a board, and the
//! bytes that arrive while a tick is busy on the servo bus wait in the receive ring
//! ([`firmware::board::RxRing`]), which the boards' receive interrupts fill.

use armctl::sim::{connect, Faults, SimBus};
use firmware::app::{Board, Firmware};
use firmware::board::{MainLoop, RxRing};
use firmware::bus::master::{BusConfig, Clock, Master, NoDirectionPin};
use firmware::bus::table::STS3215;
use firmware::controller::Config;
use firmware::link::frame::{decode_payload, encode_message, FrameDecoder, FrameKind, MAX_ENCODED};
use firmware::link::message::{FirmwareMessage, HostMessage};

const BAUD: u32 = 1_000_000;

/// `count` pings, one frame each, sequence numbers 1 on.
fn pings(count: usize) -> Vec<u8> {
    let mut bytes = Vec::new();
    for seq in 1..=count {
        let mut frame = [0u8; MAX_ENCODED];
        let n = encode_message(seq as u8, FrameKind::Request, &HostMessage::Ping, &mut frame).unwrap();
        bytes.extend_from_slice(&frame[..n]);
    }
    bytes
}

/// The replies in `tx`, as (sequence number, message).
fn replies(tx: &[u8]) -> Vec<(u8, FirmwareMessage)> {
    let mut decoder = FrameDecoder::<MAX_ENCODED>::new();
    let mut out = Vec::new();
    for &byte in tx {
        if let Some(Ok(frame)) = decoder.push(byte) {
            if frame.kind == FrameKind::Reply {
                out.push((frame.seq, decode_payload(frame.payload).unwrap()));
            }
        }
    }
    out
}

/// A tick with servo 3 silent (its read times out: about 3.5 ms of bus), and, while it runs, as
/// many bytes as 1 Mbps brings in that time and more: every frame among them is answered on the
/// next pass. A ring too small for them drops and counts the excess.
///
/// The servos answer at once (return delay 0, an EEPROM value: servos once set up by LeRobot or
/// `armctl --bus` keep it). From the factory (500 µs each) the same tick takes about 8 ms, more
/// than a 512-byte ring holds of a link at 1 Mbps line rate.
#[test]
fn bytes_that_come_during_a_long_bus_cycle_are_all_answered() {
    for (ring_size_ok, name) in [(true, "512-byte ring"), (false, "64-byte ring")] {
        let faults = Faults { silent: vec![3], ..Faults::default() };
        let mut bus = SimBus::new(STS3215.protocol, &STS3215, &[1, 2, 3, 4, 5, 6], BAUD).with_faults(faults);
        for servo in bus.servos_mut() {
            servo.set(STS3215.items.return_delay, 0);
        }
        let (_bus, port, mut clock) = connect(bus);
        let config = BusConfig { return_delay_us: 0, ..BusConfig::new(STS3215.protocol, BAUD) };
        let mut master: Master<_, _, _> = Master::new(port, NoDirectionPin, clock.clone(), config);
        let board = Board { bus: config, model: &STS3215, control: Config::default(), max_bus_baud: u32::MAX };
        let mut app = Firmware::<5, 32>::new(board, Some(&firmware::builtin::SO101)).unwrap();
        static BIG: RxRing<512> = RxRing::new();
        static SMALL: RxRing<64> = RxRing::new();
        let mut tx = Vec::new();

        // The first pass runs a tick at once; time it on the virtual clock.
        let start = clock.now_us();
        let (arrived, dropped) = if ring_size_ok {
            let mut main = MainLoop::new(&mut app, &mut master, &BIG);
            main.poll(&mut tx);
            let cycle_us = clock.now_us() - start;
            assert!(cycle_us >= 3_000, "a tick with a silent servo takes {cycle_us} µs");
            // The bytes 1 Mbps brings in during that cycle (10 bits each), as whole pings.
            let frames = pings(60);
            assert!(frames.len() as u64 * 10 >= cycle_us, "{} bytes for {cycle_us} µs", frames.len());
            for &b in &frames {
                BIG.push(b);
            }
            main.poll(&mut tx);
            (frames.len(), BIG.dropped())
        } else {
            let mut main = MainLoop::new(&mut app, &mut master, &SMALL);
            main.poll(&mut tx);
            let frames = pings(60);
            for &b in &frames {
                SMALL.push(b);
            }
            main.poll(&mut tx);
            (frames.len(), SMALL.dropped())
        };
        let answered = replies(&tx);
        if ring_size_ok {
            assert_eq!(dropped, 0, "{name}");
            let seqs: Vec<u8> = answered.iter().map(|(s, _)| *s).collect();
            assert_eq!(seqs, (1..=60).collect::<Vec<u8>>(), "{name}: every ping answered, in order");
            assert!(answered.iter().all(|(_, m)| matches!(m, FirmwareMessage::Ack { .. })), "{name}");
        } else {
            // 63 bytes fit; the rest were dropped and counted, and only whole frames among the
            // kept bytes are answered.
            assert_eq!(dropped as usize, arrived - 63, "{name}");
            assert!(answered.len() < 60 / 2, "{name}: {} answered", answered.len());
        }
    }
}

/// Sends `messages` through the ring, one frame each, and polls until every one is answered;
/// returns the replies in order.
fn send<const R: usize, P, D, C, const BUF: usize>(
    main: &mut MainLoop<'_, { firmware::board::JOINTS }, 32, R, P, D, C, BUF>,
    ring: &RxRing<R>,
    messages: &[HostMessage],
    first_seq: u8,
) -> Vec<FirmwareMessage>
where
    P: embedded_io::Read + embedded_io::Write + embedded_io::ReadReady + firmware::board::BusPort,
    D: embedded_hal::digital::OutputPin,
    C: Clock,
{
    let mut tx = Vec::new();
    for (i, m) in messages.iter().enumerate() {
        let mut frame = [0u8; MAX_ENCODED];
        let n = encode_message(first_seq.wrapping_add(i as u8), FrameKind::Request, m, &mut frame).unwrap();
        for &b in &frame[..n] {
            assert!(ring.push(b));
        }
        main.poll(&mut tx);
    }
    let replies: Vec<FirmwareMessage> = replies(&tx).into_iter().map(|(_, m)| m).collect();
    assert_eq!(replies.len(), messages.len(), "{replies:?}");
    replies
}

/// The boards' build, started with the built-in SO-101 on Feetech at 1 Mbps, on a bus of
/// OpenManipulator-X servos (Dynamixel 2.0) set to 2 Mbps. The arm sent over the link switches the
/// main loop's bus to the arm's protocol and baud rate, and the firmware then reads every servo:
/// four joints of the six the build holds, the link carrying four values. Sendings it cannot take
/// (an arm on a bus too slow for the control period or faster than the board's UART, more joints
/// than the build, a bus named with no arm begun) are refused and change nothing.
#[test]
fn an_arm_sent_over_the_link_switches_the_bus_and_uses_four_of_six_joints() {
    use armctl::arm::servos::ServoSetup;
    use armctl::arm::ArmSpec;
    use armctl::link::arm_config::configure_messages;
    use firmware::bus::table::XM430_W350;
    use firmware::link::message::{BusProtocol, NakReason, Problem};

    let omx = ArmSpec::load("open-manipulator-x", None).unwrap();
    let mut servos = ServoSetup::for_arm("open-manipulator-x").unwrap();
    servos.baud = 2_000_000;
    let mut bus = SimBus::new(XM430_W350.protocol, &XM430_W350, &servos.bus_ids(), servos.baud);
    // The board's UART starts at the built-in arm's 1 Mbps: the servos hear nothing of it.
    bus.set_baud(BAUD);
    let (shared, port, clock) = connect(bus);
    let config = BusConfig::new(STS3215.protocol, BAUD);
    let mut master: Master<_, _, _> = Master::new(port, NoDirectionPin, clock.clone(), config);
    let board = Board { bus: config, model: &STS3215, control: Config::default(), max_bus_baud: 2_000_000 };
    let mut app = Firmware::<{ firmware::board::JOINTS }, 32>::new(board, Some(&firmware::builtin::SO101)).unwrap();
    static RING: RxRing<512> = RxRing::new();
    let mut main = MainLoop::new(&mut app, &mut master, &RING);
    let hello = HostMessage::Hello { protocol_version: firmware::link::message::PROTOCOL_VERSION };
    let info = |m: &FirmwareMessage| match m {
        FirmwareMessage::Info(i) => (i.arm_name.to_string(), i.joints),
        other => panic!("{other:?}"),
    };
    assert_eq!(info(&send(&mut main, &RING, std::slice::from_ref(&hello), 1)[0]), ("so101".to_string(), 5));

    // Refused at commit: the same arm at 115.2 kbps (a cycle of five Dynamixel servos takes
    // longer than the 10 ms period) and at 3 Mbps (beyond this board's UART); seven joints at
    // once.
    let bus_refused = |m: &FirmwareMessage| {
        matches!(m, FirmwareMessage::Nak { reason: NakReason::BadValue(v) }
            if v.field == firmware::link::message::Field::Bus && v.problem == Problem::OutOfRange)
    };
    for (k, baud) in [115_200, 3_000_000].into_iter().enumerate() {
        let refused = ServoSetup { baud, ..servos.clone() };
        let replies = send(&mut main, &RING, &configure_messages(&omx, &refused).unwrap(), 10 + 20 * k as u8);
        assert!(bus_refused(replies.last().unwrap()), "{baud}: {replies:?}");
    }
    let mut seven = configure_messages(&omx, &servos).unwrap().remove(0);
    if let HostMessage::ConfigureBegin { joints, .. } = &mut seven {
        *joints = 7;
    }
    let replies = send(&mut main, &RING, &[seven], 50);
    assert!(
        matches!(&replies[0], FirmwareMessage::Nak { reason: NakReason::BadValue(v) } if v.problem == Problem::Count)
    );
    assert_eq!(info(&send(&mut main, &RING, std::slice::from_ref(&hello), 55)[0]), ("so101".to_string(), 5));
    assert_eq!(main_bus(&shared), BAUD, "the line untouched");

    // Taken: the bus follows, and every servo answers at 2 Mbps.
    let replies = send(&mut main, &RING, &configure_messages(&omx, &servos).unwrap(), 60);
    assert!(replies.iter().all(|m| matches!(m, FirmwareMessage::Ack { .. })), "{replies:?}");
    assert_eq!(info(&send(&mut main, &RING, &[hello], 80)[0]), ("open-manipulator-x".to_string(), 4));
    assert_eq!(main_bus(&shared), 2_000_000);
    // The arm committed, nothing is begun: a bus named now has no arm to go with.
    let early = HostMessage::ConfigureBus { protocol: BusProtocol::Dynamixel2, baud: 1_000_000 };
    assert_eq!(send(&mut main, &RING, &[early], 85)[0], FirmwareMessage::Nak { reason: NakReason::NotReady });
    for _ in 0..20 {
        let next = main.poll(&mut Vec::new());
        clock.advance_to(next * 1000);
    }
    let status = send(&mut main, &RING, &[HostMessage::GetStatus], 90);
    let FirmwareMessage::Status(s) = &status[0] else { panic!("{status:?}") };
    assert_eq!((s.measured.len(), s.setpoints.len(), s.lost_servos), (4, 4, 0), "{s:?}");
    assert!(s.measured.iter().all(|q| q.abs() < 1e-3), "servos at their middle: {:?}", s.measured);
    assert!(s.gripper.is_some());
    // Five values for a four-joint arm: the wrong count.
    let five = HostMessage::MoveJoints {
        positions: [0.0; 5].into_iter().collect(),
        timing: firmware::link::message::Timing::Duration(1.0),
    };
    let reply = send(&mut main, &RING, &[five], 100);
    assert!(
        matches!(&reply[0], FirmwareMessage::Nak { reason: NakReason::BadValue(v) } if v.problem == Problem::Count),
        "{reply:?}"
    );
}

fn main_bus(bus: &armctl::sim::SharedBus) -> u32 {
    bus.borrow().baud()
}

type BoardApp = Firmware<{ firmware::board::JOINTS }, 32>;
type SimMaster = Master<armctl::sim::SimPort, NoDirectionPin, armctl::sim::VirtualClock>;

/// The boards' build with the built-in SO-101 on simulated servos, for the tests below.
fn board_app() -> (BoardApp, SimMaster, armctl::sim::VirtualClock) {
    let bus = SimBus::new(STS3215.protocol, &STS3215, &[1, 2, 3, 4, 5, 6], BAUD);
    let (_bus, port, clock) = connect(bus);
    let config = BusConfig::new(STS3215.protocol, BAUD);
    let master = Master::new(port, NoDirectionPin, clock.clone(), config);
    let board = Board { bus: config, model: &STS3215, control: Config::default(), max_bus_baud: u32::MAX };
    let app = Firmware::new(board, Some(&firmware::builtin::SO101)).unwrap();
    (app, master, clock)
}

/// The host sends 100 pings (700 bytes) while the loop is away, into the boards' 512-byte ring:
/// 511 are kept, 189 dropped. After the loop has drained the ring, a status read through the same
/// ring reports those 189 drops, and the UART overruns its receive interrupt counted (three,
/// counted here as an interrupt would). Telemetry carries them too.
#[test]
fn the_status_reports_the_bytes_the_ring_dropped_and_the_uart_overruns() {
    use firmware::link::message::Status;
    let (mut app, mut master, clock) = board_app();
    static RING: RxRing<512> = RxRing::new();
    let mut main = MainLoop::new(&mut app, &mut master, &RING);
    fn status(
        main: &mut MainLoop<
            '_,
            { firmware::board::JOINTS },
            32,
            512,
            armctl::sim::SimPort,
            NoDirectionPin,
            armctl::sim::VirtualClock,
            256,
        >,
        seq: u8,
    ) -> Status {
        match send(main, &RING, &[HostMessage::GetStatus], seq).remove(0) {
            FirmwareMessage::Status(s) => s,
            other => panic!("{other:?}"),
        }
    }
    let before = status(&mut main, 1);
    assert_eq!((before.errors.link_dropped, before.errors.link_overruns), (0, 0));

    let flood = pings(100);
    assert_eq!(flood.len(), 700);
    let kept = flood.iter().filter(|&&b| RING.push(b)).count();
    assert_eq!((kept, RING.dropped()), (511, 189));
    for _ in 0..3 {
        RING.overrun();
    }
    let mut tx = Vec::new();
    while !RING.is_empty() {
        main.poll(&mut tx);
    }
    // The ring kept the first 73 pings whole (511 bytes), and the rest went.
    assert_eq!(replies(&tx).len(), 511 / 7);

    let after = status(&mut main, 120);
    assert_eq!((after.errors.link_dropped, after.errors.link_overruns), (189, 3), "{:?}", after.errors);
    // Telemetry, the status the firmware sends unasked, carries them as well.
    let _ = send(&mut main, &RING, &[HostMessage::SetTelemetry { rate_hz: 100 }], 121);
    let mut tx = Vec::new();
    for _ in 0..3 {
        let next = main.poll(&mut tx);
        clock.advance_to(next * 1_000);
    }
    let mut decoder = FrameDecoder::<MAX_ENCODED>::new();
    let mut telemetry = Vec::new();
    for &b in &tx {
        if let Some(Ok(frame)) = decoder.push(b) {
            if frame.kind == FrameKind::Event {
                telemetry.push(decode_payload::<FirmwareMessage>(frame.payload).unwrap());
            }
        }
    }
    assert!(
        telemetry.iter().any(
            |m| matches!(m, FirmwareMessage::Telemetry(s) if (s.errors.link_dropped, s.errors.link_overruns) == (189, 3))
        ),
        "{telemetry:?}"
    );
}

/// A host that never pauses cannot hold the control tick back: with 300 pings (2,100 bytes)
/// waiting, a pass whose tick is due takes [`DRAIN_PER_PASS`] bytes (73 whole pings), then ticks;
/// the rest follow on the next passes. Without the bound the pass would answer all 300 first.
#[test]
fn a_pass_takes_at_most_its_bound_of_bytes_then_ticks() {
    use firmware::board::main_loop::DRAIN_PER_PASS;
    let (mut app, mut master, clock) = board_app();
    static RING: RxRing<4096> = RxRing::new();
    let mut main = MainLoop::new(&mut app, &mut master, &RING);
    let mut tx = Vec::new();
    let due = main.poll(&mut tx);
    assert!(tx.is_empty());
    clock.advance_to(due * 1_000);

    let flood = pings(300);
    assert!(flood.iter().all(|&b| RING.push(b)));
    let next = main.poll(&mut tx);
    assert_eq!(replies(&tx).len(), DRAIN_PER_PASS / 7, "one pass answers the pings in its bound");
    assert!(next >= due + 10_000, "the tick due at {due} µs ran in that pass (next due {next} µs)");
    let mut passes = 1;
    while !RING.is_empty() {
        main.poll(&mut tx);
        passes += 1;
    }
    assert_eq!(passes, flood.len().div_ceil(DRAIN_PER_PASS));
    let seqs: Vec<u8> = replies(&tx).iter().map(|(s, _)| *s).collect();
    assert_eq!(seqs, (1..=300).map(|s| s as u8).collect::<Vec<u8>>(), "every ping answered, in order");
}
