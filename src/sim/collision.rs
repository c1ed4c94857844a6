//! Self-collision checking from the links' URDF `<collision>` shapes (the only parry user).
//!
//! Every link's primitives (box, cylinder, capsule, sphere) become parry shapes once, at
//! construction; a check then places them with the link poses of one configuration and tests
//! every pair of links that are not *adjacent*. Links welded together by fixed joints form one
//! rigid body: all links of a body are mutually adjacent, and adjacent to every link of the
//! bodies joined to it by a single movable joint, or by several whose bodies in between have no
//! collision shapes (a two-joint shoulder). Adjacent links may touch (that is how joints
//! are drawn), so they are never checked.
//!
//! Mesh shapes (STL, OBJ, COLLADA) are loaded when a loader is given
//! ([`CollisionChecker::with_meshes`]) and the file resolves; each becomes its *convex hull*,
//! computed once per file and scale however many links use it, which is fast and conservative
//! (a concave link counts as its hull). Meshes that cannot be found or read are skipped and
//! listed.
//!
//! parry 0.31 works in glam types; poses are converted from [`crate::math::Pose`] here and
//! nowhere else, so nothing of parry leaks out of this module.

use super::mesh::MeshLookup;
use crate::error::{Error, Result};
use crate::math::Pose;
use crate::tree::{JointKind, KinematicTree, LinkId, Shape};
use parry3d_f64::math::{Pose as ShapePose, Rotation as ShapeRotation, Vector as ShapeVector};
use parry3d_f64::query::{self, ClosestPoints};
use parry3d_f64::shape::SharedShape;

/// Which `<collision>` shapes the self-collision check of `plan` and `simulate` uses
/// (`--collision-check`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum CollisionCheck {
    /// Primitives and meshes; a mesh that cannot be found or read is an error, as poses would
    /// otherwise go unchecked against its link.
    #[default]
    Meshes,
    /// Primitives (box, cylinder, capsule, sphere) only; mesh shapes are left out.
    PrimitivesOnly,
    /// No self-collision check at all.
    Off,
}

impl CollisionCheck {
    /// The flag value: `meshes`, `primitives-only` or `off`.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Meshes => "meshes",
            Self::PrimitivesOnly => "primitives-only",
            Self::Off => "off",
        }
    }
}

/// Settings of the [`CollisionChecker`].
#[derive(Debug, Clone, Default)]
pub struct CollisionOptions {
    /// Links closer than this (m) count as colliding; 0 counts only touching or overlapping.
    pub margin: f64,
}

/// One collision shape, placed in its link's frame.
#[derive(Clone)]
struct LinkShape {
    shape: SharedShape,
    /// Pose of parry's shape frame in the link frame (URDF `<origin>`, plus the axis change
    /// for cylinders).
    link_from_shape: ShapePose,
    /// A capsule around the shape, in the link frame: its segment's ends and radius. Tight for
    /// cylinders, capsules and spheres, so most pairs are decided without parry.
    bound: [ShapeVector; 2],
    bound_radius: f64,
}

/// The shapes of one link that has any, with a bounding sphere around all of them.
#[derive(Clone)]
struct CollisionLink {
    link: LinkId,
    shapes: Vec<LinkShape>,
    /// Centre of the link's bounding sphere in the link frame.
    center: ShapeVector,
    radius: f64,
}

/// Decides whether a configuration of a tree is in self-collision.
///
/// Built once per tree; checking a configuration takes the link poses of
/// [`KinematicTree::link_poses`] and allocates only a small buffer.
#[derive(Clone)]
pub struct CollisionChecker {
    link_count: usize,
    links: Vec<CollisionLink>,
    /// Pairs of indices into `links`, first < second, never adjacent; fewest movable joints
    /// apart first.
    pairs: Vec<(usize, usize)>,
    margin: f64,
    skipped_meshes: Vec<String>,
    unreadable_meshes: Vec<(String, String)>,
    loaded_meshes: usize,
}

/// Returns the vertices of a URDF mesh `filename` (as written in the URDF), or why there are
/// none; see [`crate::io::mesh_file_loader`].
pub type MeshLoader<'a> = &'a (dyn Fn(&str) -> MeshLookup + 'a);

/// A mesh's convex hull and its placement, or why it was left out (`None`: not found).
type MeshHull = std::result::Result<(SharedShape, ShapePose), Option<String>>;

impl std::fmt::Debug for CollisionChecker {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("CollisionChecker")
            .field("links_with_shapes", &self.links.len())
            .field("pairs", &self.pairs.len())
            .field("margin", &self.margin)
            .field("skipped_meshes", &self.skipped_meshes.len())
            .field("loaded_meshes", &self.loaded_meshes)
            .finish()
    }
}

impl CollisionChecker {
    /// A checker for `tree` with no margin: only touching or overlapping shapes collide.
    pub fn new(tree: &KinematicTree) -> Result<Self> {
        Self::with_options(tree, &CollisionOptions::default())
    }

    /// A checker for `tree` with the given options; mesh shapes are skipped.
    pub fn with_options(tree: &KinematicTree, options: &CollisionOptions) -> Result<Self> {
        Self::with_meshes(tree, options, &|_| MeshLookup::NotFound)
    }

    /// A checker for `tree` whose mesh shapes are read through `load` (as their convex hulls,
    /// scaled by the URDF `scale`, each file and scale once); meshes it cannot find or read are
    /// skipped ([`Self::skipped_mesh_files`], [`Self::unreadable_meshes`]).
    pub fn with_meshes(
        tree: &KinematicTree,
        options: &CollisionOptions,
        load: MeshLoader<'_>,
    ) -> Result<Self> {
        if !(options.margin.is_finite() && options.margin >= 0.0) {
            return Err(Error::InvalidData {
                origin: "collision options".into(),
                message: format!(
                    "the collision margin must be a finite distance of 0 m or more, not {}",
                    options.margin
                ),
            });
        }
        let mut links = Vec::new();
        let mut skipped_meshes = Vec::new();
        let mut unreadable_meshes = Vec::new();
        let mut loaded_meshes = 0;
        let mut hulls: std::collections::HashMap<(String, [u64; 3]), MeshHull> =
            std::collections::HashMap::new();
        for (index, link) in tree.links().iter().enumerate() {
            let mut shapes = Vec::new();
            for (link_from_urdf_shape, shape) in &link.geometry.collisions {
                let invalid = |what: &str, value: f64| Error::InvalidRobot {
                    origin: tree.name().to_owned(),
                    message: format!(
                        "link '{}' has a <collision> {what} of {value}; it must be a finite \
                         length of 0 m or more",
                        link.name
                    ),
                };
                let found = match shape {
                    Shape::Mesh { filename, scale } => {
                        let key = (filename.clone(), scale.map(f64::to_bits).into());
                        let hull = match hulls.get(&key) {
                            Some(hull) => hull.clone(),
                            None => {
                                let hull = mesh_hull(filename, scale, load, &link.name)?;
                                hulls.insert(key, hull.clone());
                                hull
                            }
                        };
                        match hull {
                            Ok(hull) => {
                                loaded_meshes += 1;
                                Some(hull)
                            }
                            // The link is checked with its other shapes only (or not at all).
                            Err(reason) => {
                                skipped_meshes.push(filename.clone());
                                if let Some(reason) = reason {
                                    unreadable_meshes.push((filename.clone(), reason));
                                }
                                None
                            }
                        }
                    }
                    _ => parry_shape(shape, &invalid)?,
                };
                let Some((parry_shape, shape_from_parry)) = found else {
                    continue;
                };
                let link_from_shape = ShapePose::from(*link_from_urdf_shape) * shape_from_parry;
                let (ends, bound_radius) = bounding_capsule(&parry_shape);
                shapes.push(LinkShape {
                    bound: ends.map(|end| link_from_shape.transform_point(end)),
                    bound_radius,
                    shape: parry_shape,
                    link_from_shape,
                });
            }
            if !shapes.is_empty() {
                let (center, radius) = enclosing_sphere(&shapes);
                links.push(CollisionLink {
                    link: LinkId(index),
                    shapes,
                    center,
                    radius,
                });
            }
        }
        let mut has_shapes = vec![false; tree.links().len()];
        for link in &links {
            has_shapes[link.link.0] = true;
        }
        let body = rigid_bodies(tree, &has_shapes);
        let mut pairs = Vec::new();
        for a in 0..links.len() {
            for b in a + 1..links.len() {
                if !adjacent(&body, links[a].link, links[b].link) {
                    pairs.push((a, b));
                }
            }
        }
        // Links few joints apart collide most often (an elbow folding back): checking them
        // first makes a colliding configuration's check stop sooner.
        pairs.sort_by_key(|&(a, b)| movable_joints_between(tree, links[a].link, links[b].link));
        Ok(Self {
            link_count: tree.links().len(),
            links,
            pairs,
            margin: options.margin,
            skipped_meshes,
            unreadable_meshes,
            loaded_meshes,
        })
    }

    /// A checker that checks nothing: every configuration is collision-free
    /// ([`CollisionCheck::Off`]).
    pub fn disabled(tree: &KinematicTree) -> Self {
        Self {
            link_count: tree.links().len(),
            links: Vec::new(),
            pairs: Vec::new(),
            margin: 0.0,
            skipped_meshes: Vec::new(),
            unreadable_meshes: Vec::new(),
            loaded_meshes: 0,
        }
    }

    /// Number of `<collision>` shapes checked (primitives and loaded meshes).
    pub fn shape_count(&self) -> usize {
        self.links.iter().map(|l| l.shapes.len()).sum()
    }

    /// Number of link pairs checked (pairs of non-adjacent links that both have shapes).
    pub fn pair_count(&self) -> usize {
        self.pairs.len()
    }

    /// The link pairs checked (lower link id first in each), fewest joints apart first.
    pub fn pairs(&self) -> impl Iterator<Item = (LinkId, LinkId)> + '_ {
        self.pairs
            .iter()
            .map(|&(a, b)| (self.links[a].link, self.links[b].link))
    }

    /// Number of `<collision>` meshes left out (not found, or unreadable).
    pub fn skipped_meshes(&self) -> usize {
        self.skipped_meshes.len()
    }

    /// The file names (as in the URDF) of the `<collision>` meshes left out.
    pub fn skipped_mesh_files(&self) -> &[String] {
        &self.skipped_meshes
    }

    /// The `<collision>` meshes found but left out, with the reason (not a mesh format that
    /// can be read, a parse error, no vertices, a flat mesh).
    pub fn unreadable_meshes(&self) -> &[(String, String)] {
        &self.unreadable_meshes
    }

    /// Number of `<collision>` meshes loaded (as convex hulls).
    pub fn loaded_meshes(&self) -> usize {
        self.loaded_meshes
    }

    /// The margin (m) below which links count as colliding.
    pub fn margin(&self) -> f64 {
        self.margin
    }

    /// Number of links of the tree the checker was built for.
    pub fn link_count(&self) -> usize {
        self.link_count
    }

    /// Whether any checked pair collides, with the link poses of one configuration (root frame,
    /// one per link, as [`KinematicTree::link_poses`] returns them). Stops at the first hit.
    /// Poses with NaN in them count as colliding.
    ///
    /// # Panics
    ///
    /// If `link_poses` has fewer entries than the tree has links (a programming error: the
    /// poses of another tree).
    pub fn in_collision(&self, link_poses: &[Pose]) -> bool {
        let placed = self.place(link_poses);
        self.pairs
            .iter()
            .any(|&(a, b)| self.pair_collides(&placed[a], a, &placed[b], b))
    }

    /// Every checked pair that collides, with the link poses of one configuration, in
    /// [`Self::pairs`] order.
    ///
    /// # Panics
    ///
    /// As [`Self::in_collision`].
    pub fn colliding_pairs(&self, link_poses: &[Pose]) -> Vec<(LinkId, LinkId)> {
        let placed = self.place(link_poses);
        self.pairs
            .iter()
            .filter(|&&(a, b)| self.pair_collides(&placed[a], a, &placed[b], b))
            .map(|&(a, b)| (self.links[a].link, self.links[b].link))
            .collect()
    }

    /// [`Self::ignore_pairs_mostly_colliding`] at every one of `configurations`: links whose
    /// meshes overlap by design (a compact wrist), MoveIt's "always in collision".
    pub fn ignore_pairs_always_colliding(
        &mut self,
        configurations: &[Vec<Pose>],
    ) -> Vec<(LinkId, LinkId)> {
        self.ignore_pairs_mostly_colliding(configurations, 1.0)
    }

    /// Stops checking the pairs that collide in at least `fraction` of `configurations` (link
    /// poses of random configurations, [`crate::sim::sample_configurations`]; MoveIt's setup
    /// assistant uses 95 %) and returns them; none when `configurations` is empty. Panics as
    /// [`Self::in_collision`].
    pub fn ignore_pairs_mostly_colliding(
        &mut self,
        configurations: &[Vec<Pose>],
        fraction: f64,
    ) -> Vec<(LinkId, LinkId)> {
        if configurations.is_empty() {
            return Vec::new();
        }
        let mut hits = vec![0usize; self.pairs.len()];
        for link_poses in configurations {
            let placed = self.place(link_poses);
            for (k, &(a, b)) in self.pairs.iter().enumerate() {
                if self.pair_collides(&placed[a], a, &placed[b], b) {
                    hits[k] += 1;
                }
            }
        }
        let threshold = fraction * configurations.len() as f64;
        let mut removed = Vec::new();
        let mut kept = Vec::with_capacity(self.pairs.len());
        for (&(a, b), &n) in self.pairs.iter().zip(&hits) {
            if n as f64 >= threshold {
                removed.push((self.links[a].link, self.links[b].link));
            } else {
                kept.push((a, b));
            }
        }
        self.pairs = kept;
        removed
    }

    /// Each shape-carrying link's pose (parry form) and bounding-sphere centre, root frame.
    fn place(&self, link_poses: &[Pose]) -> Vec<(ShapePose, ShapeVector)> {
        assert!(
            link_poses.len() >= self.link_count,
            "collision check needs {} link poses, got {}",
            self.link_count,
            link_poses.len()
        );
        self.links
            .iter()
            .map(|l| {
                let root_from_link = ShapePose::from(link_poses[l.link.0]);
                (root_from_link, root_from_link.transform_point(l.center))
            })
            .collect()
    }

    fn pair_collides(
        &self,
        (root_from_a, center_a): &(ShapePose, ShapeVector),
        a: usize,
        (root_from_b, center_b): &(ShapePose, ShapeVector),
        b: usize,
    ) -> bool {
        let (link_a, link_b) = (&self.links[a], &self.links[b]);
        let reach = link_a.radius + link_b.radius + self.margin;
        let squared = center_a.distance_squared(*center_b);
        if squared > reach * reach {
            return false;
        }
        if squared.is_nan() {
            // A pose with NaN in it: say "colliding" rather than hand parry garbage.
            return true;
        }
        for shape_a in &link_a.shapes {
            let [a0, a1] = shape_a.bound.map(|end| root_from_a.transform_point(end));
            for shape_b in &link_b.shapes {
                let [b0, b1] = shape_b.bound.map(|end| root_from_b.transform_point(end));
                // The slack keeps rounding from ever skipping a pair that touches.
                let reach = shape_a.bound_radius + shape_b.bound_radius + self.margin + 1e-9;
                if segment_distance_squared(a0, a1, b0, b1) > reach * reach {
                    continue;
                }
                let root_from_shape_a = root_from_a * shape_a.link_from_shape;
                let root_from_shape_b = root_from_b * shape_b.link_from_shape;
                if self.shapes_collide(&root_from_shape_a, shape_a, &root_from_shape_b, shape_b) {
                    return true;
                }
            }
        }
        false
    }

    fn shapes_collide(
        &self,
        root_from_a: &ShapePose,
        a: &LinkShape,
        root_from_b: &ShapePose,
        b: &LinkShape,
    ) -> bool {
        // An unsupported pair cannot happen with the convex primitives built here; should a
        // future shape be unsupported, counting it as a collision is the safe side for a
        // sampler or planner.
        if self.margin > 0.0 {
            query::closest_points(root_from_a, &*a.shape, root_from_b, &*b.shape, self.margin)
                .map_or(true, |points| !matches!(points, ClosestPoints::Disjoint))
        } else {
            query::intersection_test(root_from_a, &*a.shape, root_from_b, &*b.shape)
                .map_or(true, |result| result.intersecting)
        }
    }
}

/// A capsule containing a shape (segment ends and radius, shape frame): the shape's own axis
/// for cylinders and capsules, the longest axis for boxes, a point for balls and anything else
/// (its bounding sphere).
fn bounding_capsule(shape: &SharedShape) -> ([ShapeVector; 2], f64) {
    if let Some(cylinder) = shape.as_cylinder() {
        let end = ShapeVector::Y * cylinder.half_height;
        ([-end, end], cylinder.radius)
    } else if let Some(capsule) = shape.as_capsule() {
        ([capsule.segment.a, capsule.segment.b], capsule.radius)
    } else if let Some(cuboid) = shape.as_cuboid() {
        let half = cuboid.half_extents;
        let axis = half.max_position();
        let mut end = ShapeVector::ZERO;
        end[axis] = half[axis];
        let mut across = half;
        across[axis] = 0.0;
        ([-end, end], across.length())
    } else {
        let sphere = shape.compute_local_bounding_sphere();
        ([sphere.center(); 2], sphere.radius())
    }
}

/// Squared distance between segments `a0–a1` and `b0–b1` (Ericson, *Real-Time Collision
/// Detection*, section 5.1.9).
fn segment_distance_squared(
    a0: ShapeVector,
    a1: ShapeVector,
    b0: ShapeVector,
    b1: ShapeVector,
) -> f64 {
    let (da, db, r) = (a1 - a0, b1 - b0, a0 - b0);
    let (length_a, length_b) = (da.length_squared(), db.length_squared());
    let f = db.dot(r);
    // Below this squared length (m²) a segment is a point.
    let point = 1e-24;
    let (s, t) = if length_a <= point && length_b <= point {
        (0.0, 0.0)
    } else if length_a <= point {
        (0.0, (f / length_b).clamp(0.0, 1.0))
    } else {
        let c = da.dot(r);
        if length_b <= point {
            ((-c / length_a).clamp(0.0, 1.0), 0.0)
        } else {
            let b = da.dot(db);
            let denominator = length_a * length_b - b * b;
            // Parallel segments: any s works, t follows from it.
            let s = if denominator > 0.0 {
                ((b * f - c * length_b) / denominator).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let t = (b * s + f) / length_b;
            if t < 0.0 {
                ((-c / length_a).clamp(0.0, 1.0), 0.0)
            } else if t > 1.0 {
                (((b - c) / length_a).clamp(0.0, 1.0), 1.0)
            } else {
                (s, t)
            }
        }
    };
    (a0 + da * s).distance_squared(b0 + db * t)
}

/// The parry shape for a URDF shape and the pose of parry's frame in the URDF shape frame;
/// `None` for meshes.
fn parry_shape(
    shape: &Shape,
    invalid: &dyn Fn(&str, f64) -> Error,
) -> Result<Option<(SharedShape, ShapePose)>> {
    let length = |what: &str, value: f64| -> Result<f64> {
        if value.is_finite() && value >= 0.0 {
            // abs() turns -0 into +0, which parry's constructors insist on.
            Ok(value.abs())
        } else {
            Err(invalid(what, value))
        }
    };
    Ok(Some(match shape {
        Shape::Box { size } => {
            let half = ShapeVector::new(
                length("box size x", size.x)? / 2.0,
                length("box size y", size.y)? / 2.0,
                length("box size z", size.z)? / 2.0,
            );
            (
                SharedShape::cuboid(half.x, half.y, half.z),
                ShapePose::IDENTITY,
            )
        }
        Shape::Cylinder { radius, length: l } => {
            let radius = length("cylinder radius", *radius)?;
            let half_height = length("cylinder length", *l)? / 2.0;
            // URDF cylinders run along z, parry's along y: +90° about x takes y to z.
            (
                SharedShape::cylinder(half_height, radius),
                ShapePose::from_rotation(ShapeRotation::from_rotation_x(
                    std::f64::consts::FRAC_PI_2,
                )),
            )
        }
        Shape::Capsule { radius, length: l } => {
            let radius = length("capsule radius", *radius)?;
            let half_height = length("capsule length", *l)? / 2.0;
            (
                SharedShape::capsule_z(half_height, radius),
                ShapePose::IDENTITY,
            )
        }
        Shape::Sphere { radius } => (
            SharedShape::ball(length("sphere radius", *radius)?),
            ShapePose::IDENTITY,
        ),
        Shape::Mesh { .. } => return Ok(None),
    }))
}

/// The convex hull of a mesh file, scaled; `Err(None)` when the loader cannot find it,
/// `Err(Some(reason))` when it cannot be read or has no volume. A non-finite scale is an error.
fn mesh_hull(
    filename: &str,
    scale: &crate::math::Vec3,
    load: MeshLoader<'_>,
    link: &str,
) -> Result<MeshHull> {
    if !scale.iter().all(|s| s.is_finite()) {
        return Err(Error::InvalidData {
            origin: filename.into(),
            message: format!("link '{link}' gives this mesh a scale that is not finite"),
        });
    }
    let vertices = match load(filename) {
        MeshLookup::Vertices(vertices) => vertices,
        MeshLookup::NotFound => return Ok(Err(None)),
        MeshLookup::Unreadable(reason) => return Ok(Err(Some(reason))),
    };
    let points: Vec<ShapeVector> = vertices
        .iter()
        .map(|v| ShapeVector::new(v.x * scale.x, v.y * scale.y, v.z * scale.z))
        .collect();
    Ok(match SharedShape::convex_hull(&points) {
        Some(hull) => Ok((hull, ShapePose::IDENTITY)),
        None => Err(Some(
            "flat or degenerate (no convex hull); give the link a primitive <collision> shape"
                .into(),
        )),
    })
}

/// A sphere (centre in the link frame, radius) around all shapes of a link.
fn enclosing_sphere(shapes: &[LinkShape]) -> (ShapeVector, f64) {
    // Each shape's own sphere: parry's or the one around its capsule, whichever is smaller.
    let spheres: Vec<(ShapeVector, f64)> = shapes
        .iter()
        .map(|s| {
            let parry = s.shape.compute_bounding_sphere(&s.link_from_shape);
            let middle = (s.bound[0] + s.bound[1]) / 2.0;
            let capsule = s.bound[0].distance(s.bound[1]) / 2.0 + s.bound_radius;
            if parry.radius() <= capsule {
                (parry.center(), parry.radius())
            } else {
                (middle, capsule)
            }
        })
        .collect();
    let center = spheres.iter().map(|s| s.0).sum::<ShapeVector>() / spheres.len() as f64;
    let radius = spheres
        .iter()
        .map(|&(c, r)| c.distance(center) + r)
        .fold(0.0, f64::max);
    (center, radius)
}

/// The rigid body of every link, with the body it hangs from.
struct Bodies {
    /// For each link, the topmost link of its rigid body (links joined by fixed joints).
    body_of: Vec<LinkId>,
    /// For each link that tops a body, the body its movable parent joint hangs from.
    parent_body: Vec<Option<LinkId>>,
}

/// `has_shapes`: whether each link has collision shapes. A body without any (the small link
/// between the two joints of a shoulder or wrist, as real descriptions have them) does not
/// separate the bodies on either side: they count as joined by one movable joint, since that
/// is how they are drawn meeting.
fn rigid_bodies(tree: &KinematicTree, has_shapes: &[bool]) -> Bodies {
    let count = tree.links().len();
    let mut body_of: Vec<LinkId> = (0..count).map(LinkId).collect();
    let mut parent_body = vec![None; count];
    // Joints are in topological order, so a parent's body is known before its children's.
    for joint in tree.joints() {
        let parent = body_of[joint.parent.0];
        if joint.kind == JointKind::Fixed {
            body_of[joint.child.0] = parent;
        } else {
            parent_body[joint.child.0] = Some(parent);
        }
    }
    let mut body_has_shapes = vec![false; count];
    for (link, &shapes) in has_shapes.iter().enumerate() {
        body_has_shapes[body_of[link].0] |= shapes;
    }
    // Parents come before children, so a parent's own parent is already skipped to a body with
    // shapes when its children are visited.
    for joint in tree.joints() {
        let child = joint.child.0;
        if let Some(parent) = parent_body[child] {
            if !body_has_shapes[parent.0] {
                parent_body[child] = parent_body[parent.0].or(Some(parent));
            }
        }
    }
    Bodies {
        body_of,
        parent_body,
    }
}

/// Number of movable joints on the tree path between two links.
fn movable_joints_between(tree: &KinematicTree, a: LinkId, b: LinkId) -> usize {
    let path_a = tree.path_from_root(a);
    let path_b = tree.path_from_root(b);
    let common = path_a
        .iter()
        .zip(&path_b)
        .take_while(|(x, y)| x == y)
        .count();
    path_a[common..]
        .iter()
        .chain(&path_b[common..])
        .filter(|j| tree.joint(**j).kind.is_movable())
        .count()
}

/// Whether two links are in the same rigid body or in bodies joined by one movable joint.
fn adjacent(bodies: &Bodies, a: LinkId, b: LinkId) -> bool {
    let (body_a, body_b) = (bodies.body_of[a.0], bodies.body_of[b.0]);
    body_a == body_b
        || bodies.parent_body[body_a.0] == Some(body_b)
        || bodies.parent_body[body_b.0] == Some(body_a)
}

mod ray;

#[cfg(test)]
mod tests;
