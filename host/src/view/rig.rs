//! `armctl view --rig RIG`: every arm of a rig in one page, one server, one token. Each arm keeps
//! its own place and core (a simulated arm becomes a real-time core against simulated servos on a
//! pseudo-terminal, as `view --sim` makes one; not the rig's virtual-clock group, which would not
//! pace a live page) and its own [`ArmLoop`], with its own queue where a stop goes first.
//!
//! The API names the arm by path (`/api/arm/NAME/...`, see [`super::server`]) and speaks the rig's
//! world frame for every arm: a target is converted to the arm's base frame before the preview
//! and the move, and the telemetry's frames, tool and preview come back in the world frame, so
//! the page draws every arm in one scene as it stands.

use std::io::Write;
use std::sync::Arc;

use anyhow::{Context, Result};
use serde_json::json;

use super::arm_loop::{ArmLoop, Seat};
use super::server::{Rig, Served, ServedArm, ViewServer};
use super::telemetry::{frame, Latest, Placement};
use super::{joints_and_gripper, listen_and_token, meshes, supervise, warn_if_open, Running, ViewRequest};
use crate::rig::RigSpec;

/// Runs `armctl view --rig rig` until Ctrl-C; `json`: the URL as {"url": URL}. `request.urdf` and
/// `request.tip` are one arm's: the caller refuses them. Returns the exit code.
pub fn run(rig: &str, json: bool, request: &ViewRequest, out: &mut dyn Write, err: &mut dyn Write) -> Result<i32> {
    let spec = RigSpec::load(rig)?;
    // Each arm's base is placed once: an arm on another's tool frame would move with its joints.
    spec.refuse_mounts("view")?;
    let (listen, token) = listen_and_token(request)?;
    let mut targets = Vec::new();
    for arm in &spec.arms {
        let (target, model) = arm.place.target_and_arm().with_context(|| format!("arm {}", arm.name))?;
        targets.push((target, model.map(str::to_string)));
    }
    warn_if_open(listen, err)?;
    // The address is taken before connecting, so a port in use changes nothing on the arms.
    let listener = ViewServer::bind(listen)?;
    let latest = Arc::new(Latest::with_arms(spec.arms.len()));
    // Dropping these (an arm that fails to connect) stops the arms connected before it.
    let mut running = Vec::new();
    let mut served = Vec::new();
    let mut described = Vec::new();
    let mut listed = Vec::new();
    for (slot, (arm, (target, model))) in spec.arms.iter().zip(targets).enumerate() {
        let (target, simulated) = target.in_real_time().with_context(|| format!("arm {}", arm.name))?;
        let seat =
            Seat { latest: latest.clone(), slot, name: Some(arm.name.clone()), placement: Placement::world(arm.base) };
        // What connecting says, each line naming the arm.
        let mut said = Vec::new();
        let spawned = ArmLoop::spawn_seated(target, model, seat, &mut said);
        for line in String::from_utf8_lossy(&said).lines() {
            writeln!(err, "arm {}: {line}", arm.name)?;
        }
        let (arm_loop, model, queue_capacity) = spawned.with_context(|| format!("arm {}", arm.name))?;
        let mut chain = meshes::arm_json(&model, queue_capacity, &[])?;
        chain["base"] = frame(&arm.base);
        described.push(json!({"name": arm.name, "base": frame(&arm.base), "arm": chain.clone()}));
        listed.push(format!("{} ({}, {})", arm.name, model.name, joints_and_gripper(&model)));
        served.push(ServedArm { name: arm.name.clone(), arm: chain, jobs: arm_loop.jobs() });
        running.push(Running { name: Some(arm.name.clone()), arm_loop, simulated });
    }
    let rig_json = json!({"name": spec.name, "frame": "world", "arms": described});
    let served =
        Served { arms: served, rig: Some(Rig { name: spec.name.clone(), json: rig_json }), meshes: Vec::new(), latest };
    let mut server = ViewServer::start(listener, served, token)?;
    super::print_url(server.url(), json, out)?;
    out.flush()?;
    writeln!(
        err,
        "rig {}: arms {}, each at its base in the world frame: open {} in a browser (the token in it is what lets \
         a page drive the arms: keep it to yourself); Ctrl-C stops every arm and exits",
        spec.name,
        listed.join(", "),
        server.url()
    )?;
    err.flush()?;
    supervise(running, &mut server, err)
}
