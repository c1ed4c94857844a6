//! The identified stiffness as a stiffness file ready for reuse.

use super::ComplianceEstimate;
use crate::kinematics::McpcModel;
use crate::kinematics::{ComplianceKind, JointStiffness, LinkStiffness, Stiffness};
use crate::tree::KinematicTree;

/// The prior stiffness data with the identified stiffness of every calibrated joint and body
/// as overrides (by joint name): a stiffness file ready for reuse.
pub fn identified_stiffness(
    prior: &Stiffness,
    tree: &KinematicTree,
    model: &McpcModel,
    estimates: &[ComplianceEstimate],
) -> Stiffness {
    let value = |frame: usize, kind: ComplianceKind| -> Option<f64> {
        let name = &tree.joint(model.frames()[frame].joint).name;
        estimates
            .iter()
            .find(|e| e.kind == kind && &e.owner == name)
            .map(|e| e.stiffness)
    };
    let mut joint_overrides = Vec::new();
    let mut link_overrides = Vec::new();
    for (frame, f) in model.frames().iter().enumerate() {
        let name = tree.joint(f.joint).name.clone();
        if let (Some(bending), Some(torsion)) = (
            value(frame, ComplianceKind::JointBending),
            value(frame, ComplianceKind::JointTorsion),
        ) {
            joint_overrides.push((name.clone(), JointStiffness { bending, torsion }));
        }
        let link = [
            ComplianceKind::LinkAxial,
            ComplianceKind::LinkBendingY,
            ComplianceKind::LinkBendingZ,
            ComplianceKind::LinkTorsion,
        ]
        .map(|k| value(frame, k));
        if let [Some(axial), Some(bending_y), Some(bending_z), Some(torsion)] = link {
            link_overrides.push((
                name,
                LinkStiffness {
                    axial,
                    bending_y,
                    bending_z,
                    torsion,
                },
            ));
        }
    }
    Stiffness {
        joint_overrides,
        link_overrides,
        ..prior.clone()
    }
}
