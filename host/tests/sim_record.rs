//! `armctl sim servos --record FILE` and `--calibration FILE`, end to end through the binary: a
//! goal written over the pty with the firmware's own bus master shows in the recording (the
//! goal column switches, the position follows on the 2 ms grid), the file is complete after
//! Ctrl-C and whole rows after a kill; a calibration moves the monitor's goal ranges; bad files
//! are one line and exit code 2, with nothing served.

use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use armctl::link::serial::{SerialTransport, StdClock};
use firmware::bus::master::{BusConfig, Master, NoDirectionPin};
use firmware::bus::table::{Item, STS3215};
use firmware::bus::Protocol;

const BAUD: u32 = 1_000_000;

/// One real-time test at a time: each judges what a server on the real clock saw.
fn one_at_a_time() -> std::sync::MutexGuard<'static, ()> {
    static LOCK: std::sync::Mutex<()> = std::sync::Mutex::new(());
    LOCK.lock().unwrap_or_else(|e| e.into_inner())
}

/// A fresh folder for one test, removed when dropped, also when the test fails.
fn temp_dir(name: &str) -> tempfile::TempDir {
    tempfile::Builder::new().prefix(&format!("armctl-sim-record-{name}-")).tempdir().unwrap()
}

/// `armctl sim servos ARGS` with its stderr gathered by a thread; returns it, the pty's path
/// (its first line on stdout) and the stderr thread.
fn serve(args: &[&str]) -> (Child, String, std::thread::JoinHandle<String>) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_armctl"))
        .args(["sim", "servos"])
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut line = String::new();
    BufReader::new(child.stdout.take().unwrap()).read_line(&mut line).unwrap();
    let stderr = child.stderr.take().unwrap();
    let errors = std::thread::spawn(move || {
        let mut text = String::new();
        for line in BufReader::new(stderr).lines().map_while(Result::ok) {
            text.push_str(&line);
            text.push('\n');
        }
        text
    });
    (child, line.trim().to_string(), errors)
}

/// Sends `signal` (INT, TERM, KILL) to `child`.
fn signal(child: &Child, signal: &str) {
    let status = Command::new("kill").args([&format!("-{signal}"), &child.id().to_string()]).status().unwrap();
    assert!(status.success(), "kill -{signal}");
}

/// The exit code, waiting at most 5 s (then the process is killed and the test fails).
fn exit_code(child: &mut Child) -> Option<i32> {
    let started = Instant::now();
    loop {
        if let Some(status) = child.try_wait().unwrap() {
            return status.code();
        }
        if started.elapsed() > Duration::from_secs(5) {
            let _ = child.kill();
            let _ = child.wait();
            panic!("armctl sim servos did not end within 5 s of the signal");
        }
        std::thread::sleep(Duration::from_millis(10));
    }
}

/// The firmware's bus master on the pty's slave end, with margins for a loaded machine.
fn master(path: &str) -> Master<SerialTransport, NoDirectionPin, StdClock> {
    let mut config = BusConfig::new(Protocol::Feetech, BAUD);
    config.margin_us = 500_000;
    config.idle_gap_us = 50_000;
    Master::new(SerialTransport::open(path, BAUD).expect("open pty"), NoDirectionPin, StdClock::new(), config)
}

fn write_item(m: &mut Master<SerialTransport, NoDirectionPin, StdClock>, id: u8, item: Item, value: i64) {
    let mut bytes = vec![0u8; item.len()];
    item.encode(value, STS3215.endian, &mut bytes).unwrap();
    m.write(id, item.address, &bytes).unwrap_or_else(|e| panic!("write {} to servo {id}: {e}", item.name));
}

fn read_item(m: &mut Master<SerialTransport, NoDirectionPin, StdClock>, id: u8, item: Item) -> i64 {
    let mut bytes = vec![0u8; item.len()];
    m.read(id, item.address, &mut bytes).unwrap_or_else(|e| panic!("read {} of servo {id}: {e}", item.name));
    item.decode(&bytes, STS3215.endian).unwrap()
}

/// The recording's header and rows, each row's fields as text.
fn read_csv(path: &Path) -> (String, Vec<Vec<String>>) {
    let text = std::fs::read_to_string(path).unwrap();
    assert!(text.ends_with('\n'), "the file ends with a whole row: {:?}", &text[text.len().saturating_sub(80)..]);
    let mut lines = text.lines();
    let header = lines.next().expect("a header").to_string();
    let rows = lines.map(|l| l.split(',').map(str::to_string).collect()).collect();
    (header, rows)
}

const HEADER: &str = "t,pos_1,pos_2,pos_3,pos_4,pos_5,pos_6,goal_1,goal_2,goal_3,goal_4,goal_5,goal_6";

/// Asserts that the rows are the 2 ms grid from 0 on, every field a number in its format.
fn assert_grid(rows: &[Vec<String>]) {
    for (k, row) in rows.iter().enumerate() {
        assert_eq!(row.len(), 13, "row {k}: {row:?}");
        assert_eq!(row[0], format!("{:.4}", k as f64 * 0.002), "row {k}: the grid of t");
        for pos in &row[1..7] {
            let (_, decimals) = pos.split_once('.').unwrap_or_else(|| panic!("row {k}: {pos}"));
            assert!(decimals.len() == 2 && pos.parse::<f64>().is_ok(), "row {k}: position {pos}");
        }
        for goal in &row[7..] {
            assert!(goal.parse::<i64>().is_ok(), "row {k}: goal {goal}");
        }
    }
}

/// `--record`: servo 1 torqued and sent 500 ticks on over the pty; Ctrl-C ends the server with
/// exit code 130 and the file is whole: the 2 ms grid from 0 to the end, the goal column switching
/// once from the start to the goal, the position standing until then and then moving toward the
/// goal without turning back until it is there; the other servos stand still.
#[test]
fn the_recording_follows_a_goal_sent_over_the_pty() {
    let _one = one_at_a_time();
    let dir = temp_dir("goal");
    let file = dir.path().join("positions.csv");
    let (mut child, path, errors) = serve(&["--pty", "--arm", "so101", "--record", file.to_str().unwrap()]);
    // The file and its header exist before the path is printed.
    assert_eq!(std::fs::read_to_string(&file).unwrap(), format!("{HEADER}\n"));
    let items = STS3215.items;
    let run = std::panic::catch_unwind(|| {
        let mut m = master(&path);
        std::thread::sleep(Duration::from_millis(100));
        write_item(&mut m, 1, items.torque_enable, 1);
        write_item(&mut m, 1, items.goal_position, 2548);
        let deadline = Instant::now() + Duration::from_secs(5);
        while read_item(&mut m, 1, items.present_position) != 2548 {
            assert!(Instant::now() < deadline, "servo 1 did not reach its goal");
            std::thread::sleep(Duration::from_millis(20));
        }
        std::thread::sleep(Duration::from_millis(100));
    });
    signal(&child, "INT");
    let code = exit_code(&mut child);
    let errors = errors.join().unwrap();
    run.expect("a goal over the pty");
    assert_eq!(code, Some(130), "{errors}");
    assert!(errors.contains(&format!("positions recorded to {}", file.display())), "{errors}");

    let (header, rows) = read_csv(&file);
    assert_eq!(header, HEADER);
    assert_grid(&rows);
    assert!(rows.len() >= 150, "at least the 0.3 s the test slept: {} rows", rows.len());
    let field = |row: &Vec<String>, i: usize| row[i].parse::<f64>().unwrap();
    let switch = rows.iter().position(|r| r[7] == "2548").expect("the goal shows in goal_1");
    assert!(switch > 0 && rows[..switch].iter().all(|r| r[7] == "2048"), "one switch of goal_1");
    assert!(rows[switch..].iter().all(|r| r[7] == "2548"), "one switch of goal_1");
    assert!(rows[..switch].iter().all(|r| r[1] == "2048.00"), "the horn stood until the goal came");
    let after: Vec<f64> = rows[switch..].iter().map(|r| field(r, 1)).collect();
    assert!(after.windows(2).all(|w| w[1] >= w[0]), "toward the goal, never back: {after:?}");
    assert_eq!(rows.last().unwrap()[1], "2548.00", "at the goal at the end");
    let moving = after.iter().filter(|&&p| p > 2048.0 && p < 2548.0).count();
    assert!(moving >= 2, "the move is sampled on its way, not a jump: {moving} rows between");
    for row in &rows {
        assert!(row[2..7].iter().all(|p| p == "2048.00") && row[8..].iter().all(|g| g == "2048"), "{row:?}");
    }
}

/// Killed outright (no handler runs), the server leaves the rows of its last flush, at most
/// half a second old: whole rows on the grid. SIGTERM, like Ctrl-C, leaves the whole recording.
#[test]
fn a_killed_server_leaves_whole_rows_and_sigterm_the_whole_recording() {
    let _one = one_at_a_time();
    let dir = temp_dir("kill");
    for (sig, code) in [("KILL", None), ("TERM", Some(130))] {
        let file = dir.path().join(format!("{sig}.csv"));
        let (mut child, _path, errors) =
            serve(&["--protocol", "sts", "--ids", "1-6", "--pty", "--record", file.to_str().unwrap()]);
        std::thread::sleep(Duration::from_millis(1300));
        signal(&child, sig);
        assert_eq!(exit_code(&mut child), code, "{sig}");
        let errors = errors.join().unwrap();
        let (header, rows) = read_csv(&file);
        assert_eq!(header, HEADER);
        assert_grid(&rows);
        let least = if code.is_some() { 600 } else { 250 };
        assert!(rows.len() >= least, "{sig}: {} rows; {errors}", rows.len());
    }
}

/// A LeRobot calibration of the SO-101 whose shoulder servos were homed elsewhere: shoulder_pan's
/// range low on the turn (its homing offset put it there), shoulder_lift's high; the others as a
/// real file has them.
const CALIBRATION: &str = r#"{
    "shoulder_pan": {"id": 1, "drive_mode": 0, "homing_offset": 1500, "range_min": 100, "range_max": 1300},
    "shoulder_lift": {"id": 2, "drive_mode": 0, "homing_offset": -1400, "range_min": 2900, "range_max": 4000},
    "elbow_flex": {"id": 3, "drive_mode": 1, "homing_offset": 1007, "range_min": 893, "range_max": 3092},
    "wrist_flex": {"id": 4, "drive_mode": 0, "homing_offset": -1007, "range_min": 1500, "range_max": 2601},
    "wrist_roll": {"id": 5, "drive_mode": 0, "homing_offset": -1838, "range_min": 0, "range_max": 4095},
    "gripper": {"id": 6, "drive_mode": 0, "homing_offset": 1160, "range_min": 2019, "range_max": 3367}
}"#;

/// `--calibration`: servo 1 stands at 600, below the nominal range of shoulder_pan and inside the
/// calibrated one; servo 2 at 2048, the middle of the nominal range and below the calibrated
/// one. Torque on, then a small step each: the nominal monitor flags servo 1's goals only, the
/// calibrated one servo 2's only.
#[test]
fn a_calibration_moves_the_goal_ranges_the_monitor_judges_by() {
    let _one = one_at_a_time();
    let dir = temp_dir("calibration");
    let calibration = dir.path().join("so101.json");
    std::fs::write(&calibration, CALIBRATION).unwrap();
    let nominal = armctl::sim::limits_of(&armctl::arm::ArmSpec::load("so101", None).unwrap()).unwrap();
    let inside = |id: u8, goal: i64| {
        let (lo, hi) = nominal[usize::from(id) - 1].goal_range;
        (lo..=hi).contains(&goal)
    };
    assert!(!inside(1, 600) && !inside(1, 650) && inside(2, 2048) && inside(2, 2098), "{nominal:?}");

    let items = STS3215.items;
    let mut found = Vec::new();
    for calibrated in [false, true] {
        let mut args = vec!["--pty", "--arm", "so101", "--start", "1=600"];
        if calibrated {
            args.extend(["--calibration", calibration.to_str().unwrap()]);
        }
        let (mut child, path, errors) = serve(&args);
        let run = std::panic::catch_unwind(|| {
            let mut m = master(&path);
            write_item(&mut m, 1, items.torque_enable, 1);
            write_item(&mut m, 2, items.torque_enable, 1);
            // Well inside the speed limit: 50 ticks after 200 ms.
            std::thread::sleep(Duration::from_millis(200));
            write_item(&mut m, 1, items.goal_position, 650);
            write_item(&mut m, 2, items.goal_position, 2098);
            std::thread::sleep(Duration::from_millis(200));
        });
        signal(&child, "TERM");
        let code = exit_code(&mut child);
        let errors = errors.join().unwrap();
        run.expect("goals over the pty");
        assert_eq!(code, Some(130), "{errors}");
        let serving = errors.lines().next().unwrap_or_default();
        assert_eq!(serving.contains("as calibrated by"), calibrated, "{serving}");
        let violations: Vec<String> =
            errors.lines().filter(|l| l.starts_with("violation: ")).map(str::to_string).collect();
        found.push(violations);
    }
    let [nominal_found, calibrated_found] = [&found[0], &found[1]];
    assert_eq!(nominal_found.len(), 2, "{nominal_found:?}");
    for (line, goal) in nominal_found.iter().zip([600, 650]) {
        assert!(line.starts_with("violation: servo 1 at "), "{line}");
        assert!(line.contains(&format!("goal {goal} outside ")), "{line}");
    }
    assert_eq!(calibrated_found.len(), 2, "{calibrated_found:?}");
    for (line, goal) in calibrated_found.iter().zip([2048, 2098]) {
        assert!(line.starts_with("violation: servo 2 at "), "{line}");
        assert!(line.contains(&format!("goal {goal} outside ")), "{line}");
        // Inside the calibrated range_min..range_max of shoulder_lift.
        let range = line.rsplit(' ').next().unwrap();
        let (lo, hi) = range.split_once("..=").unwrap();
        let (lo, hi): (i64, i64) = (lo.parse().unwrap(), hi.parse().unwrap());
        assert!(lo >= 2900 && hi <= 4000 && lo < hi, "{line}");
    }
}

/// `armctl sim servos ARGS` in this process: its exit code, stdout and stderr.
fn run(args: &[&str]) -> (i32, String, String) {
    let (mut out, mut err) = (Vec::new(), Vec::new());
    let argv = ["armctl", "sim", "servos", "--pty"].iter().chain(args);
    let code = armctl::cli::main(argv, &mut out, &mut err);
    (code, String::from_utf8(out).unwrap(), String::from_utf8(err).unwrap())
}

/// A path that cannot be created, a directory, or a calibration that cannot be read or does not
/// fit the arm: one `error:` line, exit code 2, no pty. A recording is not created when other
/// arguments are wrong.
#[test]
fn bad_record_paths_and_calibrations_are_one_line() {
    let dir = temp_dir("bad");
    let missing_dir = dir.path().join("no-such-dir").join("x.csv");
    let not_json = dir.path().join("not.json");
    std::fs::write(&not_json, "{ this is not json").unwrap();
    let short = dir.path().join("short.json");
    std::fs::write(
        &short,
        r#"{"shoulder_pan": {"id": 1, "drive_mode": 0, "homing_offset": 0, "range_min": 100, "range_max": 1300}}"#,
    )
    .unwrap();
    let absent = dir.path().join("absent.json");
    let (missing, directory) = (missing_dir.to_str().unwrap(), dir.path().to_str().unwrap());
    for (args, expected) in [
        (vec!["--arm", "so101", "--record", missing], format!("error: --record {missing}: ")),
        (vec!["--arm", "so101", "--record", directory], format!("error: --record {directory}: ")),
        (vec!["--arm", "so101", "--calibration", absent.to_str().unwrap()], "error: --calibration: cannot read".into()),
        (vec!["--arm", "so101", "--calibration", not_json.to_str().unwrap()], "not a LeRobot calibration".into()),
        (vec!["--arm", "so101", "--calibration", short.to_str().unwrap()], "no motor with id 2".into()),
        (vec!["--protocol", "sts", "--ids", "1", "--calibration", short.to_str().unwrap()], "--arm".into()),
    ] {
        let (code, out, err) = run(&args);
        assert_eq!(code, 2, "{args:?}: {err}");
        assert!(err.starts_with("error: ") && err.lines().count() == 1, "{args:?}: {err}");
        assert!(err.contains(&expected), "{args:?}: {err}");
        assert!(out.is_empty(), "{args:?}: nothing served: {out}");
    }
    let untouched = dir.path().join("untouched.csv");
    let (code, _, err) = run(&["--arm", "so101", "--burst-ms", "0", "--record", untouched.to_str().unwrap()]);
    assert_eq!(code, 2, "{err}");
    assert!(!untouched.exists(), "no recording for arguments refused");
}
