//! Finding the servos: which protocol and baud rate they speak, which ids answer, and whether the
//! adapter hears its own transmission.
//!
//! A person at first power-on often does not know the baud rate (Dynamixel ships at 57600,
//! Feetech at 1 Mbps, an arm set up elsewhere at anything) nor the ids. With no `--protocol` or
//! `--baud`, every usual rate of both protocols is tried, the factory rates first, until something
//! answers. At each, the ids pinged are `--arm`'s (and the factory id 1), else 0 to 20: a full
//! scan of 253 ids at 16 rates would take minutes when nothing answers.

use std::time::Duration;

use anyhow::{Context, Result};
use embedded_io::{Read, Write};
use firmware::bus::master::{BusConfig, MasterError};
use firmware::bus::{Id, Instruction, InstructionPacket, Protocol};

use crate::commands::servo::commands::protocol_bauds;
use crate::link::serial::SerialTransport;
use crate::runtime::pc::timing::margins;
use crate::runtime::servo_session::{BusFailure, Servo, Session};

/// The rates tried when none is given, most likely first: both protocols' factory rates, then
/// the common ones. Each protocol tries those its models have.
pub const SCAN_BAUDS: [u32; 13] = [
    1_000_000, 57_600, 115_200, 500_000, 2_000_000, 3_000_000, 4_000_000, 4_500_000, 250_000, 128_000, 76_800, 38_400,
    9_600,
];

/// The ids pinged when no arm says which: the factory id and the ids of the usual arms (SO-101
/// and Koch 1-6, OpenManipulator-X 11-15).
pub const SCAN_IDS: std::ops::RangeInclusive<u8> = 0..=20;

/// The adapter latency the scan allows for: an FTDI chip's factory 16 ms latency timer, and some.
pub const SCAN_LATENCY_US: u64 = 20_000;

/// Extra attempts, once something answered at a rate, for an id that did not answer cleanly.
pub const AGAIN_RETRIES: u8 = 4;

/// What answered where.
#[derive(Debug)]
pub struct Found {
    /// The protocol the servos speak.
    pub protocol: Protocol,
    /// Their baud rate.
    pub baud: u32,
    /// The servos that answered a ping, in id order.
    pub servos: Vec<Servo>,
    /// Ids whose replies came garbled (two servos with one id answer at once), in id order.
    pub garbled: Vec<Id>,
    /// The (protocol, baud) pairs tried, in order.
    pub tried: Vec<(Protocol, u32)>,
}

/// The (protocol, baud) pairs to try: the given ones, else every usual rate of both protocols,
/// the arm's protocol and rate first.
pub fn candidates(
    protocol: Option<Protocol>,
    baud: Option<u32>,
    preferred: Option<(Protocol, u32)>,
) -> Vec<(Protocol, u32)> {
    let protocols: Vec<Protocol> = match (protocol, preferred) {
        (Some(p), _) => vec![p],
        (None, Some((p, _))) => vec![p, other(p)],
        (None, None) => vec![Protocol::Feetech, Protocol::Dxl2],
    };
    let mut pairs = Vec::new();
    if let (Some((p, b)), None) = (preferred, baud) {
        if protocols.contains(&p) {
            pairs.push((p, b));
        }
    }
    let bauds: Vec<u32> = match baud {
        Some(b) => vec![b],
        None => SCAN_BAUDS.to_vec(),
    };
    for b in bauds {
        for &p in &protocols {
            let known = protocol_bauds(p).contains(&b) || baud.is_some();
            if known && !pairs.contains(&(p, b)) {
                pairs.push((p, b));
            }
        }
    }
    pairs
}

fn other(p: Protocol) -> Protocol {
    match p {
        Protocol::Feetech => Protocol::Dxl2,
        Protocol::Dxl2 => Protocol::Feetech,
    }
}

/// The bus configuration of the scan: no retries (a missing servo costs one timeout), reply
/// timeouts that outlast a slow adapter.
pub fn scan_config(protocol: Protocol, baud: u32, echo: bool) -> BusConfig {
    let bus = BusConfig { retries: 0, echo, ..BusConfig::new(protocol, baud) };
    margins(bus, SCAN_LATENCY_US)
}

/// Pings `ids` at each of `pairs` until a servo answers (or a garbled reply says one is there);
/// `None` when nothing answered anywhere. `progress` gets a line per pair tried.
pub fn scan(
    path: &str,
    pairs: &[(Protocol, u32)],
    ids: &[Id],
    echo: bool,
    progress: &mut dyn std::io::Write,
) -> Result<Option<Found>> {
    let mut tried = Vec::new();
    for &(protocol, baud) in pairs {
        tried.push((protocol, baud));
        writeln!(progress, "looking for servos: {} at {baud} baud", protocol.name())?;
        let mut session = Session::open(path, scan_config(protocol, baud, echo))?;
        let (mut servos, mut garbled) = ping(&mut session, ids, path, baud)?;
        // Something is at this rate. A noisy line loses or garbles a ping now and then, which
        // one attempt takes for a missing servo or for two servos with one id: the ids that did
        // not answer cleanly are asked again with retries. Only a servo that never answers stays
        // missing, and only one that never answers cleanly stays garbled (two servos with one id
        // collide on every attempt).
        if !servos.is_empty() || !garbled.is_empty() {
            let again: Vec<Id> = ids.iter().copied().filter(|id| !servos.iter().any(|s| s.id == *id)).collect();
            session.set_config(BusConfig { retries: AGAIN_RETRIES, ..session.config() });
            let (more, still) = ping(&mut session, &again, path, baud)?;
            servos.extend(more);
            servos.sort_by_key(|s| s.id);
            garbled = still;
        }
        if !servos.is_empty() || !garbled.is_empty() {
            return Ok(Some(Found { protocol, baud, servos, garbled, tried }));
        }
    }
    // Nothing anywhere. One reply late by more than the scan's latency allowance (a busy PC, a
    // slow adapter) loses a whole rate, as the scan asks each id once: the likeliest rate gets a
    // second look with retries before the bus is called silent.
    let Some(&(protocol, baud)) = pairs.first() else { return Ok(None) };
    writeln!(progress, "looking for servos again, more patiently: {} at {baud} baud", protocol.name())?;
    let mut session = Session::open(path, BusConfig { retries: AGAIN_RETRIES, ..scan_config(protocol, baud, echo) })?;
    let (servos, garbled) = ping(&mut session, ids, path, baud)?;
    Ok((!servos.is_empty() || !garbled.is_empty()).then_some(Found { protocol, baud, servos, garbled, tried }))
}

/// Pings each of `ids` once per attempt of the session's configuration: the servos that answer,
/// and the ids whose replies came garbled.
fn ping<P: crate::runtime::servo_session::Port, C: firmware::bus::master::Clock>(
    session: &mut Session<P, C>,
    ids: &[Id],
    path: &str,
    baud: u32,
) -> Result<(Vec<Servo>, Vec<Id>)> {
    let mut servos = Vec::new();
    let mut garbled = Vec::new();
    for &id in ids {
        match session.identify(id) {
            Ok(servo) => servos.push(servo),
            Err(BusFailure(MasterError::NoReply { corrupt: 0, .. })) => {}
            Err(BusFailure(
                MasterError::NoReply { .. } | MasterError::BadReply { .. } | MasterError::Refused { .. },
            )) => garbled.push(id),
            Err(e) => return Err(e).with_context(|| format!("{path}: scanning at {baud} baud")),
        }
    }
    Ok((servos, garbled))
}

/// An id no arm uses, for the echo probe: nothing should answer it.
const ECHO_PROBE_ID: Id = 199;

/// Whether the adapter hears its own transmission: a ping to an id nobody has is sent, and the
/// bytes that come back within `wait` are searched for the ping itself. A half-duplex adapter
/// with a direction-switched buffer (U2D2, Feetech's URT-1, Waveshare's bus servo boards) gives
/// nothing back; one wire tied to both TX and RX gives the packet back.
pub fn hears_itself(path: &str, protocol: Protocol, baud: u32, wait: Duration) -> Result<bool> {
    let mut packet = [0u8; 16];
    let n = protocol
        .encode_instruction(&InstructionPacket { id: ECHO_PROBE_ID, instruction: Instruction::Ping }, &mut packet)
        .map_err(|e| anyhow::anyhow!("encoding the echo probe: {e}"))?;
    let sent = &packet[..n];
    let mut port = SerialTransport::open(path, baud)?;
    // Whatever was pending is not the echo.
    drain(&mut port)?;
    port.write_all(sent).map_err(|e| anyhow::anyhow!("{path}: {e:?}"))?;
    port.flush().map_err(|e| anyhow::anyhow!("{path}: {e:?}"))?;
    let deadline = std::time::Instant::now() + wait;
    let mut got = Vec::new();
    while std::time::Instant::now() < deadline {
        let mut buf = [0u8; 64];
        let k = port.read(&mut buf).map_err(|e| anyhow::anyhow!("{path}: {e:?}"))?;
        got.extend_from_slice(&buf[..k]);
        if contains(&got, sent) {
            return Ok(true);
        }
        if k == 0 {
            std::thread::sleep(Duration::from_millis(1));
        }
    }
    Ok(false)
}

fn drain(port: &mut SerialTransport) -> Result<()> {
    let mut buf = [0u8; 256];
    while port.read(&mut buf).map_err(|e| anyhow::anyhow!("{e:?}"))? > 0 {}
    Ok(())
}

fn contains(haystack: &[u8], needle: &[u8]) -> bool {
    haystack.windows(needle.len()).any(|w| w == needle)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn given_protocol_and_baud_are_the_only_candidate() {
        assert_eq!(candidates(Some(Protocol::Dxl2), Some(57_600), None), [(Protocol::Dxl2, 57_600)]);
    }

    #[test]
    fn the_scan_tries_the_arms_rate_first_then_the_factory_rates_of_both_protocols() {
        let pairs = candidates(None, None, Some((Protocol::Dxl2, 1_000_000)));
        assert_eq!(
            &pairs[..3],
            &[(Protocol::Dxl2, 1_000_000), (Protocol::Feetech, 1_000_000), (Protocol::Dxl2, 57_600)]
        );
        // Feetech has no 57600... it does (index 6); but no 2 Mbps.
        assert!(pairs.contains(&(Protocol::Feetech, 57_600)));
        assert!(!pairs.contains(&(Protocol::Feetech, 2_000_000)));
        assert!(pairs.contains(&(Protocol::Dxl2, 4_500_000)));
        let unique: std::collections::BTreeSet<_> = pairs.iter().map(|(p, b)| (p.name(), *b)).collect();
        assert_eq!(unique.len(), pairs.len(), "no pair twice");
    }

    #[test]
    fn without_a_protocol_feetech_comes_first_at_1_mbps() {
        let pairs = candidates(None, None, None);
        assert_eq!(pairs[0], (Protocol::Feetech, 1_000_000));
        assert_eq!(pairs[1], (Protocol::Dxl2, 1_000_000));
    }

    #[test]
    fn the_echo_is_found_inside_other_bytes() {
        assert!(contains(&[0, 1, 2, 3, 4], &[2, 3]));
        assert!(!contains(&[0, 1, 2], &[2, 3]));
    }
}
