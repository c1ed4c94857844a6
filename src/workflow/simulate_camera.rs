//! `simulate --observation camera|mixed|tracker-rigid`: the camera simulation
//! ([`crate::sim::camera`]) over seeded trials, with its summary.md and results.json.

use super::checker::collision_checker;
use super::simulate::{ObservationChoice, SimulateConfig, Simulation};
use super::source::branches;
use super::{Note, Progress, ProgressFn};
use crate::camera::{CameraSpec, Rig, TargetShape, TargetSpec};
use crate::sim::ContactSimulation;
use crate::sim::ErrorRanges;
use crate::sim::NoiseModel;
use crate::sim::{
    board_size, camera_trial_data, held_out_views, run_camera_trial, CameraSetup,
    CameraSimulationOptions, CameraTrialReport, ObservationMode,
};
use crate::sim::{camera_specs, CameraRigOptions};
use crate::{McpcModel, Result};
use rayon::prelude::*;
use std::sync::atomic::{AtomicUsize, Ordering};

/// The camera simulation of `config` (its `observation` is not `Tracker`).
pub(super) fn simulate_camera(
    config: &SimulateConfig,
    progress: ProgressFn<'_>,
) -> Result<Simulation> {
    if let Some(reference) = &config.reference_link {
        return Err(crate::Error::InvalidData {
            origin: "simulate".into(),
            message: format!(
                "the camera simulation measures from the URDF root; reference link '{reference}' \
                 is not supported with a camera observation yet: leave the reference link out"
            ),
        });
    }
    let mut notes = Vec::new();
    let robot = config.robot.load()?;
    notes.extend(robot.notes());
    let tree = &robot.import.tree;
    let (camera_link, branches) = camera_branches(config, &robot.import, &mut notes)?;
    let nominal = McpcModel::from_tree(tree, &branches)?;
    let checker = collision_checker(
        &config.robot,
        tree,
        &config.package_paths,
        config.collision_check,
        &mut notes,
    )?;
    let rig_options = CameraRigOptions {
        camera_link,
        world_board: if config.world_board {
            CameraRigOptions::default().world_board
        } else {
            None
        },
        estimate_intrinsics: config.estimate_intrinsics,
        ..CameraRigOptions::default()
    };
    let (cameras, targets) = camera_specs(
        tree,
        &branches,
        &nominal,
        Some(&checker),
        &rig_options,
        config.seed,
    )?;
    let (rig, augmented) = Rig::build(tree, &nominal, &cameras, &targets)?;
    let options = simulation_options(config, rig_options)?;
    let mode = match config.observation {
        ObservationChoice::Camera => ObservationMode::Camera,
        ObservationChoice::Mixed => ObservationMode::Mixed,
        ObservationChoice::RigidTracker | ObservationChoice::Tracker => ObservationMode::Tracker,
    };
    let setup = CameraSetup {
        tree,
        branches: &branches,
        checker: Some(&checker),
        rig: &rig,
        augmented: &augmented,
    };
    let reports = run_trials(&setup, &options, mode, config.trials, progress)?;
    let shapes: Vec<TargetShape> = rig.targets.iter().map(|t| t.shape.clone()).collect();
    let header = header(config, tree.name(), &shapes, &options, mode);
    let markdown = markdown(&header, &reports);
    if let Some(first) = reports.first() {
        if !first.unidentifiable.is_empty() {
            notes.push(Note::warning(format!(
                "the camera data cannot determine {} unknown(s): {}",
                first.unidentifiable.len(),
                first.unidentifiable.join(", ")
            )));
        }
    }
    let results = serde_json::json!({
        "schema_version": 1,
        "robot": tree.name(),
        "observation": mode,
        "seed": config.seed,
        "setup": header,
        "trials": reports,
        "mean_validation_position_mm": mean(reports.iter().map(|r| r.mean_position_mm)),
        "mean_predicted_rms_position_mm": mean(reports.iter().map(|r| r.predicted_rms_position_mm)),
        "mean_rms_position_mm": mean(reports.iter().map(|r| r.rms_position_mm)),
    });
    let mut simulation = Simulation::without_tracker_trials(notes, results, markdown, reports)?;
    if mode != ObservationMode::Tracker && config.trials > 0 {
        let lab = LabFiles {
            text: &robot.text,
            origin: &robot.origin,
            cameras: &cameras,
            targets: &targets,
        };
        simulation
            .files
            .extend(lab_files(&setup, &options, mode, &lab)?);
    }
    Ok(simulation)
}

/// The camera's link (`camera_link`, if given) and the branches: the tools' (`tools` or the
/// default ones), extended by the camera's link when joints on no branch move it.
fn camera_branches(
    config: &SimulateConfig,
    import: &crate::urdf::UrdfImport,
    notes: &mut Vec<Note>,
) -> Result<(Option<crate::tree::LinkId>, crate::Branches)> {
    let tree = &import.tree;
    let camera_link = match &config.camera_link {
        Some(name) => Some(tree.link_id(name)?),
        None => None,
    };
    let mut branches = branches(import, config.tools.as_deref(), None)?;
    if let Some(link) = camera_link {
        if let Some(extended) = with_camera_link(tree, &branches, link, notes)? {
            branches = extended;
        }
    }
    Ok((camera_link, branches))
}

/// The camera simulation's settings from `config` and the rig's.
fn simulation_options(
    config: &SimulateConfig,
    rig: CameraRigOptions,
) -> Result<CameraSimulationOptions> {
    Ok(CameraSimulationOptions {
        rig,
        configurations: config.poses + config.torso_poses,
        validation_poses: config.validation_poses,
        errors: ErrorRanges {
            angle: config.angle_error,
            length: config.length_error,
        },
        pixel_sigma: config.pixel_sigma,
        tracker_noise: NoiseModel::parse(&config.noise)?,
        seed: config.seed,
        contacts: contact_settings(config),
        ..CameraSimulationOptions::default()
    })
}

/// `trials` seeded trials in parallel (in trial order), each reported to `progress`.
fn run_trials(
    setup: &CameraSetup<'_>,
    options: &CameraSimulationOptions,
    mode: ObservationMode,
    trials: usize,
    progress: ProgressFn<'_>,
) -> Result<Vec<CameraTrialReport>> {
    let done = AtomicUsize::new(0);
    (0..trials)
        .into_par_iter()
        .map(|trial| {
            let report = run_camera_trial(setup, options, mode, trial);
            progress(Progress {
                stage: None,
                done: done.fetch_add(1, Ordering::SeqCst) + 1,
                total: trials,
                unit: "trials",
            });
            report
        })
        .collect()
}

/// The robot's text and the rig as a user describes it, for [`lab_files`].
struct LabFiles<'a> {
    text: &'a str,
    origin: &'a str,
    cameras: &'a [CameraSpec],
    targets: &'a [TargetSpec],
}

/// Trial 1's data as a lab would hand them to `calibrate --camera`: detections.csv (the
/// identification images), tracker.csv (with `mixed`: the tracker rows at the same
/// configurations, in the root frame), validation_detections.csv (held-out images of the same robot),
/// cameras.yaml (the nominal camera and targets) and truth.urdf (the true robot, with
/// `<tool>_marker` links where a true tool frame is off its joint's axis), to judge the
/// calibration against.
fn lab_files(
    setup: &CameraSetup<'_>,
    options: &CameraSimulationOptions,
    mode: ObservationMode,
    lab: &LabFiles<'_>,
) -> Result<Vec<(String, Vec<u8>)>> {
    use crate::io::camera_file_yaml;
    use crate::io::detections_to_csv;
    let data = camera_trial_data(setup, options, mode, 0)?;
    let held_out = held_out_views(setup, options, &data, options.validation_poses.max(1))?;
    let truth = setup.rig.robot_model(&data.truth)?.with_offsets_absorbed();
    let export_options = crate::urdf::ExportOptions {
        add_tool_links: true,
        ..Default::default()
    };
    let urdf =
        crate::urdf::export_urdf_with(lab.text, lab.origin, setup.tree, &truth, &export_options)?;
    let mut files = Vec::new();
    if mode == ObservationMode::Mixed {
        // The tracker rows in the robot's root frame (the simulated tracker's frame).
        let robot = setup.rig.robot_model(setup.augmented)?;
        let csv = crate::io::measurements_to_csv(setup.tree, &robot, &data.tracker)?;
        files.push(("tracker.csv".to_owned(), csv.into_bytes()));
    }
    files.extend([
        (
            "detections.csv".to_owned(),
            detections_to_csv(setup.tree, setup.rig, &data.views).into_bytes(),
        ),
        (
            "validation_detections.csv".to_owned(),
            detections_to_csv(setup.tree, setup.rig, &held_out).into_bytes(),
        ),
        (
            "cameras.yaml".to_owned(),
            camera_file_yaml(setup.tree, lab.cameras, lab.targets).into_bytes(),
        ),
        ("truth.urdf".to_owned(), urdf.urdf.into_bytes()),
    ]);
    if let Some((scene, _)) = &data.contacts {
        // contacts.csv, contacts-validation.csv and contact-setup.yaml, for `calibrate
        // --camera … --contacts contacts.csv --contact-setup contact-setup.yaml`.
        files.extend(super::simulate_contacts::lab_files(
            setup.tree,
            setup.augmented,
            scene,
            None,
            None,
        )?);
    }
    Ok(files)
}

/// [`with_camera_link`] for every camera of a camera file mounted on a link: `branches`
/// (of the named or the default tools) extended by each camera's link. Named tools are the
/// links the boards ride on; the camera's link is observed too, so the joints that move it
/// are calibrated either way (issue 31) rather than refused.
pub(super) fn with_camera_links(
    tree: &crate::KinematicTree,
    mut branches: crate::Branches,
    cameras: &[CameraSpec],
    notes: &mut Vec<Note>,
) -> Result<crate::Branches> {
    for camera in cameras {
        if let crate::camera::Mount::Link(link) = camera.mount {
            if let Some(extended) = with_camera_link(tree, &branches, link, notes)? {
                branches = extended;
            }
        }
    }
    Ok(branches)
}

/// A camera on a link moved by joints on no branch (a head camera behind its neck) would
/// see the boards through joints the model does not have: the branches are detected again
/// with the camera's link as one more observed link, so that those joints are calibrated
/// (issue 31), and a note says so. `None` when every joint that
/// moves the camera is already on a branch.
pub(super) fn with_camera_link(
    tree: &crate::KinematicTree,
    branches: &crate::Branches,
    link: crate::tree::LinkId,
    notes: &mut Vec<Note>,
) -> Result<Option<crate::Branches>> {
    let calibrated: Vec<_> = std::iter::once(&branches.coupled)
        .chain(&branches.arms)
        .flat_map(|b| b.joints.iter().copied())
        .collect();
    let missing: Vec<String> = tree
        .path_from_root(link)
        .into_iter()
        .filter(|&j| tree.joint(j).kind.is_movable() && !calibrated.contains(&j))
        .map(|j| tree.joint(j).name.clone())
        .collect();
    if missing.is_empty() {
        return Ok(None);
    }
    let mut tools = branches.tools();
    tools.push(link);
    let extended = crate::detect_branches_from(tree, Some(&tools), branches.reference)?;
    notes.push(Note::info(format!(
        "the camera's link '{}' is moved by {}, on no branch of the tools: they are \
         calibrated too, the link observed through the camera (its extrinsics place it)",
        tree.link(link).name,
        missing.join(", ")
    )));
    Ok(Some(extended))
}

/// The contacts beside the camera (`--observation camera,touch`): `None` without any; the
/// contact simulation's settings (per kind `--poses + --torso-poses` configurations, the
/// encoder noise, the tables) otherwise.
fn contact_settings(config: &SimulateConfig) -> Option<ContactSimulation> {
    (!config.contacts.is_empty()).then(|| super::simulate_contacts::contact_settings(config))
}

fn mean(values: impl Iterator<Item = f64>) -> f64 {
    let values: Vec<f64> = values.collect();
    values.iter().sum::<f64>() / values.len().max(1) as f64
}

/// The paragraph under summary.md's title: every setting that shaped the numbers.
fn header(
    config: &SimulateConfig,
    robot: &str,
    shapes: &[TargetShape],
    options: &CameraSimulationOptions,
    mode: ObservationMode,
) -> String {
    let camera = &options.rig.intrinsics;
    let world = match &options.rig.world_board {
        Some(board) => format!(
            "a world board of {} {:.1} m in front of the camera ({})",
            board_size(board),
            options.rig.world_board_distance,
            if options.rig.estimate_world_board {
                "pose estimated"
            } else {
                "pose known in the root frame"
            }
        ),
        None => "no world board".into(),
    };
    let tool_board = shapes.first().map_or_else(String::new, board_size);
    let contacts = options.contacts.as_ref().map_or_else(String::new, |c| {
        let noise = crate::sim::camera_contacts::contact_noise(c);
        format!(
            " Contacts fitted with the pixels: {} ({} configurations each, drawn over the \
             whole joint ranges; encoder noise σ {} rad; rows weighed by σ gap {} mm, height \
             {} mm, tilt {} rad, bar {} mm; contact points {} m off at the start).",
            c.kinds
                .iter()
                .map(|k| k.name())
                .collect::<Vec<_>>()
                .join(", "),
            c.per_kind,
            c.encoder_sigma,
            noise.gap * 1e3,
            noise.height * 1e3,
            noise.tilt,
            noise.length * 1e3,
            c.nuisance_start_error,
        )
    });
    let text = format!(
        "Robot '{robot}', {} trial(s), seed {}; observation: {mode:?}; {} identification \
         configurations (each showing the camera a tool board{}, each board detected when at \
         least {:.0} % of its corners are in the image and it is within {:.0}° of facing the \
         camera; torso joints drawn within ±{:.2} rad), {} validation configurations over the \
         whole joint ranges; errors ±{} rad, ±{} m (robot and camera mounting); camera \
         {:.0} × {:.0} px, fx {:.1} px, distortion {:?}, {} above the {} link, intrinsics {}; \
         a board of {tool_board} on each tool; {world}; pixel noise σ {} px; tracker noise {} \
         (three targets per tool); rigid robot (no gravity loads); one simultaneous fit.",
        config.trials,
        config.seed,
        options.configurations,
        if options.world_board_always && options.rig.world_board.is_some() {
            " and the world board"
        } else {
            ""
        },
        options.rig.min_detected_fraction * 100.0,
        options.rig.max_view_angle.to_degrees(),
        options.torso_spread,
        options.validation_poses,
        options.errors.angle,
        options.errors.length,
        camera.width,
        camera.height,
        camera.fx,
        camera.distortion,
        format_args!("{:.2} m", options.rig.camera_height),
        config
            .camera_link
            .as_deref()
            .unwrap_or("coupled branch's last"),
        if options.rig.estimate_intrinsics {
            "estimated"
        } else {
            "known"
        },
        options.pixel_sigma,
        config.noise,
    );
    text + &contacts
}

/// summary.md: the set-up, one row per trial and the means.
fn markdown(header: &str, reports: &[CameraTrialReport]) -> String {
    let mut text = format!("# Camera simulation\n\n{header}\n\n");
    text.push_str(
        "| trial | views | points | tracker rows | contacts | before (mm) | mean (mm) | max (mm) | RMS (mm) | predicted RMS (mm) | orientation (deg) | σ̂ | σ̂ by kind | rank / unknowns |\n\
         | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |\n",
    );
    for (k, r) in reports.iter().enumerate() {
        text.push_str(&format!(
            "| {} | {} | {} | {} | {} | {:.2} | {:.3} | {:.3} | {:.3} | {:.3} | {:.4} | {:.3} | {} | {} / {} |\n",
            k + 1,
            r.views,
            r.points,
            r.tracker_rows,
            r.contacts,
            r.before_mean_position_mm,
            r.mean_position_mm,
            r.max_position_mm,
            r.rms_position_mm,
            r.predicted_rms_position_mm,
            r.mean_orientation_deg,
            r.residual_scale,
            r.kinds
                .iter()
                .map(|k| format!("{} {:.2}", k.kind, k.residual_scale))
                .collect::<Vec<_>>()
                .join(", "),
            r.rank,
            r.unknowns
        ));
    }
    let measured = mean(reports.iter().map(|r| r.rms_position_mm));
    let predicted = mean(reports.iter().map(|r| r.predicted_rms_position_mm));
    text.push_str(&format!(
        "\nMean validation tool position error {:.3} mm (RMS {:.3} mm; the covariance predicts \
         {:.3} mm RMS, ratio {:.2}).\n",
        mean(reports.iter().map(|r| r.mean_position_mm)),
        measured,
        predicted,
        measured / predicted
    ));
    if let Some(first) = reports.first() {
        if !first.unidentifiable.is_empty() {
            text.push_str(&format!(
                "\nNot determined by the data (kept at their nominal values): {}.\n",
                first.unidentifiable.join(", ")
            ));
        }
    }
    text
}
