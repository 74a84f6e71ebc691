//! `armctl bench servos`: what the simulator's physical servos ([`crate::sim::drive`]) cost on
//! this PC. The arm's servos on a bus with physics move between random configurations (a new goal
//! for every joint each half second, fixed seed) for a number of virtual seconds; each virtual
//! second is timed on the wall clock, and the figure is its median per servo per step, against the
//! same bus with ideal servos. A benchmark, not a test: the figures go in docs/servo-model.md.

use std::io::Write;
use std::time::Instant;

use anyhow::{anyhow, bail, Result};
use kinematics::SplitMix64;
use serde::Serialize;

use crate::arm::dof::build;
use crate::arm::servos::servos_of;
use crate::arm::ArmSpec;
use crate::sim::drive::STEP_NS;
use crate::sim::physics::ServoKind;
use crate::sim::SimBus;

/// A `bench servos` run.
#[derive(Clone, Debug, PartialEq)]
pub struct ServosBenchRequest {
    /// The arm (a preset or an arm file with servos).
    pub arm: String,
    /// Virtual seconds simulated (each timed on its own).
    pub seconds: usize,
}

/// Its figures.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ServosBenchReport {
    /// The arm.
    pub arm: String,
    /// Servos on its bus.
    pub servos: usize,
    /// Whether its links have masses (gravity and inertia reach the servos).
    pub gravity: bool,
    /// The drive's step, us of virtual time.
    pub step_us: f64,
    /// Wall time per servo per step with physics, median over the virtual seconds (ns).
    pub physical_ns_per_servo_step: f64,
    /// The same bus with ideal servos, per servo per step of the same length (ns).
    pub ideal_ns_per_servo_step: f64,
    /// Virtual seconds simulated per wall second with physics, median.
    pub physical_real_time_factor: f64,
}

/// Runs the benchmark and prints its report (one JSON object with `json`, else one line).
pub fn run(request: &ServosBenchRequest, json: bool, out: &mut dyn Write) -> Result<i32> {
    if request.seconds == 0 || request.seconds > 600 {
        bail!("--seconds must be 1 to 600");
    }
    let arm = ArmSpec::load(&request.arm, None)?;
    let report = measure(&arm, request.seconds)?;
    if json {
        writeln!(out, "{}", serde_json::to_string_pretty(&report)?)?;
    } else {
        writeln!(
            out,
            "bench servos, {} ({} servos, {}): {:.0} ns per servo per {:.0} us step with physics (median of {} \
             virtual seconds), {:.0} ns ideal; {:.0} virtual seconds per second",
            report.arm,
            report.servos,
            if report.gravity { "links with mass" } else { "no link masses" },
            report.physical_ns_per_servo_step,
            report.step_us,
            request.seconds,
            report.ideal_ns_per_servo_step,
            report.physical_real_time_factor,
        )?;
    }
    Ok(0)
}

/// Each virtual second's wall time (s) on `arm`'s bus with `kind` servos.
fn seconds_timed(arm: &ArmSpec, kind: ServoKind, seconds: usize) -> Result<Vec<f64>> {
    let servos = servos_of(arm).ok_or_else(|| anyhow!("arm {} has no servos", arm.name))?;
    let model = servos.model;
    let physics = kind.physics(Some(arm))?;
    let mut bus = SimBus::new(model.protocol, model, &servos.bus_ids(), servos.baud).with_physics(physics);
    let built = build(arm.clone())?;
    let mut rng = SplitMix64::new(7);
    let ids = servos.bus_ids();
    for servo in bus.servos_mut() {
        servo.set_register(model.items.torque_enable, 1, 0).map_err(|e| anyhow!(e))?;
    }
    let mut times = Vec::with_capacity(seconds);
    let mut now = 0u64;
    for _ in 0..seconds {
        let started = Instant::now();
        for _ in 0..2 {
            let q = built.random_configuration(&mut rng);
            for (j, &angle) in q.iter().enumerate() {
                let (Some(mapping), Some(&id)) = (servos.mapping(j), ids.get(j)) else { continue };
                let ticks = mapping.to_ticks(angle).map_err(|e| anyhow!("{e:?}"))?;
                if let Some(servo) = bus.servo_mut(id) {
                    servo.set_register(model.items.goal_position, i64::from(ticks), now).map_err(|e| anyhow!(e))?;
                }
            }
            now += 500_000_000;
            bus.advance_to(now);
        }
        times.push(started.elapsed().as_secs_f64());
    }
    Ok(times)
}

fn median(mut values: Vec<f64>) -> f64 {
    values.sort_by(f64::total_cmp);
    values[values.len() / 2]
}

fn measure(arm: &ArmSpec, seconds: usize) -> Result<ServosBenchReport> {
    let servos =
        servos_of(arm).ok_or_else(|| anyhow!("arm {} has no servos: give one with a [servos] table", arm.name))?;
    let count = servos.bus_ids().len();
    let physics = ServoKind::Physical(None).physics(Some(arm))?;
    let gravity = physics.as_ref().is_some_and(|p| p.has_gravity());
    let steps_per_second = 1e9 / STEP_NS as f64;
    let per_servo_step = |wall: f64| wall / steps_per_second / count as f64 * 1e9;
    let physical = median(seconds_timed(arm, ServoKind::Physical(None), seconds)?);
    let ideal = median(seconds_timed(arm, ServoKind::Ideal, seconds)?);
    Ok(ServosBenchReport {
        arm: arm.name.clone(),
        servos: count,
        gravity,
        step_us: STEP_NS as f64 / 1e3,
        physical_ns_per_servo_step: per_servo_step(physical),
        ideal_ns_per_servo_step: per_servo_step(ideal),
        physical_real_time_factor: 1.0 / physical,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The report's figures are there and in proportion (a benchmark's numbers are not judged).
    #[test]
    fn reports_both_servo_kinds_on_the_so101() {
        let arm = ArmSpec::load("so101", None).unwrap();
        let report = measure(&arm, 1).unwrap();
        assert_eq!((report.servos, report.gravity), (6, true));
        assert!(report.physical_ns_per_servo_step > 0.0 && report.ideal_ns_per_servo_step > 0.0);
        assert!(run(&ServosBenchRequest { arm: "so101".into(), seconds: 0 }, false, &mut Vec::new()).is_err());
    }
}
