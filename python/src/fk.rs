//! `treecal.fk`: the pose of a link for joint configurations.

use crate::{invalid, to_py};
use pyo3::prelude::*;
use std::path::PathBuf;
use treecal::urdf::{load_urdf, parse_urdf};

const BUILT_IN_ROBONAUT: &str = include_str!("../../robots/robonaut/robonaut.urdf");

/// `root_from_tip` of `tip` for each row of `joints` (columns named by `joint_names`), as
/// row-major 4×4 matrices flattened to 16 values.
#[pyfunction]
#[pyo3(signature = (robot, tip, joint_names, joints, angle_unit = "rad"))]
pub fn fk(
    py: Python<'_>,
    robot: Option<PathBuf>,
    tip: String,
    joint_names: Vec<String>,
    joints: Vec<Vec<f64>>,
    angle_unit: &str,
) -> PyResult<Vec<Vec<f64>>> {
    let scale = match angle_unit {
        "rad" => 1.0,
        "deg" => std::f64::consts::PI / 180.0,
        other => return Err(invalid(format!("angle_unit '{other}': use 'rad' or 'deg'"))),
    };
    py.detach(|| {
        let import = match &robot {
            Some(path) => load_urdf(path),
            None => parse_urdf(BUILT_IN_ROBONAUT, "built-in robonaut.urdf"),
        }
        .map_err(to_py)?;
        let tree = &import.tree;
        let tip = tree.link_id(&tip).map_err(to_py)?;
        let mut dofs = Vec::with_capacity(joint_names.len());
        for name in &joint_names {
            let joint = tree.joint_id(name).map_err(to_py)?;
            let dof = tree.dofs().iter().position(|&j| j == joint);
            dofs.push((dof, tree.joint(joint).kind));
        }
        joints
            .iter()
            .enumerate()
            .map(|(row, values)| {
                if values.len() != joint_names.len() {
                    return Err(invalid(format!(
                        "joints row {row}: {} values for {} joint names",
                        values.len(),
                        joint_names.len()
                    )));
                }
                let mut q = tree.zero_configuration();
                for (&(dof, kind), &value) in dofs.iter().zip(values) {
                    if let Some(dof) = dof {
                        q[dof] = if kind == treecal::tree::JointKind::Prismatic {
                            value
                        } else {
                            value * scale
                        };
                    }
                }
                let pose = tree.link_pose(tip, &q).map_err(to_py)?;
                Ok(matrix(&pose))
            })
            .collect()
    })
}

fn matrix(pose: &treecal::math::Pose) -> Vec<f64> {
    let m = pose.to_homogeneous();
    (0..4)
        .flat_map(|i| (0..4).map(move |j| (i, j)))
        .map(|(i, j)| m[(i, j)])
        .collect()
}
