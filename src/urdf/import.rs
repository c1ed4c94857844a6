//! URDF → kinematic tree.
//!
//! urdf-rs parses the XML; everything it does not check is checked here, with messages that
//! name the element and, where it can be found, the line.

use super::bounds::element_line;
use crate::error::{Error, Result};
use crate::limits::{magnitude_problem, Quantity};
use crate::math::{pose, rotation_from_rpy, Mat3, Pose, Vec3};
use crate::tree::{
    Actuation, DofId, Inertial, Joint, JointId, JointKind, KinematicTree, Limits, Link,
    LinkGeometry, LinkId, Shape,
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

        // Names must be unique: everything downstream refers to links and joints by name.
        let mut link_index: HashMap<&str, usize> = HashMap::new();
        for (index, link) in robot.links.iter().enumerate() {
            if link_index.insert(link.name.as_str(), index).is_some() {
                return Err(self.invalid(
                    "link",
                    &link.name,
                    format!(
                        "link name '{}' is used twice; link names must be unique",
                        link.name
                    ),
                ));
            }
        }
        let mut joint_names: HashMap<&str, usize> = HashMap::new();
        for (index, joint) in robot.joints.iter().enumerate() {
            if joint_names.insert(joint.name.as_str(), index).is_some() {
                return Err(self.invalid(
                    "joint",
                    &joint.name,
                    format!(
                        "joint name '{}' is used twice; joint names must be unique",
                        joint.name
                    ),
                ));
            }
        }

        // Parent/child structure: each link at most one parent joint, every named link exists.
        let mut parent_joint_of: Vec<Option<usize>> = vec![None; robot.links.len()];
        let mut children_of: Vec<Vec<usize>> = vec![Vec::new(); robot.links.len()];
        for (index, joint) in robot.joints.iter().enumerate() {
            let parent = *link_index.get(joint.parent.link.as_str()).ok_or_else(|| {
                self.invalid(
                    "joint",
                    &joint.name,
                    format!(
                        "joint '{}' names parent link '{}', which does not exist{}",
                        joint.name,
                        joint.parent.link,
                        crate::error::did_you_mean(&joint.parent.link, link_index.keys().copied())
                    ),
                )
            })?;
            let child = *link_index.get(joint.child.link.as_str()).ok_or_else(|| {
                self.invalid(
                    "joint",
                    &joint.name,
                    format!(
                        "joint '{}' names child link '{}', which does not exist{}",
                        joint.name,
                        joint.child.link,
                        crate::error::did_you_mean(&joint.child.link, link_index.keys().copied())
                    ),
                )
            })?;
            if let Some(other) = parent_joint_of[child] {
                return Err(self.invalid(
                    "joint",
                    &joint.name,
                    format!(
                        "link '{}' is the child of both joint '{}' and joint '{}'; a URDF must be a tree",
                        joint.child.link, robot.joints[other].name, joint.name
                    ),
                ));
            }
            parent_joint_of[child] = Some(index);
            children_of[parent].push(index);
        }

        let roots: Vec<usize> = (0..robot.links.len())
            .filter(|&l| parent_joint_of[l].is_none())
            .collect();
        let root = match roots.as_slice() {
            [root] => *root,
            [] => {
                return Err(self.cycle_error(
                    robot,
                    &parent_joint_of,
                    &link_index,
                    0,
                    "every link has a parent joint, so there is no root link",
                ));
            }
            many => {
                let names: Vec<&str> = many.iter().map(|&l| robot.links[l].name.as_str()).collect();
                return Err(Error::InvalidRobot {
                    origin: self.origin.to_owned(),
                    message: format!(
                        "the robot has {} root links ({}); connect all but one to the tree with a joint",
                        names.len(),
                        names.join(", ")
                    ),
                });
            }
        };

        // Breadth-first order from the root; links never reached sit on a cycle.
        let mut order = Vec::with_capacity(robot.links.len());
        let mut queue = VecDeque::from([root]);
        while let Some(link) = queue.pop_front() {
            order.push(link);
            for &joint in &children_of[link] {
                queue.push_back(link_index[robot.joints[joint].child.link.as_str()]);
            }
        }
        if order.len() != robot.links.len() {
            let mut seen = vec![false; robot.links.len()];
            for &l in &order {
                seen[l] = true;
            }
            // Walking up the parent joints from any unreached link must end on a cycle.
            let stuck = (0..robot.links.len()).find(|&l| !seen[l]).unwrap_or(0);
            return Err(self.cycle_error(
                robot,
                &parent_joint_of,
                &link_index,
                stuck,
                &format!(
                    "some links cannot be reached from the root link '{}'",
                    robot.links[root].name
                ),
            ));
        }
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

        // A <mimic> of a joint that does not exist is ignored by urdfdom (check_urdf accepts
        // it); the joint is then independent, with a warning.
        let mut dangling: Vec<&str> = Vec::new();
        for joint in &robot.joints {
            if let Some(mimic) = &joint.mimic {
                if !joint_names.contains_key(mimic.joint.as_str()) {
                    warnings.push(format!(
                        "joint '{}' mimics joint '{}', which does not exist{}; treating '{}' as an independent joint",
                        joint.name,
                        mimic.joint,
                        crate::error::did_you_mean(&mimic.joint, joint_names.keys().copied()),
                        joint.name
                    ));
                    dangling.push(joint.name.as_str());
                }
            }
        }

        // Independent joints get configuration slots in topological order; mimics follow them.
        let mut dofs = Vec::new();
        for (index, joint) in joints.iter_mut().enumerate() {
            if joint.kind.is_movable()
                && (dangling.contains(&joint.name.as_str())
                    || robot.joints[source_index(robot, &joint.name)]
                        .mimic
                        .is_none())
            {
                joint.actuation = Actuation::Independent(DofId(dofs.len()));
                dofs.push(JointId(index));
            }
        }
        self.resolve_mimics(robot, &mut joints, &joint_position)?;

        let tree = KinematicTree::from_parts(robot.name.clone(), links, joints, dofs)?;
        Ok(UrdfImport { tree, warnings })
    }

    /// An error naming the joints of the cycle found by walking parent joints up from link
    /// `start`, located at the first of them in the file.
    fn cycle_error(
        &self,
        robot: &urdf_rs::Robot,
        parent_joint_of: &[Option<usize>],
        link_index: &HashMap<&str, usize>,
        start: usize,
        context: &str,
    ) -> Error {
        let mut step_of = vec![None; parent_joint_of.len()];
        let mut walked = Vec::new();
        let mut link = start;
        while step_of[link].is_none() {
            step_of[link] = Some(walked.len());
            let Some(joint) = parent_joint_of[link] else {
                break;
            };
            walked.push(joint);
            link = link_index[robot.joints[joint].parent.link.as_str()];
        }
        // Child → parent order; turn it round and start at the joint written first.
        let mut cycle = walked.split_off(step_of[link].unwrap_or(walked.len()));
        cycle.reverse();
        if let Some(first) = cycle
            .iter()
            .enumerate()
            .min_by_key(|(_, &j)| j)
            .map(|(i, _)| i)
        {
            cycle.rotate_left(first);
        }
        let Some(&first) = cycle.first() else {
            return Error::InvalidRobot {
                origin: self.origin.to_owned(),
                message: format!("{context}; a URDF must be a tree with one root link"),
            };
        };
        let joints: Vec<String> = cycle
            .iter()
            .map(|&j| format!("'{}'", robot.joints[j].name))
            .collect();
        let mut path = vec![robot.joints[first].parent.link.as_str()];
        path.extend(cycle.iter().map(|&j| robot.joints[j].child.link.as_str()));
        self.invalid(
            "joint",
            &robot.joints[first].name,
            format!(
                "{context}: joints {} form a cycle ({}); a URDF must be a tree with one root link",
                joints.join(", "),
                path.join(" → ")
            ),
        )
    }

    fn joint(
        &self,
        joint: &urdf_rs::Joint,
        parent: LinkId,
        child: LinkId,
        is_root_joint: bool,
        warnings: &mut Vec<String>,
    ) -> Result<Joint> {
        use urdf_rs::JointType;
        let kind = match joint.joint_type {
            JointType::Fixed => JointKind::Fixed,
            JointType::Revolute => JointKind::Revolute,
            JointType::Continuous => JointKind::Continuous,
            JointType::Prismatic => JointKind::Prismatic,
            JointType::Floating | JointType::Planar if is_root_joint => {
                let kind = format!("{:?}", joint.joint_type).to_lowercase();
                warnings.push(format!(
                    "joint '{}' is {kind} at the root; treating it as fixed (the base does not move during calibration)",
                    joint.name
                ));
                JointKind::Fixed
            }
            ref other => {
                return Err(self.invalid(
                    "joint",
                    &joint.name,
                    format!(
                        "joint '{}' has type {}, which treecal does not support; only revolute, continuous, prismatic and fixed joints (and a floating or planar joint at the root, treated as fixed) are accepted",
                        joint.name,
                        format!("{other:?}").to_lowercase()
                    ),
                ))
            }
        };
        let xyz = joint.origin.xyz.0;
        let rpy = joint.origin.rpy.0;
        if xyz.iter().chain(rpy.iter()).any(|v| !v.is_finite()) {
            return Err(self.invalid(
                "joint",
                &joint.name,
                format!(
                    "joint '{}' has a non-finite <origin> (xyz=\"{} {} {}\" rpy=\"{} {} {}\")",
                    joint.name, xyz[0], xyz[1], xyz[2], rpy[0], rpy[1], rpy[2]
                ),
            ));
        }
        let parent_from_joint = pose(
            Vec3::new(xyz[0], xyz[1], xyz[2]),
            rotation_from_rpy(rpy[0], rpy[1], rpy[2]),
        );
        let raw_axis = Vec3::from(joint.axis.xyz.0);
        let axis = if kind.is_movable() {
            let norm = raw_axis.norm();
            if !norm.is_finite() || norm < 1e-9 {
                return Err(self.invalid(
                    "joint",
                    &joint.name,
                    format!(
                        "joint '{}' has axis \"{} {} {}\", which has no direction; give a non-zero finite axis",
                        joint.name, raw_axis.x, raw_axis.y, raw_axis.z
                    ),
                ));
            }
            Unit::new_normalize(raw_axis)
        } else {
            Vec3::x_axis()
        };
        let limits = match kind {
            JointKind::Revolute | JointKind::Prismatic => {
                let limit = &joint.limit;
                let (lower, upper) = (limit.lower, limit.upper);
                if lower.is_nan() || upper.is_nan() {
                    return Err(self.invalid(
                        "joint",
                        &joint.name,
                        format!(
                            "joint '{}' has a NaN limit (lower={lower} upper={upper})",
                            joint.name
                        ),
                    ));
                }
                if lower > upper {
                    return Err(self.invalid(
                        "joint",
                        &joint.name,
                        format!(
                            "joint '{}' has limits lower={lower} upper={upper}; lower must not exceed upper",
                            joint.name
                        ),
                    ));
                }
                // urdf-rs fills a missing <limit> with zeros; a joint that cannot move at all is
                // far more likely a missing element than a real limit.
                let all_zero = [lower, upper, limit.effort, limit.velocity]
                    .iter()
                    .all(|v| *v == 0.0);
                if all_zero {
                    warnings.push(format!(
                        "joint '{}' is {} but has no <limit> (or an all-zero one); treating it as unbounded",
                        joint.name,
                        kind.urdf_name()
                    ));
                    None
                } else {
                    (lower.is_finite() || upper.is_finite()).then_some(Limits { lower, upper })
                }
            }
            _ => None,
        };
        Ok(Joint {
            name: joint.name.clone(),
            kind,
            parent,
            child,
            parent_from_joint,
            axis,
            limits,
            actuation: Actuation::None,
        })
    }

    fn resolve_mimics(
        &self,
        robot: &urdf_rs::Robot,
        joints: &mut [Joint],
        position: &HashMap<&str, JointId>,
    ) -> Result<()> {
        for index in 0..joints.len() {
            if !joints[index].kind.is_movable() {
                continue;
            }
            let name = joints[index].name.clone();
            let Some(first) = robot.joints[source_index(robot, &name)].mimic.as_ref() else {
                continue;
            };
            if matches!(joints[index].actuation, Actuation::Independent(_)) {
                // A mimic of a joint that does not exist, made independent above.
                continue;
            }
            // Follow mimic → mimic chains to an independent joint, composing the affine maps.
            let (mut multiplier, mut offset) = (1.0, 0.0);
            let mut mimic = first;
            let mut visited = vec![name.clone()];
            loop {
                let m = mimic.multiplier.unwrap_or(1.0);
                let o = mimic.offset.unwrap_or(0.0);
                if !m.is_finite() || !o.is_finite() {
                    return Err(self.invalid(
                        "joint",
                        &name,
                        format!("joint '{name}' has a non-finite <mimic> multiplier or offset"),
                    ));
                }
                // value = multiplier·(m·q_master + o) + offset
                offset += multiplier * o;
                multiplier *= m;
                // Each factor is bounded, their product is not: a long chain can overflow.
                let composed = magnitude_problem(multiplier, Quantity::Factor)
                    .map(|p| format!("multiplier: {p}"))
                    .or_else(|| {
                        magnitude_problem(offset, Quantity::JointLimit)
                            .map(|p| format!("offset: {p}"))
                    });
                if let Some(problem) = composed {
                    return Err(self.invalid(
                        "joint",
                        &name,
                        format!(
                            "the <mimic> chain {} → {} composes to a {problem}; shorten the chain \
                             or reduce its multipliers",
                            visited.join(" → "),
                            mimic.joint
                        ),
                    ));
                }
                let master = *position.get(mimic.joint.as_str()).ok_or_else(|| {
                    self.invalid(
                        "joint",
                        &name,
                        format!(
                            "joint '{name}' mimics joint '{}', which does not exist{}",
                            mimic.joint,
                            crate::error::did_you_mean(&mimic.joint, position.keys().copied())
                        ),
                    )
                })?;
                if visited.contains(&mimic.joint) {
                    return Err(self.invalid(
                        "joint",
                        &name,
                        format!(
                            "mimic joints {} → {} follow each other in a cycle; one of them must be independent",
                            visited.join(" → "),
                            mimic.joint
                        ),
                    ));
                }
                visited.push(mimic.joint.clone());
                match joints[master.0].actuation {
                    Actuation::Independent(dof) => {
                        joints[index].actuation = Actuation::Mimic {
                            master: dof,
                            multiplier,
                            offset,
                        };
                        break;
                    }
                    _ if !joints[master.0].kind.is_movable() => {
                        return Err(self.invalid(
                            "joint",
                            &name,
                            format!(
                                "joint '{name}' mimics joint '{}', which is fixed",
                                mimic.joint
                            ),
                        ));
                    }
                    // The master is itself a mimic (movable, not independent): follow it.
                    _ => match robot.joints[source_index(robot, &mimic.joint)]
                        .mimic
                        .as_ref()
                    {
                        Some(next) => mimic = next,
                        None => break,
                    },
                }
            }
        }
        Ok(())
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

fn source_index(robot: &urdf_rs::Robot, name: &str) -> usize {
    robot
        .joints
        .iter()
        .position(|j| j.name == name)
        .unwrap_or(0)
}

fn urdf_pose(p: &urdf_rs::Pose) -> Pose {
    pose(
        Vec3::from(p.xyz.0),
        rotation_from_rpy(p.rpy.0[0], p.rpy.0[1], p.rpy.0[2]),
    )
}
