//! `armctl view`: the arm live in a browser. One more link client of the firmware, with a web page
//! in front of it: the arm in 3D from its chain, one slider per joint, a target to drag (IK
//! preview on this PC, the move on the firmware), telemetry, keyframe files, stop and torque.
//! Every button of the page is a request of a small JSON API that scripts can make too.
//!
//! - [`access`]: who may drive it (the token, `Host`, `Origin`, the content type);
//! - [`api`]: the requests, checked before anything moves;
//! - [`jobs`]: the requests waiting for the arm loop, a stop first;
//! - [`arm_loop`]: the one thread that talks to the firmware;
//! - [`preview`]: the IK preview;
//! - [`telemetry`]: the status as the page draws it;
//! - [`http`]: one HTTP/1.1 connection, with a bound on everything a client could hold;
//! - [`server`]: the connections, the API's routes and the websocket;
//! - [`workers`]: the threads that serve connections;
//! - [`assets`]: the page's files, embedded in the binary;
//! - [`meshes`]: a URDF's visual meshes over the chain;
//! - [`rig`]: `armctl view --rig RIG`, every arm of a rig in one page, each with its own arm loop.
//!
//! `--sim` (the default) runs the firmware core on this PC in real time against simulated servos
//! on a pseudo-terminal, as `armctl serve --sim` does: the page shows motion as it happens, which
//! the virtual clock of the drive commands' `--sim` would not.

pub mod access;
pub mod api;
pub mod arm_loop;
pub mod assets;
pub mod http;
pub mod jobs;
pub mod meshes;
pub mod preview;
pub mod rig;
pub mod server;
pub mod telemetry;
pub mod workers;

use std::io::Write;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Duration;

use access::Token;
use anyhow::{bail, Context, Result};

use crate::arm::servos::servos_of;
use crate::runtime::connection::Place;
use crate::support::interrupt;
use arm_loop::ArmLoop;
use server::{Served, ServedArm, ViewServer};
use telemetry::Latest;

/// Where the page is served unless `--listen` says otherwise: this machine only.
pub const DEFAULT_LISTEN: &str = "127.0.0.1:8765";

/// What `armctl view` is asked for, as typed: the view checks it (`listen` an address, `token`
/// long enough, the URDF's joints the arm's) before anything is opened.
#[derive(Clone, Debug)]
pub struct ViewRequest {
    /// The address and port to serve the page on, `ADDR:PORT`.
    pub listen: String,
    /// The API's token; `None` draws a random one for this run.
    pub token: Option<String>,
    /// A URDF whose visual meshes are drawn over the chain (one arm only).
    pub urdf: Option<PathBuf>,
    /// The link the URDF's chain ends at, where it has several leaves.
    pub tip: Option<String>,
}

/// The first line of stdout: the page's URL, or with `--json` {"url": URL}.
fn print_url(url: &str, json: bool, out: &mut dyn Write) -> Result<()> {
    // Not through `cli::print_json`: the command line is the layer above this one.
    if json {
        Ok(writeln!(out, "{}", serde_json::json!({ "url": url }))?)
    } else {
        Ok(writeln!(out, "{url}")?)
    }
}

/// Runs `armctl view` of the one arm at `place` until Ctrl-C; `json`: the URL as {"url": URL}.
/// Returns the exit code.
pub fn run(place: &Place, json: bool, request: &ViewRequest, out: &mut dyn Write, err: &mut dyn Write) -> Result<i32> {
    let mut place = place.clone();
    // --sim is the default (see the module doc).
    if place.port.is_none() && place.bus.is_none() {
        place.sim = true;
    }
    let (listen, token) = listen_and_token(request)?;
    let urdf = request.urdf.as_deref().map(|file| meshes::Urdf::read(file, request.tip.as_deref())).transpose()?;
    let (target, arm) = place.target_and_arm()?;
    let arm = arm.map(str::to_string);
    warn_if_open(listen, err)?;
    // The address is taken before connecting, so a port in use changes nothing on the arm.
    let listener = ViewServer::bind(listen)?;
    // --sim runs in real time here (see the module doc).
    let (target, simulated) = target.in_real_time()?;
    let latest = Arc::new(Latest::default());
    let (arm_loop, spec, queue_capacity) = ArmLoop::spawn(target, arm, latest.clone(), err)?;
    let (meshes, missing) = match urdf {
        Some(urdf) => urdf.over(&spec)?,
        None => (Vec::new(), Vec::new()),
    };
    for line in &missing {
        writeln!(err, "warning: {line}")?;
    }
    let arm_json = meshes::arm_json(&spec, queue_capacity, &meshes)?;
    let served = Served {
        arms: vec![ServedArm { name: spec.name.clone(), arm: arm_json, jobs: arm_loop.jobs() }],
        rig: None,
        meshes: meshes.iter().map(|m| m.file.clone()).collect(),
        latest,
    };
    let mut server = ViewServer::start(listener, served, token)?;
    print_url(server.url(), json, out)?;
    out.flush()?;
    writeln!(
        err,
        "arm {} ({}): open {} in a browser (the token in it is what lets a page drive the arm: keep it to \
         yourself); Ctrl-C stops the arm and exits",
        spec.name,
        joints_and_gripper(&spec),
        server.url()
    )?;
    err.flush()?;
    supervise(vec![Running { name: None, arm_loop, simulated }], &mut server, err)
}

/// `--listen` and `--token`, checked.
fn listen_and_token(request: &ViewRequest) -> Result<(SocketAddr, Token)> {
    let listen: SocketAddr = request
        .listen
        .parse()
        .with_context(|| format!("--listen {}: expected ADDR:PORT, e.g. 127.0.0.1:8765", request.listen))?;
    let token = match &request.token {
        Some(text) => Token::given(text)?,
        None => Token::generate()?,
    };
    Ok((listen, token))
}

/// Warns on `err` when `listen` is not this machine's loopback.
fn warn_if_open(listen: SocketAddr, err: &mut dyn Write) -> Result<()> {
    if !listen.ip().is_loopback() {
        writeln!(
            err,
            "warning: --listen {listen} is not this machine's loopback: anyone who has the URL can move the arm, and \
             plain HTTP shows its token to the network; to reach the view from another machine, keep the default and \
             use an SSH tunnel (ssh -L 8765:127.0.0.1:8765 this-machine)"
        )?;
        err.flush()?;
    }
    Ok(())
}

/// "5 joints and a gripper".
fn joints_and_gripper(spec: &crate::arm::ArmSpec) -> String {
    let gripper = servos_of(spec).and_then(|s| s.gripper).is_some();
    format!("{} joints{}", spec.dof(), if gripper { " and a gripper" } else { "" })
}

/// An arm loop, its name in a rig, and the simulated servos it drives (for `--sim` arms).
struct Running {
    name: Option<String>,
    arm_loop: ArmLoop,
    simulated: Option<crate::sim::PtyServer>,
}

impl Running {
    /// What to put before a line about this arm: nothing in the one-arm view.
    fn prefix(&self) -> String {
        self.name.as_ref().map(|n| format!("arm {n}: ")).unwrap_or_default()
    }
}

/// Serves until Ctrl-C or until an arm's link ends; then stops every arm (each decelerates within
/// its limits and holds; a second Ctrl-C switches the torque off), closes the server, and says
/// what each arm did. Returns the exit code.
fn supervise(running: Vec<Running>, server: &mut ViewServer, err: &mut dyn Write) -> Result<i32> {
    interrupt::catch();
    while !interrupt::requested() {
        std::thread::sleep(Duration::from_millis(20));
        if running.iter().any(|r| r.arm_loop.is_finished()) {
            break;
        }
        if let Some(r) = running.iter().find(|r| r.simulated.as_ref().is_some_and(crate::sim::PtyServer::is_finished)) {
            bail!("{}the simulated servos stopped", r.prefix());
        }
    }
    let interrupted = interrupt::requested();
    if interrupted {
        // The arms first: stopped and holding (or limp, on a second signal) before the server
        // closes, whatever its clients do; the server's threads never hold an arm loop.
        let which = if running.len() == 1 { "the arm decelerates" } else { "every arm decelerates" };
        writeln!(err, "stopping: {which} within its limits, then holds (Ctrl-C again: torque off)")?;
        err.flush()?;
        for r in &running {
            r.arm_loop.begin_stop();
        }
        while !running.iter().all(|r| r.arm_loop.is_finished()) {
            if interrupt::count() >= 2 {
                for r in &running {
                    r.arm_loop.torque_off();
                }
            }
            std::thread::sleep(Duration::from_millis(2));
        }
    }
    server.shutdown();
    let mut failed = None;
    let mut ended = None;
    for r in running {
        let prefix = r.prefix();
        let finished = r.arm_loop.is_finished();
        let said = match r.arm_loop.finish() {
            Ok(said) => said,
            Err(e) => {
                failed.get_or_insert(e.context(format!("{prefix}the arm loop")));
                continue;
            }
        };
        for line in said.lines() {
            writeln!(err, "{prefix}{line}")?;
        }
        if let Some(report) = r.simulated.as_ref().and_then(crate::sim::PtyServer::monitor) {
            writeln!(err, "{prefix}safety monitor: {}", report.summary())?;
        }
        if finished && ended.is_none() {
            ended = Some(prefix);
        }
    }
    if let Some(e) = failed {
        return Err(e);
    }
    if !interrupted {
        match ended.filter(|p| !p.is_empty()) {
            Some(prefix) => bail!("{prefix}the connection to the firmware ended"),
            None => bail!("the connection to the firmware ended"),
        }
    }
    Ok(if interrupt::count() >= 2 { interrupt::EXIT_CODE } else { 0 })
}
