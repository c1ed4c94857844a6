//! How the deflected tool poses change with the MCPC parameters (forward differences): the
//! deflections change with the geometry through the lever arms of the loads, which a
//! Jacobian on the deflected chain leaves out.

use super::model::FlexibilityModel;
use crate::error::Result;
use crate::kinematics::McpcModel;
use crate::math::{pose_error, Pose, Transform};
use crate::tree::KinematicTree;
use nalgebra::Vector6;

impl FlexibilityModel {
    /// Per parameter of `parameters` (indices of [`McpcModel::parameters`]), the change of
    /// every deflected tool pose per unit parameter at configuration `q`, `[dp; δθ]` in the
    /// convention of [`pose_error`]: `(pose(p + step) ⊖ base) / step`, where `base` are the
    /// deflected tool poses at `model` ([`Self::deflected_tool_poses`]).
    ///
    /// Equal bit for bit to shifting the parameter and calling
    /// [`Self::deflected_tool_poses`], but what does not depend on the parameters (the
    /// checks, the tree's link poses for masses behind joints outside the model) is computed
    /// once per configuration instead of once per parameter.
    pub fn deflected_pose_derivatives(
        &self,
        tree: &KinematicTree,
        model: &McpcModel,
        q: &[f64],
        base: &[Pose],
        parameters: &[usize],
        step: f64,
    ) -> Result<Vec<Vec<Vector6<f64>>>> {
        self.check(tree, model, q)?;
        let tree_poses = if self.uses_tree {
            tree.link_poses(q)?
        } else {
            Vec::new()
        };
        let values = model.parameters();
        let mut shifted = model.clone();
        let mut columns = Vec::with_capacity(parameters.len());
        for &p in parameters {
            shifted.set_parameter(p, values[p] + step)?;
            let evaluation = self.evaluate_with(&shifted, q, &tree_poses);
            let tools = self.deflected_tools_evaluated(&shifted, q, &evaluation);
            columns.push(
                tools
                    .iter()
                    .map(Transform::to_pose)
                    .zip(base)
                    .map(|(a, b)| pose_error(&a, b) / step)
                    .collect(),
            );
            shifted.set_parameter(p, values[p])?;
        }
        Ok(columns)
    }
}
