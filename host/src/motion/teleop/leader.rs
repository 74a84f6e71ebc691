//! The leader arm: its servos on a bus of their own, limp, read as joint angles and a gripper
//! opening.
//!
//! A reading is one sync read of every servo's present position, the gripper's included, as
//! LeRobot's `SOLeader.get_action` does (the master retries the servos that did not answer, twice
//! by default). The ticks become angles through the leader's own mapping: its LeRobot calibration
//! when one is given, else the nominal one of its arm file. The follower's firmware maps the angles
//! back to its own servos' ticks through its calibration, so a position passes through both.
//!
//! Where a leader is ([`LeaderSpec`]) lives here, beside the reading, so that `armctl teleop`'s
//! options and a rig file's `[arm.leader]` name it the same way without one importing the other.

use std::path::PathBuf;

use anyhow::{anyhow, bail, Context, Result};
use firmware::bus::mapping::JointMapping;
use firmware::bus::master::{BusConfig, Clock};
use firmware::bus::table::Model;
use firmware::bus::{Id, Protocol};

use crate::arm::servos::{servos_of, GripperSpec};
use crate::arm::ArmSpec;
use crate::link::serial::{SerialTransport, StdClock};
use crate::runtime::pc::{timing, SEARCH_MARGIN_US};
use crate::runtime::servo_session::{Port, Session};

/// A leader arm, as `armctl teleop`'s `--leader*` options name it for one follower, or a rig
/// file's `[arm.leader]` for each rig arm (`armctl teleop --rig`).
#[derive(Clone, Debug, PartialEq)]
pub struct LeaderSpec {
    /// Its serial port, or `sim` (simulated leader servos turned by `script`).
    pub port: String,
    /// With `sim`: the path the simulated hand moves it along (a joint keyframe file).
    pub script: Option<PathBuf>,
    /// The leader arm: a preset or an arm file [default: so101].
    pub arm: String,
    /// Its LeRobot calibration file.
    pub calibration: Option<PathBuf>,
    /// Its servo protocol [default: its servos'].
    pub protocol: Option<Protocol>,
    /// Its bus's baud rate [default: its arm file's].
    pub baud: Option<u32>,
}

/// One reading of the leader.
#[derive(Clone, Debug, PartialEq)]
pub struct Reading {
    /// Joint angles (rad), base first.
    pub joints: Vec<f64>,
    /// The gripper's opening (percent, 0 closed to 100 open, clamped), if the leader has one.
    pub gripper: Option<f64>,
}

/// The leader's bus and how its ticks map to angles.
pub struct Leader<P: Port, C: Clock> {
    session: Session<P, C>,
    model: &'static Model,
    /// The joints' servos then the gripper's: the order of one sync read.
    ids: Vec<Id>,
    mappings: Vec<JointMapping>,
    gripper: Option<GripperSpec>,
}

impl Leader<SerialTransport, StdClock> {
    /// Opens the leader `arm` on the port `path` with `bus`'s protocol and baud rate. The servos
    /// are looked for with a margin for any adapter's latency timer, then the bus is timed as the
    /// PC-hosted core times its own ([`crate::runtime::pc::timing`]) and the reply margin set from
    /// the latency measured. Returns the leader and that latency (µs).
    pub fn open(path: &str, bus: BusConfig, arm: &ArmSpec) -> Result<(Self, u64)> {
        let searching = BusConfig { margin_us: SEARCH_MARGIN_US, idle_gap_us: SEARCH_MARGIN_US, ..bus };
        let session = Session::open(path, searching).map_err(|e| anyhow!("leader: {e}"))?;
        let mut leader = Self::on(session, arm)?;
        let measured = timing::measure(leader.session.master_mut(), leader.model, &leader.ids)
            .with_context(|| format!("leader on {path}"))?;
        leader.session.set_config(timing::margins(bus, measured.latency_us()));
        Ok((leader, measured.latency_us()))
    }
}

impl<P: Port, C: Clock> Leader<P, C> {
    /// The leader `arm` on an open bus: every servo is pinged and its torque switched off (a
    /// leader is moved by hand). Fails naming the servo that does not answer or is not the model
    /// the arm file says.
    pub fn on(mut session: Session<P, C>, arm: &ArmSpec) -> Result<Self> {
        let servos = servos_of(arm).ok_or_else(|| {
            anyhow!("leader arm {} has no servo mapping: add a [servos] table to its arm file", arm.name)
        })?;
        if session.protocol() != servos.model.protocol {
            bail!(
                "leader arm {}'s servos ({}) do not speak {}",
                arm.name,
                servos.model.name,
                protocol_name(session.protocol())
            );
        }
        let mappings = (0..arm.dof())
            .map(|j| servos.mapping(j).ok_or_else(|| anyhow!("leader arm {}: joint {} has no servo", arm.name, j + 1)))
            .collect::<Result<Vec<_>>>()?;
        let ids = servos.bus_ids();
        let model = servos.model;
        for &id in &ids {
            let servo = session.identify(id).with_context(|| format!("leader on {}", session.path()))?;
            if servo.model.map(|m| m.number) != Some(model.number) {
                bail!(
                    "leader on {}: servo {id} is a {}, but arm {} has {}",
                    session.path(),
                    servo.model_text(),
                    arm.name,
                    model.name
                );
            }
            session
                .write_item(id, model, model.items.torque_enable, 0)
                .with_context(|| format!("leader on {}: switching servo {id}'s torque off", session.path()))?;
        }
        Ok(Self { session, model, ids, mappings, gripper: servos.gripper })
    }

    /// The leader's joint count.
    pub fn joints(&self) -> usize {
        self.mappings.len()
    }

    /// Whether the leader has a gripper (its trigger).
    pub fn has_gripper(&self) -> bool {
        self.gripper.is_some()
    }

    /// Reads every servo once.
    pub fn read(&mut self) -> Result<Reading> {
        let ticks = self.session.sync_read_item(&self.ids, self.model, self.model.items.present_position)?;
        let tick = |k: usize| {
            i32::try_from(ticks[k]).map_err(|_| anyhow!("servo {}: position {} out of range", self.ids[k], ticks[k]))
        };
        let joints = (0..self.mappings.len())
            .map(|j| Ok(self.mappings[j].to_radians::<f64>(tick(j)?)))
            .collect::<Result<_>>()?;
        let gripper = match self.gripper {
            Some(g) => Some(g.percent(tick(self.mappings.len())?).clamp(0.0, 100.0)),
            None => None,
        };
        Ok(Reading { joints, gripper })
    }
}

/// The leader's bus settings: its protocol (that of its servos unless given) at its arm file's baud
/// rate unless given.
pub fn bus_config(arm: &ArmSpec, protocol: Option<Protocol>, baud: Option<u32>) -> Result<BusConfig> {
    let servos =
        servos_of(arm).ok_or_else(|| anyhow!("leader arm {} has no servo mapping: add a [servos] table", arm.name))?;
    Ok(BusConfig::new(protocol.unwrap_or(servos.model.protocol), baud.unwrap_or(servos.baud)))
}

fn protocol_name(protocol: Protocol) -> &'static str {
    match protocol {
        Protocol::Dxl2 => "Dynamixel 2.0 (dxl2)",
        Protocol::Feetech => "Feetech (sts)",
    }
}
