//! The pairs never checked, found by sampling as MoveIt's setup assistant finds its
//! allowed-collision matrix: two bodies closer than the margin at the zero pose, or in more than
//! [`SHARE`] of [`SAMPLES`] random poses within the joint limits, are neighbours that a check
//! would always stop (a joint's two sides, a motor in its holder); a body closer than the margin
//! to an obstacle at the zero pose stands on it (the base on the table). Two bodies on one frame
//! never move apart and are never checked, so they are not listed.
//!
//! The sampled rule is kept to bodies at most [`REACH`] joints apart along the chain (a joint's
//! two sides, or a short link's two neighbours). Farther pairs that touch in many random poses
//! are the arm folding onto itself, which is what the check is for: on the SO-101 the gripper
//! reaches the base in 8 % of them, and allowing that pair would let a move drive it there.

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
/// The most joints between two bodies the sampled rule allows.
pub const REACH: usize = 2;

/// The allowed pairs found, by the reason they were found for.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Found {
    /// Bodies closer than the margin at the zero pose.
    pub at_zero: Vec<[String; 2]>,
    /// Bodies at most [`REACH`] joints apart, closer than the margin in more than [`SHARE`] of the
    /// samples, with that share.
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
    let (at_zero, standing) = touching_at_zero(arm, spec)?;
    let bodies = &spec.bodies;
    let name = |i: usize| bodies[i].name.clone();
    let pairs: Vec<(usize, usize)> = body_pairs(bodies)
        .filter(|p| !at_zero.contains(&[name(p.0), name(p.1)]))
        .filter(|&(i, j)| joints_between(&bodies[i], &bodies[j]) <= REACH)
        .collect();
    let mut counts = vec![0usize; pairs.len()];
    let mut rng = SplitMix64::new(SEED);
    for _ in 0..SAMPLES {
        let at = placed(bodies, &model.joint_frames(&model.random_configuration(&mut rng))?);
        for (count, &(i, j)) in counts.iter_mut().zip(&pairs) {
            *count += usize::from(capsule_capsule(&at[i], &at[j]) < spec.margin);
        }
    }
    let often = pairs
        .iter()
        .zip(counts)
        .map(|(&(i, j), count)| ([name(i), name(j)], count as f64 / SAMPLES as f64))
        .filter(|(_, share)| *share > SHARE)
        .collect();
    Ok(Found { at_zero, often, standing })
}

/// The pairs of bodies on different frames, and of a body and an obstacle, closer than the
/// margin at the zero pose: the first are neighbours, the second what the arm stands on.
#[allow(clippy::type_complexity)]
pub fn touching_at_zero(arm: &ArmSpec, spec: &CollisionSpec) -> Result<(Vec<[String; 2]>, Vec<[String; 2]>)> {
    let frames = crate::dof::build(arm.clone())?.joint_frames(&zero_pose(arm))?;
    let zero = placed(&spec.bodies, &frames);
    let name = |i: usize| spec.bodies[i].name.clone();
    let bodies = body_pairs(&spec.bodies)
        .filter(|&(i, j)| capsule_capsule(&zero[i], &zero[j]) < spec.margin)
        .map(|(i, j)| [name(i), name(j)])
        .collect();
    let mut standing = Vec::new();
    for (i, capsule) in zero.iter().enumerate() {
        for obstacle in spec.obstacles.iter().filter(|o| distance(capsule, &o.shape) < spec.margin) {
            standing.push([name(i), obstacle.name.clone()]);
        }
    }
    Ok((bodies, standing))
}

/// The pairs of bodies on different frames (those on one frame are never checked).
fn body_pairs(bodies: &[BodySpec]) -> impl Iterator<Item = (usize, usize)> + '_ {
    (0..bodies.len())
        .flat_map(move |i| ((i + 1)..bodies.len()).map(move |j| (i, j)))
        .filter(|&(i, j)| bodies[i].link != bodies[j].link)
}

/// How many joints lie between the frames of two bodies of a chain.
fn joints_between(a: &BodySpec, b: &BodySpec) -> usize {
    let frame = |body: &BodySpec| body.link.map_or(0, |l| l + 1);
    frame(a).abs_diff(frame(b))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::collision::{ObstacleSpec, DEFAULT_MARGIN, TABLE};
    use kinematics::collision::Shape;
    use kinematics::nalgebra::Vector3;

    /// A pan on a post, an arm pitching about y, and a hand rolling at the arm's end: the arm
    /// folds down onto the post over half its pitch range, and the hand with it.
    #[test]
    fn neighbours_are_found_and_far_pairs_are_not() {
        let joint = |name: &str, xyz: &str, axis: &str, limits: &str| {
            format!(
                "[[joint]]\nname = \"{name}\"\ntype = \"revolute\"\nxyz = {xyz}\naxis = {axis}\nlimits = {limits}\n"
            )
        };
        let text = format!(
            "name = \"t\"\n{}{}{}",
            joint("pan", "[0, 0, 0.1]", "[0, 0, 1]", "[-3, 3]"),
            joint("pitch", "[0, 0, 0.05]", "[0, 1, 0]", "[-0.3, 2.9]"),
            joint("roll", "[0.2, 0, 0]", "[1, 0, 0]", "[-3, 3]")
        );
        let arm = crate::toml_file::parse(&text).unwrap();
        let capsule = |a: [f64; 3], b: [f64; 3], radius| Capsule { a: a.into(), b: b.into(), radius };
        let body = |name: &str, link, c| BodySpec { name: name.into(), link, capsule: c };
        let spec = CollisionSpec {
            margin: DEFAULT_MARGIN,
            bodies: vec![
                body("post", None, capsule([0.0; 3], [0.0, 0.0, 0.1], 0.02)),
                body("turret", Some(0), capsule([0.0; 3], [0.0, 0.0, 0.03], 0.02)),
                body("arm", Some(1), capsule([0.05, 0.0, 0.0], [0.17, 0.0, 0.0], 0.015)),
                body("hand", Some(2), capsule([0.0; 3], [-0.1, 0.0, 0.0], 0.02)),
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
        let pair = |a: &str, b: &str| [a.to_string(), b.to_string()];
        // post and turret touch at zero (one on the other), and arm and hand (a joint's sides);
        // the post's foot is on the table; nothing is near the far box.
        assert_eq!(found.at_zero, [pair("post", "turret"), pair("arm", "hand")]);
        assert_eq!(found.standing, [pair("post", TABLE)]);
        // Pitched past about 1.3 rad (by hand: 0.17 sin q >= 0.05 and 0.17 cos q < 0.045 + the
        // margin), the arm's end is at the post: two joints apart, in about half the samples,
        // allowed; pitched down at all, its root nears the turret (one joint apart). The hand
        // follows the arm onto the post, but three joints from it: the arm folded onto itself,
        // which stays checked.
        let often: Vec<&[String; 2]> = found.often.iter().map(|(p, _)| p).collect();
        assert_eq!(often, [&pair("post", "arm"), &pair("turret", "arm")], "{found:?}");
        let share = found.often[0].1;
        assert!((0.45..0.65).contains(&share), "{share}");
        assert_eq!(found.pairs().len(), 5);
    }
}
