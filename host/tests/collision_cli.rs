//! `armctl collision fit|check` and the drive options `--obstacle` and `--no-table` from the
//! command line: a URDF's collision elements fitted into a `[collision]` section that an arm file
//! reads back as fitted, the SO-101 preset refusing the issue's three targets below its base plane
//! (found by `armctl ik`, an independent path) and naming the gripper and the table, obstacles
//! added and the table taken away, and every bad input one line.

mod support;

use serde_json::Value;
use support::{armctl, TempPath};

/// A binary STL of `triangles` (the format's header, count, and 50 bytes a facet).
fn binary_stl(triangles: &[[[f32; 3]; 3]]) -> Vec<u8> {
    let mut bytes = vec![b' '; 80];
    bytes.extend((triangles.len() as u32).to_le_bytes());
    for t in triangles {
        bytes.extend([0u8; 12]);
        t.iter().flatten().for_each(|x| bytes.extend(x.to_le_bytes()));
        bytes.extend([0u8; 2]);
    }
    bytes
}

/// A two-joint arm: a cylinder for a base, a box on the pan joint, a mesh (a 0.2 m bar, in mm)
/// on the lift joint.
const URDF: &str = r#"<robot name="bar-arm">
  <link name="base_link">
    <collision><origin xyz="0 0 0.03"/><geometry><cylinder radius="0.04" length="0.06"/></geometry></collision>
  </link>
  <link name="turret_link">
    <collision><origin xyz="0 0 0.02"/><geometry><box size="0.05 0.05 0.04"/></geometry></collision>
  </link>
  <link name="bar_link">
    <collision><geometry><mesh filename="meshes/bar.stl" scale="0.001 0.001 0.001"/></geometry></collision>
  </link>
  <link name="tip_link"/>
  <joint name="pan" type="revolute"><parent link="base_link"/><child link="turret_link"/><origin xyz="0 0 0.06"/>
    <axis xyz="0 0 1"/><limit lower="-3" upper="3"/></joint>
  <joint name="lift" type="revolute"><parent link="turret_link"/><child link="bar_link"/><origin xyz="0 0 0.08"/>
    <axis xyz="0 1 0"/><limit lower="-1.5" upper="1.5"/></joint>
  <joint name="tip" type="fixed"><parent link="bar_link"/><child link="tip_link"/><origin xyz="0.2 0 0"/></joint>
</robot>"#;

fn bar_arm() -> TempPath {
    let urdf = TempPath::new("bar-arm/bar.urdf");
    std::fs::create_dir_all(urdf.parent().unwrap().join("meshes")).unwrap();
    std::fs::write(&*urdf, URDF).unwrap();
    let bar = [
        [[30.0, -10.0, -10.0], [200.0, 10.0, -10.0], [200.0, -10.0, 10.0]],
        [[30.0, 10.0, 10.0], [30.0, -10.0, 10.0], [200.0, 10.0, 10.0]],
        [[30.0, 10.0, -10.0], [200.0, -10.0, -10.0], [30.0, -10.0, -10.0]],
    ];
    std::fs::write(urdf.parent().unwrap().join("meshes/bar.stl"), binary_stl(&bar)).unwrap();
    urdf
}

#[test]
fn a_fitted_section_is_read_back_by_an_arm_file_as_fitted() {
    let urdf = bar_arm();
    let path = urdf.to_str().unwrap();
    let fit = armctl(&["collision", "fit", "--arm", path]);
    assert_eq!(fit.code, 0, "{}", fit.stderr);
    assert!(
        fit.stdout.starts_with(&format!(
            "# The collision geometry of bar-arm, made by\n#   armctl collision fit --arm {path}\n"
        )),
        "{}",
        fit.stdout
    );
    let report = armctl(&["collision", "fit", "--arm", path, "--json"]).json();
    assert_eq!(report["toml"].as_str().unwrap(), fit.stdout);
    let names: Vec<&str> = report["bodies"].as_array().unwrap().iter().map(|b| b["name"].as_str().unwrap()).collect();
    assert_eq!(names, ["base", "turret", "bar"]);
    // The mesh's corners in metres, each within its capsule: by hand the bar along x from 0.03 to
    // 0.2 with a radius of its cross-section's half diagonal, 0.0141 m.
    let bar = &report["bodies"][2];
    assert_eq!(bar["link"], "lift");
    let radius = bar["radius"].as_f64().unwrap();
    assert!((0.0141..0.0145).contains(&radius), "{bar}");
    // The base's cylinder and the turret's box touch at rest: a pair found at the zero pose; the
    // base stands on the table.
    let allowed: Vec<(String, String)> = report["allowed"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| {
            (
                format!("{}-{}", p["pair"][0].as_str().unwrap(), p["pair"][1].as_str().unwrap()),
                p["reason"].as_str().unwrap().to_string(),
            )
        })
        .collect();
    assert!(allowed.iter().any(|(p, r)| p == "base-turret" && r.contains("zero pose")), "{allowed:?}");
    assert!(allowed.iter().any(|(p, r)| p == "base-table" && r.contains("standing")), "{allowed:?}");

    // The arm file: the URDF's joints written by the arm crate, and the section as printed.
    let spec = armctl::arm::urdf::parse(URDF, None).unwrap();
    let file = TempPath::new("bar-arm.toml");
    std::fs::write(&*file, format!("{}\n{}", armctl::arm::toml_writer::to_text(&spec, &[]), fit.stdout)).unwrap();
    let read = armctl::arm::ArmSpec::load(file.to_str().unwrap(), None).unwrap().collision.unwrap();
    for (body, reported) in read.bodies.iter().zip(report["bodies"].as_array().unwrap()) {
        assert_eq!(body.capsule.radius, reported["radius"].as_f64().unwrap());
        let a: [f64; 3] = body.capsule.a.into();
        assert_eq!(serde_json::to_value(a).unwrap(), reported["a"]);
    }
    // The file and the URDF give one answer: the bar folded down onto the base is in contact.
    for arm in [file.to_str().unwrap(), path] {
        let folded = armctl(&["collision", "check", "--arm", arm, "--joints=0,1.5", "--json"]);
        assert_eq!(folded.code, 1, "{}", folded.stderr);
        let v: Value = serde_json::from_str(folded.stdout.trim()).unwrap();
        assert_eq!((v["free"].as_bool(), v["closest"][0].as_str()), (Some(false), Some("bar")), "{v}");
        assert_eq!(armctl(&["collision", "check", "--arm", arm, "--joints=0,0"]).code, 0);
    }
}

/// `armctl ik` finds the joints for a target, as `move` would drive them.
fn ik(target: &str) -> String {
    let q = armctl(&["ik", "--arm", "so101", "--target", target]).json()["q"].clone();
    q.as_array().unwrap().iter().map(|x| x.as_f64().unwrap().to_string()).collect::<Vec<_>>().join(",")
}

#[test]
fn the_so101_below_its_base_plane_is_in_contact_with_the_table_and_named() {
    for target in ["0.20,0,-0.08", "0.15,0.10,-0.03", "0.25,-0.05,-0.01"] {
        let q = ik(target);
        let run = armctl(&["collision", "check", "--arm", "so101", &format!("--joints={q}"), "--json"]);
        assert_eq!(run.code, 1, "{target}: {}", run.stdout);
        let v: Value = serde_json::from_str(run.stdout.trim()).unwrap();
        let body = v["closest"][0].as_str().unwrap();
        assert!(body.starts_with("gripper") || body.starts_with("moving_jaw"), "{target}: {v}");
        assert_eq!(v["closest"][1], "table", "{target}: {v}");
        assert!(v["said"].as_str().unwrap().contains(" and table overlap by "), "{v}");
        // Without the table, the table is not what is in the way (the wrist reaching down in
        // front of the base may still come within the margin of the shoulder).
        let bare = armctl(&["--no-table", "collision", "check", "--arm", "so101", &format!("--joints={q}"), "--json"]);
        let v: Value = serde_json::from_str(bare.stdout.trim()).unwrap_or_else(|_| panic!("{}", bare.stderr));
        assert_ne!(v["closest"][1], "table", "{target}: {v}");
    }
    let zero = armctl(&["collision", "check", "--arm", "so101", "--joints=0,0,0,0,0"]);
    assert_eq!((zero.code, zero.stdout.starts_with("free: ")), (0, true), "{}", zero.stdout);
}

#[test]
fn an_obstacle_at_the_tool_is_named_and_bad_ones_are_one_line() {
    let fk = armctl(&["fk", "--arm", "so101", "--q", "0,0,0,0,0"]).json();
    let p: Vec<f64> = fk["position"].as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect();
    let bin = format!("bin=sphere:{},{},{},0.02", p[0], p[1], p[2]);
    let run = armctl(&["collision", "check", "--arm", "so101", "--joints=0,0,0,0,0", "--obstacle", &bin, "--json"]);
    assert_eq!(run.code, 1, "{}", run.stderr);
    let v: Value = serde_json::from_str(run.stdout.trim()).unwrap();
    assert_eq!(v["closest"][1], "bin", "{v}");
    for (args, needle) in [
        (vec!["--obstacle", "box:0,0,0,0.1,-0.1,0.1"], "a box's size must be positive in every direction, not -0.1"),
        (vec!["--obstacle", "sphere:0,0,nan,0.1"], "must be finite numbers"),
        (vec!["--obstacle", "cone:0,0,0,1"], "\"cone\" is not a kind of obstacle"),
        (vec!["--arm", "planar:2", "--obstacle", "sphere:1,1,1,0.1"], "arm planar:2 has no collision bodies"),
        (
            vec!["--port", "/dev/null", "--no-table"],
            "--obstacle and --no-table change the arm sent to the board: name it with --arm",
        ),
    ] {
        let mut all = args.clone();
        if !all.contains(&"--port") {
            all.insert(0, "--sim");
        }
        all.push("status");
        let run = armctl(&all);
        assert_ne!(run.code, 0, "{all:?}");
        assert!(
            run.stderr.contains(needle) && run.stderr.trim().lines().count() == 1,
            "{all:?}: {needle:?} not in {:?}",
            run.stderr
        );
    }
    let fit = armctl(&["collision", "fit", "--arm", "so101"]);
    assert!(fit.code == 1 && fit.stderr.contains("so101 is not a .urdf file"), "{}", fit.stderr);
    // A drive command with an obstacle out of the way runs as before.
    let status = armctl(&["--sim", "--obstacle", "wall=plane:-1,0,0,-0.6", "--no-table", "status", "--json"]);
    assert_eq!(status.code, 0, "{}", status.stderr);
}
