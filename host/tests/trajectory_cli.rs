//! `armctl trajectory sample` end to end: real processes on keyframe files, CSV and JSON on
//! stdout, one-line errors naming the file line, and the PNG plot.

use serde_json::Value;
use std::path::Path;
use std::process::Command;

mod support;

struct Run {
    code: i32,
    stdout: String,
    stderr: String,
}

fn armctl(args: &[&str]) -> Run {
    let output = Command::new(env!("CARGO_BIN_EXE_armctl"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("armctl runs");
    Run {
        code: output.status.code().expect("armctl exits normally"),
        stdout: String::from_utf8(output.stdout).expect("UTF-8 stdout"),
        stderr: String::from_utf8(output.stderr).expect("UTF-8 stderr"),
    }
}

/// Writes `text` to `name` in a folder of its own, removed when dropped (also when the test fails).
fn file(name: &str, text: &str) -> support::TempPath {
    let path = support::TempPath::new(name);
    std::fs::write(&path, text).unwrap();
    path
}

fn sample(path: &Path, extra: &[&str]) -> Run {
    let mut args = vec!["trajectory", "sample", "--keyframes", path.to_str().unwrap()];
    args.extend_from_slice(extra);
    armctl(&args)
}

/// Parsed CSV output: header and rows of numbers.
fn csv(run: &Run) -> (Vec<String>, Vec<Vec<f64>>) {
    assert_eq!(run.code, 0, "stderr: {}", run.stderr);
    // Only notes (such as velocity columns a method does not use) may appear on stderr.
    assert!(run.stderr.lines().all(|l| l.starts_with("note: ")), "unexpected stderr: {}", run.stderr);
    let mut lines = run.stdout.lines();
    let header = lines.next().expect("header").split(',').map(String::from).collect::<Vec<_>>();
    let rows: Vec<Vec<f64>> =
        lines.map(|l| l.split(',').map(|x| x.parse::<f64>().expect("number")).collect()).collect();
    for row in &rows {
        assert_eq!(row.len(), header.len());
    }
    (header, rows)
}

fn assert_fails(run: &Run, needles: &[&str]) {
    assert_ne!(run.code, 0, "expected failure; stdout: {}", run.stdout);
    assert!(run.stdout.is_empty(), "stdout on failure: {}", run.stdout);
    // One error line; notes about ignored input may come before it.
    let lines: Vec<&str> = run.stderr.lines().filter(|l| !l.starts_with("note: ")).collect();
    assert_eq!(lines.len(), 1, "expected one stderr line besides notes: {:?}", run.stderr);
    assert!(lines[0].starts_with("error:"), "{}", lines[0]);
    for needle in needles {
        assert!(lines[0].contains(needle), "{:?} not in {:?}", needle, lines[0]);
    }
}

const TWO_JOINTS: &str = "t,q1,q2\n0,0,1\n0.5,1,0.5\n1.5,-1,2\n2,0,0\n";
const WITH_VELOCITIES: &str = "t,q1,q2,v1,v2\n0,0,1,0,0\n0.5,1,0.5,1,-1\n1.5,-1,2,0.5,0\n2,0,0,0,0\n";
const METHODS: [&str; 6] = ["linear", "catmull-rom", "monotone", "natural", "hermite", "kb"];

#[test]
fn every_method_passes_through_the_keyframes() {
    let path = file("methods.csv", WITH_VELOCITIES);
    let keyframes = [(0.0, [0.0, 1.0]), (0.5, [1.0, 0.5]), (1.5, [-1.0, 2.0]), (2.0, [0.0, 0.0])];
    for method in METHODS {
        let (header, rows) = csv(&sample(&path, &["--method", method]));
        assert_eq!(header, ["t", "q1", "q2", "v1", "v2", "a1", "a2"], "{method}");
        assert_eq!(rows.len(), 201, "{method}: 2 s at 100 Hz, both ends included");
        for (t, q) in keyframes {
            let row =
                rows.iter().find(|r| (r[0] - t).abs() < 1e-12).unwrap_or_else(|| panic!("{method}: no row at {t}"));
            assert!((row[1] - q[0]).abs() < 1e-12 && (row[2] - q[1]).abs() < 1e-12, "{method} at {t}: {row:?}");
        }
        assert_eq!(rows.last().unwrap()[0], 2.0);
        assert!(rows.iter().flatten().all(|x| x.is_finite()));
    }
}

#[test]
fn hermite_uses_the_given_velocities_and_kb_its_parameters() {
    let path = file("hermite.csv", WITH_VELOCITIES);
    let (_, rows) = csv(&sample(&path, &["--method", "hermite"]));
    let at = |t: f64| rows.iter().find(|r| (r[0] - t).abs() < 1e-12).unwrap().clone();
    assert!((at(0.5)[3] - 1.0).abs() < 1e-12 && (at(0.5)[4] + 1.0).abs() < 1e-12);
    assert!((at(1.5)[3] - 0.5).abs() < 1e-12);
    // Tension 1 zeroes every tangent: velocity zero at each keyframe, unlike Catmull-Rom.
    let (_, tense) = csv(&sample(&path, &["--method", "kb", "--tension", "1"]));
    let (_, cr) = csv(&sample(&path, &["--method", "catmull-rom"]));
    assert!(tense[50][3].abs() < 1e-12 && cr[50][3].abs() > 0.1, "{:?} {:?}", tense[50], cr[50]);
    let (_, kb0) = csv(&sample(&path, &["--method", "kb", "--tension=0", "--continuity", "0", "--bias", "0"]));
    for (a, b) in kb0.iter().zip(&cr) {
        for (x, y) in a.iter().zip(b) {
            assert!((x - y).abs() < 1e-9, "kb with zero TCB is Catmull-Rom");
        }
    }
}

#[test]
fn rate_sets_the_row_count() {
    let path = file("rate.csv", TWO_JOINTS);
    assert_eq!(csv(&sample(&path, &["--method", "linear", "--rate", "10"])).1.len(), 21);
    assert_eq!(csv(&sample(&path, &["--method", "linear", "--rate", "1"])).1.len(), 3);
    // 2 s at 3 Hz: 0, 1/3, ..., 6/3 = 2.
    assert_eq!(csv(&sample(&path, &["--method", "natural", "--rate", "3"])).1.len(), 7);
    // 2 s at 0.8 Hz: 0 and 1.25 on the grid, then the last keyframe time itself.
    let (_, rows) = csv(&sample(&path, &["--method", "natural", "--rate", "0.8"]));
    assert_eq!(rows.iter().map(|r| r[0]).collect::<Vec<_>>(), [0.0, 1.25, 2.0]);
    let run = sample(&path, &["--method", "linear", "--rate", "0"]);
    assert_fails(&run, &["--rate"]);
}

#[test]
fn json_output() {
    let path = file("json.csv", TWO_JOINTS);
    let run = sample(&path, &["--method", "monotone", "--rate", "10", "--json"]);
    assert_eq!(run.code, 0, "{}", run.stderr);
    assert_eq!(run.stdout.lines().count(), 1);
    let v: Value = serde_json::from_str(&run.stdout).unwrap();
    assert_eq!(v["method"], "monotone");
    assert_eq!(v["joints"], 2);
    assert_eq!(v["samples"].as_array().unwrap().len(), 21);
    assert_eq!(v["keyframes"].as_array().unwrap().len(), 4);
    assert_eq!(v["samples"][5]["q"], serde_json::json!([1.0, 0.5]));
}

#[test]
fn malformed_files_name_the_line() {
    let cases: [(&str, &str, &[&str]); 7] = [
        ("ragged.csv", "t,q1,q2\n0,0,0\n1,1\n2,0,0\n", &["line 3", "2 fields", "header has 3"]),
        ("order.csv", "t,q1\n0,0\n1,1\n# comment\n1,2\n", &["line 5", "not later", "line 3"]),
        ("nan.csv", "t,q1,q2\n0,0,0\n1,NaN,0\n", &["line 3", "column q1", "finite"]),
        ("word.csv", "t,q1\n0,0\n1,abc\n", &["line 3", "column q1", "not a number"]),
        ("header.csv", "time,q1\n0,0\n1,1\n", &["line 1", "header"]),
        ("one.csv", "t,q1\n0,0\n", &["line 2", "at least 2"]),
        ("empty.csv", "", &["empty"]),
    ];
    for (name, text, needles) in cases {
        let path = file(name, text);
        let run = sample(&path, &["--method", "linear"]);
        assert_fails(&run, needles);
        assert!(run.stderr.contains(name), "the file is named: {}", run.stderr);
    }
}

#[test]
fn hermite_without_velocity_columns() {
    let path = file("no_v.csv", TWO_JOINTS);
    assert_fails(&sample(&path, &["--method", "hermite"]), &["hermite", "v1", "v2"]);
}

#[test]
fn unreadable_file() {
    let run = armctl(&["trajectory", "sample", "--keyframes", "no/such/file.csv", "--method", "linear"]);
    assert_fails(&run, &["cannot read keyframe file", "no/such/file.csv"]);
}

#[test]
fn unknown_method_is_a_usage_error() {
    let path = file("usage.csv", TWO_JOINTS);
    let run = sample(&path, &["--method", "cubic"]);
    assert_eq!(run.code, 2);
    assert_eq!(run.stderr.lines().count(), 1, "{}", run.stderr);
}

#[test]
fn limits_slow_the_trajectory_down() {
    let path = file("limits.csv", TWO_JOINTS);
    // Within generous limits nothing changes and nothing is said.
    let (_, free) = csv(&sample(&path, &["--method", "catmull-rom", "--limits", "v=100,a=1000"]));
    assert_eq!(free.len(), 201);
    let run = sample(&path, &["--method", "catmull-rom", "--limits", "v=1,a=2", "--json"]);
    assert_eq!(run.code, 0, "{}", run.stderr);
    assert!(run.stderr.starts_with("note: time-scaled") && run.stderr.contains("duration 2 s ->"), "{}", run.stderr);
    let v: Value = serde_json::from_str(&run.stdout).unwrap();
    assert_eq!(v["time_scaled"], true);
    let duration = v["duration"].as_f64().unwrap();
    assert!(duration > 2.0);
    for s in v["samples"].as_array().unwrap() {
        for (x, limit) in [("v", 1.0), ("a", 2.0)] {
            for value in s[x].as_array().unwrap() {
                assert!(value.as_f64().unwrap().abs() <= limit * (1.0 + 1e-6), "{x} {s}");
            }
        }
    }
    assert_fails(&sample(&path, &["--method", "linear", "--limits", "v=1,a=2"]), &["linear", "--limits"]);
    assert_fails(&sample(&path, &["--method", "natural", "--limits", "v=1"]), &["--limits", "a="]);
    assert_fails(&sample(&path, &["--method", "natural", "--limits", "v=1:2:3,a=1"]), &["3 values for 2 joints"]);
    assert_fails(
        &sample(&path, &["--method", "natural", "--limits", "v=5,a=50,lo=-0.5,hi=3"]),
        &["line 4", "q1 = -1", "position range"],
    );
}

#[test]
fn plot_writes_a_png() {
    let path = file("plot.csv", WITH_VELOCITIES);
    let png = path.with_file_name("plot.png");
    let run = sample(&path, &["--method", "kb", "--continuity", "0.5", "--plot", png.to_str().unwrap()]);
    assert_eq!(run.code, 0, "{}", run.stderr);
    let bytes = std::fs::read(&png).expect("plot written");
    assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n");
    assert!(bytes.len() > 20_000, "only {} bytes", bytes.len());
    let run = sample(&path, &["--method", "kb", "--plot", "no/such/dir/plot.png"]);
    assert_fails(&run, &["cannot write plot"]);
}

#[test]
fn example_files_work() {
    let (header, rows) = csv(&armctl(&[
        "trajectory",
        "sample",
        "--keyframes",
        "examples/trajectories/pick_and_place_6dof.csv",
        "--method",
        "monotone",
    ]));
    assert_eq!(header.len(), 19);
    assert_eq!(rows.len(), 751);
    let (_, rows) = csv(&armctl(&[
        "trajectory",
        "sample",
        "--keyframes",
        "examples/trajectories/wave_with_velocities_3dof.csv",
        "--method",
        "hermite",
        "--rate",
        "50",
    ]));
    assert_eq!(rows.len(), 201);
}

#[test]
fn options_a_method_would_ignore_are_refused_or_noted() {
    let path = file("ignored.csv", WITH_VELOCITIES);
    let run = sample(&path, &["--method", "catmull-rom"]);
    assert_eq!(run.code, 0, "{}", run.stderr);
    assert_eq!(run.stderr.trim(), "note: --method catmull-rom ignores the velocity columns (only hermite uses them)");
    assert!(sample(&path, &["--method", "hermite"]).stderr.is_empty());
    assert_fails(&sample(&path, &["--method", "natural", "--tension", "0.5"]), &["--tension", "kb"]);
    assert_fails(&sample(&path, &["--method", "monotone", "--ends", "natural"]), &["--ends"]);
}
