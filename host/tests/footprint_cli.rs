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
    assert_eq!(bounds.len(), 2, "start-up and the control loop");
    for bound in bounds {
        assert!(bound["bytes"].as_u64().unwrap() > 0, "{bound}");
        assert!(!bound["path"].as_array().unwrap().is_empty());
    }
    assert!(board["measured_stack"].is_null(), "--no-qemu");
}

/// The STM32F411 binary: no panic path, its defmt logger included (the board's own RTT logger,
/// which drops a nested frame where defmt-rtt panicked), and the RTT control block laid out as
/// probe-rs finds it: the id, one up channel named `defmt` over a 1 KiB buffer in RAM, starting in
/// non-blocking mode; and the stack below the statics (flip-link).
#[test]
fn the_stm32_binary_has_no_panic_path_and_an_rtt_control_block() {
    use object::{Object, ObjectSection, ObjectSymbol};
    let (mut out, mut err) = (Vec::new(), Vec::new());
    let code = armctl::cli::main(["armctl", "footprint", "--board", "stm32f411", "--json"], &mut out, &mut err);
    assert_eq!(code, 0, "armctl footprint failed: {}", String::from_utf8_lossy(&err));
    let report: Value = serde_json::from_slice(&out).unwrap();
    let board = &report["boards"][0];
    assert_eq!(board["board"], "stm32f411");
    assert_eq!(board["panic_site_count"], 0, "panic sites: {}", board["panic_sites"]);

    let elf = std::fs::read(board["elf"].as_str().unwrap()).unwrap();
    let file = object::File::parse(&*elf).unwrap();
    // The initial value of a symbol, from its section's data.
    let initial = |name: &str, len: usize| -> (u64, Vec<u8>) {
        let symbol = file.symbols().find(|s| s.name() == Ok(name)).unwrap_or_else(|| panic!("no {name}"));
        let section = file.section_by_index(symbol.section_index().unwrap()).unwrap();
        let data = section.data().unwrap();
        let at = (symbol.address() - section.address()) as usize;
        (symbol.address(), data[at..at + len].to_vec())
    };
    let (_, block) = initial("_SEGGER_RTT", 16 + 8 + 24);
    let word = |i: usize| u32::from_le_bytes(block[i..i + 4].try_into().unwrap());
    assert_eq!(&block[..16], b"SEGGER RTT\0\0\0\0\0\0");
    assert_eq!((word(16), word(20)), (1, 0), "one up channel, no down channel");
    assert_eq!(word(32), 1024, "buffer size");
    assert_eq!((word(36), word(40), word(44)), (0, 0, 1), "cursors at 0, non-blocking trim");
    // The name and the buffer lie in the F411's RAM (0x2000_0000..0x2002_0000).
    for pointer in [word(24), word(28)] {
        assert!((0x2000_0000..0x2002_0000).contains(&pointer), "{pointer:#x}");
    }
    let name_section = file
        .sections()
        .find(|s| (s.address()..s.address() + s.size()).contains(&u64::from(word(24))))
        .expect("the section of the channel's name");
    let data = name_section.data().unwrap();
    let at = (u64::from(word(24)) - name_section.address()) as usize;
    assert_eq!(&data[at..at + 6], b"defmt\0");

    // Linked by flip-link: the stack starts right below the statics and grows down to the start
    // of RAM, so an overflow faults there instead of running into the firmware's state (without
    // it the stack starts at the top of RAM, above the statics).
    let address = |name: &str| file.symbols().find(|s| s.name() == Ok(name)).map(|s| s.address());
    let (stack_start, statics) = (address("_stack_start").unwrap(), address("__sdata").unwrap());
    assert!(stack_start <= statics, "stack from {stack_start:#x}, statics from {statics:#x}");
    assert!(stack_start > 0x2000_0000 + 8 * 1024, "room for the stack below the statics: {stack_start:#x}");
}

/// The STM32F411's first log line carries the voltage scale and the brown-out reset level as read
/// back (issue 44's bring-up), and every way start-up can stop or write the option bytes says so:
/// read from the ELF's defmt table (each format string is a symbol in `.defmt`; defmt keeps the
/// strings on the host, so this is the one place they can be checked without a probe).
#[test]
fn the_stm32_binary_logs_the_supply_on_its_first_line() {
    use object::{Object, ObjectSymbol};
    let (mut out, mut err) = (Vec::new(), Vec::new());
    let code =
        armctl::cli::main(["armctl", "footprint", "--board", "stm32f411", "--no-qemu", "--json"], &mut out, &mut err);
    assert_eq!(code, 0, "armctl footprint failed: {}", String::from_utf8_lossy(&err));
    let report: Value = serde_json::from_slice(&out).unwrap();
    let elf = std::fs::read(report["boards"][0]["elf"].as_str().unwrap()).unwrap();
    let file = object::File::parse(&*elf).unwrap();
    let strings: Vec<String> = file.symbols().filter_map(|s| s.name().ok().map(str::to_string)).collect();
    for text in [
        "stm32f411: {=istr}; voltage scale {=u8}, brown-out reset level {=u8} (0: off); starting the clocks",
        "reset by power-on: servos' torque off",
        "reset by the watchdog: servos' torque off",
        "brown-out reset {=istr}",
        "level 3 (2.7 V) written to the option bytes and read back",
        "written only after a power-on",
        "start-up stopped: {=istr}",
        "voltage scale {=u8} (VOSRDY {=bool})",
    ] {
        assert!(strings.iter().any(|s| s.contains(text)), "no defmt string containing {text:?}");
    }
}
