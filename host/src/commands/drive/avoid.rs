//! Joint moves checked against the arm's collision geometry before anything is sent, for every
//! front end (`armctl joints`, `move` once it goes by joints, the view's Go, Python, a rig): a
//! goal in collision is refused at once, naming the pair; a free goal whose straight joint
//! segment is free goes as one joint move (`joint`); one whose segment is blocked goes by a
//! planned path ([`crate::motion::plan`]), streamed as keyframes at rest at each corner
//! (`planned`). An arm without collision geometry is not checked: its moves go straight, as
//! before.

use anyhow::anyhow;
use firmware::link::message::{JointKeyframe, Joints, Timing};

use crate::link::client::LinkError;
use crate::link::session::Keyframe;
use crate::motion::collision::{shown, Checker};
use crate::motion::mocap::retarget::timebase::limits_of;
use crate::motion::plan::{self, keyframes, Keyframes, Options, PlanError};
use crate::runtime::driver::Driver;

/// How a checked joint move went out.
#[derive(Clone, Debug, PartialEq)]
pub struct Sent {
    /// "joint" (the straight joint segment) or "planned" (around what was in the way).
    pub path: &'static str,
    /// Keyframes of the planned path (0 for a straight move).
    pub keyframes: usize,
    /// The planned path's joint-space length (rad), and the straight segment's.
    pub lengths: Option<(f64, f64)>,
    /// Why it was planned, in words.
    pub why: Option<String>,
}

/// Why a joint move was not sent, or was refused.
#[derive(Debug)]
pub enum NotSent {
    /// The host's check: the goal (or the start) in collision, no path found, a geometry that
    /// cannot be checked.
    Host(anyhow::Error),
    /// The link or the firmware.
    Link(LinkError),
}

impl std::fmt::Display for NotSent {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            NotSent::Host(e) => write!(f, "{e:#}"),
            NotSent::Link(e) => write!(f, "{e}"),
        }
    }
}

/// The host's check of the arm the driver runs against its geometry; `None` where there is
/// nothing to check: no geometry, or the check turned off (`--no-collision-check`, the firmware's
/// too).
pub fn host_checker(driver: &Driver) -> anyhow::Result<Option<Checker<'_>>> {
    if !driver.collision_checked() {
        return Ok(None);
    }
    Checker::of(driver.model())
}

/// Refuses `goal` if it is in collision (`what` names it: "the target", "the host's
/// solution"); Ok for an arm without collision geometry.
pub fn check_goal(driver: &Driver, goal: &[f64], what: &str) -> Result<(), NotSent> {
    let Some(mut checker) = host_checker(driver).map_err(NotSent::Host)? else { return Ok(()) };
    crate::motion::collision::refuse_contact(&mut checker, goal, what).map_err(NotSent::Host)
}

/// Sends the move from `start` (where the arm stands) to `goal` (checked against the limits
/// already), as a straight joint move where that is free and as a planned path where it is not;
/// refuses a goal in collision, naming the pair. `timing`: a joint speed cap or a duration.
pub fn send(driver: &mut Driver, start: &[f64], goal: &[f64], timing: Timing) -> Result<Sent, NotSent> {
    let straight = Sent { path: "joint", keyframes: 0, lengths: None, why: None };
    let planned = {
        let Some(mut checker) = host_checker(driver).map_err(NotSent::Host)? else {
            return send_straight(driver, goal, timing).map(|()| straight);
        };
        crate::motion::collision::refuse_contact(&mut checker, goal, "the target").map_err(NotSent::Host)?;
        let Some(blocked) = checker.straight(start, goal).map_err(NotSent::Host)? else {
            drop(checker);
            return send_straight(driver, goal, timing).map(|()| straight);
        };
        let why = format!("the straight joint path is blocked: {}", checker.describe_along(&blocked));
        let path = plan::plan(&mut checker, start, goal, &Options::default()).map_err(|e| {
            NotSent::Host(match e {
                PlanError::NotFound { .. } => anyhow!("{why}, and {e}"),
                other => anyhow!("{other}"),
            })
        })?;
        (path, why)
    };
    let (path, why) = planned;
    let (mut max_velocity, max_acceleration) = limits_of(driver.model());
    let duration = match timing {
        Timing::MaxSpeed(s) => {
            max_velocity = max_velocity.min(f64::from(s));
            None
        }
        Timing::Duration(d) => Some(f64::from(d)),
    };
    let k = keyframes(&path.corners, max_velocity, max_acceleration, duration);
    stream(driver, &k)?;
    let direct = plan::length(&[start.to_vec(), goal.to_vec()]);
    Ok(Sent {
        path: "planned",
        keyframes: k.times.len(),
        lengths: Some((path.length(), direct)),
        why: Some(format!(
            "{why}, so the arm went around it by a planned path of {} keyframes ({:.2} rad of joint motion \
             against {direct:.2} straight)",
            k.times.len(),
            path.length()
        )),
    })
}

fn send_straight(driver: &mut Driver, goal: &[f64], timing: Timing) -> Result<(), NotSent> {
    let positions = joints(goal).map_err(NotSent::Host)?;
    driver.session().move_joints(positions, timing).map_err(NotSent::Link)
}

fn joints(q: &[f64]) -> anyhow::Result<Joints> {
    Joints::from_slice(&q.iter().map(|&x| x as f32).collect::<Vec<_>>())
        .map_err(|_| anyhow!("{}: more joints than the link carries", shown(q)))
}

/// Queues the keyframes (as far as the queue holds), starts them, and pushes the rest as slots
/// free up. A queue left from before is dropped first: it is not part of this move.
fn stream(driver: &mut Driver, k: &Keyframes) -> Result<(), NotSent> {
    let mut frames = Vec::with_capacity(k.times.len());
    for ((t, p), v) in k.times.iter().zip(&k.positions).zip(&k.velocities) {
        let (positions, velocities) = (joints(p).map_err(NotSent::Host)?, joints(v).map_err(NotSent::Host)?);
        frames.push(Keyframe::Joints(JointKeyframe {
            time: *t as f32,
            positions,
            velocities: Some(velocities),
            gripper: None,
        }));
    }
    if driver.status().map_err(NotSent::Host)?.queued > 0 {
        driver.session().stop().map_err(NotSent::Link)?;
    }
    let first = frames.len().min(driver.queue_capacity().max(1));
    let session = driver.session();
    for frame in &frames[..first] {
        session.push(frame).map_err(NotSent::Link)?;
    }
    session.start().map_err(NotSent::Link)?;
    for frame in &frames[first..] {
        session.push(frame).map_err(NotSent::Link)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use firmware::link::message::MovePath;

    use super::*;
    use crate::commands::drive::joints::{joints, JointsRequest};
    use crate::commands::drive::move_to::{move_to, MoveRequest};
    use crate::motion::collision::tests::so101_with_box;
    use crate::runtime::connection::Place;

    /// The SO-101 in SIL, the host checking against capsules from its frames, the table and a box.
    fn driver() -> (Driver, crate::arm::collision::CollisionSpec) {
        let place = Place { sim: true, arm: Some("so101".into()), ..Place::default() };
        let (target, arm) = place.target_and_arm().unwrap();
        let mut driver = Driver::open(target, arm, &mut std::io::sink()).unwrap();
        let (_, spec) = so101_with_box();
        driver.set_collision(Some(spec.clone())).unwrap();
        (driver, spec)
    }

    /// Every goal the servos got in the run recorded, checked by the test against the scene.
    fn every_goal_keeps_the_margin(driver: &mut Driver, spec: &crate::arm::collision::CollisionSpec) -> usize {
        let trace = driver.sil().unwrap().take_trace();
        let mut scene = spec.scene::<f64, 24, 8>(5).unwrap();
        for sample in &trace {
            let frames = driver.model().joint_frames(&sample.setpoints).unwrap();
            if let Some(contact) = scene.first_contact(&frames) {
                panic!("at {:.3} s the servos got {:?}: {}", sample.time, sample.setpoints, spec.describe(&contact));
            }
        }
        trace.len()
    }

    /// `joints` to a target in collision is refused naming the pair, and nothing moves; from one
    /// side of the box to the other, the arm goes around it by a planned path, and no goal the
    /// servos got comes within the margin of anything.
    #[test]
    fn joints_refuses_a_target_in_collision_and_plans_around_the_box() {
        let (mut driver, spec) = driver();
        let (left, right) = (vec![0.8, -0.2, 0.5, 1.0, 0.0], vec![-0.8, -0.2, 0.5, 1.0, 0.0]);
        // The simulated horns, not the firmware's reading: the first reading after the arm is
        // sent again can be the previous arm's mapping's.
        let horns = |driver: &mut Driver| driver.sil().unwrap().horns();
        let before = horns(&mut driver);
        let inside = JointsRequest::new(vec![0.0, 0.5, 0.5, 0.5, 0.0], None, None, 20.0).unwrap();
        let e = joints(&mut driver, &inside, &mut std::io::sink()).unwrap_err().to_string();
        assert!(
            e.contains("the target is in collision: elbow_flex and box overlap") && e.contains("nothing moved"),
            "{e}"
        );
        assert_eq!(horns(&mut driver), before, "a servo moved");

        let there = joints(&mut driver, &JointsRequest::new(left, None, None, 20.0).unwrap(), &mut std::io::sink());
        assert!(there.is_ok(), "{:?}", there.err().map(|e| e.to_string()));
        driver.sil().unwrap().record();
        let report =
            joints(&mut driver, &JointsRequest::new(right.clone(), None, None, 30.0).unwrap(), &mut std::io::sink())
                .unwrap();
        assert_eq!(report.path, "planned", "{report:?}");
        assert!(report.planned_keyframes >= 2 && report.max_error < 0.01, "{report:?}");
        assert!(report.text().contains("the straight joint path is blocked: "), "{}", report.text());
        assert!(every_goal_keeps_the_margin(&mut driver, &spec) > 100);
    }

    /// `move` to a point inside the box is refused naming the pair; to the tool's place on the
    /// far side of the box, past it, by a path that keeps the margin at every goal.
    #[test]
    fn move_refuses_a_point_in_the_box_and_goes_around_it_to_one_beyond() {
        let (mut driver, spec) = driver();
        let (left, right) = (vec![0.8, -0.2, 0.5, 1.0, 0.0], [-0.8, -0.2, 0.5, 1.0, 0.0]);
        joints(&mut driver, &JointsRequest::new(left, None, None, 20.0).unwrap(), &mut std::io::sink()).unwrap();
        let into = MoveRequest::new([0.2, 0.0, 0.05], None, None, None, MovePath::Auto, 20.0).unwrap();
        let e = move_to(&mut driver, &into, &mut std::io::sink()).unwrap_err().to_string();
        assert!(e.contains("the target is in collision: ") && e.contains("box") && e.contains("nothing moved"), "{e}");

        let beyond: [f64; 3] = driver.model().tool_pose(&right).unwrap().translation.into();
        driver.sil().unwrap().record();
        let request = MoveRequest::new(beyond, None, None, None, MovePath::Auto, 30.0).unwrap();
        let report = move_to(&mut driver, &request, &mut std::io::sink()).unwrap();
        assert!(report.path == "planned" || report.path == "joint", "{report:?}");
        assert!(report.error_mm < 2.0, "{report:?}");
        assert!(report.text().contains("the straight line is blocked"), "{}", report.text());
        assert!(every_goal_keeps_the_margin(&mut driver, &spec) > 100);
    }

    /// `play` checks the whole file before anything moves and names the first keyframe pair
    /// whose segment, as the player plays it, collides.
    #[test]
    fn play_names_the_first_keyframe_pair_that_collides_and_nothing_moves() {
        let (mut driver, _) = driver();
        let left = vec![0.8, -0.2, 0.5, 1.0, 0.0];
        joints(&mut driver, &JointsRequest::new(left, None, None, 20.0).unwrap(), &mut std::io::sink()).unwrap();
        let before = driver.status().unwrap().measured;
        let text = "t,q1,q2,q3,q4,q5\n1,0.8,-0.3,0.5,1.0,0\n2,0.8,-0.2,0.5,1.0,0\n4,-0.8,-0.2,0.5,1.0,0\n";
        let plan = crate::commands::drive::play::Plan::parse(text, std::path::Path::new("sweep.csv"), 30.0).unwrap();
        let e = crate::commands::drive::play::play(&mut driver, &plan, &mut std::io::sink()).unwrap_err().to_string();
        assert!(
            e.starts_with("sweep.csv: between keyframes 2 and 3 (lines 3 and 4): ")
                && e.contains(" and box ")
                && e.ends_with("; nothing was sent, nothing moved"),
            "{e}"
        );
        assert_eq!(driver.status().unwrap().measured, before);
    }
}
