//! `verify`: a calibration as deployed (its URDF, with its registration and compensation
//! file when it has them) scored on fresh measurements: per-row and summary errors, the strata
//! of the rows against the calibrated ranges, the worst row, and a verdict against a tolerance.
//!
//! One code path with `calibrate`'s validation: the predictions are
//! `artifact_scoring::Scoring::predict`'s, the row errors
//! `artifact_scoring::row_errors`, the strata
//! [`crate::calibration::ChainPostures::stratum`] on the postures report.json
//! records, the figures [`crate::report::ValidationStrata::of_rows`]. Only the
//! nuisance a fresh session needs is refitted: its measurement frame (six parameters per
//! session), or nothing with [`VerifyFrame::Registration`] (docs/workflows.md, "Verify").

use super::artifact_scoring::{row_errors, CompensationFile, Scoring};
use super::calibrate_artifact::REGISTRATION_FILE;
use super::calibrate_config::{CalibrateConfig, GravityFrame};
use super::calibrate_steps::Loaded;
use super::note::Note;
use super::postures::{chains_of, RecordedPostures, POSTURES_KEY};
use super::report_json::read_calibration_report;
use super::source::{MeasurementSource, RobotSource, StiffnessSource};
use crate::calibration::IdentificationOptions;
use crate::calibration::{
    fit_session_frame_robust, gross_blunders, Sessions, FRAME_BLOCK_PARAMETERS,
};
use crate::calibration::{ChainPostures, Stratum};
use crate::error::{Error, Result};
use crate::io::{read_registration, AngleUnit, LengthUnit, MeasurementReadOptions};
use crate::math::Pose;
use crate::measurement::Measurement;
use crate::report::{VerifyReport, VerifyRow, VerifySession};
use crate::tree::KinematicTree;
use std::path::{Path, PathBuf};

/// The files [`Verification::write`] writes.
pub const VERIFY_FILES: [&str; 5] = [
    "report.md",
    "report.html",
    "report.json",
    "errors.svg",
    "provenance.yaml",
];

/// How the measurement frame of the fresh rows is found.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum VerifyFrame {
    /// Refitted per session (six parameters each), the geometry fixed: a tracker set up
    /// anew.
    #[default]
    Fit,
    /// The calibration's registration as written: nothing refitted (the tracker not moved).
    Registration,
    /// The rows are in the URDF's root link frame: nothing refitted.
    Base,
}

impl VerifyFrame {
    /// `fit`, `registration` or `base`.
    pub fn as_str(self) -> &'static str {
        match self {
            VerifyFrame::Fit => "fit",
            VerifyFrame::Registration => "registration",
            VerifyFrame::Base => "base",
        }
    }
}

/// Everything a verification needs; `Default` holds the CLI's defaults (the measurements and
/// the calibration or the robot must be set).
#[derive(Debug, Clone, PartialEq)]
pub struct VerifyConfig {
    /// A `calibrate` output folder: its calibrated.urdf, registration.yaml, stiffness.yaml
    /// (when written) and report.json (the calibrated ranges) are used unless given below.
    pub calibration: Option<PathBuf>,
    /// The deployed URDF [default: the calibration's calibrated.urdf, or with a compensation
    /// file its calibrated_compensated.urdf when there is one].
    pub robot: Option<PathBuf>,
    /// The registration (the URDF root in the measurement frame) [default: the calibration's
    /// registration.yaml when there is one].
    pub registration: Option<PathBuf>,
    /// The compensation (stiffness) file [default: the calibration's stiffness.yaml when
    /// there is one, else rigid].
    pub stiffness: Option<StiffnessSource>,
    /// The fresh measurements.
    pub measurements: MeasurementSource,
    /// Tool links [default: the measured tools].
    pub tools: Option<Vec<String>>,
    /// Unit of lengths in the measurements [default: as stated, else m].
    pub length_unit: Option<LengthUnit>,
    /// Unit of revolute joint values [default: as stated, else rad].
    pub angle_unit: Option<AngleUnit>,
    /// Unit of prismatic joint values [default: the length unit].
    pub joint_length_unit: Option<LengthUnit>,
    /// How the measurement frame is found.
    pub frame: VerifyFrame,
    /// The frame of the stiffness file's gravity vector.
    pub gravity_frame: GravityFrame,
    /// Position noise (m) weighting the frame fit of measured poses.
    pub position_sigma: f64,
    /// Rotation noise (rad) weighting the frame fit of measured poses.
    pub rotation_sigma: f64,
    /// The largest acceptable RMS position error over all rows (mm) [default: no verdict].
    pub max_error_mm: Option<f64>,
}

impl Default for VerifyConfig {
    fn default() -> Self {
        Self {
            calibration: None,
            robot: None,
            registration: None,
            stiffness: None,
            measurements: MeasurementSource::default(),
            tools: None,
            length_unit: None,
            angle_unit: None,
            joint_length_unit: None,
            frame: VerifyFrame::Fit,
            gravity_frame: GravityFrame::Measurement,
            position_sigma: crate::calibration::DEFAULT_POSITION_SIGMA,
            rotation_sigma: crate::calibration::DEFAULT_ROTATION_SIGMA,
            max_error_mm: None,
        }
    }
}

/// The outcome of a verification.
#[derive(Debug, Clone)]
pub struct Verification {
    /// report.json's content.
    pub report: VerifyReport,
    /// report.md.
    pub markdown: String,
    /// What the CLI prints on stderr.
    pub notes: Vec<Note>,
    /// Every output file: `(name, bytes)`.
    pub files: Vec<(String, Vec<u8>)>,
    /// The input files it read (the writers refuse to replace them).
    pub inputs: Vec<PathBuf>,
}

impl Verification {
    /// Whether the RMS position error is within `--max-error` (true without a tolerance).
    pub fn passed(&self) -> bool {
        self.report.verdict.passed
    }

    /// Replaces the folder `out` with the output files; refuses a folder holding an input or
    /// files that are not a previous verify output.
    pub fn write(&self, out: &Path) -> Result<()> {
        let inputs: Vec<&Path> = self.inputs.iter().map(PathBuf::as_path).collect();
        super::checks::check_outputs(&[super::checks::Output::Folder(out)], &inputs)?;
        crate::io::check_output_folder(out, &is_output_file)?;
        crate::io::replace_folder(out, &self.files)
    }
}

/// Whether a file name is one `verify` writes.
pub fn is_output_file(name: &str) -> bool {
    VERIFY_FILES.contains(&name)
}

/// The files a verification reads, resolved from the calibration folder where not given.
#[derive(Debug, Clone)]
struct Resolved {
    robot: PathBuf,
    registration: Option<PathBuf>,
    stiffness: Option<StiffnessSource>,
    report: Option<PathBuf>,
}

fn invalid(origin: &str, message: impl Into<String>) -> Error {
    Error::InvalidData {
        origin: origin.to_owned(),
        message: message.into(),
    }
}

fn resolve(config: &VerifyConfig) -> Result<Resolved> {
    let existing = |name: &str| {
        config
            .calibration
            .as_ref()
            .map(|dir| dir.join(name))
            .filter(|p| p.is_file())
    };
    if let Some(dir) = &config.calibration {
        if !dir.is_dir() {
            return Err(invalid(
                &dir.display().to_string(),
                "not a folder: give the output folder of `treecal calibrate` (--out)",
            ));
        }
    }
    let stiffness = config
        .stiffness
        .clone()
        .or_else(|| existing("stiffness.yaml").map(StiffnessSource::File));
    let robot = match (&config.robot, &stiffness) {
        (Some(path), _) => path.clone(),
        (None, Some(_)) => existing(super::calibrate_artifact::COMPENSATED_URDF)
            .or_else(|| existing("calibrated.urdf"))
            .ok_or_else(|| no_robot(config))?,
        (None, None) => existing("calibrated.urdf").ok_or_else(|| no_robot(config))?,
    };
    Ok(Resolved {
        robot,
        registration: config
            .registration
            .clone()
            .or_else(|| existing(REGISTRATION_FILE)),
        stiffness,
        report: existing("report.json"),
    })
}

/// A warning for each file read from the calibration folder that is not the file `calibrate`
/// wrote there (its SHA-256 against provenance.yaml's `outputs`): edited or replaced after the
/// calibration, so the figures score something that was never validated.
fn changed_since_written(config: &VerifyConfig, files: &Resolved) -> Result<Vec<Note>> {
    let Some(dir) = &config.calibration else {
        return Ok(Vec::new());
    };
    let record = dir.join(super::provenance::PROVENANCE_FILE);
    if !record.is_file() {
        return Ok(Vec::new());
    }
    let origin = record.display().to_string();
    let text = crate::io::read_text(&record, crate::limits::MAX_YAML_BYTES)?;
    let written = crate::io::recorded_outputs(&text, &origin)?;
    let mut read: Vec<&Path> = vec![&files.robot];
    read.extend(files.registration.as_deref());
    if let Some(StiffnessSource::File(path)) = &files.stiffness {
        read.push(path);
    }
    let mut notes = Vec::new();
    for path in read
        .into_iter()
        .filter(|p| p.parent() == Some(dir.as_path()))
    {
        let Some(recorded) = path
            .file_name()
            .and_then(|name| written.get(name.to_string_lossy().as_ref()))
        else {
            continue;
        };
        let now = crate::io::input_file(path)?.sha256;
        if &now != recorded {
            notes.push(Note::warning(format!(
                "{} is not the file `calibrate` wrote (SHA-256 {}…, {origin} records {}…): it \
                 was edited or replaced after the calibration, so these figures score a file \
                 that was never validated; calibrate again, or verify the file calibrate wrote",
                path.display(),
                &now[..12],
                recorded.get(..12).unwrap_or(recorded),
            )));
        }
    }
    Ok(notes)
}

fn no_robot(config: &VerifyConfig) -> Error {
    match &config.calibration {
        Some(dir) => invalid(
            &dir.display().to_string(),
            "holds no calibrated.urdf (a failed verdict writes none): give the deployed URDF with `robot`",
        ),
        None => invalid(
            "verify",
            "no robot: give `calibration` (a calibrate output folder) or `robot` (the deployed URDF)",
        ),
    }
}

/// A warning when the calibration's headline figure came with a compensation file this
/// verification does not have: calibrate compensated with the user's own stiffness file
/// (which stays outside the output folder) and verify, given no `stiffness`, scores the URDF
/// rigid, which can be far worse (the built-in Robonaut's example: 0.09 mm compensated,
/// 54 mm rigid). The warning names what the calibration validated.
fn rigid_where_compensated(files: &Resolved, report: Option<&serde_json::Value>) -> Option<Note> {
    let (None, Some(report)) = (&files.stiffness, report) else {
        return None;
    };
    let with = &report["artifact"]["with_compensation"];
    let validated = with["files"].as_str()?;
    let figure = |value: &serde_json::Value| {
        value["errors"]["rms_position_mm"]
            .as_f64()
            .map_or_else(String::new, |rms| format!(" ({rms:.3} mm)"))
    };
    let advice = if validated.contains("joint_errors.yaml") {
        "verify does not apply joint_errors.yaml: its figures compare with the URDF alone"
    } else {
        "give `stiffness` with the stiffness file the calibration used to verify what was \
         validated"
    };
    Some(Note::warning(format!(
        "the calibration was validated as {validated}{}, but no compensation is applied \
         here: this verification scores the URDF rigid, like {} alone{} in the calibration; \
         {advice}",
        figure(with),
        report["artifact"]["urdf_alone"]["files"]
            .as_str()
            .unwrap_or("the URDF"),
        figure(&report["artifact"]["urdf_alone"]),
    )))
}

/// The recorded identification postures of a report.json read from `path`.
pub(crate) fn postures_of(
    json: &serde_json::Value,
    path: &Path,
) -> Result<Option<RecordedPostures>> {
    let origin = path.display().to_string();
    json.get(POSTURES_KEY)
        .map(|v| serde_json::from_value(v.clone()).map_err(|e| invalid(&origin, e.to_string())))
        .transpose()
}

/// Verifies: reads the deployed files and the fresh rows, predicts every row, refits the
/// measurement frame when asked, and renders the reports. Writes nothing.
pub fn verify(config: &VerifyConfig) -> Result<Verification> {
    let started = super::provenance::Started::now();
    super::checks::sigmas(config.position_sigma, config.rotation_sigma)?;
    if let Some(max) = config.max_error_mm.filter(|m| !(m.is_finite() && *m > 0.0)) {
        return Err(Error::setting(
            "max_error",
            format!("{max} must be a positive number of mm"),
        ));
    }
    let files = resolve(config)?;
    let changed = changed_since_written(config, &files)?;
    let calibrate_config = CalibrateConfig {
        robot: RobotSource::File(files.robot.clone()),
        measurements: config.measurements.clone(),
        tools: config.tools.clone(),
        ..CalibrateConfig::default()
    };
    let loaded = Loaded::new(&calibrate_config)?;
    let mut notes = changed;
    notes.extend(loaded.robot.notes());
    notes.extend(loaded.points.note());
    let tree = loaded.robot.tree();
    let options = MeasurementReadOptions {
        length_unit: config.length_unit,
        angle_unit: config.angle_unit,
        joint_length_unit: config.joint_length_unit,
        ignore_columns: Vec::new(),
        strict_limits: false,
        tool: config
            .tools
            .as_ref()
            .filter(|t| t.len() == 1)
            .map(|t| t[0].trim().to_owned()),
    };
    let set = config.measurements.read(tree, &loaded.nominal, &options)?;
    notes.extend(set.warnings.iter().map(Note::warning));
    notes.extend(set.notes.iter().map(Note::info));
    // report.json is read once (at 10⁶ rows it is ~900 MB): for the warning and the strata.
    let recorded = files
        .report
        .as_ref()
        .map(|path| read_calibration_report(path).map(|report| (path, report)))
        .transpose()?;
    notes.extend(rigid_where_compensated(
        &files,
        recorded.as_ref().map(|(_, r)| r),
    ));
    let frame = measurement_frame(config, &files)?;
    let names = file_names(&files, frame.1.is_some());
    let compensation = files.stiffness.as_ref().map(CompensationFile::Source);
    let scoring = Scoring {
        loaded: &loaded,
        world_from_base: frame.1.unwrap_or_else(Pose::identity),
        scored_links: scored_links(tree, &loaded),
        joint_errors: None,
    };
    let predicted = scoring.predict(
        &loaded.robot.text,
        &names,
        &set.measurements,
        compensation.as_ref(),
        config.gravity_frame,
    )?;
    let (predicted, sessions, outliers) = refit(config, &set.measurements, predicted);
    let chains = match &recorded {
        Some((path, report)) => match postures_of(report, path)? {
            Some(recorded) => Some(chains_of(
                &recorded,
                tree,
                &loaded.nominal,
                &path.display().to_string(),
            )?),
            None => None,
        },
        None => None,
    };
    if chains.is_none() {
        notes.push(Note::info(
            "no calibration record (report.json with identification_postures): the rows are not sorted into strata; give `calibration` with the calibrate output folder",
        ));
    }
    let rows = scored_rows(&loaded, &set, (&predicted, &outliers), chains.as_deref());
    let report = VerifyReport::new(
        crate::report::VerifyContext {
            robot: tree.name().to_owned(),
            files: names,
            measurements: config.measurements.origin(),
            frame: config.frame.as_str().to_owned(),
            refitted_parameters: sessions.len() * FRAME_BLOCK_PARAMETERS,
            sessions,
            strata_judged: chains.is_some(),
        },
        rows,
        config.max_error_mm,
    );
    finish(config, &files, report, notes, started)
}

/// The measurement frame: the registration (asked, or to start the fit from), or none.
fn measurement_frame(
    config: &VerifyConfig,
    files: &Resolved,
) -> Result<(VerifyFrame, Option<Pose>)> {
    match (config.frame, &files.registration) {
        (VerifyFrame::Base, _) => Ok((VerifyFrame::Base, None)),
        (frame, Some(path)) => Ok((frame, Some(read_registration(path)?))),
        (VerifyFrame::Fit, None) => Ok((VerifyFrame::Fit, None)),
        (VerifyFrame::Registration, None) => Err(Error::setting(
            "frame",
            "registration: no registration: the calibration folder holds no registration.yaml (its frame was the robot's root frame: use `frame` base) and none was given with `registration`",
        )),
    }
}

/// How the report names the files used, e.g. `calibrated.urdf + registration.yaml`.
fn file_names(files: &Resolved, registered: bool) -> String {
    let name = |p: &Path| p.display().to_string();
    let mut text = name(&files.robot);
    if let (true, Some(path)) = (registered, &files.registration) {
        text.push_str(&format!(" + {}", name(path)));
    }
    if let Some(stiffness) = &files.stiffness {
        text.push_str(&format!(" + {}", stiffness.origin()));
    }
    text
}

/// Per model tool, the link of the deployed URDF that carries the calibrated tool frame
/// ([`scored_link`]).
fn scored_links(tree: &KinematicTree, loaded: &Loaded) -> Vec<String> {
    loaded
        .nominal
        .tools()
        .iter()
        .map(|tool| scored_link(tree, tool.link))
        .collect()
}

/// The link of a written URDF that carries the calibrated frame of tool link `tool`: a fixed
/// leaf `<tool>_marker` (or `<tool>_calibrated`, written by exports before session 22) below
/// it when the export added one, else the
/// tool link (`calibrate` names the same links from its export report).
pub(crate) fn scored_link(tree: &KinematicTree, tool: crate::tree::LinkId) -> String {
    let name = tree.link(tool).name.clone();
    // A marker first: exported again, an older file's `_calibrated` link is left behind.
    ["marker", "calibrated"]
        .iter()
        .map(|suffix| format!("{name}_{suffix}"))
        .find(|added| {
            tree.link_id(added).is_ok_and(|id| {
                let link = tree.link(id);
                link.child_joints.is_empty()
                    && link
                        .parent_joint
                        .is_some_and(|j| tree.joint(j).parent == tool)
            })
        })
        .unwrap_or(name)
}

/// With [`VerifyFrame::Fit`], each session's frame refitted robustly to its rows (the geometry
/// fixed) and applied to the predictions; the sessions with their frames; per row whether it
/// is a gross blunder (left out of its session's fit and of the verdict).
fn refit(
    config: &VerifyConfig,
    measurements: &[Measurement],
    mut predicted: Vec<Pose>,
) -> (Vec<Pose>, Vec<VerifySession>, Vec<bool>) {
    let options = IdentificationOptions {
        position_sigma: config.position_sigma,
        rotation_sigma: config.rotation_sigma,
        ..IdentificationOptions::default()
    };
    let loss = options.robust;
    if config.frame != VerifyFrame::Fit {
        let measured: Vec<&Measurement> = measurements.iter().collect();
        let outliers = gross_blunders(&predicted, &measured, &options, loss);
        return (predicted, Vec::new(), outliers);
    }
    let groups = Sessions::of(measurements);
    let mut sessions = Vec::new();
    let mut outliers = vec![false; measurements.len()];
    for (s, name) in groups.names.iter().enumerate() {
        let rows: Vec<usize> = (0..measurements.len())
            .filter(|&i| groups.of[i] == s)
            .collect();
        let fit = fit_session_frame_robust(
            &rows.iter().map(|&i| predicted[i]).collect::<Vec<_>>(),
            &rows.iter().map(|&i| &measurements[i]).collect::<Vec<_>>(),
            &options,
            loss,
        );
        for (k, &i) in rows.iter().enumerate() {
            predicted[i] = fit.frame * predicted[i];
            outliers[i] = fit.gross[k];
        }
        sessions.push(VerifySession::new(
            name.clone(),
            rows.len(),
            &fit.frame,
            fit.determined,
        ));
    }
    (predicted, sessions, outliers)
}

/// Every row scored, with its stratum when the calibration's postures are known.
fn scored_rows(
    loaded: &Loaded,
    set: &crate::io::MeasurementSet,
    (predicted, outliers): (&[Pose], &[bool]),
    chains: Option<&[Option<ChainPostures>]>,
) -> Vec<VerifyRow> {
    let tree = loaded.robot.tree();
    let indices: Option<Vec<_>> = chains.map(|c| {
        c.iter()
            .map(|chain| chain.as_ref().map(ChainPostures::index))
            .collect()
    });
    set.measurements
        .iter()
        .zip(predicted)
        .enumerate()
        .map(|(i, (m, pose))| {
            let (position_mm, orientation_deg) = row_errors(m, pose);
            let stratum: Option<Stratum> = indices.as_ref().map(|c| match c.get(m.tool) {
                Some(Some(index)) => index.stratum(&m.q),
                _ => Stratum::Outside,
            });
            VerifyRow {
                id: set.ids[i].clone(),
                index: i,
                tool: tree.link(loaded.nominal.tools()[m.tool].link).name.clone(),
                session: m.session.clone(),
                position_mm,
                orientation_deg,
                stratum,
                outlier: outliers.get(i).copied().unwrap_or(false),
            }
        })
        .collect()
}

/// Renders the files and the provenance.
fn finish(
    config: &VerifyConfig,
    files: &Resolved,
    mut report: VerifyReport,
    mut notes: Vec<Note>,
    started: super::provenance::Started,
) -> Result<Verification> {
    let mut inputs: Vec<PathBuf> = vec![files.robot.clone()];
    inputs.extend(files.registration.clone());
    inputs.extend(
        files
            .stiffness
            .as_ref()
            .and_then(|s| s.path().map(Path::to_owned)),
    );
    inputs.extend(config.measurements.paths().into_iter().map(Path::to_owned));
    inputs.extend(files.report.clone());
    let mut settings = config.clone();
    if let MeasurementSource::Table(table) = &config.measurements {
        settings.measurements = MeasurementSource::Csv(PathBuf::from(&table.origin));
    }
    let provenance = super::provenance::record(
        "verify",
        super::provenance::settings_text(&settings),
        &inputs,
        &[],
        started,
    )?;
    report.provenance = super::provenance::PROVENANCE_FILE.to_owned();
    report.warnings = notes
        .iter()
        .filter(|n| n.level == super::note::NoteLevel::Warning)
        .map(|n| n.text.clone())
        .collect();
    notes.push(Note::info(report.verdict.sentence()));
    let markdown = report.markdown();
    let json = crate::io::to_json(&report)?;
    let svg = report.plot()?;
    let html = crate::report::markdown_page("treecal verify", &markdown, &[&svg]);
    let files = vec![
        ("report.md".to_owned(), markdown.clone().into_bytes()),
        ("report.html".to_owned(), html.into_bytes()),
        ("report.json".to_owned(), json.into_bytes()),
        ("errors.svg".to_owned(), svg.into_bytes()),
        (
            super::provenance::PROVENANCE_FILE.to_owned(),
            provenance.to_yaml()?.into_bytes(),
        ),
    ];
    Ok(Verification {
        report,
        markdown,
        notes,
        files,
        inputs,
    })
}
