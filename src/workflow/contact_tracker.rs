//! Tracker rows with contacts (`calibrate --contacts C.csv --contact-setup S.yaml
//! --measurements tracker.csv`, issue 29): the tracker's rows of the robot's tools fitted in
//! one least squares with the contacts, each row kind divided by its own σ (tracker positions
//! and rotations by `position_sigma`/`rotation_sigma`, contact heights, tilts, gaps and bar
//! lengths by the setup's σ's).
//!
//! The tracker's frame is fitted (`measurement_frame` fit or auto: a closed-form start from
//! the tool positions the nominal robot predicts, then six measurement-frame parameters with
//! the rest) or taken as the reference link's (`base`). The measured tools' target offsets
//! are fitted (positions: x, y, z; poses: all six). The contacts' planes are given in the
//! reference link; they are carried into the tracker's frame at the start
//! ([`super::calibrate_contacts::contact_problem`]), and the fitted plane then lives there.

use super::calibrate::MeasurementFrameChoice;
use super::camera_tracker::CameraTrackerInput;
use super::contact_fit::{ContactFit, ContactProblem};
use super::note::Note;
use super::source::MeasurementSource;
use crate::calibration::IdentificationOptions;
use crate::calibration::{fit_rigid_transform, kind_of, weighted_jacobian, Rigid, RowKind};
use crate::camera::KindScale;
use crate::error::{Error, Result};
use crate::io::ContactSetup;
use crate::kinematics::{McpcModel, ParameterKind, ParameterOwner};
use crate::math::{rpy_from_rotation, Vec3};
use crate::measurement::{Measurement, Observation};
use crate::report::TrackerRegistration;
use crate::tree::KinematicTree;
use std::path::Path;

/// The tracker rows of a contact calibration, read and registered.
#[derive(Debug, Clone)]
pub(super) struct ContactTracker {
    /// The rows (the tracker frame's measurements of the model's tools).
    pub rows: Vec<Measurement>,
    /// The model parameters they add to the fit: the measurement frame (when fitted) and the
    /// measured tools' target offsets.
    pub free: Vec<usize>,
    /// Whether the tracker's frame is fitted.
    pub fitted_frame: bool,
    /// The measurement CSV.
    pub file: String,
    /// Whether some rows are poses (their tools' rotation offsets are fitted too).
    pub poses: bool,
}

/// The tool links the tracker rows name (the model gets them as tools).
pub(super) fn tracker_links(input: &CameraTrackerInput) -> Result<Vec<String>> {
    MeasurementSource::Csv(input.measurements.clone()).tool_names()
}

impl ContactTracker {
    /// Reads `input`'s rows against `model` and returns the model registered to them (with
    /// measurement-frame parameters when the frame is fitted).
    pub(super) fn read(
        input: &CameraTrackerInput,
        tree: &KinematicTree,
        model: McpcModel,
    ) -> Result<(McpcModel, Self)> {
        input.validate()?;
        let set = input.read(tree, &model, None, None)?;
        let rows = set.measurements;
        let fitted_frame = input.frame != MeasurementFrameChoice::Base;
        let model = if fitted_frame {
            registered(model, &rows, input)?
        } else {
            model
        };
        let free = tracker_free(&model, &rows);
        let poses = rows
            .iter()
            .any(|m| matches!(m.observation, Observation::Pose(_)));
        Ok((
            model,
            Self {
                rows,
                free,
                fitted_frame,
                file: input.measurements.display().to_string(),
                poses,
            },
        ))
    }

    /// Refuses a held plane with a fitted tracker frame and names what a tracked contact
    /// tool's fitted target offset carries (`setup_file`: the setup's path, for messages).
    ///
    /// A held plane stays where the closed-form start put it from the nominal robot, in the
    /// tracker's frame; the tracker rows pin the robot in that frame, so the plane cannot
    /// follow the robot's errors (measured: σ̂ ≈ 100 on the built-in robot). A tool both
    /// tracked and in contact has one frame: its fitted target offset moves its contact face
    /// or point with it, which their own fitted values absorb (the face's in-plane position
    /// carries nothing; a point's x, y, z are free), not when they are held.
    pub(super) fn check_setup(
        &self,
        setup: &ContactSetup,
        setup_file: &Path,
        tree: &KinematicTree,
        model: &McpcModel,
    ) -> Result<Vec<Note>> {
        if self.fitted_frame && !setup.free.plane && !setup.planes.is_empty() {
            return Err(Error::InvalidData {
                origin: setup_file.display().to_string(),
                message: format!(
                    "the planes are held (\"free: plane: false\") while the tracker's frame is \
                     fitted from {}: a held plane is placed from the nominal robot in the \
                     tracker's frame and cannot follow the robot's errors there; free the \
                     planes, or give the tracker rows in the reference link's frame \
                     (\"measurement_frame\" base)",
                    self.file
                ),
            });
        }
        let tracked: Vec<&str> = self
            .rows
            .iter()
            .filter_map(|m| model.tools().get(m.tool))
            .map(|t| tree.link(t.link).name.as_str())
            .collect();
        let held: Vec<&str> = setup
            .tools
            .values()
            .filter(|t| tracked.contains(&t.link.as_str()))
            .filter(|t| {
                (t.point.is_some() && !setup.free.point)
                    || (t.face.is_some() && !setup.free.face_tilt && self.poses)
            })
            .map(|t| t.link.as_str())
            .collect();
        let mut notes = Vec::new();
        if !held.is_empty() {
            notes.push(Note::warning(format!(
                "{} tracked and in contact with its contact point or face held: the fitted \
                 target offset moves the held point or face with it (one frame per tool); \
                 free them (\"free: point\", \"free: face_tilt\") unless they are given \
                 relative to the tracked target",
                held.join(", ")
            )));
        }
        Ok(notes)
    }

    /// The fitted tracker frame of `fitted` (the calibrated model).
    pub(super) fn registration(&self, fitted: &McpcModel) -> TrackerRegistration {
        let pose = fitted.world_from_base();
        TrackerRegistration {
            file: self.file.clone(),
            rows: self.rows.len(),
            fitted: self.fitted_frame,
            xyz: pose.translation.vector.into(),
            rpy: rpy_from_rotation(&pose.rotation),
        }
    }
}

/// `model` with the tracker's frame as a start (Kabsch on the tool positions the nominal
/// model predicts in its reference frame against the measured ones) and six
/// measurement-frame parameters.
fn registered(
    mut model: McpcModel,
    rows: &[Measurement],
    input: &CameraTrackerInput,
) -> Result<McpcModel> {
    let (predicted, measured): (Vec<Vec3>, Vec<Vec3>) = rows
        .iter()
        .filter_map(|m| {
            let measured = match &m.observation {
                Observation::Pose(pose) => pose.translation.vector,
                Observation::Position(p) => *p,
                Observation::Contact(_) => return None,
            };
            Some((model.tool_pose(m.tool, &m.q).translation.vector, measured))
        })
        .unzip();
    let Some(tracker_from_reference) = fit_rigid_transform(&predicted, &measured) else {
        return Err(Error::InvalidData {
            origin: input.measurements.display().to_string(),
            message: "the tracker rows do not fix the tracker's frame (fewer than three \
                      positions, or all on a line); measure more configurations, or give \
                      `measurement_frame` base when the rows are in the reference link's frame"
                .into(),
        });
    };
    model.set_world_from_base(&tracker_from_reference);
    Ok(model.with_frame_parameters())
}

/// The measurement frame's parameters and the measured tools' target offsets (x, y, z for
/// positions, all six for poses).
fn tracker_free(model: &McpcModel, rows: &[Measurement]) -> Vec<usize> {
    let mut position = vec![false; model.tools().len()];
    let mut pose = vec![false; model.tools().len()];
    for m in rows {
        match m.observation {
            Observation::Pose(_) => pose[m.tool] = true,
            Observation::Position(_) => position[m.tool] = true,
            Observation::Contact(_) => {}
        }
    }
    model
        .parameter_layout()
        .iter()
        .enumerate()
        .filter(|(_, (owner, kind))| match owner {
            ParameterOwner::Measurement => true,
            ParameterOwner::Tool(t) => {
                pose[*t]
                    || (position[*t]
                        && matches!(kind, ParameterKind::X | ParameterKind::Y | ParameterKind::Z))
            }
            ParameterOwner::Frame(_) => false,
        })
        .map(|(k, _)| k)
        .collect()
}

/// σ̂ per row kind of the calibrated fit's training rows: `tracker position`, `tracker
/// rotation` and the contact row kinds (`height`, `tilt`, `gap`, `length`), each
/// `√(Σ r² / (rows·(1 − rank/N)))` over its weighted residuals (as the camera's).
pub(super) fn contact_kind_scales(
    problem: &ContactProblem,
    fit: &ContactFit,
    options: &IdentificationOptions,
) -> Result<Vec<KindScale>> {
    let mut model = problem.model.clone();
    model.set_parameters(&fit.after.parameters)?;
    let (_, residual) = weighted_jacobian(
        &model,
        &fit.after.nuisance,
        &problem.training,
        &Rigid,
        &[],
        options,
    )?;
    let names = |kind: RowKind| match kind {
        RowKind::Position => "tracker position",
        RowKind::Rotation => "tracker rotation",
        other => other.name(),
    };
    // (name, observations, rows, Σ r²) in RowKind::ALL order.
    let mut sums: Vec<(&str, usize, usize, f64)> = RowKind::ALL
        .iter()
        .map(|&k| (names(k), 0, 0, 0.0))
        .collect();
    let mut row = 0;
    for m in &problem.training {
        let kinds = kind_of(&m.observation).row_kinds();
        let mut seen = [false; 6];
        for &kind in kinds {
            let index = RowKind::ALL.iter().position(|&k| k == kind).unwrap_or(0);
            let entry = &mut sums[index];
            entry.2 += 1;
            entry.3 += residual.get(row).map_or(0.0, |r| r * r);
            if !seen[index] {
                entry.1 += 1;
                seen[index] = true;
            }
            row += 1;
        }
    }
    let kept = 1.0 - fit.after.rank as f64 / row.max(1) as f64;
    Ok(sums
        .into_iter()
        .filter(|(_, _, rows, _)| *rows > 0)
        .map(|(kind, observations, rows, sum)| KindScale {
            kind: kind.to_owned(),
            observations,
            rows,
            residual_scale: if kept > 0.0 {
                (sum / (rows as f64 * kept)).sqrt()
            } else {
                f64::NAN
            },
        })
        .collect())
}
