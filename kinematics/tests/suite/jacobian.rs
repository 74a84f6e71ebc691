//! The geometric Jacobian (rows linear x, y, z then angular x, y, z, base frame) against the course's
//! seed checks and against central finite differences of forward kinematics.

use core::f64::consts::{FRAC_PI_4, PI, TAU};
use kinematics::nalgebra::{SMatrix, SVector, Vector3};
use kinematics::{presets, rotation_error, Chain, Joint, JointKind, Limits, Pose};
use proptest::prelude::*;

// ---------------------------------------------------------------------------------------------
// Seed checks (shared/reference/seed-checks.md): dchain is the 2 x n Jacobian of the end position
// of the planar unit-link chain, i.e. rows 0 and 1 of ours. Printed to 8 decimals: 1e-8.
// ---------------------------------------------------------------------------------------------

fn assert_dchain<const N: usize>(q: [f64; N], expected: [[f64; N]; 2]) {
    let chain = presets::planar::<f64, N>().unwrap();
    let j = chain.jacobian(&SVector::from(q));
    for (r, row) in expected.iter().enumerate() {
        for (c, &e) in row.iter().enumerate() {
            assert!((j[(r, c)] - e).abs() <= 1e-8, "dchain({q:?})[{r}][{c}] = {}, expected {e}", j[(r, c)]);
        }
    }
    // The chain moves in the xy plane about z: no z velocity, no x/y rotation, unit z rotation per
    // joint (exact: the axes are (0, 0, 1) and rotations about z keep them so).
    for c in 0..N {
        assert_eq!([j[(2, c)], j[(3, c)], j[(4, c)]], [0.0; 3], "dchain({q:?}) column {c}");
        assert_eq!(j[(5, c)], 1.0, "dchain({q:?}) angular z of column {c}");
    }
}

#[test]
fn seed_check_one_link_at_zero() {
    assert_dchain([0.0], [[0.0], [1.0]]);
}

#[test]
#[allow(clippy::approx_constant)] // seed-checks.md's decimals, not a library constant
fn seed_check_one_link_at_quarter_pi() {
    assert_dchain([FRAC_PI_4], [[-0.70710678], [0.70710678]]);
}

#[test]
fn seed_check_four_straight_links() {
    assert_dchain([0.0; 4], [[0.0; 4], [4.0, 3.0, 2.0, 1.0]]);
}

#[test]
fn seed_check_three_bent_links() {
    assert_dchain([0.1, 0.2, 0.3], [[-0.9599961, -0.86016268, -0.56464247], [2.77567627, 1.7806721, 0.82533561]]);
}

#[test]
fn planar_angular_z_row_is_all_ones_anywhere() {
    let chain = presets::planar::<f64, 5>().unwrap();
    let j = chain.jacobian(&SVector::from([0.4, -2.0, 3.1, 1.0, -0.3]));
    assert_eq!(j.row(5).iter().copied().collect::<Vec<_>>(), vec![1.0; 5]);
}

// ---------------------------------------------------------------------------------------------
// Central finite differences. Step h = 1e-6: truncation O(h^2 |d3 FK|) ~ 1e-12 and rounding
// O(eps / h) ~ 1e-10, so the difference matches the analytic Jacobian to ~1e-9; the check is
// |J - J_fd| <= 1e-6 * max(1, max |J|) per entry.
// ---------------------------------------------------------------------------------------------

const H: f64 = 1e-6;

fn finite_difference<const N: usize>(chain: &Chain<f64, N>, q: &SVector<f64, N>) -> SMatrix<f64, 6, N> {
    let mut j = SMatrix::<f64, 6, N>::zeros();
    for k in 0..N {
        let mut plus = *q;
        let mut minus = *q;
        plus[k] += H;
        minus[k] -= H;
        let (tp, tm) = (chain.tool_pose(&plus), chain.tool_pose(&minus));
        let linear = (tp.translation - tm.translation) / (2.0 * H);
        // log(R(q + h e_k) R(q - h e_k)^T) / 2h: the base-frame angular velocity per unit dq_k.
        let angular = rotation_error(&tp.rotation, &tm.rotation) / (2.0 * H);
        j.fixed_view_mut::<3, 1>(0, k).copy_from(&linear);
        j.fixed_view_mut::<3, 1>(3, k).copy_from(&angular);
    }
    j
}

fn check_against_fd<const N: usize>(chain: &Chain<f64, N>, q: &SVector<f64, N>) -> Result<(), TestCaseError> {
    let analytic = chain.jacobian(q);
    let numeric = finite_difference(chain, q);
    let scale = analytic.amax().max(1.0);
    let err = (analytic - numeric).amax();
    prop_assert!(err <= 1e-6 * scale, "q {q:?}: |J - J_fd| = {err:e}\nJ {analytic}\nJ_fd {numeric}");
    // The Jacobian from precomputed frames is the same matrix.
    prop_assert_eq!(chain.jacobian_of(&chain.forward(q)), analytic);
    Ok(())
}

fn within_limits<const N: usize>(chain: &Chain<f64, N>, u: [f64; N]) -> SVector<f64, N> {
    SVector::from_fn(|i, _| {
        let j = &chain.joints()[i];
        match j.kind {
            JointKind::Continuous => -PI + TAU * u[i],
            _ => j.limits.lower + j.limits.span() * u[i],
        }
    })
}

/// A URDF-style chain with a prismatic joint between revolute ones, tilted origins, an axis that
/// is not unit length (normalised on construction) and an offset, rotated tool.
fn with_prismatic() -> Chain<f64, 4> {
    let joints = [
        Joint::revolute(Pose::from_xyz_rpy([0.0, 0.0, 0.2], [0.0, 0.0, 0.3]), [0.0, 0.0, 1.0], Limits::symmetric(3.0)),
        Joint::prismatic(
            Pose::from_xyz_rpy([0.1, 0.0, 0.3], [0.4, -0.2, 0.0]),
            [0.0, 2.0, 1.0],
            Limits::new(-0.2, 0.6),
        ),
        Joint::revolute(Pose::from_xyz_rpy([0.0, 0.25, 0.0], [1.2, 0.0, 0.5]), [1.0, 0.0, 0.0], Limits::symmetric(2.5)),
        Joint::continuous(Pose::from_xyz_rpy([0.05, 0.0, 0.15], [0.0, 0.7, 0.0]), [0.0, 1.0, 1.0]),
    ];
    Chain::new(joints, Pose::from_xyz_rpy([0.02, -0.01, 0.12], [0.1, 0.2, -0.3])).unwrap()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(128))]

    #[test]
    fn ur5e_matches_finite_differences(u in proptest::array::uniform::<_, 6>(0.0..1.0f64)) {
        let chain = presets::ur5e::<f64>().unwrap();
        check_against_fd(&chain, &within_limits(&chain, u))?;
    }

    #[test]
    fn puma560_matches_finite_differences(u in proptest::array::uniform::<_, 6>(0.0..1.0f64)) {
        let chain = presets::puma560::<f64>().unwrap();
        check_against_fd(&chain, &within_limits(&chain, u))?;
    }

    #[test]
    fn iiwa14_matches_finite_differences(u in proptest::array::uniform::<_, 7>(0.0..1.0f64)) {
        let chain = presets::iiwa14::<f64>().unwrap();
        check_against_fd(&chain, &within_limits(&chain, u))?;
    }

    #[test]
    fn so101_matches_finite_differences(u in proptest::array::uniform::<_, 5>(0.0..1.0f64)) {
        let chain = presets::so101::<f64>().unwrap();
        check_against_fd(&chain, &within_limits(&chain, u))?;
    }

    #[test]
    fn open_manipulator_x_matches_finite_differences(u in proptest::array::uniform::<_, 4>(0.0..1.0f64)) {
        let chain = presets::open_manipulator_x::<f64>().unwrap();
        check_against_fd(&chain, &within_limits(&chain, u))?;
    }

    #[test]
    fn planar5_matches_finite_differences(u in proptest::array::uniform::<_, 5>(0.0..1.0f64)) {
        let chain = presets::planar::<f64, 5>().unwrap();
        check_against_fd(&chain, &within_limits(&chain, u))?;
    }

    #[test]
    fn prismatic_chain_matches_finite_differences(u in proptest::array::uniform::<_, 4>(0.0..1.0f64)) {
        let chain = with_prismatic();
        let q = within_limits(&chain, u);
        check_against_fd(&chain, &q)?;
        // The prismatic column has no angular part and a unit linear part (a unit axis in motion).
        let j = chain.jacobian(&q);
        prop_assert_eq!([j[(3, 1)], j[(4, 1)], j[(5, 1)]], [0.0; 3]);
        prop_assert!((Vector3::new(j[(0, 1)], j[(1, 1)], j[(2, 1)]).norm() - 1.0).abs() <= 1e-12);
    }
}

#[test]
fn f32_jacobian_agrees_with_f64() {
    // Same chain in both scalars at the same q: entries agree to single-precision rounding of
    // unit-scale sums (2e-6 absolute is ~16 ulps of 1.0 in f32).
    let c64 = presets::ur5e::<f64>().unwrap();
    let c32 = presets::ur5e::<f32>().unwrap();
    let q = [0.3, -1.2, 1.0, -0.5, 1.1, 0.2];
    let j64 = c64.jacobian(&SVector::from(q));
    let j32 = c32.jacobian(&SVector::from(q.map(|v| v as f32)));
    let err = (j64 - j32.map(f64::from)).amax();
    assert!(err <= 2e-6, "|J64 - J32| = {err:e}");
}
