//! The HTTP side: the page's files, the JSON API and the telemetry websocket, on a few threads of
//! a small synchronous server. Every request that moves the arm becomes a job for the arm loop;
//! reading the status or drawing data never waits on the link.

use std::io::Read;
use std::sync::mpsc::{self, Sender};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::Duration;

use anyhow::{anyhow, Result};
use serde_json::Value;
use tiny_http::{Header, Method, Request as HttpRequest, Response, Server};
use tungstenite::protocol::Role;
use tungstenite::{Message, WebSocket};

use super::api::{self, ApiError, MAX_BODY};
use super::arm_loop::Job;
use super::assets;
use super::telemetry::Latest;

/// Threads answering requests (a websocket takes a thread of its own).
const WORKERS: usize = 4;
/// How long a request may wait for the arm loop's answer.
const JOB_TIMEOUT: Duration = Duration::from_secs(10);

/// What the server serves besides the page.
pub struct Served {
    /// `GET /api/arm`.
    pub arm: Value,
    /// `GET /api/mesh/K`: the files of the meshes.
    pub meshes: Vec<std::path::PathBuf>,
    /// The newest telemetry.
    pub latest: Arc<Latest>,
}

/// A running server.
pub struct ViewServer {
    server: Arc<Server>,
    url: String,
    workers: Vec<JoinHandle<()>>,
}

impl ViewServer {
    /// Listens on `addr` (`127.0.0.1:0` for a free port); answers nothing until [`Self::start`].
    pub fn bind(addr: &str) -> Result<Server> {
        Server::http(addr).map_err(|e| anyhow!("--listen {addr}: cannot listen there: {e}"))
    }

    /// Starts answering on `server`.
    pub fn start(server: Server, served: Served, jobs: Sender<Job>) -> Result<Self> {
        let server = Arc::new(server);
        let bound = server.server_addr().to_ip().ok_or_else(|| anyhow!("the server's address is not an IP address"))?;
        let url = format!("http://{bound}/");
        let served = Arc::new(served);
        let workers = (0..WORKERS)
            .map(|i| {
                let (server, served, jobs) = (server.clone(), served.clone(), jobs.clone());
                std::thread::Builder::new().name(format!("view-http-{i}")).spawn(move || {
                    for request in server.incoming_requests() {
                        answer(request, &served, &jobs);
                    }
                })
            })
            .collect::<std::io::Result<Vec<_>>>()?;
        Ok(Self { server, url, workers })
    }

    /// The page's address.
    pub fn url(&self) -> &str {
        &self.url
    }
}

impl Drop for ViewServer {
    fn drop(&mut self) {
        self.server.unblock();
        for _ in 1..self.workers.len() {
            self.server.unblock();
        }
        for w in self.workers.drain(..) {
            let _ = w.join();
        }
    }
}

fn header(name: &str, value: &str) -> Header {
    Header::from_bytes(name.as_bytes(), value.as_bytes()).expect("ASCII header")
}

fn json_response(status: u16, body: &Value) -> Response<std::io::Cursor<Vec<u8>>> {
    Response::from_data(body.to_string().into_bytes())
        .with_status_code(status)
        .with_header(header("Content-Type", "application/json"))
        .with_header(header("Cache-Control", "no-store"))
}

fn error_response(e: &ApiError) -> Response<std::io::Cursor<Vec<u8>>> {
    json_response(e.status, &e.body())
}

/// Answers one request; a failure to write the answer only means the client went away.
fn answer(mut request: HttpRequest, served: &Served, jobs: &Sender<Job>) {
    let path = request.url().split('?').next().unwrap_or("/").to_string();
    let method = request.method().clone();
    let response = match (&method, path.as_str()) {
        (Method::Get, "/api/ws") => return websocket(request, served.latest.clone()),
        (Method::Get, "/api/arm") => json_response(200, &served.arm),
        (Method::Get, "/api/status") => {
            let (seq, text) = served.latest.get();
            match seq {
                0 => error_response(&ApiError::new(503, "no status from the firmware yet")),
                _ => Response::from_data(text.as_bytes().to_vec())
                    .with_header(header("Content-Type", "application/json"))
                    .with_header(header("Cache-Control", "no-store")),
            }
        }
        (Method::Get, p) if p.starts_with("/api/mesh/") => mesh(&p["/api/mesh/".len()..], served),
        (Method::Post, p) if p.starts_with("/api/") => {
            let endpoint = p["/api/".len()..].to_string();
            match read_body(&mut request).and_then(|body| api::parse(&endpoint, &body)).and_then(|r| run_job(r, jobs)) {
                Ok(body) => json_response(200, &body),
                Err(e) => error_response(&e),
            }
        }
        (_, p) if p.starts_with("/api/") => {
            error_response(&ApiError::new(405, format!("{method} {p}: not an endpoint (see the README's API list)")))
        }
        (Method::Get, "/") => static_file("index.html"),
        (Method::Get, p) if p.starts_with("/assets/") => static_file(&p["/assets/".len()..]),
        (_, p) => error_response(&ApiError::new(404, format!("{method} {p}: not found"))),
    };
    let _ = request.respond(response);
}

fn read_body(request: &mut HttpRequest) -> Result<Vec<u8>, ApiError> {
    let mut body = Vec::new();
    request
        .as_reader()
        .take(MAX_BODY as u64 + 1)
        .read_to_end(&mut body)
        .map_err(|e| ApiError::bad(format!("cannot read the body: {e}")))?;
    Ok(body)
}

fn run_job(request: api::Request, jobs: &Sender<Job>) -> Result<Value, ApiError> {
    let (reply, answer) = mpsc::channel();
    jobs.send((request, reply)).map_err(|_| ApiError::new(503, "the arm loop has ended"))?;
    answer.recv_timeout(JOB_TIMEOUT).map_err(|_| ApiError::new(503, "the arm loop did not answer in time"))?
}

fn static_file(path: &str) -> Response<std::io::Cursor<Vec<u8>>> {
    match assets::get(path) {
        Some((bytes, kind)) => Response::from_data(bytes.to_vec()).with_header(header("Content-Type", kind)),
        None => error_response(&ApiError::new(404, format!("/assets/{path}: not found"))),
    }
}

fn mesh(index: &str, served: &Served) -> Response<std::io::Cursor<Vec<u8>>> {
    let Some(file) = index.parse::<usize>().ok().and_then(|i| served.meshes.get(i)) else {
        return error_response(&ApiError::new(404, format!("no mesh {index}")));
    };
    match std::fs::read(file) {
        Ok(bytes) => Response::from_data(bytes).with_header(header("Content-Type", "model/stl")),
        Err(e) => error_response(&ApiError::new(404, format!("mesh {}: {e}", file.display()))),
    }
}

/// Upgrades to a websocket and sends the newest telemetry as it comes, skipping what a slow
/// client could not take, until the client goes away.
fn websocket(request: HttpRequest, latest: Arc<Latest>) {
    let key = request.headers().iter().find(|h| h.field.equiv("Sec-WebSocket-Key")).map(|h| h.value.to_string());
    let Some(key) = key else {
        let _ = request.respond(error_response(&ApiError::bad("/api/ws is a websocket: connect with one")));
        return;
    };
    let response = Response::empty(101)
        .with_header(header("Upgrade", "websocket"))
        .with_header(header("Connection", "Upgrade"))
        .with_header(header("Sec-WebSocket-Accept", &tungstenite::handshake::derive_accept_key(key.as_bytes())));
    let stream = request.upgrade("websocket", response);
    let _ = std::thread::Builder::new().name("view-ws".into()).spawn(move || {
        let mut socket = WebSocket::from_raw_socket(stream, Role::Server, None);
        let mut seen = 0;
        loop {
            let message = match latest.wait_newer(seen, Duration::from_secs(1)) {
                Some((seq, text)) => {
                    seen = seq;
                    Message::text(text.as_str())
                }
                // No telemetry (the firmware is silent): a ping finds out whether the client is
                // still there.
                None => Message::Ping(Vec::new().into()),
            };
            if socket.send(message).is_err() {
                return;
            }
        }
    });
}
