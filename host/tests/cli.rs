//! The `armctl` binary end to end: real processes, real arguments, JSON on stdout, one-line errors
//! on stderr and the exit codes scripts rely on.

use serde_json::Value;
use std::io::Write;
use std::process::{Command, Stdio};

/// What one run of the binary did.
struct Run {
    code: i32,
    stdout: String,
    stderr: String,
}

impl Run {
    /// The single JSON line on stdout of a successful run.
    fn json(&self) -> Value {
        assert_eq!(self.code, 0, "exit code; stderr: {}", self.stderr);
        let lines: Vec<&str> = self.stdout.lines().collect();
        assert_eq!(lines.len(), 1, "expected one stdout line, got {:?}", self.stdout);
        serde_json::from_str(lines[0]).unwrap_or_else(|e| panic!("not JSON ({e}): {}", lines[0]))
    }

    /// Every stdout line as JSON.
    fn json_lines(&self) -> Vec<Value> {
        self.stdout.lines().map(|l| serde_json::from_str(l).unwrap_or_else(|e| panic!("not JSON ({e}): {l}"))).collect()
    }
}

fn armctl_with_input(args: &[&str], input: Option<&str>) -> Run {
    let mut child = Command::new(env!("CARGO_BIN_EXE_armctl"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .stdin(if input.is_some() { Stdio::piped() } else { Stdio::null() })
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("armctl starts");
    if let Some(text) = input {
        // Written from a thread so a large output cannot dead-lock against a full input pipe.
        let mut stdin = child.stdin.take().unwrap();
        let text = text.to_string();
        std::thread::spawn(move || stdin.write_all(text.as_bytes()).unwrap());
    }
    let output = child.wait_with_output().expect("armctl runs");
    Run {
        code: output.status.code().expect("armctl exits normally"),
        stdout: String::from_utf8(output.stdout).expect("UTF-8 stdout"),
        stderr: String::from_utf8(output.stderr).expect("UTF-8 stderr"),
    }
}

fn armctl(args: &[&str]) -> Run {
    armctl_with_input(args, None)
}

/// Asserts a failed run: non-zero exit, nothing on stdout, exactly one stderr line, which contains
/// every one of `needles`.
fn assert_fails(args: &[&str], needles: &[&str]) {
    let run = armctl(args);
    assert_ne!(run.code, 0, "{args:?} should fail; stdout: {}", run.stdout);
    assert!(run.stdout.is_empty(), "{args:?}: stdout should be empty, got {:?}", run.stdout);
    assert!(run.stderr.ends_with('\n'), "{args:?}: stderr {:?}", run.stderr);
    let lines: Vec<&str> = run.stderr.lines().collect();
    assert_eq!(lines.len(), 1, "{args:?}: expected one stderr line, got {:?}", run.stderr);
    assert!(lines[0].starts_with("error:"), "{args:?}: {}", lines[0]);
    for needle in needles {
        assert!(lines[0].contains(needle), "{args:?}: {:?} does not mention {needle:?}", lines[0]);
    }
}

fn numbers(v: &Value) -> Vec<f64> {
    v.as_array().unwrap_or_else(|| panic!("not an array: {v}")).iter().map(|x| x.as_f64().unwrap()).collect()
}

fn join(values: &[f64]) -> String {
    values.iter().map(|v| v.to_string()).collect::<Vec<_>>().join(",")
}

/// Tool position and quaternion of `arm` at `q`, from `armctl fk`.
fn fk(arm: &str, q: &[f64]) -> ([f64; 3], [f64; 4]) {
    let v = armctl(&["fk", "--arm", arm, "--q", &join(q)]).json();
    let p = numbers(&v["position"]);
    let w = numbers(&v["quaternion_wxyz"]);
    ([p[0], p[1], p[2]], [w[0], w[1], w[2], w[3]])
}

fn distance(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum::<f64>().sqrt()
}

/// Angle between the rotations of two unit quaternions w, x, y, z (q and -q are the same rotation),
/// from the relative rotation conj(a) * b as 2 atan2(|vector part|, |scalar part|).
fn angle(a: &[f64; 4], b: &[f64; 4]) -> f64 {
    let [aw, ax, ay, az] = *a;
    let [bw, bx, by, bz] = *b;
    let w = aw * bw + ax * bx + ay * by + az * bz;
    let x = aw * bx - ax * bw - ay * bz + az * by;
    let y = aw * by + ax * bz - ay * bw - az * bx;
    let z = aw * bz - ax * by + ay * bx - az * bw;
    2.0 * (x * x + y * y + z * z).sqrt().atan2(w.abs())
}

/// A file in the temp directory, removed when dropped (also when the test fails).
struct TempFile(tempfile::TempPath);

impl TempFile {
    fn new(tag: &str, contents: &str) -> Self {
        let prefix = format!("armctl-cli-test-{tag}-");
        let file = tempfile::Builder::new().prefix(&prefix).suffix(".jsonl").tempfile().unwrap();
        std::fs::write(file.path(), contents).unwrap();
        Self(file.into_temp_path())
    }

    fn path(&self) -> &str {
        self.0.to_str().unwrap()
    }
}

/// A path in the temp directory that does not exist.
fn missing_path(name: &str) -> String {
    let path = std::env::temp_dir().join(format!("armctl-cli-test-{}-does-not-exist", std::process::id())).join(name);
    assert!(!path.exists());
    path.to_str().unwrap().to_string()
}

const UR5E_Q: [f64; 6] = [0.3, -1.2, 1.0, -0.5, 1.1, 0.2];

#[test]
fn fk_ur5e_at_zero() {
    let v = armctl(&["fk", "--arm", "ur5e", "--q", "0,0,0,0,0,0"]).json();
    assert_eq!(v["arm"], "ur5e");
    // Standard DH at zero: (a2 + a3, -(d4 + d6), d1 - d5).
    let expected = [-0.425 - 0.3922, -(0.1333 + 0.0996), 0.1625 - 0.0997];
    let position = numbers(&v["position"]);
    assert_eq!(position.len(), 3);
    for (p, e) in position.iter().zip(expected) {
        assert!((p - e).abs() <= 1e-9, "position {position:?}, expected {expected:?}");
    }
    assert!((expected[0] + 0.8172).abs() < 1e-12 && (expected[1] + 0.2329).abs() < 1e-12);
    assert!((expected[2] - 0.0628).abs() < 1e-12);
    let quaternion = numbers(&v["quaternion_wxyz"]);
    assert_eq!(quaternion.len(), 4);
    assert!((quaternion.iter().map(|x| x * x).sum::<f64>().sqrt() - 1.0).abs() <= 1e-12, "{quaternion:?}");
    let rotation = v["rotation"].as_array().unwrap();
    assert_eq!(rotation.len(), 3);
    let frames = v["frames"].as_array().unwrap();
    assert_eq!(frames.len(), 6);
    for (i, frame) in frames.iter().enumerate() {
        assert_eq!(frame["joint"], format!("joint{}", i + 1));
        assert_eq!(numbers(&frame["position"]).len(), 3);
        assert_eq!(numbers(&frame["quaternion_wxyz"]).len(), 4);
    }
}

#[test]
fn jacobian_planar2() {
    let v = armctl(&["jacobian", "--arm", "planar:2", "--q", "0,0"]).json();
    let rows = v["jacobian"].as_array().unwrap();
    assert_eq!(rows.len(), 6);
    for row in rows {
        assert_eq!(numbers(row).len(), 2, "{row}");
    }
    // Two unit links along x, both joints about z: d(tip y)/dq = (2, 1), angular z = (1, 1).
    assert_eq!(numbers(&rows[1]), [2.0, 1.0]);
    assert_eq!(numbers(&rows[5]), [1.0, 1.0]);
}

#[test]
fn ik_reaches_a_pose_from_fk() {
    let (position, quaternion) = fk("ur5e", &UR5E_Q);
    let v = armctl(&["ik", "--arm", "ur5e", "--target", &join(&position), "--quat", &join(&quaternion)]).json();
    assert_eq!(v["status"], "converged", "{v}");
    assert!(v["position_error"].as_f64().unwrap() <= 1e-5, "{v}");
    assert!(v["orientation_error"].as_f64().unwrap() <= 1e-5, "{v}");
    let q = numbers(&v["q"]);
    assert_eq!(q.len(), 6);
    let (reached, reached_quaternion) = fk("ur5e", &q);
    assert!(distance(&reached, &position) <= 1e-5 + 1e-12, "{reached:?} vs {position:?}");
    assert!(angle(&reached_quaternion, &quaternion) <= 1e-5 + 1e-9, "{reached_quaternion:?} vs {quaternion:?}");
}

/// `--solver auto` (the default) answers by the closed form where the geometry has one, and says
/// so; `--all-solutions` lists every solution, each checked here by FK from outside; an arm
/// without a closed form, or a target its shape does not answer, is a one-line error.
#[test]
fn ik_closed_form_and_every_solution() {
    let (position, quaternion) = fk("ur5e", &UR5E_Q);
    let (target, quat) = (join(&position), join(&quaternion));
    let v = armctl(&["ik", "--arm", "ur5e", "--target", &target, "--quat", &quat]).json();
    assert_eq!(v["solver"], "analytic", "{v}");
    assert_eq!(v["status"], "converged", "{v}");
    let v = armctl(&["ik", "--arm", "ur5e", "--target", &target, "--quat", &quat, "--solver", "numeric"]).json();
    assert_eq!(v["solver"], "dls", "{v}");

    let v = armctl(&["ik", "--arm", "ur5e", "--target", &target, "--quat", &quat, "--all-solutions"]).json();
    assert_eq!(v["shape"], "three_parallel", "{v}");
    let solutions = v["solutions"].as_array().unwrap();
    assert_eq!(solutions.len(), 8, "{v}");
    let mut own = false;
    for s in solutions {
        let q = numbers(&s["q"]);
        let (reached, reached_quaternion) = fk("ur5e", &q);
        if s["exact"] == true {
            assert!(distance(&reached, &position) <= 1e-9 && angle(&reached_quaternion, &quaternion) <= 1e-7, "{s}");
        }
        own |= q.iter().zip(&UR5E_Q).all(|(a, b)| (a - b).abs() < 1e-6);
    }
    assert!(own, "the joints posed from are not among {v}");

    let (position, _) = fk("iiwa14", &[0.1, 0.5, -0.2, -1.0, 0.3, 0.8, 0.0]);
    assert_fails(
        &["ik", "--arm", "iiwa14", "--target", &join(&position), "--solver", "analytic"],
        &["iiwa14 has no closed form"],
    );
    assert_fails(&["ik", "--arm", "iiwa14", "--target", &join(&position), "--all-solutions"], &["no closed form"]);
    assert_fails(&["ik", "--arm", "ur5e", "--target", "0.3,0.2,0.4", "--solver", "analytic"], &["needs a full pose"]);
    assert_fails(&["ik", "--arm", "ur5e", "--target", "0.3,0.2,0.4", "--all-solutions"], &["needs a full pose"]);
    assert_fails(
        &["ik", "--arm", "ur5e", "--target", &target, "--quat", &quat, "--all-solutions", "--scalar", "f32"],
        &["runs in f64"],
    );
}

#[test]
fn ik_position_only_has_no_orientation_error() {
    let q = [0.2, -0.4, 0.6, 0.3, -0.5];
    let (position, _) = fk("so101", &q);
    let v = armctl(&["ik", "--arm", "so101", "--target", &join(&position)]).json();
    assert_eq!(v["status"], "converged", "{v}");
    assert!(v["orientation_error"].is_null(), "{v}");
    assert!(v["position_error"].as_f64().unwrap() <= 1e-5, "{v}");
    let (reached, _) = fk("so101", &numbers(&v["q"]));
    assert!(distance(&reached, &position) <= 1e-5 + 1e-12, "{reached:?} vs {position:?}");
}

#[test]
fn ik_in_f32() {
    let (position, quaternion) = fk("ur5e", &UR5E_Q);
    let v =
        armctl(&["ik", "--arm", "ur5e", "--target", &join(&position), "--quat", &join(&quaternion), "--scalar", "f32"])
            .json();
    assert_eq!(v["status"], "converged", "{v}");
    // The f32 defaults: 1e-4 m and 1e-3 rad.
    assert!(v["position_error"].as_f64().unwrap() <= 1e-4, "{v}");
    assert!(v["orientation_error"].as_f64().unwrap() <= 1e-3, "{v}");
    let (reached, reached_quaternion) = fk("ur5e", &numbers(&v["q"]));
    assert!(distance(&reached, &position) <= 2e-4, "{reached:?} vs {position:?}");
    assert!(angle(&reached_quaternion, &quaternion) <= 2e-3, "{reached_quaternion:?} vs {quaternion:?}");
}

#[test]
fn ik_runs_every_solver() {
    let (position, quaternion) = fk("ur5e", &UR5E_Q);
    for solver in ["auto", "analytic", "numeric", "dls", "newton", "transpose", "ccd", "gradient", "regularised"] {
        let run = armctl(&[
            "ik",
            "--arm",
            "ur5e",
            "--target",
            &join(&position),
            "--quat",
            &join(&quaternion),
            "--solver",
            solver,
        ]);
        let v = run.json();
        let status = v["status"].as_str().unwrap_or_else(|| panic!("{solver}: {v}"));
        assert!(["converged", "best_effort", "iteration_limit"].contains(&status), "{solver}: {v}");
        let q = numbers(&v["q"]);
        assert_eq!(q.len(), 6, "{solver}: {v}");
        assert!(q.iter().all(|x| x.is_finite()), "{solver}: {v}");
        // The reported errors are those of the returned q.
        let (reached, reached_quaternion) = fk("ur5e", &q);
        let position_error = v["position_error"].as_f64().unwrap();
        let orientation_error = v["orientation_error"].as_f64().unwrap();
        assert!((distance(&reached, &position) - position_error).abs() <= 1e-9, "{solver}: {v}");
        assert!((angle(&reached_quaternion, &quaternion) - orientation_error).abs() <= 1e-6, "{solver}: {v}");
        if status == "converged" {
            assert!(position_error <= 1e-5 && orientation_error <= 1e-5, "{solver}: {v}");
        }
    }
}

#[test]
fn errors_are_one_line_on_stderr() {
    let so101_urdf = "tests/data/so101_new_calib.urdf";
    let (missing_urdf, missing_toml) = (missing_path("arm.urdf"), missing_path("arm.toml"));
    let cases: Vec<(Vec<&str>, Vec<&str>)> = vec![
        (vec!["fk", "--arm", "no-such-arm", "--q", "0"], vec!["unknown arm", "no-such-arm"]),
        (vec!["fk", "--arm", "ur5e", "--q", "0,0"], vec!["6 joints", "2 joint values"]),
        (vec!["jacobian", "--arm", "planar:2", "--q", "0,0,0"], vec!["2 joints", "3 joint values"]),
        (vec!["fk", "--arm", "ur5e", "--q", "1,x"], vec!["--q", "\"x\"", "not a number"]),
        (vec!["fk", "--arm", "ur5e", "--q", "nan,0,0,0,0,0"], vec!["--q", "not a finite number"]),
        (vec!["ik", "--arm", "ur5e", "--target", "0.3,0.1,0.4", "--quat", "0,0,0,0"], vec!["quaternion"]),
        (vec!["ik", "--arm", "ur5e", "--target", "0.3,0.1"], vec!["--target", "expected 3"]),
        (vec!["ik", "--arm", "ur5e", "--target", "0.3,0.1,0.4", "--seed", "0,0"], vec!["6 joints", "2 joint values"]),
        (vec!["fk", "--arm", &missing_urdf, "--q", "0"], vec!["cannot read URDF", &missing_urdf]),
        (vec!["fk", "--arm", &missing_toml, "--q", "0"], vec!["cannot read arm file", &missing_toml]),
        (vec!["fk", "--arm", so101_urdf, "--q", "0,0,0,0,0"], vec!["--tip", "gripper_frame_link"]),
        (vec!["ik", "--arm", "ur5e", "--batch", &missing_toml], vec!["cannot open batch file"]),
        (vec!["frobnicate"], vec!["frobnicate"]),
        (vec!["fk", "--arm", "ur5e"], vec!["--q"]),
        (vec!["ik", "--arm", "ur5e"], vec!["--target"]),
        (vec!["jacobian", "--q", "0"], vec!["--arm"]),
        (vec!["ik", "--arm", "ur5e", "--target", "0,0,0", "--batch", "-"], vec!["--batch"]),
        (vec!["ik", "--arm", "ur5e", "--target", "0,0,0", "--solver", "magic"], vec!["magic"]),
        (vec!["bench", "ik", "--arm", "ur5e", "--n", "0"], vec!["--n"]),
        (vec!["fk", "--arm", "ur5e", "--tip", "tool0", "--q", "0,0,0,0,0,0"], vec!["--tip", ".urdf"]),
        (
            vec!["ik", "--arm", "ur5e", "--target", "0.3,0.1,0.4", "--quat", "0,2,0,0"],
            vec!["unit quaternion", "norm 2"],
        ),
        (vec![], vec!["command is missing"]),
        (vec!["bench"], vec!["command is missing"]),
    ];
    for (args, needles) in &cases {
        assert_fails(args, needles);
    }
}

#[test]
fn urdf_with_tip_works() {
    let v = armctl(&[
        "fk",
        "--arm",
        "tests/data/so101_new_calib.urdf",
        "--tip",
        "gripper_frame_link",
        "--q",
        "0.2,-0.4,0.6,0.3,-0.5",
    ])
    .json();
    let (preset, _) = fk("so101", &[0.2, -0.4, 0.6, 0.3, -0.5]);
    assert!(distance(&numbers(&v["position"]), &preset) <= 1e-9, "{v}");
}

/// Batch lines for UR5e: four good targets (1-4), a blank line (5), then three bad ones (6-8).
fn batch_input() -> (String, Vec<[f64; 3]>) {
    let qs = [UR5E_Q, [-0.7, -1.9, 1.6, 0.4, -0.8, 1.3], [1.2, -0.9, -1.1, 0.8, 0.6, -0.4]];
    let poses: Vec<([f64; 3], [f64; 4])> = qs.iter().map(|q| fk("ur5e", q)).collect();
    let pose_line =
        |(p, w): &([f64; 3], [f64; 4])| serde_json::json!({"position": p, "quaternion_wxyz": w}).to_string();
    let seed: Vec<f64> = qs[2].iter().map(|v| v + 0.05).collect();
    let lines = [
        pose_line(&poses[0]),
        pose_line(&poses[1]),
        serde_json::json!({"position": poses[1].0}).to_string(),
        serde_json::json!({"position": poses[2].0, "quaternion_wxyz": poses[2].1, "seed": seed}).to_string(),
        "   ".to_string(),
        r#"{"position": [0.1, 0.2"#.to_string(),
        serde_json::json!({"position": poses[0].0, "seed": [0.0, 0.0]}).to_string(),
        serde_json::json!({"position": poses[0].0, "speed": 1}).to_string(),
    ];
    let targets = vec![poses[0].0, poses[1].0, poses[1].0, poses[2].0];
    (lines.join("\n") + "\n", targets)
}

fn check_batch(run: &Run, targets: &[[f64; 3]], source: &str) {
    assert_eq!(run.code, 1, "bad lines give exit code 1; stderr: {}", run.stderr);
    let out = run.json_lines();
    assert_eq!(out.len(), 7, "one line per non-blank input line: {}", run.stdout);
    let numbers_seen: Vec<u64> = out.iter().map(|v| v["line"].as_u64().unwrap()).collect();
    assert_eq!(numbers_seen, [1, 2, 3, 4, 6, 7, 8]);
    for (v, target) in out[..4].iter().zip(targets) {
        assert_eq!(v["status"], "converged", "{v}");
        assert!(v.get("error").is_none(), "{v}");
        assert!(v["position_error"].as_f64().unwrap() <= 1e-5, "{v}");
        let (reached, _) = fk("ur5e", &numbers(&v["q"]));
        assert!(distance(&reached, target) <= 1e-5 + 1e-12, "{v}");
    }
    assert!(out[0]["orientation_error"].as_f64().unwrap() <= 1e-5);
    assert!(out[2]["orientation_error"].is_null(), "position-only line: {}", out[2]);
    for (v, (line, needle)) in out[4..].iter().zip([(6, ""), (7, "2 joint values"), (8, "speed")]) {
        let error = v["error"].as_str().unwrap_or_else(|| panic!("no error for line {line}: {v}"));
        assert!(error.contains(&format!("line {line}")), "{v}");
        assert!(error.contains(needle), "{v}");
        assert!(v.get("q").is_none() && v.get("status").is_none(), "{v}");
    }
    let stderr: Vec<&str> = run.stderr.lines().collect();
    assert_eq!(stderr.len(), 4, "three bad-line errors and the summary: {}", run.stderr);
    for (message, line) in stderr[..3].iter().zip([6, 7, 8]) {
        assert!(message.starts_with("error:") && message.contains(source), "{message}");
        assert!(message.contains(&format!("line {line}")), "{message}");
    }
    let summary = stderr[3];
    assert!(summary.contains("4/7 converged") && summary.contains("3 rejected"), "{summary}");
}

#[test]
fn batch_file() {
    let (input, targets) = batch_input();
    let file = TempFile::new("mixed", &input);
    let run = armctl(&["ik", "--arm", "ur5e", "--batch", file.path()]);
    check_batch(&run, &targets, file.path());
}

#[test]
fn batch_from_stdin() {
    let (input, targets) = batch_input();
    let run = armctl_with_input(&["ik", "--arm", "ur5e", "--batch", "-"], Some(&input));
    check_batch(&run, &targets, "-");
}

/// A line that is not UTF-8 is an error of that line alone: the lines around it are solved.
#[test]
fn batch_line_that_is_not_utf8_is_one_bad_line() {
    let (input, _) = batch_input();
    let good: Vec<&str> = input.lines().take(2).collect();
    let file = TempFile::new("utf8", "");
    let mut bytes = format!("{}\n", good[0]).into_bytes();
    bytes.extend_from_slice(b"{\"position\": [0.1, 0.2, 0.3], \"seed\": \"\xff\xfe\"}\n");
    bytes.extend_from_slice(format!("{}\n", good[1]).as_bytes());
    std::fs::write(&file.0, bytes).unwrap();
    let run = armctl(&["ik", "--arm", "ur5e", "--batch", file.path()]);
    assert_eq!(run.code, 1, "stderr: {}", run.stderr);
    let out = run.json_lines();
    assert_eq!(out.len(), 3, "{}", run.stdout);
    assert_eq!(out[0]["status"], "converged");
    assert!(out[1]["error"].as_str().unwrap().contains("line 2"), "{}", out[1]);
    assert_eq!(out[2]["status"], "converged");
    assert_eq!(run.stderr.lines().count(), 2, "{}", run.stderr);
}

/// `--batch -` answers each line before the next arrives: a program that writes a target and
/// waits for its result (a co-process) gets it, although output is buffered.
#[test]
fn batch_from_a_pipe_answers_before_the_next_line() {
    use std::io::{BufRead, BufReader, Write};
    let (input, _) = batch_input();
    let lines: Vec<&str> = input.lines().take(2).collect();
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_armctl"))
        .args(["ik", "--arm", "ur5e", "--batch", "-"])
        .stdin(std::process::Stdio::piped())
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let mut stdin = child.stdin.take().unwrap();
    let (sender, results) = std::sync::mpsc::channel();
    let stdout = child.stdout.take().unwrap();
    std::thread::spawn(move || {
        for line in BufReader::new(stdout).lines() {
            let _ = sender.send(line.unwrap());
        }
    });
    for (i, line) in lines.iter().enumerate() {
        writeln!(stdin, "{line}").unwrap();
        stdin.flush().unwrap();
        // stdin stays open: the answer must come without the end of the input.
        let answer = results.recv_timeout(std::time::Duration::from_secs(20)).expect("no answer to a line");
        let v: serde_json::Value = serde_json::from_str(&answer).unwrap();
        assert_eq!(v["line"], i + 1, "{v}");
        assert_eq!(v["status"], "converged", "{v}");
    }
    drop(stdin);
    assert!(child.wait().unwrap().success());
}

#[test]
fn batch_of_good_lines_exits_zero() {
    let (input, _) = batch_input();
    let good: Vec<&str> = input.lines().take(4).collect();
    let file = TempFile::new("good", &(good.join("\n") + "\n"));
    let run = armctl(&["ik", "--arm", "ur5e", "--batch", file.path()]);
    assert_eq!(run.code, 0, "stderr: {}", run.stderr);
    let out = run.json_lines();
    assert_eq!(out.len(), 4);
    for (i, v) in out.iter().enumerate() {
        assert_eq!(v["line"], i + 1);
        assert_eq!(v["status"], "converged", "{v}");
    }
    let stderr: Vec<&str> = run.stderr.lines().collect();
    assert_eq!(stderr.len(), 1, "{}", run.stderr);
    assert!(stderr[0].contains("4/4 converged") && stderr[0].contains("0 rejected"), "{}", stderr[0]);
    // The summary's figures: per solve, and end to end per line with the part that is not solving.
    let figure = |name: &str| -> f64 {
        let at = stderr[0].find(name).unwrap_or_else(|| panic!("no {name:?} in {}", stderr[0])) + name.len();
        stderr[0][at..].trim_start().split(' ').next().unwrap().parse().unwrap()
    };
    let (mean, median, p99) = (figure("mean"), figure("median"), figure("p99"));
    assert!(0.0 < median && median <= p99 && mean <= p99, "{}", stderr[0]);
    let (per_line, rest) = (figure("end to end"), figure("of which"));
    assert!(per_line >= mean && rest > 0.0 && rest < per_line, "{}", stderr[0]);
}

/// `--tolerance` is `--position-tolerance` (KDL's eps), and a tolerance far below the default is
/// met as asked.
#[test]
fn ik_takes_a_tighter_tolerance_and_more_iterations() {
    let (position, quaternion) = fk("ur5e", &UR5E_Q);
    let (target, quat) = (join(&position), join(&quaternion));
    let args = ["ik", "--arm", "ur5e", "--target", &target, "--quat", &quat, "--max-iterations", "5000"];
    let v = armctl(&[&args[..], &["--tolerance", "1e-12", "--orientation-tolerance", "1e-12"]].concat()).json();
    assert_eq!(v["status"], "converged", "{v}");
    assert!(v["position_error"].as_f64().unwrap() <= 1e-12, "{v}");
    assert!(v["orientation_error"].as_f64().unwrap() <= 1e-12, "{v}");
    assert_fails(&[&args[..], &["--tolerance", "0"]].concat(), &["tolerances must be positive"]);
    assert_fails(&[&args[..], &["--tolerance", "1e-6", "--position-tolerance", "1e-6"]].concat(), &["tolerance"]);
}

#[test]
fn bench_ik_without_k() {
    let run = armctl(&["bench", "ik", "--arm", "ur5e", "--n", "50", "--no-k"]);
    let v = run.json();
    let solvers = v["solvers"].as_array().unwrap();
    // The numerical solver, then auto (the UR5e has a closed form: three parallel axes).
    assert_eq!(solvers.len(), 2, "{v}");
    assert_eq!(solvers[0]["solver"], "armctl dls (numeric)");
    assert_eq!(solvers[1]["solver"], "armctl auto (closed form: three_parallel)");
    for s in solvers {
        assert_eq!(s["targets"], 50);
        assert!(s["success_percent"].as_f64().unwrap() >= 98.0, "{v}");
        assert_eq!(s["false_claims"], 0);
    }
    assert_eq!(run.stderr.lines().count(), 2, "{}", run.stderr);
}

/// With the `compare-k` feature (on under `cargo test --workspace`), k's solver runs beside ours;
/// without it (`cargo test -p armctl`), one note on stderr says how to get it.
#[test]
fn bench_ik_with_k() {
    let run = armctl(&["bench", "ik", "--arm", "ur5e", "--n", "20"]);
    let v = run.json();
    let solvers = v["solvers"].as_array().unwrap();
    for s in solvers {
        assert_eq!(s["targets"], 20, "{v}");
    }
    assert_eq!(solvers[0]["false_claims"], 0, "{v}");
    assert!(solvers[0]["success_percent"].as_f64().unwrap() >= 95.0, "{v}");
    if cfg!(feature = "compare-k") {
        assert_eq!(solvers.len(), 3, "{v}");
        assert!(solvers[2]["solver"].as_str().unwrap().starts_with('k'), "{v}");
        assert_eq!(run.stderr.lines().count(), 3, "{}", run.stderr);
    } else {
        assert_eq!(solvers.len(), 2, "{v}");
        assert_eq!(run.stderr.lines().count(), 3, "{}", run.stderr);
        assert!(
            run.stderr.contains("note: k's solver is not beside ours") && run.stderr.contains("--features compare-k")
        );
    }
}

/// A value that is finite in f64 but overflows f32 passes the host's checks and is refused by the
/// f32 solver: the JSON says invalid_input with its reason and no errors, stderr has one line, and
/// the exit code is 1.
#[test]
fn f32_overflow_is_refused_with_an_error() {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_armctl"))
        .args(["ik", "--arm", "ur5e", "--target", "1e39,0,0", "--scalar", "f32"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["status"], "invalid_input", "{v}");
    assert!(v["position_error"].is_null() && v["reason"].as_str().unwrap().contains("NaN or infinity"), "{v}");
    let stderr = String::from_utf8(out.stderr).unwrap();
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(stderr.starts_with("error: ") && stderr.contains("F32"), "{stderr}");
}

/// f32 is solved for the joint counts the firmware carries (1 to 8), as the firmware does; planar:8
/// solves in f32 and planar:9 is refused in one line that says what to use instead.
#[test]
fn f32_is_for_the_firmware_joint_counts() {
    let run = |arm: &str| {
        std::process::Command::new(env!("CARGO_BIN_EXE_armctl"))
            .args(["ik", "--arm", arm, "--target", "3,2,0", "--scalar", "f32"])
            .output()
            .unwrap()
    };
    let eight = run("planar:8");
    assert_eq!(eight.status.code(), Some(0), "{}", String::from_utf8_lossy(&eight.stderr));
    let v: serde_json::Value = serde_json::from_slice(&eight.stdout).unwrap();
    assert_eq!(v["status"], "converged", "{v}");
    let nine = run("planar:9");
    assert_eq!(nine.status.code(), Some(1));
    assert!(nine.stdout.is_empty());
    let stderr = String::from_utf8(nine.stderr).unwrap();
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(
        stderr.contains("1 to 8 joints") && stderr.contains("planar:9 has 9") && stderr.contains("--scalar f64"),
        "{stderr}"
    );
}

/// `armctl sim --qemu` on a machine without QEMU: one line saying how to install it, before any
/// board build. The binary runs with an empty PATH, so no qemu-system-arm can be found. Built
/// without the `board-tools` feature (`cargo test -p armctl`), the line says how to build it.
#[test]
fn sim_qemu_without_qemu_says_how_to_install_it() {
    let output = std::process::Command::new(env!("CARGO_BIN_EXE_armctl"))
        .args(["sim", "--qemu"])
        .env("PATH", "")
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(1), "{stderr}");
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    let expected = if cfg!(feature = "board-tools") {
        "qemu-system-arm is not installed (Debian: apt-get install qemu-system-arm)"
    } else {
        "armctl sim --qemu needs the board-tools feature"
    };
    assert!(stderr.contains(expected), "{stderr}");
}

/// Without the `board-tools` feature, each command that runs or reads a board binary fails at
/// once, in one line that gives the build that has it; with it, they are tested in bench_mcu.rs,
/// bench_loop_pass.rs, footprint_cli.rs and tests/hil_qemu.rs.
#[test]
#[cfg(not(feature = "board-tools"))]
fn board_commands_say_which_build_has_them() {
    for (args, command) in [
        (&["footprint"][..], "footprint"),
        (&["bench", "mcu"], "bench mcu"),
        (&["bench", "loop-pass"], "bench loop-pass"),
        (&["sim", "--qemu"], "sim --qemu"),
    ] {
        let output = std::process::Command::new(env!("CARGO_BIN_EXE_armctl")).args(args).output().unwrap();
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert_eq!(output.status.code(), Some(1), "{stderr}");
        assert!(output.stdout.is_empty());
        assert_eq!(stderr.lines().count(), 1, "{stderr}");
        assert!(stderr.contains(&format!("--features board-tools -- {command}")), "{command}: {stderr}");
    }
}

/// `armctl --help` lists the commands under the headings of `armctl::cli::GROUPS`, every visible
/// command in exactly one group, every name of the table a command, each with its own help line.
#[test]
fn help_groups_every_command_once() {
    let command = armctl::cli::command();
    let visible: Vec<&str> = command
        .get_subcommands()
        .filter(|c| !c.is_hide_set() && c.get_name() != "help")
        .map(|c| c.get_name())
        .collect();
    let grouped: Vec<&str> = armctl::cli::GROUPS.iter().flat_map(|(_, names)| names.iter().copied()).collect();
    for name in &visible {
        let n = grouped.iter().filter(|g| *g == name).count();
        assert_eq!(n, 1, "{name} is in {n} groups");
    }
    for name in &grouped {
        assert!(visible.contains(name), "the groups name {name}, which is no command");
    }
    let run = armctl(&["--help"]);
    assert_eq!(run.code, 0, "{}", run.stderr);
    let help = &run.stdout;
    assert!(help.starts_with("armctl drives arms of serial bus servos"), "{help}");
    for (heading, names) in armctl::cli::GROUPS {
        assert!(help.contains(&format!("\n{heading}:\n")), "{heading} missing from {help}");
        for name in *names {
            let about = command.find_subcommand(name).unwrap().get_about().unwrap().to_string();
            assert!(help.lines().any(|l| l.trim_start().starts_with(name) && l.ends_with(&about)), "{name}: {about}");
        }
    }
    // Listed once: clap's own flat list is not there as well.
    assert!(!help.contains("Commands:"), "{help}");
    assert_eq!(help.matches("\n  fk ").count(), 1, "{help}");
    // -h shows the same groups.
    assert!(armctl(&["-h"]).stdout.contains("\nKinematics:\n"));
}

/// `--json` before the command and after it, for every command whose output is JSON already (it
/// changes nothing) and for those that print text otherwise: the same single JSON line.
#[test]
fn json_before_or_after_every_command() {
    let keyframes = TempFile::new("keyframes", "t,q1,q2\n0,0,0\n1,0.5,-0.5\n");
    let bvh = format!("{}/tests/data/bvh/t_pose_arm.bvh", env!("CARGO_MANIFEST_DIR"));
    let commands: Vec<Vec<&str>> = vec![
        vec!["fk", "--arm", "so101", "--q", "0,0.1,0.2,0.3,0.4"],
        vec!["jacobian", "--arm", "planar:2", "--q", "0,0"],
        vec!["ik", "--arm", "so101", "--target", "0.2,0,0.1"],
        vec!["bench", "ik", "--arm", "planar:3", "--n", "20", "--no-k"],
        vec!["bench", "rate", "--protocol", "sts", "--seconds", "0.2"],
        vec!["bench", "bus", "--protocol", "dxl2", "--cycles", "5"],
        vec!["trajectory", "sample", "--keyframes", keyframes.path(), "--method", "linear", "--rate", "4"],
        vec!["ports"],
        vec!["retarget", bvh.as_str(), "--arm", "so101", "--seconds", "0.5"],
    ];
    for args in &commands {
        let before: Vec<&str> = std::iter::once("--json").chain(args.iter().copied()).collect();
        let after: Vec<&str> = args.iter().copied().chain(std::iter::once("--json")).collect();
        let (a, b) = (armctl(&before), armctl(&after));
        for run in [&a, &b] {
            assert_eq!(run.code, 0, "{args:?}: {}", run.stderr);
            let text = run.stdout.trim_end();
            serde_json::from_str::<Value>(text).unwrap_or_else(|e| panic!("{args:?}: not JSON ({e}): {text}"));
        }
        // The same answer, except for what is measured in real time.
        if !matches!(args[0], "bench" | "retarget") {
            assert_eq!(a.stdout, b.stdout, "{args:?}");
        }
    }
    // Given on both sides it is the same option once.
    armctl(&["--json", "fk", "--arm", "so101", "--q", "0,0,0,0,0", "--json"]).json();
    // --arm is global too, for the commands that have one.
    let q = ["--q", "0,0.1,0.2,0.3,0.4"];
    assert_eq!(
        armctl(&[&["--arm", "so101", "fk"][..], &q].concat()).stdout,
        armctl(&[&["fk", "--arm", "so101"][..], &q].concat()).stdout
    );
}

/// The demo prints text unless --json, which works on either side.
#[test]
fn demo_json_before_or_after() {
    for args in [&["--json", "demo", "--no-plot"][..], &["demo", "--no-plot", "--json"]] {
        let v = armctl(args).json();
        assert_eq!(v["arm"], "so101", "{args:?}");
    }
    let v = armctl(&["--arm", "open-manipulator-x", "--json", "demo", "--no-plot"]).json();
    assert_eq!(v["arm"], "open-manipulator-x");
    assert_fails(&["--arm", "so101", "demo", "--arm", "open-manipulator-x"], &["--arm is given twice"]);
}

/// Commands that need hardware take --json on either side: they get as far as the port, which
/// does not exist, and fail there in one line.
#[test]
fn json_is_parsed_for_the_commands_that_need_a_port() {
    let port = missing_path("ttyUSB9");
    let commands: Vec<Vec<&str>> = vec![
        vec!["servo", "scan", "--port", &port, "--protocol", "sts", "--ids", "1"],
        vec!["servo", "torque", "on", "--port", &port, "--protocol", "dxl2", "--id", "1"],
        vec!["doctor", "--bus", &port, "--protocol", "sts", "--baud", "1000000"],
        vec!["calibrate", "--bus", &port, "--protocol", "sts", "--arm", "so101", "--out", "/nonexistent-dir/a.toml"],
        vec!["--bus", &port, "--protocol", "sts", "status"],
        vec!["--bus", &port, "--protocol", "sts", "--arm", "so101", "calibrate", "--out", "/nonexistent-dir/a.toml"],
    ];
    for args in &commands {
        let before: Vec<&str> = std::iter::once("--json").chain(args.iter().copied()).collect();
        let after: Vec<&str> = args.iter().copied().chain(std::iter::once("--json")).collect();
        for argv in [before, after] {
            let run = armctl(&argv);
            assert_eq!(run.code, 1, "{argv:?}: clap refused it: {}", run.stderr);
            assert!(run.stdout.is_empty(), "{argv:?}: {}", run.stdout);
            assert_eq!(run.stderr.lines().count(), 1, "{argv:?}: {}", run.stderr);
            assert!(run.stderr.starts_with("error: "), "{argv:?}: {}", run.stderr);
            assert!(!run.stderr.contains("unexpected argument"), "{argv:?}: {}", run.stderr);
        }
    }
    // servo's --json also goes between servo and its subcommand.
    let run = armctl(&["servo", "--json", "scan", "--port", &port, "--protocol", "sts"]);
    assert_eq!((run.code, run.stderr.lines().count()), (1, 1), "{}", run.stderr);
}

/// A drive option before a command that has no use for it: one line naming the option and the
/// command.
#[test]
fn drive_options_before_other_commands_are_refused_in_one_line() {
    assert_fails(&["--rig", "bimanual-so101", "fk", "--arm", "so101", "--q", "0"], &["--rig", "`armctl fk`"]);
    assert_fails(&["--sim", "ik", "--arm", "so101", "--target", "0.2,0,0.1"], &["--sim", "`armctl ik`"]);
    assert_fails(
        &["--sim", "--object-mm", "20", "bench", "ik", "--arm", "so101"],
        &["--sim, --object-mm", "`armctl bench ik`"],
    );
    assert_fails(
        &["--port", "/dev/null", "servo", "scan", "--port", "/dev/null", "--protocol", "sts"],
        &["--port", "`armctl servo scan`"],
    );
    assert_fails(&["--arm", "so101", "calibrate", "--out", "a.toml"], &["calibrate needs --bus PORT, --protocol"]);
    assert_fails(&["--bus", "a", "calibrate", "--bus", "b", "--out", "a.toml"], &["--bus is given twice"]);
    assert_fails(&["fk", "--q", "0"], &["--arm is missing"]);
    // clap's own errors point at the help of the command they are about.
    assert_fails(&["bench", "ik", "--arm", "so101", "--bogus"], &["'--bogus'", "(see armctl bench ik --help)"]);
}

/// The commands that print a path or URL first and then serve: with --json the first line is an
/// object. Each is stopped by killing it once the line is read.
#[test]
fn json_first_line_of_the_serving_commands() {
    use std::io::BufRead;
    for (args, key) in [
        (&["--json", "sim", "servos", "--pty", "--protocol", "sts", "--ids", "1"][..], "pty"),
        (&["sim", "servos", "--pty", "--protocol", "sts", "--ids", "1", "--json"], "pty"),
        (&["--json", "--sim", "serve"], "pty"),
        (&["serve", "--sim", "--json"], "pty"),
        (&["--json", "view", "--listen", "127.0.0.1:0"], "url"),
        (&["view", "--sim", "--listen", "127.0.0.1:0", "--json"], "url"),
    ] {
        let mut child = Command::new(env!("CARGO_BIN_EXE_armctl"))
            .args(args)
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        let mut line = String::new();
        std::io::BufReader::new(child.stdout.take().unwrap()).read_line(&mut line).unwrap();
        child.kill().unwrap();
        child.wait().unwrap();
        let v: Value = serde_json::from_str(&line).unwrap_or_else(|e| panic!("{args:?}: not JSON ({e}): {line:?}"));
        assert!(v[key].as_str().is_some_and(|s| !s.is_empty()), "{args:?}: {v}");
    }
}
