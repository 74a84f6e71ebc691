//! Arm files through `ArmSpec::load`, as the command line reads them: the real SO-101 and SO-100
//! URDFs (copied into tests/data, see its README) and the example TOML arm files.

use armctl::arm::ArmSpec;
use kinematics::nalgebra::SVector;
use kinematics::SplitMix64;

fn path(relative: &str) -> String {
    format!("{}/{relative}", env!("CARGO_MANIFEST_DIR"))
}

#[test]
fn so101_urdf_reproduces_the_preset() {
    let urdf = ArmSpec::load(&path("tests/data/so101_new_calib.urdf"), Some("gripper_frame_link")).unwrap();
    let names: Vec<&str> = urdf.joints.iter().map(|j| j.name.as_str()).collect();
    assert_eq!(names, ["shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "wrist_roll"]);
    let preset = ArmSpec::load("so101", None).unwrap();
    let (urdf, preset) = (urdf.chain::<f64, 5>().unwrap(), preset.chain::<f64, 5>().unwrap());
    let mut rng = SplitMix64::new(2024);
    for _ in 0..10 {
        let q = SVector::<f64, 5>::from_fn(|i, _| {
            let l = preset.joints()[i].limits;
            rng.uniform(l.lower, l.upper)
        });
        let (a, b) = (urdf.tool_pose(&q), preset.tool_pose(&q));
        assert!((a.translation - b.translation).amax() <= 1e-9, "q = {q:?}");
        assert!((a.rotation - b.rotation).amax() <= 1e-9, "q = {q:?}");
    }
}

#[test]
fn so101_urdf_needs_a_tip() {
    let e = ArmSpec::load(&path("tests/data/so101_new_calib.urdf"), None).unwrap_err();
    let message = format!("{e:#}");
    assert!(
        message.contains("(--tip, or tip= in Python), one of gripper_frame_link, moving_jaw_so101_v1_link"),
        "{message}"
    );
}

#[test]
fn so100_urdf_imports_to_the_gripper() {
    let spec = ArmSpec::load(&path("tests/data/so100.urdf"), Some("gripper")).unwrap();
    assert_eq!(spec.name, "so_arm100");
    assert_eq!(spec.dof(), 5);
    let chain = spec.chain::<f64, 5>().unwrap();
    // Every joint at zero: a finite tool pose within the arm's reach (under half a metre).
    let p = chain.tool_pose(&SVector::zeros()).translation;
    assert!(p.norm() < 0.5, "{p}");
}

#[test]
fn example_arm_files_load() {
    let mine = ArmSpec::load(&path("examples/arms/my-arm.toml"), None).unwrap();
    assert_eq!(mine.dof(), 4);
    mine.chain::<f64, 4>().unwrap();
    let ur5e = ArmSpec::load(&path("examples/arms/ur5e-dh.toml"), None).unwrap().chain::<f64, 6>().unwrap();
    let preset = ArmSpec::load("ur5e", None).unwrap().chain::<f64, 6>().unwrap();
    let q = SVector::<f64, 6>::from([0.3, -1.2, 1.0, -0.5, 1.1, 0.2]);
    let (a, b) = (ur5e.tool_pose(&q), preset.tool_pose(&q));
    assert!((a.translation - b.translation).amax() <= 1e-12);
    assert!((a.rotation - b.rotation).amax() <= 1e-12);
}
