//! The host's collision check of an arm: a configuration, a joint-space segment and a Hermite
//! segment (what the firmware's player plays between two keyframes) against the arm's scene
//! ([`crate::arm::collision::collision_of`]: its bodies, the table and the obstacles), in f64, so
//! that a move in the way is refused or planned around before anything is sent. The firmware
//! checks every goal again; it never trusts this check.
//!
//! A segment is checked by conservative advancement: every joint `i` moves any point of any body
//! by at most `reach[i]` metres per radian (the longest lever from its axis to a body it carries,
//! bounded from the arm's frames so that it holds in every configuration). Over a piece of the
//! segment whose joints move by `dq`, no point moves more than `sum |dq_i| reach[i]`, so two
//! bodies' distance changes by at most twice that. A piece whose middle is clear of the margin by
//! more than that bound is clear all along and is not looked at again; other pieces are halved,
//! down to pieces over which no point moves more than a quarter of the margin ([`Checker::step`]),
//! whose middle must keep the margin: between two such samples no pair comes closer than half the
//! margin. Far from everything a segment costs one or two checks; near an obstacle it is sampled
//! at that resolution.

use anyhow::{anyhow, Result};
use kinematics::collision::{Contact, Scene};
use kinematics::JointKind;

use crate::arm::collision::{collision_of, CollisionSpec, MAX_BODIES, MAX_OBSTACLES};
use crate::arm::dof::DynArm;

/// The finest piece a segment is cut into, as a fraction of the margin: no point of any body
/// moves more than this between two samples.
pub const STEP_OF_MARGIN: f64 = 0.25;
/// The finest piece when the margin is zero (m).
const MIN_STEP: f64 = 0.5e-3;
/// Halvings of a segment at most (2^30 pieces: far beyond any arm's reach over the step).
const MAX_DEPTH: u32 = 30;

/// An arm's collision check: its geometry, the scene it makes and each joint's reach.
pub struct Checker<'a> {
    arm: &'a dyn DynArm,
    spec: CollisionSpec,
    scene: Scene<f64, MAX_BODIES, MAX_OBSTACLES>,
    reach: Vec<f64>,
    step: f64,
    checks: u64,
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
        let scene = spec.scene::<f64, MAX_BODIES, MAX_OBSTACLES>(joints)?;
        let reach = reach(arm.spec(), &spec);
        let step = (spec.margin * STEP_OF_MARGIN).max(MIN_STEP);
        Ok(Self { arm, spec, scene, reach, step, checks: 0 })
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

    /// The first pair closer than the margin at `q`, or `None` when every pair keeps it.
    pub fn contact(&mut self, q: &[f64]) -> Result<Option<Contact<f64>>> {
        let frames = self.arm.joint_frames(q)?;
        self.checks += 1;
        Ok(self.scene.first_contact(&frames))
    }

    /// True if `q` keeps the margin (a `q` of the wrong length is not free).
    pub fn is_free(&mut self, q: &[f64]) -> bool {
        matches!(self.contact(q), Ok(None))
    }

    /// The closest checked pair at `q` (its distance may be below the margin).
    pub fn closest(&mut self, q: &[f64]) -> Result<Option<Contact<f64>>> {
        let frames = self.arm.joint_frames(q)?;
        self.checks += 1;
        Ok(self.scene.closest(&frames))
    }

    /// How far any point of any body moves, at most, when the joints change by `dq`.
    pub fn motion(&self, dq: &[f64]) -> f64 {
        dq.iter().zip(&self.reach).map(|(d, r)| d.abs() * r).sum()
    }

    /// A contact on the straight segment from `from` to `to`, its start not included (it is
    /// where the arm is, or a checked node); `None` when it keeps the margin all along.
    pub fn straight(&mut self, from: &[f64], to: &[f64]) -> Result<Option<SegmentContact>> {
        if let Some(contact) = self.contact(to)? {
            return Ok(Some(SegmentContact { at: 1.0, q: to.to_vec(), contact }));
        }
        self.along(&Straight { from, to })
    }

    /// True if the straight segment from `from` to `to` keeps the margin (its start not checked).
    pub fn straight_free(&mut self, from: &[f64], to: &[f64]) -> bool {
        matches!(self.straight(from, to), Ok(None))
    }

    /// A contact inside `segment` (its two ends not included: they are keyframes, checked on
    /// their own), found by halving it; `None` when it keeps the margin all along.
    pub fn along(&mut self, segment: &dyn Segment) -> Result<Option<SegmentContact>> {
        self.piece(segment, 0.0, 1.0, 0)
    }

    fn piece(&mut self, segment: &dyn Segment, s0: f64, s1: f64, depth: u32) -> Result<Option<SegmentContact>> {
        let middle = 0.5 * (s0 + s1);
        // From the middle to either end of the piece, no point moves more than this.
        let half = 0.5 * self.motion(&segment.speed(s0, s1)) * (s1 - s0);
        let q = segment.at(middle);
        let Some(closest) = self.closest(&q)? else { return Ok(None) };
        if !(closest.distance >= self.spec.margin) {
            return Ok(Some(SegmentContact { at: middle, q, contact: closest }));
        }
        // Two bodies approach by at most twice what each moves.
        if 2.0 * half <= closest.distance - self.spec.margin || half <= 0.5 * self.step || depth >= MAX_DEPTH {
            return Ok(None);
        }
        if let Some(found) = self.piece(segment, s0, middle, depth + 1)? {
            return Ok(Some(found));
        }
        self.piece(segment, middle, s1, depth + 1)
    }
}

/// Each joint's reach over `spec`'s bodies on `arm`: for joint `i`, the largest distance from its
/// origin to a point of a body it carries, by the triangle inequality along the frames between
/// (each joint origin's offset, and a prismatic joint's longest travel), so that it holds in every
/// configuration. A revolute joint turned by `dq` moves a point at distance `r` by at most
/// `r |dq|`; a prismatic joint moves everything it carries by its own travel (reach 1).
pub fn reach(arm: &crate::arm::ArmSpec, spec: &CollisionSpec) -> Vec<f64> {
    let travel = |j: usize| {
        let joint = &arm.joints[j];
        match joint.kind {
            JointKind::Prismatic => joint.lower.abs().max(joint.upper.abs()),
            _ => 0.0,
        }
    };
    (0..arm.joints.len())
        .map(|i| {
            if arm.joints[i].kind == JointKind::Prismatic {
                return 1.0;
            }
            spec.bodies
                .iter()
                .filter_map(|body| {
                    let k = body.link?;
                    if k < i {
                        return None;
                    }
                    let between: f64 =
                        ((i + 1)..=k).map(|m| arm.joints[m].origin.translation.norm() + travel(m)).sum::<f64>();
                    let c = &body.capsule;
                    Some(between + c.a.norm().max(c.b.norm()) + c.radius)
                })
                .fold(0.0, f64::max)
        })
        .collect()
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
mod tests {
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
        assert_eq!(checker.spec().name(found.contact.other), "box", "{}", checker.describe(&found.contact));
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
