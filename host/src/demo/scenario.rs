//! What the demo asks of each arm: Cartesian targets to reach one by one, then a pick-and-place
//! path streamed as Cartesian keyframes that carry the gripper's opening: open on the way down,
//! closed on the object at the pick point, carried, opened at the place point. All points lie
//! well inside the arm's reach.

/// One arm's demo.
pub struct Scenario {
    /// Targets of the point-to-point moves (m).
    pub targets: Vec<[f32; 3]>,
    /// Tool speed of the moves (m/s).
    pub speed: f32,
    /// Waypoints of the pick-and-place path: time (s on the playback clock), tool position (m)
    /// and gripper opening (percent, 0 closed to 100 open).
    pub waypoints: Vec<(f32, [f32; 3], f32)>,
    /// Where the object to pick up lies (m).
    pub pick: [f32; 3],
    /// Where the object is to be put down (m).
    pub place: [f32; 3],
    /// The object's width (mm), less than the open jaws'.
    pub object_mm: f64,
    /// Spacing of the keyframes streamed along the path (s).
    pub keyframe_spacing: f32,
}

/// Gripper openings of the path, percent.
const OPEN: f32 = 100.0;
const CLOSED: f32 = 0.0;

/// The path of a pick at `pick` and a place at `place`, approached from `hover` metres above.
/// The jaws open on the way to the pick, close there over a second (the grippers' speed is a
/// full stroke a second, so the ramp is not cut short), stay closed while the object is carried,
/// and open at the place point before the tool rises.
fn pick_and_place(pick: [f32; 3], place: [f32; 3], hover: f32, home: [f32; 3]) -> Vec<(f32, [f32; 3], f32)> {
    let above = |p: [f32; 3]| [p[0], p[1], p[2] + hover];
    vec![
        (1.0, above(pick), OPEN),
        (1.8, pick, OPEN),
        (2.8, pick, CLOSED),
        (3.2, pick, CLOSED),
        (4.0, above(pick), CLOSED),
        (5.4, above(place), CLOSED),
        (6.2, place, CLOSED),
        (7.2, place, OPEN),
        (7.4, place, OPEN),
        (8.2, above(place), OPEN),
        (9.6, home, OPEN),
    ]
}

impl Scenario {
    /// The demo of the simulated arm `name` (`so101` or `open-manipulator-x`).
    pub fn for_arm(name: &str) -> Option<Self> {
        let (targets, pick, place, home) = match name {
            "so101" => (
                vec![[0.20, 0.0, 0.15], [0.15, 0.15, 0.10], [0.25, -0.10, 0.05], [0.12, -0.18, 0.20]],
                [0.22, 0.08, 0.03],
                [0.22, -0.08, 0.03],
                [0.20, 0.0, 0.15],
            ),
            "open-manipulator-x" => (
                vec![[0.20, 0.0, 0.10], [0.15, 0.10, 0.15], [0.18, -0.08, 0.05], [0.25, 0.0, 0.20]],
                [0.20, 0.06, 0.04],
                [0.20, -0.06, 0.04],
                [0.20, 0.0, 0.10],
            ),
            _ => return None,
        };
        Some(Self {
            targets,
            speed: 0.15,
            waypoints: pick_and_place(pick, place, 0.06, home),
            pick,
            place,
            object_mm: 30.0,
            keyframe_spacing: 0.2,
        })
    }

    /// The keyframes streamed: the path between waypoints sampled every `keyframe_spacing`
    /// seconds on straight lines, waypoints included, the gripper's opening linear between them.
    pub fn keyframes(&self) -> Vec<(f32, [f32; 3], f32)> {
        let mut out = vec![self.waypoints[0]];
        for pair in self.waypoints.windows(2) {
            let ((t0, a, ga), (t1, b, gb)) = (pair[0], pair[1]);
            let steps = ((t1 - t0) / self.keyframe_spacing).round().max(1.0) as usize;
            for s in 1..=steps {
                let u = s as f32 / steps as f32;
                out.push((t0 + u * (t1 - t0), [0, 1, 2].map(|i| a[i] + u * (b[i] - a[i])), ga + u * (gb - ga)));
            }
        }
        out
    }
}
