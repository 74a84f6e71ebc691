//! An arm's collision geometry as the host keeps it: named bodies on named links, named
//! obstacles (the table under a preset by default), the pairs never checked, and the margin;
//! from the arm file or the presets' tables (see [`collision_of`]), turned into the kinematics
//! crate's fixed-size [`Scene`] for the host's checks and sent to the firmware with the arm.

pub mod allowed;
pub mod edit;
pub mod fit;
pub mod obstacle;
pub mod reach;
pub mod stl;
pub mod toml;
pub mod urdf;
pub mod validate;

use anyhow::{anyhow, bail, Result};
use kinematics::collision::{Body, Capsule, Contact, Part, Scene, Shape};
use kinematics::Real;

use crate::ArmSpec;

/// The most bodies a firmware (and so an arm file) holds.
pub const MAX_BODIES: usize = 24;
/// The most obstacles a firmware holds.
pub const MAX_OBSTACLES: usize = 8;
/// The distance kept between checked pairs when the arm file names none (m).
pub const DEFAULT_MARGIN: f64 = 0.01;
/// The name of the table every preset stands on unless told otherwise.
pub const TABLE: &str = "table";

/// A body of the arm: a capsule (or a sphere) in the frame of a joint after its motion, or of
/// the base.
#[derive(Clone, Debug, PartialEq)]
pub struct BodySpec {
    /// Its name, as errors and the view show it (`gripper`, `upper_arm`, ...).
    pub name: String,
    /// The joint whose moving frame carries it (index into [`ArmSpec::joints`]); `None`: the base.
    pub link: Option<usize>,
    /// The capsule in that frame.
    pub capsule: Capsule<f64>,
}

/// Something around the arm, in its base frame.
#[derive(Clone, Debug, PartialEq)]
pub struct ObstacleSpec {
    /// Its name (`table`, `box`, ...).
    pub name: String,
    /// Its shape, base frame.
    pub shape: Shape<f64>,
}

/// Everything collision knows of an arm.
#[derive(Clone, Debug, PartialEq)]
pub struct CollisionSpec {
    /// The distance every checked pair keeps (m).
    pub margin: f64,
    /// The arm's bodies.
    pub bodies: Vec<BodySpec>,
    /// The surroundings.
    pub obstacles: Vec<ObstacleSpec>,
    /// Pairs never checked, by name: two bodies (neighbours that always touch), or a body and an
    /// obstacle (the base's foot on the table).
    pub allowed: Vec<[String; 2]>,
}

impl CollisionSpec {
    /// The index of the body or obstacle named `name`.
    pub fn part(&self, name: &str) -> Option<Part> {
        if let Some(i) = self.bodies.iter().position(|b| b.name == name) {
            return Some(Part::Body(i as u8));
        }
        self.obstacles.iter().position(|o| o.name == name).map(|o| Part::Obstacle(o as u8))
    }

    /// The name of a part.
    pub fn name(&self, part: Part) -> &str {
        let name = match part {
            Part::Body(i) => self.bodies.get(usize::from(i)).map(|b| b.name.as_str()),
            Part::Obstacle(o) => self.obstacles.get(usize::from(o)).map(|o| o.name.as_str()),
        };
        name.unwrap_or("?")
    }

    /// "gripper and table are 3.2 mm apart (margin 10 mm)", or "... overlap by 4.0 mm".
    pub fn describe<T: Real>(&self, contact: &Contact<T>) -> String {
        let (a, b) = (self.name(Part::Body(contact.body)), self.name(contact.other));
        let mm = contact.distance.to_f64() * 1e3;
        let margin = self.margin * 1e3;
        if mm < 0.0 {
            format!("{a} and {b} overlap by {:.1} mm (margin {margin:.0} mm)", -mm)
        } else if mm.is_nan() {
            format!("{a} and {b}: their distance is not a number")
        } else {
            format!("{a} and {b} are {mm:.1} mm apart (margin {margin:.0} mm)")
        }
    }

    /// The same geometry without any obstacle: the arm's own bodies only.
    pub fn without_obstacles(mut self) -> Self {
        let obstacles: Vec<String> = self.obstacles.iter().map(|o| o.name.clone()).collect();
        for name in obstacles {
            self = self.without(&name);
        }
        self
    }

    /// The same geometry without the obstacle named `name` (`--no-table`).
    pub fn without(mut self, name: &str) -> Self {
        self.obstacles.retain(|o| o.name != name);
        self.allowed.retain(|pair| pair.iter().all(|n| n != name));
        self
    }

    /// The fixed-size scene for an arm of `joints` joints, in `T`, with `B` bodies and `O`
    /// obstacles at most; fails naming what does not fit or is not valid.
    pub fn scene<T: Real, const B: usize, const O: usize>(&self, joints: usize) -> Result<Scene<T, B, O>> {
        if self.bodies.len() > B.min(MAX_BODIES) {
            bail!("{} collision bodies: at most {} are held", self.bodies.len(), B.min(MAX_BODIES));
        }
        if self.obstacles.len() > O.min(MAX_OBSTACLES) {
            bail!("{} obstacles: at most {} are held", self.obstacles.len(), O.min(MAX_OBSTACLES));
        }
        if !(self.margin.is_finite() && self.margin >= 0.0) {
            bail!("the collision margin {} is not a distance of zero or more", self.margin);
        }
        let mut scene = Scene::new(T::of(self.margin));
        for body in &self.bodies {
            let capsule = Capsule {
                a: body.capsule.a.map(T::of),
                b: body.capsule.b.map(T::of),
                radius: T::of(body.capsule.radius),
            };
            let frame = body.link.map(|l| l.min(255) as u8);
            scene
                .add_body(Body { frame, capsule }, joints)
                .map_err(|e| anyhow!("collision body {}: {e}", body.name))?;
        }
        for obstacle in &self.obstacles {
            scene.add_obstacle(cast_shape(&obstacle.shape)).map_err(|e| anyhow!("obstacle {}: {e}", obstacle.name))?;
        }
        for [a, b] in &self.allowed {
            let (pa, pb) = (self.part(a), self.part(b));
            let (body, other) = match (pa, pb) {
                (Some(Part::Body(i)), Some(other)) => (i, other),
                (Some(other), Some(Part::Body(i))) => (i, other),
                (None, _) => bail!("allowed pair {a} and {b}: no body or obstacle is named {a}"),
                (_, None) => bail!("allowed pair {a} and {b}: no body or obstacle is named {b}"),
                _ => bail!("allowed pair {a} and {b}: two obstacles are never checked anyway"),
            };
            scene.allow(body, other).map_err(|e| anyhow!("allowed pair {a} and {b}: {e}"))?;
        }
        Ok(scene)
    }
}

/// `shape` in scalar `T`.
pub fn cast_shape<T: Real>(shape: &Shape<f64>) -> Shape<T> {
    match shape {
        Shape::Capsule(c) => Shape::Capsule(Capsule { a: c.a.map(T::of), b: c.b.map(T::of), radius: T::of(c.radius) }),
        Shape::Box { centre, rotation, half } => {
            Shape::Box { centre: centre.map(T::of), rotation: rotation.map(T::of), half: half.map(T::of) }
        }
        Shape::HalfSpace { normal, offset } => Shape::HalfSpace { normal: normal.map(T::of), offset: T::of(*offset) },
    }
}

/// The collision geometry of `arm`: its own (the arm file's), else its preset's, else none.
pub fn collision_of(arm: &ArmSpec) -> Option<CollisionSpec> {
    arm.collision.clone()
}

impl CollisionSpec {
    /// Geometry measured from the arm's frames alone, for an arm whose meshes are not at hand: one
    /// capsule of `radius` per link, from its joint's origin to the next joint's (the last to the
    /// tool), named after the joint; the base a capsule from its origin to the first joint; the
    /// table at the base plane (`z = 0`). Neighbouring links share a joint, so each is allowed
    /// to touch the next, and the base's foot to stand on the table.
    pub fn from_frames(arm: &ArmSpec, radius: f64) -> Self {
        let next = |i: usize| arm.joints.get(i + 1).map_or(arm.tool.translation, |j| j.origin.translation);
        let origin = kinematics::nalgebra::Vector3::zeros();
        let mut bodies = vec![BodySpec {
            name: "base".into(),
            link: None,
            capsule: Capsule { a: origin, b: arm.joints.first().map_or(origin, |j| j.origin.translation), radius },
        }];
        bodies.extend(arm.joints.iter().enumerate().map(|(i, joint)| BodySpec {
            name: joint.name.clone(),
            link: Some(i),
            capsule: Capsule { a: origin, b: next(i), radius },
        }));
        let mut allowed: Vec<[String; 2]> =
            bodies.windows(2).map(|pair| [pair[0].name.clone(), pair[1].name.clone()]).collect();
        allowed.push(["base".into(), TABLE.into()]);
        Self {
            margin: DEFAULT_MARGIN,
            bodies,
            obstacles: vec![ObstacleSpec { name: TABLE.into(), shape: Shape::table(0.0) }],
            allowed,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use kinematics::nalgebra::SVector;

    #[test]
    fn capsules_from_frames_find_the_tool_below_the_table_and_not_at_the_middle() {
        let arm = crate::presets::by_name("so101").unwrap();
        let spec = CollisionSpec::from_frames(&arm, 0.02);
        let chain = arm.chain::<f64, 5>().unwrap();
        let mut scene = spec.scene::<f64, 24, 8>(5).unwrap();
        assert_eq!(scene.first_contact(&chain.forward(&SVector::zeros()).joints), None, "the zero pose is free");
        // Shoulder lift pitched forward and the elbow folded down: the wrist goes under z = 0.
        let low = chain.forward(&SVector::from([0.0, 1.6, 0.0, 0.0, 0.0]));
        let contact = scene.first_contact(&low.joints).expect("below the table");
        assert_eq!(spec.name(contact.other), TABLE, "{}", spec.describe(&contact));
    }
}
