//! The camera simulation (`simulate --observation camera|mixed|tracker`): a true robot with
//! random parameter errors, observed at the same configurations by the head camera looking at
//! the boards, by a tracker, or by both, calibrated by [`crate::camera::calibrate_camera`], and
//! judged on tool poses against the true robot in its root frame at separate validation
//! configurations, whatever was observed. The robot is rigid here (no gravity loads).

use super::camera_contacts::{camera_contact_scene, contact_noise, contact_unknowns};
use super::camera_setup::CameraRigOptions;
use super::collision::CollisionChecker;
use super::contacts::{ContactScene, ContactSimulation};
use super::experiment::trial_seed;
use super::noise::{observe, NoiseModel, Targets};
use super::sampling::{sample_configurations, SamplingOptions};
use super::truth::{true_model, ErrorRanges};
use crate::calibration::Nuisance;
use crate::camera::{
    calibrate_camera, predict_pixels, CameraFitOptions, CameraFitReport, CameraProblem,
    ContactRows, Rig, TargetShape, Unknown, View,
};
use crate::error::{Error, Result};
use crate::kinematics::McpcModel;
use crate::measurement::Measurement;
use crate::tree::{Branches, KinematicTree};
use nalgebra::{DMatrix, Vector2};
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use rand_distr::{Distribution, Normal};
use serde::Serialize;

/// What the simulated calibration observes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ObservationMode {
    /// A laser tracker measures three targets on every tool.
    Tracker,
    /// The head camera sees the boards.
    Camera,
    /// Both, each with its own σ.
    Mixed,
}

/// Settings of a camera simulation.
#[derive(Debug, Clone)]
pub struct CameraSimulationOptions {
    /// The camera, boards and what is estimated.
    pub rig: CameraRigOptions,
    /// Identification configurations (each sees at least one board).
    pub configurations: usize,
    /// Validation configurations (drawn over the whole joint ranges).
    pub validation_poses: usize,
    /// Parameter errors of the true robot (and of the camera's mounting).
    pub errors: ErrorRanges,
    /// Pixel noise σ of a detected corner (px).
    pub pixel_sigma: f64,
    /// Tracker noise (tracker and mixed).
    pub tracker_noise: NoiseModel,
    /// The coupled branch's joints are drawn within ± this of zero (rad); with
    /// `world_board_always`, those in which the camera does not see the world board are
    /// dropped, so the torso angles spread as far as the board stays in view.
    pub torso_spread: f64,
    /// Whether every identification configuration must show the world board (when there is
    /// one) besides its tool board: the world board is all that determines the coupled
    /// branch, so a configuration without it tells nothing about the torso.
    pub world_board_always: bool,
    /// The master seed.
    pub seed: u64,
    /// Contacts the robot also makes, fitted with the pixels (`camera,touch`); `None`: none.
    pub contacts: Option<ContactSimulation>,
}

impl Default for CameraSimulationOptions {
    fn default() -> Self {
        Self {
            rig: CameraRigOptions::default(),
            configurations: 30,
            validation_poses: 20,
            errors: ErrorRanges::default(),
            pixel_sigma: 0.5,
            tracker_noise: NoiseModel::at901(),
            torso_spread: 1.0,
            world_board_always: true,
            seed: 0,
            contacts: None,
        }
    }
}

/// Everything a trial needs that does not change between trials.
pub struct CameraSetup<'a> {
    /// The robot.
    pub tree: &'a KinematicTree,
    /// Its branches.
    pub branches: &'a Branches,
    /// Self-collision checks for sampling.
    pub checker: Option<&'a CollisionChecker>,
    /// The cameras and targets.
    pub rig: &'a Rig,
    /// The nominal model with the rig's frames ([`Rig::build`]).
    pub augmented: &'a McpcModel,
}

/// The outcome of one trial in one observation mode.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CameraTrialReport {
    /// The trial's seed.
    pub seed: u64,
    /// What was observed.
    pub mode: ObservationMode,
    /// Identification configurations.
    pub configurations: usize,
    /// Images (one target in one configuration) used.
    pub views: usize,
    /// Detected points used.
    pub points: usize,
    /// Tracker rows used.
    pub tracker_rows: usize,
    /// Contacts used (touch, bar, flush, point rows of the fit: 3, 1, 3, 1 each).
    pub contacts: usize,
    /// Mean validation tool position error before calibration (mm).
    pub before_mean_position_mm: f64,
    /// Mean validation tool position error after calibration (mm).
    pub mean_position_mm: f64,
    /// Largest validation tool position error (mm).
    pub max_position_mm: f64,
    /// RMS validation tool position error (mm).
    pub rms_position_mm: f64,
    /// The RMS position error the fit's covariance predicts at the validation
    /// configurations (mm).
    pub predicted_rms_position_mm: f64,
    /// Mean validation tool orientation error (deg).
    pub mean_orientation_deg: f64,
    /// `σ̂` of the fit.
    pub residual_scale: f64,
    /// Unknowns fitted and the rank of the problem.
    pub unknowns: usize,
    /// Numerical rank.
    pub rank: usize,
    /// The parameters the data cannot determine, by name.
    pub unidentifiable: Vec<String>,
    /// Each kind's rows and own σ̂ (pixels, tracker rows, contact heights, tilts, gaps, bar
    /// lengths).
    pub kinds: Vec<crate::camera::KindScale>,
}

/// The truth and the observations of one trial.
#[derive(Debug, Clone)]
pub struct CameraTrialData {
    /// The trial's seed.
    pub seed: u64,
    /// The true augmented model (robot, camera and target poses).
    pub truth: McpcModel,
    /// Identification configurations.
    pub configurations: Vec<Vec<f64>>,
    /// Validation configurations (over the whole joint ranges).
    pub validation: Vec<Vec<f64>>,
    /// The noisy images (none in tracker mode).
    pub views: Vec<View>,
    /// The tracker rows (none in camera mode).
    pub tracker: Vec<Measurement>,
    /// The contacts the true robot makes and the fit's starting nuisance values
    /// ([`CameraSimulationOptions::contacts`]).
    pub contacts: Option<(ContactScene, Nuisance)>,
}

/// The truth and observations of trial `trial` in `mode`. Configurations, truth and noise
/// depend on the seed only, so the three modes see the same robot at the same configurations.
pub fn camera_trial_data(
    setup: &CameraSetup<'_>,
    options: &CameraSimulationOptions,
    mode: ObservationMode,
    trial: usize,
) -> Result<CameraTrialData> {
    let seed = trial_seed(options.seed, trial);
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let truth = camera_truth(setup, options, &mut rng)?;
    let configurations =
        visible_configurations(setup, &truth, options, options.configurations, &mut rng)?;
    let validation = sample_configurations(
        setup.tree,
        setup.checker,
        options.validation_poses,
        &mut rng,
        &SamplingOptions::default(),
        &[],
    )?;
    // Noise from its own stream: the three modes draw the same pixels and the same targets.
    let mut noise_rng = ChaCha8Rng::seed_from_u64(seed ^ 0x5EED_CA11_B7A7_E000);
    let views = if mode == ObservationMode::Tracker {
        Vec::new()
    } else {
        observe_views(setup.rig, &truth, &configurations, options, &mut noise_rng)?
    };
    let mut tracker_rng = ChaCha8Rng::seed_from_u64(seed ^ 0x7AC4_E500_0000_0001);
    let tracker = if mode == ObservationMode::Camera {
        Vec::new()
    } else {
        tracker_rows(
            setup.rig,
            &truth,
            &configurations,
            options,
            &mut tracker_rng,
        )
    };
    let contacts = match &options.contacts {
        Some(settings) => Some(camera_contact_scene(setup.tree, &truth, settings, seed)?),
        None => None,
    };
    Ok(CameraTrialData {
        seed,
        truth,
        configurations,
        validation,
        views,
        tracker,
        contacts,
    })
}

/// Held-out images of `data`'s truth: `count` further configurations drawn as the
/// identification ones were (each showing a tool board, and the world board when every
/// configuration must), from their own random stream, with ids `h<k>-<target>`.
pub fn held_out_views(
    setup: &CameraSetup<'_>,
    options: &CameraSimulationOptions,
    data: &CameraTrialData,
    count: usize,
) -> Result<Vec<View>> {
    let mut rng = ChaCha8Rng::seed_from_u64(data.seed ^ 0x4E1D_0BB5_0000_0002);
    let configurations = visible_configurations(setup, &data.truth, options, count, &mut rng)?;
    let mut views = observe_views(setup.rig, &data.truth, &configurations, options, &mut rng)?;
    for view in &mut views {
        view.id = format!("h{}", &view.id[1..]);
    }
    Ok(views)
}

/// Runs trial `trial` in `mode`: its data ([`camera_trial_data`]), the fit, and the fit
/// judged against the truth.
pub fn run_camera_trial(
    setup: &CameraSetup<'_>,
    options: &CameraSimulationOptions,
    mode: ObservationMode,
    trial: usize,
) -> Result<CameraTrialReport> {
    let CameraTrialData {
        seed,
        truth,
        configurations,
        validation,
        views,
        tracker,
        contacts,
    } = camera_trial_data(setup, options, mode, trial)?;
    let mut unknowns = setup.rig.unknowns(setup.augmented, !views.is_empty());
    let contact_rows = match &contacts {
        Some((scene, start)) => {
            unknowns.extend(contact_unknowns(scene));
            ContactRows {
                rows: &scene.measurements,
                nuisance: start,
            }
        }
        None => ContactRows::default(),
    };
    let problem = CameraProblem {
        rig: setup.rig,
        views: &views,
        tracker: &tracker,
        unknowns,
        contacts: contact_rows,
    };
    let fit_options = fit_options(options);
    let report = calibrate_camera(setup.augmented, &problem, &fit_options)?;
    let judged = judge(setup, &truth, &report, &validation)?;
    Ok(CameraTrialReport {
        seed,
        mode,
        configurations: configurations.len(),
        views: views.len(),
        points: views.iter().map(|v| v.points.len()).sum(),
        tracker_rows: tracker.len(),
        contacts: contact_rows.rows.len(),
        before_mean_position_mm: judged.before_mean,
        mean_position_mm: judged.mean,
        max_position_mm: judged.max,
        rms_position_mm: judged.rms,
        predicted_rms_position_mm: judged.predicted_rms,
        mean_orientation_deg: judged.orientation_mean,
        residual_scale: report.residual_scale,
        unknowns: report.unknowns.len(),
        rank: report.rank,
        unidentifiable: unidentifiable_names(setup, &problem, &report),
        kinds: report.kinds.clone(),
    })
}

/// The fit's settings for the simulated noise.
pub fn fit_options(options: &CameraSimulationOptions) -> CameraFitOptions {
    let mut fit = CameraFitOptions {
        pixel_sigma: if options.pixel_sigma > 0.0 {
            options.pixel_sigma
        } else {
            0.5
        },
        ..CameraFitOptions::default()
    };
    if !options.tracker_noise.is_none() {
        let sigma = options.tracker_noise.sigma(&crate::math::Vec3::zeros());
        fit.position_sigma = sigma;
        fit.rotation_sigma = std::f64::consts::SQRT_2 * sigma / crate::measurement::TARGET_SPACING;
    }
    if let Some(contacts) = &options.contacts {
        fit.contact_noise = contact_noise(contacts);
    }
    fit
}

/// The true augmented model: every parameter of the robot and of the camera mounting off by
/// a random error; targets whose pose is not estimated stay where they are declared to be.
fn camera_truth(
    setup: &CameraSetup<'_>,
    options: &CameraSimulationOptions,
    rng: &mut ChaCha8Rng,
) -> Result<McpcModel> {
    let mut truth = true_model(setup.augmented, &options.errors, rng)?;
    let nominal = setup.augmented.parameters();
    let mut values = truth.parameters();
    for (extra, (_, free)) in setup.rig.extra.iter().enumerate() {
        if !free {
            for p in setup.rig.extra_parameters(setup.augmented, extra) {
                values[p] = nominal[p];
            }
        }
    }
    truth.set_parameters(&values)?;
    Ok(truth)
}

/// `count` configurations in which `model` (the truth, or the nominal robot for a planner's
/// pool) shows the camera at least one whole board facing it: the coupled branch within
/// ±`torso_spread`, the rest anywhere.
fn visible_configurations(
    setup: &CameraSetup<'_>,
    model: &McpcModel,
    options: &CameraSimulationOptions,
    count: usize,
    rng: &mut ChaCha8Rng,
) -> Result<Vec<Vec<f64>>> {
    let tree = setup.tree;
    let limits = tree.dof_limits();
    let torso = setup.branches.coupled.dofs(tree);
    let tool_targets: Vec<usize> = (0..setup.rig.targets.len())
        .filter(|&t| setup.rig.targets[t].tool < setup.rig.robot_tools)
        .collect();
    let mut accepted = Vec::with_capacity(count);
    let mut unsampled = None;
    let attempts = 500 * count.max(1);
    for _ in 0..attempts {
        if accepted.len() == count {
            return Ok(accepted);
        }
        let fixed: Vec<(usize, f64)> = torso
            .iter()
            .map(|&d| {
                let (lower, upper) =
                    limits[d].map_or((-options.torso_spread, options.torso_spread), |l| {
                        (
                            l.lower.max(-options.torso_spread),
                            l.upper.min(options.torso_spread),
                        )
                    });
                (
                    d,
                    if upper > lower {
                        rng.random_range(lower..upper)
                    } else {
                        lower
                    },
                )
            })
            .collect();
        let q = match sample_configurations(
            tree,
            setup.checker,
            1,
            rng,
            &SamplingOptions::default(),
            &fixed,
        ) {
            Ok(mut drawn) => drawn.remove(0),
            // This torso leaves nothing collision-free (a humanoid's back bent into its
            // pelvis): draw another; the error stands if no draw ever samples.
            Err(error) => {
                unsampled = Some(error);
                continue;
            }
        };
        // Each configuration shows the tool boards in turn (every tool is seen as often),
        // and whatever else is in view.
        let visible = visible_targets(setup.rig, model, &q, options);
        let wanted = tool_targets
            .get(accepted.len() % tool_targets.len().max(1))
            .copied();
        let world = (0..setup.rig.targets.len())
            .find(|&t| setup.rig.targets[t].tool >= setup.rig.robot_tools);
        let world_seen = !options.world_board_always
            || world.is_none_or(|w| visible.iter().any(|v| v.target == w));
        if world_seen && visible.iter().any(|v| wanted.is_none_or(|t| v.target == t)) {
            accepted.push(q);
        }
    }
    if let (true, Some(error)) = (accepted.is_empty(), unsampled) {
        return Err(error);
    }
    Err(Error::InvalidData {
        origin: "camera simulation".into(),
        message: format!(
            "only {} of {} configurations in {attempts} draws show the camera a whole board; \
             choose another camera link or a smaller board",
            accepted.len(),
            count
        ),
    })
}

/// The targets wholly visible at `q` on `truth`, with their exact pixels.
pub(super) fn visible_targets(
    rig: &Rig,
    truth: &McpcModel,
    q: &[f64],
    options: &CameraSimulationOptions,
) -> Vec<View> {
    let poses = truth.tool_poses(q);
    let mut views = Vec::new();
    for (camera_index, camera) in rig.cameras.iter().enumerate() {
        let camera_pose = poses[camera.tool];
        for (target_index, target) in rig.targets.iter().enumerate() {
            let board = poses[target.tool] * target.tool_from_target;
            if target.shape.has_face() {
                let to_camera =
                    (camera_pose.translation.vector - board.translation.vector).normalize();
                let face = board.rotation * -nalgebra::Vector3::z();
                if face.dot(&to_camera) < options.rig.max_view_angle.cos() {
                    continue;
                }
            }
            let mut view = View {
                id: String::new(),
                q: q.to_vec(),
                camera: camera_index,
                target: target_index,
                points: (0..target.shape.point_count())
                    .map(|k| (k, Vector2::zeros()))
                    .collect(),
            };
            // A board is detected in part (as a ChArUco board is) when enough of its corners
            // are in the image; only those corners are detected.
            let pixels = predict_pixels(rig, &view, &poses, &camera.intrinsics, true);
            let total = pixels.len();
            view.points = view
                .points
                .iter()
                .zip(pixels)
                .filter_map(|((k, _), pixel)| pixel.ok().map(|p| (*k, p)))
                .collect();
            let needed = ((options.rig.min_detected_fraction * total as f64).ceil() as usize)
                .clamp(1, total.max(1));
            if view.points.len() >= needed {
                views.push(view);
            }
        }
    }
    views
}

/// The noisy views of every configuration.
fn observe_views(
    rig: &Rig,
    truth: &McpcModel,
    configurations: &[Vec<f64>],
    options: &CameraSimulationOptions,
    rng: &mut ChaCha8Rng,
) -> Result<Vec<View>> {
    let noise = Normal::new(0.0, options.pixel_sigma.max(0.0)).map_err(|e| Error::InvalidData {
        origin: "camera simulation".into(),
        message: format!("pixel σ {}: {e}", options.pixel_sigma),
    })?;
    let mut views = Vec::new();
    for (index, q) in configurations.iter().enumerate() {
        for mut view in visible_targets(rig, truth, q, options) {
            view.id = format!("c{index}-{}", rig.targets[view.target].name);
            if options.pixel_sigma > 0.0 {
                for (_, pixel) in &mut view.points {
                    pixel.x += noise.sample(rng);
                    pixel.y += noise.sample(rng);
                }
            }
            views.push(view);
        }
    }
    Ok(views)
}

/// Three-target frames of every robot tool at every configuration.
fn tracker_rows(
    rig: &Rig,
    truth: &McpcModel,
    configurations: &[Vec<f64>],
    options: &CameraSimulationOptions,
    rng: &mut ChaCha8Rng,
) -> Vec<Measurement> {
    let mut rows = Vec::new();
    let carriers = rig.camera_carriers(truth);
    for q in configurations {
        for (tool, pose) in truth.tool_poses(q).iter().take(rig.robot_tools).enumerate() {
            if carriers.contains(&tool) {
                continue;
            }
            rows.push(Measurement {
                tool,
                q: q.clone(),
                observation: observe(pose, Targets::Three, &options.tracker_noise, rng),
                stage: None,
                payload: None,
                session: None,
            });
        }
    }
    rows
}

/// Validation figures of a fit.
struct Judged {
    before_mean: f64,
    mean: f64,
    max: f64,
    rms: f64,
    predicted_rms: f64,
    orientation_mean: f64,
}

/// Tool pose errors of the fitted robot against the truth at `validation` (robot tools only,
/// root frame), and the RMS the fit's covariance predicts there.
fn judge(
    setup: &CameraSetup<'_>,
    truth: &McpcModel,
    report: &CameraFitReport,
    validation: &[Vec<f64>],
) -> Result<Judged> {
    let tools = setup.rig.robot_tools;
    let carriers = setup.rig.camera_carriers(setup.augmented);
    let (mut before, mut after, mut orientation, mut predicted) =
        (Vec::new(), Vec::new(), Vec::new(), 0.0);
    let columns: Vec<Option<usize>> = report
        .unknowns
        .iter()
        .map(|u| match u {
            Unknown::Parameter(p) => Some(*p),
            Unknown::Intrinsic { .. } | Unknown::Nuisance(_) => None,
        })
        .collect();
    for q in validation {
        let actual = truth.tool_poses(q);
        let nominal = setup.augmented.tool_poses(q);
        let fitted = report.model.tool_jacobians(q);
        for tool in (0..tools).filter(|t| !carriers.contains(t)) {
            let d = |p: &crate::math::Pose| {
                (actual[tool].translation.vector - p.translation.vector).norm() * 1e3
            };
            before.push(d(&nominal[tool]));
            after.push(d(&fitted[tool].pose));
            orientation.push(
                actual[tool]
                    .rotation
                    .angle_to(&fitted[tool].pose.rotation)
                    .to_degrees(),
            );
            if let Some(covariance) = &report.covariance {
                let position = DMatrix::from_fn(3, columns.len(), |r, c| {
                    columns[c].map_or(0.0, |p| fitted[tool].jacobian[(r, p)])
                });
                predicted += (&position * covariance * position.transpose()).trace();
            }
        }
    }
    let n = after.len().max(1) as f64;
    let mean = |v: &[f64]| v.iter().sum::<f64>() / n;
    Ok(Judged {
        before_mean: mean(&before),
        mean: mean(&after),
        max: after.iter().copied().fold(0.0, f64::max),
        rms: crate::math::root_mean_square(&after).unwrap_or(0.0),
        predicted_rms: if report.covariance.is_some() {
            (predicted / n).sqrt() * 1e3
        } else {
            f64::NAN
        },
        orientation_mean: mean(&orientation),
    })
}

/// The names of the unknowns the data cannot determine.
fn unidentifiable_names(
    setup: &CameraSetup<'_>,
    problem: &CameraProblem<'_>,
    report: &CameraFitReport,
) -> Vec<String> {
    report
        .identifiable
        .iter()
        .enumerate()
        .filter(|(_, ok)| !**ok)
        .map(|(k, _)| problem.unknown_name(setup.tree, &report.model, k))
        .collect()
}

/// The default board on each tool, for messages and reports.
pub fn board_size(shape: &TargetShape) -> String {
    match shape {
        TargetShape::Board {
            rows,
            columns,
            spacing,
        } => format!("{rows} × {columns} corners, {:.0} mm apart", spacing * 1e3),
        TargetShape::Marker => "a single marker".into(),
    }
}
