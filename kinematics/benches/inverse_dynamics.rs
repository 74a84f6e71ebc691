//! Inverse dynamics by the recursive Newton-Euler algorithm (`Dynamics::inverse`: positions,
//! velocities and accelerations in, every joint's torque out, gravity included) for the 6-joint
//! PUMA 560 and the 5-joint SO-101, in f64 and f32, and the SO-101's gravity torques alone. The
//! anchor: Pinocchio's RNEA for a 6-joint arm, under 1 us. Links of random mass properties and
//! random states (a fixed seed): the algorithm's cost does not depend on the numbers.

use core::hint::black_box;
use criterion::{criterion_group, criterion_main, Criterion};
use kinematics::dynamics::{Dynamics, Inertia};
use kinematics::nalgebra::{Matrix3, SVector, Vector3};
use kinematics::{presets, Chain, Real, SplitMix64};

fn links<T: Real, const N: usize>(rng: &mut SplitMix64) -> Dynamics<T, N> {
    let links = core::array::from_fn(|_| {
        let com = Vector3::new(rng.uniform(-0.1, 0.1), rng.uniform(-0.1, 0.1), rng.uniform(-0.1, 0.1));
        let tensor = Matrix3::from_diagonal(&Vector3::new(2e-3, 3e-3, 4e-3));
        Inertia { mass: T::of(rng.uniform(0.1, 2.0)), com: com.map(T::of), tensor: tensor.map(T::of) }
    });
    Dynamics::new(links).unwrap()
}

fn states<T: Real, const N: usize>(rng: &mut SplitMix64) -> Vec<[SVector<T, N>; 3]> {
    (0..64).map(|_| core::array::from_fn(|_| SVector::from_fn(|_, _| T::of(rng.uniform(-1.5, 1.5))))).collect()
}

fn bench<T: Real, const N: usize>(c: &mut Criterion, name: &str, chain: &Chain<T, N>) {
    let mut rng = SplitMix64::new(3);
    let dynamics = links::<T, N>(&mut rng);
    let states = states::<T, N>(&mut rng);
    let mut i = 0;
    c.bench_function(name, |b| {
        b.iter(|| {
            i = (i + 1) % states.len();
            let [q, qd, qdd] = &states[i];
            black_box(dynamics.inverse(chain, black_box(q), black_box(qd), black_box(qdd)))
        })
    });
}

fn inverse_dynamics(c: &mut Criterion) {
    bench::<f64, 6>(c, "rnea_puma560_f64", &presets::puma560().unwrap());
    bench::<f32, 6>(c, "rnea_puma560_f32", &presets::puma560().unwrap());
    bench::<f64, 5>(c, "rnea_so101_f64", &presets::so101().unwrap());
    let chain: Chain<f64, 5> = presets::so101().unwrap();
    let mut rng = SplitMix64::new(4);
    let dynamics = links::<f64, 5>(&mut rng);
    let states = states::<f64, 5>(&mut rng);
    let mut i = 0;
    c.bench_function("gravity_so101_f64", |b| {
        b.iter(|| {
            i = (i + 1) % states.len();
            black_box(dynamics.gravity_torques(&chain, black_box(&states[i][0])))
        })
    });
}

criterion_group!(benches, inverse_dynamics);
criterion_main!(benches);
