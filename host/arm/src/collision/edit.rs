//! The surroundings as front ends change them: an obstacle given as one JSON object (the view's
//! API; Python's dicts and tuples are turned into one), every shape's numbers checked before
//! anything moves, added to or removed from an arm's [`CollisionSpec`] by name, and the geometry
//! listed back in the same form.
//!
//! An obstacle is `{"shape": KIND, ...}`, lengths in metres, in the arm's base frame:
//!
//! | shape | fields |
//! |---|---|
//! | `box` | `centre` `[x, y, z]`, `size` `[sx, sy, sz]` (full sizes), optional `rotation` (3 rows, the box's axes as columns) |
//! | `sphere` | `centre`, `radius` |
//! | `capsule` | `a`, `b` (the core segment's ends), `radius` |
//! | `table` | optional `height` (m, default 0): the solid below the plane z = height |
//! | `plane` | `normal` (unit, out of the solid), `offset`: the solid where normal · x <= offset |
//!
//! and an optional `name` (else the shape's kind, numbered when taken: `box`, `box2`, ...).

use anyhow::{anyhow, bail, Result};
use kinematics::collision::{Capsule, Shape};
use kinematics::nalgebra::{Matrix3, Vector3};
use serde_json::{json, Map, Value};

use super::{collision_of, CollisionSpec, ObstacleSpec, MAX_OBSTACLES};
use crate::ArmSpec;

/// The radius of the capsules [`geometry_of`] measures from an arm's frames (m): about a
/// hobby servo's half width.
pub const FRAME_RADIUS: f64 = 0.02;

/// The shapes a front end may give, by the names it gives them.
pub const KINDS: [&str; 5] = ["box", "sphere", "capsule", "table", "plane"];

/// The geometry a front end checks and edits for `arm`: its own (the arm file's or its preset's),
/// else one capsule of [`FRAME_RADIUS`] per link measured from its frames, on a table at its base
/// plane ([`CollisionSpec::from_frames`]).
pub fn geometry_of(arm: &ArmSpec) -> CollisionSpec {
    collision_of(arm).unwrap_or_else(|| CollisionSpec::from_frames(arm, FRAME_RADIUS))
}

/// Where the geometry of [`geometry_of`] comes from, in words.
pub fn source_of(arm: &ArmSpec) -> &'static str {
    match arm.collision {
        Some(_) => "the arm's collision geometry",
        None => "measured from the arm's frames (it has no collision geometry of its own): one 20 mm capsule per link",
    }
}

fn field<'a>(map: &'a Map<String, Value>, name: &str, what: &str) -> Result<&'a Value> {
    map.get(name).ok_or_else(|| anyhow!("{what}: missing field \"{name}\""))
}

fn number(v: &Value, what: &str) -> Result<f64> {
    match v.as_f64() {
        Some(x) if x.is_finite() => Ok(x),
        Some(x) => bail!("{what}: {x} is not a finite number"),
        None if v.is_number() => bail!("{what}: {v} is not a finite number"),
        // Python's NaN and infinities, which JSON cannot spell, come as their names from the
        // binding's conversion.
        None => match v.as_str() {
            Some(s) if s.parse::<f64>().is_ok_and(|x| !x.is_finite()) => bail!("{what}: {s} is not a finite number"),
            _ => bail!("{what}: expected a number, found {v}"),
        },
    }
}

fn point(v: &Value, what: &str) -> Result<Vector3<f64>> {
    let items = v.as_array().ok_or_else(|| anyhow!("{what}: expected 3 numbers [x, y, z], found {v}"))?;
    if items.len() != 3 {
        bail!("{what}: expected 3 numbers [x, y, z], found {}", items.len());
    }
    let mut p = Vector3::zeros();
    for (i, item) in items.iter().enumerate() {
        p[i] = number(item, &format!("{what}[{i}]"))?;
    }
    Ok(p)
}

fn positive(x: f64, what: &str) -> Result<f64> {
    if x > 0.0 {
        Ok(x)
    } else {
        bail!("{what}: {x} m is not a size: it must be above 0")
    }
}

/// The name and shape of the obstacle `value` gives (name `None` when it gives none); refuses
/// with one line a missing or unknown field, a number that is not finite, a size or radius not
/// above zero, a rotation whose axes are not orthonormal, a plane's normal not of unit length.
pub fn obstacle_from_json(value: &Value) -> Result<(Option<String>, Shape<f64>)> {
    let map = value.as_object().ok_or_else(|| anyhow!("an obstacle is an object with a \"shape\", not {value}"))?;
    let kind = field(map, "shape", "obstacle")?
        .as_str()
        .ok_or_else(|| anyhow!("obstacle: \"shape\" must be one of {}", KINDS.join(", ")))?;
    let name = match map.get("name") {
        None | Some(Value::Null) => None,
        Some(Value::String(s)) if is_name(s) => Some(s.clone()),
        Some(other) => bail!("obstacle name {other}: use 1 to 32 letters, digits, '_' or '-'"),
    };
    let what = format!("obstacle {}", name.as_deref().unwrap_or(kind));
    let known: &[&str] = match kind {
        "box" => &["centre", "size", "rotation"],
        "sphere" => &["centre", "radius"],
        "capsule" => &["a", "b", "radius"],
        "table" => &["height"],
        "plane" => &["normal", "offset"],
        other => bail!("obstacle shape {other:?}: one of {}", KINDS.join(", ")),
    };
    if let Some(unknown) = map.keys().find(|k| !known.contains(&k.as_str()) && !["shape", "name"].contains(&k.as_str()))
    {
        bail!("{what}: unknown field \"{unknown}\" (a {kind} takes {})", known.join(", "));
    }
    let radius =
        || positive(number(field(map, "radius", &what)?, &format!("{what}: radius"))?, &format!("{what}: radius"));
    let shape = match kind {
        "box" => {
            let centre = point(field(map, "centre", &what)?, &format!("{what}: centre"))?;
            let size = point(field(map, "size", &what)?, &format!("{what}: size"))?;
            for (i, s) in size.iter().enumerate() {
                positive(*s, &format!("{what}: size[{i}]"))?;
            }
            let rotation = match map.get("rotation") {
                None | Some(Value::Null) => Matrix3::identity(),
                Some(rows) => {
                    let rows = rows.as_array().filter(|r| r.len() == 3).ok_or_else(|| {
                        anyhow!("{what}: rotation: expected 3 rows of 3 numbers (the box's axes as columns)")
                    })?;
                    let mut m = Matrix3::zeros();
                    for (i, row) in rows.iter().enumerate() {
                        let row = point(row, &format!("{what}: rotation[{i}]"))?;
                        m.set_row(i, &row.transpose());
                    }
                    m
                }
            };
            Shape::Box { centre, rotation, half: size * 0.5 }
        }
        "sphere" => {
            Shape::Capsule(Capsule::sphere(point(field(map, "centre", &what)?, &format!("{what}: centre"))?, radius()?))
        }
        "capsule" => Shape::Capsule(Capsule {
            a: point(field(map, "a", &what)?, &format!("{what}: a"))?,
            b: point(field(map, "b", &what)?, &format!("{what}: b"))?,
            radius: radius()?,
        }),
        "table" => {
            let height = map.get("height").map(|h| number(h, &format!("{what}: height"))).transpose()?;
            Shape::table(height.unwrap_or(0.0))
        }
        _ => Shape::HalfSpace {
            normal: point(field(map, "normal", &what)?, &format!("{what}: normal"))?,
            offset: number(field(map, "offset", &what)?, &format!("{what}: offset"))?,
        },
    };
    if !shape.is_valid() {
        bail!("{what}: {}", kinematics::collision::SceneError::Invalid);
    }
    Ok((name, shape))
}

/// Letters, digits, `_` and `-`, 1 to 32 of them: a name that reads on one line.
fn is_name(s: &str) -> bool {
    (1..=32).contains(&s.len()) && s.chars().all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
}

fn xyz(v: &Vector3<f64>) -> Value {
    json!([v.x, v.y, v.z])
}

/// `shape` as [`obstacle_from_json`] reads it (a horizontal half-space as a `table`).
pub fn shape_json(shape: &Shape<f64>) -> Value {
    match shape {
        Shape::Capsule(c) if c.a == c.b => json!({"shape": "sphere", "centre": xyz(&c.a), "radius": c.radius}),
        Shape::Capsule(c) => json!({"shape": "capsule", "a": xyz(&c.a), "b": xyz(&c.b), "radius": c.radius}),
        Shape::Box { centre, rotation, half } => {
            let rows: Vec<Value> =
                (0..3).map(|i| json!([rotation[(i, 0)], rotation[(i, 1)], rotation[(i, 2)]])).collect();
            json!({"shape": "box", "centre": xyz(centre), "size": xyz(&(half * 2.0)), "rotation": rows})
        }
        Shape::HalfSpace { normal, offset } if *normal == Vector3::z() => json!({"shape": "table", "height": offset}),
        Shape::HalfSpace { normal, offset } => json!({"shape": "plane", "normal": xyz(normal), "offset": offset}),
    }
}

/// An obstacle with its name, as [`obstacle_from_json`] reads it.
pub fn obstacle_json(obstacle: &ObstacleSpec) -> Value {
    let mut value = shape_json(&obstacle.shape);
    value["name"] = json!(obstacle.name);
    value
}

/// Everything of `spec` for drawing and listing: the margin, each body (`name`, `link`: the
/// joint whose moving frame carries it, null for the base; `a`, `b`, `radius` in that frame), the
/// obstacles as [`obstacle_json`] gives them, and the allowed pairs.
pub fn geometry_json(spec: &CollisionSpec) -> Value {
    let bodies: Vec<Value> = spec
        .bodies
        .iter()
        .map(|b| {
            json!({"name": b.name, "link": b.link, "a": xyz(&b.capsule.a), "b": xyz(&b.capsule.b), "radius": b.capsule.radius})
        })
        .collect();
    json!({
        "margin": spec.margin,
        "bodies": bodies,
        "obstacles": spec.obstacles.iter().map(obstacle_json).collect::<Vec<_>>(),
        "allowed": spec.allowed,
    })
}

impl CollisionSpec {
    /// `kind` if no body or obstacle has that name, else `kind2`, `kind3`, ...
    pub fn unused_name(&self, kind: &str) -> String {
        (1..)
            .map(|n| if n == 1 { kind.to_string() } else { format!("{kind}{n}") })
            .find(|name| self.part(name).is_none())
            .unwrap_or_else(|| kind.to_string())
    }

    /// Adds an obstacle named `name` (else a fresh name after its kind); returns the name. Refuses
    /// a name already taken by a body or an obstacle, more than [`MAX_OBSTACLES`], a shape that is
    /// not valid.
    pub fn add_obstacle(&mut self, name: Option<&str>, shape: Shape<f64>) -> Result<String> {
        if !shape.is_valid() {
            bail!("obstacle {}: {}", name.unwrap_or("?"), kinematics::collision::SceneError::Invalid);
        }
        if self.obstacles.len() >= MAX_OBSTACLES {
            bail!("there are {MAX_OBSTACLES} obstacles already, as many as the firmware holds: remove one first");
        }
        let name = match name {
            Some(n) if self.part(n).is_some() => bail!("there is a body or obstacle named {n} already"),
            Some(n) => n.to_string(),
            None => {
                let kind = shape_json(&shape)["shape"].as_str().unwrap_or("obstacle").to_string();
                self.unused_name(&kind)
            }
        };
        self.obstacles.push(ObstacleSpec { name: name.clone(), shape });
        Ok(name)
    }

    /// Removes the obstacle named `name` and its allowed pairs; refuses a name that is not an
    /// obstacle's, listing theirs.
    pub fn remove_obstacle(&mut self, name: &str) -> Result<()> {
        if !self.obstacles.iter().any(|o| o.name == name) {
            let names: Vec<&str> = self.obstacles.iter().map(|o| o.name.as_str()).collect();
            let listed = if names.is_empty() { "there are none".to_string() } else { names.join(", ") };
            bail!("no obstacle named {name} (obstacles: {listed})");
        }
        *self = self.clone().without(name);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn read(text: &str) -> Result<(Option<String>, Shape<f64>)> {
        obstacle_from_json(&serde_json::from_str(text).unwrap())
    }

    #[test]
    fn reads_every_shape_and_gives_it_back_the_same() {
        for text in [
            r#"{"shape": "box", "centre": [0.2, 0, 0.05], "size": [0.1, 0.2, 0.1], "name": "crate"}"#,
            r#"{"shape": "sphere", "centre": [0.1, 0.1, 0.1], "radius": 0.03}"#,
            r#"{"shape": "capsule", "a": [0, 0, 0], "b": [0, 0, 0.3], "radius": 0.02}"#,
            r#"{"shape": "table", "height": -0.01}"#,
            r#"{"shape": "plane", "normal": [1, 0, 0], "offset": 0.4}"#,
        ] {
            let (name, shape) = read(text).unwrap();
            let back = shape_json(&shape);
            let (_, again) = obstacle_from_json(&back).unwrap();
            assert_eq!(again, shape, "{text} -> {back}");
            if let Some(name) = name {
                assert_eq!(name, "crate");
            }
        }
        let (_, shape) = read(r#"{"shape": "box", "centre": [0.2, 0, 0.05], "size": [0.1, 0.2, 0.4]}"#).unwrap();
        let Shape::Box { half, .. } = shape else { panic!("a box") };
        assert_eq!(half, Vector3::new(0.05, 0.1, 0.2), "sizes are full sizes");
        assert_eq!(read(r#"{"shape": "table"}"#).unwrap().1, Shape::table(0.0));
    }

    #[test]
    fn refuses_bad_numbers_with_one_line() {
        let cases = [
            (
                r#"{"shape": "box", "centre": [0, 0, 0], "size": [0.1, -0.1, 0.1]}"#,
                "obstacle box: size[1]: -0.1 m is not a size",
            ),
            (r#"{"shape": "sphere", "centre": [0, 0, 0], "radius": 0}"#, "obstacle sphere: radius: 0 m is not a size"),
            (r#"{"shape": "sphere", "centre": [0, 0], "radius": 1}"#, "obstacle sphere: centre: expected 3 numbers"),
            (
                r#"{"shape": "sphere", "centre": [0, "x", 0], "radius": 1}"#,
                "obstacle sphere: centre[1]: expected a number",
            ),
            (r#"{"shape": "cone"}"#, "obstacle shape \"cone\": one of box, sphere"),
            (r#"{"shape": "sphere", "centre": [0, 0, 0]}"#, "obstacle sphere: missing field \"radius\""),
            (r#"{"shape": "table", "size": 1}"#, "obstacle table: unknown field \"size\""),
            (r#"{"shape": "plane", "normal": [1, 1, 0], "offset": 0}"#, "obstacle plane: a collision shape"),
            (r#"{"shape": "table", "name": "a b"}"#, "obstacle name \"a b\""),
            (r#"[1]"#, "an obstacle is an object"),
        ];
        for (text, start) in cases {
            let e = format!("{:#}", read(text).unwrap_err());
            assert!(e.starts_with(start), "{text}: {e}");
            assert!(!e.contains('\n'), "{e}");
        }
        // NaN: JSON has no spelling for it; Python's float('nan') comes by its name.
        let nan = json!({"shape": "sphere", "centre": ["NaN", 0.0, 0.0], "radius": 0.1});
        assert_eq!(
            format!("{:#}", obstacle_from_json(&nan).unwrap_err()),
            "obstacle sphere: centre[0]: NaN is not a finite number"
        );
        let inf = json!({"shape": "sphere", "centre": [0.0, 0.0, 0.0], "radius": "inf"});
        assert_eq!(
            format!("{:#}", obstacle_from_json(&inf).unwrap_err()),
            "obstacle sphere: radius: inf is not a finite number"
        );
    }

    #[test]
    fn adds_and_removes_by_name() {
        let arm = crate::presets::by_name("so101").unwrap();
        let mut spec = geometry_of(&arm);
        assert!(spec.obstacles.iter().any(|o| o.name == super::super::TABLE));
        let sphere = Shape::Capsule(Capsule::sphere(Vector3::new(0.2, 0.0, 0.1), 0.03));
        assert_eq!(spec.add_obstacle(None, sphere).unwrap(), "sphere");
        assert_eq!(spec.add_obstacle(None, sphere).unwrap(), "sphere2");
        assert!(spec.add_obstacle(Some("sphere"), sphere).is_err(), "a name is taken once");
        assert!(spec.add_obstacle(Some("base"), sphere).is_err(), "a body's name too");
        spec.remove_obstacle("sphere").unwrap();
        let names: Vec<&str> = spec.obstacles.iter().map(|o| o.name.as_str()).collect();
        assert_eq!(names, ["table", "sphere2"]);
        spec.remove_obstacle("table").unwrap();
        assert!(spec.allowed.iter().all(|p| !p.contains(&"table".to_string())), "its allowed pairs go with it");
        let e = spec.remove_obstacle("table").unwrap_err().to_string();
        assert_eq!(e, "no obstacle named table (obstacles: sphere2)");
        while spec.obstacles.len() < MAX_OBSTACLES {
            spec.add_obstacle(None, sphere).unwrap();
        }
        assert!(spec.add_obstacle(None, sphere).unwrap_err().to_string().contains("as many as the firmware holds"));
        // Listed back: every body on its link, every obstacle as it is read.
        let listed = geometry_json(&spec);
        assert_eq!(listed["bodies"].as_array().unwrap().len(), spec.bodies.len());
        assert_eq!(listed["obstacles"][0]["name"], "sphere2");
        assert_eq!(listed["bodies"][0]["link"], Value::Null, "the base's body is on no joint");
    }
}
