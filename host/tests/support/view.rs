//! A running `armctl view --sim` (or `--rig RIG`) and plain HTTP requests to it, for the API and
//! hostile-client tests (view_api.rs, view_guard.rs, view_rig.rs).

use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use serde_json::Value;

/// A running `armctl view`, its address and token.
pub struct View {
    pub child: Child,
    /// `127.0.0.1:PORT`.
    pub host: String,
    /// The token of the printed URL.
    pub token: String,
    /// Reads stderr to its end; taken once the process has exited.
    stderr: Option<std::thread::JoinHandle<String>>,
}

impl View {
    /// Starts `armctl view --listen 127.0.0.1:0` with `extra`, reads the URL on its first line and
    /// waits for a first status.
    pub fn start(extra: &[&str]) -> Self {
        let view = Self::spawn(extra);
        view.wait_for(|s| s["seq"].as_u64().is_some(), "a first status", 5.0);
        view
    }

    /// Starts `armctl view --rig rig --listen 127.0.0.1:0` and waits for a first status of every arm.
    pub fn start_rig(rig: &str) -> Self {
        let view = Self::spawn(&["--rig", rig]);
        let started = Instant::now();
        loop {
            let (code, status) = view.call("GET", "/api/status", "");
            if code == 200 && status["arms"].as_object().is_some_and(|arms| !arms.is_empty()) {
                return view;
            }
            assert!(started.elapsed() < Duration::from_secs(10), "no status of every arm within 10 s: {status}");
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    /// Starts `armctl view --listen 127.0.0.1:0` with `extra` and reads the URL on its first line.
    fn spawn(extra: &[&str]) -> Self {
        let mut child = Command::new(env!("CARGO_BIN_EXE_armctl"))
            .args(["view", "--listen", "127.0.0.1:0"])
            .args(extra)
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("armctl view starts");
        let mut stderr = child.stderr.take().expect("stderr");
        let stderr = std::thread::spawn(move || {
            let mut text = String::new();
            let _ = stderr.read_to_string(&mut text);
            text
        });
        let mut line = String::new();
        BufReader::new(child.stdout.take().expect("stdout")).read_line(&mut line).expect("the first line");
        let (host, token) = line
            .trim()
            .strip_prefix("http://")
            .and_then(|rest| rest.split_once("/?token="))
            .unwrap_or_else(|| panic!("the first line is not the page's URL with its token: {line:?}"));
        Self { child, host: host.to_string(), token: token.to_string(), stderr: Some(stderr) }
    }

    /// Sends `request` as it is on a new connection; returns the status code and the body (JSON
    /// where it is).
    pub fn raw(&self, request: &[u8]) -> (u16, Value) {
        let mut stream = TcpStream::connect(&self.host).expect("connects");
        stream.set_read_timeout(Some(Duration::from_secs(15))).unwrap();
        stream.write_all(request).unwrap();
        let mut response = Vec::new();
        stream.read_to_end(&mut response).expect("a response");
        parse_response(&response)
    }

    /// One request as the page makes it (the token, JSON); returns the status code and the body.
    pub fn call(&self, method: &str, path: &str, body: &str) -> (u16, Value) {
        let request = format!(
            "{method} {path} HTTP/1.1\r\nHost: {}\r\nAuthorization: Bearer {}\r\nContent-Type: application/json\r\n\
             Content-Length: {}\r\nConnection: close\r\n\r\n{body}",
            self.host,
            self.token,
            body.len()
        );
        self.raw(request.as_bytes())
    }

    pub fn post(&self, endpoint: &str, body: Value) -> (u16, Value) {
        self.call("POST", &format!("/api/{endpoint}"), &body.to_string())
    }

    pub fn status(&self) -> Value {
        let (code, body) = self.call("GET", "/api/status", "");
        assert_eq!(code, 200, "{body}");
        body
    }

    /// Polls the status until `done` holds; panics after `seconds`.
    pub fn wait_for(&self, done: impl Fn(&Value) -> bool, what: &str, seconds: f64) -> Value {
        let started = Instant::now();
        loop {
            let (code, status) = self.call("GET", "/api/status", "");
            if code == 200 && done(&status) {
                return status;
            }
            assert!(started.elapsed().as_secs_f64() < seconds, "no {what} within {seconds} s; last status {status}");
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    /// A request to one arm of a rig's view: `POST /api/arm/ARM/ENDPOINT`.
    pub fn post_arm(&self, arm: &str, endpoint: &str, body: Value) -> (u16, Value) {
        self.call("POST", &format!("/api/arm/{arm}/{endpoint}"), &body.to_string())
    }

    /// The telemetry of one arm of a rig's view.
    pub fn arm_status(&self, arm: &str) -> Value {
        let (code, body) = self.call("GET", &format!("/api/arm/{arm}/status"), "");
        assert_eq!(code, 200, "{body}");
        body
    }

    /// Polls one arm's telemetry until `done` holds; panics after `seconds`.
    pub fn wait_arm(&self, arm: &str, done: impl Fn(&Value) -> bool, what: &str, seconds: f64) -> Value {
        let started = Instant::now();
        loop {
            let (code, status) = self.call("GET", &format!("/api/arm/{arm}/status"), "");
            if code == 200 && done(&status) {
                return status;
            }
            assert!(
                started.elapsed().as_secs_f64() < seconds,
                "arm {arm}: no {what} within {seconds} s; last status {status}"
            );
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    /// Sends SIGINT, as a person's Ctrl-C.
    pub fn interrupt(&self) {
        let _ = Command::new("kill").args(["-INT", &self.child.id().to_string()]).status();
    }

    /// Ctrl-C; returns the exit code and stderr.
    pub fn stop(mut self) -> (i32, String) {
        self.interrupt();
        let code = self.child.wait().expect("armctl view exits").code().unwrap_or(-1);
        (code, self.take_stderr())
    }

    fn take_stderr(&mut self) -> String {
        self.stderr.take().and_then(|reader| reader.join().ok()).unwrap_or_default()
    }

    /// Waits for the process to exit by itself (after [`Self::interrupt`]) for up to `limit`;
    /// returns the exit code (`None` if it still ran: it is killed) and stderr.
    pub fn exit_within(mut self, limit: Duration) -> (Option<i32>, String) {
        let started = Instant::now();
        let code = loop {
            if let Some(status) = self.child.try_wait().expect("waiting") {
                break Some(status.code().unwrap_or(-1));
            }
            if started.elapsed() > limit {
                let _ = self.child.kill();
                let _ = self.child.wait();
                break None;
            }
            std::thread::sleep(Duration::from_millis(5));
        };
        (code, self.take_stderr())
    }
}

impl Drop for View {
    /// A test that failed half-way leaves no server running.
    fn drop(&mut self) {
        if self.child.try_wait().ok().flatten().is_none() {
            let _ = self.child.kill();
            let _ = self.child.wait();
        }
    }
}

/// The status code and body of an HTTP response.
pub fn parse_response(response: &[u8]) -> (u16, Value) {
    let text = String::from_utf8_lossy(response).into_owned();
    let (head, body) = text.split_once("\r\n\r\n").unwrap_or_else(|| panic!("no header end in {text:?}"));
    let code = head.split(' ').nth(1).and_then(|c| c.parse().ok()).unwrap_or_else(|| panic!("status line {head:?}"));
    let value = serde_json::from_str(body).unwrap_or(Value::String(body.to_string()));
    (code, value)
}

pub fn numbers(v: &Value) -> Vec<f64> {
    v.as_array().expect("an array").iter().map(|x| x.as_f64().expect("a number")).collect()
}

pub fn distance(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y).powi(2)).sum::<f64>().sqrt()
}

/// Holding, its joints at their setpoints.
pub fn at_rest(s: &Value) -> bool {
    s["state"] == "Idle" && distance(&numbers(&s["measured"]), &numbers(&s["setpoints"])) < 2e-3
}
