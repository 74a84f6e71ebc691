//! Obstacles from numbers: the arm file's `[[obstacles]]` and the command line's `--obstacle`
//! (`box:x,y,z,sx,sy,sz`, `sphere:x,y,z,r`, `capsule:x1,y1,z1,x2,y2,z2,r`, `plane:nx,ny,nz,offset`,
//! each optionally `NAME=` first), checked so that a bad one is one line saying what is wrong; and
//! the surroundings a command line adds to an arm ([`Surroundings`]).

use std::str::FromStr;

use anyhow::{anyhow, bail, Result};
use kinematics::collision::{Capsule, Shape};
use kinematics::nalgebra::Vector3;
use kinematics::Pose;

use super::{CollisionSpec, ObstacleSpec, MAX_OBSTACLES, TABLE};
use crate::ArmSpec;

/// A box about `centre` of full sizes `size`, turned by fixed-axis `rpy` (rad, as URDF's).
pub fn cuboid(centre: [f64; 3], size: [f64; 3], rpy: [f64; 3]) -> Result<Shape<f64>> {
    finite("centre", &centre)?;
    finite("size", &size)?;
    finite("rpy", &rpy)?;
    if let Some(s) = size.iter().find(|s| **s <= 0.0) {
        bail!("a box's size must be positive in every direction, not {s} (size {size:?})");
    }
    let rotation = Pose::from_xyz_rpy([0.0; 3], rpy).rotation;
    Ok(Shape::Box { centre: centre.into(), rotation, half: Vector3::from(size) * 0.5 })
}

/// A sphere of `radius` about `centre`.
pub fn sphere(centre: [f64; 3], radius: f64) -> Result<Shape<f64>> {
    finite("centre", &centre)?;
    positive_radius(radius)?;
    Ok(Shape::Capsule(Capsule::sphere(centre.into(), radius)))
}

/// The points within `radius` of the segment from `a` to `b`.
pub fn capsule(a: [f64; 3], b: [f64; 3], radius: f64) -> Result<Shape<f64>> {
    finite("a", &a)?;
    finite("b", &b)?;
    positive_radius(radius)?;
    Ok(Shape::Capsule(Capsule { a: a.into(), b: b.into(), radius }))
}

/// The solid on the side of the plane `normal · x = offset` that `normal` points away from
/// (`normal` made unit; `offset` in metres along it).
pub fn plane(normal: [f64; 3], offset: f64) -> Result<Shape<f64>> {
    finite("normal", &normal)?;
    finite("offset", &[offset])?;
    let n = Vector3::from(normal);
    if n.norm() < 1e-9 {
        bail!("a plane's normal {normal:?} has no direction");
    }
    Ok(Shape::HalfSpace { normal: n.normalize(), offset })
}

fn finite(key: &str, values: &[f64]) -> Result<()> {
    if values.iter().all(|v| v.is_finite()) {
        Ok(())
    } else {
        bail!("{key} {values:?} must be finite numbers (no nan or inf)")
    }
}

fn positive_radius(radius: f64) -> Result<()> {
    if radius.is_finite() && radius > 0.0 {
        Ok(())
    } else {
        bail!("the radius must be a positive number, not {radius}")
    }
}

impl FromStr for ObstacleSpec {
    type Err = anyhow::Error;

    /// `[NAME=]KIND:NUMBERS`: `box:x,y,z,sx,sy,sz`, `sphere:x,y,z,r`,
    /// `capsule:x1,y1,z1,x2,y2,z2,r` or `plane:nx,ny,nz,offset` (m, the base frame); the name is
    /// the kind's when none is given.
    fn from_str(text: &str) -> Result<Self> {
        let (name, rest) = match text.split_once('=') {
            Some((name, rest)) => (Some(name.trim()), rest),
            None => (None, text),
        };
        let (kind, numbers) = rest.split_once(':').ok_or_else(|| {
            anyhow!("obstacle {text:?}: KIND:NUMBERS, e.g. box:x,y,z,sx,sy,sz, sphere:x,y,z,r, capsule:x1,y1,z1,x2,y2,z2,r or plane:nx,ny,nz,offset")
        })?;
        let kind = kind.trim().to_ascii_lowercase();
        if let Some(name) = name {
            if name.is_empty() || !name.chars().all(|c| c.is_ascii_alphanumeric() || "_-.".contains(c)) {
                bail!("obstacle {text:?}: a name is letters, digits, _, - and . (NAME=KIND:NUMBERS)");
            }
        }
        let values: Vec<f64> = numbers
            .split(',')
            .map(|v| v.trim().parse::<f64>().map_err(|_| anyhow!("obstacle {text:?}: {:?} is not a number", v.trim())))
            .collect::<Result<_>>()?;
        let expected = match kind.as_str() {
            "box" => 6,
            "sphere" => 4,
            "capsule" => 7,
            "plane" => 4,
            other => bail!("obstacle {text:?}: {other:?} is not a kind of obstacle (box, sphere, capsule or plane)"),
        };
        if values.len() != expected {
            bail!("obstacle {text:?}: {kind} takes {expected} numbers, not {}", values.len());
        }
        let v = |i: usize| values[i];
        let shape = match kind.as_str() {
            "box" => cuboid([v(0), v(1), v(2)], [v(3), v(4), v(5)], [0.0; 3]),
            "sphere" => sphere([v(0), v(1), v(2)], v(3)),
            "capsule" => capsule([v(0), v(1), v(2)], [v(3), v(4), v(5)], v(6)),
            _ => plane([v(0), v(1), v(2)], v(3)),
        }
        .map_err(|e| anyhow!("obstacle {text:?}: {e}"))?;
        Ok(ObstacleSpec { name: name.map_or(kind, str::to_string), shape })
    }
}

/// What the command line changes around an arm: obstacles added (`--obstacle`), the table taken
/// away (`--no-table`).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Surroundings {
    /// Added to the arm's own.
    pub obstacles: Vec<ObstacleSpec>,
    /// Without the table the arm stands on.
    pub no_table: bool,
}

impl Surroundings {
    /// True when nothing is changed.
    pub fn is_empty(&self) -> bool {
        self.obstacles.is_empty() && !self.no_table
    }
}

impl CollisionSpec {
    /// The same geometry with `surroundings` applied: the table removed, then the obstacles
    /// added, one named as another is gets `.2`, `.3`... Fails when they do not fit.
    pub fn with_surroundings(self, surroundings: &Surroundings) -> Result<Self> {
        let mut spec = if surroundings.no_table { self.without(TABLE) } else { self };
        for obstacle in &surroundings.obstacles {
            let taken = |name: &str| spec.part(name).is_some();
            let name = match taken(&obstacle.name) {
                false => obstacle.name.clone(),
                true => (2..).map(|k| format!("{}.{k}", obstacle.name)).find(|n| !taken(n)).unwrap_or_default(),
            };
            spec.obstacles.push(ObstacleSpec { name, shape: obstacle.shape });
        }
        if spec.obstacles.len() > MAX_OBSTACLES {
            bail!(
                "{} obstacles: at most {MAX_OBSTACLES} are held (the arm's own and --obstacle's)",
                spec.obstacles.len()
            );
        }
        Ok(spec)
    }
}

impl ArmSpec {
    /// The arm with `surroundings` applied to its collision geometry; an arm without any fails
    /// (obstacles would stop nothing) unless nothing is asked.
    pub fn with_surroundings(mut self, surroundings: &Surroundings) -> Result<Self> {
        if surroundings.is_empty() {
            return Ok(self);
        }
        let Some(spec) = self.collision.take() else {
            bail!(
                "arm {} has no collision bodies, so --obstacle and --no-table would change nothing: give its arm file a \
                 [collision] table (`armctl collision fit` makes one from a URDF)",
                self.name
            );
        };
        self.collision = Some(spec.with_surroundings(surroundings)?);
        Ok(self)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn error(text: &str) -> String {
        let message = format!("{:#}", text.parse::<ObstacleSpec>().unwrap_err());
        assert!(!message.contains('\n'), "{message}");
        message
    }

    #[test]
    fn every_kind_reads_from_its_text() {
        let b: ObstacleSpec = "box:0.2,0,0.05,0.1,0.2,0.1".parse().unwrap();
        assert_eq!(b.name, "box");
        assert_eq!(b.shape, Shape::aligned_box(Vector3::new(0.2, 0.0, 0.05), Vector3::new(0.1, 0.2, 0.1)));
        let s: ObstacleSpec = "ball=sphere:0.1,-0.1,0.2,0.03".parse().unwrap();
        assert_eq!(
            (s.name.as_str(), s.shape),
            ("ball", Shape::Capsule(Capsule::sphere(Vector3::new(0.1, -0.1, 0.2), 0.03)))
        );
        let c: ObstacleSpec = "capsule:0,0,0,0,0,1,0.5".parse().unwrap();
        assert_eq!(c.shape, Shape::Capsule(Capsule { a: Vector3::zeros(), b: Vector3::z(), radius: 0.5 }));
        // A wall at x = 0.3 facing the arm: the normal made unit, the solid beyond it.
        let p: ObstacleSpec = "wall=plane:-2,0,0,-0.3".parse().unwrap();
        assert_eq!(p.shape, Shape::HalfSpace { normal: Vector3::new(-1.0, 0.0, 0.0), offset: -0.3 });
        assert!(p.shape.is_valid());
    }

    #[test]
    fn bad_text_is_one_line_naming_it() {
        for (text, needle) in [
            (
                "box:0,0,0,0.1,-0.1,0.1",
                "obstacle \"box:0,0,0,0.1,-0.1,0.1\": a box's size must be positive in every direction, not -0.1",
            ),
            ("box:0,0,nan,0.1,0.1,0.1", "centre [0.0, 0.0, NaN] must be finite"),
            ("sphere:0,0,0,0", "the radius must be a positive number, not 0"),
            ("sphere:0,0,0", "sphere takes 4 numbers, not 3"),
            ("cone:0,0,0,1", "\"cone\" is not a kind of obstacle"),
            ("box 0,0,0", "KIND:NUMBERS"),
            ("box:0,0,x,1,1,1", "\"x\" is not a number"),
            ("plane:0,0,0,1", "has no direction"),
            ("my box=sphere:0,0,0,1", "a name is letters"),
        ] {
            let e = error(text);
            assert!(e.contains(needle), "{needle:?} not in {e:?}");
        }
    }

    #[test]
    fn surroundings_add_obstacles_and_take_the_table_away() {
        let arm = crate::presets::by_name("open-manipulator-x").unwrap();
        let spec = CollisionSpec::from_frames(&arm, 0.02);
        let boxes = Surroundings {
            obstacles: vec![
                "box:0.2,0,0.05,0.1,0.1,0.1".parse().unwrap(),
                "box:0.3,0,0.05,0.1,0.1,0.1".parse().unwrap(),
            ],
            no_table: true,
        };
        let changed = spec.clone().with_surroundings(&boxes).unwrap();
        let names: Vec<&str> = changed.obstacles.iter().map(|o| o.name.as_str()).collect();
        assert_eq!(names, ["box", "box.2"]);
        assert!(changed.allowed.iter().all(|pair| !pair.contains(&TABLE.to_string())));
        let many = Surroundings { obstacles: vec![boxes.obstacles[0].clone(); MAX_OBSTACLES], no_table: false };
        let e = spec.with_surroundings(&many).unwrap_err().to_string();
        assert!(e.starts_with(&format!("{} obstacles: at most {MAX_OBSTACLES}", MAX_OBSTACLES + 1)), "{e}");
        let bare = ArmSpec { collision: None, ..arm };
        assert!(bare.clone().with_surroundings(&Surroundings::default()).is_ok());
        let e = bare.with_surroundings(&boxes).unwrap_err().to_string();
        assert!(e.contains("has no collision bodies"), "{e}");
    }
}
