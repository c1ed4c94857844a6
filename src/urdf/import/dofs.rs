//! Which joints are independent (configuration slots) and which follow another by `<mimic>`.

use crate::tree::{Actuation, DofId, Joint, JointId};
use std::collections::HashMap;

/// The joints whose `<mimic>` names a joint that does not exist (ignored by urdfdom, which
/// check_urdf accepts): independent, with a warning.
pub(super) fn dangling_mimics<'r>(
    robot: &'r urdf_rs::Robot,
    joint_names: &HashMap<&str, usize>,
    warnings: &mut Vec<String>,
) -> Vec<&'r str> {
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
    dangling
}

/// Independent joints get configuration slots in topological order (their ids returned);
/// mimics follow them.
pub(super) fn independent_joints(
    robot: &urdf_rs::Robot,
    joints: &mut [Joint],
    dangling: &[&str],
) -> Vec<JointId> {
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
    dofs
}

/// The index in the file of the joint named `name`.
pub(super) fn source_index(robot: &urdf_rs::Robot, name: &str) -> usize {
    robot
        .joints
        .iter()
        .position(|j| j.name == name)
        .unwrap_or(0)
}
