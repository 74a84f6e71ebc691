//! One tick of a 6-joint `f32` player with a queue of keyframes (goal: at most 100 ns).

use core::hint::black_box;
use criterion::{criterion_group, criterion_main, Criterion};
use kinematics::nalgebra::SVector;
use kinematics::trajectory::{JointLimits, Player, PlayerKeyframe};

fn player_tick(c: &mut Criterion) {
    let limits = JointLimits::<f32, 6>::new(
        SVector::repeat(-3.0),
        SVector::repeat(3.0),
        SVector::repeat(2.0),
        SVector::repeat(10.0),
    )
    .unwrap();
    let mut player = Player::<f32, 6, 32>::new(SVector::zeros(), limits).unwrap();
    for i in 1..=32u16 {
        let p = SVector::from_fn(|j, _| 0.05 * f32::from((i + j as u16) % 5));
        player.push(PlayerKeyframe::new(0.5 * f32::from(i), p)).unwrap();
    }
    // Enter the first segment; then every measured tick evaluates it (1 kHz clock within it).
    player.tick(0.0);
    let mut now = 0.0f32;
    c.bench_function("player_tick_6j_f32", |b| {
        b.iter(|| {
            now = if now >= 0.499 { 0.001 } else { now + 0.001 };
            black_box(player.tick(black_box(now)))
        })
    });
}

criterion_group!(benches, player_tick);
criterion_main!(benches);
