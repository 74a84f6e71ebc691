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
//! - [`meshes`]: a URDF's visual meshes over the chain.
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
use crate::drive::args::LinkArgs;
use crate::drive::interrupt;
use arm_loop::ArmLoop;
use server::{Served, ViewServer};
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

/// Runs `armctl view` until Ctrl-C; returns the exit code.
pub fn run(link: &LinkArgs, args: ViewArgs, out: &mut dyn Write, err: &mut dyn Write) -> Result<i32> {
    // Everything the user typed is checked before anything is opened.
    let mut link = link.merged(&args.link)?;
    if link.port.is_none() && link.bus.is_none() {
        link.sim = true;
    }
    if link.object_mm.is_some() {
        bail!("--object-mm: the view's simulated arm has no object between its jaws");
    }
    let listen: SocketAddr = args
        .listen
        .parse()
        .with_context(|| format!("--listen {}: expected ADDR:PORT, e.g. 127.0.0.1:8765", args.listen))?;
    let token = match &args.token {
        Some(text) => Token::given(text)?,
        None => Token::generate()?,
    };
    let urdf = args.urdf.as_deref().map(|file| meshes::Urdf::read(file, args.tip.as_deref())).transpose()?;
    let (target, arm) = link.target()?;
    let arm = arm.map(str::to_string);
    if !listen.ip().is_loopback() {
        writeln!(
            err,
            "warning: --listen {listen} is not this machine's loopback: anyone who has the URL can move the arm, and \
             plain HTTP shows its token to the network; to reach the view from another machine, keep the default and \
             use an SSH tunnel (ssh -L 8765:127.0.0.1:8765 this-machine)"
        )?;
        err.flush()?;
    }
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
    let served = Served { arm: arm_json, meshes: meshes.iter().map(|m| m.file.clone()).collect(), latest };
    let mut server = ViewServer::start(listener, served, arm_loop.jobs(), token)?;
    writeln!(out, "{}", server.url())?;
    out.flush()?;
    writeln!(
        err,
        "arm {} ({} joints{}): open {} in a browser (the token in it is what lets a page drive the arm: keep it to \
         yourself); Ctrl-C stops the arm and exits",
        spec.name,
        spec.dof(),
        if servos_of(&spec).and_then(|s| s.gripper).is_some() { " and a gripper" } else { "" },
        server.url()
    )?;
    err.flush()?;
    interrupt::catch();
    while !interrupt::requested() {
        std::thread::sleep(Duration::from_millis(20));
        if arm_loop.is_finished() {
            break;
        }
        if simulated.as_ref().is_some_and(crate::sim::PtyServer::is_finished) {
            bail!("the simulated servos stopped");
        }
    }
    let interrupted = interrupt::requested();
    if interrupted {
        // The arm first: stopped and holding (or limp, on a second signal) before the server
        // closes, whatever its clients do; the server's threads never hold the arm loop.
        writeln!(err, "stopping: the arm decelerates within its limits, then holds (Ctrl-C again: torque off)")?;
        err.flush()?;
        arm_loop.begin_stop();
        while !arm_loop.is_finished() {
            if interrupt::count() >= 2 {
                arm_loop.torque_off();
            }
            std::thread::sleep(Duration::from_millis(2));
        }
    }
    server.shutdown();
    let said = arm_loop.finish().context("the arm loop")?;
    err.write_all(said.as_bytes())?;
    if let Some(report) = simulated.as_ref().and_then(crate::sim::PtyServer::monitor) {
        writeln!(err, "safety monitor: {}", report.summary())?;
    }
    if !interrupted {
        bail!("the connection to the firmware ended");
    }
    Ok(if interrupt::count() >= 2 { interrupt::EXIT_CODE } else { 0 })
}
