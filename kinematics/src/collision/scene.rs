//! A scene: an arm's bodies, each a capsule fixed to one of its frames, the obstacles around it,
//! the pairs that are never checked (the allowed-collision matrix) and the margin every other
//! pair must keep. Fixed capacity, no heap, no panics: what a firmware checks every goal against.
//!
//! Bodies are placed from the frames forward kinematics gives (a chain's [`crate::Frames`] or a
//! tree's [`crate::tree::TreeFrames`]), so chains and trees share it. The bodies of one frame
//! form a group. Groups are first compared by bounding spheres (a group against another and
//! against each obstacle), then the pairs of groups that come within the margin body by body, and
//! only a pair whose spheres come within it is measured exactly: most pairs of an arm are far
//! apart most of the time, and a link cut into several capsules costs one comparison while it is.

use heapless::Vec;

use super::distance::{box_measure, capsule_capsule, distance};
use super::shape::{Capsule, Shape};
use crate::{Pose, Real};

/// A body of the arm: a capsule in the frame of a joint (after its motion), or of the base.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Body<T: Real> {
    /// The joint whose moving frame carries it; `None`: the base, which does not move.
    pub frame: Option<u8>,
    /// The capsule, in that frame.
    pub capsule: Capsule<T>,
}

/// What a body can come too close to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Part {
    /// Another body of the arm, by index.
    Body(u8),
    /// An obstacle, by index.
    Obstacle(u8),
}

/// Two parts closer than the margin (or the closest pair, for a report).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Contact<T: Real> {
    /// The arm's body, by index.
    pub body: u8,
    /// What it is close to.
    pub other: Part,
    /// Their signed distance (m); negative when they overlap.
    pub distance: T,
}

/// Why a body or an obstacle was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SceneError {
    /// Its numbers are not finite, a size not positive, a box's axes not orthonormal.
    Invalid,
    /// It sits on a frame the arm does not have.
    NoFrame,
    /// There is no room for another.
    Full,
    /// An index names no body or obstacle.
    NoSuchPart,
}

impl core::fmt::Display for SceneError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            SceneError::Invalid => "a collision shape has a non-finite number or a size that is not positive",
            SceneError::NoFrame => "a collision body is on a joint the arm does not have",
            SceneError::Full => "too many collision bodies or obstacles for this build",
            SceneError::NoSuchPart => "a collision pair names a body or obstacle that does not exist",
        })
    }
}

/// Up to `B` bodies and `O` obstacles (each at most 32: the allowed pairs are bit masks).
#[derive(Clone, Debug)]
pub struct Scene<T: Real, const B: usize, const O: usize> {
    bodies: Vec<Body<T>, B>,
    obstacles: Vec<Shape<T>, O>,
    /// Bit `j` of `allowed_bodies[i]`: bodies `i` and `j` are never checked (both bits are set).
    allowed_bodies: [u32; B],
    /// Bit `o` of `allowed_obstacles[i]`: body `i` and obstacle `o` are never checked.
    allowed_obstacles: [u32; B],
    margin: T,
    /// The bodies where the last check placed them (kept here, not on the stack: a firmware's
    /// stack is small and this is its largest array).
    placed: [Capsule<T>; B],
    /// The bounding sphere of each placed body (centre, radius): computed once a check, not once
    /// a pair (a square root each, in software on a Cortex-M4F).
    spheres: [(nalgebra::Vector3<T>, T); B],
    /// Each body's group: the bodies of one frame (they never move apart, and are not checked
    /// against each other).
    group: [u8; B],
    /// Each group's bodies (bit masks, by body index); groups are numbered from 0 as they appear.
    members: [u32; B],
    /// The groups there are.
    groups: u8,
    /// Each group's bounding sphere, as placed by the last check.
    group_spheres: [(nalgebra::Vector3<T>, T); B],
    /// Per group, the bodies of the groups whose spheres come within the last check's distance
    /// of its own (its own included), and the obstacles that do.
    near_bodies: [u32; B],
    near_obstacles: [u32; B],
}

fn bit(i: usize) -> u32 {
    1u32.checked_shl(i as u32).unwrap_or(0)
}

/// The set bits of `mask`, lowest first.
fn bits(mut mask: u32) -> impl Iterator<Item = u8> {
    core::iter::from_fn(move || {
        let i = mask.trailing_zeros();
        mask &= mask.wrapping_sub(1);
        (i < 32).then_some(i as u8)
    })
}

/// True if spheres whose centres are `gap_squared` apart (squared) are farther apart than `reach`
/// (their radii and the distance asked for); `reach` is negative where an overlap is asked for,
/// and then any non-negative gap is far. A NaN gap (a frame not given) is never far, so it is
/// measured and reads as a contact.
fn far<T: Real>(gap_squared: T, reach: T) -> bool {
    gap_squared > reach * reach && reach >= T::zero() || reach < T::zero() && gap_squared >= T::zero()
}

/// True if the sphere at `centre` of `radius` is farther than `beyond` from `shape`, so nothing
/// within it can come closer.
fn sphere_far_from<T: Real>(centre: &nalgebra::Vector3<T>, radius: T, shape: &Shape<T>, beyond: T) -> bool {
    match shape {
        // The centre's signed distance to the box, as its measure: squared outside, minus the
        // depth inside (a centre deep inside can be deeper than an overlap already found).
        Shape::Box { centre: c, rotation, half } => {
            let measure = box_measure(&rotation.tr_mul(&(centre - c)), half);
            if measure > T::zero() {
                far(measure, radius + beyond)
            } else {
                measure > radius + beyond
            }
        }
        Shape::Capsule(c) => {
            let (c2, r2) = c.bounding_sphere();
            far((centre - c2).norm_squared(), radius + r2 + beyond)
        }
        Shape::HalfSpace { .. } => distance(&Capsule::sphere(*centre, radius), shape) > beyond,
    }
}

impl<T: Real, const B: usize, const O: usize> Scene<T, B, O> {
    /// No bodies, no obstacles, the margin given (negative or not finite: zero).
    pub fn new(margin: T) -> Self {
        let nowhere = Capsule::sphere(nalgebra::Vector3::zeros(), T::zero());
        // Returned as one literal, not built in a local and then returned: the compiler then
        // writes it straight into its destination, and a firmware's start-up stack holds no copy.
        Self {
            bodies: Vec::new(),
            obstacles: Vec::new(),
            allowed_bodies: [0; B],
            allowed_obstacles: [0; B],
            margin: if margin.finite() && margin > T::zero() { margin } else { T::zero() },
            placed: [nowhere; B],
            spheres: [(nalgebra::Vector3::zeros(), T::zero()); B],
            group: [0; B],
            members: [0; B],
            groups: 0,
            group_spheres: [(nalgebra::Vector3::zeros(), T::zero()); B],
            near_bodies: [0; B],
            near_obstacles: [0; B],
        }
    }

    /// Makes this scene a copy of `other`, in place: no second scene is built on the stack (a
    /// firmware's scene is a few kilobytes, its stack budget eight).
    pub fn assign(&mut self, other: &Self) {
        self.bodies.clear();
        // Both hold the same capacity, so every body and obstacle fits.
        for body in other.bodies.iter() {
            let _ = self.bodies.push(*body);
        }
        self.obstacles.clear();
        for shape in other.obstacles.iter() {
            let _ = self.obstacles.push(*shape);
        }
        self.allowed_bodies = other.allowed_bodies;
        self.allowed_obstacles = other.allowed_obstacles;
        self.margin = other.margin;
        self.group = other.group;
        self.members = other.members;
        self.groups = other.groups;
    }

    /// Whether there is any pair to check: at least one body, and another body or an obstacle.
    pub fn is_empty(&self) -> bool {
        self.bodies.is_empty() || (self.bodies.len() < 2 && self.obstacles.is_empty())
    }

    /// Removes every body, obstacle and allowed pair; keeps the margin.
    pub fn clear(&mut self) {
        // In place, not `*self = Self::new(..)`: that would build a whole scene on the stack.
        self.bodies.clear();
        self.obstacles.clear();
        self.allowed_bodies = [0; B];
        self.allowed_obstacles = [0; B];
        self.group = [0; B];
        self.members = [0; B];
        self.groups = 0;
    }

    /// Sets the distance every checked pair must keep (m); negative or not finite: zero.
    pub fn set_margin(&mut self, margin: T) {
        self.margin = if margin.finite() && margin > T::zero() { margin } else { T::zero() };
    }

    /// The margin every checked pair keeps.
    pub fn margin(&self) -> T {
        self.margin
    }

    /// The bodies, in the order they were added.
    pub fn bodies(&self) -> &[Body<T>] {
        &self.bodies
    }

    /// The obstacles, in the order they were added.
    pub fn obstacles(&self) -> &[Shape<T>] {
        &self.obstacles
    }

    /// Adds a body of an arm of `joints` joints; returns its index.
    pub fn add_body(&mut self, body: Body<T>, joints: usize) -> Result<u8, SceneError> {
        if !body.capsule.is_valid() {
            return Err(SceneError::Invalid);
        }
        if body.frame.is_some_and(|f| usize::from(f) >= joints) {
            return Err(SceneError::NoFrame);
        }
        let index = self.bodies.len();
        if index >= B.min(32) {
            return Err(SceneError::Full);
        }
        // Its frame's group, or a new one.
        let group = match self.bodies.iter().position(|b| b.frame == body.frame) {
            Some(k) => self.group.get(k).copied().ok_or(SceneError::Full)?,
            None => self.groups,
        };
        self.bodies.push(body).map_err(|_| SceneError::Full)?;
        if group == self.groups {
            self.groups += 1;
        }
        // Within `B` (the index is), so neither fails.
        if let (Some(g), Some(m)) = (self.group.get_mut(index), self.members.get_mut(usize::from(group))) {
            *g = group;
            *m |= bit(index);
        }
        Ok(index as u8)
    }

    /// Adds an obstacle; returns its index.
    pub fn add_obstacle(&mut self, shape: Shape<T>) -> Result<u8, SceneError> {
        if !shape.is_valid() {
            return Err(SceneError::Invalid);
        }
        let index = self.obstacles.len();
        if index >= O.min(32) {
            return Err(SceneError::Full);
        }
        self.obstacles.push(shape).map_err(|_| SceneError::Full)?;
        Ok(index as u8)
    }

    /// Removes every obstacle and the pairs allowed with them; the bodies stay.
    pub fn clear_obstacles(&mut self) {
        self.obstacles.clear();
        self.allowed_obstacles = [0; B];
    }

    /// Never checks body `body` against `other` (a neighbour it always touches, or the table
    /// under the base).
    pub fn allow(&mut self, body: u8, other: Part) -> Result<(), SceneError> {
        let i = usize::from(body);
        if i >= self.bodies.len() {
            return Err(SceneError::NoSuchPart);
        }
        // Through `get_mut`: the lengths are within the masks' `B`, which the compiler cannot
        // see, and a firmware links no panic path.
        match other {
            Part::Body(j) if usize::from(j) < self.bodies.len() => {
                let j = usize::from(j);
                let (mi, mj) = (bit(i), bit(j));
                self.allowed_bodies.get_mut(i).map(|m| *m |= mj).ok_or(SceneError::NoSuchPart)?;
                self.allowed_bodies.get_mut(j).map(|m| *m |= mi).ok_or(SceneError::NoSuchPart)?;
            }
            Part::Obstacle(o) if usize::from(o) < self.obstacles.len() => {
                let mo = bit(usize::from(o));
                self.allowed_obstacles.get_mut(i).map(|m| *m |= mo).ok_or(SceneError::NoSuchPart)?;
            }
            _ => return Err(SceneError::NoSuchPart),
        }
        Ok(())
    }

    /// True if the pair is never checked.
    pub fn allowed(&self, body: u8, other: Part) -> bool {
        let i = usize::from(body);
        let mask = match other {
            Part::Body(j) => self.allowed_bodies.get(i).map(|m| m & bit(usize::from(j))),
            Part::Obstacle(o) => self.allowed_obstacles.get(i).map(|m| m & bit(usize::from(o))),
        };
        // Bodies of one frame never move apart: they are not checked either.
        let same_frame = match other {
            Part::Body(j) => match (self.bodies.get(i), self.bodies.get(usize::from(j))) {
                (Some(a), Some(b)) => a.frame == b.frame,
                _ => true,
            },
            Part::Obstacle(_) => false,
        };
        same_frame || mask.is_none_or(|m| m != 0)
    }

    /// Places every body at `frames` (each joint's moving frame in the base frame).
    fn place(&mut self, frames: &[Pose<T>]) {
        for (placed, body) in self.placed.iter_mut().zip(self.bodies.iter()) {
            *placed = match body.frame {
                None => body.capsule,
                Some(f) => match frames.get(usize::from(f)) {
                    Some(pose) => body.capsule.placed(pose),
                    // A frame the caller did not give: nowhere anything can be checked against,
                    // so every pair with it reads as touching (NaN compares as "not apart").
                    None => Capsule::sphere(nalgebra::Vector3::repeat(T::of(f64::NAN)), T::zero()),
                },
            };
        }
        for (sphere, placed) in self.spheres.iter_mut().zip(self.placed.iter()).take(self.bodies.len()) {
            *sphere = placed.bounding_sphere();
        }
        // Each group's sphere: about the middle of its bodies' spheres' bounding box, wide enough
        // for the farthest of them.
        for (g, sphere) in self.group_spheres.iter_mut().enumerate().take(usize::from(self.groups)) {
            let mask = self.members.get(g).copied().unwrap_or(0);
            let of_group = || bits(mask).filter_map(|i| self.spheres.get(usize::from(i)));
            // A group of one body: its own sphere.
            if mask.count_ones() == 1 {
                if let Some(only) = of_group().next() {
                    *sphere = *only;
                }
                continue;
            }
            let infinite = nalgebra::Vector3::repeat(T::of(f64::INFINITY));
            let (mut low, mut high) = (infinite, -infinite);
            for (c, r) in of_group() {
                low = low.inf(&(c - nalgebra::Vector3::repeat(*r)));
                high = high.sup(&(c + nalgebra::Vector3::repeat(*r)));
            }
            let centre = (low + high) * T::of(0.5);
            let radius = of_group().fold(T::zero(), |top, (c, r)| top.max((c - centre).norm_squared().root() + *r));
            // A NaN anywhere (a frame not given) makes the whole sphere NaN: never far.
            let nan = of_group().any(|(c, r)| !(c.iter().all(|x| x.finite()) && r.finite()));
            *sphere =
                if nan { (nalgebra::Vector3::repeat(T::of(f64::NAN)), T::of(f64::NAN)) } else { (centre, radius) };
        }
    }

    /// Which groups and obstacles come within `beyond` of each group, by their spheres.
    fn near_groups(&mut self, beyond: T) {
        let groups = usize::from(self.groups);
        for g in 0..groups {
            let own = self.members.get(g).copied().unwrap_or(0);
            if let Some(b) = self.near_bodies.get_mut(g) {
                *b = own;
            }
        }
        for g in 0..groups {
            let Some(&(centre, radius)) = self.group_spheres.get(g) else { continue };
            let own = self.members.get(g).copied().unwrap_or(0);
            // Each pair of groups once: the later group's bodies to this one's mask, and back.
            for h in (g + 1)..groups {
                let Some(&(c2, r2)) = self.group_spheres.get(h) else { continue };
                if !far((centre - c2).norm_squared(), radius + r2 + beyond) {
                    let theirs = self.members.get(h).copied().unwrap_or(0);
                    if let Some(b) = self.near_bodies.get_mut(g) {
                        *b |= theirs;
                    }
                    if let Some(b) = self.near_bodies.get_mut(h) {
                        *b |= own;
                    }
                }
            }
            let mut obstacles = 0;
            for (o, shape) in self.obstacles.iter().enumerate() {
                if !sphere_far_from(&centre, radius, shape, beyond) {
                    obstacles |= bit(o);
                }
            }
            if let Some(o) = self.near_obstacles.get_mut(g) {
                *o = obstacles;
            }
        }
    }

    /// The checked pairs whose groups came within the last [`Scene::near_groups`]' distance, in
    /// the order of [`Scene::pairs`]: bodies against later bodies, then against obstacles.
    fn near_pairs(&self) -> impl Iterator<Item = (u8, Part)> + '_ {
        let (n, m) = (self.bodies.len(), self.obstacles.len());
        (0..n).flat_map(move |i| {
            let g = usize::from(self.group.get(i).copied().unwrap_or(0));
            let at = |masks: &[u32; B], k: usize| masks.get(k).copied().unwrap_or(0);
            // Later bodies of other groups near this one, not allowed to touch it.
            let later = !bit(i + 1).wrapping_sub(1) & bit(n).wrapping_sub(1);
            let bodies = later & at(&self.near_bodies, g) & !at(&self.members, g) & !at(&self.allowed_bodies, i);
            let obstacles = bit(m).wrapping_sub(1) & at(&self.near_obstacles, g) & !at(&self.allowed_obstacles, i);
            bits(bodies)
                .map(move |j| (i as u8, Part::Body(j)))
                .chain(bits(obstacles).map(move |o| (i as u8, Part::Obstacle(o))))
        })
    }

    /// The signed distance between placed body `i` and `other`, or `None` when their bounding
    /// spheres are farther apart than `beyond`. The spheres are compared by squared distances, so
    /// a pair that is far apart costs no square root.
    fn measured(&self, i: usize, other: Part, beyond: T) -> Option<T> {
        let capsule = self.placed.get(i)?;
        let (centre, radius) = *self.spheres.get(i)?;
        match other {
            Part::Body(j) => {
                let q = self.placed.get(usize::from(j))?;
                let (c2, r2) = *self.spheres.get(usize::from(j))?;
                if far((centre - c2).norm_squared(), radius + r2 + beyond) {
                    return None;
                }
                Some(capsule_capsule(capsule, q))
            }
            Part::Obstacle(o) => {
                let shape = self.obstacles.get(usize::from(o))?;
                if sphere_far_from(&centre, radius, shape, beyond) {
                    return None;
                }
                Some(distance(capsule, shape))
            }
        }
    }

    /// Every pair that is checked, bodies against later bodies then against obstacles.
    #[cfg(test)]
    fn pairs(&self) -> impl Iterator<Item = (u8, Part)> + '_ {
        let (n, m) = (self.bodies.len() as u8, self.obstacles.len() as u8);
        (0..n)
            .flat_map(move |i| {
                ((i + 1)..n).map(move |j| (i, Part::Body(j))).chain((0..m).map(move |o| (i, Part::Obstacle(o))))
            })
            .filter(move |(i, other)| !self.allowed(*i, *other))
    }

    /// The first checked pair closer than the margin at `frames`, or `None` when every pair
    /// keeps it: the check a goal must pass.
    pub fn first_contact(&mut self, frames: &[Pose<T>]) -> Option<Contact<T>> {
        self.place(frames);
        let margin = self.margin;
        self.near_groups(margin);
        self.near_pairs().find_map(|(body, other)| {
            let distance = self.measured(usize::from(body), other, margin)?;
            // A NaN distance (a frame not given, a non-finite pose) is a contact, never free.
            let keeps_margin = distance >= margin;
            (!keeps_margin).then_some(Contact { body, other, distance })
        })
    }

    /// The closest checked pair at `frames` and its distance, for a report; `None` when no pair
    /// is checked.
    pub fn closest(&mut self, frames: &[Pose<T>]) -> Option<Contact<T>> {
        self.place(frames);
        self.closest_of(|_| true, T::of(f64::INFINITY))
    }

    /// The closest checked pair whose distance can change with the joints (every pair but a body
    /// of the base against an obstacle), at `frames`, if it is closer than `within`: what a check
    /// along a motion bounds, since a pair that never moves never comes closer. `None` when no
    /// such pair is closer than `within` (pairs farther apart are not measured exactly: their
    /// bounding spheres tell).
    pub fn closest_moving(&mut self, frames: &[Pose<T>], within: T) -> Option<Contact<T>> {
        self.place(frames);
        self.closest_of(|moves| moves, within)
    }

    /// The closest checked pair whose distance never changes (a body of the base against an
    /// obstacle), wherever the joints are; `None` when there is none.
    pub fn closest_fixed(&mut self) -> Option<Contact<T>> {
        // The base's bodies are placed the same for any frames; the others are not looked at.
        self.place(&[]);
        self.closest_of(|moves| !moves, T::of(f64::INFINITY))
    }

    /// True if the pair's distance can change with the joints.
    fn moves(&self, body: u8, other: Part) -> bool {
        match other {
            Part::Obstacle(_) => self.bodies.get(usize::from(body)).is_some_and(|b| b.frame.is_some()),
            // Bodies of one frame are never checked; a pair of frames moves.
            Part::Body(_) => true,
        }
    }

    /// The closest of the checked pairs `wanted` keeps (given whether the pair moves), as placed,
    /// if closer than `within` (a NaN distance always is).
    fn closest_of(&mut self, wanted: impl Fn(bool) -> bool, within: T) -> Option<Contact<T>> {
        self.near_groups(within);
        let mut best: Option<Contact<T>> = None;
        for (body, other) in self.near_pairs().filter(|(body, other)| wanted(self.moves(*body, *other))) {
            let beyond = best.map_or(within, |b| b.distance);
            if let Some(distance) = self.measured(usize::from(body), other, beyond) {
                let closer = match best {
                    None => distance < within || distance.partial_cmp(&within).is_none(),
                    Some(b) => distance < b.distance,
                };
                if closer {
                    best = Some(Contact { body, other, distance });
                }
            }
        }
        best
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;

    #[test]
    fn a_body_below_the_table_is_a_contact_and_one_above_is_not() {
        let mut scene: Scene<f64, 4, 2> = Scene::new(0.01);
        let capsule = Capsule { a: Vector3::zeros(), b: Vector3::new(0.1, 0.0, 0.0), radius: 0.02 };
        scene.add_body(Body { frame: Some(0), capsule }, 1).unwrap();
        scene.add_obstacle(Shape::table(0.0)).unwrap();
        let up = Pose::from_translation(Vector3::new(0.0, 0.0, 0.05));
        assert_eq!(scene.first_contact(&[up]), None);
        let low = Pose::from_translation(Vector3::new(0.0, 0.0, 0.025));
        let contact = scene.first_contact(&[low]).unwrap();
        assert_eq!(contact.other, Part::Obstacle(0));
        assert!((contact.distance - 0.005).abs() < 1e-12);
        scene.allow(0, Part::Obstacle(0)).unwrap();
        assert_eq!(scene.first_contact(&[low]), None);
        // A frame not given reads as a contact, never as free.
        let mut scene: Scene<f64, 4, 2> = Scene::new(0.01);
        scene.add_body(Body { frame: Some(0), capsule }, 1).unwrap();
        scene.add_obstacle(Shape::table(0.0)).unwrap();
        assert!(scene.first_contact(&[]).is_some());
    }

    /// A body whose centre is deep in a box, checked after a shallower overlap was found, is
    /// still the closest pair (its sphere's centre is inside the box: no gap, but a depth).
    #[test]
    fn a_deeper_overlap_in_a_box_found_after_a_shallow_one_is_the_closest() {
        let mut scene: Scene<f64, 4, 2> = Scene::new(0.01);
        let shallow = Capsule::sphere(Vector3::new(0.0, 0.0, 0.095), 0.05);
        let deep = Capsule::sphere(Vector3::zeros(), 0.01);
        scene.add_body(Body { frame: Some(0), capsule: shallow }, 2).unwrap();
        scene.add_body(Body { frame: Some(1), capsule: deep }, 2).unwrap();
        scene.allow(0, Part::Body(1)).unwrap();
        scene.add_obstacle(Shape::aligned_box(Vector3::zeros(), Vector3::repeat(0.2))).unwrap();
        let closest = scene.closest(&[Pose::identity(), Pose::identity()]).unwrap();
        assert_eq!(closest.body, 1);
        assert!((closest.distance + 0.11).abs() < 1e-12, "{}", closest.distance);
    }

    /// The bounding-sphere filters (of groups, then of bodies) never change an answer: the first
    /// contact and the closest pair are those of every pair measured exactly, over random
    /// placements of capsules, boxes, a capsule obstacle and a table.
    #[test]
    fn the_filter_changes_no_answer() {
        let mut rng = crate::SplitMix64::new(7);
        for round in 0..600 {
            let mut scene: Scene<f64, 8, 4> = Scene::new(rng.uniform(0.0, 0.05));
            // Every other round short capsules spread wide, so that whole groups are far apart; in
            // every fourth, spheres, each on a frame of its own (below), so that a group's
            // bounding sphere is its body, and a filter that cuts it close shows.
            let (spread, length) = match round % 4 {
                0 | 2 => (1.0, 1.0),
                1 => (3.0, 0.0),
                _ => (3.0, 0.1),
            };
            let point = move |rng: &mut crate::SplitMix64| {
                Vector3::new(rng.uniform(-0.3, 0.3), rng.uniform(-0.3, 0.3), rng.uniform(-0.1, 0.4)) * spread
            };
            for k in 0..6u8 {
                let a = point(&mut rng);
                let capsule = Capsule { a, b: a + (point(&mut rng) - a) * length, radius: rng.uniform(0.0, 0.05) };
                // Body 3 is the base's: it never moves. Every fourth round each body has a frame
                // of its own, so each group's sphere is its body's.
                let frame = match (k, round % 4) {
                    (3, _) => None,
                    (_, 1) => Some(k),
                    _ => Some(k % 3),
                };
                scene.add_body(Body { frame, capsule }, 6).unwrap();
            }
            let rotation = crate::axis_angle_matrix(&Vector3::new(0.3, -0.5, 0.8).normalize(), rng.uniform(-3.0, 3.0));
            let half = Vector3::new(rng.uniform(0.01, 0.1), rng.uniform(0.01, 0.1), rng.uniform(0.01, 0.1));
            scene.add_obstacle(Shape::Box { centre: point(&mut rng), rotation, half }).unwrap();
            let capsule = Capsule { a: point(&mut rng), b: point(&mut rng), radius: 0.02 };
            scene.add_obstacle(Shape::Capsule(capsule)).unwrap();
            scene.add_obstacle(Shape::table(rng.uniform(-0.1, 0.1))).unwrap();
            let frames: std::vec::Vec<Pose<f64>> = (0..6)
                .map(|_| Pose::from_xyz_rpy([rng.uniform(-0.1, 0.1), 0.0, 0.1], [rng.uniform(-1.0, 1.0), 0.0, 0.3]))
                .collect();
            // Every pair measured exactly, in the order `pairs` visits them.
            scene.place(&frames);
            let exact: std::vec::Vec<Contact<f64>> = scene
                .pairs()
                .map(|(body, other)| {
                    let c = scene.placed[usize::from(body)];
                    let distance = match other {
                        Part::Body(j) => capsule_capsule(&c, &scene.placed[usize::from(j)]),
                        Part::Obstacle(o) => distance(&c, &scene.obstacles[usize::from(o)]),
                    };
                    Contact { body, other, distance }
                })
                .collect();
            let margin = scene.margin();
            let first = exact.iter().find(|c| c.distance.partial_cmp(&margin).is_none_or(|o| o.is_lt())).copied();
            assert_eq!(scene.first_contact(&frames), first);
            let closest = exact.iter().copied().reduce(|a, b| if b.distance < a.distance { b } else { a });
            assert_eq!(scene.closest(&frames).map(|c| c.distance), closest.map(|c| c.distance));
            // The moving and the fixed pairs part the same pairs: the closer of the two closest is
            // the closest.
            let (moving, fixed) = (scene.closest_moving(&frames, f64::INFINITY), scene.closest_fixed());
            let either = [moving, fixed].into_iter().flatten().map(|c| c.distance).reduce(f64::min);
            assert_eq!(either, closest.map(|c| c.distance));
            // Within a bound: the same pair when it is closer than the bound, else none.
            let within = rng.uniform(0.0, 0.2);
            let expected = moving.filter(|c| c.distance < within);
            assert_eq!(scene.closest_moving(&frames, within).map(|c| c.distance), expected.map(|c| c.distance));
            // A margin right at one pair's distance, and a hair beyond it: the filters are exact
            // at their edge too.
            if let Some(edge) = exact.get(round % exact.len().max(1)).filter(|c| c.distance > 0.0) {
                for margin in [edge.distance, edge.distance * (1.0 + 1e-12)] {
                    scene.set_margin(margin);
                    let first = exact.iter().find(|c| c.distance < margin).copied();
                    assert_eq!(scene.first_contact(&frames), first);
                }
            }
        }
    }
}
