//! Issue 5's timing check: the control rate the firmware's controller reaches with 6 servos, on
//! Dynamixel and Feetech, at 1 Mbps and at 57600 baud, is within 10 % of the wire-time limit
//! (shared/reference/protocols.md, "Wire time"). Deterministic: the controller runs against
//! simulated servos on the virtual clock (`armctl bench rate`'s library function), not on the wall
//! clock.

use armctl::commands::bench::rate::{measure, RateReport, RateRun, RateSetup, SERVOS};
use firmware::bus::table::{Model, STS3215, XM430_W350};
use firmware::bus::timing::cycle_bytes;

fn check(model: &'static Model, baud: u32) -> RateReport {
    let setup = RateSetup { model, baud, return_delay_us: 0, seconds: 2.0 };
    let r = measure(&setup).unwrap();
    let what = format!("{} at {baud} baud", model.name);
    let (goal, position) = (model.items.goal_position.len(), model.items.present_position.len());
    assert_eq!(r.cycle_bytes, cycle_bytes(model.protocol, SERVOS, goal, position));
    assert!(
        r.ratio() >= 0.9,
        "{what}: {:.1} Hz is {:.3} of the {:.1} Hz limit",
        r.back_to_back.rate_hz,
        r.ratio(),
        r.limit_hz
    );
    // Never faster than the wire allows: the simulation charges every byte.
    assert!(r.ratio() <= 1.0 + 1e-9, "{what}: {:.1} Hz above the {:.1} Hz limit", r.back_to_back.rate_hz, r.limit_hz);
    let runs: [&RateRun; 2] = [&r.back_to_back, &r.fixed_period];
    for run in runs {
        let what = format!("{what}, {:?}", run.schedule);
        assert!(run.ticks >= 50, "{what}: only {} ticks", run.ticks);
        assert_eq!(run.missing_replies, 0, "{what}: missing replies");
        assert_eq!(run.bus_errors, 0, "{what}: bus errors");
        assert_eq!(run.goals_outside_limits, 0, "{what}: goals outside the limits");
        // Exactly the minimal cycle on the wire, tick after tick.
        assert_eq!(run.bytes_per_tick, r.cycle_bytes as f64, "{what}: bytes per tick");
        // A move is in progress throughout: nearly every tick sends new goals.
        assert!(
            run.ticks_with_new_goals * 10 >= run.ticks * 9,
            "{what}: {} of {} ticks moved",
            run.ticks_with_new_goals,
            run.ticks
        );
    }
    assert_eq!(r.back_to_back.deadline_misses, 0, "{what}: back to back");
    assert_eq!(r.fixed_period.deadline_misses, 0, "{what}: on the controller's period of {} us", r.period_us);
    // On its period the controller ticks at 1e6 / period_us.
    let expected = 1e6 / f64::from(r.period_us);
    assert!(
        (r.fixed_period.rate_hz - expected).abs() < 0.01 * expected,
        "{what}: {} Hz on the period",
        r.fixed_period.rate_hz
    );
    r
}

#[test]
fn dynamixel_1_mbps() {
    check(&XM430_W350, 1_000_000);
}

#[test]
fn dynamixel_57600() {
    check(&XM430_W350, 57_600);
}

#[test]
fn feetech_1_mbps() {
    check(&STS3215, 1_000_000);
}

#[test]
fn feetech_57600() {
    check(&STS3215, 57_600);
}
