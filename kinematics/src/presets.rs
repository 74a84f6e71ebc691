//! The reference arms, with the published parameters of `shared/reference/arms.md`. Each
//! constructor is infallible in practice; it returns the chain or the validation error so no
//! `unwrap` is needed in no_std code.

use crate::{Chain, ChainError, DhRow, Joint, JointKind, Limits, Pose, Real};

fn xyz<T: Real>(x: f64, y: f64, z: f64) -> Pose<T> {
    Pose::from_xyz_rpy([T::of(x), T::of(y), T::of(z)], [T::zero(); 3])
}

fn origin<T: Real>(x: [f64; 3], rpy: [f64; 3]) -> Pose<T> {
    Pose::from_xyz_rpy(x.map(T::of), rpy.map(T::of))
}

fn revolute<T: Real>(origin: Pose<T>, axis: [f64; 3], lower: f64, upper: f64) -> Joint<T> {
    Joint::revolute(origin, axis.map(T::of), Limits::from_f64(lower, upper))
}

fn dh_revolute<T: Real>(a: f64, alpha: f64, d: f64, limit: f64) -> DhRow<T> {
    DhRow {
        a: T::of(a),
        alpha: T::of(alpha),
        d: T::of(d),
        theta: T::zero(),
        kind: JointKind::Revolute,
        limits: Limits::from_f64(-limit, limit),
    }
}

/// The "homework chain": N unit links in the plane, every joint about +z, the first at the origin,
/// each angle relative to the previous link. Limits +-pi (an unlimited elbow reaches every angle).
pub fn planar<T: Real, const N: usize>() -> Result<Chain<T, N>, ChainError> {
    let joints = core::array::from_fn(|k| {
        let o = if k == 0 { xyz(0.0, 0.0, 0.0) } else { xyz(1.0, 0.0, 0.0) };
        Joint::continuous(o, [T::zero(), T::zero(), T::one()])
    });
    let tool = if N == 0 { Pose::identity() } else { xyz(1.0, 0.0, 0.0) };
    Chain::new(joints, tool)
}

/// Universal Robots UR5e, standard DH ("Parameters for calculations of kinematics and dynamics"),
/// limits +-2 pi.
pub fn ur5e<T: Real>() -> Result<Chain<T, 6>, ChainError> {
    use core::f64::consts::{FRAC_PI_2, TAU};
    let rows = [
        dh_revolute(0.0, FRAC_PI_2, 0.1625, TAU),
        dh_revolute(-0.425, 0.0, 0.0, TAU),
        dh_revolute(-0.3922, 0.0, 0.0, TAU),
        dh_revolute(0.0, FRAC_PI_2, 0.1333, TAU),
        dh_revolute(0.0, -FRAC_PI_2, 0.0997, TAU),
        dh_revolute(0.0, 0.0, 0.0996, TAU),
    ];
    Chain::from_dh_standard(rows, Pose::identity())
}

/// PUMA 560, standard DH as in Corke's Robotics Toolbox (`models/DH/Puma560.py`), with its limits.
pub fn puma560<T: Real>() -> Result<Chain<T, 6>, ChainError> {
    use core::f64::consts::FRAC_PI_2;
    let a = [0.0, 0.4318, 0.0203, 0.0, 0.0, 0.0];
    let d = [0.67183, 0.0, 0.15005, 0.4318, 0.0, 0.0];
    let alpha = [FRAC_PI_2, 0.0, -FRAC_PI_2, FRAC_PI_2, -FRAC_PI_2, 0.0];
    let limits_deg: [f64; 6] = [160.0, 110.0, 135.0, 266.0, 100.0, 266.0];
    let rows = core::array::from_fn(|i| dh_revolute(a[i], alpha[i], d[i], limits_deg[i].to_radians()));
    Chain::from_dh_standard(rows, Pose::identity())
}

/// KUKA LBR iiwa 14 R820 (ros-industrial kuka_experimental `lbr_iiwa_14_r820_macro.xacro`), base to
/// flange (`tool0`).
pub fn iiwa14<T: Real>() -> Result<Chain<T, 7>, ChainError> {
    let (a, b, c) = (2.9668, 2.0942, 3.0541);
    let joints = [
        revolute(xyz(0.0, 0.0, 0.1575), [0.0, 0.0, 1.0], -a, a),
        revolute(xyz(0.0, 0.0, 0.2025), [0.0, 1.0, 0.0], -b, b),
        revolute(xyz(0.0, 0.0, 0.2045), [0.0, 0.0, 1.0], -a, a),
        revolute(xyz(0.0, 0.0, 0.2155), [0.0, -1.0, 0.0], -b, b),
        revolute(xyz(0.0, 0.0, 0.1845), [0.0, 0.0, 1.0], -a, a),
        revolute(xyz(0.0, 0.0, 0.2155), [0.0, 1.0, 0.0], -b, b),
        revolute(xyz(0.0, 0.0, 0.081), [0.0, 0.0, 1.0], -c, c),
    ];
    Chain::new(joints, xyz(0.0, 0.0, 0.045))
}

/// SO-101 (TheRobotStudio SO-ARM100, `so101_new_calib.urdf`): `base_link` to `gripper_frame_link`
/// through shoulder_pan, shoulder_lift, elbow_flex, wrist_flex and wrist_roll, values copied from the
/// URDF (the host's URDF importer reproduces this chain from the file; a test checks it). The
/// file rounds pi to 3.14159 and pi/2 to 1.5708; the preset keeps the file's numbers exactly.
#[allow(clippy::approx_constant)]
pub fn so101<T: Real>() -> Result<Chain<T, 5>, ChainError> {
    let z = [0.0, 0.0, 1.0];
    let joints = [
        revolute(origin([0.0388353, -8.97657e-09, 0.0624], [3.14159, 4.18253e-17, -3.14159]), z, -1.91986, 1.91986),
        revolute(origin([-0.0303992, -0.0182778, -0.0542], [-1.5708, -1.5708, 0.0]), z, -1.74533, 1.74533),
        revolute(origin([-0.11257, -0.028, 1.73763e-16], [-3.63608e-16, 8.74301e-16, 1.5708]), z, -1.69, 1.69),
        revolute(origin([-0.1349, 0.0052, 3.62355e-17], [4.02456e-15, 8.67362e-16, -1.5708]), z, -1.65806, 1.65806),
        revolute(origin([5.55112e-17, -0.0611, 0.0181], [1.5708, 0.0486795, 3.14159]), z, -2.74385, 2.84121),
    ];
    Chain::new(joints, origin([-0.0079, -0.000218121, -0.0981274], [0.0, 3.14159, 0.0]))
}

/// ROBOTIS OpenManipulator-X (open_manipulator_description), joint1 to the end-effector frame.
pub fn open_manipulator_x<T: Real>() -> Result<Chain<T, 4>, ChainError> {
    let pi = core::f64::consts::PI;
    let y = [0.0, 1.0, 0.0];
    let joints = [
        revolute(xyz(0.012, 0.0, 0.017), [0.0, 0.0, 1.0], -0.9 * pi, 0.9 * pi),
        revolute(xyz(0.0, 0.0, 0.0595), y, -0.57 * pi, 0.5 * pi),
        revolute(xyz(0.024, 0.0, 0.128), y, -0.3 * pi, 0.44 * pi),
        revolute(xyz(0.124, 0.0, 0.0), y, -0.57 * pi, 0.65 * pi),
    ];
    Chain::new(joints, xyz(0.126, 0.0, 0.0))
}
