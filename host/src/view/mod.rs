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
use clap::Args;

use crate::arm::servos::servos_of;
use crate::cli::link::LinkArgs;
use crate::support::interrupt;
use arm_loop::ArmLoop;
use server::{Served, ServedArm, ViewServer};
use telemetry::Latest;

/// Where the page is served unless `--listen` says otherwise: this machine only.
pub const DEFAULT_LISTEN: &str = "127.0.0.1:8765";

/// `armctl view`.
#[derive(Args, Debug)]
pub struct ViewArgs {
    #[command(flatten)]
    #[allow(missing_docs)]
    pub link: LinkArgs,
    /// Serve the page on this address and port. The default serves this machine only; any other
    /// address lets whoever has the URL move the arm, and plain HTTP shows the token to the
    /// network (an SSH tunnel is the safe way in from another machine). Port 0 picks a free one.
    #[arg(long, value_name = "ADDR:PORT", default_value = DEFAULT_LISTEN)]
    pub listen: String,
    /// The API's token (at least 32 letters, digits or -._~) instead of a random one drawn for
    /// this run. Other users of this machine can read a command line: prefer the random one.
    #[arg(long, value_name = "TOKEN")]
    pub token: Option<String>,
    /// Draw this URDF's visual meshes (STL) over the chain; its moving joints must be the arm's.
    #[arg(long, value_name = "FILE.urdf")]
    pub urdf: Option<PathBuf>,
    /// The link the --urdf chain ends at, where the URDF has several leaves (the SO-101's:
    /// gripper_frame_link).
    #[arg(long, value_name = "LINK", requires = "urdf")]
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

/// Runs `armctl view` until Ctrl-C; returns the exit code.
pub fn run(link: &LinkArgs, args: ViewArgs, out: &mut dyn Write, err: &mut dyn Write) -> Result<i32> {
    // Everything the user typed is checked before anything is opened.
    let mut link = link.merged(&args.link)?;
    if let Some(rig) = link.rig.clone() {
        return rig::run(&rig, &link, &args, out, err);
    }
    if link.port.is_none() && link.bus.is_none() {
        link.sim = true;
    }
    if link.object_mm.is_some() {
        bail!("--object-mm: the view's simulated arm has no object between its jaws");
    }
    let (listen, token) = listen_and_token(&args)?;
    let urdf = args.urdf.as_deref().map(|file| meshes::Urdf::read(file, args.tip.as_deref())).transpose()?;
    let place = link.one_place()?;
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
    print_url(server.url(), link.json, out)?;
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
fn listen_and_token(args: &ViewArgs) -> Result<(SocketAddr, Token)> {
    let listen: SocketAddr = args
        .listen
        .parse()
        .with_context(|| format!("--listen {}: expected ADDR:PORT, e.g. 127.0.0.1:8765", args.listen))?;
    let token = match &args.token {
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
