//! What the demo asks of an arm: Cartesian targets to reach one by one, then a pick-and-place path
//! streamed as Cartesian keyframes that carry the gripper's opening: open on the way down, closed
//! on the object at the pick point, carried, opened at the place point.
//!
//! Nothing here is written per arm. The points are drawn from the arm's own reachable workspace,
//! the same way every run ([`Scenario::for_arm`]): joint vectors from a fixed-seed generator in the
//! middle of the joint ranges, their tool positions by forward kinematics, kept when they lie
//! comfortably inside the reach and every straight line the tool will follow to them solves by IK
//! (position only, f32 as on the firmware) from one point to the next without a jump.

use anyhow::{bail, Result};
use kinematics::SplitMix64;

use crate::arm::collision::{collision_of, CollisionSpec};
use crate::arm::dof::DynArm;
use crate::arm::servos::GripperSpec;
use crate::motion::collision::Checker;
use crate::motion::line::Line;

/// One arm's demo.
pub struct Scenario {
    /// Targets of the point-to-point moves (m).
    pub targets: Vec<[f32; 3]>,
    /// Tool speed of the moves (m/s).
    pub speed: f32,
    /// Waypoints of the pick-and-place path: time (s on the playback clock), tool position (m)
    /// and gripper opening (percent, 0 closed to 100 open; `None` for an arm without a gripper).
    pub waypoints: Vec<(f32, [f32; 3], Option<f32>)>,
    /// Where the object to pick up lies (m).
    pub pick: [f32; 3],
    /// Where it is to be put down (m).
    pub place: [f32; 3],
    /// The object's width (mm), less than the open jaws' (`None`: no gripper, nothing to pick).
    pub object_mm: Option<f64>,
    /// Spacing of the keyframes streamed along the path (s).
    pub keyframe_spacing: f32,
}

/// The generator's seed: every run of every arm draws the same sequence.
const SEED: u64 = 0xDE30;
/// How many joint vectors are drawn at most.
const DRAWS: usize = 4000;
/// How far the joints are drawn from the middle of their ranges, as a fraction of the half range:
/// well away from the limits, so the moves between the points stay clear of them too.
const SPREAD: f64 = 0.6;
/// The Cartesian moves' tool speed, and the pick-and-place path's (m/s).
const MOVE_SPEED: f32 = 0.15;
const PATH_SPEED: f32 = 0.1;
/// The object's width unless the jaws are too narrow for it (mm).
const OBJECT_MM: f64 = 30.0;
/// Points checked by IK along each straight line, ends included ([`Line::follow`]).
const LINE_POINTS: usize = 8;
/// Pick and place pairs whose path is checked by IK at most.
const MAX_PAIRS: usize = 200;

fn distance(a: [f64; 3], b: [f64; 3]) -> f64 {
    (0..3).map(|i| (a[i] - b[i]).powi(2)).sum::<f64>().sqrt()
}

fn horizontal(p: [f64; 3]) -> f64 {
    p[0].hypot(p[1])
}

/// How many times the arm's collision margin the demo's lines keep from the table and obstacles.
const AROUND: f64 = 1.5;
/// How many times the margin they keep between the arm's own bodies.
const OWN: f64 = 3.0;

/// The arm's workspace as the demo draws from it.
struct Workspace<'a> {
    arm: &'a dyn DynArm,
    /// The check of the arm against its collision geometry (the table, its own links): the demo
    /// draws only lines that keep the margin, as the host and the firmware will require. `None`
    /// for an arm without geometry. In a cell because following a line is a query of `&self`.
    checker: std::cell::RefCell<Vec<Checker<'a>>>,
    /// The farthest drawn tool position from the base (m).
    reach: f64,
    /// Candidate tool positions, in the order drawn.
    points: Vec<[f64; 3]>,
}

impl<'a> Workspace<'a> {
    fn draw(arm: &'a dyn DynArm) -> Result<Self> {
        let mut rng = SplitMix64::new(SEED);
        let middle = arm.middle();
        let mut points = Vec::with_capacity(DRAWS);
        for _ in 0..DRAWS {
            let r = arm.random_configuration(&mut rng);
            let q: Vec<f64> = r.iter().zip(&middle).map(|(r, m)| m + SPREAD * (r - m)).collect();
            let p = arm.tool_pose(&q)?.translation;
            points.push([p.x, p.y, p.z]);
        }
        let reach = points.iter().map(|p| distance(*p, [0.0; 3])).fold(0.0, f64::max);
        if !(reach.is_finite() && reach > 0.02) {
            bail!("arm {}: its tool does not leave the base ({reach} m): no demo to draw", arm.spec().name);
        }
        // Lines that keep more than the margin: the firmware looks ahead along its brake, which
        // runs on past a turn of the path, and its IK of each keyframe may fold a redundant arm a
        // little otherwise than the host's; a stream that grazes the margin would be stopped.
        // Bodies on the base and the obstacles never move relative to each other: no line of the
        // demo changes their distance, so those pairs are left to the firmware's own margin.
        let checkers = match collision_of(arm.spec()) {
            None => Vec::new(),
            Some(spec) => {
                let fixed = spec.bodies.iter().filter(|b| b.link.is_none()).map(|b| b.name.clone());
                let pairs: Vec<[String; 2]> =
                    fixed.flat_map(|b| spec.obstacles.iter().map(move |o| [b.clone(), o.name.clone()])).collect();
                let allowed = spec.allowed.iter().cloned().chain(pairs).collect();
                let around = CollisionSpec { margin: AROUND * spec.margin, allowed, ..spec.clone() };
                let own = CollisionSpec { margin: OWN * spec.margin, ..spec }.without_obstacles();
                vec![Checker::new(arm, around)?, Checker::new(arm, own)?]
            }
        };
        let checker = std::cell::RefCell::new(checkers);
        Ok(Self { arm, checker, reach, points })
    }

    /// Comfortably inside the reach: off the base axis, short of full stretch, above the base.
    fn comfortable(&self, p: [f64; 3]) -> bool {
        horizontal(p) >= 0.3 * self.reach && distance(p, [0.0; 3]) <= 0.85 * self.reach && p[2] >= 0.05 * self.reach
    }

    /// The joint values at `to` when the tool follows the straight line there from `from`, where
    /// the joints are `q`; `None` unless every point of it solves, near the last, and the arm
    /// keeps its collision margin all the way.
    fn follow(&self, q: &[f64], from: [f64; 3], to: [f64; 3]) -> Option<Vec<f64>> {
        let line = Line { from, to, orientation: None };
        let mut checkers = self.checker.borrow_mut();
        if checkers.is_empty() {
            return line.follow(self.arm, q, LINE_POINTS).ok()?.ok();
        }
        // The same IK path each time (seeded alike), checked against each checker.
        let mut end = None;
        for checker in checkers.iter_mut() {
            end = Some(line.follow_checked(self.arm, q, LINE_POINTS, Some(checker)).ok()?.ok()?);
        }
        end
    }

    /// Follows every line of `path` from `q`; the joints at its end, or `None`.
    fn follow_all(&self, q: &[f64], path: &[[f64; 3]]) -> Option<Vec<f64>> {
        path.windows(2).try_fold(q.to_vec(), |q, w| self.follow(&q, w[0], w[1]))
    }
}

/// Gripper openings of the path, percent.
const OPEN: f32 = 100.0;
const CLOSED: f32 = 0.0;

fn f32s(p: [f64; 3]) -> [f32; 3] {
    p.map(|x| x as f32)
}

impl Scenario {
    /// The demo of `arm`, whose joints stand at `start`, with `gripper` if it has one: four
    /// Cartesian targets and a pick-and-place path, all drawn from its reachable workspace.
    pub fn for_arm(arm: &dyn DynArm, start: &[f64], gripper: Option<&GripperSpec>) -> Result<Self> {
        let ws = Workspace::draw(arm)?;
        let name = &arm.spec().name;
        let home = {
            let p = arm.tool_pose(start)?.translation;
            [p.x, p.y, p.z]
        };
        // Moves of a useful length that a 3 s move at MOVE_SPEED covers.
        let (shortest, longest) = (0.15 * ws.reach, (0.5 * ws.reach).min(0.4));
        let mut targets = Vec::new();
        let (mut here, mut q) = (home, start.to_vec());
        for &p in &ws.points {
            if targets.len() == 4 {
                break;
            }
            let d = distance(here, p);
            if !ws.comfortable(p) || d < shortest || d > longest {
                continue;
            }
            if let Some(next) = ws.follow(&q, here, p) {
                targets.push(f32s(p));
                (here, q) = (p, next);
            }
        }
        if targets.len() < 4 {
            bail!("arm {name}: found {} of 4 targets its tool reaches on straight lines", targets.len());
        }
        // The path starts where the last target left the tool.
        let hover = (0.2 * ws.reach).clamp(0.03, 0.08);
        let above = |p: [f64; 3]| [p[0], p[1], p[2] + hover];
        let low: Vec<[f64; 3]> = ws.points.iter().copied().filter(|&p| ws.comfortable(p)).collect();
        let z_floor = low.iter().map(|p| p[2]).fold(f64::INFINITY, f64::min);
        let near_table = |p: &[f64; 3]| p[2] <= z_floor + 0.1 * ws.reach && ws.comfortable(above(*p));
        let mut found = None;
        let mut tries = 0;
        'search: for pick in low.iter().copied().filter(near_table) {
            for place in low.iter().copied().filter(near_table) {
                let apart = distance(pick, place);
                if apart < shortest || apart > longest || (pick[2] - place[2]).abs() > 0.02 * ws.reach {
                    continue;
                }
                tries += 1;
                if tries > MAX_PAIRS {
                    break 'search;
                }
                let path = [here, above(pick), pick, above(pick), above(place), place, above(place), home];
                if ws.follow_all(&q, &path).is_some() {
                    found = Some((pick, place));
                    break 'search;
                }
            }
        }
        let Some((pick, place)) = found else {
            bail!("arm {name}: found no pick and place points its tool reaches on straight lines");
        };
        let object_mm = gripper.map(|g| OBJECT_MM.min(0.5 * g.opening_mm));
        let opening = |pct: f32| gripper.map(|_| pct);
        // Each leg at PATH_SPEED, none shorter than `least` seconds; the jaws close and open over
        // a second (the grippers' speed is a full stroke a second, so the ramp is not cut short).
        let mut waypoints = Vec::new();
        let mut t = 0.0f32;
        let mut at = |from: [f64; 3], to: [f64; 3], least: f32, pct: f32| {
            t += (distance(from, to) as f32 / PATH_SPEED).max(least);
            waypoints.push((t, f32s(to), opening(pct)));
        };
        at(here, above(pick), 1.0, OPEN);
        at(above(pick), pick, 0.8, OPEN);
        at(pick, pick, 1.0, CLOSED);
        at(pick, pick, 0.4, CLOSED);
        at(pick, above(pick), 0.8, CLOSED);
        at(above(pick), above(place), 1.4, CLOSED);
        at(above(place), place, 0.8, CLOSED);
        at(place, place, 1.0, OPEN);
        at(place, place, 0.2, OPEN);
        at(place, above(place), 0.8, OPEN);
        at(above(place), home, 1.4, OPEN);
        Ok(Self {
            targets,
            speed: MOVE_SPEED,
            waypoints,
            pick: f32s(pick),
            place: f32s(place),
            object_mm,
            keyframe_spacing: 0.2,
        })
    }

    /// The keyframes streamed: the path between waypoints sampled every `keyframe_spacing`
    /// seconds on straight lines, waypoints included, the gripper's opening linear between them.
    pub fn keyframes(&self) -> Vec<(f32, [f32; 3], Option<f32>)> {
        let mut out = vec![self.waypoints[0]];
        for pair in self.waypoints.windows(2) {
            let ((t0, a, ga), (t1, b, gb)) = (pair[0], pair[1]);
            let steps = ((t1 - t0) / self.keyframe_spacing).round().max(1.0) as usize;
            for s in 1..=steps {
                let u = s as f32 / steps as f32;
                let g = ga.zip(gb).map(|(ga, gb)| ga + u * (gb - ga));
                out.push((t0 + u * (t1 - t0), [0, 1, 2].map(|i| a[i] + u * (b[i] - a[i])), g));
            }
        }
        out
    }
}
