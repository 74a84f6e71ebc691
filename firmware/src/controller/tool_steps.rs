//! End-effector steps (issue 43, item 2): small steps of the tool in every direction, its
//! orientation held, from random starts across the joint ranges, as LeRobot's end-effector actions
//! send them (Python's `send_pose`, a Cartesian keyframe, `Command::PushToolKeyframe`). On an arm
//! of fewer than six joints the orientation is a tilt (its yaw follows the pan); whether a step is
//! reachable is decided independently, by the f64 solver with many restarts.

use super::{joint_limits, Command, Config, Controller, Refusal};
use crate::bus::mapping::JointMapping;
use crate::bus::table::STS3215;
use kinematics::ik::{IkConfig, IkProblem, IkStatus, Target};
use kinematics::nalgebra::{SVector, Vector3};
use kinematics::trajectory::PlayerKeyframe;
use kinematics::{presets, Chain, Pose, SplitMix64};

fn controller<const N: usize>(chain: Chain<f32, N>) -> Controller<N, 32> {
    let mappings: [JointMapping; N] = core::array::from_fn(|i| JointMapping::centred(i as u8 + 1, 4096));
    let limits = joint_limits(&chain, &mappings, SVector::repeat(1.5), SVector::repeat(6.0)).unwrap();
    Controller::new(chain, mappings, &STS3215, limits, Config::default()).unwrap()
}

/// The angle between the base's z seen from the tool at `current` and from one at `target`.
fn tilt_angle(target: &Pose<f64>, current: &Pose<f64>) -> f64 {
    let (a, b): (Vector3<f64>, Vector3<f64>) =
        (current.rotation.row(2).transpose(), target.rotation.row(2).transpose());
    a.cross(&b).norm().atan2(a.dot(&b))
}

/// What the steps came to.
#[derive(Debug, Default)]
struct Tally {
    steps: usize,
    /// Reachable by the independent check, or by the firmware's own (checked) answer.
    reachable: usize,
    /// Accepted by the firmware, and its keyframe checked by FK in f64.
    executed: usize,
    /// Refused although reachable.
    missed: usize,
}

/// `steps` random steps of 5 to 20 mm in random directions, each from a random start within the
/// middle 90 % of every joint's range, the orientation held as it was at the start.
fn steps<const N: usize>(chain32: Chain<f32, N>, chain64: &Chain<f64, N>, steps: usize, seed: u64) -> Tally {
    let mut ctl = controller(chain32);
    let mut rng = SplitMix64::new(seed);
    let (position_tolerance, orientation_tolerance) = (1e-4, 1e-3);
    let mut tally = Tally::default();
    for _ in 0..steps {
        let start = SVector::<f32, N>::from_fn(|i, _| {
            let l = ctl.limits;
            let margin = (l.upper[i] - l.lower[i]) * 0.05;
            rng.uniform(l.lower[i] + margin, l.upper[i] - margin)
        });
        let here = ctl.chain.tool_pose(&start);
        let direction = loop {
            let d = Vector3::new(rng.uniform(-1.0f32, 1.0), rng.uniform(-1.0, 1.0), rng.uniform(-1.0, 1.0));
            if d.norm() > 0.1 && d.norm() <= 1.0 {
                break d.normalize();
            }
        };
        let position: [f32; 3] = (here.translation + direction * rng.uniform(0.005f32, 0.020)).into();
        let orientation = here.quaternion_wxyz();

        // The keyframe before is the start (the seed of the next); the tool's follows it.
        let keyframe = PlayerKeyframe { time: 1.0, position: start, velocity: None };
        ctl.command(Command::PushKeyframe { keyframe, gripper: None }, 0).unwrap();
        let pushed = ctl.command(
            Command::PushToolKeyframe { time: 2.0, position, orientation: Some(orientation), gripper: None },
            0,
        );
        let q = ctl.queue_tail;
        ctl.command(Command::Stop, 0).unwrap();

        let rotation = Pose::rotation_from_quaternion_wxyz(orientation.map(f64::from)).unwrap();
        let target = Pose { rotation, translation: Vector3::from(position.map(f64::from)) };
        tally.steps += 1;
        match pushed {
            Ok(()) => {
                // Checked here in f64: within the limits, at the position, tilted as the start.
                let q = q.map(f64::from);
                let reached = chain64.tool_pose(&q);
                assert!(chain64.admits(&q), "{q:?}");
                let (dp, tilt) = ((reached.translation - target.translation).norm(), tilt_angle(&target, &reached));
                assert!(dp <= position_tolerance + 1e-5 && tilt <= orientation_tolerance + 1e-5, "{dp} m, {tilt} rad");
                tally.executed += 1;
                tally.reachable += 1;
            }
            Err(refusal) => {
                assert!(
                    matches!(refusal, Refusal::Unreachable { position_error } if position_error >= 0.0),
                    "{refusal:?}"
                );
                let config = IkConfig {
                    position_tolerance,
                    orientation_tolerance,
                    max_iterations: 40_000,
                    max_restarts: 400,
                    ..IkConfig::default()
                };
                let problem = IkProblem { target: Target::Tilt(target), seed: start.map(f64::from), config };
                if chain64.solve(&problem).status == IkStatus::Converged {
                    tally.reachable += 1;
                    tally.missed += 1;
                }
            }
        }
    }
    tally
}

fn assert_executed<const N: usize>(name: &str, chain32: Chain<f32, N>, chain64: &Chain<f64, N>, seed: u64) {
    let t = steps(chain32, chain64, 2000, seed);
    let fraction = t.executed as f64 / t.reachable as f64;
    std::println!("{name}: {t:?}, executed {:.2} % of the reachable steps", 100.0 * fraction);
    assert!(fraction >= 0.99, "{name}: {t:?}");
    // Most steps from starts within the ranges are reachable; a handful start at a limit.
    assert!(t.reachable >= t.steps * 9 / 10, "{name}: {t:?}");
}

#[test]
fn so101_executes_the_reachable_end_effector_steps() {
    assert_executed("so101", presets::so101().unwrap(), &presets::so101().unwrap(), 1);
}

/// Four joints, no wrist roll: the tilt is the pitch alone (a start's orientation has no roll to
/// keep).
#[test]
fn open_manipulator_x_executes_the_reachable_end_effector_steps() {
    let (chain32, chain64) = (presets::open_manipulator_x().unwrap(), presets::open_manipulator_x().unwrap());
    assert_executed("open-manipulator-x", chain32, &chain64, 2);
}

/// A five-joint yaw-pitch arm of other proportions than the SO-101's (round numbers of a desk
/// arm's size, its pan's axis along the base's z, the roll's along the forearm, wider ranges),
/// standing in for the Koch, of which the repository has no preset.
fn other_proportions<T: kinematics::Real>() -> Chain<T, 5> {
    let at = |x: f64, z: f64| Pose::from_xyz_rpy([T::of(x), T::zero(), T::of(z)], [T::zero(); 3]);
    let (z, y, x) = ([0.0, 0.0, 1.0].map(T::of), [0.0, 1.0, 0.0].map(T::of), [1.0, 0.0, 0.0].map(T::of));
    let limits = |m: f64| kinematics::Limits::symmetric(T::of(m));
    let joints = [
        kinematics::Joint::revolute(at(0.0, 0.05), z, limits(2.8)),
        kinematics::Joint::revolute(at(0.0, 0.03), y, limits(1.6)),
        kinematics::Joint::revolute(at(0.03, 0.11), y, limits(1.7)),
        kinematics::Joint::revolute(at(0.10, 0.0), y, limits(1.7)),
        kinematics::Joint::revolute(at(0.045, 0.0), x, limits(2.8)),
    ];
    Chain::new(joints, at(0.05, 0.0)).unwrap()
}

#[test]
fn a_five_joint_arm_of_other_proportions_executes_the_reachable_end_effector_steps() {
    assert_executed("other proportions", other_proportions(), &other_proportions(), 3);
}

/// A six-joint arm keeps the full pose: a step with the orientation held ends at that orientation.
#[test]
fn a_six_joint_arm_keeps_the_full_orientation() {
    let chain64 = presets::ur5e::<f64>().unwrap();
    let mut ctl = controller(presets::ur5e::<f32>().unwrap());
    let start = SVector::<f32, 6>::from([0.3, -1.2, 1.0, -0.5, 1.1, 0.2]);
    let here = ctl.chain.tool_pose(&start);
    let position: [f32; 3] = (here.translation + Vector3::new(0.0, 0.01, 0.0)).into();
    let orientation = here.quaternion_wxyz();
    let keyframe = PlayerKeyframe { time: 1.0, position: start, velocity: None };
    ctl.command(Command::PushKeyframe { keyframe, gripper: None }, 0).unwrap();
    ctl.command(Command::PushToolKeyframe { time: 2.0, position, orientation: Some(orientation), gripper: None }, 0)
        .unwrap();
    let reached = chain64.tool_pose(&ctl.queue_tail.map(f64::from));
    let full = kinematics::rotation_error(&here.rotation.map(f64::from), &reached.rotation).norm();
    assert!(full <= 1e-3 + 1e-5, "{full} rad");
}
