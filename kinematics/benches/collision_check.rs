//! One full collision check of the SO-101 on the host, in f32 and f64 (goal in f32: under 1 us):
//! forward kinematics of the five joints, then every checked pair of the scene. The bodies are one
//! capsule of 20 mm per link from the chain's frames, as the host's
//! `CollisionSpec::from_frames` makes them (the base from its origin to the first joint, each link
//! from its joint to the next, the last to the tool), each allowed to touch its neighbour and the
//! base to stand on the table; the obstacles are the table at the base plane and the box of `armctl
//! bench plan` (6 x 16 x 12 cm on the table, at half the middle pose's reach). The configurations
//! are random within the limits (a fixed seed), as a planner asks.

use core::hint::black_box;
use criterion::{criterion_group, criterion_main, Criterion};
use kinematics::collision::{Body, Capsule, Part, Scene, Shape};
use kinematics::nalgebra::{SVector, Vector3};
use kinematics::{Chain, Real, SplitMix64};

fn scene<T: Real>(chain: &Chain<T, 5>) -> Scene<T, 24, 8> {
    let radius = T::of(0.02);
    let mut scene = Scene::new(T::of(0.01));
    let joints = chain.joints();
    let base = Capsule { a: Vector3::zeros(), b: joints[0].origin.translation, radius };
    scene.add_body(Body { frame: None, capsule: base }, 5).unwrap();
    for i in 0..5 {
        let next = joints.get(i + 1).map_or(chain.tool().translation, |j| j.origin.translation);
        let capsule = Capsule { a: Vector3::zeros(), b: next, radius };
        scene.add_body(Body { frame: Some(i as u8), capsule }, 5).unwrap();
        scene.allow(i as u8, Part::Body(i as u8 + 1)).unwrap();
    }
    let table = scene.add_obstacle(Shape::table(T::zero())).unwrap();
    scene.allow(0, Part::Obstacle(table)).unwrap();
    let reach = chain.forward(&chain.middle()).tool.translation.norm();
    let centre = Vector3::new(reach * T::of(0.5), T::zero(), T::of(0.06));
    scene.add_obstacle(Shape::aligned_box(centre, Vector3::new(T::of(0.06), T::of(0.16), T::of(0.12)))).unwrap();
    scene
}

fn check<T: Real>(c: &mut Criterion, name: &str) {
    let chain = kinematics::presets::so101::<T>().unwrap();
    let mut scene = scene(&chain);
    let mut rng = SplitMix64::new(1);
    let configurations: Vec<SVector<T, 5>> = (0..1024)
        .map(|_| SVector::from_fn(|j, _| rng.uniform(chain.joints()[j].limits.lower, chain.joints()[j].limits.upper)))
        .collect();
    let mut k = 0;
    c.bench_function(name, |b| {
        b.iter(|| {
            k = (k + 1) % configurations.len();
            let frames = chain.forward(black_box(&configurations[k]));
            black_box(scene.first_contact(&frames.joints))
        })
    });
}

fn collision_check(c: &mut Criterion) {
    check::<f32>(c, "collision_check_so101_f32");
    check::<f64>(c, "collision_check_so101_f64");
}

criterion_group!(benches, collision_check);
criterion_main!(benches);
