//! A rig: several arms on one timeline, each with its own firmware core (one board or one USB
//! adapter per arm, as LeRobot's bimanual robots use two ports) and its base somewhere in one
//! world frame. A rig is several link clients, one per arm, on one clock: the host's.
//!
//! - [`file`]: the rig file ([`RigSpec`]), and the built-in rigs.
//! - [`Rig`]: the arms connected. Arms simulated in this process (`sim = true`) share one virtual
//!   clock ([`crate::runtime::sil::group`]), so their cores run in step as two boards would.
//! - [`commands`]: `armctl --rig FILE status|stop|torque|move|play`.
//! - [`clearance`]: each arm an obstacle for the others, checked on the rig's timeline and moves.
//! - [`columns`]: a keyframe file with every arm's columns, split into one file per arm.
//! - [`teleop`]: `armctl teleop --rig`, every arm driven by its own leader.
//! - [`handover`]: `armctl demo --rig`, two simulated arms handing an object over.
//! - [`tree`]: a rig whose arms are mounted on one another (a shared joint) as one kinematic tree.
//! - [`retarget`]: `armctl retarget FILE.bvh --rig FILE`, the human's arms onto every arm at once.

pub mod clearance;
pub mod columns;
pub mod commands;
pub mod file;
pub mod handover;
pub mod play;
pub mod report;
pub mod retarget;
pub mod teleop;
pub mod tree;

use std::io::Write;

use anyhow::{bail, Context, Result};
use firmware::link::message::{RunState, Status};
use kinematics::Pose;

pub use file::{RigArmSpec, RigSpec};

use crate::link::session::seconds_waited;
use crate::runtime::connection::{self, Target};
use crate::runtime::driver::Driver;
use crate::runtime::sil::group::SilGroup;
use crate::runtime::sil::Sil;
use crate::support::interrupt;

/// One arm of a connected rig.
pub struct RigArm {
    /// Its name in the rig.
    pub name: String,
    /// Its base: in the world frame, or on the tool frame of the arm it is mounted on.
    pub base: Pose<f64>,
    /// The earlier arm it is mounted on (`None`: its base is fixed in the world).
    pub mount: Option<usize>,
    /// The connection to its core.
    pub driver: Driver,
}

/// The arms of a rig, connected.
pub struct Rig {
    /// The rig's name.
    pub name: String,
    /// The arms, in the rig file's order.
    pub arms: Vec<RigArm>,
    /// The simulated boards of the arms with `sim = true`, on one virtual clock.
    pub sim: Option<SilGroup>,
    /// Pairs of arms whose hands may touch (a handover): the bodies on each one's last joint are
    /// not checked against the other's ([`clearance`]); everything else of theirs still is.
    pub hands_meet: Vec<[usize; 2]>,
}

impl Rig {
    /// Connects every arm of `spec`: the simulated ones in one group on one virtual clock, the
    /// others each at its place. What connecting to a `bus` measured is said on `err`.
    pub fn open(spec: &RigSpec, err: &mut dyn Write) -> Result<Self> {
        let mut targets = Vec::new();
        for arm in &spec.arms {
            let (target, name) = arm.place.target_and_arm().with_context(|| format!("arm {}", arm.name))?;
            targets.push((target, name.map(str::to_string)));
        }
        // The simulated boards first, all made before any link opens, so they start together.
        let mut sils = Vec::new();
        let mut sim_arms = Vec::new();
        for (target, _) in &targets {
            if let Target::Sim(options) = target {
                let mut options = options.as_ref().clone();
                options.read_timeout_ms = connection::READ_TIMEOUT.as_millis() as u64;
                sim_arms.push(options.arm.clone());
                sils.push(Sil::new(&options)?);
            }
        }
        let group = (!sils.is_empty()).then(|| SilGroup::new(sils)).transpose()?;
        let mut arms = Vec::new();
        let mut sim_index = 0;
        for (arm, (target, name)) in spec.arms.iter().zip(targets) {
            let conn = match (target, &group) {
                (Target::Sim(_), Some(group)) => {
                    sim_index += 1;
                    connection::open_in_group(group, sim_index - 1, sim_arms[sim_index - 1].clone())
                }
                (target, _) => connection::open(target, name.as_deref(), err),
            }
            .with_context(|| format!("arm {}", arm.name))?;
            arms.push(RigArm { name: arm.name.clone(), base: arm.base, mount: arm.mount, driver: Driver::on(conn)? });
        }
        if let Some(group) = &group {
            group.settle_reads();
        }
        Ok(Self { name: spec.name.clone(), arms, sim: group, hands_meet: Vec::new() })
    }

    /// Arm `i`'s base in the world frame now: fixed, or carried by the arm it is mounted on (whose
    /// joints are read for it).
    pub fn world_base(&mut self, i: usize) -> Result<Pose<f64>> {
        let Some(m) = self.arms[i].mount else { return Ok(self.arms[i].base) };
        let carrier = self.world_base(m)?;
        let q = self.arms[m].driver.status()?.measured;
        let tool = self.arms[m].driver.tool_pose(&q)?;
        Ok(carrier.compose(&tool).compose(&self.arms[i].base))
    }

    /// Arm `i`'s tool position in the world frame at its joint values `q`.
    pub fn tool_in_world(&mut self, i: usize, q: &[f32]) -> Result<[f64; 3]> {
        let base = self.world_base(i)?;
        Ok(base.compose(&self.arms[i].driver.tool_pose(q)?).translation.into())
    }

    /// The rig as one kinematic tree, if an arm is mounted on another (a shared joint).
    pub fn tree(&self) -> Result<Option<tree::RigTree>> {
        if self.arms.iter().all(|a| a.mount.is_none()) {
            return Ok(None);
        }
        let arms: Vec<tree::TreeArm<'_>> =
            self.arms.iter().map(|a| tree::TreeArm { arm: a.driver.arm(), base: a.base, mount: a.mount }).collect();
        tree::RigTree::new(&arms).map(Some)
    }

    /// Polls every arm of `arms` until all are at rest, then lets each settle
    /// ([`Driver::settle`]). Every moving arm hears from the host at each poll, so none stops on
    /// its link watchdog while the host waits on another. Gives up after `timeout` controller
    /// seconds (stopping every arm); fails if an arm goes limp or is emergency-stopped; `None`
    /// after Ctrl-C, with nothing sent about it yet.
    pub fn wait_all(&mut self, arms: &[usize], timeout: f64) -> Result<Option<Vec<Status>>> {
        let started = std::time::Instant::now();
        let mut first: Option<f32> = None;
        loop {
            if interrupt::requested() {
                return Ok(None);
            }
            let mut statuses = Vec::new();
            for &a in arms {
                let arm = &mut self.arms[a];
                let status = arm.driver.status()?;
                match status.state {
                    RunState::TorqueOff => bail!("arm {} went limp (torque off) before it was at rest", arm.name),
                    RunState::EStopped => bail!("arm {} was emergency-stopped before it was at rest", arm.name),
                    _ => statuses.push(status),
                }
            }
            if statuses.iter().all(|s| s.state == RunState::Idle) {
                let mut settled = Vec::new();
                for (&a, status) in arms.iter().zip(statuses) {
                    settled.push(self.arms[a].driver.settle(status)?);
                }
                return Ok(Some(settled));
            }
            let now = statuses.first().map_or(0.0, |s| s.time);
            let waited = f64::from(now - *first.get_or_insert(now));
            if waited > timeout || started.elapsed().as_secs_f64() > 4.0 * timeout + 10.0 {
                let stopped = play::stop_all(self);
                bail!("timed out after {} s with an arm still moving; {stopped}", seconds_waited(waited));
            }
            if let Some(&a) = arms.first() {
                self.arms[a].driver.pause()?;
            }
        }
    }

    /// Ends every connection, saying on `err` what each place that ran a core did.
    pub fn close(self, err: &mut dyn Write) -> Result<()> {
        for arm in self.arms {
            arm.driver.close(err)?;
        }
        Ok(())
    }
}
