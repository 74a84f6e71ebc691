//! Planning around what is in the way: a collision-free joint-space path from where the arm is to
//! a free target whose straight joint segment is blocked, made into keyframes the firmware plays.
//!
//! 1. **RRT-Connect** (Kuffner and LaValle, ICRA 2000; as OMPL's `RRTConnect`): two trees, one
//!    from the start and one from the goal, within the joint limits. Each sample (uniform in the
//!    limits, from [`SplitMix64`] with a fixed seed, so a plan repeats) extends one tree a step
//!    towards it, and the other tree then greedily connects to the new node; the trees swap roles
//!    every sample. Every edge is a straight joint segment checked by [`Checker::straight`], so
//!    every point of it keeps the margin. A fixed budget of samples: past it the plan fails
//!    ("no collision-free path found in N samples").
//! 2. **Shortcutting**: every corner that can be skipped skipped (from the start, to the farthest
//!    corner in sight), after random pairs of points along the path (not only its corners) joined
//!    by a straight segment where that segment is free, if asked ([`DEFAULT_SHORTCUTS`]).
//! 3. **Keyframes**: one per corner, at rest there, each segment the player's rest-to-rest cubic
//!    (smoothstep) within the arm's velocity and acceleration limits. Every joint of such a
//!    segment follows the same smoothstep of its own change, so the played path is the straight
//!    segment between the corners, which was checked: nothing the player does between keyframes
//!    leaves it. [`check_keyframes`] checks the played Hermite segments again, densely.

use std::time::{Duration, Instant};

use anyhow::{bail, Result};
use kinematics::collision::{Part, Shape};
use kinematics::nalgebra::SVector;
use kinematics::nalgebra::Vector3;
use kinematics::trajectory::JointLimits;
use kinematics::SplitMix64;

use super::collision::{shown, Checker, Hermite, SegmentContact};
use crate::arm::collision::{collision_of, CollisionSpec, ObstacleSpec};
use crate::arm::dof::DynArm;

/// Samples RRT-Connect draws before it gives up.
pub const DEFAULT_SAMPLES: usize = 4000;
/// The seed of the sampler: a plan repeats.
pub const DEFAULT_SEED: u64 = 0x5eed_a11e;
/// The longest step a tree extends by (rad, Euclidean in joint space).
pub const DEFAULT_RANGE: f64 = 0.6;
/// Random shortcuts tried before the corners are skipped. None by default: on the SO-101 forty
/// made paths 3 % shorter (1.02 times the straight segment's length against 1.05, median) and
/// planning four times slower (3.3 ms against 0.86 ms), the checks of the shortcuts costing more
/// than the search (`armctl bench plan --shortcuts N`). The corners are skipped either way.
pub const DEFAULT_SHORTCUTS: usize = 0;
/// Each keyframe's segment takes this much longer than the least its limits allow, so that the
/// firmware's f32 finds it within them too.
const TIME_SLACK: f64 = 1.02;

/// How hard to look.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Options {
    /// Samples before giving up.
    pub samples: usize,
    /// The sampler's seed.
    pub seed: u64,
    /// The longest step of a tree (rad).
    pub range: f64,
    /// Random shortcuts tried.
    pub shortcuts: usize,
}

impl Default for Options {
    fn default() -> Self {
        Self { samples: DEFAULT_SAMPLES, seed: DEFAULT_SEED, range: DEFAULT_RANGE, shortcuts: DEFAULT_SHORTCUTS }
    }
}

/// A collision-free path: its corners, start and goal included.
#[derive(Clone, Debug, PartialEq)]
pub struct Path {
    /// Corners, from the start to the goal.
    pub corners: Vec<Vec<f64>>,
    /// Samples drawn.
    pub samples: usize,
    /// Configurations checked.
    pub checks: u64,
    /// Time taken.
    pub took: Duration,
}

impl Path {
    /// True if it is the straight joint segment from start to goal (nothing was in the way).
    pub fn is_direct(&self) -> bool {
        self.corners.len() == 2 && self.samples == 0
    }

    /// Its length in joint space (rad, Euclidean).
    pub fn length(&self) -> f64 {
        length(&self.corners)
    }
}

/// The Euclidean joint-space length of a polyline.
pub fn length(corners: &[Vec<f64>]) -> f64 {
    corners.windows(2).map(|w| distance(&w[0], &w[1])).sum()
}

fn distance(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum::<f64>().sqrt()
}

fn lerp(a: &[f64], b: &[f64], u: f64) -> Vec<f64> {
    a.iter().zip(b).map(|(x, y)| x + u * (y - x)).collect()
}

/// A tree of configurations, each with its parent.
struct Tree {
    nodes: Vec<Vec<f64>>,
    parents: Vec<usize>,
}

impl Tree {
    fn new(root: &[f64]) -> Self {
        Self { nodes: vec![root.to_vec()], parents: vec![0] }
    }

    fn nearest(&self, q: &[f64]) -> usize {
        let squared = |n: &Vec<f64>| n.iter().zip(q).map(|(a, b)| (a - b) * (a - b)).sum::<f64>();
        let mut best = (0, f64::INFINITY);
        for (i, n) in self.nodes.iter().enumerate() {
            let d = squared(n);
            if d < best.1 {
                best = (i, d);
            }
        }
        best.0
    }

    /// From node `i` back to the root.
    fn branch(&self, mut i: usize) -> Vec<Vec<f64>> {
        let mut out = vec![self.nodes[i].clone()];
        while i != 0 {
            i = self.parents[i];
            out.push(self.nodes[i].clone());
        }
        out
    }
}

/// What one extension did.
enum Extended {
    /// Stopped by a contact: nothing added.
    Trapped,
    /// A step added (node index).
    Advanced(usize),
    /// The target itself added (node index).
    Reached(usize),
}

fn extend(tree: &mut Tree, target: &[f64], range: f64, checker: &mut Checker<'_>) -> Extended {
    let near = tree.nearest(target);
    let from = tree.nodes[near].clone();
    let d = distance(&from, target);
    let (to, reached) = if d <= range { (target.to_vec(), true) } else { (lerp(&from, target, range / d), false) };
    if !checker.straight_free(&from, &to) {
        return Extended::Trapped;
    }
    tree.nodes.push(to);
    tree.parents.push(near);
    let i = tree.nodes.len() - 1;
    if reached {
        Extended::Reached(i)
    } else {
        Extended::Advanced(i)
    }
}

/// Why no path was made.
#[derive(Debug)]
pub enum PlanError {
    /// The start or the goal is itself in contact (the pair in words).
    InCollision {
        /// "the start" or "the goal".
        which: &'static str,
        /// The pair and its distance.
        said: String,
    },
    /// Outside the joint limits, or of the wrong length.
    Invalid(String),
    /// The budget ran out.
    NotFound {
        /// Samples drawn.
        samples: usize,
    },
}

impl std::fmt::Display for PlanError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            PlanError::InCollision { which, said } => write!(f, "{which} is in collision: {said}"),
            PlanError::Invalid(why) => write!(f, "{why}"),
            PlanError::NotFound { samples } => write!(f, "no collision-free path found in {samples} samples"),
        }
    }
}

impl std::error::Error for PlanError {}

/// Refuses a start or a goal outside the limits or in collision, naming the pair: what every
/// plan checks first.
pub fn check_ends(checker: &mut Checker<'_>, start: &[f64], goal: &[f64]) -> Result<(), PlanError> {
    for (q, which) in [(start, "the start"), (goal, "the goal")] {
        if !checker.arm().admits(q) {
            return Err(PlanError::Invalid(format!("{which} ({}) is outside the joint limits", shown(q))));
        }
        match checker.contact(q) {
            Err(e) => return Err(PlanError::Invalid(format!("{e:#}"))),
            Ok(Some(contact)) => return Err(PlanError::InCollision { which, said: checker.describe(&contact) }),
            Ok(None) => {}
        }
    }
    Ok(())
}

/// A collision-free path from `start` to `goal` (both within the limits and free), shortcut.
pub fn plan(checker: &mut Checker<'_>, start: &[f64], goal: &[f64], options: &Options) -> Result<Path, PlanError> {
    let began = Instant::now();
    let checks_before = checker.checks();
    let arm = checker.arm();
    check_ends(checker, start, goal)?;
    let done = |corners: Vec<Vec<f64>>, samples: usize, checker: &mut Checker<'_>| Path {
        corners,
        samples,
        checks: checker.checks() - checks_before,
        took: began.elapsed(),
    };
    if checker.straight_free(start, goal) {
        return Ok(done(vec![start.to_vec(), goal.to_vec()], 0, checker));
    }
    let mut rng = SplitMix64::new(options.seed);
    let (mut a, mut b) = (Tree::new(start), Tree::new(goal));
    // `a` grows from the start while this is false.
    let mut swapped = false;
    for sample in 1..=options.samples {
        let q = arm.random_configuration(&mut rng);
        let new = match extend(&mut a, &q, options.range, checker) {
            Extended::Trapped => None,
            Extended::Advanced(i) | Extended::Reached(i) => Some(i),
        };
        if let Some(i) = new {
            let target = a.nodes[i].clone();
            let joined = loop {
                match extend(&mut b, &target, options.range, checker) {
                    Extended::Advanced(_) => continue,
                    Extended::Reached(j) => break Some(j),
                    Extended::Trapped => break None,
                }
            };
            if let Some(j) = joined {
                let (from_a, from_b) = (a.branch(i), b.branch(j));
                // `from_b` starts with `target` again (its last node): drop the copy.
                let (mut forward, backward) = if swapped { (from_b, from_a) } else { (from_a, from_b) };
                forward.reverse();
                forward.extend(backward.into_iter().skip(1));
                let corners = shortcut(checker, forward, &mut rng, options.shortcuts);
                return Ok(done(corners, sample, checker));
            }
        }
        std::mem::swap(&mut a, &mut b);
        swapped = !swapped;
    }
    Err(PlanError::NotFound { samples: options.samples })
}

/// Shortens a free path: `tries` random pairs of points along it joined where the straight
/// segment between them is free (the points lie on checked segments, so they are free), then
/// every corner skipped whose neighbours see each other.
pub fn shortcut(
    checker: &mut Checker<'_>,
    mut path: Vec<Vec<f64>>,
    rng: &mut SplitMix64,
    tries: usize,
) -> Vec<Vec<f64>> {
    for _ in 0..tries {
        if path.len() < 3 {
            break;
        }
        let total = length(&path);
        let (mut u, mut v) = (rng.unit_f64() * total, rng.unit_f64() * total);
        if u > v {
            std::mem::swap(&mut u, &mut v);
        }
        let ((i, p), (j, q)) = (point_at(&path, u), point_at(&path, v));
        // Both on one segment, or next to each other: nothing to gain.
        if j <= i {
            continue;
        }
        if checker.straight_free(&p, &q) {
            let mut shorter = path[..=i].to_vec();
            shorter.push(p);
            shorter.push(q);
            shorter.extend(path[j + 1..].iter().cloned());
            shorter.dedup_by(|x, y| distance(x, y) < 1e-9);
            path = shorter;
        }
    }
    // Skip every corner that can be skipped, from the start.
    let mut kept = vec![path[0].clone()];
    let mut i = 0;
    while i + 1 < path.len() {
        let mut far = path.len() - 1;
        while far > i + 1 && !checker.straight_free(&path[i], &path[far]) {
            far -= 1;
        }
        kept.push(path[far].clone());
        i = far;
    }
    kept
}

/// The point `along` (rad of length) the path, and the index of the corner before it.
fn point_at(path: &[Vec<f64>], along: f64) -> (usize, Vec<f64>) {
    let mut left = along;
    for (i, w) in path.windows(2).enumerate() {
        let d = distance(&w[0], &w[1]);
        if left <= d && d > 0.0 {
            return (i, lerp(&w[0], &w[1], left / d));
        }
        left -= d;
    }
    let last = path.len() - 1;
    (last.saturating_sub(1), path[last].clone())
}

/// The scene of the planner's property test and of `armctl bench plan`: the arm's own collision
/// geometry, else capsules of 20 mm from its frames with the table at its base
/// ([`CollisionSpec::from_frames`], the pairs that touch at the zero pose allowed), and a box 6 cm
/// deep, 16 cm wide and 12 cm high standing on
/// the table in front of the arm at half the reach of its middle pose.
pub fn boxed_scene(arm: &dyn DynArm) -> Result<CollisionSpec> {
    let mut spec = match collision_of(arm.spec()) {
        Some(own) => own,
        None => {
            // Capsules measured from the frames can touch where the real links do not (the
            // OpenManipulator-X's first link sits 17 mm above the base plane, closer than its
            // capsule's radius): pairs that touch at the zero pose are neighbours, as MoveIt's
            // setup assistant decides.
            let mut spec = CollisionSpec::from_frames(arm.spec(), 0.02);
            let zero = vec![0.0; arm.spec().dof()];
            for _ in 0..spec.bodies.len() * spec.bodies.len() {
                let mut checker = Checker::new(arm, spec.clone())?;
                let Some(contact) = checker.contact(&zero)? else { break };
                let pair = [spec.name(Part::Body(contact.body)).to_string(), spec.name(contact.other).to_string()];
                spec.allowed.push(pair);
            }
            spec
        }
    };
    let reach = arm.tool_pose(&arm.middle())?.translation.norm();
    let shape = Shape::aligned_box(Vector3::new(0.5 * reach, 0.0, 0.06), Vector3::new(0.06, 0.16, 0.12));
    spec.obstacles.push(ObstacleSpec { name: "box".into(), shape });
    Ok(spec)
}

/// Keyframes as the firmware's player takes them.
#[derive(Clone, Debug, PartialEq)]
pub struct Keyframes {
    /// Seconds on the playback clock, which starts at zero at the start; one per corner after
    /// the first.
    pub times: Vec<f64>,
    /// Joints at each.
    pub positions: Vec<Vec<f64>>,
    /// Joint velocities at each (zero: at rest at every corner).
    pub velocities: Vec<Vec<f64>>,
}

/// The shortest time the player's rest-to-rest cubic takes from `from` to `to` within the
/// velocity and acceleration limits (rad/s, rad/s², the same for every joint).
pub fn rest_to_rest(from: &[f64], to: &[f64], max_velocity: f64, max_acceleration: f64) -> f64 {
    let limits = JointLimits::<f64, 1> {
        lower: SVector::from([f64::NEG_INFINITY]),
        upper: SVector::from([f64::INFINITY]),
        max_velocity: SVector::from([max_velocity]),
        max_acceleration: SVector::from([max_acceleration]),
    };
    from.iter()
        .zip(to)
        .map(|(a, b)| limits.rest_to_rest_time(&SVector::from([*a]), &SVector::from([*b])))
        .fold(0.0, f64::max)
}

/// The keyframes of a path: at rest at every corner after the start, each segment the least time
/// the limits allow (and a little more), stretched evenly to `duration` if that is longer.
pub fn keyframes(corners: &[Vec<f64>], max_velocity: f64, max_acceleration: f64, duration: Option<f64>) -> Keyframes {
    let spans: Vec<f64> = corners
        .windows(2)
        .map(|w| (rest_to_rest(&w[0], &w[1], max_velocity, max_acceleration) * TIME_SLACK).max(1e-3))
        .collect();
    let least: f64 = spans.iter().sum();
    let stretch = duration.map_or(1.0, |d| (d / least).max(1.0));
    let mut t = 0.0;
    let times = spans
        .iter()
        .map(|s| {
            t += s * stretch;
            t
        })
        .collect();
    let positions: Vec<Vec<f64>> = corners.iter().skip(1).cloned().collect();
    let velocities = positions.iter().map(|p| vec![0.0; p.len()]).collect();
    Keyframes { times, positions, velocities }
}

/// The keyframes as the firmware's player plays them from `start` (at rest, at time zero): a
/// velocity not given is the one the player chooses, `(p_next - p_before) / (t_next - t_before)`
/// clamped to `max_velocity`, zero at the last keyframe; a first keyframe sooner than the
/// rest-to-rest time from `start` is reached in that time, the rest shifted with it, as the player
/// shifts late keyframes.
pub fn as_played(
    start: &[f64],
    times: &[f64],
    positions: &[Vec<f64>],
    velocities: Option<&[Vec<f64>]>,
    max_velocity: f64,
    max_acceleration: f64,
) -> Keyframes {
    let first = positions.first().map_or(0.0, |p| rest_to_rest(start, p, max_velocity, max_acceleration));
    let shift = times.first().map_or(0.0, |t| (first - t).max(0.0));
    let times: Vec<f64> = times.iter().map(|t| t + shift).collect();
    let chosen = (0..positions.len())
        .map(|k| match velocities {
            Some(v) => v[k].clone(),
            None if k + 1 < positions.len() => {
                let (before, t_before) =
                    if k == 0 { (start, 0.0) } else { (positions[k - 1].as_slice(), times[k - 1]) };
                let span = times[k + 1] - t_before;
                positions[k + 1]
                    .iter()
                    .zip(before)
                    .map(|(after, before)| ((after - before) / span).clamp(-max_velocity, max_velocity))
                    .collect()
            }
            None => vec![0.0; start.len()],
        })
        .collect();
    Keyframes { times, positions: positions.to_vec(), velocities: chosen }
}

/// A contact on the path the player plays from `start` through `keyframes` (each segment the
/// cubic Hermite between two keyframes with their velocities, the start at rest at time zero),
/// with the keyframes it lies between (1 = the first keyframe; 0 = the start).
pub fn check_keyframes(
    checker: &mut Checker<'_>,
    start: &[f64],
    keyframes: &Keyframes,
) -> Result<Option<(usize, SegmentContact)>> {
    if keyframes.positions.len() != keyframes.times.len() || keyframes.velocities.len() != keyframes.times.len() {
        bail!("keyframes: times, positions and velocities differ in number");
    }
    let zero = vec![0.0; start.len()];
    let (mut p0, mut v0, mut t0) = (start.to_vec(), zero, 0.0);
    for (k, ((t1, p1), v1)) in keyframes.times.iter().zip(&keyframes.positions).zip(&keyframes.velocities).enumerate() {
        if let Some(contact) = checker.contact(p1)? {
            let q = p1.clone();
            return Ok(Some((k, SegmentContact { at: 1.0, q, contact })));
        }
        let h = t1 - t0;
        let tangent = |v: &[f64]| v.iter().map(|x| x * h).collect::<Vec<f64>>();
        if let Some(found) = checker.along(&Hermite::new(&p0, &tangent(&v0), p1, &tangent(v1)))? {
            return Ok(Some((k, found)));
        }
        (p0, v0, t0) = (p1.clone(), v1.clone(), *t1);
    }
    Ok(None)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::motion::collision::tests::so101_with_box;
    use crate::motion::collision::Segment;

    /// A box between start and goal: the direct segment is blocked, the plan goes around it, and
    /// every densely sampled point of the keyframes as played keeps the margin (checked here at a
    /// tenth of the checker's step, by the scene's closest pair, not by the checker's word).
    #[test]
    fn the_plan_goes_around_the_box_and_every_played_point_keeps_the_margin() {
        let (arm, spec) = so101_with_box();
        let mut checker = Checker::new(arm.as_ref(), spec.clone()).unwrap();
        let (start, goal) = ([0.8, -0.2, 0.5, 1.0, 0.0], [-0.8, -0.2, 0.5, 1.0, 0.0]);
        assert!(checker.straight(&start, &goal).unwrap().is_some(), "the direct segment is blocked");
        let path = plan(&mut checker, &start, &goal, &Options::default()).unwrap();
        assert!(path.corners.len() >= 3, "{:?}", path.corners);
        assert_eq!((path.corners[0].as_slice(), path.corners.last().unwrap().as_slice()), (&start[..], &goal[..]));
        let direct = distance(&start, &goal);
        assert!(path.length() > direct && path.length() < 3.0 * direct, "{} vs {direct}", path.length());
        // Repeatable: the same seed, the same path.
        assert_eq!(plan(&mut checker, &start, &goal, &Options::default()).unwrap().corners, path.corners);

        let k = keyframes(&path.corners, 2.0, 8.0, None);
        assert_eq!(check_keyframes(&mut checker, &start, &k).unwrap(), None);
        let mut previous = (start.to_vec(), 0.0);
        let mut lowest = f64::INFINITY;
        for (t1, p1) in k.times.iter().zip(&k.positions) {
            let zero = vec![0.0; 5];
            let h = Hermite::new(&previous.0, &zero, p1, &zero);
            let n = (checker.motion(&h.speed(0.0, 1.0)) / (0.1 * checker.step())).ceil() as usize;
            for i in 0..=n {
                let q = h.at(i as f64 / n as f64);
                lowest = lowest.min(checker.closest(&q).unwrap().unwrap().distance);
            }
            // Within the limits: the smoothstep's peak velocity and acceleration.
            let d = p1.iter().zip(&previous.0).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
            let span = t1 - previous.1;
            assert!(1.5 * d / span <= 2.0 && 6.0 * d / (span * span) <= 8.0);
            previous = (p1.clone(), *t1);
        }
        assert!(lowest >= spec.margin, "{lowest}");
    }

    #[test]
    fn a_goal_in_collision_or_out_of_reach_is_refused_and_a_boxed_in_goal_runs_out_of_samples() {
        let (arm, spec) = so101_with_box();
        let mut checker = Checker::new(arm.as_ref(), spec).unwrap();
        let start = [0.8, -0.2, 0.5, 1.0, 0.0];
        // Shoulder pitched down, elbow folded: the wrist in the box.
        let e = plan(&mut checker, &start, &[0.0, 0.5, 0.5, 0.5, 0.0], &Options::default()).unwrap_err();
        assert!(e.to_string().starts_with("the goal is in collision: elbow_flex and box overlap"), "{e}");
        let e = plan(&mut checker, &start, &[3.0, 0.0, 0.0, 0.0, 0.0], &Options::default()).unwrap_err();
        assert!(e.to_string().contains("outside the joint limits"), "{e}");
        let few = Options { samples: 1, ..Options::default() };
        let e = plan(&mut checker, &start, &[-0.8, -0.2, 0.5, 1.0, 0.0], &few).unwrap_err();
        assert_eq!(e.to_string(), "no collision-free path found in 1 samples");
    }
}
