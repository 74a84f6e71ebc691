//! The `armctl demo` plot: a synthetic trace becomes a PNG of the documented size; bad traces give
//! one-line errors and leave no file; odd but valid traces draw without panicking.

use armctl::commands::demo::plot::{write_demo_png, DemoTrace, GripperTrace, MIN_HEIGHT, WIDTH};

mod support;

/// A gripper that opens, closes on something at 35 % from 4 s to 7 s, then opens again.
fn gripper(time: &[f64]) -> GripperTrace {
    let goal: Vec<f64> = time.iter().map(|&t| if (3.0..7.0).contains(&t) { 0.0 } else { 100.0 }).collect();
    let holding: Vec<bool> = time.iter().map(|&t| (4.0..7.0).contains(&t)).collect();
    GripperTrace {
        opening: time
            .iter()
            .zip(&holding)
            .map(|(&t, &h)| {
                if h {
                    35.0
                } else if t < 3.0 {
                    100.0
                } else {
                    60.0
                }
            })
            .collect(),
        load: holding.iter().map(|&h| if h { 50.0 } else { 2.0 }).collect(),
        goal,
        holding,
    }
}

/// Five joints following sinusoids for 10 s at 50 Hz; the servos lag 40 ms and droop slightly.
fn trace() -> DemoTrace {
    const JOINTS: usize = 5;
    let time: Vec<f64> = (0..500).map(|i| f64::from(i) * 0.02).collect();
    let q = |t: f64, j: usize| 0.4 * (j as f64 + 1.0) * (0.6 * t + j as f64).sin();
    let planned: Vec<Vec<f64>> = time.iter().map(|&t| (0..JOINTS).map(|j| q(t, j)).collect()).collect();
    let measured: Vec<Vec<f64>> = time.iter().map(|&t| (0..JOINTS).map(|j| 0.98 * q(t - 0.04, j)).collect()).collect();
    // A made-up planar arm with a vertical base axis, enough to give the path two distinct views.
    let fk = |q: &Vec<f64>| {
        let reach = 0.2 + 0.15 * q[1].cos() + 0.1 * (q[1] + q[2]).cos();
        [reach * q[0].cos(), reach * q[0].sin(), 0.1 + 0.15 * q[1].sin() + 0.1 * (q[1] + q[2]).sin()]
    };
    DemoTrace {
        arm: "synthetic 5-dof".into(),
        joint_names: ["base", "shoulder", "elbow", "wrist pitch", "wrist roll"].map(String::from).to_vec(),
        tool_planned: planned.iter().map(fk).collect(),
        tool_measured: measured.iter().map(fk).collect(),
        targets: [0.0, 2.0, 4.0, 6.2, 8.0].iter().map(|&t| fk(&(0..JOINTS).map(|j| q(t, j)).collect())).collect(),
        phases: vec![(0.0, "move to targets".into()), (6.2, "pick and place".into())],
        gripper: Some(gripper(&time)),
        time,
        planned,
        measured,
    }
}

/// `name` in a folder of its own, removed when dropped (also when the test fails).
fn scratch(name: &str) -> support::TempPath {
    support::TempPath::new(name)
}

/// The image size from a PNG's IHDR chunk, after checking the signature.
fn png_size(bytes: &[u8]) -> (u32, u32) {
    assert!(bytes.len() > 24, "{} bytes is no PNG", bytes.len());
    assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n", "PNG signature");
    assert_eq!(&bytes[12..16], b"IHDR", "first chunk");
    let be = |b: &[u8]| u32::from_be_bytes(b.try_into().unwrap());
    (be(&bytes[16..20]), be(&bytes[20..24]))
}

#[test]
fn synthetic_trace_writes_a_png() {
    let path = scratch("synthetic.png");
    write_demo_png(&path, &trace()).unwrap();
    assert_eq!(png_size(&std::fs::read(&path).unwrap()), (WIDTH, MIN_HEIGHT));
}

#[test]
fn bad_traces_are_one_line_errors_and_write_nothing() {
    type Case = (&'static str, fn(&mut DemoTrace), &'static str);
    let cases: [Case; 8] = [
        ("nan", |t| t.measured[7][2] = f64::NAN, "measured[7][2] is NaN"),
        ("inf", |t| t.tool_planned[3][1] = f64::INFINITY, "tool_planned[3][1] is inf"),
        ("short", |t| t.tool_measured.truncate(499), "500 time samples but 499 tool_measured"),
        ("row", |t| t.planned[9].truncate(4), "planned[9] has 4 values for 5 joints"),
        ("empty", |t| *t = DemoTrace { joint_names: t.joint_names.clone(), ..empty() }, "empty trace"),
        ("backwards", |t| t.time[100] = 0.0, "time decreases from sample 99 to 100"),
        ("gripper nan", |t| t.gripper.as_mut().unwrap().load[42] = f64::NAN, "gripper load[42] is NaN"),
        ("gripper short", |t| t.gripper.as_mut().unwrap().holding.truncate(499), "499 gripper holding"),
    ];
    for (name, spoil, expected) in cases {
        let path = scratch(&format!("{name}.png"));
        let mut t = trace();
        spoil(&mut t);
        let message = write_demo_png(&path, &t).unwrap_err().to_string();
        assert!(message.contains(expected), "{name}: {message}");
        assert!(!message.contains('\n'), "{name}: {message}");
        assert!(!path.exists(), "{name}: file written");
    }
}

#[test]
fn unwritable_path_is_an_error() {
    let path = scratch("no/such/dir/plot.png");
    let message = write_demo_png(&path, &trace()).unwrap_err().to_string();
    assert!(message.starts_with("cannot write plot"), "{message}");
    assert!(!message.contains('\n'), "{message}");
}

fn empty() -> DemoTrace {
    DemoTrace {
        arm: String::new(),
        joint_names: vec![],
        time: vec![],
        planned: vec![],
        measured: vec![],
        tool_planned: vec![],
        tool_measured: vec![],
        targets: vec![],
        phases: vec![],
        gripper: None,
    }
}

/// Degenerate but valid traces: one sample, constant values far from zero, phases outside the
/// time range, many joints, no targets.
#[test]
fn odd_traces_draw() {
    let one = DemoTrace {
        arm: "one sample".into(),
        joint_names: vec!["j".into()],
        time: vec![1e6],
        planned: vec![vec![3.0]],
        measured: vec![vec![3.0]],
        tool_planned: vec![[1e3, 1e3, 1e3]],
        tool_measured: vec![[1e3, 1e3, 1e3]],
        targets: vec![],
        phases: vec![(-5.0, "before".into()), (2e6, "after".into())],
        gripper: Some(GripperTrace { goal: vec![0.0], opening: vec![20.0], load: vec![30.0], holding: vec![true] }),
    };
    write_demo_png(&scratch("one.png"), &one).unwrap();

    let joints = 12;
    let n = 20;
    let many = DemoTrace {
        arm: "many joints".into(),
        joint_names: (0..joints).map(|j| format!("q{j}")).collect(),
        time: (0..n).map(f64::from).collect(),
        planned: vec![vec![0.5; joints]; n as usize],
        measured: vec![vec![0.5; joints]; n as usize],
        tool_planned: vec![[0.1, 0.0, 0.0]; n as usize],
        tool_measured: (0..n).map(|i| [0.1, 0.0, f64::from(i) * 1e-3]).collect(),
        targets: vec![],
        phases: vec![(0.0, String::new())],
        gripper: None,
    };
    let path = scratch("many.png");
    write_demo_png(&path, &many).unwrap();
    let (w, h) = png_size(&std::fs::read(&path).unwrap());
    assert_eq!(w, WIDTH);
    assert!(h > MIN_HEIGHT, "{h}");
    // The gripper gets a panel of its own below the joints: the image grows by one panel.
    let with_gripper = DemoTrace { gripper: Some(gripper(&many.time)), ..many };
    let path = scratch("many-gripper.png");
    write_demo_png(&path, &with_gripper).unwrap();
    let (_, taller) = png_size(&std::fs::read(&path).unwrap());
    assert_eq!(taller, h + 150, "one panel (150 px) more");
}
