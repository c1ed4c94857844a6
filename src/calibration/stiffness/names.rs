//! The compliance scales in words, and when one counts as determined (shared by the selection,
//! the fit and the report of the stiffness identification).

use crate::kinematics::{ComplianceParameter, McpcModel};
use crate::tree::KinematicTree;

/// Common scale factors after the individual ones: all joint compliances, all link compliances.
/// A compliance's scale is its own times its group's, so a stiffness file that is off by the
/// same factor everywhere is corrected everywhere, also where the data cannot tell one joint or
/// link from another.
pub(crate) const GROUPS: usize = 2;

/// A compliance is identified when the data alone determine its scale to this fraction of the
/// prior's uncertainty or better (a third: the data carry nine times the prior's information),
/// so that what is identified is determined by the data rather than fitted to their noise.
pub const DETERMINED: f64 = 1.0 / 3.0;

/// The groups in words.
pub(crate) const GROUP_NAMES: [&str; GROUPS] = ["all joints", "all links"];

/// "left_joint1 bending (+0.71) with torso_joint2 EI_z (−0.71)".
pub(crate) fn describe(
    tree: &KinematicTree,
    model: &McpcModel,
    parameters: &[ComplianceParameter],
    terms: &[(usize, f64)],
) -> String {
    terms
        .iter()
        .map(|&(k, w)| format!("{} ({w:+.2})", label(tree, model, parameters, k)))
        .collect::<Vec<_>>()
        .join(" with ")
}

/// Scale `k` in words: a compliance's name, or a group's (indices after the parameters).
pub(crate) fn label(
    tree: &KinematicTree,
    model: &McpcModel,
    parameters: &[ComplianceParameter],
    k: usize,
) -> String {
    match parameters.get(k) {
        Some(parameter) => name(tree, model, parameter),
        None => GROUP_NAMES[k - parameters.len()].to_owned(),
    }
}

/// `left_joint2 bending`, `left_joint2 EI_y`.
pub fn name(tree: &KinematicTree, model: &McpcModel, parameter: &ComplianceParameter) -> String {
    format!(
        "{} {}",
        tree.joint(model.frames()[parameter.frame].joint).name,
        parameter.kind.name()
    )
}
