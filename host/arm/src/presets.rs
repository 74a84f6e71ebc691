//! The built-in arms by name.

use super::ArmSpec;
use anyhow::{anyhow, bail, Context, Result};
use kinematics::presets;

/// The preset names, for help and error messages.
pub const NAMES: &str = "planar:N (N = 0..=32), ur5e, puma560, iiwa14, so101, open-manipulator-x";

/// The preset called `name`.
pub fn by_name(name: &str) -> Result<ArmSpec> {
    let invalid = |e| anyhow!("preset {name} is invalid: {e}");
    if let Some(n) = name.strip_prefix("planar:") {
        let n: usize = n.parse().with_context(|| format!("planar:N needs a joint count, got {name:?}"))?;
        return super::dof::planar_spec(n);
    }
    Ok(match name {
        "ur5e" => ArmSpec::from_chain(name, &presets::ur5e().map_err(invalid)?),
        "puma560" => ArmSpec::from_chain(name, &presets::puma560().map_err(invalid)?),
        "iiwa14" => ArmSpec::from_chain(name, &presets::iiwa14().map_err(invalid)?),
        "so101" => named(
            ArmSpec::from_chain(name, &presets::so101().map_err(invalid)?),
            &["shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "wrist_roll"],
        ),
        "open-manipulator-x" => named(
            ArmSpec::from_chain(name, &presets::open_manipulator_x().map_err(invalid)?),
            &["joint1", "joint2", "joint3", "joint4"],
        ),
        _ => bail!("unknown arm {name:?}: use a preset ({NAMES}) or a path to a .urdf or .toml file"),
    })
}

fn named(mut spec: ArmSpec, names: &[&str]) -> ArmSpec {
    for (j, n) in spec.joints.iter_mut().zip(names) {
        j.name = (*n).to_string();
    }
    spec
}
