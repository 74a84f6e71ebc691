//! `armctl view --rig bimanual-so101`'s JSON API, without a browser: the rig and each arm's chain,
//! the status of both arms in the world frame, a joint move and a world-frame target of each arm
//! reaching it (the other arm left where it was), a stop of one arm and the stop of every arm (also
//! under a flood of requests), an unknown arm and unnamed arm requests refused with one line, the
//! guards (token, Host, Origin, content type, size) on every arm's endpoints, the websocket
//! carrying both arms, and Ctrl-C stopping both. (The page: view_browser.rs, host/tests/view/rig.mjs.)
//!
//! The tests run one at a time (each runs two real-time simulated arms, and one measures stops).

mod support;

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use serde_json::{json, Value};
use support::view::{at_rest, distance, numbers, View};

const RIG: &str = "bimanual-so101";
const ARMS: [&str; 2] = ["left", "right"];
/// The built-in rig's bases in the world frame: both facing +x, 0.3 m apart on y.
const BASES: [[f64; 3]; 2] = [[0.0, 0.15, 0.0], [0.0, -0.15, 0.0]];

/// One test at a time.
static SERIAL: Mutex<()> = Mutex::new(());

fn serial() -> std::sync::MutexGuard<'static, ()> {
    SERIAL.lock().unwrap_or_else(|e| e.into_inner())
}

/// The SO-101's tool at joints `q`, in its base frame.
fn tool_at(q: [f64; 5]) -> [f64; 3] {
    let so101 = kinematics::presets::so101::<f64>().unwrap();
    so101.tool_pose(&kinematics::nalgebra::SVector::from(q)).translation.into()
}

fn plus(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

fn median(mut values: Vec<f64>) -> f64 {
    values.sort_by(f64::total_cmp);
    values[values.len() / 2]
}

#[test]
fn draws_and_drives_both_arms_in_the_world_frame() {
    let _one = serial();
    let view = View::start_rig(RIG);

    // The rig: two arms, each with its base and its chain.
    let (code, rig) = view.call("GET", "/api/rig", "");
    assert_eq!(code, 200, "{rig}");
    assert_eq!((rig["name"].as_str(), rig["frame"].as_str()), (Some(RIG), Some("world")));
    let arms = rig["arms"].as_array().unwrap();
    assert_eq!(arms.iter().map(|a| a["name"].as_str().unwrap()).collect::<Vec<_>>(), ARMS);
    for (a, base) in arms.iter().zip(BASES) {
        assert_eq!(numbers(&a["base"]["p"]), base);
        assert_eq!((a["arm"]["name"].as_str(), a["arm"]["dof"].as_u64()), (Some("so101"), Some(5)));
    }
    let (code, left) = view.call("GET", "/api/arm/left", "");
    assert_eq!(code, 200);
    assert_eq!(left["joints"].as_array().unwrap().len(), 5);
    assert_eq!(numbers(&left["base"]["p"]), BASES[0]);
    // Each arm's collision geometry, in its own base frame, with its base in the world for drawing.
    for (name, base) in ARMS.iter().zip(BASES) {
        let (code, geometry) = view.call("GET", &format!("/api/arm/{name}/collision"), "");
        assert_eq!(code, 200, "{geometry}");
        assert_eq!(numbers(&geometry["base"]["p"]), base);
        assert!(!geometry["bodies"].as_array().unwrap().is_empty(), "{geometry}");
        assert_eq!(geometry["obstacles"][0]["name"], "table");
    }

    // The status of both arms, each naming itself, in the world frame: at the same joints the
    // left arm's every frame is the right arm's 0.3 m along y.
    let status = view.status();
    assert_eq!(status["rig"], RIG);
    for name in ARMS {
        let t = &status["arms"][name];
        assert_eq!(t["arm"], name, "{status}");
        assert_eq!(t["frames"].as_array().unwrap().len(), 6);
        assert_eq!(numbers(&t["frames"][5]["p"]), numbers(&t["tool"]));
    }
    let (l, r) = (&status["arms"]["left"], &status["arms"]["right"]);
    assert_eq!(numbers(&l["measured"]), numbers(&r["measured"]), "both arms start at the same joints");
    for k in 0..6 {
        let shift: Vec<f64> =
            numbers(&l["frames"][k]["p"]).iter().zip(numbers(&r["frames"][k]["p"])).map(|(a, b)| a - b).collect();
        assert!(distance(&shift, &[0.0, 0.3, 0.0]) < 1e-6, "frame {k}: left - right = {shift:?}");
    }

    // A joint move of each arm reaches its joints; the other arm does not move.
    let q_left = [0.4, -0.3, 0.5, 0.2, -0.6];
    assert_eq!(view.post_arm("left", "joints", json!({"q": q_left})), (200, json!({"ok": true})));
    view.wait_arm("left", |s| at_rest(s) && distance(&numbers(&s["measured"]), &q_left) < 2e-3, "joint move", 10.0);
    let right = view.arm_status("right");
    assert!(distance(&numbers(&right["setpoints"]), &[0.0; 5]) < 1e-6, "the right arm moved: {}", right["setpoints"]);
    let q_right = [-0.3, 0.2, 0.4, -0.2, 0.5];
    assert_eq!(view.post_arm("right", "joints", json!({"q": q_right})).0, 200);
    view.wait_arm("right", |s| at_rest(s) && distance(&numbers(&s["measured"]), &q_right) < 2e-3, "joint move", 10.0);

    // A target for each arm, in the world frame: the preview draws the arm there (world frame),
    // then "go" brings its tool there. Each is a point its arm had at other joints, about 11 cm
    // above the table (within a few centimetres of it, the jaws come within the margin).
    let goals =
        [plus(BASES[0], tool_at([0.2, 0.0, 0.2, 0.4, 0.0])), plus(BASES[1], tool_at([-0.25, 0.0, 0.1, 0.5, 0.0]))];
    for (name, goal) in ARMS.iter().zip(goals) {
        let before = view.arm_status(name);
        let (code, preview) = view.post_arm(name, "target", json!({"position": goal}));
        assert_eq!(code, 200, "{name}: {preview}");
        assert!(preview["position_error_mm"].as_f64().unwrap() < 0.5, "{preview}");
        let drawn = numbers(&preview["frames"][5]["p"]);
        assert!(distance(&drawn, &goal) < 5e-4, "{name}: the preview's tool {drawn:?} is not at {goal:?}");
        std::thread::sleep(Duration::from_millis(100));
        assert_eq!(view.arm_status(name)["setpoints"], before["setpoints"], "{name}: a preview moved the arm");
        let (code, went) = view.post_arm(name, "target", json!({"position": goal, "go": true}));
        assert_eq!(code, 200, "{name}: {went}");
    }
    for (name, goal) in ARMS.iter().zip(goals) {
        let reached =
            view.wait_arm(name, |s| at_rest(s) && distance(&numbers(&s["tool"]), &goal) < 1e-3, "the target", 15.0);
        assert_eq!(numbers(&reached["target"]["position"]), goal, "the target is said in the world frame");
    }

    // Bad input on a named arm: 4xx with the reason, one line, and nothing moves.
    let setpoints = numbers(&view.arm_status("left")["setpoints"]);
    for (path, body, code, words) in [
        ("/api/arm/left/joints", r#"{"q": [0.1, 0.2]}"#, 400, "2 joint values, but the arm so101 has 5"),
        ("/api/arm/left/target", r#"{"position": [2.0, 0.15, 0.1], "go": true}"#, 422, "unreachable"),
        ("/api/arm/left/fly", "{}", 404, "no endpoint"),
        ("/api/arm/nope/joints", r#"{"q": [0, 0, 0, 0, 0]}"#, 400, "no arm \"nope\" in the rig bimanual-so101"),
        ("/api/arm/nope/stop", "{}", 400, "its arms: left, right"),
        ("/api/arm//joints", "{}", 400, "no arm \"\""),
        ("/api/joints", r#"{"q": [0, 0, 0, 0, 0]}"#, 400, "name the arm, POST /api/arm/NAME/joints"),
        ("/api/target", r#"{"position": [0.2, 0, 0.1]}"#, 400, "its arms: left, right"),
    ] {
        let (got, answer) = view.call("POST", path, body);
        let error = answer["error"].as_str().unwrap_or_else(|| panic!("{path}: no error in {answer}"));
        assert_eq!(got, code, "{path} {body}: {error}");
        assert!(error.contains(words), "{path}: {error:?} does not say {words:?}");
        assert!(!error.contains('\n'), "one line: {error:?}");
    }
    for (path, code, words) in [
        ("/api/arm/nope/status", 400, "no arm \"nope\""),
        ("/api/arm/nope", 400, "no arm \"nope\""),
        ("/api/arm", 400, "GET /api/rig for every arm"),
        ("/api/arm/left/nothing", 405, "not an endpoint"),
    ] {
        let (got, answer) = view.call("GET", path, "");
        assert_eq!(got, code, "GET {path}: {answer}");
        assert!(answer["error"].as_str().unwrap().contains(words), "GET {path}: {answer}");
    }
    std::thread::sleep(Duration::from_millis(200));
    assert_eq!(numbers(&view.arm_status("left")["setpoints"]), setpoints, "a refused request moved the arm");

    // One arm's stop stops that arm only; the rig's stop stops both.
    let far = |sign: f64| [sign * 1.5, 0.0, 0.0, 0.0, 0.0];
    for (name, sign) in ARMS.iter().zip([1.0, -1.0]) {
        assert_eq!(view.post_arm(name, "joints", json!({"q": far(sign), "speed": 0.4})).0, 200);
    }
    for name in ARMS {
        view.wait_arm(name, |s| s["state"] == "Moving", "a move", 3.0);
    }
    assert_eq!(view.post_arm("left", "stop", json!({})), (200, json!({"ok": true})));
    view.wait_arm("left", |s| s["state"] == "Idle", "the left arm's stop", 3.0);
    assert_eq!(view.arm_status("right")["state"], "Moving", "one arm's stop stopped the other");
    let (code, answer) = view.post("stop", json!({}));
    assert_eq!(code, 200, "{answer}");
    assert_eq!(answer, json!({"ok": true, "arms": {"left": {"ok": true}, "right": {"ok": true}}}));
    let stopped = view.wait_arm("right", |s| s["state"] == "Idle", "the rig's stop", 3.0);
    assert!(distance(&numbers(&stopped["setpoints"]), &far(-1.0)) > 0.2, "the move ended on its own");

    // The websocket carries both arms' telemetry, each arm's in order.
    let (mut socket, _) =
        tungstenite::connect(format!("ws://{}/api/ws?token={}", view.host, view.token)).expect("websocket");
    let started = Instant::now();
    let mut seqs: [Vec<u64>; 2] = Default::default();
    while started.elapsed() < Duration::from_secs(1) {
        if let tungstenite::Message::Text(text) = socket.read().expect("a message") {
            let t: Value = serde_json::from_str(&text).expect("JSON telemetry");
            let arm = ARMS.iter().position(|a| t["arm"] == *a).unwrap_or_else(|| panic!("no arm named: {t}"));
            seqs[arm].push(t["seq"].as_u64().unwrap());
        }
    }
    println!("websocket: {} messages of the left arm and {} of the right in one second", seqs[0].len(), seqs[1].len());
    for (name, seqs) in ARMS.iter().zip(&seqs) {
        assert!(seqs.windows(2).all(|w| w[1] > w[0]), "{name}: telemetry out of order");
        assert!(seqs.len() >= 50, "{name}: {} messages in one second", seqs.len());
    }
    drop(socket);

    let (code, stderr) = view.stop();
    assert_eq!(code, 0, "{stderr}");
    for name in ARMS {
        assert!(stderr.contains(&format!("arm {name}: stopped: the arm holds")), "{stderr}");
        assert!(stderr.contains(&format!("arm {name}: safety monitor:")), "{stderr}");
    }
    assert_eq!(stderr.matches(" 0 violations").count(), 2, "{stderr}");
}

/// Every guard of the one-arm view applies to every arm's endpoints and to the rig's own: the
/// token, the Host, the Origin, the content type, the size. Nothing moves.
#[test]
fn the_guards_apply_to_every_arm() {
    let _one = serial();
    let view = View::start_rig(RIG);
    let host = view.host.clone();
    let port = host.rsplit_once(':').unwrap().1.to_string();
    let auth = format!("Authorization: Bearer {}\r\n", view.token);
    let before: Vec<Vec<f64>> = ARMS.iter().map(|a| numbers(&view.arm_status(a)["setpoints"])).collect();
    let request = |method: &str, path: &str, headers: &str, body: &str| {
        let text = format!(
            "{method} {path} HTTP/1.1\r\n{headers}Content-Length: {}\r\nConnection: close\r\n\r\n{body}",
            body.len()
        );
        view.raw(text.as_bytes())
    };
    let json = "Content-Type: application/json\r\n";
    let cases: Vec<(String, &str, u16, &str)> = vec![
        (format!("Host: {host}\r\n{json}"), "no token", 403, "no token"),
        (
            format!("Host: {host}\r\nAuthorization: Bearer {}\r\n{json}", "0".repeat(48)),
            "a wrong token",
            403,
            "wrong token",
        ),
        (format!("Host: {host}\r\nOrigin: http://evil.example\r\n{auth}{json}"), "a foreign Origin", 403, "Origin"),
        (format!("Host: evil.example:{port}\r\n{auth}{json}"), "a rebinding Host", 403, "Host"),
        (format!("Host: {host}\r\n{auth}Content-Type: text/plain\r\n"), "text/plain", 415, "application/json"),
    ];
    let q = json!({"q": [0.6, -0.4, 0.5, 0.3, -0.5]}).to_string();
    for arm in ARMS {
        for (endpoint, body) in [
            ("joints", q.as_str()),
            ("target", r#"{"position": [0.2, 0.0, 0.1], "go": true}"#),
            ("torque", r#"{"on": false}"#),
            ("stop", "{}"),
        ] {
            for (headers, what, code, words) in &cases {
                let path = format!("/api/arm/{arm}/{endpoint}");
                let (got, answer) = request("POST", &path, headers, body);
                assert_eq!(got, *code, "{what}, POST {path}: {answer}");
                assert!(answer["error"].as_str().unwrap_or_default().contains(words), "{what}, POST {path}: {answer}");
            }
        }
    }
    for (headers, what, code, _) in &cases[..4] {
        for path in ["/api/rig", "/api/status", "/api/arm/left", "/api/arm/right/status", "/api/arm/nope/status"] {
            assert_eq!(request("GET", path, headers, "").0, *code, "{what}: GET {path}");
        }
        assert_eq!(request("POST", "/api/stop", headers, "{}").0, *code, "{what}: POST /api/stop");
    }
    // Sizes: a joint move's body is capped small, before it is read.
    let big = format!("{{\"q\": [{}0]}}", "0,".repeat(3000));
    let (code, answer) = request("POST", "/api/arm/left/joints", &format!("Host: {host}\r\n{auth}{json}"), &big);
    assert_eq!(code, 413, "{answer}");
    // A websocket without the token is refused.
    let refused = tungstenite::connect(format!("ws://{host}/api/ws"));
    assert!(matches!(refused, Err(tungstenite::Error::Http(ref r)) if r.status() == 403), "{refused:?}");
    std::thread::sleep(Duration::from_millis(200));
    for (arm, before) in ARMS.iter().zip(before) {
        let now = view.arm_status(arm);
        assert_eq!(numbers(&now["setpoints"]), before, "arm {arm} moved");
    }
    let (code, stderr) = view.stop();
    assert_eq!(code, 0, "{stderr}");
}

/// The rig's stop is queued ahead of each arm's other jobs: with both arms moving and a flood of
/// joint moves and status reads on both, it is answered within the one-arm view's figures (a
/// median under 100 ms, none over a second) and both arms stop.
#[test]
fn the_rigs_stop_gets_through_a_flood_on_both_arms() {
    let _one = serial();
    let view = Arc::new(View::start_rig(RIG));
    let flooding = Arc::new(AtomicBool::new(true));
    let sent = Arc::new(AtomicU64::new(0));
    let flood: Vec<_> = (0..8)
        .map(|i| {
            let (view, flooding, sent) = (view.clone(), flooding.clone(), sent.clone());
            std::thread::spawn(move || {
                let arm = ARMS[i % 2];
                while flooding.load(Ordering::SeqCst) {
                    let _ = match i % 4 {
                        // Previews: each takes the arm loop's time and fills its queue, and none
                        // moves the arm (its motion is the test's).
                        0 | 1 => view.post_arm(arm, "target", json!({"position": [0.2, 0.0, 0.1]})),
                        _ => view.call("GET", &format!("/api/arm/{arm}/status"), ""),
                    };
                    sent.fetch_add(1, Ordering::Relaxed);
                }
            })
        })
        .collect();
    let mut latencies = Vec::new();
    for round in 0..6 {
        let sign = if round % 2 == 0 { 1.0 } else { -1.0 };
        let q = [sign * 1.2, 0.0, 0.0, 0.0, 0.0];
        for arm in ARMS {
            assert_eq!(view.post_arm(arm, "joints", json!({"q": q, "speed": 0.5})).0, 200);
        }
        for arm in ARMS {
            view.wait_arm(arm, |s| s["state"] == "Moving", "a move", 3.0);
        }
        let asked = Instant::now();
        let (code, answer) = view.post("stop", json!({}));
        latencies.push(asked.elapsed().as_secs_f64() * 1e3);
        assert_eq!(code, 200, "{answer}");
        for arm in ARMS {
            let stopped = view.wait_arm(arm, |s| s["state"] == "Idle", "the rig's stop", 3.0);
            assert!(distance(&numbers(&stopped["setpoints"]), &q) > 0.1, "arm {arm}: the move ended on its own");
        }
    }
    flooding.store(false, Ordering::SeqCst);
    for t in flood {
        t.join().unwrap();
    }
    let (mid, max) = (median(latencies.clone()), latencies.iter().copied().fold(0.0, f64::max));
    println!(
        "the rig's stop with 8 clients flooding both arms ({} requests): median {mid:.1} ms, max {max:.1} ms",
        sent.load(Ordering::Relaxed)
    );
    assert!(mid < 100.0, "a stop took {mid:.1} ms (median of six)");
    assert!(max < 1000.0, "a stop took {max:.1} ms");
    let view = Arc::try_unwrap(view).unwrap_or_else(|_| panic!("the flood's threads hold the view"));
    let (code, stderr) = view.stop();
    assert_eq!(code, 0, "{stderr}");
}

#[test]
fn refuses_one_arm_options_and_unknown_rigs_before_opening_anything() {
    let torso = format!("{}/examples/rigs/torso-rig.toml", env!("CARGO_MANIFEST_DIR"));
    for (args, words) in [
        (&["view", "--rig", RIG, "--arm", "so101"][..], "--arm with --rig"),
        (&["view", "--rig", RIG, "--urdf", "arm.urdf"][..], "--urdf with --rig"),
        (&["view", "--rig", RIG, "--baud", "57600"][..], "--baud with --rig"),
        (&["view", "--rig", "/nonexistent/rig.toml"][..], "no such file, and not a built-in rig"),
        (&["view", "--rig", RIG, "--sim"][..], "cannot be used with"),
        (&["view", "--rig", &torso][..], "mounted on another arm (a shared joint), which view does not handle yet"),
        (&["view", "--rig", RIG, "--listen", "localhost"][..], "expected ADDR:PORT"),
    ] {
        let run = support::armctl(args);
        assert_ne!(run.code, 0, "{args:?}: {}", run.stderr);
        assert!(run.stdout.is_empty(), "{args:?} printed a URL: {}", run.stdout);
        assert!(run.stderr.contains(words), "{args:?}: {}", run.stderr);
        assert!(!run.stderr.contains("set-up:"), "{args:?} opened the servos first: {}", run.stderr);
    }
}
