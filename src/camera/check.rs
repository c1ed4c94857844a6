//! What camera observations can and cannot determine, before any fit: the rank decision of
//! the fit ([`calibrate_camera`] at the nominal model, no iteration) over the same unknowns,
//! with the undetermined parameters named and the reasons a camera has for them said in
//! words: a camera carried by the coupled branch sees the arms only relative to itself
//! unless something fixed in the world is observed, and nothing fixes the scale when only
//! single markers (no board spacing, no tracker) are seen. See `docs/camera.md` §5.

use super::fit::{CameraFitOptions, CameraFitReport, CameraProblem};
use super::solve::calibrate_camera;
use super::target::TargetShape;
use crate::error::Result;
use crate::kinematics::McpcModel;
use crate::tree::{Branches, KinematicTree};
use serde::Serialize;

/// What a camera data set determines.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CameraIdentifiability {
    /// Unknowns of the fit.
    pub unknowns: usize,
    /// Numerical rank of the weighted, column-scaled pixel Jacobian.
    pub rank: usize,
    /// The unknowns the data cannot determine, by name.
    pub undetermined: Vec<String>,
    /// Why, in words (empty when everything is determined).
    pub findings: Vec<String>,
}

/// The identifiability of `problem` on `model` (the rig's augmented nominal model of `tree`,
/// whose coupled branch is `branches.coupled`) with pixel noise `pixel_sigma`.
pub fn camera_identifiability(
    tree: &KinematicTree,
    branches: &Branches,
    model: &McpcModel,
    problem: &CameraProblem<'_>,
    pixel_sigma: f64,
) -> Result<CameraIdentifiability> {
    let options = CameraFitOptions {
        pixel_sigma,
        max_iterations: 0,
        ..CameraFitOptions::default()
    };
    let report = calibrate_camera(model, problem, &options)?;
    Ok(explain(tree, branches, model, problem, &report))
}

/// What `report` (a fit of `problem` on `model`, the rig's augmented model of `tree`) leaves
/// undetermined, by name, and why in words.
pub fn explain(
    tree: &KinematicTree,
    branches: &Branches,
    model: &McpcModel,
    problem: &CameraProblem<'_>,
    report: &CameraFitReport,
) -> CameraIdentifiability {
    let undetermined: Vec<String> = (0..report.unknowns.len())
        .filter(|&k| !report.identifiable[k])
        .map(|k| problem.unknown_name(tree, model, k))
        .collect();
    let mut findings = Vec::new();
    let coupled: Vec<&str> = branches
        .coupled
        .joints
        .iter()
        .map(|&j| tree.joint(j).name.as_str())
        .collect();
    let torso: Vec<&String> = undetermined
        .iter()
        .filter(|name| coupled.iter().any(|j| name.starts_with(&format!("{j} "))))
        .collect();
    // A target rigid on the base (a board fixed in the world) relates the camera to the root.
    let anchored = !problem.tracker.is_empty()
        || problem.views.iter().any(|v| {
            model.tools()[problem.rig.targets[v.target].tool]
                .parent
                .is_none()
        });
    if !torso.is_empty() && anchored {
        findings.push(format!(
            "the coupled branch ({}) does not move enough in these images: {} of its \
             parameters stay at their nominal values although a target fixed in the world is \
             seen; add images at other angles of these joints with that target in view",
            coupled.join(", "),
            torso.len()
        ));
    } else if !torso.is_empty() {
        findings.push(format!(
            "the coupled branch ({}) is seen only relative to the camera: no board fixed in \
             the world (and no tracker row) is observed through it, so {} of its parameters \
             stay at their nominal values and the arms come out relative to the torso; add a \
             board fixed in the world, or tracker rows, to calibrate it",
            coupled.join(", "),
            torso.len()
        ));
    }
    let metric = !problem.tracker.is_empty()
        || problem.views.iter().any(|v| {
            matches!(
                problem.rig.targets[v.target].shape,
                TargetShape::Board { .. }
            )
        });
    if !metric && !undetermined.is_empty() {
        findings.push(
            "nothing metric is observed (single markers only, no board spacing, no tracker \
             row): the scale of the robot is not determined by the images; see a board or add \
             tracker rows"
                .into(),
        );
    }
    let others: Vec<&String> = undetermined
        .iter()
        .filter(|name| !torso.contains(name))
        .collect();
    if metric && !others.is_empty() {
        findings.push(format!(
            "{} other unknown(s) are not determined by these images (they stay at their \
             nominal values): {}",
            others.len(),
            others
                .iter()
                .map(|s| s.as_str())
                .collect::<Vec<_>>()
                .join(", ")
        ));
    }
    CameraIdentifiability {
        unknowns: report.unknowns.len(),
        rank: report.rank,
        undetermined,
        findings,
    }
}
