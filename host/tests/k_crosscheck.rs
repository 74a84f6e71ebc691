//! Our forward kinematics against an independent library's: every preset and the example TOML arm
//! are built a second time as a chain of openrr's `k` crate (`armctl::commands::bench::k::KArm`), and the
//! two tool poses must agree to 1e-12 at random joint vectors within the limits.

use armctl::arm::dof;
use armctl::arm::ArmSpec;
use armctl::commands::bench::k::KArm;
use kinematics::SplitMix64;

const TOLERANCE: f64 = 1e-12;
const SAMPLES: usize = 50;

fn path(relative: &str) -> String {
    format!("{}/{relative}", env!("CARGO_MANIFEST_DIR"))
}

/// Largest component difference between two quaternions, up to their sign (q and -q are the same
/// rotation).
fn quaternion_distance(a: [f64; 4], b: [f64; 4]) -> f64 {
    let same = a.iter().zip(&b).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max);
    let opposite = a.iter().zip(&b).map(|(x, y)| (x + y).abs()).fold(0.0, f64::max);
    same.min(opposite)
}

fn crosscheck(arm: &str, rng_seed: u64) {
    let spec = ArmSpec::load(arm, None).unwrap_or_else(|e| panic!("{arm}: {e:#}"));
    let k_arm = KArm::new(&spec).unwrap_or_else(|e| panic!("{arm}: k: {e:#}"));
    let ours = dof::build(spec).unwrap_or_else(|e| panic!("{arm}: {e:#}"));
    let mut rng = SplitMix64::new(rng_seed);
    for _ in 0..SAMPLES {
        let q = ours.random_configuration(&mut rng);
        assert!(ours.admits(&q), "{arm}: sampled q = {q:?} outside the limits");
        let pose = ours.tool_pose(&q).unwrap();
        let (k_position, k_quaternion) = k_arm.tool_pose(&q).unwrap_or_else(|e| panic!("{arm}: q = {q:?}: {e:#}"));
        let position: [f64; 3] = pose.translation.into();
        let position_difference = position.iter().zip(&k_position).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
        assert!(
            position_difference <= TOLERANCE,
            "{arm}: q = {q:?}: position {position:?} vs k {k_position:?} ({position_difference:e})"
        );
        let quaternion = pose.quaternion_wxyz();
        let norm = quaternion.iter().map(|v| v * v).sum::<f64>().sqrt();
        assert!((norm - 1.0).abs() <= TOLERANCE, "{arm}: q = {q:?}: |quaternion| = {norm}");
        let rotation_difference = quaternion_distance(quaternion, k_quaternion);
        assert!(
            rotation_difference <= TOLERANCE,
            "{arm}: q = {q:?}: quaternion {quaternion:?} vs k {k_quaternion:?} ({rotation_difference:e})"
        );
    }
}

#[test]
fn ur5e_matches_k() {
    crosscheck("ur5e", 1);
}

#[test]
fn puma560_matches_k() {
    crosscheck("puma560", 2);
}

#[test]
fn iiwa14_matches_k() {
    crosscheck("iiwa14", 3);
}

#[test]
fn so101_matches_k() {
    crosscheck("so101", 4);
}

#[test]
fn open_manipulator_x_matches_k() {
    crosscheck("open-manipulator-x", 5);
}

#[test]
fn planar5_matches_k() {
    crosscheck("planar:5", 6);
}

#[test]
fn example_toml_arm_matches_k() {
    crosscheck(&path("examples/arms/my-arm.toml"), 7);
}

/// The check itself must be able to fail: a different joint vector gives a different pose.
#[test]
fn crosscheck_detects_a_mismatch() {
    let spec = ArmSpec::load("ur5e", None).unwrap();
    let k_arm = KArm::new(&spec).unwrap();
    let ours = dof::build(spec).unwrap();
    let q = [0.3, -1.2, 1.0, -0.5, 1.1, 0.2];
    let shifted = [0.3, -1.2, 1.0, -0.5, 1.1, 0.2 + 1e-3];
    let (k_position, k_quaternion) = k_arm.tool_pose(&shifted).unwrap();
    let pose = ours.tool_pose(&q).unwrap();
    let position: [f64; 3] = pose.translation.into();
    let moved = position.iter().zip(&k_position).any(|(a, b)| (a - b).abs() > TOLERANCE);
    assert!(moved || quaternion_distance(pose.quaternion_wxyz(), k_quaternion) > TOLERANCE);
    // And k rejects a joint vector of the wrong length rather than reading past it.
    assert!(k_arm.tool_pose(&q[..5]).is_err());
}
