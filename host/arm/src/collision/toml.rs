//! The collision part of the arm file, read ([`read`]) and written ([`write`]):
//!
//! ```toml
//! [collision]
//! margin = 0.01            # m: the distance every checked pair keeps (default 0.01)
//! table = 0.0              # the table top's z in the base frame, or false for no table (default 0)
//!
//! [[collision.bodies]]     # at most 24: a capsule on a joint's moving frame, or on the base
//! name = "upper_arm"
//! link = "shoulder_lift"   # a joint's name, or "base"
//! a = [0, 0, 0]            # the core segment's ends (m), in that frame
//! b = [0.11, 0, 0]
//! radius = 0.025
//!
//! [[collision.bodies]]     # a sphere: its centre instead of a and b
//! name = "gripper"
//! link = "wrist_roll"
//! centre = [0, 0, -0.08]
//! radius = 0.03
//!
//! [[collision.allowed]]    # pairs never checked: neighbours, and what stands on the table
//! reason = "touch at the zero pose"   # optional, for the reader
//! pairs = [["base", "shoulder_pan"], ["base", "table"]]
//!
//! [[obstacles]]            # at most 8 with the table, in the base frame
//! name = "bin"
//! box = { centre = [0.25, 0, 0.05], size = [0.1, 0.2, 0.1], rpy = [0, 0, 0.3] }  # rpy optional
//! # or sphere = { centre = [x, y, z], radius = r }
//! #    capsule = { a = [x, y, z], b = [x, y, z], radius = r }
//! #    plane = { normal = [x, y, z], offset = d }  # the solid is where normal . x <= d
//! ```
//!
//! Angles (`rpy`) follow the file's `angles`. Every error is one line naming the line of the file
//! and the entry at fault; [`super::validate::check`] then checks the whole against the arm.

use std::fmt::Write as _;

use anyhow::{anyhow, bail, Result};
use kinematics::collision::{Capsule, Shape};
use serde::Deserialize;
use toml::Spanned;

use super::{obstacle, BodySpec, CollisionSpec, ObstacleSpec, DEFAULT_MARGIN, TABLE};
use crate::toml_file::position;
use crate::toml_writer::{list, quoted, xyz_rpy};
use crate::ArmSpec;

/// `[collision]`.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct CollisionEntry {
    margin: Option<f64>,
    table: Option<TableEntry>,
    #[serde(default)]
    bodies: Vec<Spanned<BodyEntry>>,
    #[serde(default)]
    allowed: Vec<Spanned<AllowedEntry>>,
}

/// `table = 0.0` or `table = false`.
#[derive(Deserialize)]
#[serde(untagged)]
enum TableEntry {
    Top(f64),
    Flag(bool),
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct BodyEntry {
    name: String,
    link: String,
    a: Option<[f64; 3]>,
    b: Option<[f64; 3]>,
    centre: Option<[f64; 3]>,
    radius: f64,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct AllowedEntry {
    #[allow(dead_code)] // For the person reading the file.
    reason: Option<String>,
    pairs: Vec<[String; 2]>,
}

/// `[[obstacles]]`.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct ObstacleEntry {
    name: String,
    #[serde(rename = "box")]
    cuboid: Option<BoxEntry>,
    sphere: Option<SphereEntry>,
    capsule: Option<CapsuleEntry>,
    plane: Option<PlaneEntry>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct BoxEntry {
    centre: [f64; 3],
    size: [f64; 3],
    rpy: Option<[f64; 3]>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SphereEntry {
    centre: [f64; 3],
    radius: f64,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct CapsuleEntry {
    a: [f64; 3],
    b: [f64; 3],
    radius: f64,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct PlaneEntry {
    normal: [f64; 3],
    offset: f64,
}

/// A file holding only the collision part (a preset's table).
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SectionFile {
    collision: Spanned<CollisionEntry>,
    #[serde(default)]
    obstacles: Vec<Spanned<ObstacleEntry>>,
}

/// The collision geometry of `arm` from the arm file's `[collision]` and `[[obstacles]]` (parsed
/// from `text`; `angle` turns the file's angles into radians); `None` when it has neither.
pub(crate) fn read(
    text: &str,
    collision: Option<&Spanned<CollisionEntry>>,
    obstacles: &[Spanned<ObstacleEntry>],
    angle: f64,
    arm: &ArmSpec,
) -> Result<Option<CollisionSpec>> {
    match (collision, obstacles.first()) {
        (None, None) => Ok(None),
        (None, Some(first)) => bail!(
            "{}: [[obstacles]] needs a [collision] table with the arm's bodies (without them nothing is checked)",
            position(text, first.span().start)
        ),
        (Some(entry), _) => read_table(text, entry, obstacles, angle, arm).map(Some),
    }
}

/// A collision table alone (`[collision]` and `[[obstacles]]`, a preset's data file) for `arm`,
/// checked as an arm file's is.
pub fn parse_section(text: &str, arm: &ArmSpec) -> Result<CollisionSpec> {
    let file: SectionFile = toml::from_str(text).map_err(|e| {
        let message = e.message().trim().replace('\n', "; ");
        match e.span() {
            Some(span) => anyhow!("{}: {message}", position(text, span.start)),
            None => anyhow!("{message}"),
        }
    })?;
    read_table(text, &file.collision, &file.obstacles, 1.0, arm)
}

fn read_table(
    text: &str,
    entry: &Spanned<CollisionEntry>,
    obstacles: &[Spanned<ObstacleEntry>],
    angle: f64,
    arm: &ArmSpec,
) -> Result<CollisionSpec> {
    let spec = collision_table(text, entry, angle, arm, obstacles)?;
    super::validate::check(arm, &spec)?;
    Ok(spec)
}

fn collision_table(
    text: &str,
    entry: &Spanned<CollisionEntry>,
    angle: f64,
    arm: &ArmSpec,
    obstacles: &[Spanned<ObstacleEntry>],
) -> Result<CollisionSpec> {
    let at = position(text, entry.span().start);
    let c = entry.get_ref();
    let margin = c.margin.unwrap_or(DEFAULT_MARGIN);
    if !(margin.is_finite() && margin >= 0.0) {
        bail!("{at}: [collision] margin = {margin}: a distance of zero or more (m)");
    }
    let mut spec = CollisionSpec { margin, bodies: Vec::new(), obstacles: Vec::new(), allowed: Vec::new() };
    match c.table {
        None => spec.obstacles.push(ObstacleSpec { name: TABLE.into(), shape: Shape::table(0.0) }),
        Some(TableEntry::Top(z)) if z.is_finite() => {
            spec.obstacles.push(ObstacleSpec { name: TABLE.into(), shape: Shape::table(z) })
        }
        Some(TableEntry::Top(z)) => bail!("{at}: [collision] table = {z}: the table top's z (m) must be finite"),
        Some(TableEntry::Flag(false)) => {}
        Some(TableEntry::Flag(true)) => bail!("{at}: [collision] table = true: give the table top's z (m), or false"),
    }
    if c.bodies.len() > super::MAX_BODIES {
        let at = position(text, c.bodies[super::MAX_BODIES].span().start);
        bail!("{at}: [[collision.bodies]]: {} bodies, at most {} are held", c.bodies.len(), super::MAX_BODIES);
    }
    for body in &c.bodies {
        spec.bodies.push(body_entry(text, body, arm)?);
    }
    for o in obstacles {
        let o_at = format!("{}: [[obstacles]] {}", position(text, o.span().start), o.get_ref().name);
        let shape = obstacle_entry(o.get_ref(), angle).map_err(|e| anyhow!("{o_at}: {e}"))?;
        spec.obstacles.push(ObstacleSpec { name: o.get_ref().name.clone(), shape });
    }
    if spec.obstacles.len() > super::MAX_OBSTACLES {
        bail!("{at}: {} obstacles with the table: at most {} are held", spec.obstacles.len(), super::MAX_OBSTACLES);
    }
    super::validate::unique_names(&spec)?;
    for group in &c.allowed {
        let g_at = position(text, group.span().start);
        for [a, b] in &group.get_ref().pairs {
            for name in [a, b] {
                if spec.part(name).is_none() {
                    bail!("{g_at}: [[collision.allowed]] pair {a} and {b}: no body or obstacle is named {name}");
                }
            }
            spec.allowed.push([a.clone(), b.clone()]);
        }
    }
    Ok(spec)
}

fn body_entry(text: &str, entry: &Spanned<BodyEntry>, arm: &ArmSpec) -> Result<BodySpec> {
    let b = entry.get_ref();
    let at = format!("{}: [[collision.bodies]] {}", position(text, entry.span().start), b.name);
    let link = match b.link.as_str() {
        "base" => None,
        name => Some(arm.joints.iter().position(|j| j.name == name).ok_or_else(|| {
            let names: Vec<&str> = arm.joints.iter().map(|j| j.name.as_str()).collect();
            anyhow!("{at}: link {name:?} is not a joint of the arm ({}) nor \"base\"", names.join(", "))
        })?),
    };
    let (a, bb) = match (b.a, b.b, b.centre) {
        (Some(a), Some(bb), None) => (a, bb),
        (None, None, Some(c)) => (c, c),
        _ => bail!("{at}: give a and b (a capsule) or centre (a sphere)"),
    };
    crate::toml_file::finite(&at, "a, b or centre", &[a, bb].concat())?;
    if !(b.radius.is_finite() && b.radius >= 0.0) {
        bail!("{at}: radius = {}: a distance of zero or more (m)", b.radius);
    }
    Ok(BodySpec { name: b.name.clone(), link, capsule: Capsule { a: a.into(), b: bb.into(), radius: b.radius } })
}

fn obstacle_entry(o: &ObstacleEntry, angle: f64) -> Result<Shape<f64>> {
    match (&o.cuboid, &o.sphere, &o.capsule, &o.plane) {
        (Some(b), None, None, None) => obstacle::cuboid(b.centre, b.size, b.rpy.unwrap_or([0.0; 3]).map(|v| v * angle)),
        (None, Some(s), None, None) => obstacle::sphere(s.centre, s.radius),
        (None, None, Some(c), None) => obstacle::capsule(c.a, c.b, c.radius),
        (None, None, None, Some(p)) => obstacle::plane(p.normal, p.offset),
        _ => bail!("give one of box, sphere, capsule or plane"),
    }
}

/// What an arm file says beside the numbers: where each body came from, and why each group of
/// pairs is allowed.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Notes {
    /// Lines of comment written before the `[collision]` table.
    pub header: Vec<String>,
    /// A comment for each body, by index (none where missing or empty).
    pub sources: Vec<String>,
    /// The allowed pairs in groups with their reason; when empty, every pair in one group.
    pub allowed: Vec<AllowedGroup>,
}

/// Allowed pairs found for one reason.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct AllowedGroup {
    /// Why they are never checked.
    pub reason: String,
    /// The pairs.
    pub pairs: Vec<[String; 2]>,
    /// A comment after each pair, by index (none where missing or empty).
    pub comments: Vec<String>,
}

/// Writes `spec` of `arm` as the arm file's `[collision]` and `[[obstacles]]` tables (angles in
/// radians), so that [`read`] gives it back.
pub fn write(out: &mut String, spec: &CollisionSpec, arm: &ArmSpec, notes: &Notes) {
    for line in &notes.header {
        let _ = writeln!(out, "# {line}");
    }
    let _ = writeln!(out, "[collision]\nmargin = {:?}  # m", spec.margin);
    let table = spec.obstacles.iter().find_map(|o| match (o.name.as_str(), o.shape) {
        (TABLE, Shape::HalfSpace { normal, offset }) if normal == kinematics::nalgebra::Vector3::z() => Some(offset),
        _ => None,
    });
    match table {
        Some(z) => {
            let _ = writeln!(out, "table = {z:?}  # the table top's z in the base frame (m), or false for none");
        }
        None => {
            let _ = writeln!(out, "table = false  # no table; give its top's z (m) to stand on one");
        }
    }
    for (i, body) in spec.bodies.iter().enumerate() {
        let _ = writeln!(out, "\n[[collision.bodies]]");
        if let Some(source) = notes.sources.get(i).filter(|s| !s.is_empty()) {
            let _ = writeln!(out, "# {source}");
        }
        let link = body.link.and_then(|l| arm.joints.get(l)).map_or("base", |j| j.name.as_str());
        let _ = writeln!(out, "name = {}\nlink = {}", quoted(&body.name), quoted(link));
        let (a, b) = (body.capsule.a, body.capsule.b);
        if a == b {
            let _ = writeln!(out, "centre = {}", list(a.as_slice()));
        } else {
            let _ = writeln!(out, "a = {}\nb = {}", list(a.as_slice()), list(b.as_slice()));
        }
        let _ = writeln!(out, "radius = {:?}", body.capsule.radius);
    }
    let all = [AllowedGroup { reason: "pairs never checked".into(), pairs: spec.allowed.clone(), comments: vec![] }];
    let groups = if notes.allowed.is_empty() { &all[..] } else { &notes.allowed[..] };
    for group in groups.iter().filter(|g| !g.pairs.is_empty()) {
        let _ = writeln!(out, "\n[[collision.allowed]]\nreason = {}\npairs = [", quoted(&group.reason));
        for (k, [a, b]) in group.pairs.iter().enumerate() {
            let pair = format!("[{}, {}],", quoted(a), quoted(b));
            let _ = match group.comments.get(k).filter(|c| !c.is_empty()) {
                Some(comment) => writeln!(out, "  {pair}  # {comment}"),
                None => writeln!(out, "  {pair}"),
            };
        }
        let _ = writeln!(out, "]");
    }
    for o in spec.obstacles.iter().filter(|o| !(o.name == TABLE && table.is_some())) {
        let _ = writeln!(out, "\n[[obstacles]]\nname = {}", quoted(&o.name));
        let v = |x: &kinematics::nalgebra::Vector3<f64>| list(x.as_slice());
        let _ = match &o.shape {
            Shape::Capsule(c) if c.a == c.b => {
                writeln!(out, "sphere = {{ centre = {}, radius = {:?} }}", v(&c.a), c.radius)
            }
            Shape::Capsule(c) => {
                writeln!(out, "capsule = {{ a = {}, b = {}, radius = {:?} }}", v(&c.a), v(&c.b), c.radius)
            }
            Shape::Box { centre, rotation, half } => {
                let (_, rpy) = xyz_rpy(&kinematics::Pose { rotation: *rotation, translation: *centre });
                writeln!(out, "box = {{ centre = {}, size = {}, rpy = {} }}", v(centre), v(&(half * 2.0)), list(&rpy))
            }
            Shape::HalfSpace { normal, offset } => {
                writeln!(out, "plane = {{ normal = {}, offset = {offset:?} }}", v(normal))
            }
        };
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::toml_file;
    use kinematics::nalgebra::Vector3;

    const ARM: &str = "name = \"t\"\n[[joint]]\nname = \"pan\"\ntype = \"revolute\"\nxyz = [0, 0, 0.1]\naxis = [0, 0, 1]\nlimits = [-3, 3]\n[[joint]]\nname = \"lift\"\ntype = \"revolute\"\nxyz = [0, 0, 0.05]\naxis = [0, 1, 0]\nlimits = [-1, 1]\n";
    const COLLISION: &str = "[collision]\nmargin = 0.005\ntable = -0.01\n[[collision.bodies]]\nname = \"post\"\nlink = \"base\"\na = [0, 0, 0]\nb = [0, 0, 0.1]\nradius = 0.02\n[[collision.bodies]]\nname = \"turret\"\nlink = \"pan\"\ncentre = [0, 0, 0]\nradius = 0.02\n[[collision.bodies]]\nname = \"arm\"\nlink = \"lift\"\na = [0.05, 0, 0]\nb = [0.2, 0, 0]\nradius = 0.015\n[[collision.allowed]]\npairs = [[\"post\", \"turret\"], [\"post\", \"table\"]]\n";

    fn error(text: &str) -> String {
        let e = toml_file::parse(text).err().unwrap_or_else(|| panic!("accepted:\n{text}"));
        let message = format!("{e:#}");
        assert!(!message.contains('\n'), "{message}");
        message
    }

    #[test]
    fn a_collision_table_is_read() {
        let arm = toml_file::parse(&format!("{ARM}{COLLISION}[[obstacles]]\nname = \"bin\"\nbox = {{ centre = [0.3, 0, 0.05], size = [0.1, 0.1, 0.1] }}\n")).unwrap();
        let spec = arm.collision.unwrap();
        assert_eq!(spec.margin, 0.005);
        assert_eq!(spec.bodies.iter().map(|b| b.link).collect::<Vec<_>>(), [None, Some(0), Some(1)]);
        assert_eq!(spec.bodies[1].capsule, Capsule::sphere(Vector3::zeros(), 0.02));
        assert_eq!(spec.obstacles[0], ObstacleSpec { name: TABLE.into(), shape: Shape::table(-0.01) });
        assert_eq!(spec.obstacles[1].shape, Shape::aligned_box(Vector3::new(0.3, 0.0, 0.05), Vector3::repeat(0.1)));
        assert_eq!(spec.allowed.len(), 2);
        // No [collision]: no geometry; `table = false`: no table.
        assert!(toml_file::parse(ARM).unwrap().collision.is_none());
        let bare = toml_file::parse(&format!(
            "{ARM}{}",
            COLLISION.replace("table = -0.01", "table = false").replace(", [\"post\", \"table\"]", "")
        ))
        .unwrap();
        assert!(bare.collision.unwrap().obstacles.is_empty());
    }

    #[test]
    fn bad_collision_tables_are_one_line_naming_the_entry() {
        let with = |from: &str, to: &str| format!("{ARM}{}", COLLISION.replace(from, to));
        let obstacle = |o: &str| format!("{ARM}{COLLISION}[[obstacles]]\nname = \"bin\"\n{o}\n");
        let many: String = (0..25)
            .map(|k| {
                format!("[[collision.bodies]]\nname = \"b{k}\"\nlink = \"pan\"\ncentre = [0, 0, 0]\nradius = 0.01\n")
            })
            .collect();
        for (text, needle) in [
            (with("b = [0.2, 0, 0]", "b = [nan, 0, 0]"), "[[collision.bodies]] arm: `a, b or centre` must be finite"),
            (with("radius = 0.015", "radius = -0.015"), "line 28, column 1: [[collision.bodies]] arm: radius = -0.015"),
            (with("link = \"lift\"", "link = \"elbow\""), "[[collision.bodies]] arm: link \"elbow\" is not a joint of the arm (pan, lift) nor \"base\""),
            (with("centre = [0, 0, 0]", "a = [0, 0, 0]"), "[[collision.bodies]] turret: give a and b (a capsule) or centre (a sphere)"),
            (with("[\"post\", \"table\"]", "[\"post\", \"desk\"]"), "[[collision.allowed]] pair post and desk: no body or obstacle is named desk"),
            (with("margin = 0.005", "margin = -1.0"), "[collision] margin = -1: a distance of zero or more"),
            (with("table = -0.01", "table = true"), "table = true: give the table top's z"),
            (with("name = \"turret\"", "name = \"post\""), "two collision bodies or obstacles are named post"),
            (format!("{ARM}{COLLISION}{many}"), "[[collision.bodies]]: 28 bodies, at most 24 are held"),
            (obstacle("box = { centre = [0, 0, 1], size = [0.1, -0.1, 0.1] }"), "[[obstacles]] bin: a box's size must be positive in every direction, not -0.1"),
            (obstacle("sphere = { centre = [0, 0, nan], radius = 0.1 }"), "[[obstacles]] bin: centre [0.0, 0.0, NaN] must be finite"),
            (obstacle("sphere = { centre = [0, 0, 1], radius = 0.1 }\nplane = { normal = [0, 0, 1], offset = 0 }"), "[[obstacles]] bin: give one of box, sphere, capsule or plane"),
            (format!("{ARM}[[obstacles]]\nname = \"bin\"\nsphere = {{ centre = [0, 0, 1], radius = 0.1 }}\n"), "[[obstacles]] needs a [collision] table"),
            // The post and the turret are neighbours: without their pair, they touch at rest.
            (with("[\"post\", \"turret\"], ", ""), "at the zero pose post and turret overlap by 40.0 mm (margin 5 mm): the collision geometry would refuse every move"),
            (with("radius = 0.02\n[[collision.bodies]]\nname = \"turret\"", "radius = 0.02\nsize = 1\n[[collision.bodies]]\nname = \"turret\""), "unknown field `size`"),
        ] {
            let e = error(&text);
            assert!(e.contains(needle), "{needle:?} not in {e:?}");
        }
        let nine: String = (0..8)
            .map(|k| format!("[[obstacles]]\nname = \"o{k}\"\nsphere = {{ centre = [1, 1, 1], radius = 0.1 }}\n"))
            .collect();
        assert!(error(&format!("{ARM}{COLLISION}{nine}")).contains("9 obstacles with the table: at most 8 are held"));
    }

    #[test]
    fn written_and_read_back_it_is_the_same() {
        let mut arm = toml_file::parse(&format!("{ARM}{COLLISION}")).unwrap();
        let mut spec = arm.collision.take().unwrap();
        spec.obstacles.push(ObstacleSpec {
            name: "bin".into(),
            shape: obstacle::cuboid([0.3, -0.1, 0.05], [0.1, 0.2, 0.3], [0.1, -0.2, 1.3]).unwrap(),
        });
        spec.obstacles
            .push(ObstacleSpec { name: "ball".into(), shape: obstacle::sphere([0.3, 0.3, 0.3], 0.05).unwrap() });
        spec.obstacles.push(ObstacleSpec {
            name: "bar".into(),
            shape: obstacle::capsule([0.4, 0.0, 0.0], [0.4, 0.0, 0.5], 0.01).unwrap(),
        });
        spec.obstacles
            .push(ObstacleSpec { name: "wall".into(), shape: obstacle::plane([-1.0, 0.0, 0.0], -0.6).unwrap() });
        arm.collision = Some(spec.clone());
        let text = crate::toml_writer::to_text(&arm, &[]);
        let back = toml_file::parse(&text).unwrap_or_else(|e| panic!("{e:#}\n{text}")).collision.unwrap();
        assert_eq!((back.margin, &back.bodies, &back.allowed), (spec.margin, &spec.bodies, &spec.allowed));
        assert_eq!(back.obstacles.len(), spec.obstacles.len());
        for (x, y) in back.obstacles.iter().zip(&spec.obstacles) {
            assert_eq!(x.name, y.name);
            match (x.shape, y.shape) {
                (Shape::Box { centre, rotation, half }, Shape::Box { centre: c, rotation: r, half: h }) => {
                    assert_eq!((centre, half), (c, h));
                    assert!((rotation - r).amax() < 1e-15, "{rotation} vs {r}");
                }
                (a, b) => assert_eq!(a, b),
            }
        }
        // No table: written as false, read back without one.
        arm.collision = Some(spec.without(TABLE));
        let text = crate::toml_writer::to_text(&arm, &[]);
        assert!(text.contains("table = false"), "{text}");
        let back = toml_file::parse(&text).unwrap().collision.unwrap();
        assert!(back.part(TABLE).is_none() && back.obstacles.len() == 4);
    }
}
