//! Rigid-body dynamics against what does not use it: the potential and kinetic energy of the
//! links placed by forward kinematics, differentiated numerically. Gravity torques are the
//! gradient of the potential energy; the mass matrix's quadratic form is twice the kinetic
//! energy (each link's centre-of-mass velocity and angular velocity by central differences of
//! its placed pose); the velocity terms are Lagrange's equation, d/dt(M q̇) - ∂T/∂q, from the mass
//! matrix so checked. Chains (the SO-101, the PUMA 560, the iiwa 14) and a tree (two SO-101 arms
//! on a turning torso). Tolerances are stated where each is asserted.

use kinematics::dynamics::{Dynamics, Inertia, InertiaError, Linkage};
use kinematics::nalgebra::{Matrix3, SVector, Vector3};
use kinematics::tree::{Effector, Tree};
use kinematics::{presets, Chain, Joint, Limits, Pose, SplitMix64};

/// An arm the dynamics takes, with forward kinematics to check it by: every joint's moving frame.
trait Placed<const N: usize>: Linkage<f64, N> {
    fn frames(&self, q: &SVector<f64, N>) -> [Pose<f64>; N];
}

impl<const N: usize> Placed<N> for Chain<f64, N> {
    fn frames(&self, q: &SVector<f64, N>) -> [Pose<f64>; N] {
        self.forward(q).joints
    }
}

impl<const N: usize, const E: usize> Placed<N> for Tree<f64, N, E> {
    fn frames(&self, q: &SVector<f64, N>) -> [Pose<f64>; N] {
        self.forward(q).joints
    }
}

/// Two SO-101 arms on a torso that turns (11 joints; each arm's first joint hangs from the
/// torso's), as the tree suite builds it.
fn torso() -> Tree<f64, 11, 2> {
    let arm = presets::so101::<f64>().unwrap();
    let torso = Joint::revolute(Pose::from_xyz_rpy([0.0, 0.0, 0.3], [0.0; 3]), [0.0, 0.0, 1.0], Limits::new(-1.5, 1.5));
    let mut joints = [torso; 11];
    let mut parents = [None; 11];
    for (a, y) in [(0usize, 0.2), (1, -0.2)] {
        for k in 0..5 {
            let mut j = arm.joints()[k];
            if k == 0 {
                j.origin = Pose::from_xyz_rpy([0.0, y, 0.0], [0.0; 3]).compose(&j.origin);
            }
            let index = 1 + 5 * a + k;
            joints[index] = j;
            parents[index] = Some(if k == 0 { 0 } else { index - 1 });
        }
    }
    let effectors =
        [Effector { joint: Some(5), offset: *arm.tool() }, Effector { joint: Some(10), offset: *arm.tool() }];
    Tree::new(joints, parents, effectors).unwrap()
}

/// A random body: 0.05 to 2 kg, its centre within 0.2 m of the frame, a tensor with random
/// principal moments (that satisfy the triangle inequality) along random axes.
fn random_link(rng: &mut SplitMix64) -> Inertia<f64> {
    let mass = rng.uniform(0.05, 2.0);
    let com = Vector3::new(rng.uniform(-0.2, 0.2), rng.uniform(-0.2, 0.2), rng.uniform(-0.2, 0.2));
    let (a, b): (f64, f64) = (rng.uniform(1e-4, 1e-2), rng.uniform(1e-4, 1e-2));
    let c = rng.uniform((a - b).abs(), a + b);
    let axis = Vector3::new(rng.uniform(-1.0, 1.0), rng.uniform(-1.0, 1.0), rng.uniform(-1.0, 1.0)).normalize();
    let r = kinematics::axis_angle_matrix(&axis, rng.uniform(-3.0, 3.0));
    Inertia { mass, com, tensor: r * Matrix3::from_diagonal(&Vector3::new(a, b, c)) * r.transpose() }
}

fn random_q<const N: usize>(chain: &impl Linkage<f64, N>, rng: &mut SplitMix64) -> SVector<f64, N> {
    SVector::from_fn(|k, _| {
        let l = chain.joints()[k].limits;
        rng.uniform(l.lower, l.upper)
    })
}

/// The potential energy of the links at `q` (J), gravity `g` in the base frame.
fn potential<const N: usize>(chain: &impl Placed<N>, d: &Dynamics<f64, N>, q: &SVector<f64, N>) -> f64 {
    let frames = chain.frames(q);
    d.links()
        .iter()
        .zip(&frames)
        .map(|(link, pose)| -link.mass * d.gravity().dot(&(pose.rotation * link.com + pose.translation)))
        .sum()
}

/// The kinetic energy at `q` moving at `qd` (J), from forward kinematics alone: each link's
/// centre-of-mass velocity and angular velocity by central differences along `q + s qd`.
fn kinetic<const N: usize>(
    chain: &impl Placed<N>,
    d: &Dynamics<f64, N>,
    q: &SVector<f64, N>,
    qd: &SVector<f64, N>,
) -> f64 {
    let h = 1e-6;
    let (ahead, behind, here) = (chain.frames(&(q + qd * h)), chain.frames(&(q - qd * h)), chain.frames(q));
    let mut energy = 0.0;
    for k in 0..N {
        let link = &d.links()[k];
        let at = |f: &[Pose<f64>; N]| f[k].rotation * link.com + f[k].translation;
        let v = (at(&ahead) - at(&behind)) / (2.0 * h);
        // Ṙ Rᵀ is the skew matrix of the angular velocity (in the base frame).
        let r = here[k].rotation;
        let spin = (ahead[k].rotation - behind[k].rotation) / (2.0 * h) * r.transpose();
        let w =
            Vector3::new(spin[(2, 1)] - spin[(1, 2)], spin[(0, 2)] - spin[(2, 0)], spin[(1, 0)] - spin[(0, 1)]) * 0.5;
        let tensor = r * link.tensor * r.transpose();
        energy += 0.5 * link.mass * v.norm_squared() + 0.5 * w.dot(&(tensor * w));
    }
    energy
}

fn random_dynamics<const N: usize>(rng: &mut SplitMix64) -> Dynamics<f64, N> {
    Dynamics::new(core::array::from_fn(|_| random_link(rng))).unwrap()
}

fn chains() -> (Chain<f64, 5>, Chain<f64, 6>, Chain<f64, 7>) {
    (presets::so101().unwrap(), presets::puma560().unwrap(), presets::iiwa14().unwrap())
}

fn gravity_is_the_gradient_of_the_potential<const N: usize>(chain: &impl Placed<N>, seed: u64) {
    let mut rng = SplitMix64::new(seed);
    for _ in 0..50 {
        let d = random_dynamics::<N>(&mut rng);
        let q = random_q(chain, &mut rng);
        let tau = d.gravity_torques(chain, &q);
        let h = 1e-3;
        for k in 0..N {
            let v = |s: f64| {
                let mut step = SVector::<f64, N>::zeros();
                step[k] = s * h;
                potential(chain, &d, &(q + step))
            };
            // The five-point stencil: error about h⁴ V⁽⁵⁾ / 30 and 1e-16 |V| / h, both near 1e-11
            // for energies of tens of joules.
            let slope = (8.0 * (v(1.0) - v(-1.0)) - (v(2.0) - v(-2.0))) / (12.0 * h);
            assert!((tau[k] - slope).abs() < 1e-9, "joint {k}: {} against {slope}", tau[k]);
        }
    }
}

#[test]
fn gravity_torques_are_the_gradient_of_the_potential_energy() {
    let (so101, puma, iiwa) = chains();
    gravity_is_the_gradient_of_the_potential(&so101, 1);
    gravity_is_the_gradient_of_the_potential(&puma, 2);
    gravity_is_the_gradient_of_the_potential(&iiwa, 3);
    gravity_is_the_gradient_of_the_potential(&torso(), 11);
}

fn mass_matrix_is_the_kinetic_energy<const N: usize>(chain: &impl Placed<N>, seed: u64) {
    let mut rng = SplitMix64::new(seed);
    for _ in 0..50 {
        let d = random_dynamics::<N>(&mut rng);
        let q = random_q(chain, &mut rng);
        let m = d.mass_matrix(chain, &q);
        assert!((m - m.transpose()).abs().max() < 1e-12, "not symmetric: {m}");
        assert!(m.cholesky().is_some(), "not positive definite: {m}");
        let qd = SVector::<f64, N>::from_fn(|_, _| rng.uniform(-2.0, 2.0));
        let quadratic = 0.5 * qd.dot(&(m * qd));
        let t = kinetic(chain, &d, &q, &qd);
        // The differences of the placed poses: error about h² and 1e-16 / h (h = 1e-6).
        assert!((quadratic - t).abs() < 1e-9, "½ q̇ᵀ M q̇ = {quadratic} against the kinetic energy {t}");
        // With no velocity and no gravity, the torque is M q̈.
        let qdd = SVector::<f64, N>::from_fn(|_, _| rng.uniform(-5.0, 5.0));
        let still = d.with_gravity(Vector3::zeros()).unwrap().inverse(chain, &q, &SVector::zeros(), &qdd);
        assert!((still - m * qdd).abs().max() < 1e-12);
    }
}

#[test]
fn the_mass_matrix_is_twice_the_kinetic_energy_and_symmetric_positive_definite() {
    let (so101, puma, iiwa) = chains();
    mass_matrix_is_the_kinetic_energy(&so101, 4);
    mass_matrix_is_the_kinetic_energy(&puma, 5);
    mass_matrix_is_the_kinetic_energy(&iiwa, 6);
    mass_matrix_is_the_kinetic_energy(&torso(), 12);
}

fn lagrange<const N: usize>(chain: &impl Placed<N>, seed: u64) {
    let mut rng = SplitMix64::new(seed);
    for _ in 0..30 {
        let d = random_dynamics::<N>(&mut rng);
        let q = random_q(chain, &mut rng);
        let qd = SVector::<f64, N>::from_fn(|_, _| rng.uniform(-2.0, 2.0));
        let qdd = SVector::<f64, N>::from_fn(|_, _| rng.uniform(-5.0, 5.0));
        let tau = d.inverse(chain, &q, &qd, &qdd);
        // Lagrange: τ = d/dt (M q̇) - ∂T/∂q + ∂V/∂q, T = ½ q̇ᵀ M q̇, along q(t) = q + q̇ t + ½ q̈ t².
        let h = 1e-5;
        let momentum = |t: f64| {
            let (qt, qdt) = (q + qd * t + qdd * (0.5 * t * t), qd + qdd * t);
            d.mass_matrix(chain, &qt) * qdt
        };
        let rate = (momentum(h) - momentum(-h)) / (2.0 * h);
        let energy = |q: &SVector<f64, N>| 0.5 * qd.dot(&(d.mass_matrix(chain, q) * qd));
        let expected = SVector::<f64, N>::from_fn(|k, _| {
            let mut step = SVector::<f64, N>::zeros();
            step[k] = h;
            let dt_dq = (energy(&(q + step)) - energy(&(q - step))) / (2.0 * h);
            rate[k] - dt_dq
        }) + d.gravity_torques(chain, &q);
        // Two central differences of a smooth function of about 1: error about h² and 1e-16 / h.
        let worst = (tau - expected).abs().max();
        assert!(worst < 1e-8, "τ = {tau} against Lagrange's {expected}");
    }
}

#[test]
fn inverse_dynamics_is_lagranges_equation() {
    let (so101, puma, iiwa) = chains();
    lagrange(&so101, 7);
    lagrange(&puma, 8);
    lagrange(&iiwa, 9);
    lagrange(&torso(), 13);
}

/// f32 follows f64 to its precision.
#[test]
fn f32_agrees_with_f64() {
    let chain64: Chain<f64, 5> = presets::so101().unwrap();
    let chain32: Chain<f32, 5> = presets::so101().unwrap();
    let mut rng = SplitMix64::new(10);
    for _ in 0..50 {
        let links: [Inertia<f64>; 5] = core::array::from_fn(|_| random_link(&mut rng));
        let narrow = links.map(|l| Inertia { mass: l.mass as f32, com: l.com.cast(), tensor: l.tensor.cast() });
        let (d64, d32) = (Dynamics::new(links).unwrap(), Dynamics::new(narrow).unwrap());
        let q = random_q(&chain64, &mut rng);
        let qd = SVector::<f64, 5>::from_fn(|_, _| rng.uniform(-2.0, 2.0));
        let qdd = SVector::<f64, 5>::from_fn(|_, _| rng.uniform(-5.0, 5.0));
        let wide = d64.inverse(&chain64, &q, &qd, &qdd);
        let narrow = d32.inverse(&chain32, &q.cast(), &qd.cast(), &qdd.cast()).map(f64::from);
        let scale = wide.abs().max().max(1.0);
        assert!((wide - narrow).abs().max() < 1e-4 * scale, "{wide} against {narrow}");
    }
}

/// Two point masses at a rod's ends are, combined, the rod's two-body inertia about its middle;
/// a payload adds its weight's torque at the tool; bad numbers are refused.
#[test]
fn bodies_combine_by_the_parallel_axis_theorem_and_bad_numbers_are_refused() {
    let (a, b) = (Inertia::point(1.0, Vector3::new(-0.1, 0.0, 0.0)), Inertia::point(1.0, Vector3::new(0.1, 0.0, 0.0)));
    let rod = a.combined(&b);
    assert_eq!(rod.mass, 2.0);
    assert!(rod.com.norm() < 1e-15);
    let expected = Matrix3::from_diagonal(&Vector3::new(0.0, 0.02, 0.02));
    assert!((rod.tensor - expected).abs().max() < 1e-15, "{}", rod.tensor);

    // A 200 g payload at the SO-101's tool: the shoulder lift's holding torque grows by the
    // payload's weight times its lever about that axis, measured from forward kinematics.
    let chain: Chain<f64, 5> = presets::so101().unwrap();
    let light = Dynamics::new([Inertia::zero(); 5]).unwrap();
    let loaded = light.with_payload(&chain, &Inertia::point(0.2, Vector3::zeros())).unwrap();
    let q = SVector::<f64, 5>::from([0.3, -0.4, 0.6, 0.2, 0.0]);
    let frames = chain.forward(&q);
    let lever = frames.tool.translation - frames.joints[1].translation;
    let axis = frames.joints[1].rotation * chain.joints()[1].axis;
    let torque = lever.cross(&Vector3::new(0.0, 0.0, -0.2 * kinematics::dynamics::STANDARD_GRAVITY));
    let expected = -axis.dot(&torque);
    let got = loaded.gravity_torques(&chain, &q)[1];
    assert!((got - expected).abs() < 1e-12, "{got} against {expected}");

    let nan = Inertia { mass: f64::NAN, ..Inertia::zero() };
    assert_eq!(Dynamics::<f64, 1>::new([nan]).unwrap_err(), InertiaError::NotFinite);
    assert_eq!(
        Dynamics::<f64, 1>::new([Inertia::point(-1.0, Vector3::zeros())]).unwrap_err(),
        InertiaError::NegativeMass
    );
    let flat =
        Inertia { mass: 1.0, com: Vector3::zeros(), tensor: Matrix3::from_diagonal(&Vector3::new(1.0, 0.1, 0.1)) };
    assert_eq!(Dynamics::<f64, 1>::new([flat]).unwrap_err(), InertiaError::NotPhysical);
    // Moments that pass the triangle inequality, but a product of inertia no body has.
    let skew =
        Inertia { mass: 1.0, com: Vector3::zeros(), tensor: Matrix3::new(1.0, 2.0, 0.0, 2.0, 1.0, 0.0, 0.0, 0.0, 1.0) };
    assert_eq!(Dynamics::<f64, 1>::new([skew]).unwrap_err(), InertiaError::NotPhysical);
    assert_eq!(light.with_gravity(Vector3::new(0.0, f64::NAN, -9.8)).unwrap_err(), InertiaError::NotFinite);
}
