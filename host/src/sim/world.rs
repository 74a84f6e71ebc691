//! The simulated arm in its surroundings: its collision geometry (bodies on its links, the table
//! and the obstacles, the pairs never checked) placed by forward kinematics of what its servos
//! hold, read through the same mapping from ticks to joint angles the firmware uses.
//!
//! Two questions are asked of it: do two bodies touch (a signed distance below zero: the
//! simulated link stops there, [`super::contact`]), and does a goal bring two bodies closer than
//! the margin (the safety monitor's rule, [`super::monitor::collision`]). The first is physics,
//! the second the contract every goal must keep.

use std::sync::Arc;

use anyhow::{anyhow, bail, Result};
use firmware::bus::mapping::JointMapping;
use kinematics::collision::{distance, Capsule, Contact, Part, Scene};
use kinematics::Pose;

use crate::arm::collision::reach::reach;
use crate::arm::collision::{CollisionSpec, MAX_BODIES, MAX_OBSTACLES};
use crate::arm::dof::{self, DynArm};
use crate::arm::servos::servos_of;
use crate::arm::ArmSpec;

/// A scene the size a firmware holds.
type ArmScene = Scene<f64, MAX_BODIES, MAX_OBSTACLES>;

/// An arm's geometry and its servos' mapping, for the simulator.
#[derive(Clone)]
pub struct World {
    arm: ArmSpec,
    geometry: CollisionSpec,
    model: Arc<dyn DynArm>,
    /// Per joint, base first: how its servo's ticks map to its angle (the servo's id included).
    mappings: Vec<JointMapping>,
    /// Margin zero: bodies that overlap touch.
    touching: ArmScene,
    /// The geometry's margin: what every goal must keep.
    near: ArmScene,
    /// The pairs checked.
    pairs: Vec<(u8, Part)>,
    /// Per joint, how far (m) any body moves at most per radian of it ([`reach`]).
    reach: Vec<f64>,
}

impl std::fmt::Debug for World {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("World").field("arm", &self.arm.name).field("geometry", &self.geometry).finish()
    }
}

impl PartialEq for World {
    fn eq(&self, other: &Self) -> bool {
        self.arm == other.arm && self.geometry == other.geometry
    }
}

/// The joint angle of `mapping`'s servo reporting `ticks` (fractional: between two whole ticks
/// the angle is interpolated, as the horn stands between them).
pub fn angle_of(mapping: &JointMapping, ticks: f64) -> f64 {
    let floor = ticks.floor();
    let whole = floor.clamp(f64::from(i32::MIN), f64::from(i32::MAX - 1)) as i32;
    let (a, b) = (mapping.to_radians::<f64>(whole), mapping.to_radians::<f64>(whole + 1));
    a + (ticks - floor) * (b - a)
}

impl World {
    /// `arm` (its servos from its `[servos]` table or its preset's) in `geometry`; fails naming
    /// what does not fit a firmware's scene, or an arm without servos.
    pub fn new(arm: &ArmSpec, geometry: CollisionSpec) -> Result<Self> {
        let servos = servos_of(arm).ok_or_else(|| anyhow!("arm {} has no [servos] table", arm.name))?;
        let n = arm.dof();
        let mappings: Vec<JointMapping> = (0..n).filter_map(|j| servos.mapping(j)).collect();
        if mappings.len() != n {
            bail!("arm {} has {n} joints but {} servo mappings", arm.name, mappings.len());
        }
        let near: ArmScene = geometry.scene(n)?;
        let mut touching = near.clone();
        touching.set_margin(0.0);
        let model = Arc::from(dof::build(arm.clone())?);
        let (bodies, obstacles) = (near.bodies().len() as u8, near.obstacles().len() as u8);
        let pairs = (0..bodies)
            .flat_map(|i| {
                ((i + 1)..bodies)
                    .map(move |j| (i, Part::Body(j)))
                    .chain((0..obstacles).map(move |o| (i, Part::Obstacle(o))))
            })
            .filter(|&(i, other)| !near.allowed(i, other))
            .collect();
        let reach = reach(arm, &geometry);
        Ok(Self { arm: arm.clone(), geometry, model, mappings, touching, near, pairs, reach })
    }

    /// `arm` in its own geometry ([`crate::arm::collision::collision_of`]); `None` when it has none.
    pub fn of(arm: &ArmSpec) -> Result<Option<Self>> {
        crate::arm::collision::collision_of(arm).map(|g| Self::new(arm, g)).transpose()
    }

    /// The geometry.
    pub fn geometry(&self) -> &CollisionSpec {
        &self.geometry
    }

    /// The arm.
    pub fn arm(&self) -> &ArmSpec {
        &self.arm
    }

    /// The joints' servo ids, base first.
    pub fn ids(&self) -> Vec<u8> {
        self.mappings.iter().map(|m| m.id).collect()
    }

    /// Joint `j`'s angle with its servo reporting `ticks` (fractional: between two whole ticks
    /// the angle is interpolated, as the horn stands between them).
    pub fn angle(&self, j: usize, ticks: f64) -> f64 {
        self.mappings.get(j).map_or(f64::NAN, |m| angle_of(m, ticks))
    }

    /// A bound on how far (m) any point of any body moves while each joint's servo travels at
    /// most `ticks[j]` ticks: the sum of each joint's reach times its angle's change.
    pub fn motion_bound(&self, ticks: &[f64]) -> f64 {
        ticks
            .iter()
            .enumerate()
            .map(|(j, t)| {
                let per_tick = (self.angle(j, 1.0) - self.angle(j, 0.0)).abs();
                self.reach.get(j).map_or(f64::INFINITY, |r| r * per_tick * t.abs())
            })
            .sum()
    }

    /// Each joint's moving frame at `q` (the frames bodies ride on); `None` for a `q` the arm
    /// cannot place (wrong length, not finite).
    fn frames(&self, q: &[f64]) -> Option<Vec<Pose<f64>>> {
        self.model.joint_frames(q).ok()
    }

    /// The first checked pair that overlaps at `q` (signed distance below zero).
    pub fn touching(&mut self, q: &[f64]) -> Option<Contact<f64>> {
        let frames = self.frames(q)?;
        self.touching.first_contact(&frames)
    }

    /// The first checked pair closer than the margin at `q`.
    pub fn within_margin(&mut self, q: &[f64]) -> Option<Contact<f64>> {
        let frames = self.frames(q)?;
        self.near.first_contact(&frames)
    }

    /// The closest checked pair at `q`.
    pub fn closest(&mut self, q: &[f64]) -> Option<Contact<f64>> {
        let frames = self.frames(q)?;
        self.near.closest(&frames)
    }

    /// Every pair the geometry checks (the allowed pairs and those on one frame left out), in a
    /// fixed order: the order of [`World::pair_distances`].
    pub fn pairs(&self) -> &[(u8, Part)] {
        &self.pairs
    }

    /// The signed distance of every checked pair at `q` ([`World::pairs`]; `None` when `q`
    /// cannot be placed).
    pub fn pair_distances(&self, q: &[f64]) -> Option<Vec<f64>> {
        let frames = self.frames(q)?;
        Some(self.pairs.iter().map(|&(body, other)| self.measure(&frames, body, other)).collect())
    }

    /// The signed distance of body `body` and `other` at `q` (NaN when `q` cannot be placed).
    pub fn distance(&self, q: &[f64], body: u8, other: Part) -> f64 {
        match self.frames(q) {
            Some(frames) => self.measure(&frames, body, other),
            None => f64::NAN,
        }
    }

    fn measure(&self, frames: &[Pose<f64>], body: u8, other: Part) -> f64 {
        let scene = &self.near;
        let place = |i: u8| -> Option<Capsule<f64>> {
            let b = scene.bodies().get(usize::from(i))?;
            match b.frame {
                None => Some(b.capsule),
                Some(f) => frames.get(usize::from(f)).map(|pose| b.capsule.placed(pose)),
            }
        };
        let Some(capsule) = place(body) else { return f64::NAN };
        match other {
            Part::Body(j) => place(j).map_or(f64::NAN, |q| distance::capsule_capsule(&capsule, &q)),
            Part::Obstacle(o) => {
                scene.obstacles().get(usize::from(o)).map_or(f64::NAN, |s| distance::distance(&capsule, s))
            }
        }
    }

    /// The two parts' names.
    pub fn names(&self, contact: &Contact<f64>) -> [String; 2] {
        [self.geometry.name(Part::Body(contact.body)).to_string(), self.geometry.name(contact.other).to_string()]
    }

    /// "gripper and table are 3.2 mm apart (margin 10 mm)".
    pub fn describe(&self, contact: &Contact<f64>) -> String {
        self.geometry.describe(contact)
    }

    /// The tool's position at `q` (m, base frame).
    pub fn tool(&self, q: &[f64]) -> Option<[f64; 3]> {
        let p = self.model.tool_pose(q).ok()?.translation;
        Some([p.x, p.y, p.z])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn so101() -> World {
        let arm = ArmSpec::load("so101", None).unwrap();
        World::new(&arm, CollisionSpec::from_frames(&arm, 0.02)).unwrap()
    }

    #[test]
    fn ticks_map_to_the_firmwares_angles_and_between_them_linearly() {
        let world = so101();
        let m = world.mappings[1];
        assert_eq!(world.angle(1, 3000.0), m.to_radians::<f64>(3000));
        let half = 0.5 * (m.to_radians::<f64>(3000) + m.to_radians::<f64>(3001));
        assert!((world.angle(1, 3000.5) - half).abs() < 1e-12);
        assert_eq!(world.ids(), [1, 2, 3, 4, 5]);
    }

    #[test]
    fn the_tool_below_the_table_touches_it_and_the_distances_agree() {
        let mut world = so101();
        let zero = [0.0; 5];
        assert_eq!(world.touching(&zero), None);
        assert!(world.within_margin(&zero).is_none());
        let low = [0.0, 1.6, 0.0, 0.0, 0.0];
        let contact = world.touching(&low).expect("below the table");
        assert_eq!(world.names(&contact)[1], "table");
        assert!(contact.distance < 0.0);
        assert!((world.distance(&low, contact.body, contact.other) - contact.distance).abs() < 1e-12);
        assert!(world.touching(&[0.0; 4]).is_none(), "a configuration the arm cannot place is not judged");
    }
}
