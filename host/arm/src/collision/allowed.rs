//! The pairs never checked, found by sampling as MoveIt's setup assistant finds its
//! allowed-collision matrix: two bodies closer than the margin at the zero pose, or in more than
//! [`SHARE`] of [`SAMPLES`] random poses within the joint limits, are neighbours that a check
//! would always stop (a joint's two sides, a motor in its holder); a body closer than the margin
//! to an obstacle at the zero pose stands on it (the base on the table). Two bodies on one frame
//! never move apart and are never checked, so they are not listed.

use anyhow::Result;
use kinematics::collision::distance::{capsule_capsule, distance};
use kinematics::collision::Capsule;
use kinematics::{Pose, SplitMix64};

use super::{BodySpec, CollisionSpec};
use crate::ArmSpec;

/// Random poses sampled.
pub const SAMPLES: usize = 2000;
/// The share of them a pair must touch in to be neighbours.
pub const SHARE: f64 = 0.05;
/// The sampler's seed: the same arm gives the same table every time.
pub const SEED: u64 = 45;

/// The allowed pairs found, by the reason they were found for.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Found {
    /// Bodies closer than the margin at the zero pose.
    pub at_zero: Vec<[String; 2]>,
    /// Bodies closer than the margin in more than [`SHARE`] of the samples, with that share.
    pub often: Vec<([String; 2], f64)>,
    /// A body and an obstacle it rests on at the zero pose.
    pub standing: Vec<[String; 2]>,
}

impl Found {
    /// Every pair, in the order found.
    pub fn pairs(&self) -> Vec<[String; 2]> {
        let often = self.often.iter().map(|(pair, _)| pair.clone());
        self.at_zero.iter().cloned().chain(often).chain(self.standing.iter().cloned()).collect()
    }
}

/// The zero pose, each joint's zero brought inside its limits: where an arm file's bodies must
/// be free of each other.
pub fn zero_pose(arm: &ArmSpec) -> Vec<f64> {
    arm.joints.iter().map(|j| if j.lower <= j.upper { 0.0f64.clamp(j.lower, j.upper) } else { 0.0 }).collect()
}

/// Each body of `bodies` placed at the joint frames `frames`.
pub fn placed(bodies: &[BodySpec], frames: &[Pose<f64>]) -> Vec<Capsule<f64>> {
    bodies
        .iter()
        .map(|b| match b.link.and_then(|l| frames.get(l)) {
            Some(pose) => b.capsule.placed(pose),
            None => b.capsule,
        })
        .collect()
}

/// The pairs of `spec`'s bodies and obstacles that are neighbours on `arm` (`spec.allowed` is
/// not read: the table is made anew).
pub fn find(arm: &ArmSpec, spec: &CollisionSpec) -> Result<Found> {
    let model = crate::dof::build(arm.clone())?;
    let bodies = &spec.bodies;
    let pairs: Vec<(usize, usize)> = (0..bodies.len())
        .flat_map(|i| ((i + 1)..bodies.len()).map(move |j| (i, j)))
        .filter(|&(i, j)| bodies[i].link != bodies[j].link)
        .collect();
    let name = |i: usize| bodies[i].name.clone();
    let zero = placed(bodies, &model.joint_frames(&zero_pose(arm))?);
    let mut found = Found::default();
    let touching =
        |placed: &[Capsule<f64>], (i, j): (usize, usize)| capsule_capsule(&placed[i], &placed[j]) < spec.margin;
    let mut counts = vec![0usize; pairs.len()];
    let mut rng = SplitMix64::new(SEED);
    for _ in 0..SAMPLES {
        let at = placed(bodies, &model.joint_frames(&model.random_configuration(&mut rng))?);
        for (count, pair) in counts.iter_mut().zip(&pairs) {
            *count += usize::from(touching(&at, *pair));
        }
    }
    for (pair, count) in pairs.iter().zip(counts) {
        let share = count as f64 / SAMPLES as f64;
        if touching(&zero, *pair) {
            found.at_zero.push([name(pair.0), name(pair.1)]);
        } else if share > SHARE {
            found.often.push(([name(pair.0), name(pair.1)], share));
        }
    }
    for (i, capsule) in zero.iter().enumerate() {
        for obstacle in &spec.obstacles {
            if distance(capsule, &obstacle.shape) < spec.margin {
                found.standing.push([name(i), obstacle.name.clone()]);
            }
        }
    }
    Ok(found)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::collision::{ObstacleSpec, DEFAULT_MARGIN, TABLE};
    use kinematics::collision::Shape;
    use kinematics::nalgebra::Vector3;

    /// A two-joint arm: a pan on a post, a 0.2 m arm pitching about y; an elbow stub that is
    /// always within 5 mm of the arm's root; a tip that reaches the post only when pitched far.
    #[test]
    fn neighbours_are_found_and_far_pairs_are_not() {
        let text = "name = \"t\"\n[[joint]]\nname = \"pan\"\ntype = \"revolute\"\nxyz = [0, 0, 0.1]\naxis = [0, 0, 1]\nlimits = [-3, 3]\n[[joint]]\nname = \"pitch\"\ntype = \"revolute\"\nxyz = [0, 0, 0.05]\naxis = [0, 1, 0]\nlimits = [-0.3, 2.9]\n";
        let arm = crate::toml_file::parse(text).unwrap();
        let capsule = |a: [f64; 3], b: [f64; 3], radius| Capsule { a: a.into(), b: b.into(), radius };
        let body = |name: &str, link, c| BodySpec { name: name.into(), link, capsule: c };
        let spec = CollisionSpec {
            margin: DEFAULT_MARGIN,
            bodies: vec![
                body("post", None, capsule([0.0; 3], [0.0, 0.0, 0.1], 0.02)),
                body("turret", Some(0), capsule([0.0; 3], [0.0, 0.0, 0.03], 0.02)),
                body("arm", Some(1), capsule([0.05, 0.0, 0.0], [0.2, 0.0, 0.0], 0.015)),
            ],
            obstacles: vec![
                ObstacleSpec { name: TABLE.into(), shape: Shape::table(0.0) },
                ObstacleSpec {
                    name: "far".into(),
                    shape: Shape::aligned_box(Vector3::new(1.0, 1.0, 1.0), Vector3::repeat(0.1)),
                },
            ],
            allowed: vec![],
        };
        let found = find(&arm, &spec).unwrap();
        // post and turret touch at zero (one on the other); the post's foot is on the table.
        assert_eq!(found.at_zero, [["post".to_string(), "turret".to_string()]]);
        assert_eq!(found.standing, [["post".to_string(), TABLE.to_string()]]);
        // The arm pitched down past ~1.9 rad folds onto the post: about a third of the range,
        // far more than 5 %; turret and arm start 15 mm apart at the pitch joint and close in
        // as the arm folds down too.
        let often: Vec<&str> = found.often.iter().map(|(p, _)| p[1].as_str()).collect();
        assert!(often.contains(&"arm"), "{found:?}");
        assert!(found.often.iter().all(|(_, share)| *share > SHARE && *share <= 1.0), "{found:?}");
        assert_eq!(found.pairs().len(), found.at_zero.len() + found.often.len() + found.standing.len());
    }
}
