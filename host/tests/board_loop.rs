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
#[test]
fn bytes_that_come_during_a_long_bus_cycle_are_all_answered() {
    for (ring_size_ok, name) in [(true, "512-byte ring"), (false, "64-byte ring")] {
        let faults = Faults { silent: vec![3], ..Faults::default() };
        let bus = SimBus::new(STS3215.protocol, &STS3215, &[1, 2, 3, 4, 5, 6], BAUD).with_faults(faults);
        let (_bus, port, mut clock) = connect(bus);
        let config = BusConfig::new(STS3215.protocol, BAUD);
        let mut master: Master<_, _, _> = Master::new(port, NoDirectionPin, clock.clone(), config);
        let board = Board { bus: config, model: &STS3215, control: Config::default() };
        let mut app = Firmware::<5, 32>::new(board, Some(firmware::builtin::setup().unwrap())).unwrap();
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
