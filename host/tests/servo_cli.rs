//! `armctl servo` end to end through `armctl::cli::main`, against simulated servos served on a
//! pseudo-terminal ([`armctl::sim::PtyServer`]): the same serial port code a real adapter gets.
//! No timing is asserted; scans name a few ids to stay quick.

use armctl::sim::{Faults, PtyServer, SimConfig};
use firmware::bus::table::{Model, STS3215, XL430_W250};
use firmware::bus::Protocol;

mod support;

/// What one run did.
struct Run {
    code: i32,
    out: String,
    err: String,
}

impl Run {
    fn lines(&self) -> Vec<&str> {
        self.out.lines().collect()
    }

    /// Asserts success with nothing on stderr.
    fn ok(self) -> Self {
        assert_eq!(self.code, 0, "stdout: {}\nstderr: {}", self.out, self.err);
        assert_eq!(self.err, "", "stderr of a successful run");
        self
    }

    /// Asserts a failure with `code` and exactly one stderr line containing every needle.
    fn fails(self, code: i32, needles: &[&str]) -> Self {
        assert_eq!(self.code, code, "stdout: {}\nstderr: {}", self.out, self.err);
        let lines: Vec<&str> = self.err.lines().collect();
        assert_eq!(lines.len(), 1, "expected one stderr line, got {:?}", self.err);
        assert!(lines[0].starts_with("error: "), "{}", lines[0]);
        for needle in needles {
            assert!(lines[0].contains(needle), "{:?} not in {:?}", needle, lines[0]);
        }
        self
    }
}

fn armctl(args: &[&str]) -> Run {
    let (mut out, mut err) = (Vec::new(), Vec::new());
    let code = armctl::cli::main(std::iter::once("armctl").chain(args.iter().copied()), &mut out, &mut err);
    Run { code, out: String::from_utf8(out).unwrap(), err: String::from_utf8(err).unwrap() }
}

/// A simulated bus of `model` servos with `ids`, at [`BAUD`].
fn sim(model: &'static Model, ids: &[u8], faults: Faults, duplicates: &[u8]) -> PtyServer {
    PtyServer::spawn(SimConfig {
        protocol: model.protocol,
        model,
        ids: ids.to_vec(),
        baud: BAUD,
        faults,
        duplicates: duplicates.to_vec(),
        fixed_baud: false,
        burst: None,
        limits: None,
        world: None,
        physics: None,
    })
    .expect("pty server starts")
}

/// The simulated buses' baud rate: Feetech's factory rate, and a rate of the X series too (the
/// set-baud test also runs at the X series' factory 57600).
const BAUD: u32 = 1_000_000;

fn proto(model: &Model) -> &'static str {
    match model.protocol {
        Protocol::Dxl2 => "dxl2",
        Protocol::Feetech => "sts",
    }
}

/// `armctl servo <command> --port <sim> --protocol <p> <rest...>`.
fn servo(server: &PtyServer, model: &Model, command: &[&str], rest: &[&str]) -> Run {
    let mut args = vec!["servo"];
    args.extend_from_slice(command);
    // A long margin: the tests run in parallel on a loaded machine, and a late reply would look
    // like a silent servo.
    let common = ["--port", server.path(), "--protocol", proto(model), "--baud", "1000000", "--timeout-ms", "200"];
    args.extend_from_slice(&common);
    args.extend_from_slice(rest);
    armctl(&args)
}

#[test]
fn scan_finds_exactly_the_dynamixel_servos() {
    let server = sim(&XL430_W250, &[1, 2, 5], Faults::default(), &[]);
    let run = servo(&server, &XL430_W250, &["scan"], &["--ids", "0-8"]).ok();
    assert_eq!(
        run.lines(),
        [
            "id 1: model 1060 XL430-W250, firmware 46, 1000000 baud",
            "id 2: model 1060 XL430-W250, firmware 46, 1000000 baud",
            "id 5: model 1060 XL430-W250, firmware 46, 1000000 baud",
        ]
    );
}

#[test]
fn scan_finds_exactly_the_feetech_servos() {
    let server = sim(&STS3215, &[1, 3], Faults::default(), &[]);
    let run = servo(&server, &STS3215, &["scan"], &["--ids", "0-6"]).ok();
    assert_eq!(
        run.lines(),
        ["id 1: model 777 STS3215, firmware 3, 1000000 baud", "id 3: model 777 STS3215, firmware 3, 1000000 baud"]
    );
}

#[test]
fn scan_of_an_empty_range_says_nobody_answered() {
    let server = sim(&XL430_W250, &[1], Faults::default(), &[]);
    let run = servo(&server, &XL430_W250, &["scan"], &["--ids", "10-12"]);
    run.fails(1, &["no servos answered at 1000000 baud"]);
}

#[test]
fn scan_at_every_baud_finds_the_servos_at_theirs() {
    let server = sim(&STS3215, &[1, 2], Faults::default(), &[]);
    servo(&server, &STS3215, &["set-baud"], &["--id", "2", "--new-baud", "57600"]).ok();
    // The pty server hears at the speed the port is opened at: each servo answers at its own rate.
    let run = servo(&server, &STS3215, &["scan"], &["--ids", "1-2", "--all-bauds"]).ok();
    assert_eq!(
        run.lines(),
        ["id 1: model 777 STS3215, firmware 3, 1000000 baud", "id 2: model 777 STS3215, firmware 3, 57600 baud"]
    );
}

#[test]
fn dynamixel_read_write_round_trip() {
    let server = sim(&XL430_W250, &[1], Faults::default(), &[]);
    let m = &XL430_W250;
    let run = servo(&server, m, &["write"], &["--id", "1", "--addr", "112", "--value", "300"]).ok();
    assert_eq!(run.lines(), ["servo 1: wrote 2c 01 00 00 at 112 (profile_velocity = 300)"]);
    let run = servo(&server, m, &["read"], &["--id", "1", "--addr", "112", "--len", "4"]).ok();
    assert_eq!(run.lines(), ["2c 01 00 00", "profile_velocity = 300"]);
    // A signed EEPROM item (torque is off from the factory), a negative value.
    servo(&server, m, &["write"], &["--id", "1", "--addr", "20", "--value", "-5"]).ok();
    let run = servo(&server, m, &["read"], &["--id", "1", "--addr", "20", "--len", "4"]).ok();
    assert_eq!(run.lines(), ["fb ff ff ff", "homing_offset = -5"]);
    // Several items in one read, each decoded. The horn stands at 2048; the servo reports it plus
    // the homing offset just written (Present = Actual + Homing_Offset).
    let run = servo(&server, m, &["read"], &["--id", "1", "--addr", "128", "--len", "8"]).ok();
    assert_eq!(run.lines()[1..], ["present_velocity = 0", "present_position = 2043"]);
}

/// `read --item`: the named items, in the order asked, from one read spanning them; an unknown
/// name is one error line listing the model's items, and --item excludes --addr.
#[test]
fn read_by_item_name() {
    let server = sim(&STS3215, &[1], Faults::default(), &[]);
    let m = &STS3215;
    let run = servo(&server, m, &["read"], &["--id", "1", "--item", "present_load,present_position"]).ok();
    // 56..62: present position, velocity and load, little-endian.
    assert_eq!(run.lines(), ["00 08 00 00 00 00", "present_load = 0", "present_position = 2048"]);
    servo(&server, m, &["read"], &["--id", "1", "--item", "present_lod"])
        .fails(1, &["no item \"present_lod\"", "present_position"]);
    let run = servo(&server, m, &["read"], &["--id", "1", "--item", "id", "--addr", "5", "--len", "1"]);
    assert_eq!(run.code, 2, "{}", run.err);
    let dxl = sim(&XL430_W250, &[1], Faults::default(), &[]);
    let run = servo(&dxl, &XL430_W250, &["read"], &["--id", "1", "--item", "present_position"]).ok();
    assert_eq!(run.lines(), ["00 08 00 00", "present_position = 2048"]);
}

#[test]
fn feetech_read_write_round_trip_relocks_the_eeprom() {
    let server = sim(&STS3215, &[1], Faults::default(), &[]);
    let m = &STS3215;
    // Homing offset: EEPROM (unlocked, written, locked again), sign-magnitude with bit 11.
    let run = servo(&server, m, &["write"], &["--id", "1", "--addr", "31", "--value", "-5"]).ok();
    assert_eq!(run.lines(), ["servo 1: wrote 05 08 at 31 (homing_offset = -5)"]);
    let run = servo(&server, m, &["read"], &["--id", "1", "--addr", "31", "--len", "2"]).ok();
    assert_eq!(run.lines(), ["05 08", "homing_offset = -5"]);
    let run = servo(&server, m, &["read"], &["--id", "1", "--addr", "55", "--len", "1"]).ok();
    assert_eq!(run.lines(), ["01", "lock = 1"]);
    // Bytes no item names: --len gives the width.
    servo(&server, m, &["write"], &["--id", "1", "--addr", "41", "--value", "0x20"]).ok();
    let run = servo(&server, m, &["read"], &["--id", "1", "--addr", "41", "--len", "1"]).ok();
    assert_eq!(run.lines(), ["20", "acceleration = 32"]);
}

/// Writing the id or baud item directly would skip set-id's and set-baud's checks and leave the
/// servo where the tool cannot confirm it: refused, and nothing changes.
#[test]
fn write_refuses_the_id_and_baud_items() {
    for m in [&XL430_W250, &STS3215] {
        let server = sim(m, &[1], Faults::default(), &[]);
        let (id_addr, baud_addr) = (m.items.id.address.to_string(), m.items.baud.address.to_string());
        servo(&server, m, &["write"], &["--id", "1", "--addr", &id_addr, "--value", "9"])
            .fails(1, &["use armctl servo set-id"]);
        servo(&server, m, &["write"], &["--id", "1", "--addr", &baud_addr, "--value", "1"])
            .fails(1, &["use armctl servo set-baud"]);
        let run = servo(&server, m, &["scan"], &["--ids", "0-10"]).ok();
        assert_eq!(run.lines().len(), 1);
        assert!(run.lines()[0].starts_with("id 1: "), "{:?}", run.lines());
    }
}

#[test]
fn write_refuses_values_that_do_not_fit_and_read_only_items() {
    let server = sim(&XL430_W250, &[1], Faults::default(), &[]);
    let m = &XL430_W250;
    servo(&server, m, &["write"], &["--id", "1", "--addr", "64", "--value", "256"])
        .fails(1, &["256 does not fit torque_enable"]);
    servo(&server, m, &["write"], &["--id", "1", "--addr", "132", "--value", "1"])
        .fails(1, &["present_position", "read-only"]);
    servo(&server, m, &["write"], &["--id", "1", "--addr", "65", "--value", "70000", "--len", "2"])
        .fails(1, &["70000 does not fit"]);
    servo(&server, m, &["write"], &["--id", "1", "--addr", "66", "--value", "1"]).fails(1, &["give --len"]);
}

#[test]
fn torque_on_and_off_show_in_a_read() {
    for m in [&XL430_W250, &STS3215] {
        let server = sim(m, &[4], Faults::default(), &[]);
        let address = m.items.torque_enable.address.to_string();
        let read = ["--id", "4", "--addr", address.as_str(), "--len", "1"];
        let run = servo(&server, m, &["torque", "on"], &["--id", "4"]).ok();
        assert_eq!(run.lines(), ["servo 4: torque on"]);
        assert_eq!(servo(&server, m, &["read"], &read).ok().lines(), ["01", "torque_enable = 1"]);
        let run = servo(&server, m, &["torque", "off"], &["--id", "4"]).ok();
        assert_eq!(run.lines(), ["servo 4: torque off"]);
        assert_eq!(servo(&server, m, &["read"], &read).ok().lines(), ["00", "torque_enable = 0"]);
        let run = servo(&server, m, &["torque", "on"], &["--id", "all"]).ok();
        assert_eq!(run.lines(), ["all servos: torque on (broadcast, not confirmed)"]);
        assert_eq!(servo(&server, m, &["read"], &read).ok().lines(), ["01", "torque_enable = 1"]);
    }
}

#[test]
fn set_id_then_scan_shows_the_new_id() {
    for m in [&XL430_W250, &STS3215] {
        let server = sim(m, &[1, 2], Faults::default(), &[]);
        let run = servo(&server, m, &["set-id"], &["--id", "1", "--new-id", "7"]).ok();
        assert_eq!(run.lines(), [format!("servo 1: id is now 7 (model {} {})", m.number, m.name)]);
        let run = servo(&server, m, &["scan"], &["--ids", "0-8"]).ok();
        let ids: Vec<&str> = run.lines().iter().map(|l| l.split(':').next().unwrap()).collect();
        assert_eq!(ids, ["id 2", "id 7"]);
        if let Some(lock) = m.items.lock {
            let address = lock.address.to_string();
            let run = servo(&server, m, &["read"], &["--id", "7", "--addr", &address, "--len", "1"]).ok();
            assert_eq!(run.lines(), ["01", "lock = 1"]);
        }
    }
}

#[test]
fn set_id_refuses_a_taken_id_and_dynamixel_torque_on() {
    let server = sim(&XL430_W250, &[1, 2], Faults::default(), &[]);
    let m = &XL430_W250;
    servo(&server, m, &["set-id"], &["--id", "1", "--new-id", "2"]).fails(1, &["id 2 is taken"]);
    servo(&server, m, &["torque", "on"], &["--id", "1"]).ok();
    servo(&server, m, &["set-id"], &["--id", "1", "--new-id", "3"]).fails(1, &["servo 1: torque is on", "torque off"]);
    // Nothing changed.
    let run = servo(&server, m, &["scan"], &["--ids", "0-4"]).ok();
    assert_eq!(run.lines().len(), 2);
    assert!(run.lines()[0].starts_with("id 1:") && run.lines()[1].starts_with("id 2:"));
}

#[test]
fn dynamixel_eeprom_write_with_torque_on_is_explained() {
    let server = sim(&XL430_W250, &[1], Faults::default(), &[]);
    let m = &XL430_W250;
    servo(&server, m, &["torque", "on"], &["--id", "1"]).ok();
    servo(&server, m, &["write"], &["--id", "1", "--addr", "11", "--value", "4"])
        .fails(1, &["servo 1: torque is on", "torque off --id 1"]);
}

#[test]
fn set_baud_refuses_a_rate_the_model_lacks_and_confirms_at_the_new_rate() {
    let server = sim(&XL430_W250, &[1], Faults::default(), &[]);
    let m = &XL430_W250;
    servo(&server, m, &["set-baud"], &["--id", "1", "--new-baud", "12345"])
        .fails(1, &["XL430-W250 has no 12345 baud", "57600"]);
    // The pty server follows the speed the port is opened at, so the servo is heard at its new rate
    // only: set-baud reopens the port at 57600 and pings there to confirm.
    let run = servo(&server, m, &["set-baud"], &["--id", "1", "--new-baud", "57600"]).ok();
    assert_eq!(run.lines(), ["servo 1: baud rate is now 57600 (baud_rate = 1)"]);
    let at = |baud: &str| {
        armctl(&[
            "servo",
            "read",
            "--port",
            server.path(),
            "--protocol",
            "dxl2",
            "--baud",
            baud,
            "--timeout-ms",
            "200",
            "--id",
            "1",
            "--addr",
            "8",
            "--len",
            "1",
        ])
    };
    assert_eq!(at("57600").ok().lines(), ["01", "baud_rate = 1"]);
    at("1000000").fails(1, &["servo 1: no reply to read"]);
}

/// A port another program holds (serialport opens ttys exclusively) is one line naming it.
#[test]
fn a_busy_port_is_one_line_naming_it() {
    let server = sim(&STS3215, &[1], Faults::default(), &[]);
    let _holder = serialport::new(server.path(), BAUD).open().expect("first open");
    let run = armctl(&["servo", "scan", "--port", server.path(), "--protocol", "sts", "--ids", "1"]);
    run.fails(1, &[server.path(), "port busy"]);
}

#[test]
fn a_missing_port_is_one_line_naming_it() {
    let run = armctl(&["servo", "scan", "--port", "/dev/armctl-no-such-port", "--protocol", "dxl2"]);
    run.fails(1, &["/dev/armctl-no-such-port: no such serial port"]);
    let run = armctl(&[
        "servo",
        "read",
        "--port",
        "/dev/armctl-nope",
        "--protocol",
        "sts",
        "--id",
        "1",
        "--addr",
        "56",
        "--len",
        "2",
    ]);
    run.fails(1, &["/dev/armctl-nope"]);
}

#[test]
fn a_silent_servo_gets_no_reply() {
    let faults = Faults { silent: vec![3], ..Faults::default() };
    for m in [&XL430_W250, &STS3215] {
        let server = sim(m, &[1, 3], faults.clone(), &[]);
        let run = servo(&server, m, &["read"], &["--id", "3", "--addr", "10", "--len", "1", "--retries", "1"]);
        assert_eq!(run.out, "");
        run.fails(1, &["servo 3: no reply to read (2 attempts"]);
        // The silent servo is left out of a scan.
        let run = servo(&server, m, &["scan"], &["--ids", "0-4"]).ok();
        assert_eq!(run.lines().len(), 1, "{:?}", run.lines());
    }
}

#[test]
fn a_corrupted_reply_is_a_bad_checksum() {
    let faults = Faults { corrupt_rate: 1.0, seed: 7, ..Faults::default() };
    for m in [&XL430_W250, &STS3215] {
        let server = sim(m, &[1], faults.clone(), &[]);
        let run = servo(&server, m, &["read"], &["--id", "1", "--addr", "10", "--len", "1"]);
        run.fails(1, &["servo 1: reply to read had a bad checksum"]);
    }
}

#[test]
fn a_duplicate_id_is_reported_by_scan() {
    let server = sim(&XL430_W250, &[1, 2], Faults::default(), &[2]);
    let run = servo(&server, &XL430_W250, &["scan"], &["--ids", "0-3"]);
    assert_eq!(run.code, 1, "stdout: {}\nstderr: {}", run.out, run.err);
    assert!(run.lines().iter().any(|l| l.starts_with("id 1:")), "{}", run.out);
    assert!(run.lines().iter().any(|l| l.starts_with("id 2:")), "{}", run.out);
    run.fails(1, &["servo 2: reply to read had a bad checksum", "two servos with id 2?"]);
}

#[test]
fn bad_arguments_exit_2() {
    let p = "/dev/null";
    let cases: [&[&str]; 7] = [
        &["servo", "scan", "--protocol", "dxl2"],
        &["servo", "scan", "--port", p, "--protocol", "dxl3"],
        &["servo", "read", "--port", p, "--protocol", "dxl2", "--id", "1", "--addr", "0", "--len", "0"],
        &[
            "servo",
            "write",
            "--port",
            p,
            "--protocol",
            "dxl2",
            "--id",
            "1",
            "--addr",
            "0",
            "--value",
            "1",
            "--len",
            "3",
        ],
        &["servo", "read", "--port", p, "--protocol", "dxl2", "--id", "253", "--addr", "0", "--len", "1"],
        &["servo", "set-id", "--port", p, "--protocol", "sts", "--id", "1", "--new-id", "1"],
        &["servo", "scan", "--port", p, "--protocol", "sts", "--ids", "5-1"],
    ];
    for args in cases {
        let run = armctl(args);
        assert_eq!(run.code, 2, "{args:?}: {}", run.err);
        assert_eq!(run.err.lines().count(), 1, "{args:?}: {}", run.err);
        assert!(run.err.starts_with("error: "), "{args:?}: {}", run.err);
        assert_eq!(run.out, "");
    }
}

/// Alerts: the pty server cannot raise a servo's hardware error, so these run the commands on the
/// simulator's in-memory line (virtual clock) instead of through `cli::main`.
#[test]
fn an_alert_shows_the_data_then_one_error_line_per_servo() {
    use armctl::commands::servo::commands;
    use armctl::runtime::servo_session::Session;
    use armctl::sim::{connect, SimBus};
    use firmware::bus::master::BusConfig;

    for (m, bits, text) in [
        (&XL430_W250, 0x20, "error: servo 3: alert: hardware error status 0x20 (overload)"),
        (&STS3215, 0x24, "error: servo 3: alert: overheat (error bits 0x24)"),
    ] {
        let (bus, port, clock) = connect(SimBus::new(m.protocol, m, &[3], BAUD));
        bus.borrow_mut().servo_mut(3).unwrap().set_hardware_error(bits, 0);
        let mut session = Session::new("sim", port, clock, BusConfig::new(m.protocol, BAUD));
        let address = m.items.present_position.address;
        let (mut out, mut err) = (Vec::new(), Vec::new());
        let code = commands::read(&mut session, 3, address, 2, false, &mut out, &mut err).unwrap();
        let (out, err) = (String::from_utf8(out).unwrap(), String::from_utf8(err).unwrap());
        assert_eq!(code, 1, "{out}{err}");
        assert_eq!(out.lines().count(), 1 + usize::from(m.protocol == Protocol::Feetech), "the data is shown: {out}");
        assert_eq!(err.lines().collect::<Vec<_>>(), [text]);
    }
}

/// A LeRobot calibration file for servos 1 and 2 (`drive_mode` 1 on the second), in a folder of its
/// own removed when dropped.
fn calibration_file(homing: [i32; 2]) -> support::TempPath {
    let text = format!(
        "{{\n    \"shoulder_pan\": {{\n        \"id\": 1,\n        \"drive_mode\": 0,\n        \"homing_offset\": {},\n        \
         \"range_min\": 758,\n        \"range_max\": 3292\n    }},\n    \"gripper\": {{\n        \"id\": 2,\n        \
         \"drive_mode\": 1,\n        \"homing_offset\": {},\n        \"range_min\": 2019,\n        \"range_max\": 3367\n    }}\n}}",
        homing[0], homing[1]
    );
    let path = support::TempPath::new("calibration.json");
    std::fs::write(&path, text).unwrap();
    path
}

/// LeRobot's calibration against factory-fresh servos: `check` names the first servo that differs
/// and the fix; `write` writes the registers (EEPROM, unlocked on Feetech) and `check` then agrees;
/// a second `write` writes nothing. On both protocols, with Dynamixel's drive mode bit.
#[test]
fn a_lerobot_calibration_is_checked_against_the_servos_and_written_to_them() {
    for model in [&STS3215, &XL430_W250] {
        let server = sim(model, &[1, 2], Faults::default(), &[]);
        let file = calibration_file([-1470, 1160]);
        let path = file.to_str().unwrap();
        servo(&server, model, &["calibration", "check"], &["--file", path]).fails(
            1,
            &["servo 1 (shoulder_pan): homing offset is 0 on the servo but -1470", "armctl servo calibration write"],
        );
        let written = servo(&server, model, &["calibration", "write"], &["--file", path]).ok();
        let lines = written.lines();
        assert!(lines.contains(&"servo 1 (shoulder_pan): homing offset 0 -> -1470"), "{lines:?}");
        assert!(lines.contains(&"servo 2 (gripper): range_max 4095 -> 3367"), "{lines:?}");
        assert_eq!(
            lines.iter().any(|l| l.contains("drive_mode 0 -> 1")),
            model.protocol == Protocol::Dxl2,
            "{lines:?}"
        );
        assert_eq!(
            servo(&server, model, &["calibration", "check"], &["--file", path]).ok().lines(),
            ["calibration matches the servos (2 motors)"]
        );
        assert_eq!(
            servo(&server, model, &["calibration", "write"], &["--file", path]).ok().lines(),
            ["the servos hold the file's calibration already; nothing written"]
        );
        let read = servo(&server, model, &["read"], &["--id", "1", "--item", "min_position_limit,max_position_limit"]);
        // The bytes in hex first, then the values.
        assert_eq!(read.ok().lines()[1..], ["min_position_limit = 758", "max_position_limit = 3292"]);
    }
}

/// A servo with torque on is refused before anything is written; a bad file touches no servo.
#[test]
fn calibration_writes_need_torque_off_and_a_good_file() {
    let server = sim(&STS3215, &[1, 2], Faults::default(), &[]);
    let good = calibration_file([-1470, 1160]);
    servo(&server, &STS3215, &["torque", "on"], &["--id", "2"]).ok();
    servo(&server, &STS3215, &["calibration", "write"], &["--file", good.to_str().unwrap()])
        .fails(1, &["servo 2: torque is on", "nothing was written"]);
    let read = servo(&server, &STS3215, &["read"], &["--id", "1", "--item", "homing_offset"]);
    assert_eq!(read.ok().lines()[1..], ["homing_offset = 0"], "servo 1 was not written either");
    // Feetech's homing offset is sign-magnitude with 11 bits: LeRobot's "Magnitude 2114 exceeds 2047".
    servo(&server, &STS3215, &["torque", "off"], &["--id", "2"]).ok();
    let too_far = calibration_file([-1470, 2114]);
    servo(&server, &STS3215, &["calibration", "write"], &["--file", too_far.to_str().unwrap()])
        .fails(1, &["servo 2 (gripper): homing offset 2114 does not fit", "nothing was written"]);
    let read = servo(&server, &STS3215, &["read"], &["--id", "1", "--item", "homing_offset"]);
    assert_eq!(read.ok().lines()[1..], ["homing_offset = 0"], "servo 1 was not written before servo 2 failed");
    let broken = good.with_file_name("broken.json");
    std::fs::write(&broken, "{\"shoulder_pan\": {\"id\": 1}}").unwrap();
    servo(&server, &STS3215, &["calibration", "check"], &["--file", broken.to_str().unwrap()])
        .fails(1, &["broken.json", "motor \"shoulder_pan\": no \"drive_mode\""]);
}

/// One JSON line of `run`'s stdout.
fn json_line(run: &Run) -> serde_json::Value {
    let lines = run.lines();
    assert_eq!(lines.len(), 1, "one line of JSON: {:?}", run.out);
    serde_json::from_str(lines[0]).unwrap_or_else(|e| panic!("not JSON ({e}): {}", lines[0]))
}

/// Every `servo` command with `--json` (after the subcommand, between `servo` and it, or before
/// `servo`): one line of JSON with what the text says.
#[test]
fn every_servo_command_prints_one_line_of_json() {
    let m = &XL430_W250;
    let server = sim(m, &[1, 2], Faults::default(), &[]);
    let v = json_line(&servo(&server, m, &["scan"], &["--ids", "0-3", "--json"]).ok());
    assert_eq!(
        v,
        serde_json::json!({"servos": [
            {"id": 1, "model_number": 1060, "model": "XL430-W250", "firmware": 46, "baud": 1000000},
            {"id": 2, "model_number": 1060, "model": "XL430-W250", "firmware": 46, "baud": 1000000},
        ]})
    );
    let v = json_line(&servo(&server, m, &["--json", "write"], &["--id", "1", "--addr", "112", "--value", "300"]).ok());
    assert_eq!(
        v,
        serde_json::json!({"id": 1, "address": 112, "bytes": [0x2c, 1, 0, 0], "item": "profile_velocity", "value": 300})
    );
    let run = {
        let common = ["--port", server.path(), "--protocol", "dxl2", "--baud", "1000000", "--timeout-ms", "200"];
        let mut args = vec!["--json", "servo", "read", "--id", "1", "--item", "profile_velocity,present_position"];
        args.extend_from_slice(&common);
        armctl(&args).ok()
    };
    assert_eq!(json_line(&run)["items"], serde_json::json!({"profile_velocity": 300, "present_position": 2048}));
    let v = json_line(&servo(&server, m, &["read"], &["--id", "1", "--addr", "112", "--len", "4", "--json"]).ok());
    assert_eq!(
        v,
        serde_json::json!({"id": 1, "address": 112, "bytes": [0x2c, 1, 0, 0], "items": {"profile_velocity": 300}})
    );
    let v = json_line(&servo(&server, m, &["torque", "on"], &["--id", "2", "--json"]).ok());
    assert_eq!(v, serde_json::json!({"id": 2, "torque": true, "confirmed": true}));
    let v = json_line(&servo(&server, m, &["torque", "off"], &["--id", "all", "--json"]).ok());
    assert_eq!(v, serde_json::json!({"id": "all", "torque": false, "confirmed": false}));
    // LeRobot's calibration: written (torque off everywhere), then checked.
    servo(&server, m, &["torque", "off"], &["--id", "2"]).ok();
    let file = calibration_file([-1470, 1160]);
    let path = file.to_str().unwrap();
    let v = json_line(&servo(&server, m, &["calibration", "write"], &["--file", path, "--json"]).ok());
    let written = v["written"].as_array().unwrap();
    assert!(
        written.contains(
            &serde_json::json!({"id": 2, "motor": "gripper", "field": "homing offset", "from": 0, "to": 1160})
        ),
        "{v}"
    );
    let v = json_line(&servo(&server, m, &["calibration", "check"], &["--file", path, "--json"]).ok());
    assert_eq!(v, serde_json::json!({"matches": true, "motors": 2}));
    let v = json_line(&servo(&server, m, &["set-id"], &["--id", "1", "--new-id", "7", "--json"]).ok());
    assert_eq!(v["new_id"], 7);
    assert_eq!(v["servo"]["model"], "XL430-W250");
    let v = json_line(&servo(&server, m, &["set-baud"], &["--id", "7", "--new-baud", "57600", "--json"]).ok());
    assert_eq!(v, serde_json::json!({"id": 7, "baud": 57600, "item": "baud_rate", "index": 1}));
}
