//! The arguments of the arm-driving commands and their dispatch: the options before the command
//! (`--port`/`--sim`, `--baud`, `--arm`, `--json`) and the commands `move`, `joints`, `play`,
//! `status`, `stop` and `torque`.

use std::io::Write;
use std::path::PathBuf;

use anyhow::{bail, Result};
use clap::{Args, Subcommand, ValueEnum};

use super::commands;
use super::connection::Target;

/// The simulated arm of `--sim` when `--arm` is not given.
pub const DEFAULT_SIM_ARM: &str = "so101";
/// The baud rate of `--port` when `--baud` is not given.
pub const DEFAULT_BAUD: u32 = 1_000_000;

/// Which arm to drive: options given before the command.
#[derive(Args, Debug, Default)]
pub struct LinkArgs {
    /// Drive the board running the firmware on this serial port (before move, joints, play,
    /// status, stop, torque).
    #[arg(long, value_name = "PORT", conflicts_with = "sim")]
    pub port: Option<String>,
    /// Baud rate of --port [default: 1000000].
    #[arg(long)]
    pub baud: Option<u32>,
    /// Drive the firmware core simulated on this PC with simulated servos (software in the loop).
    #[arg(long)]
    pub sim: bool,
    /// With --sim: the simulated arm, so101 (default) or open-manipulator-x. With --port: a preset
    /// arm to configure on the board first (default: the arm the board runs).
    #[arg(long = "arm", value_name = "ARM")]
    pub arm: Option<String>,
    /// Print the result as one line of JSON.
    #[arg(long)]
    pub json: bool,
}

impl LinkArgs {
    /// Refuses these options for a command that does not drive an arm.
    pub fn refuse_for_other_commands(&self) -> Result<()> {
        let given: Vec<&str> = [
            (self.port.is_some(), "--port"),
            (self.baud.is_some(), "--baud"),
            (self.sim, "--sim"),
            (self.arm.is_some(), "--arm"),
            (self.json, "--json"),
        ]
        .into_iter()
        .filter_map(|(given, name)| given.then_some(name))
        .collect();
        if !given.is_empty() {
            bail!(
                "{} before the command: only for move, joints, play, status, stop and torque (other commands take \
                 their options after the command name)",
                given.join(", ")
            );
        }
        Ok(())
    }

    /// The board or simulation to connect to, and the arm to configure on it.
    fn target(&self) -> Result<(Target, Option<&str>)> {
        match (&self.port, self.sim) {
            (Some(path), false) => {
                Ok((Target::Port { path: path.clone(), baud: self.baud.unwrap_or(DEFAULT_BAUD) }, self.arm.as_deref()))
            }
            (None, true) if self.baud.is_some() => bail!("--baud is the baud rate of --port; --sim has none"),
            (None, true) => {
                let arm = self.arm.as_deref().unwrap_or(DEFAULT_SIM_ARM);
                Ok((Target::Sim(crate::sil::SilOptions::new(arm)?), Some(arm)))
            }
            (Some(_), true) => bail!("--port and --sim exclude each other: give one"),
            (None, false) if self.baud.is_some() => bail!("--baud is the baud rate of --port, which is missing"),
            (None, false) => bail!(
                "this command drives an arm: give --port PORT (a board running the firmware) or --sim (the simulated \
                 arm) before it, e.g. `armctl --sim status`"
            ),
        }
    }
}

/// The arm-driving commands.
#[derive(Subcommand, Debug)]
pub enum DriveCommand {
    /// Move the tool to a point (and orientation) along a straight line, IK on the firmware.
    ///
    /// Switches torque on if it is off. Waits until the arm is at rest and prints the target,
    /// the position reached (forward kinematics of the measured joints), the error and the time;
    /// Ctrl-C stops the arm.
    Move(MoveArgs),
    /// Move the joints to values (all joints arrive together, at rest).
    ///
    /// Switches torque on if it is off. Waits until the arm is at rest; Ctrl-C stops the arm.
    Joints(JointsArgs),
    /// Play a keyframe file, joint or Cartesian, with a progress bar.
    ///
    /// Joint keyframes have the header t,q1,...,qN[,v1,...,vN], as for `armctl trajectory sample`;
    /// Cartesian ones t,x,y,z or t,x,y,z,qw,qx,qy,qz (metres, unit quaternion w first; IK on the
    /// firmware). The header tells the format. The whole file is checked before anything is sent;
    /// the keyframes are streamed with flow control. Ctrl-C stops the arm.
    Play(PlayArgs),
    /// The controller's state: run state, joints, queue, IK, loop timing, error counters.
    Status,
    /// Stop: decelerate within the limits, drop queued keyframes and hold.
    Stop,
    /// Torque on (hold the present position; also leaves an emergency stop) or off (limp).
    Torque {
        /// on or off.
        #[arg(value_enum)]
        state: OnOff,
    },
}

/// `torque on|off`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum OnOff {
    /// Torque on.
    On,
    /// Torque off.
    Off,
}

/// `armctl move`.
#[derive(Args, Debug)]
pub struct MoveArgs {
    /// Tool position x,y,z (m, base frame).
    #[arg(long, allow_hyphen_values = true)]
    pub to: String,
    /// Tool orientation as a unit quaternion w,x,y,z (omit to leave it free).
    #[arg(long, allow_hyphen_values = true)]
    pub quat: Option<String>,
    /// Tool speed along the line (m/s) [default: 0.1].
    #[arg(long, conflicts_with = "duration", allow_hyphen_values = true)]
    pub speed: Option<f64>,
    /// Arrive after this many seconds (joint limits permitting).
    #[arg(long, allow_hyphen_values = true)]
    pub duration: Option<f64>,
    /// Give up waiting (and stop the arm) after this many seconds of controller time.
    #[arg(long, default_value_t = 60.0)]
    pub timeout: f64,
}

/// `armctl joints`.
#[derive(Args, Debug)]
pub struct JointsArgs {
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

/// `armctl play`.
#[derive(Args, Debug)]
pub struct PlayArgs {
    /// Keyframe CSV file.
    pub file: PathBuf,
    /// Give up waiting (and stop the arm) this many seconds of controller time after the last
    /// keyframe's time.
    #[arg(long, default_value_t = 30.0)]
    pub timeout: f64,
}

/// Runs an arm-driving command; returns the exit code.
pub fn run(link: &LinkArgs, command: DriveCommand, out: &mut dyn Write, err: &mut dyn Write) -> Result<i32> {
    // Everything the user typed is checked before connecting, so bad input changes nothing.
    let request = commands::Request::parse(&command)?;
    let (target, arm) = link.target()?;
    let mut driver = super::session::Driver::open(target, arm)?;
    commands::run(&mut driver, request, link.json, out, err)
}
