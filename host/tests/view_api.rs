//! `armctl view`'s JSON API against the simulated arm, without a browser: the chain, the status,
//! joint moves, the IK preview and "go", stop, torque, playing a file, the websocket's rate, the
//! URDF meshes, and every kind of bad input refused with a 4xx and the arm left where it was.
//! (The page itself is tested in a real browser by view_browser.rs.)

mod support;

use std::time::{Duration, Instant};

use serde_json::{json, Value};
use support::view::{at_rest, distance, numbers, View};

/// A target the firmware's own IK misses from this start (pc_bus.rs has the same pair, and says
/// why the arm is the SO-101 without its collision geometry): the host's solution takes the arm
/// there by joints, and the answer says so.
#[test]
fn a_target_the_firmware_misses_goes_by_the_hosts_solution() {
    let dir = tempfile::tempdir().unwrap();
    let bare = support::so101_without_geometry(dir.path());
    let view = View::start(&["--arm", bare.to_str().unwrap()]);
    let so101 = kinematics::presets::so101::<f64>().unwrap();
    let start = [1.26971, 0.326671, 1.382003, 1.155796, -1.784273];
    assert_eq!(view.post("joints", json!({"q": start})).0, 200);
    view.wait_for(|s| at_rest(s) && distance(&numbers(&s["measured"]), &start) < 2e-3, "the start", 10.0);
    let end = kinematics::nalgebra::SVector::from([0.176832, -1.243207, -1.401943, -1.273808, 1.889245]);
    let missed: [f64; 3] = so101.tool_pose(&end).translation.into();
    let (code, went) = view.post("target", json!({"position": missed, "go": true}));
    assert_eq!(code, 200, "{went}");
    assert_eq!(went["path"], "joint", "{went}");
    assert!(went["how"].as_str().unwrap().contains("the host's"), "{went}");
    view.wait_for(|s| at_rest(s) && distance(&numbers(&s["tool"]), &missed) < 1e-3, "the missed target", 20.0);
    assert_eq!(view.stop().0, 0);
}

#[test]
fn drives_the_simulated_arm_through_the_api_and_refuses_bad_input() {
    let view = View::start(&[]);
    let (code, arm) = view.call("GET", "/api/arm", "");
    assert_eq!(code, 200);
    assert_eq!(arm["name"], "so101");
    assert_eq!(arm["dof"], 5);
    assert_eq!(arm["joints"].as_array().unwrap().len(), 5);
    assert_eq!(arm["orientation"], false);
    assert!(arm["gripper"].is_object());
    let status = view.status();
    assert_eq!(status["frames"].as_array().unwrap().len(), 6, "five joint frames and the tool's");
    assert_eq!(numbers(&status["frames"][5]["p"]), numbers(&status["tool"]));

    // Joints: the arm goes there (torque switched on).
    let q = [0.4, -0.3, 0.5, 0.2, -0.6];
    assert_eq!(view.post("joints", json!({"q": q})), (200, json!({"ok": true})));
    let there = view.wait_for(|s| at_rest(s) && distance(&numbers(&s["measured"]), &q) < 2e-3, "joint move", 10.0);
    assert_eq!(there["torque"], true);

    // Bad input: 4xx with the reason, and nothing moves.
    let setpoints = numbers(&there["setpoints"]);
    let bad: &[(&str, &str, u16, &str)] = &[
        ("joints", "{\"q\": [0.1,", 400, "bad JSON"),
        ("joints", "{\"q\": [NaN, 0, 0, 0, 0]}", 400, "bad JSON"),
        ("joints", "{\"q\": [\"0.1\", 0, 0, 0, 0]}", 400, "expected a number"),
        ("joints", "{\"q\": [0.1, 0.2]}", 400, "2 joint values, but the arm so101 has 5"),
        ("joints", "{\"q\": [3.0, 0, 0, 0, 0]}", 400, "outside its limits"),
        ("joints", "{\"q\": [0, 0, 0, 0, 0], \"speed\": -1}", 400, "speed"),
        ("target", "{\"position\": [0.2, 0.0]}", 400, "expected 3 numbers"),
        ("target", "{\"position\": [2.0, 0.0, 0.1], \"go\": true}", 422, "unreachable"),
        ("target", "{\"position\": [0.2, 0, 0.1], \"orientation\": [1, 0, 0, 0]}", 400, "too few to choose"),
        ("torque", "{\"on\": \"off\"}", 400, "expected true or false"),
        ("gripper", "{\"percent\": 140}", 400, "within 0"),
        ("play", "{\"csv\": \"t,q1,q2,q3,q4,q5\\n0,0,0,0,0,0\\n1,0,0,zero,0,0\\n\"}", 400, "line 3"),
        ("play", "{\"csv\": \"t,q1\\n0,0\\n1,0.1\\n\"}", 400, "1 joint values, but the arm so101 has 5"),
        ("fly", "{}", 404, "no endpoint"),
    ];
    for (endpoint, body, code, words) in bad {
        let (got, answer) = view.call("POST", &format!("/api/{endpoint}"), body);
        let error = answer["error"].as_str().unwrap_or_else(|| panic!("{endpoint} {body}: no error in {answer}"));
        assert_eq!(got, *code, "{endpoint} {body}: {error}");
        assert!(error.contains(words), "{endpoint} {body}: {error:?} does not say {words:?}");
        assert!(!error.contains('\n'), "one line: {error:?}");
    }
    let (got, _) = view.call("GET", "/api/nothing", "");
    assert_eq!(got, 405);
    std::thread::sleep(Duration::from_millis(200));
    let after = view.status();
    assert_eq!(numbers(&after["setpoints"]), setpoints, "a refused request moved the arm");
    assert_eq!(after["state"], "Idle");

    // The IK preview: a point the arm reaches (its tool at other joints), then "go".
    let goal = [0.25, 0.08, 0.12];
    let (code, preview) = view.post("target", json!({"position": goal}));
    assert_eq!(code, 200, "{preview}");
    assert_eq!(preview["reachable"], true);
    assert!(preview["position_error_mm"].as_f64().unwrap() < 0.5);
    let drawn = numbers(&preview["frames"][5]["p"]);
    assert!(distance(&drawn, &goal) < 5e-4, "the preview's tool {drawn:?} is not at {goal:?}");
    assert_eq!(numbers(&view.status()["setpoints"]), setpoints, "a preview moved the arm");
    let (code, went) = view.post("target", json!({"position": goal, "go": true}));
    assert_eq!(code, 200);
    assert_eq!(went["path"], "line", "{went}");
    let reached = view.wait_for(|s| at_rest(s) && distance(&numbers(&s["tool"]), &goal) < 1e-3, "the target", 10.0);
    assert_eq!(reached["target"]["reachable"], true);
    assert_eq!(reached["last_move"]["path"], "Line", "the firmware's own account of the move: {reached}");

    // A target whose straight line runs into the joint limits (the pair of pc_bus.rs): checked
    // on the host first, as `armctl move` does, it goes by joints, says so, and arrives.
    let start = [0.223, -0.966, -0.151, -1.205, 0.411];
    assert_eq!(view.post("joints", json!({"q": start})).0, 200);
    view.wait_for(|s| at_rest(s) && distance(&numbers(&s["measured"]), &start) < 2e-3, "the start", 10.0);
    let so101 = kinematics::presets::so101::<f64>().unwrap();
    let end = kinematics::nalgebra::SVector::from([1.161, -0.869, 0.026, -0.045, -0.411]);
    let far: [f64; 3] = so101.tool_pose(&end).translation.into();
    let (code, went) = view.post("target", json!({"position": far, "go": true}));
    assert_eq!(code, 200, "{went}");
    assert_eq!(went["path"], "joint", "{went}");
    let how = went["how"].as_str().unwrap();
    assert!(how.contains("the straight line is blocked") && how.contains("by joints"), "{how}");
    let arrived = view.wait_for(|s| at_rest(s) && distance(&numbers(&s["tool"]), &far) < 1e-3, "the far target", 20.0);
    assert_eq!(arrived["target"]["path"], "joint");
    assert_eq!(arrived["last_move"]["path"], "Joints", "{arrived}");

    // A file plays; stop stops it halfway.
    let rows: String =
        (0..=40).map(|i| format!("{},{:.4},0,0,0,0\n", i as f64 * 0.1, 0.8 * (i as f64 * 0.1).sin())).collect();
    let csv = format!("t,q1,q2,q3,q4,q5\n{rows}");
    let (code, planned) = view.post("play", json!({"name": "wave.csv", "csv": csv}));
    assert_eq!(code, 200, "{planned}");
    assert_eq!(planned["keyframes"], 41);
    assert_eq!(planned["path"].as_array().unwrap().len(), 41);
    let (code, busy) = view.post("joints", json!({"q": q}));
    assert_eq!(code, 409, "{busy}");
    view.wait_for(|s| s["play"]["play_time"].as_f64().unwrap_or(0.0) > 0.5, "playing", 5.0);
    assert_eq!(view.post("stop", json!({})).0, 200);
    let stopped = view.wait_for(|s| s["state"] == "Idle", "a stop", 3.0);
    assert!(
        stopped["play"]["done"] == true && stopped["play"]["play_time"].as_f64().unwrap() < 3.0,
        "{}",
        stopped["play"]
    );

    // The whole file plays to its end.
    let (code, _) = view.post("play", json!({"name": "wave.csv", "csv": csv}));
    assert_eq!(code, 200);
    // The telemetry can still carry the stopped play for a tick: this one's start first.
    view.wait_for(|s| s["play"]["done"] == false, "the file to start", 5.0);
    let played = view.wait_for(|s| s["play"]["done"] == true, "the end of the file", 15.0);
    assert!(played["play"]["error"].is_null(), "{}", played["play"]);
    assert!(played["play"]["play_time"].as_f64().unwrap() >= 3.9);

    // Torque off and on.
    assert_eq!(view.post("torque", json!({"on": false})).0, 200);
    view.wait_for(|s| s["state"] == "TorqueOff" && s["torque"] == false, "torque off", 3.0);
    assert_eq!(view.post("torque", json!({"on": true})).0, 200);
    view.wait_for(|s| s["torque"] == true, "torque on", 3.0);

    // The websocket carries telemetry at the control rate (100 Hz; at least 50 counted here,
    // where the machine is shared).
    let (mut socket, _) =
        tungstenite::connect(format!("ws://{}/api/ws?token={}", view.host, view.token)).expect("websocket");
    let started = Instant::now();
    let mut seqs = Vec::new();
    while started.elapsed() < Duration::from_secs(1) {
        if let tungstenite::Message::Text(text) = socket.read().expect("a message") {
            let t: Value = serde_json::from_str(&text).expect("JSON telemetry");
            seqs.push(t["seq"].as_u64().unwrap());
        }
    }
    assert!(seqs.windows(2).all(|w| w[1] > w[0]), "telemetry out of order");
    assert!(seqs.len() >= 50, "{} messages in one second", seqs.len());
    drop(socket);

    let (code, stderr) = view.stop();
    assert_eq!(code, 0, "{stderr}");
    assert!(stderr.contains("safety monitor:") && stderr.contains(" 0 violations"), "{stderr}");
    assert!(stderr.contains("stopped: the arm holds"), "{stderr}");
}

/// A six-joint arm takes orientation targets: the tool goes to a pose the arm had (position
/// within 1 mm, orientation within 1 degree).
#[test]
fn a_six_joint_arm_goes_to_a_pose() {
    let arm = format!("{}/examples/arms/six-dof.toml", env!("CARGO_MANIFEST_DIR"));
    let view = View::start(&["--arm", &arm]);
    let (_, spec) = view.call("GET", "/api/arm", "");
    assert_eq!((spec["dof"].as_u64(), spec["orientation"].as_bool()), (Some(6), Some(true)), "{spec}");
    let q = [0.3, -0.4, 0.6, 0.2, -0.5, 0.4];
    assert_eq!(view.post("joints", json!({"q": q})).0, 200);
    let there = view.wait_for(|s| at_rest(s) && distance(&numbers(&s["measured"]), &q) < 2e-3, "joint move", 15.0);
    let (p, o) = (numbers(&there["frames"][6]["p"]), numbers(&there["frames"][6]["q"]));
    let zero = [0.0; 6];
    assert_eq!(view.post("joints", json!({"q": zero})).0, 200);
    view.wait_for(|s| at_rest(s) && distance(&numbers(&s["measured"]), &zero) < 2e-3, "joint move", 15.0);
    let (code, answer) = view.post("target", json!({"position": p, "orientation": o, "go": true}));
    assert_eq!(code, 200, "{answer}");
    let reached = view.wait_for(|s| at_rest(s) && distance(&numbers(&s["tool"]), &p) < 1e-3, "the pose", 15.0);
    let got = numbers(&reached["frames"][6]["q"]);
    let dot = got.iter().zip(&o).map(|(a, b)| a * b).sum::<f64>().abs().min(1.0);
    let degrees = (2.0 * dot.acos()).to_degrees();
    assert!(degrees < 1.0, "the tool's orientation is {degrees:.2} degrees off");
    let (code, stderr) = view.stop();
    assert_eq!(code, 0, "{stderr}");
}

#[test]
fn draws_a_urdfs_meshes_and_says_which_are_missing() {
    use std::io::{Read, Write};
    // A five-joint URDF shaped like the SO-101 preset's joints (revolute about z), with an STL
    // for the base and one for the third link, and one mesh that is not there.
    let temp = tempfile::tempdir().unwrap();
    let dir = temp.path();
    std::fs::create_dir_all(dir.join("meshes")).unwrap();
    // A binary STL of one triangle: 80-byte header, count, normal, 3 vertices, attribute.
    let mut stl = vec![0u8; 80];
    stl.extend(1u32.to_le_bytes());
    for v in [0.0f32, 0.0, 1.0, 0.0, 0.0, 0.0, 0.01, 0.0, 0.0, 0.0, 0.01, 0.0] {
        stl.extend(v.to_le_bytes());
    }
    stl.extend([0, 0]);
    std::fs::write(dir.join("meshes/base.stl"), &stl).unwrap();
    std::fs::write(dir.join("meshes/upper.stl"), &stl).unwrap();
    let visual = |file: &str| {
        format!("<visual><origin xyz=\"0 0 0.01\"/><geometry><mesh filename=\"{file}\"/></geometry></visual>")
    };
    let mut urdf = format!("<robot name=\"five\"><link name=\"l0\">{}</link>", visual("meshes/base.stl"));
    for i in 1..=5 {
        let inside = match i {
            3 => visual("meshes/upper.stl"),
            5 => visual("meshes/gone.stl"),
            _ => String::new(),
        };
        urdf += &format!(
            "<link name=\"l{i}\">{inside}</link><joint name=\"j{i}\" type=\"revolute\"><parent link=\"l{}\"/><child link=\"l{i}\"/>\
             <origin xyz=\"0 0 0.05\"/><axis xyz=\"0 0 1\"/><limit lower=\"-1\" upper=\"1\" effort=\"1\" velocity=\"1\"/></joint>",
            i - 1
        );
    }
    urdf += "</robot>";
    let file = dir.join("five.urdf");
    std::fs::write(&file, urdf).unwrap();

    let view = View::start(&["--urdf", file.to_str().unwrap()]);
    let (code, arm) = view.call("GET", "/api/arm", "");
    assert_eq!(code, 200);
    let meshes = arm["meshes"].as_array().unwrap();
    assert_eq!(meshes.len(), 2, "{arm}");
    assert_eq!((meshes[0]["frame"].as_u64(), meshes[1]["frame"].as_u64()), (Some(0), Some(3)));
    assert_eq!(numbers(&meshes[1]["p"]), [0.0, 0.0, 0.01]);
    let mut stream = std::net::TcpStream::connect(&view.host).unwrap();
    write!(
        stream,
        "GET {} HTTP/1.1\r\nHost: {}\r\nAuthorization: Bearer {}\r\nConnection: close\r\n\r\n",
        meshes[1]["url"].as_str().unwrap(),
        view.host,
        view.token
    )
    .unwrap();
    let mut response = Vec::new();
    stream.read_to_end(&mut response).unwrap();
    assert!(response.ends_with(&stl), "the mesh's bytes are served as they are");
    let (code, stderr) = view.stop();
    assert_eq!(code, 0, "{stderr}");
    assert!(stderr.contains("warning: --urdf") && stderr.contains("gone.stl"), "{stderr}");
}

#[test]
fn refuses_bad_options_before_opening_anything() {
    // Held for the whole test, so its port is in use.
    let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let taken = listener.local_addr().unwrap().to_string();
    for (args, words) in [
        (&["view", "--listen", taken.as_str()][..], "cannot listen there"),
        (&["view", "--listen", "localhost"][..], "--listen localhost: expected ADDR:PORT"),
        (&["view", "--arm", "nonsense"][..], "unknown arm"),
        (&["view", "--object-mm", "20"][..], "--object-mm"),
        (
            &["view", "--urdf", "/nonexistent/arm.urdf", "--listen", "127.0.0.1:0"][..],
            "cannot read /nonexistent/arm.urdf",
        ),
    ] {
        let run = support::armctl(args);
        assert_eq!(run.code, 1, "{args:?}: {}", run.stderr);
        assert!(run.stdout.is_empty(), "{args:?} printed a URL: {}", run.stdout);
        assert!(run.stderr.contains(words), "{args:?}: {}", run.stderr);
        assert!(!run.stderr.contains("set-up:"), "{args:?} opened the servos first: {}", run.stderr);
    }
}

/// The collision geometry: listed for drawing (every body on a joint's frame or the base, the
/// table under the arm), obstacles added and removed for the commands that follow, bad ones
/// refused with the reason and nothing changed, and the telemetry saying that it changed.
#[test]
fn lists_the_collision_geometry_and_takes_obstacles() {
    let view = View::start(&[]);
    let (code, geometry) = view.call("GET", "/api/collision", "");
    assert_eq!(code, 200, "{geometry}");
    let bodies = geometry["bodies"].as_array().unwrap();
    assert!(!bodies.is_empty(), "{geometry}");
    for b in bodies {
        assert!(b["link"].is_null() || b["link"].as_u64().is_some_and(|l| l < 5), "{b}");
        assert!(b["radius"].as_f64().is_some_and(|r| r > 0.0), "{b}");
    }
    let names = |g: &Value| -> Vec<String> {
        g["obstacles"].as_array().unwrap().iter().map(|o| o["name"].as_str().unwrap().to_string()).collect()
    };
    assert_eq!(names(&geometry), ["table"], "a preset stands on a table");
    assert_eq!(geometry["obstacles"][0]["shape"], "table");
    assert!(geometry["base"].is_null(), "the one-arm view speaks the base frame");
    let version = view.status()["collision_version"].as_u64().unwrap();

    // The firmware takes new geometry with the arm, which it takes with the torque off only.
    assert_eq!(view.post("torque", json!({"on": false})).0, 200);
    let crate_ = json!({"shape": "box", "name": "crate", "centre": [0.2, 0.1, 0.05], "size": [0.06, 0.06, 0.1]});
    let ball = json!({"shape": "sphere", "centre": [0.15, -0.1, 0.12], "radius": 0.03});
    let (code, added) = view.post("obstacles", json!({"add": [crate_, ball]}));
    assert_eq!(code, 200, "{added}");
    assert_eq!(names(&added), ["table", "crate", "sphere"]);
    assert_eq!(added["obstacles"][1]["size"], json!([0.06, 0.06, 0.1]));
    assert!(added["sent_to_firmware"].is_boolean(), "{added}");
    assert_eq!(names(&view.call("GET", "/api/collision", "").1), ["table", "crate", "sphere"]);
    view.wait_for(|s| s["collision_version"].as_u64() == Some(version + 1), "the telemetry's collision_version", 5.0);

    // Refused, all or nothing: the obstacles stay as they were.
    let bad: &[(Value, &str)] = &[
        (
            json!({"add": [{"shape": "box", "centre": [0.2, 0, 0], "size": [0.1, -0.1, 0.1]}]}),
            "size[1]: -0.1 m is not a size",
        ),
        (json!({"add": [{"shape": "sphere", "centre": [0.2, 0], "radius": 0.1}]}), "centre: expected 3 numbers"),
        (json!({"add": [{"shape": "cone"}]}), "one of box, sphere"),
        (json!({"add": [{"shape": "table", "name": "crate"}]}), "named crate already"),
        (json!({"remove": ["crate", "shelf"]}), "no obstacle named shelf"),
        (json!({}), "nothing to do"),
    ];
    for (body, words) in bad {
        let (code, answer) = view.post("obstacles", body.clone());
        let error = answer["error"].as_str().unwrap_or_else(|| panic!("{body}: no error in {answer}"));
        assert_eq!(code, 400, "{body}: {error}");
        assert!(error.contains(words), "{body}: {error:?} does not say {words:?}");
        assert!(!error.contains('\n'), "{error:?}");
    }
    assert_eq!(names(&view.call("GET", "/api/collision", "").1), ["table", "crate", "sphere"]);

    let (code, removed) = view.post("obstacles", json!({"remove": ["crate", "table"]}));
    assert_eq!(code, 200, "{removed}");
    assert_eq!(names(&removed), ["sphere"]);
    // The arm still drives.
    let q = [0.2, -0.2, 0.3, 0.1, 0.0];
    assert_eq!(view.post("joints", json!({"q": q})).0, 200);
    view.wait_for(|s| at_rest(s) && distance(&numbers(&s["measured"]), &q) < 2e-3, "joint move", 10.0);
    let (code, stderr) = view.stop();
    assert_eq!(code, 0, "{stderr}");
}
