//! `armctl bench rate`: the control rate the firmware's controller reaches on a servo bus, against
//! the wire-time limit of that bus.
//!
//! The firmware's [`Controller`] drives six simulated servos (the UR5e preset's chain, its joint
//! range cut to the servos' tick range by [`joint_limits`]) through the firmware's own bus master on
//! the virtual clock, with a joint move always in progress, so every tick reads every position and
//! writes changing goals. Two schedules run for the same virtual time:
//!
//! - back to back: each tick starts when the previous one ended, as a firmware running flat out
//!   would. Its rate is compared with the wire-time limit, `1e9 / cycle_time_ns`: the rate of a bus
//!   carrying nothing but the minimal cycle (`firmware::bus::timing::cycle_bytes` plus each
//!   servo's return delay).
//! - fixed period: ticks on the period the controller is configured with,
//!   [`minimum_period_us`] (the cycle plus the master's reply margin); no tick may miss its deadline.
//!
//! Compute time is free on the virtual clock: only the wire and the servos' return delays move it.
//! The rates are what the bus allows the controller's traffic; the compute budget on a board is
//! the hardware-in-the-loop measurement (instruction counts). One more thing moves it: before each
//! send the master checks for stale input with `read_ready`, which the simulated port answers on an
//! empty line by advancing one poll step (one byte time). That is two byte times per tick (a sync
//! read and a sync write) a board's UART does not spend, so the back-to-back rate here is 1 to 2 %
//! below what the wire alone allows.

use std::io::Write;

use anyhow::{anyhow, bail, Result};
use firmware::bus::mapping::JointMapping;
use firmware::bus::master::{BusConfig, Master, NoDirectionPin};
use firmware::bus::table::Model;
use firmware::bus::timing::{cycle_bytes, cycle_time_ns};
use firmware::controller::{joint_limits, minimum_period_us, Command, Config, Controller, Mode};
use kinematics::nalgebra::SVector;
use kinematics::presets;
use serde_json::{json, Value};

use crate::sim::{connect, SharedBus, SimBus, VirtualClock};

/// Joints of the driven chain (the UR5e preset).
pub const SERVOS: usize = 6;
/// Joint velocity limit of the bench, rad/s.
const VMAX: f32 = 2.0;
/// Joint acceleration limit of the bench, rad/s².
const AMAX: f32 = 10.0;
/// The two ends of the back-and-forth joint move, rad (inside every servo's ±π).
const MOVE_TO: [f32; SERVOS] = [1.0, -0.8, 0.9, -1.0, 0.7, -0.6];

/// What `armctl bench rate` is asked for, before it is checked into a [`RateSetup`].
#[derive(Clone, Copy, Debug)]
pub struct RateBenchRequest {
    /// The servos' model; the bus speaks its protocol.
    pub model: &'static Model,
    /// Number of servos: [`SERVOS`] only (the bench drives the UR5e preset's 6-joint chain).
    pub servos: usize,
    /// Baud rate.
    pub baud: u32,
    /// The servos' return delay in microseconds, set on the simulated servos and in the master's
    /// bus configuration; rounded down to the model's 2 us unit.
    pub return_delay_us: u32,
    /// Virtual seconds each schedule runs (compute time is free on the virtual clock).
    pub seconds: f64,
    /// One JSON object (indented) instead of the table.
    pub json: bool,
}

/// What is measured.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RateSetup {
    /// The servos' model (its protocol is the bus's).
    pub model: &'static Model,
    /// Baud rate.
    pub baud: u32,
    /// The servos' return delay, µs (a multiple of the model's unit).
    pub return_delay_us: u32,
    /// Virtual seconds each schedule runs.
    pub seconds: f64,
}

/// When ticks start.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Schedule {
    /// Each tick when the previous one ended.
    BackToBack,
    /// Every `period_us` (the controller's configured period).
    FixedPeriod,
}

/// The figures of one schedule, over the measured ticks (set-up ticks excluded).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RateRun {
    /// The schedule.
    pub schedule: Schedule,
    /// Ticks run.
    pub ticks: u32,
    /// Virtual seconds from the first tick's start to the start the next tick would have.
    pub seconds: f64,
    /// Ticks per virtual second.
    pub rate_hz: f64,
    /// The controller's deadline misses.
    pub deadline_misses: u32,
    /// The controller's missing replies (servo positions that did not arrive).
    pub missing_replies: u32,
    /// Bus transactions that failed on the port.
    pub bus_errors: u32,
    /// Bytes on the wire (sent plus received) per tick, on average.
    pub bytes_per_tick: f64,
    /// Goals received by a servo outside its joint's limits (summed over servos and ticks).
    pub goals_outside_limits: u32,
    /// Ticks after which some servo's goal differed from the one before.
    pub ticks_with_new_goals: u32,
    /// Joint moves commanded (a new one each time the previous ended).
    pub moves: u32,
    /// Longest work time of a tick as the controller measured it, µs.
    pub max_loop_us: u32,
}

/// Both schedules' figures and the wire-time limit they are compared with.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RateReport {
    /// The set-up.
    pub setup: RateSetup,
    /// Servos on the bus.
    pub servos: usize,
    /// The least bytes of one control cycle.
    pub cycle_bytes: usize,
    /// Wire time of the minimal cycle plus the return delays, ns.
    pub cycle_ns: u64,
    /// The wire-time limit: `1e9 / cycle_ns`, Hz.
    pub limit_hz: f64,
    /// The controller's period: [`minimum_period_us`] of the bus.
    pub period_us: u32,
    /// Ticks back to back.
    pub back_to_back: RateRun,
    /// Ticks on the controller's period.
    pub fixed_period: RateRun,
}

impl RateReport {
    /// Back-to-back rate over the wire-time limit.
    pub fn ratio(&self) -> f64 {
        self.back_to_back.rate_hz / self.limit_hz
    }
}

/// The controller, its bus master and the simulated servos behind it.
struct Rig {
    bus: SharedBus,
    clock: VirtualClock,
    master: Master<crate::sim::SimPort, NoDirectionPin, VirtualClock>,
    ctl: Controller<SERVOS, 8>,
    /// Each joint's allowed goal range in ticks.
    goal_range: [(i64, i64); SERVOS],
}

impl Rig {
    fn new(setup: &RateSetup) -> Result<Self> {
        let model = setup.model;
        let ids: [u8; SERVOS] = core::array::from_fn(|i| i as u8 + 1);
        let mut bus = SimBus::new(model.protocol, model, &ids, setup.baud);
        let delay_units = setup.return_delay_us / model.return_delay_unit_us.max(1);
        for servo in bus.servos_mut() {
            servo.set(model.items.return_delay, i64::from(delay_units));
        }
        let (bus, port, clock) = connect(bus);
        let mut bus_config = BusConfig::new(model.protocol, setup.baud);
        bus_config.return_delay_us = setup.return_delay_us;
        let master = Master::new(port, NoDirectionPin, clock.clone(), bus_config);
        let chain = presets::ur5e::<f32>().map_err(|e| anyhow!("UR5e preset: {e:?}"))?;
        let mappings = ids.map(|id| JointMapping::centred(id, model.ticks_per_revolution));
        let limits = joint_limits(&chain, &mappings, SVector::repeat(VMAX), SVector::repeat(AMAX))
            .map_err(|e| anyhow!("joint limits: {e}"))?;
        let goal_range = core::array::from_fn(|j| {
            let a = mappings[j].to_ticks(limits.lower[j]).map_or(i64::MIN, i64::from);
            let b = mappings[j].to_ticks(limits.upper[j]).map_or(i64::MAX, i64::from);
            (a.min(b), a.max(b))
        });
        let period_us = minimum_period_us(model, &bus_config, SERVOS);
        let config = Config { period_us, ..Config::default() };
        let ctl = Controller::new(chain, mappings, model, limits, config).map_err(|e| anyhow!("controller: {e}"))?;
        Ok(Self { bus, clock, master, ctl, goal_range })
    }

    fn goals(&self) -> [i64; SERVOS] {
        let model = self.bus.borrow().model();
        let mut bus = self.bus.borrow_mut();
        bus.advance_to(self.clock.now_ns());
        core::array::from_fn(|j| bus.servo(j as u8 + 1).map_or(i64::MIN, |s| s.get(model.items.goal_position)))
    }

    /// Reads the positions, turns the torque on (holding) and returns when the measured ticks
    /// start, µs: once the set-up ticks are over, as the torque-on tick writes more than a cycle
    /// and the tick after it reads the torque back (one plain tick follows, so that the first
    /// measured tick does not count that longer one's time as lateness).
    fn start(&mut self) -> Result<u64> {
        self.ctl.tick(&mut self.master, 0);
        let now = self.clock_us();
        self.ctl.command(Command::TorqueOn, now).map_err(|e| anyhow!("torque on refused: {e}"))?;
        self.ctl.tick(&mut self.master, now);
        for _ in 0..2 {
            let now = self.clock_us();
            self.ctl.tick(&mut self.master, now);
        }
        if self.ctl.mode() != Mode::Holding {
            bail!("the controller did not hold after torque on (mode {:?})", self.ctl.mode());
        }
        Ok(self.clock_us())
    }

    /// The virtual clock in whole µs (as the master's clock reads it).
    fn clock_us(&self) -> u64 {
        self.clock.now_ns() / 1000
    }

    /// The start of the tick after the one that started at `now` (µs), with the clock moved there:
    /// when the last one ended, or the next period (a tick that overran starts the next at once).
    fn next_start(&self, schedule: Schedule, now: u64) -> u64 {
        let next = match schedule {
            Schedule::BackToBack => self.clock_us(),
            Schedule::FixedPeriod => (now + u64::from(self.ctl.config().period_us)).max(self.clock_us()),
        };
        self.clock.advance_to(next * 1000);
        next
    }

    fn run(&mut self, schedule: Schedule, seconds: f64) -> Result<RateRun> {
        let mut now = self.start()?;
        let first = now;
        let end = first + (seconds * 1e6).round() as u64;
        let counters = *self.ctl.counters();
        let stats = self.master.stats();
        let mut run = RateRun {
            schedule,
            ticks: 0,
            seconds: 0.0,
            rate_hz: 0.0,
            deadline_misses: 0,
            missing_replies: 0,
            bus_errors: 0,
            bytes_per_tick: 0.0,
            goals_outside_limits: 0,
            ticks_with_new_goals: 0,
            moves: 0,
            max_loop_us: 0,
        };
        let mut last_goals = self.goals();
        let mut forward = true;
        while now < end {
            self.ctl.command(Command::HostAlive, now).map_err(|e| anyhow!("host alive refused: {e}"))?;
            if self.ctl.mode() == Mode::Holding {
                let q = MOVE_TO.map(|x| if forward { x } else { -x });
                forward = !forward;
                self.ctl
                    .command(Command::MoveJoints { q, duration: 0.0 }, now)
                    .map_err(|e| anyhow!("move refused: {e}"))?;
                run.moves += 1;
            }
            let report = self.ctl.tick(&mut self.master, now);
            run.max_loop_us = run.max_loop_us.max(report.loop_us);
            run.ticks += 1;
            let goals = self.goals();
            for (goal, (lo, hi)) in goals.iter().zip(&self.goal_range) {
                run.goals_outside_limits += u32::from(!(lo..=hi).contains(&goal));
            }
            run.ticks_with_new_goals += u32::from(goals != last_goals);
            last_goals = goals;
            now = self.next_start(schedule, now);
        }
        let after = *self.ctl.counters();
        let stats_after = self.master.stats();
        run.seconds = (now - first) as f64 * 1e-6;
        run.rate_hz = f64::from(run.ticks) / run.seconds.max(f64::MIN_POSITIVE);
        run.deadline_misses = after.deadline_misses - counters.deadline_misses;
        run.missing_replies = after.missing_replies - counters.missing_replies;
        run.bus_errors = after.bus_errors - counters.bus_errors;
        let bytes = (stats_after.bytes_sent + stats_after.bytes_received) - (stats.bytes_sent + stats.bytes_received);
        run.bytes_per_tick = bytes as f64 / f64::from(run.ticks.max(1));
        Ok(run)
    }
}

/// Runs both schedules for `setup` with six servos.
pub fn measure(setup: &RateSetup) -> Result<RateReport> {
    if !(setup.seconds > 0.0 && setup.seconds <= 3600.0) {
        bail!("--seconds must be above 0 and at most 3600");
    }
    let model = setup.model;
    let protocol = model.protocol;
    let (goal, position) = (model.items.goal_position.len(), model.items.present_position.len());
    let cycle_ns = cycle_time_ns(protocol, SERVOS, goal, position, setup.baud, setup.return_delay_us);
    let back_to_back = Rig::new(setup)?.run(Schedule::BackToBack, setup.seconds)?;
    let mut rig = Rig::new(setup)?;
    let period_us = rig.ctl.config().period_us;
    let fixed_period = rig.run(Schedule::FixedPeriod, setup.seconds)?;
    Ok(RateReport {
        setup: *setup,
        servos: SERVOS,
        cycle_bytes: cycle_bytes(protocol, SERVOS, goal, position),
        cycle_ns,
        limit_hz: 1e9 / cycle_ns as f64,
        period_us,
        back_to_back,
        fixed_period,
    })
}

fn run_json(run: &RateRun, limit_hz: f64) -> Value {
    json!({
        "ticks": run.ticks,
        "seconds": run.seconds,
        "rate_hz": run.rate_hz,
        "ratio_to_limit": run.rate_hz / limit_hz,
        "deadline_misses": run.deadline_misses,
        "missing_replies": run.missing_replies,
        "bus_errors": run.bus_errors,
        "bytes_per_tick": run.bytes_per_tick,
        "goals_outside_limits": run.goals_outside_limits,
        "ticks_with_new_goals": run.ticks_with_new_goals,
        "moves": run.moves,
        "max_loop_us": run.max_loop_us,
    })
}

/// The report as one JSON object.
pub fn to_json(r: &RateReport) -> Value {
    json!({
        "protocol": r.setup.model.protocol.name(),
        "model": r.setup.model.name,
        "servos": r.servos,
        "baud": r.setup.baud,
        "return_delay_us": r.setup.return_delay_us,
        "cycle_bytes": r.cycle_bytes,
        "cycle_us": r.cycle_ns as f64 / 1e3,
        "wire_time_limit_hz": r.limit_hz,
        "period_us": r.period_us,
        "back_to_back": run_json(&r.back_to_back, r.limit_hz),
        "fixed_period": run_json(&r.fixed_period, r.limit_hz),
    })
}

fn write_table(r: &RateReport, out: &mut dyn Write) -> std::io::Result<()> {
    writeln!(
        out,
        "{} {}, {} servos, {} baud, return delay {} us: {} bytes per cycle, wire-time limit {:.1} Hz ({:.1} us)",
        r.setup.model.protocol.name(),
        r.setup.model.name,
        r.servos,
        r.setup.baud,
        r.setup.return_delay_us,
        r.cycle_bytes,
        r.limit_hz,
        r.cycle_ns as f64 / 1e3,
    )?;
    writeln!(
        out,
        "{:<14} {:>9} {:>7} {:>9} {:>9} {:>6} {:>11} {:>8} {:>11} {:>13}",
        "schedule",
        "period_us",
        "ticks",
        "seconds",
        "rate_hz",
        "ratio",
        "bytes/tick",
        "deadline",
        "no_replies",
        "goals_outside"
    )?;
    for (name, period, run) in
        [("back to back", "-".to_string(), &r.back_to_back), ("fixed period", r.period_us.to_string(), &r.fixed_period)]
    {
        writeln!(
            out,
            "{:<14} {:>9} {:>7} {:>9.4} {:>9.1} {:>6.3} {:>11.1} {:>8} {:>11} {:>13}",
            name,
            period,
            run.ticks,
            run.seconds,
            run.rate_hz,
            run.rate_hz / r.limit_hz,
            run.bytes_per_tick,
            run.deadline_misses,
            run.missing_replies,
            run.goals_outside_limits,
        )?;
    }
    writeln!(out, "(virtual clock: compute time is free; the rates are the bus's share)")
}

/// Runs `armctl bench rate`: the table (or one JSON object) on `out`. Exit code 1 when a reply
/// went missing, a goal left the limits, or a tick on the controller's period missed its deadline.
pub fn run(args: &RateBenchRequest, out: &mut dyn Write) -> Result<i32> {
    let model = args.model;
    if args.servos != SERVOS {
        bail!("--servos must be {SERVOS} (the bench drives the UR5e preset's 6-joint chain)");
    }
    if model.baud_index(args.baud).is_none() {
        bail!("{} has no baud index for {}", model.name, args.baud);
    }
    let units = args.return_delay_us / model.return_delay_unit_us;
    if units > 254 {
        bail!("--return-delay-us is at most {} on the {}", 254 * model.return_delay_unit_us, model.name);
    }
    let setup = RateSetup {
        model,
        baud: args.baud,
        return_delay_us: units * model.return_delay_unit_us,
        seconds: args.seconds,
    };
    let report = measure(&setup)?;
    if args.json {
        writeln!(out, "{}", serde_json::to_string_pretty(&to_json(&report))?)?;
    } else {
        write_table(&report, out)?;
    }
    let bad = |r: &RateRun| r.missing_replies > 0 || r.goals_outside_limits > 0 || r.bus_errors > 0;
    Ok(i32::from(bad(&report.back_to_back) || bad(&report.fixed_period) || report.fixed_period.deadline_misses > 0))
}
