//! The arm-driving commands on the command line: what was typed becomes a typed operation
//! ([`crate::commands::drive::Operation`]) before anything is connected, so bad input changes nothing; its
//! report is printed as text or as one line of JSON.

use std::io::Write;

use anyhow::{bail, Result};
use firmware::link::message::MovePath;

use crate::commands::drive::args::{DriveCommand, GripperAction, JointsArgs, LinkArgs, MoveArgs, OnOff};
use crate::commands::drive::gripper::{GripperGoal, GripperRequest};
use crate::commands::drive::joints::JointsRequest;
use crate::commands::drive::move_to::MoveRequest;
use crate::commands::drive::play::Plan;
use crate::commands::drive::Operation;
use crate::support::numbers as parse;

/// Runs an arm-driving command; returns the exit code.
pub fn run(link: &LinkArgs, command: DriveCommand, out: &mut dyn Write, err: &mut dyn Write) -> Result<i32> {
    // Everything the user typed is checked before connecting, so bad input changes nothing.
    let link = link.merged(command.link())?;
    let operation = operation(&command)?;
    crate::commands::drive::run(&link, &operation, out, err)
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
