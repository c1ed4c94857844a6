//! The MCPC model of a tree's selected branches at their nominal (URDF) geometry: where each
//! frame sits on its joint axis and which φ keeps it off the singularity (`docs/mcpc.md`).

// The model's fields and types, and the imports of `mcpc.rs`.
use super::*;

impl McpcModel {
    /// The MCPC model of `branches` of `tree` at its nominal (URDF) geometry.
    /// At most [`crate::limits::MAX_PARAMETERS`] parameters.
    pub fn from_tree(tree: &KinematicTree, branches: &Branches) -> Result<Self> {
        let model = convert(tree, branches)?;
        crate::limits::check_count(
            model.parameter_count(),
            crate::limits::MAX_PARAMETERS,
            &format!("robot '{}'", tree.name()),
            "MCPC parameters on the selected branches",
        )?;
        Ok(model)
    }
}

/// Geometry of an MCPC frame at the all-joints-zero configuration, in the root frame.
#[derive(Clone, Copy)]
struct Placed {
    rotation: Rotation,
    origin: Vec3,
    /// Rotation about z of this frame relative to its reference frame ([`McpcFrame::twist`]).
    twist: f64,
}

const BASE: Placed = Placed {
    rotation: Rotation::new_unchecked(nalgebra::Quaternion::new(1.0, 0.0, 0.0, 0.0)),
    origin: Vec3::new(0.0, 0.0, 0.0),
    twist: 0.0,
};

/// α, β with `Rx(α)·Ry(β)·e_z = axis`. Only used where |β| ≤ 60°, so α is well defined; the
/// guard keeps an axis exactly along ±x from giving atan2(±0, −0) = ±π.
fn axis_angles(axis: &Vec3) -> (f64, f64) {
    let beta = axis.x.atan2(axis.y.hypot(axis.z));
    let alpha = if axis.y == 0.0 && axis.z == 0.0 {
        0.0
    } else {
        wrap_angle((-axis.y).atan2(axis.z))
    };
    (alpha, beta)
}

fn convert(tree: &KinematicTree, branches: &Branches) -> Result<McpcModel> {
    // Every joint at its own zero (mimic offsets are not applied: the model is in joint values).
    let mut root_from_link = vec![Pose::identity()];
    for joint in tree.joints() {
        root_from_link.push(root_from_link[joint.parent.0] * joint.parent_from_child(0.0));
    }

    let mut frames: Vec<McpcFrame> = Vec::new();
    let mut placed: Vec<Placed> = Vec::new();
    let frame_of =
        |frames: &[McpcFrame], joint: JointId| frames.iter().position(|f| f.joint == joint);
    // The nearest movable ancestor joint of a link that is already a frame.
    let parent_frame = |frames: &[McpcFrame], link: LinkId| -> Option<usize> {
        tree.path_from_root(link)
            .iter()
            .rev()
            .find_map(|&j| frame_of(frames, j))
    };

    for joint_id in frame_order(tree, branches) {
        let joint = tree.joint(joint_id);
        let kind = match joint.kind {
            JointKind::Revolute | JointKind::Continuous => FrameKind::Revolute,
            JointKind::Prismatic => FrameKind::Prismatic,
            JointKind::Fixed => continue,
        };
        let parent = parent_frame(&frames, joint.parent);
        let previous = parent.map_or(BASE, |p| placed[p]);
        let root_from_joint = root_from_link[joint.parent.0] * joint.parent_from_joint;
        let axis_root = root_from_joint.rotation * joint.axis.into_inner();

        let reference = previous.rotation * rot_z(-previous.twist);
        let (alpha_ref, beta_ref) = axis_angles(&(reference.inverse() * axis_root));
        let reparametrised = beta_ref.abs() > SINGULARITY_THRESHOLD;
        let (phi, alpha, beta, rotation, twist) = if !reparametrised {
            let rotation = reference * rot_x(alpha_ref) * rot_y(beta_ref);
            (-previous.twist, alpha_ref, beta_ref, rotation, 0.0)
        } else {
            let turned = reference * rot_z(FRAC_PI_2);
            let (alpha, beta) = axis_angles(&(turned.inverse() * axis_root));
            let rotation = turned * rot_x(alpha) * rot_y(beta);
            // Later rows are expressed relative to the frame whose x axis is the previous joint
            // axis (−z for β > 0, +z for β < 0) projected onto the plane normal to this axis: the
            // plain MCPC frame when the axis is exactly along the previous X (Table 1's β = 90°
            // rows), and well conditioned near there, where the plain α is not.
            let previous_axis = reference * Vec3::z();
            let towards = previous_axis * -beta_ref.signum();
            let reference_x = (towards - axis_root * towards.dot(&axis_root)).normalize();
            let actual_x = rotation * Vec3::x();
            let twist = reference_x
                .cross(&actual_x)
                .dot(&axis_root)
                .atan2(reference_x.dot(&actual_x));
            (-previous.twist + FRAC_PI_2, alpha, beta, rotation, twist)
        };
        let origin = match kind {
            FrameKind::Revolute => {
                let point = root_from_joint.translation.vector;
                point + axis_root * (previous.origin - point).dot(&axis_root)
            }
            FrameKind::Prismatic => previous.origin,
        };
        let offset = rotation.inverse() * (origin - previous.origin);
        let (x, y) = match kind {
            FrameKind::Revolute => (offset.x, offset.y),
            FrameKind::Prismatic => (0.0, 0.0),
        };
        let root_from_frame = pose(origin, rotation);
        frames.push(McpcFrame {
            joint: joint_id,
            kind,
            parent,
            actuation: joint.actuation,
            phi: wrap_angle(phi),
            alpha,
            beta,
            x,
            y,
            frame_from_link: root_from_frame.inverse() * root_from_link[joint.child.0],
            reparametrised,
            twist,
        });
        placed.push(Placed {
            rotation,
            origin,
            twist,
        });
    }

    let reference = (branches.reference != tree.root()).then(|| {
        let parent = parent_frame(&frames, branches.reference);
        let previous = parent.map_or(BASE, |p| placed[p]);
        super::super::ReferenceLink {
            link: branches.reference,
            parent,
            last_from_link: pose(previous.origin, previous.rotation).inverse()
                * root_from_link[branches.reference.0],
        }
    });
    let mut tools = Vec::new();
    for tool_link in branches.tools() {
        let parent = parent_frame(&frames, tool_link);
        let previous = parent.map_or(BASE, |p| placed[p]);
        let last_from_tool =
            pose(previous.origin, previous.rotation).inverse() * root_from_link[tool_link.0];
        tools.push(McpcTool::from_relative_pose(
            tool_link,
            parent,
            previous.twist,
            &last_from_tool,
        ));
    }
    let mut model = McpcModel::new(frames, tools)?;
    model.set_reference(reference)?;
    Ok(model)
}

/// The joints that get an MCPC frame, parents first: the branches' joints in branch order,
/// each preceded by those of its URDF ancestors that are on a branch too (a path up a leg from
/// a reference link lists a leg's joints against their URDF order).
fn frame_order(tree: &KinematicTree, branches: &Branches) -> Vec<JointId> {
    let wanted: Vec<JointId> = branches
        .all()
        .flat_map(|b| b.joints.iter().copied())
        .collect();
    let mut ordered: Vec<JointId> = Vec::with_capacity(wanted.len());
    for &joint in &wanted {
        for ancestor in tree.path_from_root(tree.joint(joint).child) {
            if wanted.contains(&ancestor) && !ordered.contains(&ancestor) {
                ordered.push(ancestor);
            }
        }
    }
    ordered
}
