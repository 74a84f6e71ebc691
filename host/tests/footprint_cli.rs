//! `armctl footprint` end to end on the MPS2 AN386 board binary (built here, release): section sizes
//! read, the disassembly parsed into a stack bound, and no panic path in the release firmware (its
//! panic handler would fail the link otherwise, so a site here means the report's parsing broke).
//! The goals are reported by the command, not asserted: a figure over a goal is a finding, not a
//! broken build. Needs the toolchain's llvm-tools component (rust-toolchain.toml lists it).

use serde_json::Value;

#[test]
fn the_mps2_binary_is_sized_and_has_no_panic_path() {
    let (mut out, mut err) = (Vec::new(), Vec::new());
    let code =
        armctl::cli::main(["armctl", "footprint", "--board", "mps2-an386", "--no-qemu", "--json"], &mut out, &mut err);
    let err = String::from_utf8_lossy(&err);
    assert_eq!(code, 0, "armctl footprint failed: {err}");
    let report: Value = serde_json::from_slice(&out).unwrap_or_else(|e| panic!("not JSON ({e}): {err}"));
    let boards = report["boards"].as_array().expect("a boards array");
    assert_eq!(boards.len(), 1);
    let board = &boards[0];
    assert_eq!(board["board"], "mps2-an386");
    assert!(board["flash"]["bytes"].as_u64().unwrap() > 0);
    assert!(board["static_ram"]["bytes"].as_u64().unwrap() > 0);
    assert_eq!(board["panic_site_count"], 0, "panic sites: {}", board["panic_sites"]);
    let bounds = board["static_stack"].as_array().expect("a static_stack array");
    assert_eq!(bounds.len(), 3, "start-up, the control loop, and the loop without a new arm's path");
    for bound in bounds {
        assert!(bound["bytes"].as_u64().unwrap() > 0, "{bound}");
        assert!(!bound["path"].as_array().unwrap().is_empty());
    }
    // Leaving functions out can only make the bound smaller.
    assert!(!bounds[2]["excluded"].as_array().unwrap().is_empty());
    assert!(bounds[2]["bytes"].as_u64() < bounds[1]["bytes"].as_u64());
    assert!(board["measured_stack"].is_null(), "--no-qemu");
}
