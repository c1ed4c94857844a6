//! `calibrate --camera cameras.yaml --detections detections.csv [--validation V.csv]`: the
//! whole camera calibration from files: read the robot, the camera file and the detections,
//! fit the robot with the camera extrinsics, the target poses and (when asked) the
//! intrinsics ([`crate::camera::calibrate_camera`]), judge it (σ̂ in pixels, points without a
//! pixel, held-out images, what the images cannot determine), and export one corrected URDF
//! and the fitted camera file. Computes everything and writes nothing
//! ([`CameraCalibration::write`] writes). See `docs/camera.md`.

use super::calibrate_camera_judge::{held_out, pixel_residuals, verdict_findings};
use super::camera_tracker::{registered, registration};
use super::checks::{check_outputs, Output};
use super::simulate_camera::with_camera_links;
use super::source::{branches, RobotSource};
use super::Note;
use crate::calibration::{Finding, Verdict};
use crate::camera::{
    calibrate_camera, explain_identifiability, CameraFitOptions, CameraFitReport, CameraProblem,
    CameraSpec, Mount, Rig, TargetSpec, Unknown, INTRINSIC_NAMES,
};
use crate::error::{Error, Result};
use crate::io::{camera_file_yaml, read_camera_file, CameraFileContents};
use crate::io::{check_output_folder, replace_folder, AngleUnit, LengthUnit, StatedUnits};
use crate::io::{parse_detections, read_detections};
use crate::math::{rpy_from_rotation, Pose};
use crate::measurement::Measurement;
use crate::report::{
    camera_markdown, CameraCalibrationReport, CameraFitSummary, FittedIntrinsic, FittedPose,
    RobotParameter,
};
use crate::tree::KinematicTree;
use crate::urdf::{export_urdf_with, ExportOptions};
use crate::McpcModel;
use std::path::{Path, PathBuf};

/// The fitted camera file [`CameraCalibration::write`] writes next to calibrated.urdf.
pub const CALIBRATED_CAMERAS: &str = "cameras_calibrated.yaml";

pub use super::calibrate_camera_judge::{PIXEL_SIGMA_FAILED, PIXEL_SIGMA_WARNING};
use super::camera_contacts::CameraContacts;
pub use super::camera_contacts::CameraContactsInput;
pub use super::camera_tracker::CameraTrackerInput;

/// Settings of [`calibrate_camera_files`].
#[derive(Debug, Clone, PartialEq)]
pub struct CameraCalibrateConfig {
    /// The robot.
    pub robot: RobotSource,
    /// Tool links ending the arms [default: detected, plus the link of a camera moved by
    /// joints on no branch].
    pub tools: Option<Vec<String>>,
    /// The camera file (cameras and targets, `docs/file-formats.md`).
    pub camera_file: PathBuf,
    /// The detections CSV.
    pub detections: DetectionsSource,
    /// Held-out detections (same format), predicted but not fitted.
    pub validation: Option<PathBuf>,
    /// Pixel noise σ of a detected point (px).
    pub pixel_sigma: f64,
    /// Tracker rows fitted with the pixels (mixed data), each kind with its own σ.
    pub tracker: Option<CameraTrackerInput>,
    /// Contacts fitted with the pixels (touch, bar, flush, point), each row kind with the
    /// setup's σ.
    pub contacts: Option<CameraContactsInput>,
    /// Unit of revolute joints in the CSVs [default: the file's `# units:` comment, else rad].
    pub angle_unit: Option<AngleUnit>,
    /// Unit of prismatic joints [default: the comment's, else m].
    pub length_unit: Option<LengthUnit>,
    /// Add `<tool>_marker` links where a calibrated tool frame is off its joint's axis.
    pub add_tool_links: bool,
}

/// Where the detections come from.
#[derive(Debug, Clone, PartialEq)]
pub enum DetectionsSource {
    /// A detections CSV file.
    File(PathBuf),
    /// Detections CSV text (the Python package's in-memory detections); `origin` names it in
    /// messages.
    Csv {
        /// The CSV text.
        text: String,
        /// Its name in messages.
        origin: String,
    },
}

/// The outcome of a camera calibration.
#[derive(Debug, Clone)]
pub struct CameraCalibration {
    /// `ok`, `warning` or `failed`, with its reasons.
    pub verdict: Verdict,
    /// What the CLI prints on stderr, in order.
    pub notes: Vec<Note>,
    /// The content of report.json.
    pub report: CameraCalibrationReport,
    /// report.md.
    pub report_markdown: String,
    /// The calibrated URDF; `None` when the verdict failed or the model cannot be exported.
    pub urdf: Option<String>,
    /// Every output file: `(name, bytes)`.
    pub files: Vec<(String, Vec<u8>)>,
    /// The input files (the writers refuse to replace them).
    pub inputs: Vec<PathBuf>,
}

impl CameraCalibrateConfig {
    /// Every file the calibration reads.
    pub fn inputs(&self) -> Vec<&Path> {
        [
            self.robot.path(),
            Some(self.camera_file.as_path()),
            match &self.detections {
                DetectionsSource::File(path) => Some(path.as_path()),
                DetectionsSource::Csv { .. } => None,
            },
            self.validation.as_deref(),
            self.tracker.as_ref().map(|t| t.measurements.as_path()),
            self.contacts.as_ref().map(|c| c.contacts.as_path()),
            self.contacts.as_ref().map(|c| c.setup.as_path()),
        ]
        .into_iter()
        .flatten()
        .collect()
    }

    /// Checks, before calibrating, that the folder `out` can receive the outputs.
    pub fn check_output(&self, out: &Path) -> Result<()> {
        check_outputs(&[Output::Folder(out)], &self.inputs())?;
        check_output_folder(out, &is_output_file)
    }
}

/// The fit's σ's: the pixel σ of `config`, its tracker's σ's, the contacts' `contact_noise`.
fn fit_options(
    config: &CameraCalibrateConfig,
    contact_noise: crate::calibration::Noise,
) -> CameraFitOptions {
    let mut options = CameraFitOptions {
        pixel_sigma: config.pixel_sigma,
        contact_noise,
        ..CameraFitOptions::default()
    };
    if let Some(input) = &config.tracker {
        options.position_sigma = input.position_sigma;
        options.rotation_sigma = input.rotation_sigma;
    }
    options
}

/// Whether a file name is one a calibration writes (a previous output may be replaced).
fn is_output_file(name: &str) -> bool {
    name == CALIBRATED_CAMERAS || super::calibrate::is_output_file(name)
}

impl CameraCalibration {
    /// Whether the result may be used (verdict `ok` or `warning`).
    pub fn usable(&self) -> bool {
        self.verdict.usable()
    }

    /// Replaces the folder `out` with the output files.
    pub fn write(&self, out: &Path) -> Result<()> {
        let inputs: Vec<&Path> = self.inputs.iter().map(PathBuf::as_path).collect();
        check_outputs(&[Output::Folder(out)], &inputs)?;
        check_output_folder(out, &is_output_file)?;
        replace_folder(out, &self.files)
    }
}

/// What the fit works on.
struct Setup {
    tree: KinematicTree,
    branches: crate::Branches,
    contents: CameraFileContents,
    rig: Rig,
    augmented: McpcModel,
    text: String,
    origin: String,
}

/// Calibrates from the files of `config`; writes nothing.
pub fn calibrate_camera_files(config: &CameraCalibrateConfig) -> Result<CameraCalibration> {
    if !(config.pixel_sigma.is_finite() && config.pixel_sigma > 0.0 && config.pixel_sigma <= 1e3) {
        return Err(Error::InvalidSetting {
            setting: "pixel_sigma".into(),
            message: format!(
                "{} px: give the detector's noise, a positive number of pixels (0.1 to a few)",
                config.pixel_sigma
            ),
        });
    }
    if let Some(tracker) = &config.tracker {
        tracker.validate()?;
    }
    let mut notes = Vec::new();
    let mut setup = load(config, &mut notes)?;
    let units = StatedUnits {
        angle: config.angle_unit,
        length: config.length_unit,
        ..StatedUnits::default()
    };
    let views = match &config.detections {
        DetectionsSource::File(path) => read_detections(path, &setup.tree, &setup.rig, &units)?,
        DetectionsSource::Csv { text, origin } => {
            parse_detections(text, origin, &setup.tree, &setup.rig, &units)?
        }
    };
    let held_out_views = match &config.validation {
        Some(path) => Some(read_detections(path, &setup.tree, &setup.rig, &units)?),
        None => None,
    };
    let tracker = read_tracker(config, &mut setup, &mut notes)?;
    let contacts = CameraContacts::read_optional(
        config.contacts.as_ref(),
        (&setup.tree, &setup.augmented),
        &mut notes,
    )?;
    let mut unknowns = setup.rig.unknowns(&setup.augmented, true);
    unknowns.extend(contacts.iter().flat_map(CameraContacts::unknowns));
    let (contact_rows, contact_noise) = CameraContacts::parts(contacts.as_ref());
    let problem = CameraProblem {
        rig: &setup.rig,
        views: &views,
        tracker: &tracker,
        unknowns,
        contacts: contact_rows,
    };
    let options = fit_options(config, contact_noise);
    let fit = calibrate_camera(&setup.augmented, &problem, &options)?;
    let unobservable = explain_identifiability(
        &setup.tree,
        &setup.branches,
        &setup.augmented,
        &problem,
        &fit,
    );
    let std_devs = std_devs(&fit);
    let (urdf, mut findings) = export_robot(&setup, config, &fit, &std_devs)?;
    let (residuals, targets, _) = pixel_residuals(&setup.rig, &views, &fit.model, &fit.intrinsics);
    let held_out = match (&held_out_views, &config.validation) {
        (Some(views), Some(path)) => {
            Some(held_out(&setup.rig, &setup.augmented, views, path, &fit))
        }
        _ => None,
    };
    let calibrated_cameras = match &urdf {
        Some(text) => Some(fitted_camera_file(&setup, &fit, text)?),
        None => None,
    };
    findings.extend(verdict_findings(
        &fit,
        &residuals,
        held_out.as_ref(),
        config.pixel_sigma,
    ));
    findings.extend(
        unobservable
            .findings
            .iter()
            .map(|f| Finding::warning("camera-unobservable", f.clone())),
    );
    let verdict = Verdict::from_findings(findings);
    notes.extend(verdict.reasons.iter().map(Note::from));
    let extra_std = extra_std_devs(&setup, &std_devs);
    let report = CameraCalibrationReport {
        schema_version: 1,
        robot: setup.tree.name().to_owned(),
        inputs: config
            .inputs()
            .iter()
            .map(|p| p.display().to_string())
            .collect(),
        fit: CameraFitSummary {
            iterations: fit.iterations,
            termination: fit.termination,
            rows: fit.rows,
            unknowns: fit.unknowns.len(),
            rank: fit.rank,
            residual_scale: fit.residual_scale,
            pixel_sigma: config.pixel_sigma,
        },
        kinds: fit.kinds.clone(),
        tracker: config
            .tracker
            .as_ref()
            .map(|input| registration(input, tracker.len(), &fit.model)),
        residuals,
        targets,
        held_out,
        rejected: fit.rejected.clone(),
        unobservable,
        cameras: Vec::new(),
        intrinsics: intrinsics_rows(&setup.rig, &fit, &std_devs),
        target_poses: Vec::new(),
        robot_parameters: robot_parameters(&setup, &fit, &std_devs)?,
        verdict: verdict.clone(),
    };
    let calibrated = calibrated_cameras.map(|(contents, yaml)| (contents, yaml, extra_std));
    finish(config, setup, report, notes, urdf, calibrated)
}

/// The tracker rows of `config` (none without them), read with the robot's tools; the setup's
/// model registered to the tracker's frame ([`registered`]).
fn read_tracker(
    config: &CameraCalibrateConfig,
    setup: &mut Setup,
    notes: &mut Vec<Note>,
) -> Result<Vec<Measurement>> {
    let Some(input) = &config.tracker else {
        return Ok(Vec::new());
    };
    let robot = setup.rig.robot_model(&setup.augmented)?;
    let set = input.read(&setup.tree, &robot, config.angle_unit, config.length_unit)?;
    notes.extend(set.notes.iter().map(|n| Note::info(n.clone())));
    notes.extend(set.warnings.iter().map(|w| Note::warning(w.clone())));
    setup.augmented = registered(&setup.augmented, &setup.rig, input, &set.measurements)?;
    Ok(set.measurements)
}

/// calibrated.urdf of the fitted robot (its standard deviations in the export's comments),
/// or a failed finding when the model cannot be written as a URDF.
fn export_robot(
    setup: &Setup,
    config: &CameraCalibrateConfig,
    fit: &CameraFitReport,
    std_devs: &StdDevs<'_>,
) -> Result<(Option<String>, Vec<Finding>)> {
    let robot_model = setup.rig.robot_model(&fit.model)?;
    let robot_std: Vec<Option<f64>> = (0..robot_model.parameter_count())
        .map(|i| std_devs.parameter(setup.rig.augmented_index(&robot_model, i)))
        .collect();
    let export_options = ExportOptions::with_uncertainty(
        &setup.tree,
        &robot_model,
        &robot_std,
        config.add_tool_links,
    );
    let mut findings = Vec::new();
    let urdf = match export_urdf_with(
        &setup.text,
        &setup.origin,
        &setup.tree,
        &robot_model.with_offsets_absorbed(),
        &export_options,
    ) {
        Ok(export) => {
            findings.extend(super::export::export_notes(&export));
            Some(export.urdf)
        }
        Err(error) => {
            findings.push(Finding::failed(
                "urdf-export",
                format!("the calibrated model cannot be written as a URDF: {error}"),
            ));
            None
        }
    };
    Ok((urdf, findings))
}

/// Per camera and target pose of the rig ([`Rig::extra`]), the standard deviations of its
/// six parameters when all are determined.
fn extra_std_devs(setup: &Setup, std: &StdDevs<'_>) -> Vec<(String, [f64; 6])> {
    (0..setup.rig.extra.len())
        .filter_map(|e| {
            let values: Option<Vec<f64>> = setup
                .rig
                .extra_parameters(&setup.augmented, e)
                .map(|p| std.parameter(p))
                .collect();
            let v = values?;
            Some((
                setup.rig.extra[e].0.clone(),
                [v[0], v[1], v[2], v[3], v[4], v[5]],
            ))
        })
        .collect()
}

/// The fitted camera file, its YAML, and the σ of each fitted pose ([`extra_std_devs`]).
type FittedCameraFile = (CameraFileContents, String, Vec<(String, [f64; 6])>);

/// The report's poses, the files, the outcome.
fn finish(
    config: &CameraCalibrateConfig,
    setup: Setup,
    mut report: CameraCalibrationReport,
    notes: Vec<Note>,
    urdf: Option<String>,
    calibrated: Option<FittedCameraFile>,
) -> Result<CameraCalibration> {
    if let Some((contents, _, std)) = &calibrated {
        let (cameras, targets) = fitted_poses(&setup, contents, std);
        report.cameras = cameras;
        report.target_poses = targets;
    }
    let markdown = camera_markdown(&report);
    let usable = report.verdict.usable();
    let urdf = urdf.filter(|_| usable);
    let mut files = vec![
        ("report.md".to_owned(), markdown.clone().into_bytes()),
        (
            "report.json".to_owned(),
            crate::io::to_json(&report)?.into_bytes(),
        ),
    ];
    if let (Some(urdf), Some((_, yaml, _))) = (&urdf, &calibrated) {
        files.push(("calibrated.urdf".to_owned(), urdf.clone().into_bytes()));
        files.push((CALIBRATED_CAMERAS.to_owned(), yaml.clone().into_bytes()));
    }
    Ok(CameraCalibration {
        verdict: report.verdict.clone(),
        notes,
        report,
        report_markdown: markdown,
        urdf,
        files,
        inputs: config.inputs().into_iter().map(Path::to_owned).collect(),
    })
}

/// Reads the robot and the camera file; the branches (with the camera's link where joints
/// on no branch move it) and the rig on the nominal model.
fn load(config: &CameraCalibrateConfig, notes: &mut Vec<Note>) -> Result<Setup> {
    let robot = config.robot.load()?;
    notes.extend(robot.notes());
    let (text, origin) = (robot.text, robot.origin);
    let import = robot.import;
    let contents = read_camera_file(&config.camera_file, &import.tree)?;
    let branches = with_camera_links(
        &import.tree,
        branches(&import, config.tools.as_deref(), None)?,
        &contents.cameras,
        notes,
    )?;
    let nominal = McpcModel::from_tree(&import.tree, &branches)?;
    let (rig, augmented) =
        Rig::build(&import.tree, &nominal, &contents.cameras, &contents.targets)?;
    Ok(Setup {
        tree: import.tree,
        branches,
        contents,
        rig,
        augmented,
        text,
        origin,
    })
}

/// Standard deviations of the fit's unknowns.
struct StdDevs<'a> {
    fit: &'a CameraFitReport,
}

impl StdDevs<'_> {
    fn of(&self, unknown: Unknown) -> Option<f64> {
        let k = self.fit.unknowns.iter().position(|u| *u == unknown)?;
        if !self.fit.identifiable[k] {
            return None;
        }
        let c = self.fit.covariance.as_ref()?;
        Some(c[(k, k)].max(0.0).sqrt())
    }

    fn parameter(&self, index: usize) -> Option<f64> {
        self.of(Unknown::Parameter(index))
    }
}

fn std_devs(fit: &CameraFitReport) -> StdDevs<'_> {
    StdDevs { fit }
}

/// The cameras and targets of the camera file with their fitted poses, expressed in the
/// links of the calibrated URDF `urdf` (so the file and the URDF go together), and the
/// fitted intrinsics: the contents and their YAML.
fn fitted_camera_file(
    setup: &Setup,
    fit: &CameraFitReport,
    urdf: &str,
) -> Result<(CameraFileContents, String)> {
    let calibrated = crate::urdf::parse_urdf(urdf, "calibrated.urdf")?.tree;
    let q0 = setup.tree.zero_configuration();
    let world_from_base = fit.model.world_from_base();
    let link_pose = |mount: Mount| -> Result<Pose> {
        match mount {
            Mount::World => Ok(Pose::identity()),
            Mount::Link(link) => {
                let id = calibrated.link_id(&setup.tree.link(link).name)?;
                let q = calibrated.zero_configuration();
                Ok(world_from_base * calibrated.link_pose(id, &q)?)
            }
        }
    };
    let poses = fit.model.tool_poses(&q0);
    let mut contents = setup.contents.clone();
    for (k, camera) in contents.cameras.iter_mut().enumerate() {
        let rig = &setup.rig.cameras[k];
        camera.mount_from_camera = link_pose(camera.mount)?.inverse() * poses[rig.tool];
        camera.intrinsics = fit.intrinsics[k];
    }
    for (k, target) in contents.targets.iter_mut().enumerate() {
        let rig = &setup.rig.targets[k];
        target.mount_from_target =
            link_pose(target.mount)?.inverse() * poses[rig.tool] * rig.tool_from_target;
    }
    let yaml = camera_file_yaml(&setup.tree, &contents.cameras, &contents.targets);
    Ok((contents, yaml))
}

/// The report's pose rows: cameras, and targets not on a tool.
fn fitted_poses(
    setup: &Setup,
    fitted: &CameraFileContents,
    std: &[(String, [f64; 6])],
) -> (Vec<FittedPose>, Vec<FittedPose>) {
    let link = |mount: &Mount| match mount {
        Mount::World => "world".to_owned(),
        Mount::Link(l) => setup.tree.link(*l).name.clone(),
    };
    let std_of = |extra: String| std.iter().find(|(n, _)| *n == extra).map(|(_, s)| *s);
    let row = |name: &str, mount: &Mount, nominal: &Pose, calibrated: &Pose, std| FittedPose {
        name: name.to_owned(),
        link: link(mount),
        nominal_xyz: nominal.translation.vector.into(),
        calibrated_xyz: calibrated.translation.vector.into(),
        nominal_rpy: rpy_from_rotation(&nominal.rotation),
        calibrated_rpy: rpy_from_rotation(&calibrated.rotation),
        std_dev: std,
    };
    let cameras = setup
        .contents
        .cameras
        .iter()
        .zip(&fitted.cameras)
        .map(|(n, f): (&CameraSpec, &CameraSpec)| {
            let std = std_of(format!("camera {}", n.name));
            row(
                &n.name,
                &n.mount,
                &n.mount_from_camera,
                &f.mount_from_camera,
                std,
            )
        })
        .collect();
    let targets = setup
        .contents
        .targets
        .iter()
        .zip(&fitted.targets)
        .zip(&setup.rig.targets)
        .filter(|(_, rig)| rig.tool >= setup.rig.robot_tools)
        .map(|((n, f), _): ((&TargetSpec, &TargetSpec), _)| {
            let std = std_of(format!("target {}", n.name));
            row(
                &n.name,
                &n.mount,
                &n.mount_from_target,
                &f.mount_from_target,
                std,
            )
        })
        .collect();
    (cameras, targets)
}

fn intrinsics_rows(rig: &Rig, fit: &CameraFitReport, std: &StdDevs<'_>) -> Vec<FittedIntrinsic> {
    let mut rows = Vec::new();
    for (camera, spec) in rig.cameras.iter().enumerate() {
        let nominal = spec.intrinsics.to_vector();
        let fitted = fit.intrinsics[camera].to_vector();
        for (index, name) in INTRINSIC_NAMES.iter().enumerate() {
            rows.push(FittedIntrinsic {
                name: format!("{} {name}", spec.name),
                nominal: nominal[index],
                calibrated: fitted[index],
                std_dev: std.of(Unknown::Intrinsic { camera, index }),
            });
        }
    }
    rows
}

/// Every parameter of the robot's own model, by name.
fn robot_parameters(
    setup: &Setup,
    fit: &CameraFitReport,
    std: &StdDevs<'_>,
) -> Result<Vec<RobotParameter>> {
    let robot = setup.rig.robot_model(&fit.model)?;
    let nominal = setup.augmented.parameters();
    let fitted = fit.model.parameters();
    Ok((0..robot.parameter_count())
        .map(|i| {
            let p = setup.rig.augmented_index(&robot, i);
            let k = fit
                .unknowns
                .iter()
                .position(|u| *u == Unknown::Parameter(p));
            RobotParameter {
                name: robot.parameter_name(&setup.tree, i),
                nominal: nominal[p],
                calibrated: fitted[p],
                std_dev: std.parameter(p),
                determined: k.is_some_and(|k| fit.identifiable[k]),
                held: k.is_none(),
            }
        })
        .collect())
}
