//! `armctl bench loop-pass` end to end: the MPS2 firmware under `qemu-system-arm` at two `-icount`
//! shifts, every simulated servo silent and the link flooded, its longest pass read back through
//! the command line and scaled to the STM32F411. Checks that the command passes its own check
//! (twice the scaled pass within the F411 watchdog's shortest timeout, the pass within
//! `WORST_PASS_US`), that both runs met flood passes of the same kind, and that the figures add up.
//! Nothing here is timed: the one bound is the command's own exit check. Skips with a message
//! where qemu-system-arm is missing, and fails instead when the `CI` variable is set.

use serde_json::Value;

fn qemu_available() -> bool {
    armctl_test_support::needs_qemu(env!("CARGO_TARGET_TMPDIR"), armctl::runtime::qemu::available())
}

#[test]
fn the_longest_pass_is_split_scaled_and_within_the_watchdog() {
    if !qemu_available() {
        return;
    }
    let (mut out, mut err) = (Vec::new(), Vec::new());
    let code = armctl::cli::main(["armctl", "bench", "loop-pass", "--json"], &mut out, &mut err);
    let err = String::from_utf8_lossy(&err);
    let report: Value = serde_json::from_slice(&out).unwrap_or_else(|e| panic!("not JSON ({e}): {err}"));
    eprintln!("{report:#}");
    assert_eq!(code, 0, "armctl bench loop-pass failed its check: {report:#} {err}");
    assert_eq!(report["passes"], true);
    assert_eq!(report["consistent"], true, "the two runs' longest passes differ in kind");

    let runs = report["runs"].as_array().unwrap();
    assert_eq!(runs.len(), 2);
    for run in runs {
        assert!(run["pass_us"].as_f64().unwrap() > 0.0, "{run}");
        assert_eq!(run["pass_bus_bytes"], runs[0]["pass_bus_bytes"], "the same reads in both ticks");
        // A flood pass: it answered most of a full drain's 73 requests.
        assert!(run["pass_replies"].as_f64().unwrap() > 40.0, "{run}");
        assert!(run["replies"].as_u64().unwrap() > 0 && run["requests"].as_u64().unwrap() > 0, "{run}");
        assert!((100..=130).contains(&run["status_bytes"].as_u64().unwrap()), "{run}");
    }
    let f = |key: &str| report[key].as_f64().unwrap_or_else(|| panic!("no {key}"));
    let (instructions, waits, wire, scaled) = (f("instructions"), f("waits_us"), f("wire_us"), f("scaled_pass_us"));
    assert!(instructions > 0.0 && waits > 0.0 && wire > 0.0, "{report:#}");
    // I consistent with both runs: T = W + I * 2^shift ns, at either shift.
    for run in runs {
        let shift = run["shift"].as_u64().unwrap() as i32;
        let t = waits + instructions * 2f64.powi(shift) / 1e3;
        let measured = run["pass_us"].as_f64().unwrap();
        assert!((t - measured).abs() < 1.0, "shift {shift}: W + I * 2^{shift} ns = {t} us, measured {measured}");
    }
    assert_eq!(report["replies_per_pass"], 74);
    let bus_wire = f("bus_wire_us");
    assert!(bus_wire > 0.0, "{report:#}");
    let expected = instructions / 84.0 + waits + wire + bus_wire;
    assert!((scaled - expected).abs() < 1.0, "{scaled} us scaled, the parts give {expected}");
    let watchdog = &report["watchdog"];
    let shortest = watchdog["shortest_us"].as_f64().unwrap();
    assert!(shortest < watchdog["typical_us"].as_f64().unwrap());
    assert!(watchdog["typical_us"].as_f64().unwrap() < watchdog["longest_us"].as_f64().unwrap());
    assert!(2.0 * scaled <= shortest && scaled <= f("worst_pass_us"), "{report:#}");
}
