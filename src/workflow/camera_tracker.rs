//! Mixed data for `calibrate --camera … --measurements tracker.csv`: the tracker rows read
//! with the robot's tools, and the tracker's frame registered to the robot's root frame so
//! that pixels and tracker rows are fitted together, each with its own σ
//! ([`crate::camera::calibrate_camera`]). See `docs/camera.md` section 6.

use super::calibrate::MeasurementFrameChoice;
use crate::calibration::fit_rigid_transform;
use crate::camera::Rig;
use crate::error::{Error, Result};
use crate::io::{read_measurements, MeasurementReadOptions, MeasurementSet};
use crate::io::{AngleUnit, LengthUnit};
use crate::math::{rpy_from_rotation, Vec3};
use crate::measurement::{Measurement, Observation};
use crate::report::TrackerRegistration;
use crate::tree::KinematicTree;
use crate::McpcModel;
use std::path::PathBuf;

/// Tracker rows fitted together with the pixels.
#[derive(Debug, Clone, PartialEq)]
pub struct CameraTrackerInput {
    /// The measurement CSV (`docs/file-formats.md`): rows of the robot's tools.
    pub measurements: PathBuf,
    /// Expected position noise of a tracker row (m).
    pub position_sigma: f64,
    /// Expected rotation noise of a measured frame (rad).
    pub rotation_sigma: f64,
    /// The tracker's frame: `Auto` and `Fit` fit it (closed form, then with the rest); `Base`
    /// takes the rows as given in the robot's root frame. A registration file is not read
    /// here.
    pub frame: MeasurementFrameChoice,
    /// Unit of the tracker's lengths [default: the file's `# units:` comment, else m].
    pub length_unit: Option<LengthUnit>,
    /// Columns of the measurement CSV to skip.
    pub ignore_columns: Vec<String>,
}

impl CameraTrackerInput {
    /// Checks the σ and the frame choice before anything is read.
    pub(super) fn validate(&self) -> Result<()> {
        for (flag, value) in [
            ("position_sigma", self.position_sigma),
            ("rotation_sigma", self.rotation_sigma),
        ] {
            if !(value.is_finite() && value > 0.0) {
                return Err(Error::setting(
                    flag,
                    format!("{value}: give the tracker's noise, a positive number (m, rad)"),
                ));
            }
        }
        if let MeasurementFrameChoice::File(path) = &self.frame {
            return Err(Error::InvalidSetting {
                setting: "measurement_frame".into(),
                message: format!(
                    "{}: a registration file is not read with `camera`; use `fit` (the \
                     tracker's frame is fitted with the rest) or `base` (the rows are in the \
                     robot's root frame)",
                    path.display()
                ),
            });
        }
        Ok(())
    }

    /// Reads the tracker rows of the robot's own tools (`robot`: the rig's robot model).
    pub(super) fn read(
        &self,
        tree: &KinematicTree,
        robot: &McpcModel,
        angle_unit: Option<AngleUnit>,
        joint_length_unit: Option<LengthUnit>,
    ) -> Result<MeasurementSet> {
        let options = MeasurementReadOptions {
            length_unit: self.length_unit,
            angle_unit,
            joint_length_unit,
            ignore_columns: self.ignore_columns.clone(),
            ..MeasurementReadOptions::default()
        };
        let set = read_measurements(&self.measurements, tree, robot, &options)?;
        if let Some(line) = set
            .measurements
            .iter()
            .zip(&set.lines)
            .find(|(m, _)| matches!(m.observation, Observation::Contact(_)))
            .map(|(_, line)| line)
        {
            return Err(Error::InvalidData {
                origin: format!("{}:{line}", self.measurements.display()),
                message: "a contact row is not a tracker row; give contacts with `contacts`".into(),
            });
        }
        Ok(set)
    }
}

/// `augmented` registered to the tracker rows: with a fitted frame, the tracker frame as a
/// start in closed form (Kabsch on the tool positions the nominal model predicts in its root
/// frame) and then six measurement-frame parameters fitted with the rest; the camera file's
/// "world" stays the robot's root frame, so the pixels do not depend on this frame. `Base`
/// leaves the model as it is.
pub(super) fn registered(
    augmented: &McpcModel,
    rig: &Rig,
    input: &CameraTrackerInput,
    rows: &[Measurement],
) -> Result<McpcModel> {
    if input.frame == MeasurementFrameChoice::Base {
        return Ok(augmented.clone());
    }
    let base_from_world = augmented.world_from_base().inverse();
    let poses: Vec<(Vec3, Vec3)> = rows
        .iter()
        .filter(|m| m.tool < rig.robot_tools)
        .filter_map(|m| {
            let measured = match &m.observation {
                Observation::Pose(pose) => pose.translation.vector,
                Observation::Position(p) => *p,
                Observation::Contact(_) => return None,
            };
            let predicted = base_from_world * augmented.tool_pose(m.tool, &m.q);
            Some((predicted.translation.vector, measured))
        })
        .collect();
    let (predicted, measured): (Vec<Vec3>, Vec<Vec3>) = poses.into_iter().unzip();
    let Some(tracker_from_root) = fit_rigid_transform(&predicted, &measured) else {
        return Err(Error::InvalidData {
            origin: input.measurements.display().to_string(),
            message: "the tracker rows do not fix the tracker's frame (fewer than three \
                      positions, or all on a line); measure more configurations, or give \
                      `measurement_frame` base when the rows are in the robot's root frame"
                .into(),
        });
    };
    let mut model = augmented.clone();
    model.set_world_from_base(&tracker_from_root);
    Ok(model.with_frame_parameters())
}

/// The fitted tracker frame of `fitted` (the calibrated augmented model).
pub(super) fn registration(
    input: &CameraTrackerInput,
    rows: usize,
    fitted: &McpcModel,
) -> TrackerRegistration {
    let pose = fitted.world_from_base();
    TrackerRegistration {
        file: input.measurements.display().to_string(),
        rows,
        fitted: input.frame != MeasurementFrameChoice::Base,
        xyz: pose.translation.vector.into(),
        rpy: rpy_from_rotation(&pose.rotation),
    }
}
