//! A rig of two simulated SO-101 arms (the built-in bimanual-so101), each with its own firmware
//! core, on one virtual clock: `armctl --rig` status, move, play and stop, the handover demo, and
//! bad input refused in one line with nothing moved.

use std::path::Path;

use armctl::link::session::Keyframe;
use armctl::rig::{play, Rig, RigSpec};
use firmware::link::message::{JointKeyframe, RunState};
use serde_json::Value;

/// `armctl ARGS` in process: exit code, stdout, stderr.
fn armctl(args: &[&str]) -> (i32, String, String) {
    let (mut out, mut err) = (Vec::new(), Vec::new());
    let code = armctl::cli::main(std::iter::once("armctl").chain(args.iter().copied()), &mut out, &mut err);
    (code, String::from_utf8(out).unwrap(), String::from_utf8(err).unwrap())
}

fn json_of(args: &[&str]) -> Value {
    let (code, out, err) = armctl(args);
    assert_eq!(code, 0, "armctl {args:?}: {err}");
    serde_json::from_str(out.trim()).unwrap_or_else(|e| panic!("not JSON ({e}): {out}"))
}

/// An error: exit code 1 and one line on stderr that contains `expected`.
fn refused(args: &[&str], expected: &str) {
    let (code, out, err) = armctl(args);
    assert_ne!(code, 0, "armctl {args:?} succeeded: {out}");
    assert_eq!(err.lines().count(), 1, "one line: {err}");
    assert!(err.contains(expected), "{err:?} does not say {expected:?}");
}

fn distance(a: &Value, b: [f64; 3]) -> f64 {
    (0..3).map(|i| (a[i].as_f64().unwrap() - b[i]).powi(2)).sum::<f64>().sqrt()
}

#[test]
fn the_handover_demo_hands_the_object_from_one_gripper_to_the_other_with_no_violation() {
    let v = json_of(&["demo", "--rig", "bimanual-so101", "--json"]);
    eprintln!("{v}");
    let (left, right) = (&v["arms"]["left"], &v["arms"]["right"]);
    for arm in [left, right] {
        assert_eq!(arm["grasp"]["held_throughout"], true, "{arm}");
        assert_eq!(arm["safety"]["violations"], 0, "{arm}");
        assert!(arm["safety"]["goals_checked"].as_u64().unwrap() > 5000);
        // The jaws stopped on the 30 mm object: a third of the SO-101's 90 mm opening.
        assert!((arm["grasp"]["jaw_mm"].as_f64().unwrap() - 30.0).abs() < 2.0, "{arm}");
    }
    let (l_from, r_from) =
        (left["grasp"]["held_from_s"].as_f64().unwrap(), right["grasp"]["held_from_s"].as_f64().unwrap());
    let l_open = left["grasp"]["told_to_open_s"].as_f64().unwrap();
    // The giver held it first, the taker closed on it before the giver let go.
    assert!(l_from < r_from && r_from < l_open, "{l_from} {r_from} {l_open}");
    assert!(v["both_held_s"].as_f64().unwrap() > 0.5);
    assert!(v["object_to_place_mm"].as_f64().unwrap() < 5.0);
    assert_eq!(v["handed_over"], true);
    assert!(v["start_skew_s"].as_f64().unwrap() < 0.01);
}

#[test]
fn move_sends_each_arm_to_its_world_target() {
    let v = json_of(&[
        "--rig",
        "bimanual-so101",
        "move",
        "--to",
        "left=0.22,0.10,0.12",
        "--to",
        "right=0.2,-0.10,0.1",
        "--json",
    ]);
    // 20 cm apart: their jaws keep the margin (closer, the rig refuses the move: another test).
    assert!(distance(&v["arms"]["left"]["reached"], [0.22, 0.10, 0.12]) < 1e-3, "{v}");
    assert!(distance(&v["arms"]["right"]["reached"], [0.2, -0.10, 0.1]) < 1e-3, "{v}");
    // The same world point is a different point of each arm's base frame.
    let status = json_of(&["--rig", "bimanual-so101", "status", "--json"]);
    let (left, right) = (&status["arms"]["left"], &status["arms"]["right"]);
    for (arm, y) in [(left, 0.15), (right, -0.15)] {
        let (tool, world) = (&arm["tool"], &arm["tool_world"]);
        assert!((world[1].as_f64().unwrap() - tool[1].as_f64().unwrap() - y).abs() < 1e-9, "{arm}");
    }
}

/// A file with the left arm's joint columns and the right arm's Cartesian ones (world frame),
/// both clear of the table and of themselves: the left shoulder lifted 0.3 rad, the right tool
/// 25 cm out (closer in, the SO-101's elbow folds its upper arm onto its gripper).
fn two_arm_file(dir: &Path) -> std::path::PathBuf {
    let mut text = String::from(
        "# both arms, one timeline\nt,left.q1,left.q2,left.q3,left.q4,left.q5,left.gripper,right.x,right.y,right.z\n",
    );
    for k in 0..=30 {
        let t = 0.5 + 0.1 * f64::from(k);
        let lift = [0.0, -0.3, 0.0, 0.0, 0.0];
        let q: Vec<String> =
            (0..5).map(|j| format!("{:.4}", 0.3 * (t + f64::from(j) * 0.5).sin() + lift[j as usize])).collect();
        text += &format!(
            "{t:.2},{},{:.1},{:.4},{:.4},0.12\n",
            q.join(","),
            50.0 + 30.0 * t.sin(),
            0.25 + 0.03 * t.sin(),
            -0.12 + 0.03 * t.cos()
        );
    }
    let path = dir.join("two_arms.csv");
    std::fs::write(&path, text).unwrap();
    path
}

#[test]
fn a_file_with_both_arms_columns_plays_on_one_timeline() {
    let dir = tempdir();
    let file = two_arm_file(dir.path());
    let v = json_of(&["--rig", "bimanual-so101", "play", file.to_str().unwrap(), "--json"]);
    eprintln!("{v}");
    assert_eq!(v["arms"]["left"]["pushed"], 31);
    assert_eq!(v["arms"]["right"]["pushed"], 31);
    assert!(v["arms"]["left"]["end_error"].as_f64().unwrap() < 0.01, "{v}");
    assert!(v["arms"]["right"]["end_error"].as_f64().unwrap() < 0.002, "{v}");
    // Both playback clocks started on the same control tick (one virtual clock measures it).
    assert_eq!(v["skew_from"], "playback clocks (one virtual clock)");
    assert!(v["start_skew_s"].as_f64().unwrap() < 1e-6, "{v}");
    // The right arm's last keyframe, in the world frame, is where its tool ended.
    let x = 0.25 + 0.03 * 3.5f64.sin();
    let y = -0.12 + 0.03 * 3.5f64.cos();
    assert!(distance(&v["arms"]["right"]["tool_world"], [x, y, 0.12]) < 2e-3, "{v}");
}

#[test]
fn stop_stops_every_arm_in_the_middle_of_a_play() {
    let spec = RigSpec::load("bimanual-so101").unwrap();
    let mut rig = Rig::open(&spec, &mut std::io::sink()).unwrap();
    for arm in &mut rig.arms {
        arm.driver.torque_on().unwrap();
        // Ten seconds of slow joint motion, more than the queue holds.
        for k in 1..=20 {
            let t = k as f32 * 0.5;
            let positions = (0..5).map(|_| 0.4 * (t / 10.0)).collect();
            let keyframe = Keyframe::Joints(JointKeyframe { time: t, positions, velocities: None, gripper: None });
            if arm.driver.free_slots() == 0 {
                break;
            }
            arm.driver.session().push(&keyframe).unwrap();
        }
    }
    for arm in &mut rig.arms {
        arm.driver.session().start().unwrap();
    }
    // Both move for a second of the shared clock, each polled (its link watchdog hears the host).
    let t0 = rig.sim.as_ref().unwrap().now_s();
    while rig.sim.as_ref().unwrap().now_s() - t0 < 1.0 {
        for arm in &mut rig.arms {
            assert_eq!(arm.driver.status().unwrap().state, RunState::Moving);
        }
        rig.arms[0].driver.pause().unwrap();
    }
    assert_eq!(play::stop_all(&mut rig), "every arm was stopped");
    let mut held = Vec::new();
    for arm in &mut rig.arms {
        let status = arm.driver.stop().unwrap();
        assert_eq!(status.state, RunState::Idle);
        assert_eq!(status.queued, 0, "the queue is dropped");
        assert!(status.measured[0] > 0.01, "it had moved: {:?}", status.measured);
        held.push(status.measured.clone());
    }
    // Half a second later neither arm has moved on.
    let t1 = rig.sim.as_ref().unwrap().now_s();
    while rig.sim.as_ref().unwrap().now_s() - t1 < 0.5 {
        rig.arms[0].driver.pause().unwrap();
        rig.arms[1].driver.status().unwrap();
    }
    for (arm, before) in rig.arms.iter_mut().zip(held) {
        let now = arm.driver.status().unwrap().measured;
        let moved = now.iter().zip(&before).map(|(a, b)| (a - b).abs()).fold(0.0f32, f32::max);
        assert!(moved < 2e-3, "{} moved {moved} rad after the stop", arm.name);
    }
    for i in 0..2 {
        assert_eq!(rig.sim.as_ref().unwrap().board(i).monitor().violation_count, 0);
    }
}

#[test]
fn bad_rig_input_is_refused_in_one_line() {
    let dir = tempdir();
    let file = two_arm_file(dir.path());
    let text = std::fs::read_to_string(&file).unwrap();
    let write = |name: &str, text: &str| {
        let path = dir.path().join(name);
        std::fs::write(&path, text).unwrap();
        path.to_str().unwrap().to_string()
    };
    let unknown = write("unknown.csv", &text.replace("right.x", "middle.x"));
    refused(&["--rig", "bimanual-so101", "play", &unknown], "no arm \"middle\"");
    let unnamed = write("unnamed.csv", &text.replace("left.q1", "q1"));
    refused(&["--rig", "bimanual-so101", "play", &unnamed], "ARM.COLUMN");
    // The right arm's tool asked 2 m away, on line 12: found before anything is sent.
    let far: Vec<String> = text
        .lines()
        .enumerate()
        .map(|(i, l)| match l.strip_suffix(",0.12") {
            Some(rest) if i == 11 => format!("{rest},2.0"),
            _ => l.to_string(),
        })
        .collect();
    let far = write("far.csv", &far.join("\n"));
    refused(&["--rig", "bimanual-so101", "play", &far], "line 12");
    refused(
        &["--rig", "bimanual-so101", "move", "--to", "left=0.2,0.05,0.1", "--to", "right=0.6,0,0.1"],
        "no arm moved",
    );
    refused(&["--rig", "bimanual-so101", "move", "--to", "0.2,0.05,0.1"], "name the arm");
    refused(&["--rig", "bimanual-so101", "move", "--to", "left=0.2,nan,0.1"], "--to");
    refused(&["--rig", "bimanual-so101", "--sim", "status"], "--sim");
    refused(&["--rig", "bimanual-so101", "joints", "--q", "0,0,0,0,0"], "--rig drives");
    refused(&["--rig", "no-such-rig", "status"], "not a built-in rig");

    let arm = |extra: &str| format!("name = \"r\"\n[[arm]]\nname = \"a\"\narm = \"so101\"\n{extra}\n");
    let cases = [
        (arm(""), "exactly one of sim"),
        (arm("sim = true\nport = \"/dev/null\""), "exactly one of sim"),
        (arm("sim = true\nxyz = [0.0, nan, 0.0]"), "finite"),
        (arm("bus = \"/dev/null\"\nprotocol = \"can\""), "protocol \"can\""),
        (arm("sim = true\nspeed = 3"), "unknown field"),
        (format!("{}[[arm]]\nname = \"a\"\narm = \"so101\"\nsim = true\n", arm("sim = true")), "two arms are named"),
        ("name = \"r\"\n".to_string(), "missing field"),
        (arm("sim = true").replace("so101", "no-such-arm"), "no-such-arm"),
    ];
    for (text, expected) in cases {
        let error =
            format!("{:#}", RigSpec::parse(&text, Path::new(".")).err().unwrap_or_else(|| panic!("accepted: {text}")));
        assert!(!error.contains('\n') && error.contains(expected), "{error:?} does not say {expected:?}");
    }
}

/// A folder of its own, removed when dropped (also when the test fails).
fn tempdir() -> tempfile::TempDir {
    tempfile::Builder::new().prefix("armctl-rig-").tempdir().unwrap()
}

/// The example rig of two SO-101 arms on a turning torso (host/examples/rigs): one tree.
fn torso_rig() -> String {
    format!("{}/examples/rigs/torso-rig.toml", env!("CARGO_MANIFEST_DIR"))
}

/// Random reachable targets for both hands of the torso rig (FK of random joints 5 % inside every
/// limit, the torso's included), moved to as one tree: every pair reached within a millimetre,
/// and the shared torso joint used (turned) where the targets ask for it.
#[test]
fn a_shared_joint_makes_the_rig_one_tree_and_random_reachable_targets_are_reached() {
    use armctl::rig::tree::{RigTree, TreeArm};
    let spec = RigSpec::load(&torso_rig()).unwrap();
    let arms: Vec<armctl::arm::ArmSpec> =
        spec.arms.iter().map(|a| armctl::arm::ArmSpec::load(a.place.arm.as_deref().unwrap(), None).unwrap()).collect();
    let tree_arms: Vec<TreeArm<'_>> =
        arms.iter().zip(&spec.arms).map(|(arm, a)| TreeArm { arm, base: a.base, mount: a.mount }).collect();
    let tree = RigTree::new(&tree_arms).unwrap();
    let mut rng = kinematics::SplitMix64::new(30);
    let mut torso_turned = 0;
    // Each arm's own geometry: a configuration it collides in is no target a user could reach.
    let models: Vec<Box<dyn armctl::arm::dof::DynArm>> =
        arms.iter().map(|a| armctl::arm::dof::build(a.clone()).unwrap()).collect();
    let mut checkers: Vec<_> =
        models.iter().map(|m| armctl::motion::collision::Checker::of(m.as_ref()).unwrap()).collect();
    let (mut case, mut drawn, mut too_close, mut missed) = (0, 0, 0, 0);
    while case < 12 {
        drawn += 1;
        assert!(drawn < 200, "{drawn} draws for 12 free cases");
        let q: Vec<Vec<f64>> = arms
            .iter()
            .map(|arm| {
                arm.joints
                    .iter()
                    .map(|j| {
                        let margin = 0.05 * (j.upper - j.lower);
                        rng.uniform(j.lower + margin, j.upper - margin)
                    })
                    .collect()
            })
            .collect();
        if checkers.iter_mut().zip(&q).any(|(c, q)| c.as_mut().is_some_and(|c| !c.is_free(q))) {
            continue;
        }
        let tools = tree.tools(&q);
        let to = |p: [f64; 3]| format!("{:.5},{:.5},{:.5}", p[0], p[1], p[2]);
        let (left, right) = (format!("left={}", to(tools[1])), format!("right={}", to(tools[2])));
        let (code, out, err) = armctl(&["--rig", &torso_rig(), "move", "--to", &left, "--to", &right, "--json"]);
        // Two hands drawn into each other: refused whole, which another test checks; draw again.
        if code != 0 && err.contains("the arms would end too close") && err.contains("no arm moved") {
            too_close += 1;
            continue;
        }
        // A miss of the tree's solver, counted and bounded below: the drawn joints are free, but
        // every solution its 201 seeds found folds an arm into itself.
        if code != 0 && err.contains("goal is in collision") && err.contains("no arm moved") {
            eprintln!("missed: {left} {right}: {err}");
            missed += 1;
            continue;
        }
        assert_eq!(code, 0, "case {case}: {left} {right}: {err}");
        let v: Value = serde_json::from_str(out.trim()).unwrap();
        assert_eq!(v["solved_as"], "one tree");
        for name in ["left", "right"] {
            let e = v["arms"][name]["error_mm"].as_f64().unwrap();
            eprintln!("case {case}: {name} {e:.3} mm");
            assert!(e < 1.0, "case {case}: {name} {e} mm: {v}");
        }
        if v["arms"]["torso"]["joints"][0].as_f64().unwrap().abs() > 0.05 {
            torso_turned += 1;
        }
        case += 1;
    }
    eprintln!(
        "the torso turned in {torso_turned} of 12 cases ({drawn} drawn, {too_close} hands too close, {missed} free \
         targets the tree's solver missed)"
    );
    // Measured: 1 missed of 13 free targets (seed 30). A known limit (collisions.md), held to it.
    assert!(missed <= 2, "the tree's solver missed {missed} free targets");
    assert!(torso_turned >= 6, "the torso turned in {torso_turned} of 12 cases");
    // A mounted arm's tool in the world: the torso's tool frame, the mount offset, the arm.
    let status = json_of(&["--rig", &torso_rig(), "status", "--json"]);
    let world = &status["arms"]["left"]["tool_world"];
    let local = &status["arms"]["left"]["tool"];
    assert!((world[1].as_f64().unwrap() - local[1].as_f64().unwrap() - 0.15).abs() < 1e-9, "{status}");
    assert!((world[2].as_f64().unwrap() - local[2].as_f64().unwrap() - 0.1).abs() < 1e-9, "{status}");
    // Out of reach for the tree: nothing moves; orientations and Cartesian columns are refused.
    refused(&["--rig", &torso_rig(), "move", "--to", "left=0.2,0.9,0.1", "--to", "right=0.2,-0.1,0.1"], "no arm moved");
    refused(&["--rig", &torso_rig(), "move", "--to", "left=0.2,0.2,0.1", "--quat", "left=1,0,0,0"], "positions only");
    refused(&["demo", "--rig", &torso_rig()], "mounted on another arm");
    let dir = tempdir();
    let cartesian = dir.path().join("cartesian.csv");
    std::fs::write(&cartesian, "t,left.x,left.y,left.z\n1,0.2,0.2,0.2\n").unwrap();
    refused(&["--rig", &torso_rig(), "play", cartesian.to_str().unwrap()], "give it joint columns");
    // Joint columns play on the tree as on any rig: the torso turns, both arms with it.
    let joints = dir.path().join("joints.csv");
    std::fs::write(
        &joints,
        "t,torso.q1,left.q1,left.q2,left.q3,left.q4,left.q5,right.q1,right.q2,right.q3,right.q4,right.q5\n\
         1,0.5,0.2,0,0,0,0,-0.2,0,0,0,0\n2,0.3,0.1,0.1,0.1,0.1,0,-0.1,0.1,0.1,0.1,0\n",
    )
    .unwrap();
    let v = json_of(&["--rig", &torso_rig(), "play", joints.to_str().unwrap(), "--json"]);
    assert!((v["arms"]["torso"]["joints"][0].as_f64().unwrap() - 0.3).abs() < 0.01, "{v}");
}

/// Each arm is an obstacle for the other: both tools driven to the same point between the bases
/// (Cartesian columns, world frame), the play stops both arms short of each other at their last
/// keyframes before the contact, and says which two bodies, of which arms, would have come how
/// close. Where they stopped is checked from their measured joints by the test: every body of one
/// arm at least the margin from every body of the other.
#[test]
fn two_arms_driven_toward_each_other_stop_short_named() {
    use armctl::arm::collision::edit::geometry_of;
    use kinematics::collision::distance::capsule_capsule;

    let spec = RigSpec::load("bimanual-so101").unwrap();
    let mut rig = Rig::open(&spec, &mut std::io::sink()).unwrap();
    let mut text = String::from("t,left.x,left.y,left.z,right.x,right.y,right.z\n");
    // From 10 cm either side of the middle to the middle, in 2 s, 26 cm out and 15 cm up (closer
    // in and lower, the SO-101 folds its gripper onto its upper arm on the way, which its own
    // check stops first).
    for k in 0..=20 {
        let (t, y) = (0.5 + 0.1 * f64::from(k), 0.10 * (1.0 - f64::from(k) / 20.0));
        text += &format!("{t:.2},0.26,{y:.4},0.15,0.26,{:.4},0.15\n", -y);
    }
    let names: Vec<&str> = rig.arms.iter().map(|a| a.name.as_str()).collect();
    let bases: Vec<_> = rig.arms.iter().map(|a| a.base).collect();
    let parts = armctl::rig::columns::split(&text, Path::new("meet.csv"), &names, &bases, 30.0).unwrap();
    let (mut err, started) = (Vec::new(), std::time::Instant::now());
    let e = format!("{:#}", play::play(&mut rig, parts, &mut err).err().expect("the play stops short"));
    eprintln!("{e} ({:.1} s)", started.elapsed().as_secs_f64());
    assert!(!e.contains('\n'), "one line: {e}");
    assert!(e.contains("the arms would come too close"), "{e}");
    assert!(e.contains(" left/") && e.contains(" and right/") && e.contains("mm"), "names both arms' bodies: {e}");
    assert!(e.contains("every arm stopped short"), "{e}");

    // Where they are now, from their measured joints.
    let margin = rig.arms.iter().map(|a| geometry_of(a.driver.arm()).margin).fold(0.0, f64::max);
    let mut placed = Vec::new();
    let mut tools = Vec::new();
    for arm in &mut rig.arms {
        let status = arm.driver.status().unwrap();
        assert_eq!(status.state, RunState::Idle, "{} is at rest", arm.name);
        let q: Vec<f64> = status.measured.iter().map(|&x| f64::from(x)).collect();
        let frames = arm.driver.model().joint_frames(&q).unwrap();
        let bodies: Vec<_> = geometry_of(arm.driver.arm())
            .bodies
            .iter()
            .map(|b| b.capsule.placed(&arm.base.compose(&b.link.map_or(kinematics::Pose::identity(), |l| frames[l]))))
            .collect();
        placed.push(bodies);
        tools.push(arm.base.compose(&arm.driver.model().tool_pose(&q).unwrap()).translation);
    }
    let closest =
        placed[0].iter().flat_map(|a| placed[1].iter().map(move |b| capsule_capsule(a, b))).fold(f64::MAX, f64::min);
    eprintln!(
        "stopped {:.1} mm apart (margin {:.0} mm), tools {:.1} mm apart",
        closest * 1e3,
        margin * 1e3,
        (tools[0] - tools[1]).norm() * 1e3
    );
    assert!(closest >= margin, "the arms stopped {:.1} mm apart, within the margin {margin}", closest * 1e3);
    // They did move toward each other: the tools started 200 mm apart.
    assert!((tools[0] - tools[1]).norm() < 0.17, "the tools are {:.3} m apart", (tools[0] - tools[1]).norm());
    for i in 0..2 {
        assert_eq!(rig.sim.as_ref().unwrap().board(i).monitor().violation_count, 0);
    }
}

/// A file whose first keyframes, at time 0, put the arms into each other: the way there (which
/// the players take before their clocks run) is checked too, and nothing moves.
#[test]
fn a_first_keyframe_into_the_other_arm_moves_nothing() {
    let spec = RigSpec::load("bimanual-so101").unwrap();
    let mut rig = Rig::open(&spec, &mut std::io::sink()).unwrap();
    let before: Vec<Vec<f32>> = rig.arms.iter_mut().map(|a| a.driver.status().unwrap().measured.to_vec()).collect();
    // Both bases turned 0.6 rad toward the other arm, the arms stretched out: their wrists meet.
    let text = "t,left.q1,left.q2,left.q3,left.q4,left.q5,right.q1,right.q2,right.q3,right.q4,right.q5\n\
                0,0.6,0,0,0,0,-0.6,0,0,0,0\n1,0.6,0,0,0,0,-0.6,0,0,0,0\n";
    let names: Vec<&str> = rig.arms.iter().map(|a| a.name.as_str()).collect();
    let bases: Vec<_> = rig.arms.iter().map(|a| a.base).collect();
    let parts = armctl::rig::columns::split(text, Path::new("into.csv"), &names, &bases, 30.0).unwrap();
    let e = format!("{:#}", play::play(&mut rig, parts, &mut Vec::new()).err().expect("refused"));
    assert!(e.contains("0.00 s into the play") && e.contains("refused, nothing moved"), "{e}");
    assert!(e.contains("left/") && e.contains("right/"), "{e}");
    for (arm, q0) in rig.arms.iter_mut().zip(before) {
        let status = arm.driver.status().unwrap();
        assert_eq!(status.queued, 0, "nothing was queued");
        let moved = status.measured.iter().zip(&q0).map(|(a, b)| (a - b).abs()).fold(0.0f32, f32::max);
        assert!(moved < 1e-3, "{} moved {moved} rad", arm.name);
    }
}

/// Two tools sent to the same world point: the arms would end in each other, and no arm moves.
#[test]
fn a_move_that_would_end_in_the_other_arm_moves_no_arm() {
    refused(
        &["--rig", "bimanual-so101", "move", "--to", "left=0.25,0.0,0.1", "--to", "right=0.25,0.0,0.1"],
        "the arms would end too close: left/",
    );
}
