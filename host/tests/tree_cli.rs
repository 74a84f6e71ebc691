//! A URDF with branches from the command line: `armctl fk`, `jacobian` and `ik` on
//! `tests/data/bimanual_torso.urdf` (two five-joint arms on a turning torso, and a camera on it),
//! read as a tree because it has several leaves and no `--tip` is given. Each end effector is
//! checked against the chain the same binary reads with `--tip` at that leaf (an independent path
//! through the file: the chain's reader and the chain's kinematics), the IK by forward kinematics
//! of its answer, and every bad input gets one line.

mod support;

use kinematics::SplitMix64;
use serde_json::Value;
use support::{armctl, Run};

const URDF: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/bimanual_torso.urdf");
const LEAVES: [&str; 3] = ["camera_link", "left_tip", "right_tip"];

/// Numbers as typed on the command line, each the shortest text that reads back to the same f64.
fn join(values: &[f64]) -> String {
    values.iter().map(|v| format!("{v:?}")).collect::<Vec<_>>().join(",")
}

fn numbers(v: &Value) -> Vec<f64> {
    v.as_array().unwrap_or_else(|| panic!("not an array: {v}")).iter().map(|x| x.as_f64().unwrap()).collect()
}

fn run(args: &[&str]) -> Value {
    armctl(args).json()
}

/// The tree's joint names (as `fk` prints its frames) and limits (from the URDF).
struct TreeJoints {
    names: Vec<String>,
    limits: Vec<(f64, f64)>,
}

fn tree_joints() -> TreeJoints {
    let fk = run(&["fk", "--arm", URDF, "--q", &join(&[0.0; 11])]);
    let names: Vec<String> =
        fk["frames"].as_array().unwrap().iter().map(|f| f["joint"].as_str().unwrap().to_string()).collect();
    let spec = armctl::arm::urdf::parse_tree(&std::fs::read_to_string(URDF).unwrap(), &[]).unwrap();
    assert_eq!(names, spec.joints.iter().map(|j| j.name.clone()).collect::<Vec<_>>());
    TreeJoints { names, limits: spec.joints.iter().map(|j| (j.lower, j.upper)).collect() }
}

fn random_q(joints: &TreeJoints, rng: &mut SplitMix64, margin: f64) -> Vec<f64> {
    joints
        .limits
        .iter()
        .map(|&(lo, hi)| {
            let m = (hi - lo) * margin;
            rng.uniform(lo + m, hi - m)
        })
        .collect()
}

/// Each end effector's pose from the tree equals the chain's read with `--tip` at its leaf, and
/// its Jacobian the chain's in the path's columns and zero elsewhere, to 1e-12 at random joints.
#[test]
fn each_end_effector_is_the_chain_to_its_leaf() {
    let joints = tree_joints();
    let mut rng = SplitMix64::new(41);
    for _ in 0..4 {
        let q = random_q(&joints, &mut rng, 0.0);
        let tree_fk = run(&["fk", "--arm", URDF, "--q", &join(&q)]);
        let tree_jacobian = run(&["jacobian", "--arm", URDF, "--q", &join(&q)]);
        assert_eq!(tree_fk["arm"], "bimanual_torso");
        assert_eq!(tree_fk["effectors"].as_object().unwrap().len(), 3);
        let columns: Vec<&str> =
            tree_jacobian["joints"].as_array().unwrap().iter().map(|n| n.as_str().unwrap()).collect();
        assert_eq!(columns, joints.names);
        for leaf in LEAVES {
            // The chain to this leaf (its joints by name, from the chain's reader), its values
            // taken from the tree's.
            let chain = armctl::arm::urdf::parse(&std::fs::read_to_string(URDF).unwrap(), Some(leaf)).unwrap();
            let path: Vec<usize> =
                chain.joints.iter().map(|j| joints.names.iter().position(|n| *n == j.name).unwrap()).collect();
            let on_path: Vec<f64> = path.iter().map(|&k| q[k]).collect();
            let chain_fk = run(&["fk", "--arm", URDF, "--tip", leaf, "--q", &join(&on_path)]);
            let mine = &tree_fk["effectors"][leaf];
            for field in ["position", "quaternion_wxyz"] {
                let (a, b) = (numbers(&mine[field]), numbers(&chain_fk[field]));
                assert!(a.iter().zip(&b).all(|(x, y)| (x - y).abs() <= 1e-12), "{leaf} {field}: {a:?} != {b:?}");
            }
            for (r, row) in mine["rotation"].as_array().unwrap().iter().enumerate() {
                let (a, b) = (numbers(row), numbers(&chain_fk["rotation"][r]));
                assert!(a.iter().zip(&b).all(|(x, y)| (x - y).abs() <= 1e-12), "{leaf} rotation row {r}");
            }
            let chain_jacobian = run(&["jacobian", "--arm", URDF, "--tip", leaf, "--q", &join(&on_path)]);
            let rows = tree_jacobian["effectors"][leaf]["jacobian"].as_array().unwrap();
            assert_eq!(rows.len(), 6);
            for (r, row) in rows.iter().enumerate() {
                let row = numbers(row);
                assert_eq!(row.len(), 11);
                let chain_row = numbers(&chain_jacobian["jacobian"][r]);
                for (k, value) in row.iter().enumerate() {
                    let want = path.iter().position(|&p| p == k).map_or(0.0, |c| chain_row[c]);
                    assert!((value - want).abs() <= 1e-12, "{leaf} row {r} column {k}: {value} != {want}");
                }
            }
        }
    }
}

/// A target: the end effector's link, its position and its quaternion (w first) if any.
type Target = (&'static str, Vec<f64>, Option<Vec<f64>>);

/// `q` is within the limits and each target reached by FK of the answer.
fn check_reached(joints: &TreeJoints, answer: &Value, targets: &[Target]) {
    assert_eq!(answer["status"], "converged", "{answer}");
    assert_eq!(answer["solver"], "dls");
    let q = numbers(&answer["q"]);
    for (v, (lo, hi)) in q.iter().zip(&joints.limits) {
        assert!(lo - 1e-12 <= *v && *v <= hi + 1e-12, "{v} outside [{lo}, {hi}]");
    }
    let fk = run(&["fk", "--arm", URDF, "--q", &join(&q)]);
    for (leaf, position, quat) in targets {
        let reached = &answer["effectors"][leaf];
        assert_eq!(reached["reached"], true, "{answer}");
        let p = numbers(&fk["effectors"][leaf]["position"]);
        let distance = p.iter().zip(position).map(|(a, b)| (a - b).powi(2)).sum::<f64>().sqrt();
        assert!(distance <= 1e-5, "{leaf}: {distance} m from its target");
        assert!((reached["position_error"].as_f64().unwrap() - distance).abs() < 1e-9);
        match quat {
            Some(want) => {
                let got = numbers(&fk["effectors"][leaf]["quaternion_wxyz"]);
                let dot: f64 = got.iter().zip(want).map(|(a, b)| a * b).sum();
                assert!(dot.abs() >= 1.0 - 1e-9, "{leaf}: orientation off ({got:?} against {want:?})");
                assert!(reached["orientation_error"].as_f64().unwrap() <= 1e-5);
            }
            None => assert!(reached["orientation_error"].is_null()),
        }
    }
    assert!(answer["effectors"].get("camera_link").is_none(), "only the end effectors with a target are listed");
}

/// Both hands to random reachable targets at once (FK of random joint values 5 % inside the
/// limits), positions and full poses, seeded at the middle: one tree problem, checked by FK.
#[test]
fn both_hands_reach_random_reachable_targets_at_once() {
    let joints = tree_joints();
    let mut rng = SplitMix64::new(42);
    for oriented in [false, true] {
        for _ in 0..4 {
            let q = random_q(&joints, &mut rng, 0.05);
            let fk = run(&["fk", "--arm", URDF, "--q", &join(&q)]);
            let targets: Vec<Target> = ["left_tip", "right_tip"]
                .into_iter()
                .map(|leaf| {
                    let e = &fk["effectors"][leaf];
                    (leaf, numbers(&e["position"]), oriented.then(|| numbers(&e["quaternion_wxyz"])))
                })
                .collect();
            let texts: Vec<String> = targets
                .iter()
                .map(|(leaf, p, quat)| {
                    let mut values = p.clone();
                    values.extend(quat.iter().flatten());
                    format!("{leaf}={}", join(&values))
                })
                .collect();
            let answer = run(&["ik", "--arm", URDF, "--target", &texts[0], "--target", &texts[1]]);
            check_reached(&joints, &answer, &targets);
        }
    }
}

/// The priority mode: the left hand's target first, the right's out of reach in the null space
/// it leaves: the left reached, the right short and said so, exit code 0 (an answer, as a chain's
/// best effort is). Seeded where the right hand's target lies.
#[test]
fn the_first_priority_is_kept_against_a_target_out_of_reach() {
    let joints = tree_joints();
    let mut rng = SplitMix64::new(43);
    let q = random_q(&joints, &mut rng, 0.1);
    let fk = run(&["fk", "--arm", URDF, "--q", &join(&q)]);
    let left = numbers(&fk["effectors"]["left_tip"]["position"]);
    let left_target = format!("left_tip={}", join(&left));
    let args =
        ["ik", "--arm", URDF, "--target", &left_target, "--target", "right_tip=2,-0.2,0.3", "--priority", "left_tip"];
    let answer = run(&args);
    assert_eq!(answer["status"], "best_effort", "{answer}");
    assert_eq!(answer["effectors"]["left_tip"]["reached"], true, "{answer}");
    assert_eq!(answer["effectors"]["left_tip"]["priority"], 0);
    assert_eq!(answer["effectors"]["right_tip"]["priority"], 1);
    assert_eq!(answer["effectors"]["right_tip"]["reached"], false);
    assert!(answer["effectors"]["right_tip"]["position_error"].as_f64().unwrap() > 1.0);
    let at = run(&["fk", "--arm", URDF, "--q", &join(&numbers(&answer["q"]))]);
    let p = numbers(&at["effectors"]["left_tip"]["position"]);
    assert!(p.iter().zip(&left).all(|(a, b)| (a - b).abs() <= 1e-5), "{p:?} against {left:?}");
}

/// Asserts a refused run: a non-zero exit code, nothing on stdout, one `error:` line naming every
/// one of `needles`.
fn assert_fails(args: &[&str], needles: &[&str]) {
    let Run { code, stdout, stderr } = armctl(args);
    assert_ne!(code, 0, "{args:?} should fail; stdout: {stdout}");
    assert!(stdout.is_empty(), "{args:?}: stdout {stdout:?}");
    let lines: Vec<&str> = stderr.lines().collect();
    assert_eq!(lines.len(), 1, "{args:?}: expected one stderr line, got {stderr:?}");
    assert!(lines[0].starts_with("error:"), "{args:?}: {}", lines[0]);
    for needle in needles {
        assert!(lines[0].contains(needle), "{args:?}: {:?} does not mention {needle:?}", lines[0]);
    }
}

#[test]
fn bad_input_is_one_line() {
    let ten = join(&[0.0; 10]);
    let left = "left_tip=0.3,0.2,0.4";
    fn ik<'a>(rest: &[&'a str]) -> Vec<&'a str> {
        [&["ik", "--arm", URDF][..], rest].concat()
    }
    let batch = support::TempPath::new("targets.jsonl");
    std::fs::write(&batch, "{\"position\":[0.3,0.2,0.4]}\n").unwrap();
    let batch = batch.display().to_string();
    for (args, needles) in [
        (ik(&["--target", "nope=0.3,0.2,0.4"]), &["no end effector \"nope\"", "camera_link, left_tip, right_tip"][..]),
        (ik(&["--target", "left_tip=nan,0,0"]), &["--target left_tip: value 1", "not a finite number"]),
        (ik(&["--target", left, "--target", "left_tip=0.1,0.2,0.3"]), &["left_tip has two targets"]),
        (ik(&["--target", "0.3,0.2,0.4"]), &["NAME=x,y,z", "left_tip"]),
        (ik(&["--target", "left_tip=0.3,0.2"]), &["expected 3 numbers (x,y,z) or 7", "got 2"]),
        (ik(&["--target", "left_tip=0.3,0.2,0.4,1,1,0,0"]), &["left_tip", "not a unit quaternion"]),
        (ik(&["--batch", &batch]), &["--batch is for chains"]),
        (ik(&["--target", left, "--all-solutions"]), &["--all-solutions", "no closed form"]),
        (ik(&["--target", left, "--quat", "1,0,0,0"]), &["--quat is for chains"]),
        (ik(&["--target", left, "--scalar", "f32"]), &["f64 only"]),
        (ik(&["--target", left, "--solver", "newton"]), &["--solver", "damped least squares"]),
        (ik(&["--target", left, "--seed", "0,0,0"]), &["11 joints", "but 3 joint values"]),
        (ik(&["--target", left, "--seed", &format!("{ten},nan")]), &["--seed: value 11", "not a finite number"]),
        (ik(&["--target", left, "--position-tolerance", "0"]), &["tolerances must be positive"]),
        (ik(&["--target", left, "--priority", "nope"]), &["--priority", "no end effector \"nope\""]),
        (ik(&["--target", left, "--priority", "right_tip"]), &["--priority", "right_tip has no target"]),
        (ik(&["--target", left, "--priority", "left_tip"]), &["--priority", "must leave some"]),
        (vec!["fk", "--arm", URDF, "--q", "0,0,0,0,0"], &["11 joints", "--tip", "but 5 joint values"]),
        (vec!["fk", "--arm", URDF, "--q", &format!("{ten},inf")], &["--q: value 11", "not a finite number"]),
        (vec!["jacobian", "--arm", URDF, "--q", "0"], &["11 joints", "but 1 joint values"]),
        (vec!["ik", "--arm", "so101", "--target", "0.2,0,0.1", "--priority", "x"], &["--priority", "so101 is a chain"]),
        (vec!["ik", "--arm", "so101", "--target", "0.2,0,0.1", "--target", "0.1,0,0.1"], &["given 2 times", "chain"]),
    ] {
        assert_fails(&args, needles);
    }
}

/// With `--tip` the same file is the chain to that tip, as before; the drive commands and
/// `bench ik`, which drive or time one chain, still ask for a tip.
#[test]
fn a_tip_keeps_the_chain() {
    let chain = run(&["fk", "--arm", URDF, "--tip", "left_tip", "--q", "0,0,0,0,0,0"]);
    assert!(chain.get("effectors").is_none());
    assert_eq!(chain["frames"].as_array().unwrap().len(), 6);
    assert_fails(
        &["bench", "ik", "--arm", URDF, "--n", "1"],
        &["several tip links: name the tip (--tip, or tip= in Python), one of"],
    );
}
