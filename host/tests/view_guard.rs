//! `armctl view` against hostile neighbours: another site's page in the person's browser, a
//! DNS-rebinding page, clients without the token, clients that trickle bytes or never read, a
//! flood of requests, and Ctrl-C with all of them connected. Each test drives the simulated arm
//! (`--sim`, real time) and checks that nothing moved that should not have, and that a stop got
//! through. The figures are printed (run with --nocapture) and quoted in docs/view.md ("Who can
//! reach it").
//!
//! The tests run one at a time (they measure timing and load on a shared machine).

mod support;

use std::io::{Read, Write};
use std::net::TcpStream;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::{self, JoinHandle};
use std::time::{Duration, Instant};

use serde_json::{json, Value};
use support::view::{at_rest, distance, numbers, parse_response, View};

/// One test at a time.
static SERIAL: Mutex<()> = Mutex::new(());

fn serial() -> std::sync::MutexGuard<'static, ()> {
    SERIAL.lock().unwrap_or_else(|e| e.into_inner())
}

/// A request with the given extra header lines (each ending in \r\n) and a body.
fn request(view: &View, method: &str, path: &str, headers: &str, body: &str) -> (u16, Value) {
    let text = format!(
        "{method} {path} HTTP/1.1\r\n{headers}Content-Length: {}\r\nConnection: close\r\n\r\n{body}",
        body.len()
    );
    view.raw(text.as_bytes())
}

fn median(mut values: Vec<f64>) -> f64 {
    values.sort_by(f64::total_cmp);
    values[values.len() / 2]
}

/// A keyframe file: joint 1 swings through `amplitude` rad for `seconds`.
fn wave(seconds: f64, amplitude: f64) -> String {
    let rows: String = (0..=(seconds * 10.0) as usize)
        .map(|i| {
            let t = i as f64 * 0.1;
            format!("{t:.1},{:.4},0,0,0,0\n", amplitude * (t * 1.5).sin())
        })
        .collect();
    format!("t,q1,q2,q3,q4,q5\n{rows}")
}

/// The body of every mutating endpoint, as a page of another site would send it.
fn mutating(q: &[f64]) -> Vec<(&'static str, String)> {
    vec![
        ("joints", json!({"q": q}).to_string()),
        ("target", json!({"position": [0.2, 0.1, 0.1], "go": true}).to_string()),
        ("torque", json!({"on": false}).to_string()),
        ("gripper", json!({"percent": 10}).to_string()),
        ("play", json!({"name": "evil.csv", "csv": wave(2.0, 0.8)}).to_string()),
        ("stop", "{}".to_string()),
        ("obstacles", json!({"remove": ["table"]}).to_string()),
    ]
}

/// Every way of reaching the API that is not its owner's is refused, and the arm stays where it
/// is: another site's simple POST (text/plain, its Origin), a DNS-rebinding Host with the right
/// token, no token, a wrong one, a token-less or foreign websocket.
#[test]
fn only_the_owner_drives_the_arm() {
    let _one = serial();
    let view = View::start(&[]);
    let q_far = [0.6, -0.4, 0.5, 0.3, -0.5];
    let host = view.host.clone();
    let port = host.rsplit_once(':').unwrap().1.to_string();
    let token = view.token.clone();
    // Torque on, at rest somewhere.
    let q_start = [0.2, 0.1, -0.1, 0.1, 0.2];
    assert_eq!(view.post("joints", json!({"q": q_start})).0, 200);
    let before = view.wait_for(|s| at_rest(s) && distance(&numbers(&s["measured"]), &q_start) < 2e-3, "rest", 10.0);
    let setpoints = numbers(&before["setpoints"]);

    let auth = format!("Authorization: Bearer {token}\r\n");
    let foreign = "Origin: http://evil.example\r\n";
    let cases: Vec<(String, &str, u16, &str)> = vec![
        // What a page on another site sends from the person's browser: no token, text/plain.
        (format!("Host: {host}\r\n{foreign}Content-Type: text/plain\r\n"), "another site's simple POST", 403, "Origin"),
        // The same, had it stolen the token.
        (format!("Host: {host}\r\n{foreign}{auth}Content-Type: text/plain\r\n"), "a foreign Origin with the token", 403, "Origin"),
        // A DNS-rebinding page: its own name in Host, and it is same-origin to itself.
        (
            format!("Host: evil.example:{port}\r\nOrigin: http://evil.example:{port}\r\n{auth}Content-Type: application/json\r\n"),
            "a rebinding Host with the token",
            403,
            "Host",
        ),
        (format!("Host: evil.example:{port}\r\n{auth}Content-Type: application/json\r\n"), "a foreign Host", 403, "Host"),
        (format!("Host: {host}\r\nContent-Type: application/json\r\n"), "no token", 403, "no token"),
        (
            format!("Host: {host}\r\nAuthorization: Bearer {}\r\nContent-Type: application/json\r\n", "0".repeat(48)),
            "a wrong token",
            403,
            "wrong token",
        ),
        (format!("Host: {host}\r\n{auth}Content-Type: text/plain\r\n"), "text/plain with the token", 415, "application/json"),
        (format!("Host: {host}\r\n{auth}"), "no content type", 415, "application/json"),
        (
            format!("Host: {host}\r\n{auth}Content-Type: application/x-www-form-urlencoded\r\n"),
            "a form post",
            415,
            "application/json",
        ),
        (format!("Host: {host}\r\nOrigin: null\r\n{auth}Content-Type: application/json\r\n"), "Origin null", 403, "Origin"),
    ];
    for (endpoint, body) in mutating(&q_far) {
        for (headers, what, code, words) in &cases {
            let (got, answer) = request(&view, "POST", &format!("/api/{endpoint}"), headers, &body);
            let error = answer["error"].as_str().unwrap_or_default();
            assert_eq!(got, *code, "{what}, POST /api/{endpoint}: {answer}");
            assert!(error.contains(words), "{what}, POST /api/{endpoint}: {error:?} does not say {words:?}");
        }
    }
    // The obstacles are as they were: the table was not removed.
    let (code, geometry) = view.call("GET", "/api/collision", "");
    assert_eq!((code, &geometry["obstacles"][0]["name"]), (200, &json!("table")), "{geometry}");
    // Reading is refused alike: the status tells where the arm is.
    for (headers, what) in [
        (format!("Host: {host}\r\n"), "no token"),
        (format!("Host: evil.example:{port}\r\n{auth}"), "a foreign Host"),
        (format!("Host: {host}\r\n{foreign}{auth}"), "a foreign Origin"),
    ] {
        for path in ["/api/status", "/api/arm", "/api/mesh/0", "/api/collision"] {
            assert_eq!(request(&view, "GET", path, &headers, "").0, 403, "{what}: GET {path}");
        }
    }
    // The token in the query works too (the websocket's way), and a CORS preflight gets nothing.
    assert_eq!(request(&view, "GET", &format!("/api/status?token={token}"), &format!("Host: {host}\r\n"), "").0, 200);
    let (code, _) = request(
        &view,
        "OPTIONS",
        "/api/joints",
        &format!("Host: {host}\r\n{foreign}Access-Control-Request-Method: POST\r\n"),
        "",
    );
    assert_eq!(code, 403);
    let mut preflight = TcpStream::connect(&host).unwrap();
    write!(preflight, "OPTIONS /api/joints HTTP/1.1\r\nHost: {host}\r\n{auth}Connection: close\r\n\r\n").unwrap();
    let mut answer = String::new();
    preflight.read_to_string(&mut answer).unwrap();
    assert!(answer.starts_with("HTTP/1.1 405"), "{answer}");
    assert!(!answer.to_ascii_lowercase().contains("access-control-"), "a CORS header: {answer}");

    // Websockets: without the token, with a wrong one, from another site, by a rebinding name.
    let ws = |url: String, origin: Option<&str>, host_header: Option<String>| {
        let mut request = tungstenite::client::IntoClientRequest::into_client_request(url).unwrap();
        if let Some(o) = origin {
            request.headers_mut().insert("Origin", o.parse().unwrap());
        }
        if let Some(h) = host_header {
            request.headers_mut().insert("Host", h.parse().unwrap());
        }
        match tungstenite::connect(request) {
            Ok(_) => 101,
            Err(tungstenite::Error::Http(response)) => response.status().as_u16(),
            Err(e) => panic!("websocket: {e}"),
        }
    };
    assert_eq!(ws(format!("ws://{host}/api/ws"), None, None), 403, "no token");
    assert_eq!(ws(format!("ws://{host}/api/ws?token={}", "1".repeat(48)), None, None), 403, "a wrong token");
    assert_eq!(
        ws(format!("ws://{host}/api/ws?token={token}"), Some("http://evil.example"), None),
        403,
        "foreign Origin"
    );
    assert_eq!(ws(format!("ws://{host}/api/ws?token={token}"), None, Some(format!("evil.example:{port}"))), 403);
    assert_eq!(
        ws(format!("ws://{host}/api/ws?token={token}"), Some(format!("http://{host}").as_str()), None),
        101,
        "the page's own"
    );

    // Nothing moved: the same setpoints, still holding, torque on, the gripper where it was.
    thread::sleep(Duration::from_millis(300));
    let after = view.status();
    assert_eq!(numbers(&after["setpoints"]), setpoints, "a refused request moved the arm");
    assert_eq!((after["state"].as_str(), after["torque"].as_bool()), (Some("Idle"), Some(true)), "{after}");
    assert_eq!(after["gripper"]["setpoint_percent"], before["gripper"]["setpoint_percent"]);
    assert!(after["play"].is_null(), "a refused file plays: {}", after["play"]);

    // The owner's request still works.
    assert_eq!(view.post("joints", json!({"q": q_far})).0, 200);
    view.wait_for(|s| at_rest(s) && distance(&numbers(&s["measured"]), &q_far) < 2e-3, "the owner's move", 10.0);
    let (code, stderr) = view.stop();
    assert_eq!(code, 0, "{stderr}");
}

/// A client that sends `at_once`, then the rest of its request a byte every 250 ms, never
/// finishing; records how the server ended it (the status it answered, or 0 for closed without
/// one) and after how long.
fn trickler(host: String, at_once: String, trickled: String, ends: Arc<Mutex<Vec<(u16, f64)>>>) -> JoinHandle<()> {
    thread::spawn(move || {
        let Ok(mut stream) = TcpStream::connect(&host) else { return };
        let started = Instant::now();
        let _ = stream.set_read_timeout(Some(Duration::from_millis(250)));
        let mut response = Vec::new();
        if stream.write_all(at_once.as_bytes()).is_err() {
            return;
        }
        for byte in trickled.bytes().chain(std::iter::repeat(b'x')) {
            if stream.write_all(&[byte]).is_err() {
                break;
            }
            let mut buf = [0u8; 512];
            match stream.read(&mut buf) {
                Ok(0) => break,
                Ok(n) => response.extend_from_slice(&buf[..n]),
                Err(_) => {}
            }
            if started.elapsed() > Duration::from_secs(30) {
                break;
            }
        }
        let _ = stream.set_read_timeout(Some(Duration::from_secs(1)));
        let _ = stream.read_to_end(&mut response);
        let code = if response.is_empty() { 0 } else { parse_response(&response).0 };
        ends.lock().unwrap().push((code, started.elapsed().as_secs_f64()));
    })
}

/// 64 clients trickle their heads and bodies a byte every 250 ms, and 100 websockets are opened
/// and never read: a stop from the owner is still answered at once and the arm stops; the
/// websockets past the cap are refused; every slow client is cut off by the server's deadlines.
#[test]
fn a_stop_gets_through_slow_clients_and_idle_websockets() {
    let _one = serial();
    let view = View::start(&[]);
    let host = view.host.clone();
    let token = view.token.clone();
    let ends = Arc::new(Mutex::new(Vec::new()));
    let mut slow = Vec::new();
    for i in 0..64 {
        let (at_once, trickled) = match i % 2 {
            // Heads that never end: no token is needed to hold a connection this way.
            0 => (String::new(), format!("POST /api/play HTTP/1.1\r\nHost: {host}\r\nX-Slow-{i}: ")),
            // With the token, a large body announced and trickled.
            _ => (
                format!(
                    "POST /api/play HTTP/1.1\r\nHost: {host}\r\nAuthorization: Bearer {token}\r\n\
                     Content-Type: application/json\r\nContent-Length: 4000000\r\n\r\n"
                ),
                "{\"csv\": \"".to_string(),
            ),
        };
        slow.push(trickler(host.clone(), at_once, trickled, ends.clone()));
    }
    // Websockets that never read a message.
    let mut sockets = Vec::new();
    let mut refused = 0;
    for _ in 0..100 {
        match tungstenite::connect(format!("ws://{host}/api/ws?token={token}")) {
            Ok((socket, _)) => sockets.push(socket),
            Err(tungstenite::Error::Http(r)) if r.status() == 503 => refused += 1,
            Err(e) => panic!("websocket: {e}"),
        }
    }
    println!("websockets: {} open, {refused} refused (503)", sockets.len());
    assert_eq!((sockets.len(), refused), (16, 84), "the websocket cap");

    // The arm moves slowly; the owner stops it, ten times over, with all of the above connected
    // (the stops made after a slow client was let go, at the 5 s head deadline, do not count).
    let mut latencies = Vec::new();
    for round in 0..10 {
        let q = if round % 2 == 0 { [1.2, 0.0, 0.0, 0.0, 0.0] } else { [-1.2, 0.0, 0.0, 0.0, 0.0] };
        assert_eq!(view.post("joints", json!({"q": q, "speed": 0.5})).0, 200);
        view.wait_for(|s| s["state"] == "Moving", "a move", 3.0);
        let asked = Instant::now();
        let (code, answer) = view.post("stop", json!({}));
        let took = asked.elapsed().as_secs_f64() * 1e3;
        if ends.lock().unwrap().is_empty() {
            latencies.push(took);
        }
        assert_eq!(code, 200, "{answer}");
        let stopped = view.wait_for(|s| s["state"] == "Idle", "the stop", 3.0);
        assert!(distance(&numbers(&stopped["setpoints"]), &q) > 0.1, "the move ended on its own");
    }
    assert!(latencies.len() >= 5, "only {} stops were made while all 64 slow clients were held", latencies.len());
    let (mid, max) = (median(latencies.clone()), latencies.iter().copied().fold(0.0, f64::max));
    println!(
        "stop with 64 slow clients and {} idle websockets: median {mid:.1} ms, max {max:.1} ms ({} stops)",
        sockets.len(),
        latencies.len()
    );
    // The goal is 100 ms; the median is asserted, the worst case only against the old failure (no
    // answer within 10 s), since this machine is shared.
    assert!(mid < 100.0, "a stop took {mid:.1} ms (median of ten)");
    assert!(max < 1000.0, "a stop took {max:.1} ms");

    // The server's deadlines end every slow client: a head within 5 s, a body within 10 s.
    for t in slow {
        t.join().unwrap();
    }
    let ends = ends.lock().unwrap();
    assert_eq!(ends.len(), 64);
    for (code, seconds) in ends.iter() {
        assert!(
            matches!(code, 408) && *seconds < 12.0,
            "a slow client ended with {code} after {seconds:.1} s; expected 408 within the deadlines"
        );
    }
    drop(sockets);
    let (code, stderr) = view.stop();
    assert_eq!(code, 0, "{stderr}");
    assert!(stderr.contains(" 0 violations"), "{stderr}");
}

/// The limits on what one request may be: refused with its status, before any body is read.
#[test]
fn oversized_requests_are_refused() {
    let _one = serial();
    let view = View::start(&[]);
    let host = view.host.clone();
    let auth = format!("Host: {host}\r\nAuthorization: Bearer {}\r\nContent-Type: application/json\r\n", view.token);
    let long = format!("{auth}X-Long: {}\r\n", "a".repeat(17 << 10));
    assert_eq!(request(&view, "GET", "/api/status", &long, "").0, 431, "a 17 KiB head");
    let many: String = (0..40).map(|i| format!("X-{i}: 1\r\n")).collect();
    assert_eq!(request(&view, "GET", "/api/status", &format!("{auth}{many}"), "").0, 431, "40 header lines");
    // A small endpoint's cap: 4 KiB, refused from Content-Length alone.
    let mut stream = TcpStream::connect(&host).unwrap();
    write!(stream, "POST /api/joints HTTP/1.1\r\n{auth}Content-Length: 5000\r\n\r\n").unwrap();
    stream.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
    let mut response = Vec::new();
    let _ = stream.read_to_end(&mut response);
    let (code, body) = parse_response(&response);
    assert_eq!(code, 413, "{body}");
    // play's: 4 MiB.
    let (code, body) = request(&view, "POST", "/api/play", &format!("{auth}X-Pad: 1\r\n"), "");
    assert_eq!(code, 400, "an empty body is bad JSON, not too large: {body}");
    let huge = format!("POST /api/play HTTP/1.1\r\n{auth}Content-Length: {}\r\n\r\n", 5 << 20);
    let (code, _) = view.raw(huge.as_bytes());
    assert_eq!(code, 413);
    // A chunked body, two Hosts, garbage.
    let chunked = format!("POST /api/stop HTTP/1.1\r\n{auth}Transfer-Encoding: chunked\r\n\r\n2\r\n{{}}\r\n0\r\n\r\n");
    assert_eq!(view.raw(chunked.as_bytes()).0, 411);
    let twice = format!("GET /api/status HTTP/1.1\r\n{auth}Host: evil.example:80\r\n\r\n");
    assert_eq!(view.raw(twice.as_bytes()).0, 400);
    assert_eq!(view.raw(b"\x16\x03\x01\x02\x00\x01\x00\x01\xfc\x03\x03\r\n\r\n").0, 400);
    let (code, stderr) = view.stop();
    assert_eq!(code, 0, "{stderr}");
}

/// Past the connection cap (128) a new connection is answered 503 at once, and the slots come
/// back when the slow clients' heads time out.
#[test]
fn the_connection_cap_refuses_at_once_and_recovers() {
    let _one = serial();
    let view = View::start(&[]);
    let host = view.host.clone();
    let held: Vec<TcpStream> = (0..128)
        .map(|_| {
            let mut s = TcpStream::connect(&host).unwrap();
            s.write_all(b"GET /api/status HTTP/1.1\r\n").unwrap();
            s
        })
        .collect();
    // Until the server has taken them all.
    thread::sleep(Duration::from_millis(500));
    let asked = Instant::now();
    let (code, body) = view.call("GET", "/api/status", "");
    assert_eq!(code, 503, "{body}");
    assert!(body["error"].as_str().unwrap().contains("connections are open"), "{body}");
    assert!(asked.elapsed() < Duration::from_secs(2), "refused at once");
    // The head deadline (5 s) frees them.
    view.wait_for(|_| true, "a free slot", 8.0);
    drop(held);
    let (code, stderr) = view.stop();
    assert_eq!(code, 0, "{stderr}");
}

/// The view process's threads seen, by id, while `run` runs (sampled every 10 ms from /proc).
fn threads_seen<T>(pid: u32, run: impl FnOnce() -> T) -> (T, usize) {
    let done = Arc::new(AtomicBool::new(false));
    let sampler = {
        let done = done.clone();
        thread::spawn(move || {
            let mut seen = std::collections::BTreeSet::new();
            while !done.load(Ordering::SeqCst) {
                if let Ok(tasks) = std::fs::read_dir(format!("/proc/{pid}/task")) {
                    seen.extend(tasks.filter_map(|t| t.ok()).map(|t| t.file_name()));
                }
                thread::sleep(Duration::from_millis(10));
            }
            seen.len()
        })
    };
    let out = run();
    done.store(true, Ordering::SeqCst);
    (out, sampler.join().unwrap())
}

/// Counts of the firmware loop and the safety monitor over `seconds` of a playing file, with
/// `flood` threads requesting the status as fast as they can; returns the loop's overruns and the
/// requests answered.
fn overruns_while_playing(view: &View, seconds: f64, flood: usize) -> (u64, u64) {
    let csv = wave(seconds + 1.0, 0.8);
    let (code, body) = view.post("play", json!({"name": "wave.csv", "csv": csv}));
    assert_eq!(code, 200, "{body}");
    let first = view.wait_for(|s| s["play"]["play_time"].as_f64().unwrap_or(0.0) > 0.2, "playing", 5.0);
    let done = Arc::new(AtomicBool::new(false));
    let answered = Arc::new(AtomicU64::new(0));
    let threads: Vec<_> = (0..flood)
        .map(|_| {
            let (done, answered) = (done.clone(), answered.clone());
            let request = format!(
                "GET /api/status HTTP/1.1\r\nHost: {}\r\nAuthorization: Bearer {}\r\nConnection: close\r\n\r\n",
                view.host, view.token
            );
            let host = view.host.clone();
            thread::spawn(move || {
                while !done.load(Ordering::SeqCst) {
                    let Ok(mut s) = TcpStream::connect(&host) else { continue };
                    let mut response = Vec::new();
                    if s.write_all(request.as_bytes()).is_ok()
                        && s.read_to_end(&mut response).is_ok()
                        && response.starts_with(b"HTTP/1.1 200")
                    {
                        answered.fetch_add(1, Ordering::Relaxed);
                    }
                }
            })
        })
        .collect();
    thread::sleep(Duration::from_secs_f64(seconds));
    done.store(true, Ordering::SeqCst);
    for t in threads {
        t.join().unwrap();
    }
    let last = view.status();
    assert!(last["play"]["error"].is_null(), "{}", last["play"]);
    let overruns = last["loop"]["overruns"].as_u64().unwrap() - first["loop"]["overruns"].as_u64().unwrap();
    view.wait_for(|s| s["play"]["done"] == true, "the end of the file", 10.0);
    (overruns, answered.load(Ordering::SeqCst))
}

/// A flood of status requests for 10 s while a file plays: the safety monitor's violations stay
/// 0, and the server answers it on the threads it keeps (a thread started per request is what made
/// the flood disturb the control loop: 75 to 112 overruns in 10 s). The loop's overruns are
/// printed, not judged: they are late ticks of a real-time loop on a shared machine (0 to 7 with
/// the flood on one machine, 35 to 66 on a slower one, the code of before that day included).
#[test]
fn a_flood_of_requests_does_not_disturb_the_control_loop() {
    let _one = serial();
    let view = View::start(&[]);
    let pid = view.child.id();
    let ((quiet, _), threads_quiet) = threads_seen(pid, || overruns_while_playing(&view, 10.0, 0));
    let ((flooded, answered), threads_flooded) = threads_seen(pid, || overruns_while_playing(&view, 10.0, 4));
    println!(
        "flood: {answered} status requests answered in 10 s ({:.0}/s); firmware loop overruns {quiet} without, {flooded} \
         with; the view's threads seen {threads_quiet} without, {threads_flooded} with",
        answered as f64 / 10.0
    );
    // A thread per request would show thousands of thread ids; the kept ones are a few dozen.
    assert!(threads_flooded <= threads_quiet + 64, "{threads_flooded} threads with the flood, {threads_quiet} without");
    assert!(answered > 1000, "the flood was no flood: {answered} requests");
    let (code, stderr) = view.stop();
    assert_eq!(code, 0, "{stderr}");
    let monitor = stderr.lines().find(|l| l.starts_with("safety monitor:")).unwrap_or_default().to_string();
    println!("{monitor}");
    assert!(monitor.contains(" 0 violations"), "{stderr}");
}

/// Ctrl-C while slow clients hold connections and a file plays: the arm is at rest and the
/// process has exited within 2 s. SIGTERM counts as Ctrl-C, and a second signal switches the
/// torque off.
#[test]
fn ctrl_c_stops_the_arm_first_then_exits_whatever_is_connected() {
    let _one = serial();
    let view = View::start(&[]);
    let host = view.host.clone();
    let (code, body) = view.post("play", json!({"name": "wave.csv", "csv": wave(10.0, 1.0)}));
    assert_eq!(code, 200, "{body}");
    view.wait_for(|s| s["play"]["play_time"].as_f64().unwrap_or(0.0) > 1.0, "playing", 5.0);
    let ends = Arc::new(Mutex::new(Vec::new()));
    let slow: Vec<_> = (0..16)
        .map(|i| trickler(host.clone(), String::new(), format!("GET /api/status HTTP/1.1\r\nX-{i}: "), ends.clone()))
        .collect();
    // A page's websocket, keeping the last telemetry it got.
    let last = Arc::new(Mutex::new(Value::Null));
    let (mut socket, _) = tungstenite::connect(format!("ws://{host}/api/ws?token={}", view.token)).unwrap();
    let reader = {
        let last = last.clone();
        thread::spawn(move || {
            while let Ok(message) = socket.read() {
                if let tungstenite::Message::Text(text) = message {
                    *last.lock().unwrap() = serde_json::from_str(&text).unwrap();
                }
            }
        })
    };
    thread::sleep(Duration::from_millis(300));
    assert_eq!(last.lock().unwrap()["state"], "Moving");
    let asked = Instant::now();
    view.interrupt();
    let (code, stderr) = view.exit_within(Duration::from_secs(10));
    let took = asked.elapsed().as_secs_f64();
    println!("Ctrl-C with 16 slow clients, a websocket and a file playing: exited in {took:.2} s");
    assert_eq!(code, Some(0), "{stderr}");
    assert!(took < 2.0, "exited {took:.2} s after Ctrl-C");
    reader.join().unwrap();
    let last = last.lock().unwrap().clone();
    assert!(at_rest(&last), "the last telemetry is not at rest: {last}");
    assert!(stderr.contains("stopped: the arm holds"), "{stderr}");
    assert!(stderr.contains(" 0 violations"), "{stderr}");
    for t in slow {
        t.join().unwrap();
    }

    // SIGTERM, then Ctrl-C while the arm brakes: torque off, exit 130.
    let view = View::start(&[]);
    let (code, body) = view.post("play", json!({"name": "wave.csv", "csv": wave(10.0, 1.0)}));
    assert_eq!(code, 200, "{body}");
    view.wait_for(|s| s["play"]["play_time"].as_f64().unwrap_or(0.0) > 1.0, "playing", 5.0);
    // The second 5 ms after the first, while the arm brakes.
    let pid = view.child.id().to_string();
    let _ = std::process::Command::new("sh").args(["-c", "kill -TERM $0; sleep 0.005; kill -INT $0", &pid]).status();
    let (code, stderr) = view.exit_within(Duration::from_secs(10));
    assert_eq!(code, Some(130), "{stderr}");
    assert!(stderr.contains("second signal: torque off"), "{stderr}");
}
