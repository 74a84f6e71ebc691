//! `armctl view`: the arm live in a browser. One more link client of the firmware, with a web page
//! in front of it: the arm in 3D from its chain, one slider per joint, a target to drag (IK
//! preview on this PC, the move on the firmware), telemetry, keyframe files, stop and torque.
//! Every button of the page is a request of a small JSON API that scripts can make too.
//!
//! - [`api`]: the requests, checked before anything moves;
//! - [`arm_loop`]: the one thread that talks to the firmware;
//! - [`preview`]: the IK preview;
//! - [`telemetry`]: the status as the page draws it;
//! - [`server`]: HTTP, the API's routes and the websocket;
//! - [`assets`]: the page's files, embedded in the binary;
//! - [`meshes`]: a URDF's visual meshes over the chain.
//!
//! `--sim` (the default) runs the firmware core on this PC in real time against simulated servos
//! on a pseudo-terminal, as `armctl serve --sim` does: the page shows motion as it happens, which
//! the virtual clock of the drive commands' `--sim` would not.

pub mod api;
pub mod arm_loop;
pub mod assets;
pub mod meshes;
pub mod preview;
pub mod server;
pub mod telemetry;

use std::io::Write;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Duration;

use anyhow::{bail, Context, Result};
use clap::Args;

use crate::arm::servos::servos_of;
use crate::drive::args::LinkArgs;
use crate::drive::connection::Target;
use crate::drive::interrupt;
use crate::places::pc::PcOptions;
use arm_loop::ArmLoop;
use server::{Served, ViewServer};
use telemetry::Latest;

/// Where the page is served unless `--listen` says otherwise: this machine only.
pub const DEFAULT_LISTEN: &str = "127.0.0.1:8765";
/// The latency timer of the simulated USB adapter of `--sim`.
const SIM_ADAPTER_LATENCY: Duration = Duration::from_millis(1);

/// `armctl view`.
#[derive(Args, Debug)]
pub struct ViewArgs {
    #[command(flatten)]
    #[allow(missing_docs)]
    pub link: LinkArgs,
    /// Serve the page on this address and port. The default serves this machine only; any other
    /// address lets whoever reaches it move the arm. Port 0 picks a free one.
    #[arg(long, value_name = "ADDR:PORT", default_value = DEFAULT_LISTEN)]
    pub listen: String,
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
    let urdf = args.urdf.as_deref().map(|file| meshes::Urdf::read(file, args.tip.as_deref())).transpose()?;
    let (target, arm) = link.target()?;
    let arm = arm.map(str::to_string);
    // The address is taken before connecting, so a port in use changes nothing on the arm.
    let listener = ViewServer::bind(&listen.to_string())?;
    // --sim runs in real time here (see the module doc).
    let (target, simulated) = match target {
        Target::Sim(options) => {
            let (options, servos) = PcOptions::simulated(options.arm, Some(SIM_ADAPTER_LATENCY))?;
            (Target::Bus(Box::new(options)), Some(servos))
        }
        other => (other, None),
    };
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
    let server = ViewServer::start(listener, served, arm_loop.jobs())?;
    writeln!(out, "{}", server.url())?;
    out.flush()?;
    if !listen.ip().is_loopback() {
        writeln!(
            err,
            "warning: listening on {listen}: anyone who can reach this address can move the arm, and nothing asks who \
             they are"
        )?;
    }
    writeln!(
        err,
        "arm {} ({} joints{}): open {} in a browser; Ctrl-C stops the arm and exits",
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
    drop(server);
    let interrupted = interrupt::requested();
    let said = arm_loop.finish().context("the arm loop")?;
    err.write_all(said.as_bytes())?;
    if let Some(report) = simulated.as_ref().and_then(crate::sim::PtyServer::monitor) {
        writeln!(err, "safety monitor: {}", report.summary())?;
    }
    if !interrupted {
        bail!("the connection to the firmware ended");
    }
    writeln!(err, "stopped: the arm holds")?;
    Ok(0)
}
