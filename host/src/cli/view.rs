//! `armctl view` on the command line: its options, the drive options merged from before and after
//! the command and refused where the view has no use for them, then [`crate::view::run`] (one arm)
//! or [`crate::view::rig::run`] (`--rig`) with a plain [`ViewRequest`].

use std::io::Write;
use std::path::PathBuf;

use anyhow::{bail, Result};
use clap::Args;

use super::link::LinkArgs;
use crate::view::{ViewRequest, DEFAULT_LISTEN};

/// `armctl view`.
#[derive(Args, Debug)]
pub struct ViewArgs {
    #[command(flatten)]
    #[allow(missing_docs)]
    pub link: LinkArgs,
    /// Serve the page on this address and port. The default serves this machine only; any other
    /// address lets whoever has the URL move the arm, and plain HTTP shows the token to the
    /// network (an SSH tunnel is the safe way in from another machine). Port 0 picks a free one.
    #[arg(long, value_name = "ADDR:PORT", default_value = DEFAULT_LISTEN)]
    pub listen: String,
    /// The API's token (at least 32 letters, digits or -._~) instead of a random one drawn for
    /// this run. Other users of this machine can read a command line: prefer the random one.
    #[arg(long, value_name = "TOKEN")]
    pub token: Option<String>,
    /// Draw this URDF's visual meshes (STL) over the chain; its moving joints must be the arm's.
    #[arg(long, value_name = "FILE.urdf")]
    pub urdf: Option<PathBuf>,
    /// The link the --urdf chain ends at, where the URDF has several leaves (the SO-101's:
    /// gripper_frame_link).
    #[arg(long, value_name = "LINK", requires = "urdf")]
    pub tip: Option<String>,
}

/// Runs `armctl view` until Ctrl-C; `global` are the drive options given before the command.
/// Returns the exit code.
pub fn run(global: &LinkArgs, args: ViewArgs, out: &mut dyn Write, err: &mut dyn Write) -> Result<i32> {
    // Everything the user typed is checked before anything is opened.
    let link = global.merged(&args.link)?;
    let request = ViewRequest { listen: args.listen, token: args.token, urdf: args.urdf, tip: args.tip };
    if let Some(rig) = &link.rig {
        refuse_one_arm_options(&link, &request)?;
        return crate::view::rig::run(rig, link.json, &request, out, err);
    }
    if link.object_mm.is_some() {
        bail!("--object-mm: the view's simulated arm has no object between its jaws");
    }
    crate::view::run(&link.place()?, link.json, &request, out, err)
}

/// Refuses the options that name one arm's place or drawing beside `--rig`: a rig's arms are in
/// its file.
fn refuse_one_arm_options(link: &LinkArgs, request: &ViewRequest) -> Result<()> {
    let mut given = link.one_arm_options();
    given.extend(
        [(request.urdf.is_some(), "--urdf"), (request.tip.is_some(), "--tip")]
            .into_iter()
            .filter_map(|(g, n)| g.then_some(n)),
    );
    if !given.is_empty() {
        bail!(
            "{} with --rig: each arm's place and model are in the rig file; `armctl view --rig RIG` takes --listen \
             and --token",
            given.join(", ")
        );
    }
    Ok(())
}
