//! The drive options (`--port`/`--sim`/`--bus`, `--protocol`, `--baud`, `--arm`,
//! `--calibration`, `--object-mm`, `--obstacle`, `--no-table`, `--rig`, `--json`), accepted before the command or after it,
//! and what the command line makes of them: one arm's [`Place`], or a rig file.

use crate::sim::physics::{servo_kind, ServoKind};
use std::path::PathBuf;

use anyhow::{bail, Result};
use clap::Args;

use crate::arm::collision::obstacle::Surroundings;
use crate::cli::bus_args::ProtocolArg;
use crate::runtime::connection::Place;

/// Which arm to drive. Accepted before the command or after it (`armctl --sim move --to ... --json`
/// as well as `armctl move --sim --to ...`), as global options are. Before another command, each
/// goes to the command's own option of that name where it has one (`armctl --json fk ...`,
/// `armctl --sim serve`), and is refused where it has none (`armctl --rig R fk ...`).
#[derive(Args, Debug, Default, Clone, PartialEq)]
pub struct LinkArgs {
    /// Drive the board running the firmware on this serial port (or on the pseudo-terminal that
    /// `armctl serve` or `armctl sim --qemu` printed).
    #[arg(long, value_name = "PORT", conflicts_with = "sim")]
    pub port: Option<String>,
    /// Drive the servos on this USB adapter's serial port (U2D2, Waveshare, FE-URT-1) with the
    /// firmware core run on this PC.
    #[arg(long, value_name = "PORT", conflicts_with_all = ["sim", "port"])]
    pub bus: Option<String>,
    /// With --bus: the servos' protocol, sts (Feetech) or dxl2 (Dynamixel 2.0).
    #[arg(long, value_enum)]
    pub protocol: Option<ProtocolArg>,
    /// Baud rate of --port or of the --bus servos [default: 1000000; for --bus, the arm file's `baud`].
    #[arg(long)]
    pub baud: Option<u32>,
    /// Drive the firmware core simulated on this PC with simulated servos (software in the loop).
    #[arg(long)]
    pub sim: bool,
    /// The arm: a preset or an arm file (.toml or .urdf). To drive it with --sim or --bus it needs
    /// servos: so101, open-manipulator-x or an arm file with a [servos] table. With --sim
    /// [default: so101]; with --port, configured on the board first [default: the arm the board
    /// runs]; with --bus [default: so101 on sts, open-manipulator-x on dxl2].
    #[arg(long = "arm", value_name = "ARM")]
    pub arm: Option<String>,
    /// With --bus: a LeRobot calibration file (JSON) of the arm's servos: the joints then map to
    /// ticks exactly as LeRobot's degree mode maps them, within the calibrated ranges.
    #[arg(long, value_name = "FILE")]
    pub calibration: Option<PathBuf>,
    /// With --sim: an object this wide (mm) between the gripper's jaws, which stop on it.
    #[arg(long, value_name = "MM", allow_negative_numbers = true)]
    pub object_mm: Option<f64>,
    /// With --sim: the simulated servos. `ideal` (the default) reach every goal exactly along
    /// their profiles; `physical` have a motor through a gearbox under their own position loop and
    /// carry the arm's links under gravity, so they sag, lag, draw current, warm up and can stall
    /// (docs/servo-model.md).
    #[arg(long, value_name = "KIND", value_parser = ["ideal", "physical"])]
    pub servos: Option<String>,
    /// With --sim --servos physical: a payload of KG kilograms at the tool frame's origin. Refused
    /// when it asks a joint for more than its servo's stall torque somewhere in its range.
    #[arg(long, value_name = "KG", allow_negative_numbers = true)]
    pub payload_kg: Option<f64>,
    /// Offset each servo's goal by the sag its own loop will leave under the arm's gravity (and
    /// --payload-kg), so the tool arrives where the IK put it (docs/servo-model.md). On by
    /// default with --sim --servos physical; off by default elsewhere (ideal servos do not sag;
    /// on a real arm it has not run yet: `on` asks for it, for an arm with masses whose servos
    /// hold the P gain `armctl servo setup` writes).
    #[arg(long, value_name = "ON|OFF", value_parser = ["on", "off"])]
    pub gravity_compensation: Option<String>,
    /// Drive every arm of a rig together (a rig file, or the built-in bimanual-so101): status,
    /// stop, torque, move (--to ARM=x,y,z in the world frame, once per arm) and play (a keyframe
    /// file with each arm's columns, ARM.q1,...); `view --rig` shows and drives every arm in one
    /// page, `teleop --rig` and `retarget --rig` take every arm's part. Each arm's place is in the
    /// file.
    #[arg(long, value_name = "FILE", conflicts_with_all = ["sim", "port", "bus"])]
    pub rig: Option<String>,
    /// An obstacle around the arm, in its base frame (m): box:x,y,z,sx,sy,sz (centre and sizes),
    /// sphere:x,y,z,r, capsule:x1,y1,z1,x2,y2,z2,r or plane:nx,ny,nz,offset (the solid where
    /// normal . x <= offset), with NAME= first to name it. Repeatable. Added to the arm's collision
    /// geometry, which every goal is checked against.
    #[arg(long = "obstacle", value_name = "SPEC")]
    pub obstacles: Vec<crate::arm::collision::ObstacleSpec>,
    /// With --sim only: an obstacle in the simulated world that the firmware is not told of (an
    /// object nobody declared): the simulated links stop at it, as at a real one. SPEC as for
    /// --obstacle. Repeatable. A move it blocks fails naming the joint (docs/collisions.md).
    #[arg(long = "hidden-obstacle", value_name = "SPEC")]
    pub hidden_obstacles: Vec<crate::arm::collision::ObstacleSpec>,
    /// Without the table the arm stands on (a preset stands on one at its base plane, an arm file
    /// where its [collision] table says).
    #[arg(long)]
    pub no_table: bool,
    /// With --sim only: send the firmware the arm's collision geometry with its check off, so
    /// that the simulated arm is seen to run into the table or an obstacle and stall there (the
    /// simulator's contact). Status says CHECK OFF. For tests; a real arm is always checked.
    #[arg(long)]
    pub no_collision_check: bool,
    /// Print the result as one line of JSON (view: its URL as {"url": URL}). Every command takes
    /// --json, before or after it: its --help says what it prints.
    #[arg(long)]
    pub json: bool,
}

impl LinkArgs {
    /// These options given before the command together with those given after it. One given in
    /// both places must have the same value.
    pub fn merged(&self, after: &LinkArgs) -> Result<LinkArgs> {
        fn one<T: Clone + PartialEq + std::fmt::Debug>(name: &str, a: &Option<T>, b: &Option<T>) -> Result<Option<T>> {
            either(name, a.clone(), b.clone())
        }
        Ok(LinkArgs {
            port: one("--port", &self.port, &after.port)?,
            bus: one("--bus", &self.bus, &after.bus)?,
            protocol: one("--protocol", &self.protocol, &after.protocol)?,
            baud: one("--baud", &self.baud, &after.baud)?,
            sim: self.sim || after.sim,
            arm: one("--arm", &self.arm, &after.arm)?,
            calibration: one("--calibration", &self.calibration, &after.calibration)?,
            object_mm: one("--object-mm", &self.object_mm, &after.object_mm)?,
            servos: one("--servos", &self.servos, &after.servos)?,
            payload_kg: one("--payload-kg", &self.payload_kg, &after.payload_kg)?,
            gravity_compensation: one(
                "--gravity-compensation",
                &self.gravity_compensation,
                &after.gravity_compensation,
            )?,
            rig: one("--rig", &self.rig, &after.rig)?,
            obstacles: self.obstacles.iter().chain(&after.obstacles).cloned().collect(),
            hidden_obstacles: self.hidden_obstacles.iter().chain(&after.hidden_obstacles).cloned().collect(),
            no_table: self.no_table || after.no_table,
            no_collision_check: self.no_collision_check || after.no_collision_check,
            json: self.json || after.json,
        })
    }

    /// The options of one arm's place and model that are given, by name.
    pub fn one_arm_options(&self) -> Vec<&'static str> {
        [
            (self.port.is_some(), "--port"),
            (self.bus.is_some(), "--bus"),
            (self.protocol.is_some(), "--protocol"),
            (self.baud.is_some(), "--baud"),
            (self.sim, "--sim"),
            (self.arm.is_some(), "--arm"),
            (self.calibration.is_some(), "--calibration"),
            (self.object_mm.is_some(), "--object-mm"),
            (self.servos.is_some(), "--servos"),
            (self.payload_kg.is_some(), "--payload-kg"),
            (self.gravity_compensation.is_some(), "--gravity-compensation"),
            (!self.obstacles.is_empty(), "--obstacle"),
            (!self.hidden_obstacles.is_empty(), "--hidden-obstacle"),
            (self.no_table, "--no-table"),
            (self.no_collision_check, "--no-collision-check"),
        ]
        .into_iter()
        .filter_map(|(given, name)| given.then_some(name))
        .collect()
    }

    /// Refuses the options of one arm's place and model beside `--rig`, whose file holds every
    /// arm's.
    pub fn refuse_beside_rig(&self) -> Result<()> {
        let given = self.one_arm_options();
        if !given.is_empty() {
            bail!("with --rig, each arm's place and arm are in the rig file: give no {}", given.join(", "));
        }
        Ok(())
    }

    /// Refuses the options given that `command` (as typed: `fk`, `bench ik`) has no use for.
    pub fn refuse_for(&self, command: &str) -> Result<()> {
        let mut given = self.one_arm_options();
        given.extend(
            [(self.rig.is_some(), "--rig"), (self.json, "--json")].into_iter().filter_map(|(g, n)| g.then_some(n)),
        );
        if !given.is_empty() {
            let (options, are) = if given.len() == 1 { ("an option", "is") } else { ("options", "are") };
            bail!("{} {are} not {options} of `armctl {command}` (see armctl {command} --help)", given.join(", "));
        }
        Ok(())
    }

    /// Where the one arm a command drives is, as typed; refused with `--rig` (a command that
    /// drives a rig's arms together dispatches to `rig::` before asking for one place).
    pub fn one_place(&self) -> Result<Place> {
        if self.rig.is_some() {
            bail!("--rig drives status, stop, torque, move and play so far; this command drives one arm");
        }
        self.place()
    }

    /// Where the arm is, as typed.
    pub fn place(&self) -> Result<Place> {
        Ok(Place {
            port: self.port.clone(),
            bus: self.bus.clone(),
            protocol: self.protocol.map(Into::into),
            baud: self.baud,
            sim: self.sim,
            arm: self.arm.clone(),
            calibration: self.calibration.clone(),
            object_mm: self.object_mm,
            servos: self.servo_kind()?,
            surroundings: self.surroundings(),
            hidden_obstacles: self.hidden_obstacles.clone(),
            no_collision_check: self.no_collision_check,
            gravity: self.gravity_compensation.as_deref().map(|v| v == "on"),
        })
    }

    /// The simulated servos `--servos` and `--payload-kg` ask for (`None`: neither given).
    pub fn servo_kind(&self) -> Result<Option<ServoKind>> {
        if self.servos.is_none() && self.payload_kg.is_none() {
            return Ok(None);
        }
        servo_kind(self.servos.as_deref(), self.payload_kg).map(Some)
    }

    /// What `--obstacle` and `--no-table` change around the arm.
    pub fn surroundings(&self) -> Surroundings {
        Surroundings { obstacles: self.obstacles.clone(), no_table: self.no_table }
    }
}

/// One option given before the command (`a`) and after it (`b`): either, or both if they agree.
pub fn either<T: PartialEq + std::fmt::Debug>(name: &str, a: Option<T>, b: Option<T>) -> Result<Option<T>> {
    match (a, b) {
        (Some(x), Some(y)) if x != y => bail!("{name} is given twice, with different values ({x:?} and {y:?})"),
        (a, b) => Ok(a.or(b)),
    }
}
