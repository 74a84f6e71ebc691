//! What makes an arm's collision geometry usable, checked where it is read (the arm file, a
//! preset's table): names unique, every shape valid and within the firmware's counts, every
//! allowed pair naming a body or obstacle, and the arm free of contacts at its zero pose, since
//! a table that finds the arm in contact at rest would refuse every move.

use anyhow::{bail, Result};

use super::{allowed::zero_pose, CollisionSpec, MAX_BODIES, MAX_OBSTACLES};
use crate::ArmSpec;

/// Fails with one line naming what is wrong with `spec` on `arm`.
pub fn check(arm: &ArmSpec, spec: &CollisionSpec) -> Result<()> {
    unique_names(spec)?;
    let mut scene = spec.scene::<f64, MAX_BODIES, MAX_OBSTACLES>(arm.dof())?;
    let frames = crate::dof::build(arm.clone())?.joint_frames(&zero_pose(arm))?;
    if let Some(contact) = scene.first_contact(&frames) {
        bail!(
            "at the zero pose {}: the collision geometry would refuse every move; allow the pair in \
             [[collision.allowed]] (`armctl collision fit` finds an arm's neighbours) or correct the bodies",
            spec.describe(&contact)
        );
    }
    Ok(())
}

/// Fails naming the first name that a body or an obstacle shares with another.
pub fn unique_names(spec: &CollisionSpec) -> Result<()> {
    let names = spec.bodies.iter().map(|b| &b.name).chain(spec.obstacles.iter().map(|o| &o.name));
    let mut seen = std::collections::BTreeSet::new();
    for name in names {
        if !seen.insert(name) {
            bail!("two collision bodies or obstacles are named {name}: names must differ");
        }
    }
    Ok(())
}
