//! Each arm of a rig is an obstacle for the others: every arm's bodies (its collision geometry,
//! [`geometry_of`]) placed by its forward kinematics and its base in the world frame, and every
//! pair of arms kept at least the larger of their two margins apart. The host checks it, as it
//! checks the rest first; an arm's firmware knows only its own arm and surroundings.
//!
//! - [`Clearance::closest`]: the two closest bodies of different arms at one set of joint values.
//! - [`timeline()`]: a rig's play, sampled on its one timeline as the players will play it; and
//!   where two arms would come too close, the keyframes that stop every arm short of it.
//!
//! An arm mounted on another (a shared joint) touches it where it is mounted: that pair of arms
//! is not checked. Two arms handing an object over ([`Rig::hands_meet`]) bring their hands
//! together: the bodies on each one's last joint are not checked against the other's.

pub mod timeline;

use anyhow::{anyhow, Result};
use kinematics::collision::distance::capsule_capsule;
use kinematics::collision::Capsule;
use kinematics::Pose;

use super::Rig;
use crate::arm::collision::edit::geometry_of;
use crate::arm::collision::CollisionSpec;
use crate::arm::dof::DynArm;
use crate::arm::ArmSpec;

pub use timeline::{timeline, Collision, Verdict};

/// Two arms' closest bodies.
#[derive(Clone, Debug, PartialEq)]
pub struct Near {
    /// The two arms, by index in the rig.
    pub arms: [usize; 2],
    /// Their bodies, each as `ARM/BODY`.
    pub bodies: [String; 2],
    /// The distance between them (m); negative when they overlap.
    pub distance: f64,
    /// The distance they must keep (m).
    pub margin: f64,
}

impl Near {
    /// "left/gripper and right/gripper are 4.1 mm apart (margin 10 mm)", or "... overlap by ...".
    pub fn describe(&self) -> String {
        let [a, b] = &self.bodies;
        let (mm, margin) = (self.distance * 1e3, self.margin * 1e3);
        if mm < 0.0 {
            format!("{a} and {b} overlap by {:.1} mm (margin {margin:.0} mm)", -mm)
        } else {
            format!("{a} and {b} are {mm:.1} mm apart (margin {margin:.0} mm)")
        }
    }

    /// Whether they are closer than the margin.
    pub fn too_close(&self) -> bool {
        // A NaN distance is never apart.
        self.distance < self.margin || self.distance.is_nan()
    }
}

/// Every arm's bodies, and how the arms' bases hang together.
pub struct Clearance {
    names: Vec<String>,
    models: Vec<Box<dyn DynArm>>,
    specs: Vec<CollisionSpec>,
    bases: Vec<Pose<f64>>,
    mounts: Vec<Option<usize>>,
    hands_meet: Vec<[usize; 2]>,
}

impl Clearance {
    /// The bodies of every arm of `rig`.
    pub fn of(rig: &Rig) -> Result<Self> {
        let arms: Vec<(String, ArmSpec, Pose<f64>, Option<usize>)> =
            rig.arms.iter().map(|a| (a.name.clone(), a.driver.arm().clone(), a.base, a.mount)).collect();
        Self::new(arms, rig.hands_meet.clone())
    }

    /// The bodies of arms given by name, description, base and mount (the arm carrying the base,
    /// by index), and the pairs whose hands may meet.
    pub fn new(arms: Vec<(String, ArmSpec, Pose<f64>, Option<usize>)>, hands_meet: Vec<[usize; 2]>) -> Result<Self> {
        let mut clearance = Self {
            names: Vec::new(),
            models: Vec::new(),
            specs: Vec::new(),
            bases: Vec::new(),
            mounts: Vec::new(),
            hands_meet,
        };
        for (name, arm, base, mount) in arms {
            clearance.specs.push(geometry_of(&arm));
            clearance.models.push(crate::arm::dof::build(arm)?);
            clearance.names.push(name);
            clearance.bases.push(base);
            clearance.mounts.push(mount);
        }
        Ok(clearance)
    }

    /// Whether body `a` of arm `i` and body `b` of arm `j` are both hands of arms whose hands meet.
    fn hands(&self, (i, a): (usize, usize), (j, b): (usize, usize)) -> bool {
        let hand = |arm: usize, body: usize| {
            let spec = &self.specs[arm];
            let last = spec.bodies.iter().filter_map(|b| b.link).max();
            spec.bodies.get(body).is_some_and(|b| b.link.is_some() && b.link == last)
        };
        self.hands_meet.iter().any(|p| *p == [i, j] || *p == [j, i]) && hand(i, a) && hand(j, b)
    }

    /// Whether arms `i` and `j` are checked against each other (neither is mounted on the other).
    fn checked(&self, i: usize, j: usize) -> bool {
        self.mounts.get(i).copied().flatten() != Some(j) && self.mounts.get(j).copied().flatten() != Some(i)
    }

    /// Every arm's bodies in the world frame with the arms at `q` (one row of joint values per
    /// arm; an arm without one, `None`, has no bodies: its place is not known).
    pub fn placed(&self, q: &[Option<Vec<f64>>]) -> Result<Vec<Vec<Capsule<f64>>>> {
        let mut world: Vec<Pose<f64>> = Vec::new();
        let mut placed = Vec::new();
        for (i, model) in self.models.iter().enumerate() {
            let name = &self.names[i];
            // A mounted arm's base rides on the tool of an earlier arm.
            let base = match self.mounts[i] {
                None => self.bases[i],
                Some(m) => {
                    let carrier = world.get(m).ok_or_else(|| anyhow!("arm {name} is mounted on a later arm"))?;
                    match q.get(m).and_then(Option::as_ref) {
                        Some(qm) => carrier.compose(&self.models[m].tool_pose(qm)?).compose(&self.bases[i]),
                        None => Pose::from_translation(kinematics::nalgebra::Vector3::repeat(f64::NAN)),
                    }
                }
            };
            world.push(base);
            let Some(qi) = q.get(i).and_then(Option::as_ref) else {
                placed.push(Vec::new());
                continue;
            };
            let frames = model.joint_frames(qi)?;
            let bodies = self.specs[i]
                .bodies
                .iter()
                .map(|b| {
                    let frame = match b.link {
                        None => base,
                        Some(l) => base.compose(frames.get(l).unwrap_or(&Pose::identity())),
                    };
                    b.capsule.placed(&frame)
                })
                .collect();
            placed.push(bodies);
        }
        Ok(placed)
    }

    /// The two closest bodies of two different arms (of the pairs checked), or `None` for a rig
    /// of one arm.
    pub fn closest(&self, placed: &[Vec<Capsule<f64>>]) -> Option<Near> {
        let mut best: Option<Near> = None;
        for i in 0..placed.len() {
            for j in (i + 1)..placed.len() {
                if !self.checked(i, j) {
                    continue;
                }
                let margin = self.specs[i].margin.max(self.specs[j].margin);
                for (a, ca) in placed[i].iter().enumerate() {
                    for (b, cb) in placed[j].iter().enumerate() {
                        if self.hands((i, a), (j, b)) {
                            continue;
                        }
                        let d = capsule_capsule(ca, cb);
                        // A NaN (a pose gone wrong) counts as touching, never as free.
                        let d = if d.is_nan() { f64::NEG_INFINITY } else { d };
                        if best.as_ref().is_none_or(|n| d - margin < n.distance - n.margin) {
                            best = Some(Near {
                                arms: [i, j],
                                bodies: [
                                    format!("{}/{}", self.names[i], self.specs[i].bodies[a].name),
                                    format!("{}/{}", self.names[j], self.specs[j].bodies[b].name),
                                ],
                                distance: d,
                                margin,
                            });
                        }
                    }
                }
            }
        }
        best
    }
}
