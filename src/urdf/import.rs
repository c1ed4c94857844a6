//! URDF → kinematic tree.
//!
//! urdf-rs parses the XML; everything it does not check is checked here, with messages that
//! name the element and, where it can be found, the line.

use super::bounds::element_line;
use crate::error::{Error, Result};
use crate::limits::{magnitude_problem, Quantity};
use crate::math::{pose, rotation_from_rpy, Mat3, Pose, Vec3};
use crate::tree::{
    Actuation, Inertial, Joint, JointId, JointKind, KinematicTree, Limits, Link, LinkGeometry,
    LinkId, Shape,
};
use nalgebra::Unit;
use std::collections::{HashMap, VecDeque};
use std::path::Path;

/// A loaded robot and what the loader thinks the user should know.
#[derive(Debug, Clone)]
pub struct UrdfImport {
    /// The kinematic tree.
    pub tree: KinematicTree,
    /// Things that were accepted but deserve a word (e.g. a floating root joint treated as fixed).
    pub warnings: Vec<String>,
}

/// Reads and converts a URDF file.
pub fn load_urdf(path: &Path) -> Result<UrdfImport> {
    let text = crate::limits::read_text(path, crate::limits::MAX_URDF_BYTES)?;
    parse_urdf(&text, &path.display().to_string())
}

/// Converts URDF text; `origin` names the source in messages (a file path or `<string>`).
///
/// The text's structure is checked first (one `<robot>` root, matching end tags, nothing
/// after the root; the same check `export` applies), then only its kinematic elements are
/// read: materials, textures, gazebo, transmissions, sensors and unknown elements never
/// stop a robot loading (see `docs/robots.md`).
pub fn parse_urdf(text: &str, origin: &str) -> Result<UrdfImport> {
    crate::limits::check_text_size(text, crate::limits::MAX_URDF_BYTES, origin)?;
    let elements = super::xml::scan(text, origin)?;
    check_expanded(text, origin, &elements)?;
    let mut warnings = Vec::new();
    let robot = super::tolerant::read_robot(text, origin, &elements, &mut warnings)?;
    super::bounds::check_sizes(&robot, text, origin)?;
    let mut import = Importer { text, origin }.convert(&robot)?;
    // After the importer's own checks (NaN, negative masses), which keep their messages.
    super::bounds::check_numbers(&robot, text, origin)?;
    warnings.append(&mut import.warnings);
    import.warnings = warnings;
    Ok(import)
}

/// Fails on what only xacro expands: an `<xacro:include>`, a macro call or a condition (which
/// would silently leave links out) or a `${…}` / `$(…)` expression in an attribute (which would
/// read as a wrong vector or a missing mesh). Leftovers that change nothing (the namespace,
/// `xacro:property`, `xacro:arg`, macro definitions and what they hold) stay ignored.
fn check_expanded(text: &str, origin: &str, elements: &[super::xml::Element]) -> Result<()> {
    const EXPAND: &str = "this is a xacro file, not a URDF: expand it first (`xacro robot.urdf.xacro > robot.urdf`; ROS 2: `ros2 run xacro xacro …`) and give the expanded file";
    const INERT: [&str; 3] = ["xacro:property", "xacro:arg", "xacro:macro"];
    let inert = |mut index: usize| loop {
        if INERT.contains(&elements[index].name.as_str()) {
            return true;
        }
        match elements[index].parent {
            Some(parent) => index = parent,
            None => return false,
        }
    };
    let at = |offset: usize| super::xml::position(text, origin, offset);
    for (index, element) in elements.iter().enumerate() {
        if inert(index) {
            continue;
        }
        if element.name.starts_with("xacro:") {
            return Err(Error::InvalidData {
                origin: at(element.start),
                message: format!("<{}>: {EXPAND}", element.name),
            });
        }
        let expression = element.attributes.iter().find(|a| {
            let value = &text[a.value.clone()];
            value.contains("${") || value.contains("$(")
        });
        if let Some(attribute) = expression {
            return Err(Error::InvalidData {
                origin: at(attribute.value.start),
                message: format!(
                    "<{} {}=\"{}\">: a xacro expression; {EXPAND}",
                    element.name,
                    attribute.name,
                    crate::limits::cut(&text[attribute.value.clone()])
                ),
            });
        }
    }
    Ok(())
}

mod dofs;
mod joints;
mod structure;
use dofs::{dangling_mimics, independent_joints};

struct Importer<'a> {
    text: &'a str,
    origin: &'a str,
}

impl Importer<'_> {
    /// An error about `<tag name="name">`, with its line number when the text shows it.
    fn invalid(&self, tag: &str, name: &str, message: String) -> Error {
        let origin = match element_line(self.text, tag, name) {
            Some(line) => format!("{}:{line}", self.origin),
            None => self.origin.to_owned(),
        };
        Error::InvalidRobot { origin, message }
    }

    fn convert(&self, robot: &urdf_rs::Robot) -> Result<UrdfImport> {
        let mut warnings = Vec::new();
        if robot.links.is_empty() {
            return Err(Error::InvalidRobot {
                origin: self.origin.to_owned(),
                message: "the robot has no <link> elements".into(),
            });
        }

        let (link_index, joint_names) = self.unique_names(robot)?;
        let (parent_joint_of, children_of) = self.parent_joints(robot, &link_index)?;
        let root = self.root_link(robot, &parent_joint_of, &link_index)?;
        let order =
            self.breadth_first(robot, root, (&parent_joint_of, &children_of), &link_index)?;
        let mut new_index = vec![0usize; robot.links.len()];
        for (position, &link) in order.iter().enumerate() {
            new_index[link] = position;
        }

        // Joints in the order of their child link.
        let mut links: Vec<Link> = Vec::with_capacity(order.len());
        let mut joints: Vec<Joint> = Vec::with_capacity(order.len() - 1);
        let mut joint_position: HashMap<&str, JointId> = HashMap::new();
        for &old in &order {
            let source = &robot.links[old];
            links.push(Link {
                name: source.name.clone(),
                parent_joint: None,
                child_joints: Vec::new(),
                inertial: self.inertial(source)?,
                geometry: self.geometry(source)?,
            });
            if let Some(j) = parent_joint_of[old] {
                let joint = &robot.joints[j];
                let id = JointId(joints.len());
                let parent = LinkId(new_index[link_index[joint.parent.link.as_str()]]);
                let child = LinkId(new_index[old]);
                let is_root_joint = parent.0 == 0;
                joints.push(self.joint(joint, parent, child, is_root_joint, &mut warnings)?);
                joint_position.insert(joint.name.as_str(), id);
            }
        }
        for (index, joint) in joints.iter().enumerate() {
            links[joint.child.0].parent_joint = Some(JointId(index));
            links[joint.parent.0].child_joints.push(JointId(index));
        }

        let dangling = dangling_mimics(robot, &joint_names, &mut warnings);
        let dofs = independent_joints(robot, &mut joints, &dangling);
        self.resolve_mimics(robot, &mut joints, &joint_position)?;

        let tree = KinematicTree::from_parts(robot.name.clone(), links, joints, dofs)?;
        Ok(UrdfImport { tree, warnings })
    }

    fn inertial(&self, link: &urdf_rs::Link) -> Result<Option<Inertial>> {
        let source = &link.inertial;
        let i = &source.inertia;
        let values = [source.mass.value, i.ixx, i.ixy, i.ixz, i.iyy, i.iyz, i.izz];
        let origin = source.origin.xyz.0.iter().chain(source.origin.rpy.0.iter());
        if values.iter().chain(origin).any(|v| !v.is_finite()) {
            return Err(self.invalid(
                "link",
                &link.name,
                format!("link '{}' has a non-finite value in <inertial>", link.name),
            ));
        }
        if source.mass.value < 0.0 {
            return Err(self.invalid(
                "link",
                &link.name,
                format!(
                    "link '{}' has negative mass {}",
                    link.name, source.mass.value
                ),
            ));
        }
        if source.mass.value == 0.0 {
            return Ok(None);
        }
        Ok(Some(Inertial {
            mass: source.mass.value,
            link_from_inertia: urdf_pose(&source.origin),
            inertia: Mat3::new(
                i.ixx, i.ixy, i.ixz, i.ixy, i.iyy, i.iyz, i.ixz, i.iyz, i.izz,
            ),
        }))
    }

    fn geometry(&self, link: &urdf_rs::Link) -> Result<LinkGeometry> {
        let shape = |g: &urdf_rs::Geometry| -> Option<Shape> {
            Some(match g {
                urdf_rs::Geometry::Box { size } => Shape::Box {
                    size: Vec3::from(size.0),
                },
                urdf_rs::Geometry::Cylinder { radius, length } => Shape::Cylinder {
                    radius: *radius,
                    length: *length,
                },
                urdf_rs::Geometry::Capsule { radius, length } => Shape::Capsule {
                    radius: *radius,
                    length: *length,
                },
                urdf_rs::Geometry::Sphere { radius } => Shape::Sphere { radius: *radius },
                urdf_rs::Geometry::Mesh { filename, scale } => Shape::Mesh {
                    filename: filename.clone(),
                    scale: scale
                        .map(|s| Vec3::from(s.0))
                        .unwrap_or_else(|| Vec3::repeat(1.0)),
                },
            })
        };
        let mut geometry = LinkGeometry::default();
        for c in &link.collision {
            if let Some(s) = shape(&c.geometry) {
                geometry.collisions.push((urdf_pose(&c.origin), s));
            }
        }
        for v in &link.visual {
            if let Some(s) = shape(&v.geometry) {
                geometry.visuals.push((urdf_pose(&v.origin), s));
            }
        }
        let finite = geometry
            .collisions
            .iter()
            .chain(&geometry.visuals)
            .all(|(p, _)| {
                p.translation.vector.iter().all(|v| v.is_finite())
                    && p.rotation.coords.iter().all(|v| v.is_finite())
            });
        if !finite {
            return Err(self.invalid(
                "link",
                &link.name,
                format!("link '{}' has a non-finite geometry <origin>", link.name),
            ));
        }
        Ok(geometry)
    }
}

fn urdf_pose(p: &urdf_rs::Pose) -> Pose {
    pose(
        Vec3::from(p.xyz.0),
        rotation_from_rpy(p.rpy.0[0], p.rpy.0[1], p.rpy.0[2]),
    )
}
