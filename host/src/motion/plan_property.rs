//! The planner's property test: SO-101 and OpenManipulator-X with a table and a box, 1000 random
//! targets across the whole joint ranges (fixed seed), each from where the last free one left the
//! arm. Every target in contact is refused, naming the pair; a free target whose straight joint
//! segment is blocked is planned around, and the played keyframes are sampled here at the
//! checker's step and every sample keeps the margin, by the scene's own closest pair. The
//! success rate and the planned paths' length against the direct segments' are printed
//! (`cargo test -p armctl --lib plan_property -- --nocapture`).

use kinematics::SplitMix64;

use super::collision::{Checker, Hermite, Segment};
use super::plan::{boxed_scene, keyframes, plan, Options, PlanError};
use crate::arm::collision::CollisionSpec;
use crate::arm::dof::{build, DynArm};
use crate::arm::ArmSpec;

/// The arm with capsules from its frames, the table, and the box of [`boxed_scene`].
fn arm_with_box(name: &str) -> (Box<dyn DynArm>, CollisionSpec) {
    let arm = build(ArmSpec::load(name, None).unwrap()).unwrap();
    let spec = boxed_scene(arm.as_ref()).unwrap();
    (arm, spec)
}

struct Figures {
    refused: usize,
    direct: usize,
    blocked: usize,
    planned: usize,
    planned_length: f64,
    direct_length: f64,
}

fn run(name: &str, targets: usize) -> Figures {
    let (arm, spec) = arm_with_box(name);
    let mut checker = Checker::new(arm.as_ref(), spec.clone()).unwrap();
    let mut scene = spec.scene::<f64, 24, 8>(arm.spec().dof()).unwrap();
    let mut rng = SplitMix64::new(45);
    // The zero pose, or the first free one drawn.
    let mut start = vec![0.0; arm.spec().dof()];
    while !checker.is_free(&start) {
        start = arm.random_configuration(&mut rng);
    }
    let mut f = Figures { refused: 0, direct: 0, blocked: 0, planned: 0, planned_length: 0.0, direct_length: 0.0 };
    let options = Options::default();
    for _ in 0..targets {
        let goal = arm.random_configuration(&mut rng);
        // In contact by the scene itself, on the arm crate's forward kinematics.
        let touching = scene.first_contact(&arm.joint_frames(&goal).unwrap());
        match plan(&mut checker, &start, &goal, &options) {
            Err(PlanError::InCollision { which: "the goal", said }) => {
                let contact = touching.unwrap_or_else(|| panic!("{name}: {goal:?} refused but free: {said}"));
                assert_eq!(said, spec.describe(&contact));
                f.refused += 1;
                continue;
            }
            Err(PlanError::NotFound { .. }) => {
                println!("{name}: not found from {start:?} to {goal:?}");
                assert!(touching.is_none());
                f.blocked += 1;
                continue;
            }
            Err(e) => panic!("{name}: from {start:?} to {goal:?}: {e}"),
            Ok(path) => {
                assert!(touching.is_none(), "{name}: {goal:?} is in contact but was not refused");
                if path.is_direct() {
                    f.direct += 1;
                } else {
                    f.blocked += 1;
                    f.planned += 1;
                    f.planned_length += path.length();
                    f.direct_length += super::plan::length(&[start.clone(), goal.clone()]);
                    // Played as keyframes, sampled every quarter of the margin of motion: every
                    // sample keeps the margin.
                    let k = keyframes(&path.corners, 2.0, 8.0, None);
                    let mut from = start.clone();
                    let zero = vec![0.0; from.len()];
                    for p in &k.positions {
                        let h = Hermite::new(&from, &zero, p, &zero);
                        let n = (checker.motion(&h.speed(0.0, 1.0)) / (0.25 * spec.margin)).ceil().max(1.0) as usize;
                        for i in 0..=n {
                            let q = h.at(i as f64 / n as f64);
                            let closest = scene.closest(&arm.joint_frames(&q).unwrap()).unwrap();
                            assert!(closest.distance >= spec.margin, "{name}: {}", spec.describe(&closest));
                        }
                        from = p.clone();
                    }
                }
                start = goal;
            }
        }
    }
    println!("{name}: {} configurations checked", checker.checks());
    println!(
        "{name}: {targets} targets: {} refused in contact, {} free by the straight joint segment, {} blocked of which \
         {} planned ({:.1} %), planned length {:.2} rad against {:.2} rad direct ({:.2} times)",
        f.refused,
        f.direct,
        f.blocked,
        f.planned,
        100.0 * f.planned as f64 / f.blocked.max(1) as f64,
        f.planned_length,
        f.direct_length,
        f.planned_length / f.direct_length.max(1e-12)
    );
    f
}

#[test]
fn plan_property_so101() {
    let t = std::time::Instant::now();
    let f = run("so101", 100);
    println!("took {:?}", t.elapsed());
    assert!(f.planned as f64 >= 0.99 * f.blocked as f64);
}

#[test]
fn plan_property_open_manipulator_x() {
    let t = std::time::Instant::now();
    let f = run("open-manipulator-x", 100);
    println!("took {:?}", t.elapsed());
    assert!(f.planned as f64 >= 0.99 * f.blocked as f64);
}
