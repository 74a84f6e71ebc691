//! The signed distances against values computed independently (exact rational arithmetic by
//! another algorithm, cross-checked with python-fcl and dense sampling: collision_values.py), to
//! 1e-9 m in f64 and 2e-6 m in f32; then the scene's checks against a brute-force minimum.

use kinematics::collision::distance::{capsule_box, capsule_capsule, distance};
use kinematics::collision::{Body, Capsule, Part, Scene, Shape};
use kinematics::nalgebra::{Matrix3, Vector3};
use kinematics::{axis_angle_matrix, Pose, Real, SplitMix64};

include!("collision_values.rs.in");

fn v<T: Real>(x: [f64; 3]) -> Vector3<T> {
    Vector3::new(T::of(x[0]), T::of(x[1]), T::of(x[2]))
}

fn capsule<T: Real>(a: [f64; 3], b: [f64; 3], radius: f64) -> Capsule<T> {
    Capsule { a: v(a), b: v(b), radius: T::of(radius) }
}

fn capsules_agree<T: Real>(tolerance: f64) {
    for (k, &(a, b, ra, c, d, rb, expected)) in CAPSULE_CAPSULE.iter().enumerate() {
        let (p, q) = (capsule::<T>(a, b, ra), capsule::<T>(c, d, rb));
        let got = capsule_capsule(&p, &q).to_f64();
        assert!((got - expected).abs() <= tolerance, "case {k}: {got} against {expected}");
        // Symmetric, and the same through the obstacle path.
        let back = distance(&q, &Shape::Capsule(p)).to_f64();
        assert!((back - expected).abs() <= tolerance, "case {k} swapped: {back} against {expected}");
    }
}

fn boxes_agree<T: Real>(tolerance: f64) {
    let mut rng = SplitMix64::new(7);
    for (k, &(a, b, radius, centre, half, expected)) in CAPSULE_BOX.iter().enumerate() {
        let c = capsule::<T>(a, b, radius);
        let got = capsule_box(&c, &v(centre), &Matrix3::identity(), &v(half)).to_f64();
        assert!((got - expected).abs() <= tolerance, "case {k}: {got} against {expected}");
        // The same pair turned about the box's centre by a random rotation: the same distance.
        let axis: Vector3<f64> = Vector3::new(rng.unit_f64() - 0.5, rng.unit_f64() - 0.5, rng.unit_f64() - 0.5);
        let rotation = axis_angle_matrix(&axis.normalize(), rng.unit_f64() * 6.0);
        let turn = |p: [f64; 3]| rotation * (Vector3::from(p) - Vector3::from(centre)) + Vector3::from(centre);
        let turned = Capsule { a: turn(a).map(T::of), b: turn(b).map(T::of), radius: T::of(radius) };
        let shape = Shape::Box { centre: v(centre), rotation: rotation.map(T::of), half: v(half) };
        let got = distance(&turned, &shape).to_f64();
        assert!((got - expected).abs() <= tolerance * 2.0, "case {k} turned: {got} against {expected}");
    }
}

#[test]
fn capsule_distances_match_the_independent_values_in_f64() {
    capsules_agree::<f64>(1e-9);
}

#[test]
fn capsule_distances_match_the_independent_values_in_f32() {
    capsules_agree::<f32>(2e-6);
}

#[test]
fn box_distances_match_the_independent_values_in_f64() {
    boxes_agree::<f64>(1e-9);
}

#[test]
fn box_distances_match_the_independent_values_in_f32() {
    boxes_agree::<f32>(2e-6);
}

#[test]
fn a_half_space_is_measured_from_its_surface_along_its_normal() {
    let c = capsule::<f64>([0.0, 0.0, 0.05], [0.1, 0.0, 0.02], 0.01);
    assert!((distance(&c, &Shape::table(0.0)) - 0.01).abs() < 1e-15);
    assert!((distance(&c, &Shape::table(0.04)) + 0.03).abs() < 1e-15);
    // A wall at x = 0.05 seen from the side x < 0.05: normal -x, offset -0.05.
    let wall = Shape::HalfSpace { normal: -Vector3::x(), offset: -0.05 };
    assert!((distance(&c, &wall) - (-0.1 + 0.05 - 0.01)).abs() < 1e-15);
}

#[test]
fn invalid_shapes_are_refused_by_the_scene() {
    let mut scene: Scene<f64, 2, 2> = Scene::new(0.01);
    let nan = capsule::<f64>([f64::NAN, 0.0, 0.0], [0.0; 3], 0.01);
    assert!(scene.add_body(Body { frame: None, capsule: nan }, 1).is_err());
    let negative = capsule::<f64>([0.0; 3], [0.0; 3], -0.01);
    assert!(scene.add_body(Body { frame: None, capsule: negative }, 1).is_err());
    assert!(scene.add_obstacle(Shape::aligned_box(Vector3::zeros(), Vector3::new(0.1, -0.1, 0.1))).is_err());
    let tilted = Shape::HalfSpace { normal: Vector3::new(0.0, 0.0, 2.0), offset: 0.0 };
    assert!(scene.add_obstacle(tilted).is_err());
    let good = capsule::<f64>([0.0; 3], [0.1, 0.0, 0.0], 0.01);
    assert!(scene.add_body(Body { frame: Some(1), capsule: good }, 1).is_err(), "no joint 1 in a 1-joint arm");
    scene.add_body(Body { frame: Some(0), capsule: good }, 1).unwrap();
    scene.add_body(Body { frame: None, capsule: good }, 1).unwrap();
    assert!(scene.add_body(Body { frame: None, capsule: good }, 1).is_err(), "full");
    assert!(scene.allow(0, Part::Obstacle(0)).is_err(), "no obstacle yet");
}

/// Random bodies on three frames and random obstacles: the scene's closest pair and first
/// contact (with their bounding-sphere shortcuts) against a brute force over every pair.
#[test]
fn the_scene_finds_what_a_brute_force_over_every_pair_finds() {
    let mut rng = SplitMix64::new(45);
    let mut r = |lo: f64, hi: f64| lo + (hi - lo) * rng.unit_f64();
    for _ in 0..500 {
        let mut scene: Scene<f64, 8, 4> = Scene::new(r(0.0, 0.03));
        let mut bodies = Vec::new();
        for k in 0..6 {
            let a = Vector3::new(r(-0.1, 0.1), r(-0.1, 0.1), r(-0.1, 0.1));
            let b = a + Vector3::new(r(-0.1, 0.1), r(-0.1, 0.1), r(-0.1, 0.1));
            let body = Body {
                frame: if k == 0 { None } else { Some((k % 3) as u8) },
                capsule: Capsule { a, b, radius: r(0.0, 0.03) },
            };
            scene.add_body(body, 3).unwrap();
            bodies.push(body);
        }
        let obstacles = [
            Shape::table(r(-0.3, -0.1)),
            Shape::aligned_box(
                Vector3::new(r(-0.2, 0.2), r(-0.2, 0.2), r(-0.2, 0.2)),
                Vector3::new(r(0.01, 0.1), r(0.01, 0.1), r(0.01, 0.1)),
            ),
            Shape::Capsule(Capsule::sphere(Vector3::new(r(-0.2, 0.2), r(-0.2, 0.2), r(-0.2, 0.2)), r(0.01, 0.05))),
        ];
        for o in obstacles {
            scene.add_obstacle(o).unwrap();
        }
        scene.allow(1, Part::Body(2)).unwrap();
        scene.allow(0, Part::Obstacle(0)).unwrap();
        let frames: Vec<Pose<f64>> = (0..3)
            .map(|_| Pose {
                rotation: axis_angle_matrix(
                    &Vector3::new(r(-1.0, 1.0), r(-1.0, 1.0), r(-1.0, 1.0)).normalize(),
                    r(0.0, 6.0),
                ),
                translation: Vector3::new(r(-0.1, 0.1), r(-0.1, 0.1), r(-0.1, 0.1)),
            })
            .collect();
        let placed: Vec<Capsule<f64>> =
            bodies.iter().map(|b| b.frame.map_or(b.capsule, |f| b.capsule.placed(&frames[f as usize]))).collect();
        let mut brute = f64::INFINITY;
        for i in 0..placed.len() {
            for j in i + 1..placed.len() {
                if bodies[i].frame != bodies[j].frame && !(i == 1 && j == 2) {
                    brute = brute.min(capsule_capsule(&placed[i], &placed[j]));
                }
            }
            for (o, shape) in obstacles.iter().enumerate() {
                if !(i == 0 && o == 0) {
                    brute = brute.min(distance(&placed[i], shape));
                }
            }
        }
        let closest = scene.closest(&frames).unwrap();
        assert!((closest.distance - brute).abs() < 1e-12, "{closest:?} against {brute}");
        let margin = scene.margin();
        assert_eq!(scene.first_contact(&frames).is_some(), brute < margin, "margin {margin}, closest {brute}");
    }
}
