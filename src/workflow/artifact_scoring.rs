//! How the outputs of `calibrate` are scored, by `calibrate` on its validation rows
//! (`calibrate_artifact`) and by `verify` on fresh rows (one code path): the written URDF text
//! re-read, placed in the measurement frame, rigid or with its compensation file predicting
//! the deflections, and each row's position and orientation error.

use super::artifact_joint_errors::AppliedJointErrors;
use super::calibrate_config::GravityFrame;
use super::calibrate_steps::Loaded;
use super::source::StiffnessSource;
use crate::calibration::ErrorSummary;
use crate::error::{Error, Result};
use crate::io::parse_stiffness;
use crate::kinematics::{FlexibilityModel, McpcModel, Stiffness};
use crate::math::Pose;
use crate::measurement::{Measurement, Observation};
use crate::report::ArtifactScore;
use crate::tree::{detect_branches, KinematicTree};
use crate::urdf::{parse_urdf, ExportReport};
use rayon::prelude::*;

/// The compensation file the outputs go with: the user's `--stiffness` file, or the
/// `stiffness.yaml` text `--identify-stiffness` writes.
pub(super) enum CompensationFile<'a> {
    /// The user's file (read again against the exported URDF).
    Source(&'a StiffnessSource),
    /// `stiffness.yaml` as written.
    Written(&'a str),
}

impl CompensationFile<'_> {
    /// How the report names it.
    pub fn name(&self) -> String {
        match self {
            CompensationFile::Source(source) => source.origin(),
            CompensationFile::Written(_) => "stiffness.yaml".into(),
        }
    }

    /// The stiffness for the exported `tree` and its `model`.
    fn read(&self, tree: &KinematicTree, model: &McpcModel) -> Result<Stiffness> {
        match self {
            CompensationFile::Source(source) => source.read(tree, model),
            CompensationFile::Written(text) => parse_stiffness(text, "stiffness.yaml", tree, model),
        }
    }
}

/// How the outputs are scored: the URDF text, the frame it sits in, the exported link of each
/// model tool, and the flexibility (stiffness and gravity frame) to predict deflections with.
/// `calibrate` scores its validation rows with it, `treecal verify` fresh rows (one code path).
pub(super) struct Scoring<'a> {
    pub loaded: &'a Loaded,
    pub world_from_base: Pose,
    /// Per model tool, the written link scored: the added `<tool>_marker` link (or
    /// `<tool>_calibrated`, from exports before session 22) when there is one, else the tool
    /// link.
    pub scored_links: Vec<String>,
    /// joint_errors.yaml's terms, added to the commanded joint angles (none: the URDF alone).
    pub joint_errors: Option<&'a AppliedJointErrors>,
}

/// Per model tool of `loaded`, the link `export` scores (see [`Scoring::scored_links`]).
pub(super) fn exported_links(loaded: &Loaded, export: &ExportReport) -> Vec<String> {
    let tree = loaded.robot.tree();
    loaded
        .nominal
        .tools()
        .iter()
        .map(|t| {
            let name = &tree.link(t.link).name;
            export
                .added_links
                .iter()
                .find(|a| &a.tool == name)
                .map_or_else(|| name.clone(), |a| a.link.clone())
        })
        .collect()
}

/// A row's position error (mm) and, for a measured pose, orientation error (deg) against the
/// predicted pose `pose` (both in the measurement frame).
pub(super) fn row_errors(measurement: &Measurement, pose: &Pose) -> (f64, Option<f64>) {
    match &measurement.observation {
        Observation::Pose(measured) => (
            (measured.translation.vector - pose.translation.vector).norm() * 1e3,
            Some(measured.rotation.angle_to(&pose.rotation).to_degrees()),
        ),
        Observation::Position(p) => ((p - pose.translation.vector).norm() * 1e3, None),
        // Contacts are scored by height and tilt (issue 29), not as tool positions.
        Observation::Contact(_) => (0.0, None),
    }
}

impl Scoring<'_> {
    /// The pose of every row's scored link predicted by the URDF text `urdf` (the files named
    /// `files`) in the measurement frame, rigid or with `compensation`'s stiffness and
    /// `gravity` predicting the deflections.
    pub fn predict(
        &self,
        urdf: &str,
        files: &str,
        measurements: &[Measurement],
        compensation: Option<&CompensationFile<'_>>,
        gravity: GravityFrame,
    ) -> Result<Vec<Pose>> {
        let import = parse_urdf(urdf, files)?;
        let tree = &import.tree;
        let original = self.loaded.robot.tree();
        let dof_of = dof_map(original, tree, files)?;
        let tools = self.loaded.nominal.tools();
        let tool_links = tools
            .iter()
            .map(|t| tree.link_id(&original.link(t.link).name))
            .collect::<Result<Vec<_>>>()?;
        let scored = self
            .scored_links
            .iter()
            .map(|name| tree.link_id(name))
            .collect::<Result<Vec<_>>>()?;
        let deflected = match compensation {
            Some(file) => {
                let branches = detect_branches(tree, Some(&tool_links))?;
                let mut model = McpcModel::from_tree(tree, &branches)?;
                model.set_world_from_base(&self.world_from_base);
                let stiffness = file.read(tree, &model)?;
                let flexibility = FlexibilityModel::new(tree, &model, &stiffness)?;
                let flexibility = match gravity {
                    GravityFrame::Measurement => flexibility.with_gravity_in_measurement_frame(),
                    GravityFrame::Base => flexibility,
                };
                Some((model, flexibility))
            }
            None => None,
        };
        // The link fixed in the world (the root unless a reference link was chosen).
        let reference = tree.link_id(&original.link(self.loaded.branches.reference).name)?;
        if reference != tree.root() && deflected.is_some() {
            // The compensated prediction below is rooted at the URDF root; scoring it against
            // rows measured from another link would mix frames and report wrong figures.
            return Err(invalid(
                files,
                "a compensation (stiffness) file with a reference link other than the URDF root cannot be scored yet: leave out the stiffness file or the reference link",
            ));
        }
        // In parallel, in row order; the first failing row's error, as a loop would give.
        let poses: Vec<Result<Pose>> = measurements
            .par_iter()
            .map(|m| {
                let turned = self.joint_errors.map(|j| j.apply(&m.q));
                let commanded = turned.as_deref().unwrap_or(&m.q);
                let q: Vec<f64> = dof_of.iter().map(|&d| commanded[d]).collect();
                let mut link_pose = tree.link_pose(scored[m.tool], &q)?;
                if reference != tree.root() {
                    link_pose = tree.link_pose(reference, &q)?.inverse() * link_pose;
                }
                Ok(match &deflected {
                    None => self.world_from_base * link_pose,
                    Some((model, flexibility)) => {
                        let tool = model
                            .tool_of_link(tool_links[m.tool])
                            .ok_or_else(|| invalid(files, "a measured tool is not a tool"))?;
                        let deflected = flexibility
                            .for_payload(m.payload)?
                            .deflected_tool_poses(tree, model, &q)?[tool];
                        // The scored link rides rigidly on the tool link.
                        let tool_from_scored =
                            tree.link_pose(tool_links[m.tool], &q)?.inverse() * link_pose;
                        deflected * tool_from_scored
                    }
                })
            })
            .collect();
        poses.into_iter().collect()
    }

    /// The validation error of the URDF text `urdf` (the files named `files`), rigid or with
    /// `compensation` predicting the deflections.
    pub fn score(
        &self,
        urdf: &str,
        files: &str,
        measurements: &[Measurement],
        compensation: Option<&CompensationFile<'_>>,
        gravity: GravityFrame,
    ) -> Result<ArtifactScore> {
        let predicted = self.predict(urdf, files, measurements, compensation, gravity)?;
        let (mut position, mut orientation) = (Vec::new(), Vec::new());
        for (m, pose) in measurements.iter().zip(&predicted) {
            let (p, o) = row_errors(m, pose);
            position.push(p);
            orientation.extend(o);
        }
        Ok(ArtifactScore {
            files: files.to_owned(),
            observations: position.len(),
            errors: ErrorSummary::of(&position, &orientation),
        })
    }
}

fn invalid(origin: &str, message: &str) -> Error {
    Error::InvalidData {
        origin: origin.to_owned(),
        message: message.to_owned(),
    }
}

/// For each independent joint of `exported`, the index of the same joint in `original`'s
/// configuration vector.
fn dof_map(original: &KinematicTree, exported: &KinematicTree, origin: &str) -> Result<Vec<usize>> {
    exported
        .dofs()
        .iter()
        .map(|&joint| {
            let name = &exported.joint(joint).name;
            original
                .dofs()
                .iter()
                .position(|&j| &original.joint(j).name == name)
                .ok_or_else(|| invalid(origin, &format!("joint '{name}' is not in the robot")))
        })
        .collect()
}
