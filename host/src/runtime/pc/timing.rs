//! Timing of a servo bus behind a USB adapter: measured when connecting, then used for the
//! control period and the bus master's reply timeouts.
//!
//! A microcontroller's UART delivers a reply byte the moment its stop bit arrives. A USB adapter
//! holds the bytes it receives until its latency timer runs out (16 ms on FTDI chips unless set to
//! 1 ms; CDC-ACM adapters send every 1 ms USB frame), so a reply can come that much later than its
//! wire time, and a packet may arrive in two pieces that far apart. The measurement times sync
//! reads of every servo's position, the first half of each control cycle and the one with a reply;
//! what a read takes beyond its wire time and the servos' return delays is the adapter's latency.

use anyhow::{bail, Result};
use embedded_io::{Read, ReadReady, Write};
use firmware::bus::master::{BusConfig, Clock, Master, NoDirectionPin};
use firmware::bus::table::Model;
use firmware::bus::timing::{sync_read_request_len, sync_write_len, wire_time_ns};
use firmware::controller::minimum_period_us;

/// Sync reads timed when connecting.
pub const SAMPLES: usize = 20;

/// Control periods the PC place chooses from (µs): the firmware's 100 Hz when the bus allows it,
/// else the first that leaves the cycle [`HEADROOM`] of the period.
pub const PERIODS_US: [u32; 6] = [10_000, 20_000, 25_000, 40_000, 50_000, 100_000];

/// The fraction of a period one bus cycle may take: the rest absorbs the PC's scheduling jitter
/// and an occasional retry.
pub const HEADROOM: f64 = 0.7;

/// What the sync reads took.
#[derive(Clone, Debug, PartialEq)]
pub struct Measured {
    /// Each read's round trip, µs, in order.
    pub reads_us: Vec<u64>,
    /// Wire time of a read request and its replies plus the return delays, µs: what a read takes
    /// on a microcontroller's UART.
    pub wire_read_us: u64,
    /// Wire time of the cycle's sync write of goals, µs (it has no reply to wait for).
    pub wire_write_us: u64,
}

impl Measured {
    /// The median read, µs.
    pub fn median_us(&self) -> u64 {
        let mut sorted = self.reads_us.clone();
        sorted.sort_unstable();
        sorted.get(sorted.len() / 2).copied().unwrap_or(0)
    }

    /// The longest read, µs.
    pub fn max_us(&self) -> u64 {
        self.reads_us.iter().copied().max().unwrap_or(0)
    }

    /// The adapter's latency: the longest read less its wire time, µs.
    pub fn latency_us(&self) -> u64 {
        self.max_us().saturating_sub(self.wire_read_us)
    }

    /// The longest control cycle seen: the longest read plus the sync write, µs.
    pub fn cycle_us(&self) -> u64 {
        self.max_us() + self.wire_write_us
    }
}

/// Times [`SAMPLES`] sync reads of the present position of `ids`; fails when a servo does not
/// answer them.
pub fn measure<P, C>(master: &mut Master<P, NoDirectionPin, C>, model: &Model, ids: &[u8]) -> Result<Measured>
where
    P: Read + Write + ReadReady,
    P::Error: std::fmt::Debug,
    C: Clock,
{
    let item = model.items.present_position;
    let config = *master.config();
    let mut out = vec![0u8; ids.len() * item.len()];
    let mut reads_us = Vec::with_capacity(SAMPLES);
    for _ in 0..SAMPLES {
        let start = master.clock().now_us();
        let report = master
            .sync_read(item.address, u16::from(item.size), ids, &mut out)
            .map_err(|e| anyhow::anyhow!("timing the bus: {e}"))?;
        let took = master.clock().now_us().saturating_sub(start);
        if !report.complete() {
            let missing: Vec<String> = report.missing(ids).map(|id| id.to_string()).collect();
            bail!("servo {} stopped answering while the bus was timed", missing.join(", "));
        }
        // A retried read is not one cycle: only first-attempt reads time the adapter.
        if report.attempts == 1 {
            reads_us.push(took);
        }
    }
    if reads_us.len() < SAMPLES / 2 {
        bail!("the bus needed retries on {} of {SAMPLES} reads while it was timed", SAMPLES - reads_us.len());
    }
    Ok(Measured::of(reads_us, &config, model, ids.len()))
}

impl Measured {
    /// `reads_us`, timed sync reads of the present position of `servos` servos of `model` on a
    /// bus run as `config`, with the wire times they are judged against.
    pub fn of(reads_us: Vec<u64>, config: &BusConfig, model: &Model, servos: usize) -> Self {
        let protocol = config.protocol;
        let replies = servos * protocol.status_len(model.items.present_position.len());
        let wire_read_ns = wire_time_ns(sync_read_request_len(protocol, servos) + replies, config.baud)
            + servos as u64 * u64::from(config.return_delay_us) * 1000;
        let goal = model.items.goal_position.len();
        let wire_write_ns = wire_time_ns(sync_write_len(protocol, servos, goal), config.baud);
        Self { reads_us, wire_read_us: wire_read_ns.div_ceil(1000), wire_write_us: wire_write_ns.div_ceil(1000) }
    }
}

/// How the bus is run, once measured.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Choice {
    /// The control period, µs.
    pub period_us: u32,
    /// The bus configuration: reply margin and idle gap follow the measured latency.
    pub bus: BusConfig,
}

/// The reply margin and idle gap for a measured adapter latency (µs): the latency and a quarter
/// more, plus the 1 ms a microcontroller's master allows for the servo's own processing; a packet
/// split across two USB transfers arrives a latency apart, so the idle gap that ends a packet
/// must outlast that too.
pub fn margins(bus: BusConfig, latency_us: u64) -> BusConfig {
    let latency = u32::try_from(latency_us).unwrap_or(u32::MAX / 2);
    let margin = latency.saturating_add(latency / 4).saturating_add(1000);
    BusConfig { margin_us: margin.max(bus.margin_us), idle_gap_us: margin.max(bus.idle_gap_us), ..bus }
}

/// The control period and bus configuration for what was measured; an error when no period of
/// [`PERIODS_US`] fits.
pub fn choose(measured: &Measured, bus: BusConfig, model: &Model, joints: usize) -> Result<Choice> {
    let bus = margins(bus, measured.latency_us());
    let minimum = minimum_period_us(model, &bus, joints);
    let cycle = measured.cycle_us() as f64;
    match PERIODS_US.iter().find(|&&p| p >= minimum && cycle <= HEADROOM * f64::from(p)) {
        Some(&period_us) => Ok(Choice { period_us, bus }),
        None => bail!(
            "one bus cycle takes up to {:.1} ms (sync read {:.1} ms, {:.1} ms of it the adapter's latency): too slow \
             for a control loop of at most {} ms",
            cycle * 1e-3,
            measured.max_us() as f64 * 1e-3,
            measured.latency_us() as f64 * 1e-3,
            PERIODS_US[PERIODS_US.len() - 1] / 1000
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use firmware::bus::table::STS3215;
    use firmware::bus::Protocol;

    fn measured(reads_us: Vec<u64>) -> Measured {
        Measured { reads_us, wire_read_us: 800, wire_write_us: 300 }
    }

    #[test]
    fn a_fast_adapter_keeps_the_firmwares_100_hz_and_its_margins() {
        let bus = BusConfig::new(Protocol::Feetech, 1_000_000);
        let m = measured(vec![900, 1000, 950, 1100]);
        assert_eq!(m.median_us(), 1000);
        assert_eq!(m.latency_us(), 300);
        let c = choose(&m, bus, &STS3215, 6).unwrap();
        assert_eq!(c.period_us, 10_000);
        // 300 µs of latency: 300 + 75 + 1000.
        assert_eq!(c.bus.margin_us, 1375);
        assert_eq!(c.bus.idle_gap_us, 1375);
    }

    #[test]
    fn a_16_ms_latency_timer_gets_a_25_ms_period_and_timeouts_beyond_it() {
        let bus = BusConfig::new(Protocol::Feetech, 1_000_000);
        // Replies held by the latency timer: anywhere up to 16 ms late.
        let m = measured(vec![3_000, 9_000, 16_800, 12_000]);
        let c = choose(&m, bus, &STS3215, 6).unwrap();
        assert_eq!(c.period_us, 25_000);
        assert_eq!(c.bus.margin_us, 16_000 + 4_000 + 1000);
        assert!(c.bus.idle_gap_us > 16_000);
    }

    #[test]
    fn a_bus_too_slow_for_any_period_is_refused_in_one_line() {
        let bus = BusConfig::new(Protocol::Feetech, 1_000_000);
        let e = choose(&measured(vec![90_000]), bus, &STS3215, 6).unwrap_err().to_string();
        assert!(e.starts_with("one bus cycle takes up to 90.3 ms"), "{e}");
        assert!(!e.contains('\n'));
    }
}
