//! `armctl teleop`'s options, and what they become: the follower's place, the leader
//! ([`LeaderSpec`]) and the loop's settings for [`crate::commands::teleop`], or with `--rig` the
//! settings for [`crate::rig::teleop`], where each arm's leader is in the rig file.

use std::io::Write;
use std::path::PathBuf;

use anyhow::{bail, Result};
use clap::Args;

use super::link::LinkArgs;
use crate::cli::bus_args::ProtocolArg;
use crate::commands::teleop::{LoopSettings, TeleopRequest};
use crate::motion::teleop::leader::LeaderSpec;

/// `armctl teleop`.
#[derive(Args, Debug)]
pub struct TeleopArgs {
    #[command(flatten)]
    #[allow(missing_docs)]
    pub link: LinkArgs,
    /// The leader arm's serial port (its USB adapter), or `sim`: simulated leader servos, turned by
    /// --leader-script.
    #[arg(long, value_name = "PORT|sim")]
    pub leader: Option<String>,
    /// The leader's servo protocol [default: that of --leader-arm's servos].
    #[arg(long, value_enum)]
    pub leader_protocol: Option<ProtocolArg>,
    /// The leader arm: a preset or an arm file with a [servos] table.
    #[arg(long, value_name = "ARM", default_value = "so101")]
    pub leader_arm: String,
    /// A LeRobot calibration file (JSON) of the leader's servos.
    #[arg(long, value_name = "FILE")]
    pub leader_calibration: Option<PathBuf>,
    /// The leader bus's baud rate [default: the leader arm file's].
    #[arg(long)]
    pub leader_baud: Option<u32>,
    /// With --leader sim: the path the hand moves the leader along, a joint keyframe file
    /// (t,q1,...,qN[,gripper], as for `armctl play`), straight from keyframe to keyframe.
    #[arg(long, value_name = "FILE")]
    pub leader_script: Option<PathBuf>,
    /// Keyframes per second.
    #[arg(long, default_value_t = 100.0)]
    pub rate: f64,
    /// How long after its reading a keyframe is played on the follower, ms [default: one period
    /// plus 8].
    #[arg(long, value_name = "MS")]
    pub lead_ms: Option<f64>,
    /// Largest change of a joint from one keyframe to the next, rad (LeRobot's
    /// max_relative_target) [default: the follower's speed limit over one period].
    #[arg(long, value_name = "RAD")]
    pub max_step: Option<f64>,
    /// End after this many seconds [default: at Ctrl-C; with --leader sim, when the script ends].
    #[arg(long, value_name = "S")]
    pub duration: Option<f64>,
    /// Write the session as a joint keyframe file that `armctl play` replays.
    #[arg(long, value_name = "FILE.csv")]
    pub record: Option<PathBuf>,
}

impl TeleopArgs {
    /// The loop's settings, checked.
    fn settings(&self) -> Result<LoopSettings> {
        LoopSettings::new(self.rate, self.lead_ms, self.max_step, self.duration)
    }

    /// Whether any option of the leader's own is given (with `--rig`, the file names each arm's).
    fn names_a_leader(&self) -> bool {
        self.leader.is_some()
            || self.leader_protocol.is_some()
            || self.leader_calibration.is_some()
            || self.leader_baud.is_some()
            || self.leader_script.is_some()
    }

    /// The leader the options name, checked.
    fn leader(&self) -> Result<LeaderSpec> {
        let Some(port) = self.leader.clone() else {
            bail!("--leader PORT|sim is missing: the leader arm's serial port, or sim with --leader-script");
        };
        match (port == "sim", &self.leader_script) {
            (true, None) => {
                bail!("--leader sim needs --leader-script FILE: the path the simulated hand moves it along")
            }
            (false, Some(_)) => bail!("--leader-script moves a simulated leader: it needs --leader sim"),
            _ => {}
        }
        Ok(LeaderSpec {
            port,
            protocol: self.leader_protocol.map(Into::into),
            arm: self.leader_arm.clone(),
            calibration: self.leader_calibration.clone(),
            baud: self.leader_baud,
            script: self.leader_script.clone(),
        })
    }
}

/// Runs `armctl teleop` with the drive options given before it (`before`); returns the exit code.
pub fn run(before: &LinkArgs, args: TeleopArgs, out: &mut dyn Write, err: &mut dyn Write) -> Result<i32> {
    // Everything the user typed is checked before anything is opened.
    let link = before.merged(&args.link)?;
    if let Some(rig) = &link.rig {
        link.refuse_beside_rig()?;
        if args.names_a_leader() {
            bail!("with --rig, each arm's leader is in the rig file ([arm.leader]): give no --leader options");
        }
        if args.record.is_some() {
            bail!("--record with --rig is not built yet: record each pair with its own `armctl teleop`");
        }
        return crate::rig::teleop::run(rig, link.json, &args.settings()?, out, err);
    }
    let request = TeleopRequest { settings: args.settings()?, leader: args.leader()?, record: args.record.clone() };
    crate::commands::teleop::run(&link.place()?, link.json, &request, out, err)
}
