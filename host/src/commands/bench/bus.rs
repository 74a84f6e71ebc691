//! `armctl bench bus`: the wire time of one control cycle (a sync write of goal positions and a
//! sync read of present positions) for N servos at a baud rate, computed and simulated.
//!
//! The computed figure is the arithmetic of `firmware::bus::timing` (10 bits per byte plus each
//! servo's return delay), the same the SIL clock charges. The simulated figure runs the firmware's
//! own cycle (`ServoGroup::cycle` on its `Master`) against simulated servos on the virtual clock,
//! so it also shows that the cycle sends no more bytes than the protocol's minimum.

use std::io::Write;

use anyhow::{bail, Result};
use firmware::bus::cycle::ServoGroup;
use firmware::bus::master::{BusConfig, Master, NoDirectionPin};
use firmware::bus::table::Model;
use firmware::bus::timing::{cycle_bytes, cycle_time_ns, sync_read_request_len, sync_write_len};
use serde_json::json;

use crate::sim::{connect, SimBus};

/// What `armctl bench bus` measures.
#[derive(Clone, Copy, Debug)]
pub struct BusBenchRequest {
    /// The servos' model; the bus speaks its protocol.
    pub model: &'static Model,
    /// Number of servos (ids 1..=N), 1 to 16.
    pub servos: usize,
    /// Baud rate.
    pub baud: u32,
    /// The servos' return delay in microseconds (`None`: the model's factory setting, 500 us on
    /// the X-series, 0 on the STS3215); rounded down to the model's 2 us unit.
    pub return_delay_us: Option<u32>,
    /// Control cycles simulated (the median is reported).
    pub cycles: usize,
}

/// One cycle's simulated figures.
struct Simulated {
    bytes_sent: u64,
    bytes_received: u64,
    cycle_ns: Vec<u64>,
    complete: usize,
}

fn simulate<const N: usize>(model: &'static Model, baud: u32, delay_units: i64, cycles: usize) -> Simulated {
    let ids: [u8; N] = core::array::from_fn(|i| i as u8 + 1);
    let mut bus = SimBus::new(model.protocol, model, &ids, baud);
    for servo in bus.servos_mut() {
        servo.set(model.items.return_delay, delay_units);
    }
    let (_bus, port, clock) = connect(bus);
    let mut config = BusConfig::new(model.protocol, baud);
    config.return_delay_us = (delay_units as u32) * model.return_delay_unit_us;
    let mut master: Master<_, _, _> = Master::new(port, NoDirectionPin, clock.clone(), config);
    let group = ServoGroup::new(model, ids);
    let goals = [2048i32; N];
    let mut positions = [0i32; N];
    let mut cycle_ns = Vec::with_capacity(cycles);
    let mut complete = 0;
    let before = master.stats();
    for _ in 0..cycles {
        let start = clock.now_ns();
        if let Ok(report) = group.cycle(&mut master, &goals, &mut positions) {
            complete += usize::from(report.complete());
        }
        cycle_ns.push(clock.now_ns() - start);
    }
    let after = master.stats();
    let n = cycles.max(1) as u64;
    Simulated {
        bytes_sent: (after.bytes_sent - before.bytes_sent) / n,
        bytes_received: (after.bytes_received - before.bytes_received) / n,
        cycle_ns,
        complete,
    }
}

macro_rules! dispatch {
    ($n:expr, $model:expr, $baud:expr, $delay:expr, $cycles:expr; $($k:literal)*) => {
        match $n {
            $($k => simulate::<$k>($model, $baud, $delay, $cycles),)*
            _ => bail!("--servos must be 1 to 16"),
        }
    };
}

/// Runs `armctl bench bus`: one JSON object on `out`.
pub fn run(args: &BusBenchRequest, out: &mut dyn Write) -> Result<i32> {
    let model = args.model;
    let protocol = model.protocol;
    if model.baud_index(args.baud).is_none() {
        bail!("{} has no baud index for {}", model.name, args.baud);
    }
    if args.cycles == 0 {
        bail!("--cycles must be at least 1");
    }
    let factory = model.defaults.iter().find(|(item, _)| *item == model.items.return_delay).map_or(0, |(_, v)| *v);
    let delay_units = match args.return_delay_us {
        Some(us) => i64::from(us / model.return_delay_unit_us),
        None => factory,
    };
    if delay_units > 254 {
        bail!("--return-delay-us is at most {} on the {}", 254 * model.return_delay_unit_us, model.name);
    }
    let return_delay_us = delay_units as u32 * model.return_delay_unit_us;
    let (goal, position) = (model.items.goal_position.len(), model.items.present_position.len());
    let n = args.servos;
    let sim = dispatch!(n, model, args.baud, delay_units, args.cycles; 1 2 3 4 5 6 7 8 9 10 11 12 13 14 15 16);
    let mut sorted = sim.cycle_ns.clone();
    sorted.sort_unstable();
    let median_ns = sorted[sorted.len() / 2];
    let computed_ns = cycle_time_ns(protocol, n, goal, position, args.baud, return_delay_us);
    let request_bytes = sync_write_len(protocol, n, goal) + sync_read_request_len(protocol, n);
    let ms = |ns: u64| ns as f64 / 1e6;
    let report = json!({
        "protocol": protocol.name(),
        "model": model.name,
        "servos": n,
        "baud": args.baud,
        "return_delay_us": return_delay_us,
        "cycle_bytes": cycle_bytes(protocol, n, goal, position),
        "min_request_bytes": request_bytes,
        "sent_bytes_per_cycle": sim.bytes_sent,
        "received_bytes_per_cycle": sim.bytes_received,
        "computed_cycle_ms": ms(computed_ns),
        "simulated_cycle_ms_median": ms(median_ns),
        "max_rate_hz": 1e9 / median_ns as f64,
        "complete_cycles": sim.complete,
        "cycles": args.cycles,
    });
    writeln!(out, "{}", serde_json::to_string_pretty(&report)?)?;
    Ok(if sim.bytes_sent as usize > request_bytes { 1 } else { 0 })
}
