//! What the demo asks of each arm: Cartesian targets to reach one by one, then a pick-and-place
//! path streamed as Cartesian keyframes. All points lie well inside the arm's reach.

/// One arm's demo.
pub struct Scenario {
    /// Targets of the point-to-point moves (m).
    pub targets: Vec<[f32; 3]>,
    /// Tool speed of the moves (m/s).
    pub speed: f32,
    /// Waypoints of the pick-and-place path with their times (s on the playback clock, m).
    pub waypoints: Vec<(f32, [f32; 3])>,
    /// Spacing of the keyframes streamed along the path (s).
    pub keyframe_spacing: f32,
}

/// The path of a pick at `pick` and a place at `place`, approached from `hover` metres above.
fn pick_and_place(pick: [f32; 3], place: [f32; 3], hover: f32, home: [f32; 3]) -> Vec<(f32, [f32; 3])> {
    let above = |p: [f32; 3]| [p[0], p[1], p[2] + hover];
    vec![
        (1.0, above(pick)),
        (1.8, pick),
        (2.4, pick),
        (3.2, above(pick)),
        (4.6, above(place)),
        (5.4, place),
        (6.0, place),
        (6.8, above(place)),
        (8.2, home),
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
        Some(Self { targets, speed: 0.15, waypoints: pick_and_place(pick, place, 0.06, home), keyframe_spacing: 0.2 })
    }

    /// The keyframes streamed: the path between waypoints sampled every `keyframe_spacing`
    /// seconds on straight lines, waypoints included.
    pub fn keyframes(&self) -> Vec<(f32, [f32; 3])> {
        let mut out = vec![self.waypoints[0]];
        for pair in self.waypoints.windows(2) {
            let ((t0, a), (t1, b)) = (pair[0], pair[1]);
            let steps = ((t1 - t0) / self.keyframe_spacing).round().max(1.0) as usize;
            for s in 1..=steps {
                let u = s as f32 / steps as f32;
                out.push((t0 + u * (t1 - t0), [0, 1, 2].map(|i| a[i] + u * (b[i] - a[i]))));
            }
        }
        out
    }
}
