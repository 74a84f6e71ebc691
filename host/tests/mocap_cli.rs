//! `armctl retarget` end to end on the small BVH files of `host/tests/data/bvh` (their README says
//! what each holds): the report, the keyframe file `armctl play` reads, the rests, the same
//! keyframes from the same motion written for three rests, CRLF and tabs, a wrong frame count,
//! one-line errors naming the file and line, and `--play` on the simulated arm.

use serde_json::Value;
use std::path::PathBuf;
mod support;

use support::armctl;

fn data(name: &str) -> String {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data/bvh").join(name).display().to_string()
}

/// `name` in a folder of its own, removed when dropped (also when the test fails).
fn temp(name: &str) -> support::TempPath {
    support::TempPath::new(name)
}

/// The report line of a successful run, and its keyframe file's text.
fn retarget(file: &str, arm: &str, extra: &[&str]) -> (Value, String, String) {
    let out = temp(&format!("{}-{arm}.csv", file.replace('/', "_")));
    let mut args = vec!["retarget", file, "--arm", arm, "--out", out.to_str().unwrap()];
    args.extend(extra);
    let run = armctl(&args);
    assert_eq!(run.code, 0, "stderr: {}", run.stderr);
    let lines: Vec<&str> = run.stdout.lines().collect();
    assert_eq!(lines.len(), 1, "{}", run.stdout);
    let report = serde_json::from_str(lines[0]).unwrap();
    let csv = std::fs::read_to_string(&out).unwrap();
    (report, csv, run.stderr)
}

#[test]
fn a_t_pose_arm_gives_a_report_and_keyframes_play_reads() {
    let (r, csv, stderr) = retarget(&data("t_pose_arm.bvh"), "so101", &[]);
    assert_eq!(r["frames"], 41);
    assert_eq!(r["frame_time"], 0.05);
    assert_eq!(r["chain"], serde_json::json!(["RightArm", "RightForeArm", "RightHand"]));
    assert_eq!(r["rest_detected"], "t-pose");
    // 2 s at 25 keyframes a second, both ends included; more where a joint's step was long.
    assert_eq!(r["keyframes_sampled"], 51);
    let keyframes = r["keyframes"].as_u64().unwrap() as usize;
    assert!(keyframes >= 51, "{r}");
    assert_eq!(r["inside_workspace"], 1.0);
    // Tool against target over reachable keyframes: the IK tolerance, 0.1 mm.
    assert!(r["tracking_mm"]["max"].as_f64().unwrap() <= 0.1, "{r}");
    // Auto scale: the SO-101's reach over the 6-unit human arm.
    let scale = r["scale_m_per_unit"].as_f64().unwrap();
    assert!((0.05..0.1).contains(&scale), "{scale}");
    assert!(
        stderr.contains("note: chain RightArm -> RightForeArm -> RightHand (the right arm by its names"),
        "{stderr}"
    );
    assert!(
        stderr.contains("note: rest: t-pose (the upper arm points 0.0 degrees below horizontal at rest)"),
        "{stderr}"
    );
    let header = csv.lines().next().unwrap();
    assert_eq!(header, "t,q1,q2,q3,q4,q5");
    let k = armctl::motion::trajectory::parse_keyframes(&csv).unwrap();
    assert_eq!(k.times.len(), keyframes);
    let arm = armctl::arm::dof::build(armctl::arm::ArmSpec::load("so101", None).unwrap()).unwrap();
    assert!(k.positions.iter().all(|q| arm.admits(q)), "a keyframe beyond the joint limits");
    // No joint faster than 90 % of the SO-101's 2 rad/s between keyframes (1e-4 for the times'
    // six decimals).
    for (t, q) in k.times.windows(2).zip(k.positions.windows(2)) {
        let dt = t[1] - t[0];
        for (a, b) in q[0].iter().zip(&q[1]) {
            assert!((a - b).abs() <= 1.8 * dt + 1e-4, "{a} -> {b} in {dt} s");
        }
    }
}

#[test]
fn the_same_motion_for_three_rests_retargets_to_the_same_keyframes() {
    let (t, t_csv, _) = retarget(&data("t_pose_arm.bvh"), "so101", &[]);
    for (file, rest, droop) in [("a_pose_arm.bvh", "a-pose", 45.0), ("arms_down.bvh", "arms-down", 90.0)] {
        let (r, csv, stderr) = retarget(&data(file), "so101", &[]);
        assert_eq!(r["rest_detected"], rest);
        assert!((r["upper_arm_droop_deg"].as_f64().unwrap() - droop).abs() < 1e-4);
        assert!(stderr.contains(&format!("note: rest: {rest}")), "{stderr}");
        assert_eq!(r["keyframes"], t["keyframes"]);
        // The files round offsets to 6 decimals: the joint values agree to 1e-5 rad.
        let a = armctl::motion::trajectory::parse_keyframes(&csv).unwrap();
        let b = armctl::motion::trajectory::parse_keyframes(&t_csv).unwrap();
        for (qa, qb) in a.positions.iter().zip(&b.positions) {
            for (x, y) in qa.iter().zip(qb) {
                assert!((x - y).abs() < 1e-5, "{file}: {x} against {y}");
            }
        }
    }
    // On a six-joint arm the hand's turn is followed too, and it is the same turn in every rest.
    let (t6, t6_csv, _) = retarget(&data("t_pose_arm.bvh"), "ur5e", &[]);
    let (a6, a6_csv, _) = retarget(&data("a_pose_arm.bvh"), "ur5e", &[]);
    assert_eq!(t6["oriented"], a6["oriented"]);
    // Where the ur5e can take the pose at all (the placed path runs near its full reach): in part.
    assert!(t6["oriented"].as_f64().unwrap() > 0.25, "{t6}");
    let a = armctl::motion::trajectory::parse_keyframes(&a6_csv).unwrap();
    let b = armctl::motion::trajectory::parse_keyframes(&t6_csv).unwrap();
    for (qa, qb) in a.positions.iter().zip(&b.positions) {
        for (x, y) in qa.iter().zip(qb) {
            assert!((x - y).abs() < 1e-4, "{x} against {y}");
        }
    }
}

#[test]
fn crlf_tabs_and_a_wrong_frame_count_read_as_the_plain_file() {
    let (_, plain, _) = retarget(&data("t_pose_arm.bvh"), "so101", &[]);
    let (_, crlf, stderr) = retarget(&data("crlf_tabs.bvh"), "so101", &[]);
    assert_eq!(crlf, plain);
    assert!(!stderr.contains("warning"), "{stderr}");
    let (r, wrong, stderr) = retarget(&data("wrong_frame_count.bvh"), "so101", &[]);
    assert_eq!(wrong, plain);
    assert_eq!(r["frames"], 41);
    let line = format!(
        "warning: {}: Frames: says 42, but 41 frame lines follow: using the 41 present",
        data("wrong_frame_count.bvh")
    );
    assert!(stderr.lines().any(|l| l == line), "{stderr}");
}

fn assert_error(args: &[&str], expected: &str) {
    let run = armctl(args);
    assert_eq!(run.code, 1, "{args:?}: {}", run.stderr);
    assert!(run.stdout.is_empty(), "{}", run.stdout);
    assert_eq!(run.stderr.trim_end(), expected);
}

#[test]
fn malformed_files_fail_in_one_line_naming_file_and_line() {
    for (file, message) in [
        ("missing_brace.bvh", "line 25: MOTION comes where `JOINT`, `End Site` or `}` was expected (a `}` missing?)"),
        ("bad_number.bvh", "line 12: OFFSET y: `0,5` is not a finite number"),
        ("short_line.bvh", "line 31: 14 values, but the hierarchy has 15 channels"),
        (
            "unknown_channel.bvh",
            "line 9: unknown channel `Xrot` (Xposition, Yposition, Zposition, Xrotation, Yrotation, Zrotation)",
        ),
    ] {
        let path = data(file);
        assert_error(&["retarget", &path, "--arm", "so101"], &format!("error: {path}: {message}"));
    }
}

#[test]
fn bad_options_fail_in_one_line() {
    let t = data("t_pose_arm.bvh");
    assert_error(
        &["retarget", &t, "--arm", "so101", "--chain", "RightArm,RightHand"],
        &format!("error: {t}: --chain RightArm,RightHand: give three joint names, SHOULDER,ELBOW,WRIST"),
    );
    assert_error(
        &["retarget", &t, "--arm", "so101", "--chain", "LeftArm,LeftForeArm,LeftHand"],
        &format!("error: {t}: --chain: no joint named LeftArm; the file's joints are Hips, RightArm, RightForeArm, RightHand"),
    );
    assert_error(&["retarget", &t], "error: --arm is required: the arm to retarget onto");
    assert_error(
        &["retarget", &t, "--arm", "so101", "--scale", "big"],
        "error: --scale big: expected auto or a number (metres per file unit)",
    );
    assert_error(
        &["retarget", &t, "--arm", "so101", "--reference", "x-pose"],
        "error: --reference x-pose: expected auto, t-pose, a-pose or arms-down",
    );
    assert_error(
        &["retarget", &t, "--arm", "so101", "--sim"],
        "error: --sim is for driving an arm: add --play to stream the keyframes to it",
    );
    assert_error(
        &["retarget", &t, "--arm", "so101", "--play"],
        "error: --play streams the keyframes to an arm: give --sim, --port PORT or --bus PORT",
    );
    let missing = data("nothing-here.bvh");
    let run = armctl(&["retarget", &missing, "--arm", "so101"]);
    assert_eq!(run.code, 1);
    assert!(run.stderr.starts_with(&format!("error: cannot read BVH file {missing}: ")), "{}", run.stderr);
    assert_eq!(run.stderr.lines().count(), 1);
}

#[test]
fn a_file_without_a_right_arm_lists_its_joints() {
    let file = temp("left.bvh");
    let text = std::fs::read_to_string(data("t_pose_arm.bvh")).unwrap().replace("Right", "Left");
    std::fs::write(&file, text).unwrap();
    let path = file.display().to_string();
    let run = armctl(&["retarget", &path, "--arm", "so101"]);
    assert_eq!(run.code, 1);
    assert_eq!(
        run.stderr.trim_end(),
        format!(
            "error: {path}: no right arm found (tried RightArm/RightForeArm/RightHand, rShldr/rForeArm/rHand, \
             RightShoulder/RightElbow/RightWrist); give --chain SHOULDER,ELBOW,WRIST from the file's joints: Hips, \
             LeftArm, LeftForeArm, LeftHand"
        )
    );
}

#[test]
fn play_streams_the_keyframes_to_the_simulated_arm() {
    let plot = temp("play.png");
    // Without the table: this file's hand, scaled to the arm, goes down to 9 mm above the base
    // plane, which the collision check refuses before anything moves (as it should).
    let run = armctl(&[
        "--sim",
        "--no-table",
        "retarget",
        &data("t_pose_arm.bvh"),
        "--arm",
        "so101",
        "--play",
        "--plot",
        plot.to_str().unwrap(),
    ]);
    assert_eq!(run.code, 0, "{}", run.stderr);
    let lines: Vec<Value> = run.stdout.lines().map(|l| serde_json::from_str(l).unwrap()).collect();
    assert_eq!(lines.len(), 2, "{}", run.stdout);
    assert_eq!(lines[0]["command"], "retarget");
    assert_eq!(lines[1]["command"], "play");
    assert_eq!(lines[1]["keyframes"], lines[0]["keyframes"]);
    assert_eq!(lines[1]["pushed"], lines[0]["keyframes"]);
    let png = std::fs::read(&plot).unwrap();
    assert_eq!(&png[1..4], b"PNG");
}
