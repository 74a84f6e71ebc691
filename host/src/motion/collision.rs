//! The host's collision check of an arm: a configuration, a joint-space segment and a Hermite
//! segment (what the firmware's player plays between two keyframes) against the arm's scene
//! ([`crate::arm::collision::collision_of`]: its bodies, the table and the obstacles), in f64, so
//! that a move in the way is refused or planned around before anything is sent. The firmware
//! checks every goal again; it never trusts this check.
//!
//! A segment is checked by conservative advancement: every joint `i` moves any point of any body
//! by at most `reach[i]` metres per radian (the longest lever from its axis to a body it carries,
//! bounded from the arm's frames so that it holds in every configuration). Over a piece of the
//! segment whose joints move by `dq`, no point moves more than `sum |dq_i| reach[i]`, so a pair's
//! distance changes by at most twice that. From the clearances beyond the margin at a piece's two
//! ends and that bound, the lowest the clearance can be anywhere on the piece follows; a piece
//! where it cannot go below zero is clear all along and is not looked at again, others are
//! halved. A segment passes only when every piece is shown clear, so every point of it, not only
//! the samples, keeps the margin; pieces are halved down to a sixteenth of the margin of motion
//! ([`Checker::step`]; finer, down to half the clearance of the segment's closer end, when an end
//! is a hair beyond the margin, so that it can be reached), and one still not shown clear there
//! (or past a budget of checks per segment) counts as blocked (a pair grazing the margin). Far
//! from everything a segment costs two or three checks; near an obstacle the pieces get as fine
//! as the clearance needs. The pairs that never move (the base's bodies against obstacles) are
//! checked once, not bounded by the motion, and a clearance is measured only as far as a piece
//! needs it.

use anyhow::{anyhow, bail, Result};
use kinematics::collision::{Contact, Scene};
use kinematics::nalgebra::SVector;
use kinematics::Chain;

use crate::arm::collision::reach::reach;
use crate::arm::collision::{collision_of, CollisionSpec, MAX_BODIES, MAX_OBSTACLES};
use crate::arm::dof::DynArm;

/// The finest piece a segment is cut into, as a fraction of the margin: over it no point of any
/// body moves more than this.
pub const STEP_OF_MARGIN: f64 = 1.0 / 16.0;
/// The finest piece when the margin is small (m).
const MIN_STEP: f64 = 0.1e-3;
/// The finest piece of a segment one of whose ends is a hair beyond the margin (m of motion). Such
/// an end (a goal 0.2 mm clear of it, with the finest step at 0.6 mm) can only be shown reached by
/// pieces finer than its clearance, so a segment is cut down to half the lower clearance of its
/// ends when that is finer than [`Checker::step`], but not below this.
const FINEST_STEP: f64 = 1e-6;
/// The checks one segment may take: a segment that grazes the margin all along, cut that fine,
/// would otherwise take one per clearance's worth of motion. Past it the segment counts as
/// blocked (too close to show clear).
const SEGMENT_CHECKS: u64 = 2000;
/// Halvings of a segment at most (2^30 pieces: far beyond any arm's reach over the step).
const MAX_DEPTH: u32 = 30;

/// The scene every check uses.
type ArmScene = Scene<f64, MAX_BODIES, MAX_OBSTACLES>;

/// An arm's chain of a fixed joint count placing its bodies in the scene. Instantiated here, in
/// this crate (the arm crate's generic code is built without optimisation for tests, and a check
/// is the planner's inner loop).
trait Placer: Send + Sync {
    fn check(&self, scene: &mut ArmScene, q: &[f64], query: Query) -> Result<Option<Contact<f64>>>;
}

/// What a check of a configuration answers.
#[derive(Clone, Copy)]
enum Query {
    /// The first pair closer than the margin.
    FirstContact,
    /// The closest pair.
    Closest,
    /// The closest pair whose distance changes with the joints, if closer than this (m).
    ClosestMoving(f64),
}

impl<const N: usize> Placer for Chain<f64, N> {
    fn check(&self, scene: &mut ArmScene, q: &[f64], query: Query) -> Result<Option<Contact<f64>>> {
        if q.len() != N {
            bail!("the arm has {N} joints but {} joint values were given", q.len());
        }
        let frames = self.forward(&SVector::from_column_slice(q));
        Ok(match query {
            Query::FirstContact => scene.first_contact(&frames.joints),
            Query::Closest => scene.closest(&frames.joints),
            Query::ClosestMoving(within) => scene.closest_moving(&frames.joints, within),
        })
    }
}

/// The chain of `spec` for the joint counts the firmware carries (1 to 8).
fn placer(spec: &crate::arm::ArmSpec) -> Result<Box<dyn Placer>> {
    fn of<const N: usize>(spec: &crate::arm::ArmSpec) -> Result<Box<dyn Placer>> {
        Ok(Box::new(spec.chain::<f64, N>()?))
    }
    match spec.dof() {
        1 => of::<1>(spec),
        2 => of::<2>(spec),
        3 => of::<3>(spec),
        4 => of::<4>(spec),
        5 => of::<5>(spec),
        6 => of::<6>(spec),
        7 => of::<7>(spec),
        8 => of::<8>(spec),
        n => bail!("collisions are checked for arms of 1 to 8 joints, as the firmware carries; {} has {n}", spec.name),
    }
}

/// An arm's collision check: its geometry, the scene it makes and each joint's reach.
pub struct Checker<'a> {
    arm: &'a dyn DynArm,
    placer: Box<dyn Placer>,
    spec: CollisionSpec,
    scene: ArmScene,
    reach: Vec<f64>,
    step: f64,
    checks: u64,
    /// A pair that never moves (a body of the base and an obstacle) closer than the margin: every
    /// configuration is in contact then.
    fixed_contact: Option<Contact<f64>>,
}

/// A contact found along a segment.
#[derive(Clone, Debug, PartialEq)]
pub struct SegmentContact {
    /// Where along the segment, 0 at its start to 1 at its end.
    pub at: f64,
    /// The joints there.
    pub q: Vec<f64>,
    /// The pair and its distance.
    pub contact: Contact<f64>,
}

/// A piece of a joint-space path, parameterised by `s` in 0..=1: each joint a cubic.
pub trait Segment {
    /// The joints at `s`.
    fn at(&self, s: f64) -> Vec<f64>;
    /// The largest |dq_i/ds| of each joint over `s0..=s1`.
    fn speed(&self, s0: f64, s1: f64) -> Vec<f64>;
}

/// A straight joint-space segment from `from` to `to`.
pub struct Straight<'s> {
    /// Start.
    pub from: &'s [f64],
    /// End.
    pub to: &'s [f64],
}

impl Segment for Straight<'_> {
    fn at(&self, s: f64) -> Vec<f64> {
        self.from.iter().zip(self.to).map(|(a, b)| a + s * (b - a)).collect()
    }

    fn speed(&self, _: f64, _: f64) -> Vec<f64> {
        self.from.iter().zip(self.to).map(|(a, b)| (b - a).abs()).collect()
    }
}

/// A cubic Hermite segment as the firmware's player plays it: from `p0` with tangent `m0` to `p1`
/// with tangent `m1`, the tangents being velocity times the segment's duration.
pub struct Hermite {
    /// Per joint, the cubic's coefficients `[a, b, c, d]` of `a + b s + c s² + d s³`.
    cubics: Vec<[f64; 4]>,
}

impl Hermite {
    /// The segment from `p0` to `p1` with unit-parameter tangents `m0`, `m1`.
    pub fn new(p0: &[f64], m0: &[f64], p1: &[f64], m1: &[f64]) -> Self {
        let cubics = (0..p0.len())
            .map(|i| {
                let (p0, m0, p1, m1) = (p0[i], m0[i], p1[i], m1[i]);
                [p0, m0, 3.0 * (p1 - p0) - 2.0 * m0 - m1, 2.0 * (p0 - p1) + m0 + m1]
            })
            .collect();
        Self { cubics }
    }
}

impl Segment for Hermite {
    fn at(&self, s: f64) -> Vec<f64> {
        self.cubics.iter().map(|[a, b, c, d]| a + s * (b + s * (c + s * d))).collect()
    }

    fn speed(&self, s0: f64, s1: f64) -> Vec<f64> {
        // The derivative b + 2cs + 3ds² is a parabola: its largest magnitude over an interval is at
        // an end or at its vertex.
        self.cubics
            .iter()
            .map(|[_, b, c, d]| {
                let slope = |s: f64| (b + 2.0 * c * s + 3.0 * d * s * s).abs();
                let mut top = slope(s0).max(slope(s1));
                if *d != 0.0 {
                    let vertex = -c / (3.0 * d);
                    if vertex > s0 && vertex < s1 {
                        top = top.max(slope(vertex));
                    }
                }
                top
            })
            .collect()
    }
}

impl<'a> Checker<'a> {
    /// The check of `arm` against its own geometry, or `None` when it has none (nothing is
    /// checked then).
    pub fn of(arm: &'a dyn DynArm) -> Result<Option<Self>> {
        collision_of(arm.spec()).map(|spec| Self::new(arm, spec)).transpose()
    }

    /// The check of `arm` against `spec`; fails naming what the scene cannot hold.
    pub fn new(arm: &'a dyn DynArm, spec: CollisionSpec) -> Result<Self> {
        let joints = arm.spec().dof();
        let mut scene = spec.scene::<f64, MAX_BODIES, MAX_OBSTACLES>(joints)?;
        let reach = reach(arm.spec(), &spec);
        let step = (spec.margin * STEP_OF_MARGIN).max(MIN_STEP);
        let fixed_contact = scene.closest_fixed().filter(|c| c.distance.is_nan() || c.distance < spec.margin);
        Ok(Self { arm, placer: placer(arm.spec())?, spec, scene, reach, step, checks: 0, fixed_contact })
    }

    /// The arm checked.
    pub fn arm(&self) -> &'a dyn DynArm {
        self.arm
    }

    /// Its geometry.
    pub fn spec(&self) -> &CollisionSpec {
        &self.spec
    }

    /// Each joint's reach: how far (m) a radian of it (a metre, for a prismatic joint) moves any
    /// point of any body, at most.
    pub fn reach(&self) -> &[f64] {
        &self.reach
    }

    /// The finest piece a segment is cut into (m of motion of any point).
    pub fn step(&self) -> f64 {
        self.step
    }

    /// Configurations checked so far (the planner's figures).
    pub fn checks(&self) -> u64 {
        self.checks
    }

    /// The pair in words ("gripper and table are 3.2 mm apart (margin 10 mm)").
    pub fn describe(&self, contact: &Contact<f64>) -> String {
        self.spec.describe(contact)
    }

    /// A contact along a segment in words: [`Checker::describe`], and where the pair keeps the
    /// margin there but grazes it, that the check could not show it clear at its finest piece.
    pub fn describe_along(&self, found: &SegmentContact) -> String {
        let words = self.describe(&found.contact);
        match found.contact.distance >= self.spec.margin {
            true => format!("{words}, too close to show clear at the check's finest step ({:.2} mm)", self.step * 1e3),
            false => words,
        }
    }

    /// The first pair closer than the margin at `q`, or `None` when every pair keeps it.
    pub fn contact(&mut self, q: &[f64]) -> Result<Option<Contact<f64>>> {
        self.checks += 1;
        self.placer.check(&mut self.scene, q, Query::FirstContact)
    }

    /// True if `q` keeps the margin (a `q` of the wrong length is not free).
    pub fn is_free(&mut self, q: &[f64]) -> bool {
        matches!(self.contact(q), Ok(None))
    }

    /// The closest checked pair at `q` (its distance may be below the margin).
    pub fn closest(&mut self, q: &[f64]) -> Result<Option<Contact<f64>>> {
        self.checks += 1;
        self.placer.check(&mut self.scene, q, Query::Closest)
    }

    /// How far any point of any body moves, at most, when the joints change by `dq`.
    pub fn motion(&self, dq: &[f64]) -> f64 {
        dq.iter().zip(&self.reach).map(|(d, r)| d.abs() * r).sum()
    }

    /// A contact on the straight segment from `from` to `to` (its ends included); `None` when it
    /// keeps the margin all along.
    pub fn straight(&mut self, from: &[f64], to: &[f64]) -> Result<Option<SegmentContact>> {
        self.along(&Straight { from, to })
    }

    /// True if the straight segment from `from` to `to` keeps the margin all along.
    pub fn straight_free(&mut self, from: &[f64], to: &[f64]) -> bool {
        matches!(self.straight(from, to), Ok(None))
    }

    /// A contact on `segment` (its ends included), found by halving it; `None` when every point
    /// of it keeps the margin.
    pub fn along(&mut self, segment: &dyn Segment) -> Result<Option<SegmentContact>> {
        if let Some(contact) = self.fixed_contact {
            return Ok(Some(SegmentContact { at: 0.0, q: segment.at(0.0), contact }));
        }
        // Clearances beyond the whole segment's motion are not needed: ends that clear show the
        // whole segment clear.
        let motion = self.motion(&segment.speed(0.0, 1.0));
        let mut ends = [(0.0, f64::INFINITY); 2];
        for (end, s) in ends.iter_mut().zip([0.0, 1.0]) {
            let q = segment.at(s);
            let (clearance, closest) = self.clearance(&q, motion)?;
            if let Some(contact) = closest.filter(|_| clearance.is_nan() || clearance < 0.0) {
                return Ok(Some(SegmentContact { at: s, q, contact }));
            }
            *end = (s, clearance);
        }
        let cut = Cut {
            finest: (0.5 * ends[0].1.min(ends[1].1)).clamp(FINEST_STEP, self.step),
            last_check: self.checks + SEGMENT_CHECKS,
        };
        self.piece(segment, &cut, ends[0], ends[1], 0)
    }

    /// How far beyond the margin the closest pair at `q` that moves with the joints is (m), and
    /// that pair; `needed` (and no pair) when every such pair is at least that far beyond it, which
    /// is all a piece needs to know (its lower bound). The pairs that never move are not bounded
    /// by the motion: they keep whatever distance they have (`fixed_contact` when too close).
    fn clearance(&mut self, q: &[f64], needed: f64) -> Result<(f64, Option<Contact<f64>>)> {
        self.checks += 1;
        let margin = self.spec.margin;
        let closest = self.placer.check(&mut self.scene, q, Query::ClosestMoving(margin + needed))?;
        Ok((closest.map_or(needed, |c| c.distance - margin), closest))
    }

    /// The piece between `(s0, c0)` and `(s1, c1)` (where, and the clearance there; both keep the
    /// margin).
    fn piece(
        &mut self,
        segment: &dyn Segment,
        cut: &Cut,
        (s0, c0): (f64, f64),
        (s1, c1): (f64, f64),
        depth: u32,
    ) -> Result<Option<SegmentContact>> {
        // No point moves more than `motion` over the piece, so a pair's distance changes by at
        // most twice that: at `u` along it the clearance is at least `c0 - 2 motion u` and at
        // least `c1 - 2 motion (1 - u)`, whose lower envelope's lowest point is this.
        let motion = self.motion(&segment.speed(s0, s1)) * (s1 - s0);
        if 0.5 * (c0 + c1) - motion >= 0.0 {
            return Ok(None);
        }
        let middle = 0.5 * (s0 + s1);
        let q = segment.at(middle);
        // Each half moves at most half as far: a clearance of `motion` there shows both clear.
        let (cm, closest) = self.clearance(&q, motion)?;
        let Some(contact) = closest else { return Ok(None) };
        let finest = motion <= cut.finest || depth >= MAX_DEPTH || self.checks >= cut.last_check;
        if cm.is_nan() || cm < 0.0 || finest {
            // Inside the margin; or at the finest piece, not shown to keep it all along.
            return Ok(Some(SegmentContact { at: middle, q, contact }));
        }
        if let Some(found) = self.piece(segment, cut, (s0, c0), (middle, cm), depth + 1)? {
            return Ok(Some(found));
        }
        self.piece(segment, cut, (middle, cm), (s1, c1), depth + 1)
    }
}

/// How finely one segment is cut.
struct Cut {
    /// The finest piece (m of motion).
    finest: f64,
    /// The check count past which the segment counts as blocked.
    last_check: u64,
}

/// `q` as the message names it: "joints 0.100, -0.200, ...".
pub fn shown(q: &[f64]) -> String {
    let values: Vec<String> = q.iter().map(|x| format!("{x:.3}")).collect();
    format!("joints {}", values.join(", "))
}

/// Fails naming the pair when `q` is in contact.
pub fn refuse_contact(checker: &mut Checker<'_>, q: &[f64], what: &str) -> Result<()> {
    match checker.contact(q)? {
        None => Ok(()),
        Some(contact) => Err(anyhow!("{what} is in collision: {}", checker.describe(&contact))),
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::arm::collision::ObstacleSpec;
    use crate::arm::dof::build;
    use crate::arm::ArmSpec;
    use kinematics::collision::Shape;
    use kinematics::nalgebra::Vector3;
    use kinematics::SplitMix64;

    pub(crate) fn so101_with_box() -> (Box<dyn DynArm>, CollisionSpec) {
        let arm = build(ArmSpec::load("so101", None).unwrap()).unwrap();
        let mut spec = CollisionSpec::from_frames(arm.spec(), 0.02);
        let shape = Shape::aligned_box(Vector3::new(0.2, 0.0, 0.05), Vector3::new(0.06, 0.06, 0.1));
        spec.obstacles.push(ObstacleSpec { name: "box".into(), shape });
        (arm, spec)
    }

    /// The reach bounds what the arm's points actually do: over random small joint steps no
    /// body end moves further than the bound says.
    #[test]
    fn the_reach_bounds_how_far_any_body_moves() {
        let (arm, spec) = so101_with_box();
        let checker = Checker::new(arm.as_ref(), spec.clone()).unwrap();
        let mut rng = SplitMix64::new(7);
        let points = |q: &[f64]| -> Vec<Vector3<f64>> {
            let frames = arm.joint_frames(q).unwrap();
            spec.bodies
                .iter()
                .filter_map(|b| b.link.map(|l| (l, b)))
                .flat_map(|(l, b)| {
                    [
                        frames[l].rotation * b.capsule.a + frames[l].translation,
                        frames[l].rotation * b.capsule.b + frames[l].translation,
                    ]
                })
                .collect()
        };
        let mut tightest = 0.0f64;
        for _ in 0..2000 {
            let a = arm.random_configuration(&mut rng);
            let b: Vec<f64> = a.iter().map(|x| x + 0.05 * (2.0 * rng.unit_f64() - 1.0)).collect();
            let bound = checker.motion(&a.iter().zip(&b).map(|(x, y)| y - x).collect::<Vec<_>>());
            let moved = points(&a).iter().zip(points(&b)).map(|(p, r)| (p - r).norm()).fold(0.0, f64::max);
            assert!(moved <= bound + 1e-12, "moved {moved} beyond the bound {bound}");
            tightest = tightest.max(moved / bound);
        }
        // Not a loose bound either: some step comes within a factor of two of it.
        assert!(tightest > 0.5, "{tightest}");
    }

    /// A segment through the box is found, with the pair named; one beside it is free; every
    /// densely sampled point of a free segment keeps the margin.
    #[test]
    fn a_segment_through_the_box_is_found_and_one_clear_of_it_keeps_the_margin() {
        let (arm, spec) = so101_with_box();
        let mut checker = Checker::new(arm.as_ref(), spec.clone()).unwrap();
        // Pan from one side of the box to the other, the wrist bent down to 4 cm above the table.
        let (left, right) = ([0.8, -0.2, 0.5, 1.0, 0.0], [-0.8, -0.2, 0.5, 1.0, 0.0]);
        assert!(checker.is_free(&left) && checker.is_free(&right), "ends free");
        let found = checker.straight(&left, &right).unwrap().expect("through the box");
        assert_eq!(checker.spec().name(found.contact.other), "box", "{}", checker.describe_along(&found));
        assert!(found.contact.distance < spec.margin, "{}", checker.describe_along(&found));
        assert!(found.at > 0.0 && found.at < 1.0);
        // Lifted: clear all along, checked point by point at a tenth of the step.
        let (up_left, up_right) = ([0.8, -0.3, -0.2, 0.2, 0.0], [-0.8, -0.3, -0.2, 0.2, 0.0]);
        assert_eq!(checker.straight(&up_left, &up_right).unwrap(), None);
        let n = (checker.motion(&[1.6, 0.0, 0.0, 0.0, 0.0]) / (0.1 * checker.step())).ceil() as usize;
        for k in 0..=n {
            let q = Straight { from: &up_left, to: &up_right }.at(k as f64 / n as f64);
            let closest = checker.closest(&q).unwrap().unwrap();
            assert!(closest.distance >= spec.margin, "{}", checker.describe(&closest));
        }
        // A turn of the pan at a posture that keeps the wrist a fifth of a step beyond the margin
        // above the table all the way (the distance to the table does not change with the pan):
        // never inside the margin, but grazing it, so blocked all the same, and said so.
        let mut table = Checker::new(arm.as_ref(), spec.clone().without("box")).unwrap();
        let posture = |lift: f64| [0.0, lift, 0.5, 1.0, 0.0];
        let wanted = spec.margin + 0.2 * table.step();
        let (mut clear, mut low) = (-0.2, 1.0);
        for _ in 0..50 {
            let lift = 0.5 * (clear + low);
            let closest = table.closest(&posture(lift)).unwrap().unwrap();
            if closest.distance < wanted {
                low = lift
            } else {
                clear = lift
            }
        }
        let closest = table.closest(&posture(clear)).unwrap().unwrap();
        assert!(
            table.describe(&closest).contains("table") && closest.distance - wanted < 1e-9,
            "{}",
            table.describe(&closest)
        );
        let (a, b) = (posture(clear), [-0.5, clear, 0.5, 1.0, 0.0]);
        let found = table.straight(&a, &b).unwrap().expect("too close to show clear");
        assert!(found.contact.distance >= spec.margin, "{}", table.describe_along(&found));
        assert!(table.describe_along(&found).contains("too close to show clear"), "{}", table.describe_along(&found));
    }

    /// The Hermite segment's derivative bound holds at every sample, and its ends are its
    /// keyframes.
    #[test]
    fn the_hermite_speed_bounds_its_slope() {
        let h = Hermite::new(&[0.0, 1.0], &[2.0, -1.0], &[1.0, 0.5], &[-3.0, 0.0]);
        assert_eq!(h.at(0.0), vec![0.0, 1.0]);
        assert!((h.at(1.0)[0] - 1.0).abs() < 1e-12 && (h.at(1.0)[1] - 0.5).abs() < 1e-12);
        let bound = h.speed(0.0, 1.0);
        for k in 0..1000 {
            let (s, ds) = (k as f64 / 1000.0, 1e-6);
            let (a, b) = (h.at(s), h.at(s + ds));
            for j in 0..2 {
                assert!(((b[j] - a[j]) / ds).abs() <= bound[j] + 1e-4);
            }
        }
    }
}
