//! Calibration from camera observations, alone or mixed with tracker rows: the model's
//! parameters, the camera and target poses of the rig and, where asked, the intrinsics, fitted
//! together by the same column-scaled, rank-revealing Gauss–Newton / Levenberg–Marquardt
//! iteration as the tracker identification (`docs/identification.md`), on pixel rows
//! divided by the pixel σ and tracker rows by theirs. See `docs/camera.md`.

use super::contact_rows::{add_contact_rows, contact_sums, ContactRows};
use super::model::{Intrinsics, Rejection, INTRINSIC_COUNT, INTRINSIC_NAMES};
use super::observation::{linearise_view, predict_pixels, View};
use super::rig::Rig;
use super::unknown::Unknown;
use crate::calibration::Termination;
use crate::calibration::{Noise, Nuisance};
use crate::error::{Error, Result};
use crate::kinematics::McpcModel;
use crate::math::{pose_error, Pose};
use crate::measurement::{Measurement, Observation};
use crate::tree::KinematicTree;
use nalgebra::{DMatrix, DVector, Vector6};

/// Settings of a camera calibration.
#[derive(Debug, Clone)]
pub struct CameraFitOptions {
    /// Expected pixel noise of a detected point (px): pixel rows are divided by it.
    pub pixel_sigma: f64,
    /// Expected position noise of a tracker row (m).
    pub position_sigma: f64,
    /// Expected rotation noise of a tracker pose row (rad).
    pub rotation_sigma: f64,
    /// Iteration limit.
    pub max_iterations: usize,
    /// Singular values below this times the largest are treated as zero (unidentifiable).
    pub rank_tolerance: f64,
    /// Stop when the scaled step is below this (relative to the scaled unknowns + 1).
    pub step_tolerance: f64,
    /// Stop when an accepted step lowers the cost by less than this fraction.
    pub cost_tolerance: f64,
    /// σ of the contact rows (heights, tilts, gaps, bar lengths; [`Noise`]): contact rows are
    /// divided by their kind's σ. Its position and rotation σ are not used (tracker rows take
    /// `position_sigma` and `rotation_sigma`).
    pub contact_noise: Noise,
}

impl Default for CameraFitOptions {
    fn default() -> Self {
        Self {
            pixel_sigma: 0.5,
            position_sigma: crate::calibration::DEFAULT_POSITION_SIGMA,
            rotation_sigma: crate::calibration::DEFAULT_ROTATION_SIGMA,
            max_iterations: 50,
            rank_tolerance: 1e-8,
            step_tolerance: 1e-12,
            cost_tolerance: 1e-10,
            contact_noise: Noise::default(),
        }
    }
}

/// The data and unknowns of a camera calibration.
#[derive(Debug, Clone)]
pub struct CameraProblem<'a> {
    /// The cameras and targets.
    pub rig: &'a Rig,
    /// The camera observations.
    pub views: &'a [View],
    /// Tracker rows of the robot's tools (tool indices of the robot model), in the world frame.
    pub tracker: &'a [Measurement],
    /// What is fitted.
    pub unknowns: Vec<Unknown>,
    /// Contacts fitted with the pixels (touch, bar, flush, point; none by default).
    pub contacts: ContactRows<'a>,
}

/// A detected point left out of the fit, and why.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct RejectedPoint {
    /// The view's id.
    pub view: String,
    /// The target point.
    pub point: usize,
    /// Why it has no predicted pixel.
    pub reason: Rejection,
}

/// What a camera calibration did and found.
#[derive(Debug, Clone)]
pub struct CameraFitReport {
    /// The fitted augmented model (robot, camera and target poses).
    pub model: McpcModel,
    /// The fitted intrinsics, per camera.
    pub intrinsics: Vec<Intrinsics>,
    /// The unknowns, in the order of the statistics below.
    pub unknowns: Vec<Unknown>,
    /// Accepted iterations.
    pub iterations: usize,
    /// Cost ½‖r‖² before the first and after each accepted iteration.
    pub costs: Vec<f64>,
    /// Why it stopped.
    pub termination: Termination,
    /// Rows (2 per detected point, 3 or 6 per tracker row).
    pub rows: usize,
    /// Numerical rank of the scaled Jacobian at the solution.
    pub rank: usize,
    /// `σ̂ = √(2·cost / (rows − rank))` (1 when the noise is as assumed).
    pub residual_scale: f64,
    /// RMS pixel residual at the solution (px).
    pub residual_rms_pixel: f64,
    /// `σ̂²·(JᵀWJ)⁺` over the unknowns, on the identifiable subspace.
    pub covariance: Option<DMatrix<f64>>,
    /// Whether each unknown is determined on its own.
    pub identifiable: Vec<bool>,
    /// Directions the data cannot determine: (unknown index, weight), largest first.
    pub unidentifiable: Vec<Vec<(usize, f64)>>,
    /// Detected points left out (no predicted pixel at the start).
    pub rejected: Vec<RejectedPoint>,
    /// The rows of each kind of observation and their own σ̂ ([`kind_scales`]).
    pub kinds: Vec<KindScale>,
    /// The contacts' nuisance values at the solution (empty without contacts).
    pub nuisance: Nuisance,
}

/// The rows of one kind of observation in a fit and their σ̂.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct KindScale {
    /// `pixel`, `tracker position`, `tracker rotation` or a contact row kind (`height`,
    /// `tilt`, `gap`, `length`).
    pub kind: String,
    /// Observations of this kind (detected points, tracker rows).
    pub observations: usize,
    /// Its residual rows.
    pub rows: usize,
    /// Its own σ̂: `√(Σ r² / (rows·(1 − rank/N)))` over its weighted residuals `r` (`N` rows in
    /// all): each kind bears its share of the degrees of freedom the fit used. 1 when the
    /// kind's noise is the declared σ.
    pub residual_scale: f64,
}

/// σ̂ per kind of the weighted `residual` of `problem` (pixel rows first, then the tracker
/// rows in order, position rows before rotation rows, then the contact rows), at numerical
/// rank `rank`.
pub fn kind_scales(
    problem: &CameraProblem<'_>,
    residual: &DVector<f64>,
    rank: usize,
) -> Vec<KindScale> {
    let total = residual.len();
    let tracker_rows: usize = problem.tracker.iter().map(|m| m.observation.rows()).sum();
    let contact_rows = problem.contacts.row_count().min(total);
    let pixel_rows = total.saturating_sub(tracker_rows + contact_rows);
    // (observations, rows, Σ r²) of pixel, tracker position, tracker rotation.
    let mut sums = [(0, 0, 0.0); 3];
    sums[0] = (
        pixel_rows / 2,
        pixel_rows,
        residual.rows(0, pixel_rows).norm_squared(),
    );
    let mut row = pixel_rows;
    for m in problem.tracker {
        let count = m.observation.rows();
        for k in 0..count.min(total - row) {
            let kind = if k < 3 { 1 } else { 2 };
            sums[kind].1 += 1;
            sums[kind].2 += residual[row + k].powi(2);
        }
        sums[1].0 += 1;
        if count > 3 {
            sums[2].0 += 1;
        }
        row += count;
    }
    let kept = 1.0 - rank as f64 / total.max(1) as f64;
    let scale = |sum: f64, rows: usize| {
        if kept > 0.0 {
            (sum / (rows as f64 * kept)).sqrt()
        } else {
            f64::NAN
        }
    };
    let instruments = ["pixel", "tracker position", "tracker rotation"]
        .iter()
        .zip(sums)
        .filter(|(_, (_, rows, _))| *rows > 0)
        .map(|(kind, (observations, rows, sum))| KindScale {
            kind: (*kind).to_owned(),
            observations,
            rows,
            residual_scale: scale(sum, rows),
        });
    let contacts = contact_sums(
        &problem.contacts,
        residual
            .as_slice()
            .get(total - contact_rows..)
            .unwrap_or(&[]),
    )
    .into_iter()
    .map(|(kind, observations, rows, sum)| KindScale {
        kind: kind.name().to_owned(),
        observations,
        rows,
        residual_scale: scale(sum, rows),
    });
    instruments.chain(contacts).collect()
}

/// The current estimate.
#[derive(Clone)]
pub(super) struct State {
    pub(super) model: McpcModel,
    pub(super) intrinsics: Vec<Intrinsics>,
    pub(super) nuisance: Nuisance,
}

/// The stacked weighted residual and Jacobian (empty when only the cost is wanted); `None`
/// when a kept point lost its pixel (a trial step too far).
pub(super) struct Linearisation {
    pub(super) residual: DVector<f64>,
    pub(super) jacobian: DMatrix<f64>,
}

impl CameraProblem<'_> {
    /// A readable name of unknown `k`.
    pub fn unknown_name(&self, tree: &KinematicTree, model: &McpcModel, k: usize) -> String {
        match self.unknowns[k] {
            Unknown::Parameter(p) => self.rig.parameter_name(tree, model, p),
            Unknown::Intrinsic { camera, index } => format!(
                "camera {} {}",
                self.rig.cameras[camera].name, INTRINSIC_NAMES[index]
            ),
            Unknown::Nuisance(k) => self
                .contacts
                .nuisance
                .value_name(k)
                .unwrap_or_else(|| format!("nuisance {k}")),
        }
    }

    pub(super) fn validate(&self, model: &McpcModel) -> Result<()> {
        let bad = |message: String| Error::InvalidData {
            origin: "camera calibration".into(),
            message,
        };
        if self.views.is_empty() && self.tracker.is_empty() && self.contacts.is_empty() {
            return Err(bad("no observations".into()));
        }
        let dofs = model
            .frames()
            .iter()
            .map(|f| f.actuation.driver().map_or(0, |dof| dof.0 + 1))
            .max()
            .unwrap_or(0);
        for view in self.views {
            let target = self.rig.targets.get(view.target);
            if view.camera >= self.rig.cameras.len() || target.is_none() {
                return Err(bad(format!("view '{}' names no camera or target", view.id)));
            }
            let count = target.map_or(0, |t| t.shape.point_count());
            if view.q.len() < dofs || !view.q.iter().all(|v| v.is_finite()) {
                return Err(bad(format!("view '{}' has a bad configuration", view.id)));
            }
            for (point, pixel) in &view.points {
                if *point >= count || !pixel.iter().all(|v| v.is_finite()) {
                    return Err(bad(format!(
                        "view '{}': point {point} is not on its target or its pixel is not finite",
                        view.id
                    )));
                }
            }
        }
        for (index, m) in self.tracker.iter().enumerate() {
            if m.tool >= self.rig.robot_tools || m.q.len() < dofs {
                return Err(bad(format!(
                    "tracker row {index} names no tool or has a bad configuration"
                )));
            }
            if matches!(m.observation, Observation::Contact(_)) {
                return Err(bad(format!(
                    "tracker row {index} is a contact: give contacts as the problem's contacts"
                )));
            }
        }
        self.contacts.validate(self.rig.robot_tools, dofs)?;
        let count = model.parameter_count();
        for unknown in &self.unknowns {
            let fine = match *unknown {
                Unknown::Parameter(p) => p < count,
                Unknown::Nuisance(k) => k < self.contacts.nuisance.len(),
                Unknown::Intrinsic { camera, index } => {
                    camera < self.rig.cameras.len() && index < INTRINSIC_COUNT
                }
            };
            if !fine {
                return Err(bad(format!("unknown {unknown:?} does not exist")));
            }
        }
        Ok(())
    }

    /// Per view, which detected points take part: those with a predicted pixel at `state`.
    pub(super) fn kept_points(&self, state: &State) -> (Vec<Vec<bool>>, Vec<RejectedPoint>) {
        let mut kept = Vec::with_capacity(self.views.len());
        let mut rejected = Vec::new();
        let mut cached: Option<(&[f64], Vec<Pose>)> = None;
        for view in self.views {
            let poses = cached_poses(&mut cached, &state.model, &view.q);
            let camera = &state.intrinsics[view.camera];
            let pixels = predict_pixels(self.rig, view, poses, camera, false);
            kept.push(
                pixels
                    .iter()
                    .zip(&view.points)
                    .map(|(p, (point, _))| match p {
                        Ok(_) => true,
                        Err(reason) => {
                            rejected.push(RejectedPoint {
                                view: view.id.clone(),
                                point: *point,
                                reason: *reason,
                            });
                            false
                        }
                    })
                    .collect(),
            );
        }
        (kept, rejected)
    }

    /// The weighted residual (and Jacobian, with `with_jacobian`) at `state`.
    pub(super) fn linearise(
        &self,
        state: &State,
        kept: &[Vec<bool>],
        options: &CameraFitOptions,
        with_jacobian: bool,
    ) -> Option<Linearisation> {
        let pixel_rows: usize = kept.iter().flatten().filter(|k| **k).count() * 2;
        let tracker_rows: usize = self.tracker.iter().map(|m| m.observation.rows()).sum();
        let rows = pixel_rows + tracker_rows + self.contacts.row_count();
        let columns = if with_jacobian {
            self.unknowns.len()
        } else {
            0
        };
        let mut residual = DVector::zeros(rows);
        let mut jacobian = DMatrix::zeros(if with_jacobian { rows } else { 0 }, columns);
        let mut row = 0;
        let weight = 1.0 / options.pixel_sigma;
        let mut cached_jacobians: Option<(&[f64], Vec<crate::kinematics::ToolJacobian>)> = None;
        let mut cached: Option<(&[f64], Vec<Pose>)> = None;
        for (view, kept) in self.views.iter().zip(kept) {
            let intrinsics = &state.intrinsics[view.camera];
            if with_jacobian {
                if cached_jacobians
                    .as_ref()
                    .is_none_or(|(q, _)| *q != view.q.as_slice())
                {
                    cached_jacobians =
                        Some((view.q.as_slice(), state.model.tool_jacobians(&view.q)));
                }
                let tools = &cached_jacobians.as_ref()?.1;
                let prediction = linearise_view(self.rig, view, tools, intrinsics);
                for (k, ((_, measured), keep)) in view.points.iter().zip(kept).enumerate() {
                    if !keep {
                        continue;
                    }
                    let pixel = prediction.pixels[k].ok()?;
                    for axis in 0..2 {
                        residual[row] = (measured[axis] - pixel[axis]) * weight;
                        for (column, unknown) in self.unknowns.iter().enumerate() {
                            jacobian[(row, column)] = weight
                                * match *unknown {
                                    Unknown::Parameter(p) => {
                                        prediction.wrt_model[(2 * k + axis, p)]
                                    }
                                    Unknown::Intrinsic { camera, index }
                                        if camera == view.camera =>
                                    {
                                        prediction.wrt_intrinsics[(2 * k + axis, index)]
                                    }
                                    Unknown::Intrinsic { .. } | Unknown::Nuisance(_) => 0.0,
                                };
                        }
                        row += 1;
                    }
                }
            } else {
                let poses = cached_poses(&mut cached, &state.model, &view.q);
                let pixels = predict_pixels(self.rig, view, poses, intrinsics, false);
                for ((pixel, (_, measured)), keep) in pixels.iter().zip(&view.points).zip(kept) {
                    if !keep {
                        continue;
                    }
                    let pixel = pixel.ok()?;
                    for axis in 0..2 {
                        residual[row] = (measured[axis] - pixel[axis]) * weight;
                        row += 1;
                    }
                }
            }
        }
        for m in self.tracker {
            let count = m.observation.rows();
            let weights = [1.0 / options.position_sigma, 1.0 / options.rotation_sigma];
            let tool = if with_jacobian {
                Some(state.model.tool_jacobian(m.tool, &m.q))
            } else {
                None
            };
            let predicted = match &tool {
                Some(tool) => tool.pose,
                None => state.model.tool_pose(m.tool, &m.q),
            };
            let error = tracker_error(&m.observation, &predicted);
            for k in 0..count {
                residual[row + k] = error[k] * weights[k / 3];
                if let Some(tool) = &tool {
                    for (column, unknown) in self.unknowns.iter().enumerate() {
                        if let Unknown::Parameter(p) = *unknown {
                            jacobian[(row + k, column)] = tool.jacobian[(k, p)] * weights[k / 3];
                        }
                    }
                }
            }
            row += count;
        }
        let (flat, positions) = seam_columns(&self.unknowns, state.model.parameter_count());
        add_contact_rows(
            &self.contacts,
            (&state.model, &state.nuisance),
            (&flat, &positions),
            &options.contact_noise,
            row,
            &mut residual,
            &mut jacobian,
        )
        .ok()?;
        Some(Linearisation { residual, jacobian })
    }

    /// `state` moved by `step` (one value per unknown).
    pub(super) fn moved(&self, state: &State, step: &DVector<f64>) -> Result<State> {
        let mut parameters = state.model.parameters();
        let mut intrinsics: Vec<[f64; INTRINSIC_COUNT]> =
            state.intrinsics.iter().map(Intrinsics::to_vector).collect();
        let mut nuisance_values = state.nuisance.values();
        for (unknown, delta) in self.unknowns.iter().zip(step.iter()) {
            match *unknown {
                Unknown::Parameter(p) => parameters[p] += delta,
                Unknown::Intrinsic { camera, index } => intrinsics[camera][index] += delta,
                Unknown::Nuisance(k) => nuisance_values[k] += delta,
            }
        }
        let mut model = state.model.clone();
        model.set_parameters(&parameters)?;
        let mut nuisance = state.nuisance.clone();
        nuisance.set_values(&nuisance_values)?;
        Ok(State {
            model,
            nuisance,
            intrinsics: state
                .intrinsics
                .iter()
                .zip(&intrinsics)
                .map(|(camera, values)| camera.with_vector(values))
                .collect(),
        })
    }
}

/// The model-parameter and nuisance unknowns as flat seam indices (the model's parameters,
/// then the nuisance values), with their positions among `unknowns`.
fn seam_columns(unknowns: &[Unknown], parameter_count: usize) -> (Vec<usize>, Vec<usize>) {
    unknowns
        .iter()
        .enumerate()
        .filter_map(|(position, unknown)| match *unknown {
            Unknown::Parameter(p) => Some((p, position)),
            Unknown::Nuisance(k) => Some((parameter_count + k, position)),
            Unknown::Intrinsic { .. } => None,
        })
        .unzip()
}

/// The tool poses of `model` at `q`, recomputed only when `q` changes.
fn cached_poses<'a, 'q>(
    cached: &'a mut Option<(&'q [f64], Vec<Pose>)>,
    model: &McpcModel,
    q: &'q [f64],
) -> &'a [Pose] {
    if cached.as_ref().is_none_or(|(at, _)| *at != q) {
        *cached = Some((q, model.tool_poses(q)));
    }
    cached.as_ref().map_or(&[], |(_, poses)| poses.as_slice())
}

/// measured ⊖ predicted of a tracker row (position rows only for a position).
fn tracker_error(measured: &Observation, predicted: &Pose) -> Vector6<f64> {
    match measured {
        Observation::Pose(pose) => pose_error(pose, predicted),
        Observation::Position(p) => {
            let d = p - predicted.translation.vector;
            Vector6::new(d.x, d.y, d.z, 0.0, 0.0, 0.0)
        }
        // Contacts are not tracker rows: they enter through `CameraProblem::contacts`
        // (`validate` keeps them out of `tracker`).
        Observation::Contact(_) => Vector6::zeros(),
    }
}
