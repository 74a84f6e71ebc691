//! The arguments of the arm-driving commands: the drive options (`--port`/`--sim`/`--bus`,
//! `--protocol`, `--baud`, `--arm`, `--json`, before or after the command) and the commands `move`, `joints`, `play`,
//! `status`, `stop`, `torque` and `gripper`.

use std::path::PathBuf;

use anyhow::{bail, Result};
use clap::{Args, Subcommand, ValueEnum};

use crate::commands::bus_args::ProtocolArg;
use crate::runtime::connection::{Place, Target};

pub use crate::runtime::connection::{calibrated, default_bus_arm, DEFAULT_BAUD, DEFAULT_SIM_ARM};

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
    /// Drive every arm of a rig together (a rig file, or the built-in bimanual-so101): status,
    /// stop, torque, move (--to ARM=x,y,z in the world frame, once per arm) and play (a keyframe
    /// file with each arm's columns, ARM.q1,...); `view --rig` shows and drives every arm in one
    /// page, `teleop --rig` and `retarget --rig` take every arm's part. Each arm's place is in the
    /// file.
    #[arg(long, value_name = "FILE", conflicts_with_all = ["sim", "port", "bus"])]
    pub rig: Option<String>,
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
            rig: one("--rig", &self.rig, &after.rig)?,
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

    /// The board or simulation to connect to, and the arm to configure on it.
    pub fn target(&self) -> Result<(Target, Option<&str>)> {
        if self.rig.is_some() {
            bail!("--rig drives status, stop, torque, move and play so far; this command drives one arm");
        }
        let place = self.place();
        Ok((place.target()?, self.arm.as_deref().or_else(|| place.default_arm())))
    }

    /// Where the arm is, as typed.
    pub fn place(&self) -> Place {
        Place {
            port: self.port.clone(),
            bus: self.bus.clone(),
            protocol: self.protocol.map(Into::into),
            baud: self.baud,
            sim: self.sim,
            arm: self.arm.clone(),
            calibration: self.calibration.clone(),
            object_mm: self.object_mm,
        }
    }
}

/// One option given before the command (`a`) and after it (`b`): either, or both if they agree.
pub fn either<T: PartialEq + std::fmt::Debug>(name: &str, a: Option<T>, b: Option<T>) -> Result<Option<T>> {
    match (a, b) {
        (Some(x), Some(y)) if x != y => bail!("{name} is given twice, with different values ({x:?} and {y:?})"),
        (a, b) => Ok(a.or(b)),
    }
}

/// The arm-driving commands.
#[derive(Subcommand, Debug)]
pub enum DriveCommand {
    /// Move the tool to a point (and orientation), IK on the firmware: a straight line, or by joints
    ///
    /// The way is --path's: the straight line, finished by joints where it runs into the joint
    /// limits (auto, the default), the line only, or by joints. Switches torque on if it is off. Waits until the arm is at rest and prints the target,
    /// the position reached (forward kinematics of the measured joints), the error and the time;
    /// Ctrl-C stops the arm.
    Move(MoveArgs),
    /// Move the joints to values (all joints arrive together, at rest).
    ///
    /// Switches torque on if it is off. Waits until the arm is at rest; Ctrl-C stops the arm.
    Joints(JointsArgs),
    /// Play a keyframe file, joint or Cartesian, with a progress bar on a terminal
    ///
    /// Joint keyframes have the header t,q1,...,qN[,v1,...,vN], as for `armctl trajectory sample`;
    /// Cartesian ones t,x,y,z or t,x,y,z,qw,qx,qy,qz (metres, unit quaternion w first; IK on the
    /// firmware). The header tells the format. The whole file is checked before anything is sent;
    /// the keyframes are streamed with flow control. Ctrl-C stops the arm.
    Play(PlayArgs),
    /// The controller's state: run state, joints, queue, IK, loop timing, error counters.
    Status(OnlyLinkArgs),
    /// Stop: decelerate within the limits, drop queued keyframes and hold.
    Stop(OnlyLinkArgs),
    /// Torque on (hold the present position; also leaves an emergency stop) or off (limp).
    Torque(TorqueArgs),
    /// Open, close or set the gripper (percent, 0 closed to 100 open), with an optional effort limit
    ///
    /// The effort limit is a percent of the servo's full torque or current. Switches torque on if
    /// it is off. Waits until the gripper is at its goal or holds something
    /// (stopped short of its goal under load) and prints where it stopped and the load.
    Gripper(GripperArgs),
}

impl DriveCommand {
    /// The drive options given after the command.
    pub fn link(&self) -> &LinkArgs {
        match self {
            DriveCommand::Move(a) => &a.link,
            DriveCommand::Joints(a) => &a.link,
            DriveCommand::Play(a) => &a.link,
            DriveCommand::Status(a) | DriveCommand::Stop(a) => &a.link,
            DriveCommand::Torque(a) => &a.link,
            DriveCommand::Gripper(a) => &a.link,
        }
    }
}

/// `armctl status` and `armctl stop`: no options but the drive options.
#[derive(Args, Debug)]
pub struct OnlyLinkArgs {
    #[command(flatten)]
    #[allow(missing_docs)]
    pub link: LinkArgs,
}

/// `armctl torque`.
#[derive(Args, Debug)]
pub struct TorqueArgs {
    /// on or off.
    #[arg(value_enum)]
    pub state: OnOff,
    #[command(flatten)]
    #[allow(missing_docs)]
    pub link: LinkArgs,
}

/// `torque on|off`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum OnOff {
    /// Torque on.
    On,
    /// Torque off.
    Off,
}

/// `move --path`: which way the tool goes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, ValueEnum)]
pub enum PathArg {
    /// The straight line; where it runs into the joint limits, the rest of the way by joints.
    #[default]
    Auto,
    /// The straight line only: where it runs into the joint limits, stop there and say why.
    Line,
    /// By joints, to the joint values IK found for the target.
    Joint,
}

impl From<PathArg> for firmware::link::message::MovePath {
    fn from(path: PathArg) -> Self {
        match path {
            PathArg::Auto => Self::Auto,
            PathArg::Line => Self::Line,
            PathArg::Joint => Self::Joint,
        }
    }
}

/// `armctl move`.
#[derive(Args, Debug)]
pub struct MoveArgs {
    #[command(flatten)]
    #[allow(missing_docs)]
    pub link: LinkArgs,
    /// Tool position x,y,z (m, base frame). With --rig: ARM=x,y,z (m, the rig's world frame),
    /// once for each arm to move.
    #[arg(long, allow_hyphen_values = true, required = true)]
    pub to: Vec<String>,
    /// Tool orientation as a unit quaternion w,x,y,z (omit to leave it free). With --rig:
    /// ARM=w,x,y,z (world frame).
    #[arg(long, allow_hyphen_values = true)]
    pub quat: Vec<String>,
    /// Tool speed along the line (m/s) [default: 0.1].
    #[arg(long, conflicts_with = "duration", allow_hyphen_values = true)]
    pub speed: Option<f64>,
    /// Arrive after this many seconds (joint limits permitting).
    #[arg(long, allow_hyphen_values = true)]
    pub duration: Option<f64>,
    /// Which way: the straight line, finished by joints where it runs into the joint limits
    /// (auto); the line only (line); or by joints (joint).
    #[arg(long, value_enum, default_value_t = PathArg::Auto)]
    pub path: PathArg,
    /// Give up waiting (and stop the arm) after this many seconds of controller time.
    #[arg(long, default_value_t = 60.0)]
    pub timeout: f64,
}

/// `armctl joints`.
#[derive(Args, Debug)]
pub struct JointsArgs {
    #[command(flatten)]
    #[allow(missing_docs)]
    pub link: LinkArgs,
    /// Joint values, comma-separated (rad, m for prismatic joints), one per joint.
    #[arg(long, allow_hyphen_values = true)]
    pub q: String,
    /// Arrive after this many seconds, or later if the joint limits need longer [default: as fast
    /// as the limits allow].
    #[arg(long, conflicts_with = "speed", allow_hyphen_values = true)]
    pub duration: Option<f64>,
    /// No joint faster than this (rad/s or m/s).
    #[arg(long, allow_hyphen_values = true)]
    pub speed: Option<f64>,
    /// Give up waiting (and stop the arm) after this many seconds of controller time.
    #[arg(long, default_value_t = 60.0)]
    pub timeout: f64,
}

/// `armctl gripper`.
#[derive(Args, Debug)]
pub struct GripperArgs {
    /// open (100 %), close (0 %) or set PERCENT.
    #[arg(value_enum)]
    pub action: GripperAction,
    /// With set: the opening, percent (0 closed to 100 open).
    #[arg(allow_negative_numbers = true)]
    pub percent: Option<f64>,
    /// Effort limit from now on, percent of the servo's full torque (STS3215) or current
    /// (Dynamixel); the arm's default until changed.
    #[arg(long, value_name = "PERCENT", allow_negative_numbers = true)]
    pub effort: Option<f64>,
    /// Give up waiting after this many seconds of controller time.
    #[arg(long, default_value_t = 10.0)]
    pub timeout: f64,
    #[command(flatten)]
    #[allow(missing_docs)]
    pub link: LinkArgs,
}

/// What `gripper` does.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum GripperAction {
    /// Fully open (100 %).
    Open,
    /// Close (0 %), stopping on whatever is between the jaws.
    Close,
    /// To an opening in percent.
    Set,
}

impl GripperAction {
    /// As typed.
    pub fn name(self) -> &'static str {
        match self {
            Self::Open => "open",
            Self::Close => "close",
            Self::Set => "set",
        }
    }
}

/// `armctl play`.
#[derive(Args, Debug)]
pub struct PlayArgs {
    #[command(flatten)]
    #[allow(missing_docs)]
    pub link: LinkArgs,
    /// Keyframe CSV file.
    pub file: PathBuf,
    /// Give up waiting (and stop the arm) this many seconds of controller time after the last
    /// keyframe's time.
    #[arg(long, default_value_t = 30.0)]
    pub timeout: f64,
}
