//! The planner's property test: SO-101 and OpenManipulator-X on their table with the box of
//! [`boxed_scene`]. 1000 random targets across the whole joint ranges (fixed seed): every one in
//! contact (by the scene itself, on the arm crate's forward kinematics) is refused by the
//! planner's check of its ends ([`check_ends`], what every plan and move asks first), naming the
//! pair, and no free one is. Then moves that the box is likely to block (from
//! a free target low beside it to its mirror image across the arm's plane of symmetry), the
//! first [`PLANNED`] whose straight joint segment is blocked: each is planned, and the played
//! keyframes, sampled every quarter of the margin of motion, keep the margin at every sample by
//! the scene's own closest pair. Sized for the test profile on two shared cores; the success rate
//! and the lengths over 1000 blocked moves are `armctl bench plan`'s (docs/collisions.md). The
//! figures print with `cargo test -p armctl --lib plan_property -- --nocapture`.

use kinematics::SplitMix64;

use super::collision::{Checker, Hermite, Segment};
use super::plan::{boxed_scene, check_ends, keyframes, length, plan, Options, PlanError};
use crate::arm::dof::build;
use crate::arm::ArmSpec;

/// Random targets drawn.
const TARGETS: usize = 1000;
/// Blocked moves planned per arm.
const PLANNED: usize = 8;

fn run(name: &str) {
    let arm = build(ArmSpec::load(name, None).unwrap()).unwrap();
    let spec = boxed_scene(arm.as_ref()).unwrap();
    let mut checker = Checker::new(arm.as_ref(), spec.clone()).unwrap();
    let mut scene = spec.scene::<f64, 24, 8>(arm.spec().dof()).unwrap();
    let mut rng = SplitMix64::new(45);
    let options = Options::default();
    // The zero pose, or the first free one drawn.
    let mut start = vec![0.0; arm.spec().dof()];
    while !checker.is_free(&start) {
        start = arm.random_configuration(&mut rng);
    }
    let (mut refused, mut free) = (0, Vec::new());
    for _ in 0..TARGETS {
        let goal = arm.random_configuration(&mut rng);
        let touching = scene.first_contact(&arm.joint_frames(&goal).unwrap());
        match (check_ends(&mut checker, &start, &goal), touching) {
            (Err(PlanError::InCollision { which: "the goal", said }), Some(contact)) => {
                assert_eq!(said, spec.describe(&contact));
                refused += 1;
            }
            (Err(PlanError::InCollision { which: "the goal", said }), None) => panic!("{name}: {goal:?}: {said}"),
            (_, Some(contact)) => panic!("{name}: {goal:?} not refused: {}", spec.describe(&contact)),
            (_, None) => free.push(goal),
        }
    }
    // Low beside the box, to the mirror image across the arm's plane (the pan and the roll
    // negated): the box in between.
    let mirror = |q: &[f64]| -> Vec<f64> {
        let mut m = q.to_vec();
        m[0] = -m[0];
        m
    };
    let (mut blocked, mut planned, mut lengths) = (0, 0, (0.0, 0.0));
    for a in &free {
        if planned == PLANNED {
            break;
        }
        let b = mirror(a);
        if arm.tool_pose(a).unwrap().translation.z > 0.15 || !arm.admits(&b) || !checker.is_free(&b) {
            continue;
        }
        if checker.straight_free(a, &b) {
            continue;
        }
        blocked += 1;
        let path = match plan(&mut checker, a, &b, &options) {
            Ok(path) => path,
            Err(e) => {
                println!("{name}: from {a:?} to {b:?}: {e}");
                continue;
            }
        };
        planned += 1;
        lengths.0 += path.length();
        lengths.1 += length(&[a.clone(), b.clone()]);
        let k = keyframes(&path.corners, 2.0, 8.0, None);
        let (mut from, zero) = (a.clone(), vec![0.0; a.len()]);
        for p in &k.positions {
            let h = Hermite::new(&from, &zero, p, &zero);
            let n = (checker.motion(&h.speed(0.0, 1.0)) / (0.25 * spec.margin)).ceil().max(1.0) as usize;
            for i in 0..=n {
                let closest = scene.closest(&arm.joint_frames(&h.at(i as f64 / n as f64)).unwrap()).unwrap();
                assert!(closest.distance >= spec.margin, "{name}: {}", spec.describe(&closest));
            }
            from = p.clone();
        }
    }
    println!(
        "{name}: {TARGETS} targets, {refused} in contact and refused, {} free; {blocked} blocked moves, {planned} \
         planned, {:.2} rad of joint motion against {:.2} rad straight; {} configurations checked",
        free.len(),
        lengths.0,
        lengths.1,
        checker.checks()
    );
    assert!(refused > 0 && free.len() > 100, "{name}: {refused} refused, {} free", free.len());
    assert_eq!(planned, PLANNED, "{name}: {planned} of {blocked} blocked moves planned");
}

#[test]
fn plan_property_so101() {
    run("so101");
}

#[test]
fn plan_property_open_manipulator_x() {
    run("open-manipulator-x");
}
