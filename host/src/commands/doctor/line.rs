//! The line and the adapter: whether the adapter hears itself, its latency timer, how many
//! replies a few hundred sync reads lose, and whether a control cycle fits the control period at
//! this baud rate and latency.
//!
//! The error rate is measured with no retries, so that every lost or corrupt reply counts: the
//! master's retries would hide a loose cable until it gets worse.

use std::path::Path;

use firmware::bus::master::{BusConfig, Clock};
use firmware::bus::table::Model;
use firmware::bus::Id;

use super::finding::Finding;
use crate::runtime::pc::latency::{latency_timer, LatencyTimer, ADVISED_MS, UDEV_RULE, UDEV_RULE_FILE};
use crate::runtime::pc::timing::{self, margins, Measured, PERIODS_US};
use crate::runtime::servo_session::{Port, Session};

/// Sync reads for the error rate, unless `--reads` says otherwise.
pub const DEFAULT_READS: u32 = 300;

/// How late a reply may come in the error-rate reads and still count as received, µs: three
/// expiries of a 16 ms latency timer.
pub const LATE_REPLY_US: u64 = 50_000;

/// Lost replies above this fraction fail the line (below it, any loss is a warning).
pub const FAIL_RATE: f64 = 0.01;

/// A median reply later than this (ms) beyond its wire time is an adapter holding replies: a
/// CDC-ACM adapter passes them on within a 1 ms USB frame, an FTDI chip at 1 ms within about 2.
pub const HELD_MS: f64 = 3.0;

/// The share of reads [`cycle`] judges by: one read in a hundred may run late (a busy PC, a
/// retry) without slowing the control period, as the control loop absorbs it.
pub const CYCLE_QUANTILE: f64 = 0.99;

/// The median read's time beyond its wire time, µs.
pub fn median_latency_us(m: &Measured) -> u64 {
    m.median_us().saturating_sub(m.wire_read_us)
}

/// The read time at `q` (0 to 1) of the sorted reads, µs.
pub fn quantile_us(m: &Measured, q: f64) -> u64 {
    let mut sorted = m.reads_us.clone();
    sorted.sort_unstable();
    let at = ((sorted.len() as f64 - 1.0) * q).round() as usize;
    sorted.get(at).copied().unwrap_or(0)
}

/// What the line did.
#[derive(Clone, Debug, Default)]
pub struct LineReport {
    /// The adapter gives back what it sends.
    pub echo: bool,
    /// The adapter's latency timer, where the system shows one.
    pub latency_timer: Option<LatencyTimer>,
    /// The timed sync reads, or why they could not be timed.
    pub timing: Option<Result<Measured, String>>,
    /// Sync reads made for the error rate.
    pub reads: u32,
    /// Replies they asked for.
    pub replies: u64,
    /// Replies that did not come, or came corrupt.
    pub lost: u64,
    /// Of those, replies that came with a bad checksum.
    pub corrupt: u64,
    /// The bus configuration in use.
    pub bus: Option<BusConfig>,
    /// Servos on the bus.
    pub servos: usize,
}

/// Measures the line: `reads` sync reads of the present position of `ids`, with no retries.
pub fn measure<P: Port, C: Clock>(
    session: &mut Session<P, C>,
    path: &Path,
    model: &Model,
    ids: &[Id],
    reads: u32,
    echo: bool,
) -> LineReport {
    let config = session.config();
    let mut report = LineReport {
        echo,
        latency_timer: latency_timer(Path::new("/sys"), path),
        servos: ids.len(),
        // The configuration `armctl --bus` starts from (its margins follow the latency measured),
        // not the doctor's own long scan timeouts.
        bus: Some(BusConfig {
            return_delay_us: config.return_delay_us,
            echo: config.echo,
            ..BusConfig::new(config.protocol, config.baud)
        }),
        ..LineReport::default()
    };
    // No retries, and a reply timeout well past any adapter's latency: a late reply is a slow
    // read (the cycle's and the adapter's findings), not a lost one.
    session.set_config(BusConfig { retries: 0, ..margins(config, LATE_REPLY_US) });
    let item = model.items.present_position;
    let mut out = vec![0u8; ids.len() * item.len()];
    let before = session.master_mut().stats().bad_checksums;
    let mut reads_us = Vec::with_capacity(reads as usize);
    for _ in 0..reads {
        let start = session.master_mut().clock().now_us();
        match session.master_mut().sync_read(item.address, u16::from(item.size), ids, &mut out) {
            Ok(r) => {
                let took = session.master_mut().clock().now_us().saturating_sub(start);
                report.reads += 1;
                report.replies += ids.len() as u64;
                let lost = r.missing(ids).count() as u64;
                report.lost += lost;
                if lost == 0 {
                    reads_us.push(took);
                }
            }
            Err(_) => break,
        }
    }
    // The reads are timed as `armctl --bus` times its 20 when it connects (`timing::measure`),
    // a few hundred instead, so that one late reply on a busy PC does not decide alone; only
    // reads every servo answered time a cycle.
    report.timing = Some(if reads_us.is_empty() {
        Err("no sync read was answered by every servo".to_string())
    } else {
        Ok(Measured::of(reads_us, &config, model, ids.len()))
    });
    report.corrupt = u64::from(session.master_mut().stats().bad_checksums.saturating_sub(before));
    session.set_config(config);
    report
}

/// `adapter`: no echo, a short latency timer.
pub fn adapter(line: &LineReport) -> Vec<Finding> {
    let mut findings = Vec::new();
    if line.echo {
        findings.push(Finding::fail(
            "adapter",
            "the adapter hears its own transmission: every request comes back before its reply, which the servo SDKs \
             (and armctl --bus) take for a garbled reply",
            "use a half-duplex adapter that switches direction (U2D2, Feetech URT-1, Waveshare's bus servo adapter), or \
             set the board's jumper or switch for USB-to-servo mode",
        ));
    }
    match &line.latency_timer {
        Some(t) if t.ms > ADVISED_MS => findings.push(Finding::warn(
            "adapter",
            format!("{}'s latency timer is {} ms: each reply can arrive up to {} ms late", t.device, t.ms, t.ms),
            format!(
                "armctl doctor --fix writes {ADVISED_MS} ms (needs write access to {}), or: echo {ADVISED_MS} | sudo tee {}; for \
                 good: echo '{UDEV_RULE}' | sudo tee {UDEV_RULE_FILE}",
                t.file.display(),
                t.file.display()
            ),
        )),
        Some(t) => findings.push(Finding::ok("adapter", format!("{}'s latency timer is {} ms", t.device, t.ms))),
        None => {}
    }
    if let Some(Ok(m)) = &line.timing {
        // The median: a 16 ms timer holds a typical reply 8 ms, while a busy PC delays a few.
        let latency_ms = median_latency_us(m) as f64 / 1000.0;
        if latency_ms > HELD_MS {
            findings.push(Finding::warn(
                "adapter",
                format!(
                    "replies arrive {latency_ms:.1} ms after their wire time (median): the adapter holds them (an FTDI \
                     chip's latency timer is 16 ms from the factory)"
                ),
                "set the adapter's latency timer to 1 ms (Linux: /sys/bus/usb-serial/devices/ttyUSBn/latency_timer; \
                 Windows: the port's Advanced settings; macOS: the FTDI driver's latency setting)",
            ));
        } else if !line.echo && findings.is_empty() {
            findings.push(Finding::ok(
                "adapter",
                format!("no echo; replies {latency_ms:.1} ms after their wire time (median)"),
            ));
        }
    }
    findings
}

/// `line`: the share of replies lost or corrupt over the sync reads.
pub fn line(line: &LineReport) -> Vec<Finding> {
    if line.reads == 0 {
        return vec![Finding::fail(
            "line",
            "no sync read went through",
            "check the cable and the adapter; run armctl doctor again with one servo connected",
        )];
    }
    let rate = line.lost as f64 / line.replies.max(1) as f64;
    let what = format!(
        "{} of {} replies lost or corrupt ({:.2} %, {} with a bad checksum) in {} sync reads without retries",
        line.lost,
        line.replies,
        rate * 100.0,
        line.corrupt,
        line.reads
    );
    let fix = "a loose or long cable, or mixed servo firmware: reseat every connector, shorten the chain, check the \
               supply; then run armctl doctor again";
    if line.lost == 0 {
        vec![Finding::ok("line", what)]
    } else if rate < FAIL_RATE {
        vec![Finding::warn("line", what, fix)]
    } else {
        vec![Finding::fail("line", what, fix)]
    }
}

/// `cycle`: whether a control cycle (a sync write of goals and a sync read of positions) fits
/// the firmware's control period on this adapter, as `armctl --bus` will measure it.
pub fn cycle(line: &LineReport, model: &Model) -> Vec<Finding> {
    let (Some(Ok(m)), Some(bus)) = (&line.timing, line.bus) else {
        let why = match &line.timing {
            Some(Err(e)) => e.clone(),
            _ => "the bus could not be timed".to_string(),
        };
        return vec![Finding::fail(
            "cycle",
            format!("the control cycle could not be timed: {why}"),
            "fix the findings above first",
        )];
    };
    // The period is chosen as `armctl --bus` chooses it, from the reads up to the quantile.
    let read_us = quantile_us(m, CYCLE_QUANTILE);
    let m = &Measured { reads_us: vec![read_us], ..m.clone() };
    let cycle_ms = m.cycle_us() as f64 / 1000.0;
    let fastest = PERIODS_US[0];
    match timing::choose(m, bus, model, line.servos) {
        Ok(choice) if choice.period_us == fastest => vec![Finding::ok(
            "cycle",
            format!(
                "a control cycle takes {cycle_ms:.1} ms (99th percentile) of the {} ms period at {} baud ({} servos)",
                fastest / 1000,
                bus.baud,
                line.servos
            ),
        )],
        Ok(choice) => vec![Finding::warn(
            "cycle",
            format!(
                "a control cycle takes {cycle_ms:.1} ms (99th percentile; {:.1} ms of it the adapter's latency): armctl --bus \
                 will run at {} ms ({:.0} Hz) instead of {} ms",
                m.latency_us() as f64 / 1000.0,
                choice.period_us / 1000,
                1e6 / f64::from(choice.period_us),
                fastest / 1000
            ),
            "set the adapter's latency timer to 1 ms, the return delay to 0, or a faster baud rate",
        )],
        Err(e) => vec![Finding::fail("cycle", e.to_string(), "set the latency timer to 1 ms and the return delay to 0")],
    }
}

#[cfg(test)]
mod tests {
    use super::super::finding::Level;
    use super::*;
    use firmware::bus::table::STS3215;
    use firmware::bus::Protocol;

    fn report(reads_us: Vec<u64>, lost: u64) -> LineReport {
        LineReport {
            timing: Some(Ok(Measured { reads_us, wire_read_us: 800, wire_write_us: 300 })),
            reads: 300,
            replies: 1800,
            lost,
            bus: Some(BusConfig::new(Protocol::Feetech, 1_000_000)),
            servos: 6,
            ..LineReport::default()
        }
    }

    #[test]
    fn a_clean_line() {
        let r = report(vec![900, 1000], 0);
        assert_eq!(adapter(&r)[0].level, Level::Ok);
        assert_eq!(line(&r)[0].level, Level::Ok);
        assert_eq!(cycle(&r, &STS3215)[0].level, Level::Ok);
    }

    #[test]
    fn lost_replies_warn_then_fail() {
        assert_eq!(line(&report(vec![900], 3))[0].level, Level::Warn);
        let f = line(&report(vec![900], 40));
        assert_eq!(f[0].level, Level::Fail);
        assert!(f[0].message.starts_with("40 of 1800 replies lost or corrupt (2.22 %"), "{}", f[0].message);
    }

    #[test]
    fn a_16_ms_adapter_slows_the_cycle() {
        let r = report(vec![3_000, 16_800], 0);
        assert_eq!(adapter(&r)[0].level, Level::Warn);
        let f = cycle(&r, &STS3215);
        assert_eq!(f[0].level, Level::Warn);
        assert!(f[0].message.contains("25 ms (40 Hz)"), "{}", f[0].message);
    }

    #[test]
    fn an_echo_fails() {
        let r = LineReport { echo: true, ..report(vec![900], 0) };
        assert_eq!(adapter(&r)[0].level, Level::Fail);
    }
}
