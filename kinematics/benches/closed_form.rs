//! Closed-form IK on the host (goal: all solutions of a 6R arm in under 2 us): the shape's own
//! solutions alone, and with each fitted into the limits and checked by forward kinematics, for
//! 1000 random reachable poses of the UR5e and the PUMA 560, cycled.

use core::hint::black_box;
use criterion::{criterion_group, criterion_main, Criterion};
use kinematics::ik::analytic::ClosedForm;
use kinematics::ik::{IkConfig, IkProblem, Target};
use kinematics::{presets, Chain, SplitMix64};

fn problems(chain: &Chain<f64, 6>) -> Vec<IkProblem<f64, 6>> {
    let mut rng = SplitMix64::new(1);
    (0..1000)
        .map(|_| IkProblem {
            target: Target::Pose(chain.tool_pose(&chain.random_configuration(&mut rng))),
            seed: chain.middle(),
            config: IkConfig::default(),
        })
        .collect()
}

fn closed_form(c: &mut Criterion) {
    for (name, chain) in [("ur5e", presets::ur5e::<f64>().unwrap()), ("puma560", presets::puma560().unwrap())] {
        let closed = ClosedForm::of(&chain).unwrap();
        let problems = problems(&chain);
        let mut i = 0;
        c.bench_function(&format!("closed_form_all_solutions_{name}"), |b| {
            b.iter(|| {
                i = (i + 1) % problems.len();
                black_box(closed.candidates(&chain, black_box(&problems[i])))
            })
        });
        c.bench_function(&format!("closed_form_all_solutions_checked_{name}"), |b| {
            b.iter(|| {
                i = (i + 1) % problems.len();
                black_box(closed.solutions(&chain, black_box(&problems[i])))
            })
        });
        c.bench_function(&format!("closed_form_nearest_{name}"), |b| {
            b.iter(|| {
                i = (i + 1) % problems.len();
                black_box(chain.solve_closed_form(&closed, black_box(&problems[i])))
            })
        });
    }
}

criterion_group!(benches, closed_form);
criterion_main!(benches);
