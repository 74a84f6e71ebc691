//! Forward kinematics and pose conventions, checked against values that do not come from the crate:
//! the course's seed checks, an independent 4x4-matrix implementation of both DH conventions,
//! published zero-pose positions, and nalgebra's own rotations.

use core::f64::consts::{FRAC_PI_2, FRAC_PI_4, PI, TAU};
use kinematics::nalgebra::{Matrix3, Matrix4, Rotation3, SVector, UnitQuaternion, Vector3};
use kinematics::{
    axis_angle_matrix, presets, rotation_error, wrap_angle, Chain, ChainError, DhRow, Joint, JointKind, Limits, Pose,
};
use proptest::prelude::*;

// ---------------------------------------------------------------------------------------------
// Helpers
// ---------------------------------------------------------------------------------------------

/// `Pose` as a 4x4 homogeneous matrix.
fn homogeneous(p: &Pose<f64>) -> Matrix4<f64> {
    let mut m = Matrix4::identity();
    m.fixed_view_mut::<3, 3>(0, 0).copy_from(&p.rotation);
    m.fixed_view_mut::<3, 1>(0, 3).copy_from(&p.translation);
    m
}

fn rot_z(t: f64) -> Matrix4<f64> {
    Rotation3::from_axis_angle(&Vector3::z_axis(), t).to_homogeneous()
}

fn rot_x(t: f64) -> Matrix4<f64> {
    Rotation3::from_axis_angle(&Vector3::x_axis(), t).to_homogeneous()
}

fn trans(x: f64, y: f64, z: f64) -> Matrix4<f64> {
    Matrix4::new_translation(&Vector3::new(x, y, z))
}

/// One DH row of the independent implementation: `(a, alpha, d, theta, prismatic)`.
type Row = (f64, f64, f64, f64, bool);

/// Standard DH written out as the textbook product `Rz(theta + q) Tz(d) Tx(a) Rx(alpha)` per row
/// (for a prismatic row the variable adds to `d` instead).
fn standard_dh_product(rows: &[Row], q: &[f64]) -> Matrix4<f64> {
    rows.iter().zip(q).fold(Matrix4::identity(), |t, (&(a, alpha, d, theta, prismatic), &qi)| {
        let (theta, d) = if prismatic { (theta, d + qi) } else { (theta + qi, d) };
        t * rot_z(theta) * trans(0.0, 0.0, d) * trans(a, 0.0, 0.0) * rot_x(alpha)
    })
}

/// Modified (Craig) DH: `Rx(alpha) Tx(a) Rz(theta + q) Tz(d)` per row.
fn modified_dh_product(rows: &[Row], q: &[f64]) -> Matrix4<f64> {
    rows.iter().zip(q).fold(Matrix4::identity(), |t, (&(a, alpha, d, theta, prismatic), &qi)| {
        let (theta, d) = if prismatic { (theta, d + qi) } else { (theta + qi, d) };
        t * rot_x(alpha) * trans(a, 0.0, 0.0) * rot_z(theta) * trans(0.0, 0.0, d)
    })
}

fn dh_rows<const N: usize>(rows: &[Row; N], limit: f64) -> [DhRow<f64>; N] {
    rows.map(|(a, alpha, d, theta, prismatic)| DhRow {
        a,
        alpha,
        d,
        theta,
        kind: if prismatic { JointKind::Prismatic } else { JointKind::Revolute },
        limits: Limits::symmetric(limit),
    })
}

/// Maps unit samples to joint values over each joint's range (continuous joints over a turn).
fn within_limits<const N: usize>(chain: &Chain<f64, N>, u: [f64; N]) -> SVector<f64, N> {
    SVector::from_fn(|i, _| {
        let j = &chain.joints()[i];
        match j.kind {
            JointKind::Continuous => -PI + TAU * u[i],
            _ => j.limits.lower + j.limits.span() * u[i],
        }
    })
}

fn max_abs_diff(a: &Matrix4<f64>, b: &Matrix4<f64>) -> f64 {
    (a - b).amax()
}

/// UR5e standard DH (arms.md, Universal Robots "Parameters for calculations of kinematics and
/// dynamics"), typed in here independently of `presets::ur5e`.
const UR5E: [Row; 6] = [
    (0.0, FRAC_PI_2, 0.1625, 0.0, false),
    (-0.425, 0.0, 0.0, 0.0, false),
    (-0.3922, 0.0, 0.0, 0.0, false),
    (0.0, FRAC_PI_2, 0.1333, 0.0, false),
    (0.0, -FRAC_PI_2, 0.0997, 0.0, false),
    (0.0, 0.0, 0.0996, 0.0, false),
];

/// PUMA 560 standard DH (arms.md, Corke's Robotics Toolbox `models/DH/Puma560.py`).
const PUMA560: [Row; 6] = [
    (0.0, FRAC_PI_2, 0.67183, 0.0, false),
    (0.4318, 0.0, 0.0, 0.0, false),
    (0.0203, -FRAC_PI_2, 0.15005, 0.0, false),
    (0.0, FRAC_PI_2, 0.4318, 0.0, false),
    (0.0, -FRAC_PI_2, 0.0, 0.0, false),
    (0.0, 0.0, 0.0, 0.0, false),
];

/// A made-up table exercising everything the presets do not: non-zero theta offsets, odd twists,
/// and a prismatic row (its variable adds to d).
const MADE_UP: [Row; 4] = [
    (0.1, 0.0, 0.3, 0.2, false),
    (0.25, -FRAC_PI_2, 0.05, -0.7, false),
    (0.0, 1.1, 0.4, 0.3, true),
    (0.15, FRAC_PI_2, -0.12, 1.9, false),
];

// ---------------------------------------------------------------------------------------------
// Seed checks (shared/reference/seed-checks.md): end position of the planar unit-link chain.
// The reference values are printed to 8 decimals, so they hold to 1e-8.
// ---------------------------------------------------------------------------------------------

fn planar_end<const N: usize>(q: [f64; N]) -> Vector3<f64> {
    let chain = presets::planar::<f64, N>().unwrap();
    chain.tool_pose(&SVector::from(q)).translation
}

fn assert_planar_end<const N: usize>(q: [f64; N], expected: [f64; 2]) {
    let p = planar_end(q);
    let err = (p - Vector3::new(expected[0], expected[1], 0.0)).amax();
    assert!(err <= 1e-8, "chain({q:?}) = {p:?}, expected ({}, {}, 0); error {err:e} > 1e-8", expected[0], expected[1]);
}

#[test]
fn seed_check_empty_chain_ends_at_the_origin() {
    assert_planar_end::<0>([], [0.0, 0.0]);
}

#[test]
fn seed_check_one_link_at_zero() {
    assert_planar_end([0.0], [1.0, 0.0]);
}

#[test]
#[allow(clippy::approx_constant)] // seed-checks.md's decimals, not a library constant
fn seed_check_one_link_at_quarter_pi() {
    assert_planar_end([FRAC_PI_4], [0.70710678, 0.70710678]);
}

#[test]
fn seed_check_four_links_bent() {
    assert_planar_end([0.1, 0.2, 0.3, 0.4], [3.31597858, 1.80146708]);
}

#[test]
fn seed_check_four_links_folded_back_on_themselves() {
    assert_planar_end([PI; 4], [0.0, 0.0]);
}

#[test]
fn planar_chain_stays_in_the_plane_with_rotation_about_z() {
    // Independent closed form: p = sum_k (cos s_k, sin s_k), s_k = q_1 + ... + q_k; R = Rz(s_N).
    let chain = presets::planar::<f64, 5>().unwrap();
    let q = SVector::from([0.3, -1.2, 2.5, 0.05, -3.0]);
    let pose = chain.tool_pose(&q);
    let mut s = 0.0;
    let mut p = Vector3::zeros();
    for qi in q.iter() {
        s += qi;
        p += Vector3::new(f64::cos(s), f64::sin(s), 0.0);
    }
    assert!((pose.translation - p).amax() <= 1e-12, "{pose:?} vs {p:?}");
    let r = Rotation3::from_axis_angle(&Vector3::z_axis(), s);
    assert!((pose.rotation - r.matrix()).amax() <= 1e-12);
}

// ---------------------------------------------------------------------------------------------
// DH conversion against the independent 4x4 implementation (to 1e-12: both are a handful of f64
// products of unit-scale numbers, so they agree to a few ulps).
// ---------------------------------------------------------------------------------------------

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn ur5e_preset_matches_standard_dh_product(u in proptest::array::uniform::<_, 6>(0.0..1.0f64)) {
        let chain = presets::ur5e::<f64>().unwrap();
        let q = within_limits(&chain, u);
        let expected = standard_dh_product(&UR5E, q.as_slice());
        let got = homogeneous(&chain.tool_pose(&q));
        prop_assert!(max_abs_diff(&got, &expected) <= 1e-12, "q {q:?}\n{got}\n{expected}");
    }

    #[test]
    fn puma560_preset_matches_standard_dh_product(u in proptest::array::uniform::<_, 6>(0.0..1.0f64)) {
        let chain = presets::puma560::<f64>().unwrap();
        let q = within_limits(&chain, u);
        let expected = standard_dh_product(&PUMA560, q.as_slice());
        let got = homogeneous(&chain.tool_pose(&q));
        prop_assert!(max_abs_diff(&got, &expected) <= 1e-12, "q {q:?}\n{got}\n{expected}");
    }

    #[test]
    fn from_dh_standard_with_offsets_prismatic_and_tool(q in proptest::array::uniform::<_, 4>(-3.0..3.0f64)) {
        // The tool frame is appended after the last DH frame.
        let tool = Pose::from_xyz_rpy([0.01, -0.02, 0.15], [0.3, -0.2, 1.0]);
        let chain = Chain::from_dh_standard(dh_rows(&MADE_UP, 4.0), tool).unwrap();
        let expected = standard_dh_product(&MADE_UP, &q) * homogeneous(&tool);
        let got = homogeneous(&chain.tool_pose(&SVector::from(q)));
        prop_assert!(max_abs_diff(&got, &expected) <= 1e-12, "q {q:?}\n{got}\n{expected}");
    }

    #[test]
    fn from_dh_modified_matches_craig_product(q in proptest::array::uniform::<_, 4>(-3.0..3.0f64)) {
        let tool = Pose::from_xyz_rpy([0.0, 0.0, 0.1], [0.0, 0.0, 0.0]);
        let chain = Chain::from_dh_modified(dh_rows(&MADE_UP, 4.0), tool).unwrap();
        let expected = modified_dh_product(&MADE_UP, &q) * homogeneous(&tool);
        let got = homogeneous(&chain.tool_pose(&SVector::from(q)));
        prop_assert!(max_abs_diff(&got, &expected) <= 1e-12, "q {q:?}\n{got}\n{expected}");
        // The joint frames too: frame k after its motion is the product of the first k+1 rows.
        let frames = chain.forward(&SVector::from(q));
        for k in 0..4 {
            let expected = modified_dh_product(&MADE_UP[..=k], &q[..=k]);
            let got = homogeneous(&frames.joints[k]);
            prop_assert!(max_abs_diff(&got, &expected) <= 1e-12, "frame {k}, q {q:?}\n{got}\n{expected}");
        }
    }
}

#[test]
fn modified_dh_prismatic_variable_adds_to_d() {
    // A single prismatic modified-DH row: Rx(pi/2) Tx(a) Tz(d + q). Rx(pi/2) maps z to -y, so the
    // tool sits at (a, -(d + q), 0) = (0.2, -0.5, 0) for d = 0.1, q = 0.4 (exact up to rounding).
    let rows = [DhRow {
        a: 0.2,
        alpha: FRAC_PI_2,
        d: 0.1,
        theta: 0.0,
        kind: JointKind::Prismatic,
        limits: Limits::new(0.0, 1.0),
    }];
    let chain = Chain::from_dh_modified(rows, Pose::identity()).unwrap();
    let p = chain.tool_pose(&SVector::from([0.4])).translation;
    let expected = Vector3::new(0.2, -0.5, 0.0);
    assert!((p - expected).amax() <= 1e-15, "{p:?} vs {expected:?}");
}

// ---------------------------------------------------------------------------------------------
// Published values.
// ---------------------------------------------------------------------------------------------

#[test]
fn puma560_zero_pose_matches_robotics_toolbox() {
    // Corke, Robotics Toolbox: p560.fkine(qz) has t = (0.4521, -0.15005, 0.4318) with d1 = 0 (the
    // KDL/old-toolbox table); the Python model has d1 = 0.67183, which adds to z. At qz every
    // Rz is the identity and the twists sum to zero, so R = I. Tolerance 1e-4 (the printed digits).
    let chain = presets::puma560::<f64>().unwrap();
    let pose = chain.tool_pose(&SVector::zeros());
    let expected = Vector3::new(0.4521, -0.15005, 0.4318 + 0.67183);
    assert!((pose.translation - expected).amax() <= 1e-4, "{:?}", pose.translation);
    assert!((pose.rotation - Matrix3::identity()).amax() <= 1e-4, "{:?}", pose.rotation);
}

#[test]
fn ur5e_zero_pose_matches_closed_form() {
    // UR5e at q = 0 (arms.md table): (a2 + a3, -(d4 + d6), d1 - d5) = (-0.8172, -0.2329, 0.0628),
    // exact in the table's digits, so to 1e-9.
    let chain = presets::ur5e::<f64>().unwrap();
    let pose = chain.tool_pose(&SVector::zeros());
    let expected = Vector3::new(-0.8172, -0.2329, 0.0628);
    assert!((pose.translation - expected).amax() <= 1e-9, "{:?}", pose.translation);
}

// ---------------------------------------------------------------------------------------------
// Rotation conventions.
// ---------------------------------------------------------------------------------------------

fn unit_axis(theta: f64, phi: f64) -> Vector3<f64> {
    Vector3::new(theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos())
}

/// Rotation angles over (0, pi], half of the cases within 1e-6 of pi where the quaternion's w is
/// tiny and naive conversions lose accuracy.
fn angle() -> impl Strategy<Value = f64> {
    prop_oneof![0.0..PI, (0.0..1e-6f64).prop_map(|e| PI - e), Just(PI), (0.0..1e-8f64)]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    #[test]
    fn from_xyz_rpy_is_urdf_fixed_axis_rpy(
        xyz in proptest::array::uniform::<_, 3>(-2.0..2.0f64),
        rpy in proptest::array::uniform::<_, 3>(-TAU..TAU),
    ) {
        // URDF: R = Rz(yaw) Ry(pitch) Rx(roll), built here from nalgebra's axis-angle rotations.
        let expected = Rotation3::from_axis_angle(&Vector3::z_axis(), rpy[2])
            * Rotation3::from_axis_angle(&Vector3::y_axis(), rpy[1])
            * Rotation3::from_axis_angle(&Vector3::x_axis(), rpy[0]);
        let pose = Pose::from_xyz_rpy(xyz, rpy);
        prop_assert!((pose.rotation - expected.matrix()).amax() <= 1e-12, "{rpy:?}");
        prop_assert_eq!(pose.translation, Vector3::from(xyz));
    }

    #[test]
    fn quaternion_round_trips_at_every_angle(theta in 0.0..PI, phi in -PI..PI, angle in angle()) {
        let axis = unit_axis(theta, phi);
        let r = *Rotation3::from_axis_angle(&kinematics::nalgebra::Unit::new_normalize(axis), angle).matrix();
        let pose = Pose { rotation: r, translation: Vector3::zeros() };
        let q = pose.quaternion_wxyz();
        // Unit, w >= 0, and equal (up to the sign it fixes) to nalgebra's quaternion; 1e-12.
        let norm = q.iter().map(|v| v * v).sum::<f64>().sqrt();
        prop_assert!((norm - 1.0).abs() <= 1e-12 && q[0] >= 0.0, "{q:?}");
        let reference = UnitQuaternion::from_axis_angle(&kinematics::nalgebra::Unit::new_normalize(axis), angle);
        let rv = [reference.w, reference.i, reference.j, reference.k];
        let same = q.iter().zip(rv).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
        let opposite = q.iter().zip(rv).map(|(a, b)| (a + b).abs()).fold(0.0, f64::max);
        prop_assert!(same.min(opposite) <= 1e-12, "{q:?} vs {rv:?}");
        let back = Pose::rotation_from_quaternion_wxyz(q).unwrap();
        prop_assert!((back - r).amax() <= 1e-12, "angle {angle}: {back} vs {r}");
    }

    #[test]
    fn rotation_error_is_the_applied_rotation_vector(
        theta in 0.0..PI, phi in -PI..PI,
        base_theta in 0.0..PI, base_phi in -PI..PI, base_angle in 0.0..PI,
        magnitude in prop_oneof![0.0..(PI - 1e-6), (0.0..1e-8f64), (1e-6..1e-3f64).prop_map(|e| PI - e)],
    ) {
        // rotation_error(R exp(w), R) = log(R exp(w) R^T) = R w, so its norm is |w| (1e-9).
        let r = axis_angle_matrix(&unit_axis(base_theta, base_phi), base_angle);
        let w = unit_axis(theta, phi) * magnitude;
        let target = r * axis_angle_matrix(&unit_axis(theta, phi), magnitude);
        let e = rotation_error(&target, &r);
        prop_assert!((e.norm() - magnitude).abs() <= 1e-9, "|e| {} vs |w| {magnitude}", e.norm());
        prop_assert!((e - r * w).amax() <= 1e-9, "{e:?} vs {:?}", r * w);
    }
}

#[test]
fn zero_quaternion_is_rejected() {
    assert_eq!(Pose::<f64>::rotation_from_quaternion_wxyz([0.0; 4]), None);
    assert_eq!(Pose::<f64>::rotation_from_quaternion_wxyz([f64::NAN, 0.0, 0.0, 1.0]), None);
    // Not unit: normalised first (a half turn about z).
    let r = Pose::<f64>::rotation_from_quaternion_wxyz([0.0, 0.0, 0.0, 2.0]).unwrap();
    assert!((r - Matrix3::from_diagonal(&Vector3::new(-1.0, -1.0, 1.0))).amax() <= 1e-15);
}

// ---------------------------------------------------------------------------------------------
// Chain validation and joint normalisation.
// ---------------------------------------------------------------------------------------------

fn good_joints() -> [Joint<f64>; 3] {
    let o = Pose::from_xyz_rpy([0.0, 0.0, 0.1], [0.0, 0.0, 0.0]);
    [
        Joint::revolute(o, [0.0, 0.0, 1.0], Limits::symmetric(2.0)),
        Joint::prismatic(o, [1.0, 0.0, 0.0], Limits::new(0.0, 0.5)),
        Joint::continuous(o, [0.0, 1.0, 0.0]),
    ]
}

#[test]
fn chain_new_accepts_a_good_chain_and_normalises_axes() {
    let mut joints = good_joints();
    joints[0].axis = Vector3::new(0.0, 0.0, 3.0);
    let chain = Chain::new(joints, Pose::identity()).unwrap();
    assert_eq!(chain.joints()[0].axis, Vector3::new(0.0, 0.0, 1.0));
}

#[test]
fn chain_new_rejects_a_zero_axis_with_its_index() {
    for k in 0..3 {
        let mut joints = good_joints();
        joints[k].axis = Vector3::zeros();
        assert_eq!(Chain::new(joints, Pose::identity()), Err(ChainError::ZeroAxis { joint: k }));
    }
    let mut joints = good_joints();
    joints[1].axis = Vector3::new(f64::NAN, 0.0, 1.0);
    assert_eq!(Chain::new(joints, Pose::identity()), Err(ChainError::ZeroAxis { joint: 1 }));
}

#[test]
fn chain_new_rejects_a_nan_origin_or_tool() {
    let mut joints = good_joints();
    joints[2].origin.translation.y = f64::NAN;
    assert_eq!(Chain::new(joints, Pose::identity()), Err(ChainError::BadFrame { joint: Some(2) }));
    let mut joints = good_joints();
    joints[0].origin.rotation[(1, 1)] = f64::INFINITY;
    assert_eq!(Chain::new(joints, Pose::identity()), Err(ChainError::BadFrame { joint: Some(0) }));
    let tool = Pose::from_xyz_rpy([0.0, f64::NAN, 0.0], [0.0; 3]);
    assert_eq!(Chain::new(good_joints(), tool), Err(ChainError::BadFrame { joint: None }));
}

#[test]
fn chain_new_rejects_inverted_or_non_finite_limits() {
    let mut joints = good_joints();
    joints[0].limits = Limits::new(1.0, -1.0);
    assert_eq!(Chain::new(joints, Pose::identity()), Err(ChainError::BadLimits { joint: 0 }));
    let mut joints = good_joints();
    joints[1].limits = Limits::new(0.5, 0.4999);
    assert_eq!(Chain::new(joints, Pose::identity()), Err(ChainError::BadLimits { joint: 1 }));
    let mut joints = good_joints();
    joints[1].limits = Limits::new(f64::NAN, 0.5);
    assert_eq!(Chain::new(joints, Pose::identity()), Err(ChainError::BadLimits { joint: 1 }));
    // lower == upper is a legal (locked) joint.
    let mut joints = good_joints();
    joints[0].limits = Limits::new(0.3, 0.3);
    assert!(Chain::new(joints, Pose::identity()).is_ok());
}

#[test]
fn continuous_joints_wrap_to_half_open_interval() {
    let j = Joint::continuous(Pose::<f64>::identity(), [0.0, 0.0, 1.0]);
    for (q, expected) in [(0.0, 0.0), (3.0 * FRAC_PI_2, -FRAC_PI_2), (-PI, PI), (PI, PI), (7.0 * PI, PI), (-0.5, -0.5)]
    {
        let got = j.normalise(q);
        assert!((got - expected).abs() <= 1e-12, "normalise({q}) = {got}, expected {expected}");
    }
    // Any finite value is admissible for a continuous joint.
    assert!(j.admits(100.0) && !j.admits(f64::NAN));
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    #[test]
    fn wrap_angle_lands_in_half_open_interval_on_the_same_angle(q in -100.0..100.0f64) {
        let w = wrap_angle(q);
        prop_assert!(w > -PI && w <= PI, "wrap_angle({q}) = {w}");
        // Same angle: differs by a whole number of turns (1e-12 relative to |q|).
        let turns = (q - w) / TAU;
        prop_assert!((turns - turns.round()).abs() <= 1e-12, "wrap_angle({q}) = {w}");
    }

    #[test]
    fn revolute_normalise_shifts_by_turns_when_that_lands_inside(
        lower in -8.0..4.0f64, width in 0.0..8.0f64, q in -20.0..20.0f64,
    ) {
        let limits = Limits::new(lower, lower + width);
        let j = Joint::revolute(Pose::<f64>::identity(), [0.0, 0.0, 1.0], limits);
        let n = j.normalise(q);
        prop_assert!(limits.contains(n), "normalise({q}) = {n} outside {limits:?}");
        // Independent search for a whole turn that lands inside.
        let inside_turn = (-5..=5).map(|k| q + f64::from(k) * TAU).find(|v| limits.contains(*v));
        if limits.contains(q) {
            prop_assert_eq!(n, q);
        } else if inside_turn.is_some() {
            let turns = (n - q) / TAU;
            prop_assert!((turns - turns.round()).abs() <= 1e-12 && turns.round() != 0.0, "{q} -> {n}");
        } else {
            // No turn fits: clamped to the nearer limit.
            prop_assert_eq!(n, q.clamp(limits.lower, limits.upper));
        }
    }
}

#[test]
fn revolute_and_prismatic_normalise_examples() {
    let r = Joint::revolute(Pose::<f64>::identity(), [0.0, 0.0, 1.0], Limits::new(-0.5, 2.0));
    assert!((r.normalise(TAU + 0.1) - 0.1).abs() <= 1e-12);
    assert!((r.normalise(-TAU + 1.5) - 1.5).abs() <= 1e-12);
    assert_eq!(r.normalise(3.0), 2.0); // 3 - 2 pi = -3.28 is outside too: clamped.
    assert_eq!(r.normalise(-1.0), -0.5); // -1 + 2 pi = 5.28 is outside: clamped.
    assert!(!r.admits(2.0001) && r.admits(-0.5));
    let p = Joint::prismatic(Pose::<f64>::identity(), [1.0, 0.0, 0.0], Limits::new(0.0, 0.5));
    assert_eq!(p.normalise(TAU + 0.1), 0.5); // never shifted by a turn
    assert_eq!(p.normalise(-0.1), 0.0);
}

#[test]
fn chain_normalise_and_admits_work_per_joint() {
    let chain = Chain::new(good_joints(), Pose::identity()).unwrap();
    let mut q = SVector::from([TAU + 1.0, 0.7, -3.0 * FRAC_PI_2]);
    assert!(!chain.admits(&q));
    chain.normalise(&mut q);
    assert!(chain.admits(&q));
    let expected = SVector::from([1.0, 0.5, FRAC_PI_2]);
    assert!((q - expected).amax() <= 1e-12, "{q:?}");
    // Middle: limit midpoints, zero for the continuous joint.
    assert_eq!(chain.middle(), SVector::from([0.0, 0.25, 0.0]));
}

// ---------------------------------------------------------------------------------------------
// Fixed joints: the padding that lets one firmware build drive fewer joints than it holds
// ---------------------------------------------------------------------------------------------

/// The SO-101's five joints, then a fixed one (with an offset of its own, folded into the tool):
/// the tool pose is the unpadded chain's whatever value the fixed joint is given, its Jacobian
/// column is zero and the other five are the unpadded chain's, and damped least squares reaches a
/// reachable target with the fixed joint left at zero.
#[test]
fn a_fixed_joint_pads_a_chain_without_changing_it() {
    let five = presets::so101::<f64>().unwrap();
    let offset = Pose::from_xyz_rpy([0.01, -0.02, 0.03], [0.1, 0.2, -0.3]);
    let joints: [Joint<f64>; 6] = core::array::from_fn(|j| if j < 5 { five.joints()[j] } else { Joint::fixed(offset) });
    let six = Chain::new(joints, Pose::identity()).unwrap();
    let padded_tool = |q5: &SVector<f64, 5>, q6: f64| {
        six.tool_pose(&SVector::<f64, 6>::from_fn(|j, _| if j < 5 { q5[j] } else { q6 }))
    };
    for q5 in [SVector::<f64, 5>::zeros(), SVector::from([0.3, -0.4, 0.5, 0.2, -0.3])] {
        // `six` ends at the fixed joint with no tool: the five joints with the offset as their tool.
        let unpadded = Chain::new(*five.joints(), offset).unwrap().tool_pose(&q5);
        for q6 in [0.0, 1.0, -2.5] {
            let p = padded_tool(&q5, q6);
            assert!((p.translation - unpadded.translation).norm() < 1e-12);
            assert!((p.rotation - unpadded.rotation).norm() < 1e-12);
        }
        let q6 = SVector::<f64, 6>::from_fn(|j, _| if j < 5 { q5[j] } else { 0.0 });
        let j6 = six.jacobian(&q6);
        let j5 = Chain::new(*five.joints(), offset).unwrap().jacobian(&q5);
        assert_eq!(j6.column(5).norm(), 0.0);
        assert!((j6.fixed_columns::<5>(0) - j5).norm() < 1e-12);
    }
    let goal = six.tool_pose(&SVector::from([0.2, -0.3, 0.4, 0.1, 0.0, 0.0]));
    let problem = kinematics::ik::IkProblem {
        target: kinematics::ik::Target::Position(goal.translation),
        seed: six.middle(),
        config: kinematics::ik::IkConfig::default(),
    };
    let solution = six.solve(&problem);
    assert_eq!(solution.status, kinematics::ik::IkStatus::Converged, "{:?}", solution.status);
    assert_eq!(solution.q[5], 0.0);
    assert!((six.tool_pose(&solution.q).translation - goal.translation).norm() < 1e-5);
    // Its value is held at zero by its limits.
    assert_eq!(six.joints()[5].normalise(0.7), 0.0);
    assert_eq!(six.joints()[5].kind, JointKind::Fixed);
}

/// A chain set in place is the one `new` builds (the motionless chain it starts from included),
/// and a refused one leaves the chain as it was; the motionless chain's tool sits at the base
/// whatever the joint values, with a zero Jacobian.
#[test]
fn a_chain_set_in_place_is_new_and_a_refused_one_changes_nothing() {
    let motionless = Chain::<f64, 3>::motionless();
    let q = SVector::<f64, 3>::from([0.4, -1.0, 2.0]);
    assert_eq!(motionless.tool_pose(&q), Pose::identity());
    assert_eq!(motionless.jacobian(&q).norm(), 0.0);
    assert_eq!(motionless.moving_joints(), 0);

    let mut chain = Chain::new(good_joints(), Pose::identity()).unwrap();
    let before = chain;
    let mut bad = good_joints();
    bad[2].axis = Vector3::zeros();
    assert_eq!(chain.set(|i| bad[i], Pose::identity()), Err(ChainError::ZeroAxis { joint: 2 }));
    let nan_tool = Pose::from_translation(Vector3::new(f64::NAN, 0.0, 0.0));
    assert_eq!(chain.set(|i| good_joints()[i], nan_tool), Err(ChainError::BadFrame { joint: None }));
    assert_eq!(chain, before);

    let mut other = good_joints();
    other[0].axis = Vector3::new(0.0, 2.0, 0.0);
    let tool = Pose::from_xyz_rpy([0.0, 0.0, 0.1], [0.0, 0.3, 0.0]);
    let mut from_motionless = Chain::<f64, 3>::motionless();
    from_motionless.set(|i| other[i], tool).unwrap();
    chain.set(|i| other[i], tool).unwrap();
    let fresh = Chain::new(other, tool).unwrap();
    assert_eq!(chain, fresh);
    assert_eq!(from_motionless, fresh);
}
