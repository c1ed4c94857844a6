//! compare's change of gauge: calibration B re-expressed in A's measurement frame before its
//! parameters are judged (docs/workflows.md, "Compare").
//!
//! With a fitted measurement frame the MCPC parameters are complete, so the frame's residual
//! error is absorbed by the first joint frames (and, for the two directions a frame's four
//! parameters cannot hold, by the rows after them). Each data set fits its own frame, so two
//! calibrations of one unchanged robot differ there by a change of gauge that their σ's
//! (conditional on the frame) know nothing of. The rigid transform that best aligns B's
//! predicted tool poses onto A's is that change of gauge (plus what noise or a drift adds);
//! applied at B's root and pushed into the parameters by an exact least-squares fit of the
//! model of A's calibrated URDF to B's transformed forward kinematics, it leaves parameter
//! differences that a change of frame cannot explain.

use super::verify::scored_link;
use crate::error::Result;
use crate::kinematics::{McpcModel, ParameterOwner};
use crate::math::{Pose, Vec3};
use crate::tree::{detect_branches, KinematicTree};
use nalgebra::{DMatrix, DVector};
use std::collections::HashMap;

/// Gauss–Newton iterations at most (the fit is exact: two or three suffice).
const ITERATIONS: usize = 20;

/// Singular values below this times the largest (columns scaled to unit norm) are not
/// stepped along.
const RANK_TOLERANCE: f64 = 1e-10;

/// Metres a radian of tool rotation weighs in the fit.
const ROTATION_WEIGHT_M: f64 = 0.1;

/// A's model reproduces A's URDF within this (m); otherwise no re-expression.
const CONSISTENCY_M: f64 = 1e-7;

/// What re-expressing B in A's measurement frame did.
pub(crate) struct Reexpression {
    /// The change of B's root frame (A's root from B's), as a rigid transform.
    pub root_change: Pose,
    /// The re-expressed B minus A, per parameter name (report.json's names), SI units.
    pub change: HashMap<String, f64>,
    /// RMS of the tool positions after the fit, against B's transformed predictions (m).
    pub residual_m: f64,
}

/// One configuration: a tool and its joint values by joint name.
pub(crate) type Configuration = (String, Vec<(String, f64)>);

/// The joint vector of `tree` for named joint values (others zero).
pub(crate) fn joint_vector(tree: &KinematicTree, joints: &[(String, f64)]) -> Vec<f64> {
    let mut q = vec![0.0; tree.dofs().len()];
    for (name, value) in joints {
        if let Some(d) = tree
            .dofs()
            .iter()
            .position(|&j| &tree.joint(j).name == name)
        {
            q[d] = *value;
        }
    }
    q
}

/// The 6-vector `target ⊖ model`: position difference, then the small rotation with
/// `R_target ≈ (I + [δ]×)·R_model`, weighted by [`ROTATION_WEIGHT_M`].
fn pose_residual(target: &Pose, model: &Pose) -> [f64; 6] {
    let p = target.translation.vector - model.translation.vector;
    let r: Vec3 = (target.rotation * model.rotation.inverse()).scaled_axis() * ROTATION_WEIGHT_M;
    [p.x, p.y, p.z, r.x, r.y, r.z]
}

/// B re-expressed in A's measurement frame: `root_change` (A's root from B's, from the tool
/// alignment and the two registrations) applied to B's calibrated URDF, the parameters of
/// A's calibrated URDF fitted to it at `configurations`. `None` when A's URDF cannot be
/// rebuilt as a model of these tools, or the model does not reproduce it.
pub(crate) fn reexpress(
    a: &KinematicTree,
    b: &KinematicTree,
    root_change: Pose,
    configurations: &[Configuration],
) -> Result<Option<Reexpression>> {
    let mut tools: Vec<String> = Vec::new();
    for (tool, _) in configurations {
        if !tools.contains(tool) {
            tools.push(tool.clone());
        }
    }
    // The links that carry the calibrated tool frames, in A's and B's URDFs.
    let scored = |tree: &KinematicTree, tool: &str| -> Result<_> {
        tree.link_id(&scored_link(tree, tree.link_id(tool)?))
    };
    let a_links = tools
        .iter()
        .map(|t| scored(a, t))
        .collect::<Result<Vec<_>>>()?;
    let Ok(branches) = detect_branches(a, Some(&a_links)) else {
        return Ok(None);
    };
    let Ok(mut model) = McpcModel::from_tree(a, &branches) else {
        return Ok(None);
    };
    let tool_of_model: Vec<usize> = a_links
        .iter()
        .map(|&l| model.tool_of_link(l))
        .collect::<Option<_>>()
        .unwrap_or_default();
    if tool_of_model.len() != tools.len() {
        return Ok(None);
    }
    // Rows: (model tool, A's joint vector, target pose in A's root frame).
    let mut rows = Vec::with_capacity(configurations.len());
    for (tool, joints) in configurations {
        let t = tools.iter().position(|x| x == tool).unwrap_or(0);
        let qa = joint_vector(a, joints);
        let own = a.link_pose(a_links[t], &qa)?;
        if (model.tool_pose(tool_of_model[t], &qa).translation.vector - own.translation.vector)
            .norm()
            > CONSISTENCY_M
        {
            return Ok(None);
        }
        let target = root_change * b.link_pose(scored(b, tool)?, &joint_vector(b, joints))?;
        rows.push((tool_of_model[t], qa, target));
    }
    let start = model.parameters();
    let residual_m = fit(&mut model, &rows)?;
    let names = parameter_names(&model, a, &tools, &a_links);
    let change = names
        .into_iter()
        .zip(model.parameters().iter().zip(&start))
        .map(|(name, (b, a))| (name, b - a))
        .collect();
    Ok(Some(Reexpression {
        root_change,
        change,
        residual_m,
    }))
}

/// Gauss–Newton on every parameter of `model` towards the target poses of `rows`; returns the
/// tool positions' RMS left (m).
fn fit(model: &mut McpcModel, rows: &[(usize, Vec<f64>, Pose)]) -> Result<f64> {
    let n = model.parameter_count();
    let position_rms = |model: &McpcModel| {
        let squares: f64 = rows
            .iter()
            .map(|(t, q, target)| {
                (model.tool_pose(*t, q).translation.vector - target.translation.vector)
                    .norm_squared()
            })
            .sum();
        (squares / rows.len().max(1) as f64).sqrt()
    };
    for _ in 0..ITERATIONS {
        let mut jacobian = DMatrix::zeros(6 * rows.len(), n);
        let mut residual = DVector::zeros(6 * rows.len());
        for (k, (t, q, target)) in rows.iter().enumerate() {
            let tool = model.tool_jacobian(*t, q);
            let r = pose_residual(target, &tool.pose);
            for i in 0..6 {
                residual[6 * k + i] = r[i];
                let weight = if i < 3 { 1.0 } else { ROTATION_WEIGHT_M };
                for c in 0..n {
                    jacobian[(6 * k + i, c)] = tool.jacobian[(i, c)] * weight;
                }
            }
        }
        let scales: Vec<f64> = jacobian
            .column_iter()
            .map(|c| if c.norm() > 0.0 { c.norm() } else { 1.0 })
            .collect();
        for (mut column, s) in jacobian.column_iter_mut().zip(&scales) {
            column /= *s;
        }
        let svd = jacobian.svd(true, true);
        let tolerance = RANK_TOLERANCE * svd.singular_values.max();
        let Ok(step) = svd.solve(&residual, tolerance) else {
            break;
        };
        let mut values = model.parameters();
        for (c, v) in values.iter_mut().enumerate() {
            *v += step[c] / scales[c];
        }
        model.set_parameters(&values)?;
        if step.norm() < 1e-12 {
            break;
        }
    }
    Ok(position_rms(model))
}

/// report.json's names of `model`'s parameters: joint frames by joint, tools by the measured
/// tool's name (not the `<tool>_marker` link the export may have added).
fn parameter_names(
    model: &McpcModel,
    tree: &KinematicTree,
    tools: &[String],
    links: &[crate::tree::LinkId],
) -> Vec<String> {
    let layout = model.parameter_layout();
    (0..model.parameter_count())
        .map(|p| match layout[p] {
            (ParameterOwner::Tool(t), kind) => {
                let link = model.tools()[t].link;
                match links.iter().position(|&l| l == link) {
                    Some(i) => format!("{} {}", tools[i], kind.name()),
                    None => model.parameter_name(tree, p),
                }
            }
            _ => model.parameter_name(tree, p),
        })
        .collect()
}
