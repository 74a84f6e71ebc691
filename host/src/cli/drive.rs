//! The arm-driving commands on the command line (`move`, `joints`, `play`, `status`, `stop`,
//! `torque`, `gripper`): their arguments, and what was typed made into a typed operation
//! ([`crate::commands::drive::Operation`]) before anything is connected, so bad input changes
//! nothing; its report is printed as text or as one line of JSON. With `--rig`, the same commands
//! become a rig's ([`crate::rig::commands::RigCommand`]).

use std::io::Write;
use std::path::PathBuf;

use anyhow::{bail, Result};
use clap::{Args, Subcommand, ValueEnum};
use firmware::link::message::MovePath;

use super::link::LinkArgs;
use crate::commands::drive::gripper::{GripperGoal, GripperRequest};
use crate::commands::drive::joints::JointsRequest;
use crate::commands::drive::move_to::MoveRequest;
use crate::commands::drive::play::Plan;
use crate::commands::drive::Operation;
use crate::rig::commands::RigCommand;
use crate::support::numbers as parse;

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

/// Runs an arm-driving command; returns the exit code.
/// `link` holds the drive options given before the command.
pub fn run(link: &LinkArgs, command: DriveCommand, out: &mut dyn Write, err: &mut dyn Write) -> Result<i32> {
    let link = link.merged(command.link())?;
    if let Some(rig) = &link.rig {
        link.refuse_beside_rig()?;
        return crate::rig::commands::run(rig, &rig_command(command)?, link.json, out, err);
    }
    // Everything the user typed is checked before connecting, so bad input changes nothing.
    let place = link.one_place()?;
    let operation = operation(&command)?;
    crate::commands::drive::run(&place, link.json, &operation, out, err)
}

/// The rig's form of a command as typed: its arm names and values are checked against the rig
/// file by the rig.
fn rig_command(command: DriveCommand) -> Result<RigCommand> {
    Ok(match command {
        DriveCommand::Status(_) => RigCommand::Status,
        DriveCommand::Stop(_) => RigCommand::Stop,
        DriveCommand::Torque(args) => RigCommand::Torque(args.state == OnOff::On),
        DriveCommand::Move(args) => RigCommand::Move {
            to: args.to,
            quat: args.quat,
            speed: args.speed,
            duration: args.duration,
            path: args.path.into(),
            timeout: args.timeout,
        },
        DriveCommand::Play(args) => RigCommand::Play { file: args.file, timeout: args.timeout },
        DriveCommand::Joints(_) | DriveCommand::Gripper(_) => bail!(
            "--rig drives status, stop, torque, move and play so far; for joints or the gripper, drive that arm on its own"
        ),
    })
}

/// The typed operation of a command as typed.
pub fn operation(command: &DriveCommand) -> Result<Operation> {
    Ok(match command {
        DriveCommand::Move(args) => Operation::Move(move_request(args)?),
        DriveCommand::Joints(args) => Operation::Joints(joints_request(args)?),
        DriveCommand::Play(args) => Operation::Play(Plan::read(&args.file, args.timeout)?),
        DriveCommand::Status(_) => Operation::Status,
        DriveCommand::Stop(_) => Operation::Stop,
        DriveCommand::Torque(args) => Operation::Torque(args.state == OnOff::On),
        DriveCommand::Gripper(args) => {
            let goal = match (args.action, args.percent) {
                (GripperAction::Open, None) => GripperGoal::Open,
                (GripperAction::Close, None) => GripperGoal::Close,
                (GripperAction::Set, Some(p)) => GripperGoal::Set(p),
                (GripperAction::Set, None) => bail!("gripper set: give the opening in percent, 0 closed to 100 open"),
                (action, Some(_)) => {
                    bail!("gripper {}: takes no percent (use `gripper set PERCENT`)", action.name())
                }
            };
            Operation::Gripper(GripperRequest::new(goal, args.effort, args.timeout)?)
        }
    })
}

fn move_request(args: &MoveArgs) -> Result<MoveRequest> {
    let [to] = args.to.as_slice() else {
        bail!("--to is given {} times: once for one arm (with --rig, once per arm as ARM=x,y,z)", args.to.len());
    };
    let quat = match args.quat.as_slice() {
        [] => None,
        [quat] => Some(quat),
        more => bail!("--quat is given {} times: at most once for one arm", more.len()),
    };
    let position = parse::fixed::<3>(to, "--to")?;
    let quat = quat.map(|text| parse::fixed::<4>(text, "--quat")).transpose()?;
    Ok(MoveRequest::new(position, quat, args.speed, args.duration, MovePath::from(args.path), args.timeout)?)
}

fn joints_request(args: &JointsArgs) -> Result<JointsRequest> {
    let q = parse::numbers(&args.q, "--q")?;
    Ok(JointsRequest::new(q, args.speed, args.duration, args.timeout)?)
}
