//! The outputs of `calibrate` validated as written: the exported URDF text is re-read and
//! scored on every validation row alone (with the written registration when the frame was
//! fitted) and with its compensation file; when the URDF alone is worse than the registered
//! nominal robot, the best rigid-only geometry (fitted to what the compensated model predicts
//! at the identification configurations) is exported instead, and the compensated geometry
//! is kept beside it (`docs/calibration.md`, "Outputs"). How a URDF is scored is
//! `artifact_scoring`.

use super::artifact_joint_errors::{
    without_joint_angle_terms, AppliedJointErrors, JOINT_ERRORS_FILE,
};
use super::artifact_scoring::{exported_links, CompensationFile, Scoring};
use super::calibrate_config::CalibrateConfig;
use super::calibrate_steps::{joint_errors_yaml, Data, Identified, Loaded};
use crate::calibration::{calibrate as run_plan, ChosenFrame, Compensation, ErrorSummary, Finding};
use crate::error::Result;
use crate::io::parse_registration;
use crate::kinematics::{FlexibilityModel, McpcModel};
use crate::math::{rpy_from_rotation, Pose};
use crate::measurement::{Measurement, Observation};
use crate::report::{ArtifactReport, ArtifactScore, UnobservableBase};
use crate::urdf::{export_urdf_with, ExportOptions, ExportReport};

/// The registration `calibrate` writes when it fits the measurement frame.
pub const REGISTRATION_FILE: &str = "registration.yaml";

/// The calibrated geometry to use with the compensation file, when `calibrated.urdf` holds
/// the rigid-only geometry instead.
pub const COMPENSATED_URDF: &str = "calibrated_compensated.urdf";

/// What the artifact step decided and found.
pub(super) struct Artifact {
    /// The report block.
    pub report: ArtifactReport,
    /// `registration.yaml`, when the frame was fitted.
    pub registration: Option<String>,
    /// The URDF to write as `calibrated.urdf` when it is not the export's (the rigid-only
    /// geometry), and the export's text to write as [`COMPENSATED_URDF`].
    pub replaced: Option<(ExportReport, String)>,
    /// Findings for the verdict.
    pub findings: Vec<Finding>,
}

/// `world_from_base` as a registration file `--measurement-frame FILE` reads, in m and rad
/// at full precision.
pub fn registration_text(world_from_base: &Pose, robot: &str) -> String {
    let t = world_from_base.translation.vector;
    let rpy = rpy_from_rotation(&world_from_base.rotation);
    format!(
        "# Robot '{robot}': where calibrated.urdf's root link frame is in the measurement (tracker) frame,\n# fitted by `treecal calibrate`. calibrated.urdf + this file reproduce the validation figures of\n# report.md; `treecal calibrate --measurement-frame registration.yaml` reads it.\nunits: {{length: m, angle: rad}}\nxyz: [{:?}, {:?}, {:?}]\nrpy: [{:?}, {:?}, {:?}]\n",
        t.x, t.y, t.z, rpy[0], rpy[1], rpy[2]
    )
}

/// The rigid model closest to what the compensated model predicts at the identification
/// configurations (the deflections of `flexibility`, the joint-angle terms of the model): the
/// plan run on those predictions, without compensation and with the joint-angle terms frozen
/// at zero.
fn rigid_equivalent(
    loaded: &Loaded,
    identified: &Identified,
    flexibility: Option<&FlexibilityModel>,
    measurements: &[Measurement],
) -> Result<McpcModel> {
    let model = &identified.run.report.model;
    let tree = loaded.robot.tree();
    let predicted = measurements
        .iter()
        .map(|m| {
            let pose = match flexibility {
                Some(f) => f
                    .for_payload(m.payload)?
                    .deflected_tool_poses(tree, model, &m.q)?[m.tool],
                None => model.tool_poses(&m.q)[m.tool],
            };
            let observation = match &m.observation {
                Observation::Pose(_) => Observation::Pose(pose),
                Observation::Position(_) => Observation::Position(pose.translation.vector),
                Observation::Contact(contact) => Observation::Contact(contact.clone()),
            };
            Ok(Measurement {
                observation,
                ..m.clone()
            })
        })
        .collect::<Result<Vec<_>>>()?;
    let (start, frozen) = without_joint_angle_terms(model)?;
    let mut options = crate::calibration::IdentificationOptions {
        observation_weights: Vec::new(),
        ..identified.options.clone()
    };
    options.frozen.extend(frozen);
    options.frozen.sort_unstable();
    options.frozen.dedup();
    Ok(run_plan(
        &loaded.branches,
        &start,
        &predicted,
        Compensation::None,
        &identified.plan,
        &options,
    )?
    .model)
}

/// The registered nominal robot's validation error (the run's "before"), over every row.
fn registered_nominal(identified: &Identified) -> Option<ArtifactScore> {
    let arms = &identified.run.validation;
    let position: Vec<f64> = arms.iter().flat_map(|a| a.position_mm[0].clone()).collect();
    let orientation: Vec<f64> = arms
        .iter()
        .flat_map(|a| a.orientation_deg[0].clone())
        .collect();
    (!position.is_empty()).then(|| ArtifactScore {
        files: "the nominal URDF, registered (\"before\")".into(),
        observations: position.len(),
        errors: ErrorSummary::of(&position, &orientation),
    })
}

/// What the data cannot see with a fitted frame: the exported root against the registered
/// nominal robot's root, and how far that moves the tool positions in the root frame.
fn unobservable_base(loaded: &Loaded, identified: &Identified, data: &Data) -> UnobservableBase {
    let run = &identified.run;
    let calibrated = run.report.model.world_from_base();
    let registered = run.baseline.world_from_base();
    let root_change = registered.inverse() * calibrated;
    let mut shifts: Vec<f64> = data
        .measurements
        .iter()
        .map(|m| {
            let p = run.report.model.tool_poses(&m.q)[m.tool].translation.vector;
            let in_root = calibrated.inverse_transform_point(&p.into());
            (root_change.transform_point(&in_root) - in_root).norm() * 1e3
        })
        .collect();
    shifts.sort_by(f64::total_cmp);
    let tree = loaded.robot.tree();
    let first: Vec<String> = run
        .report
        .model
        .frames()
        .iter()
        .filter(|f| f.parent.is_none())
        .map(|f| tree.joint(f.joint).name.clone())
        .collect();
    UnobservableBase {
        transform: format!(
            "the transform from the robot's base link '{}' to its first joint{} ({})",
            tree.link(crate::tree::LinkId(0)).name,
            if first.len() == 1 { "" } else { "s" },
            first.join(", ")
        ),
        translation_mm: root_change.translation.vector.norm() * 1e3,
        rotation_deg: root_change.rotation.angle().to_degrees(),
        tool_shift_mm: [
            shifts.first().copied().unwrap_or(0.0),
            shifts.last().copied().unwrap_or(0.0),
        ],
    }
}

/// Scores the outputs as written; with compensation and a URDF alone worse than the
/// registered nominal robot, exports the rigid-only geometry instead.
pub(super) fn assess(
    config: &CalibrateConfig,
    loaded: &Loaded,
    data: &Data,
    identified: &Identified,
    export: Option<&ExportReport>,
    compensation: Option<CompensationFile<'_>>,
) -> Result<Artifact> {
    let run = &identified.run;
    let fitted = run.frame.chosen == ChosenFrame::Fitted;
    let world_from_base = run.report.model.world_from_base();
    let robot = loaded.robot.tree().name();
    let registration = fitted.then(|| registration_text(&world_from_base, robot));
    let frame = match &registration {
        Some(text) => parse_registration(text, REGISTRATION_FILE)?,
        None => world_from_base,
    };
    let registered = registered_nominal(identified);
    // From a reference link behind joints (a sole), what the frame absorbs is that link's
    // placement, not the root's: the `reference-gauge` note says it, this one would mislead.
    let measured_from_root = run.report.model.reference_chain().is_empty();
    let unobservable =
        (fitted && measured_from_root).then(|| unobservable_base(loaded, identified, data));
    let mut findings: Vec<Finding> = unobservable.iter().map(unobservable_finding).collect();
    let mut report = ArtifactReport {
        registration: registration.as_ref().map(|_| REGISTRATION_FILE.to_owned()),
        urdf_alone: None,
        with_compensation: None,
        registered_nominal: registered.clone(),
        how_to_use: String::new(),
        unobservable_base: unobservable,
    };
    let (Some(export), false) = (export, data.validation.is_empty()) else {
        report.how_to_use = how_to_use(fitted, None, false, false);
        return Ok(Artifact {
            report,
            registration,
            replaced: None,
            findings,
        });
    };
    let written = Written {
        config,
        loaded,
        data,
        identified,
        fitted,
        frame,
        before: registered.as_ref().map(|r| r.errors.rms_position_mm),
        set_aside: crate::calibration::validation_set_aside(&identified.run),
    };
    let scores = written.score(export, compensation.as_ref())?;
    findings.extend(scores.findings);
    report.urdf_alone = Some(scores.urdf_alone);
    report.with_compensation = scores.with_compensation;
    report.how_to_use = scores.how_to_use;
    Ok(Artifact {
        report,
        registration,
        replaced: scores.replaced,
        findings,
    })
}

/// What [`assess`] scores the written outputs against: the run, its data, and the frame the
/// URDF is placed in (the written registration when the frame was fitted).
struct Written<'a> {
    config: &'a CalibrateConfig,
    loaded: &'a Loaded,
    data: &'a Data,
    identified: &'a Identified,
    /// Whether the measurement frame was fitted (registration.yaml is written).
    fitted: bool,
    frame: Pose,
    /// The registered nominal robot's RMS validation position error (mm), if there are rows.
    before: Option<f64>,
    /// Per validation row: whether the comparisons with `before` leave it out (a few rows
    /// flagged as outliers, [`crate::calibration::validation_set_aside`]); every row still
    /// counts in the scores reported.
    set_aside: Vec<bool>,
}

/// A URDF's RMS validation position error and the registered nominal robot's, over the rows
/// the comparisons judge (mm), and the rows they left out.
#[derive(Clone, Copy)]
struct Judged {
    rms: f64,
    before: f64,
    set_aside: usize,
}

/// The scores of the written outputs and what they decided.
struct Scores {
    urdf_alone: ArtifactScore,
    with_compensation: Option<ArtifactScore>,
    /// See [`Artifact::replaced`].
    replaced: Option<(ExportReport, String)>,
    findings: Vec<Finding>,
    how_to_use: String,
}

impl Written<'_> {
    /// `urdf` with `registration.yaml` named beside it when the frame was fitted.
    fn with_registration(&self, urdf: &str) -> String {
        if self.fitted {
            format!("{urdf} + {REGISTRATION_FILE}")
        } else {
            urdf.to_owned()
        }
    }

    /// Scores `export` alone and with its companion files (the compensation file, when a
    /// stiffness was in play, and joint_errors.yaml); with a companion and the URDF alone
    /// worse than the registered nominal robot, replaces it by the rigid-only geometry.
    fn score(
        &self,
        export: &ExportReport,
        compensation: Option<&CompensationFile<'_>>,
    ) -> Result<Scores> {
        let (loaded, run) = (self.loaded, &self.identified.run);
        let scoring = Scoring {
            loaded,
            world_from_base: self.frame,
            scored_links: exported_links(loaded, export),
            joint_errors: None,
        };
        // Rows of other sessions are placed in the training frame, as the run scored them.
        let validation = &crate::calibration::validation_in_training_frames(
            &self.data.validation,
            run.sessions.as_ref(),
        );
        let gravity = self.config.gravity_frame;
        let alone_name = self.with_registration("calibrated.urdf");
        let mut alone = scoring.score(&export.urdf, &alone_name, validation, None, gravity)?;
        let mut replaced = None;
        let mut findings = Vec::new();
        let mut with_compensation = None;
        let joint_errors = joint_errors_yaml(loaded.robot.tree(), &run.report.model)
            .map(|text| AppliedJointErrors::read(&text, loaded))
            .transpose()?;
        let stiffness = match (&self.identified.flexibility, compensation) {
            (Some(flexibility), Some(source)) => Some((flexibility, source)),
            _ => None,
        };
        let compensation_name = compensation.map(CompensationFile::name);
        let compensation_file = compensation_name.as_deref().filter(|_| stiffness.is_some());
        let files: Vec<&str> = compensation_file
            .into_iter()
            .chain(joint_errors.as_ref().map(|_| JOINT_ERRORS_FILE))
            .collect();
        let companion = (!files.is_empty()).then(|| files.join(" + "));
        let judged_rows = self.judged_rows(validation);
        let mut judged = self.judged(&alone, export, &alone_name, judged_rows.as_deref())?;
        if let Some(file) = &companion {
            let worse = judged.filter(|j| j.rms > j.before);
            let compensated_name = if worse.is_some() {
                COMPENSATED_URDF
            } else {
                "calibrated.urdf"
            };
            let with_terms = Scoring {
                joint_errors: joint_errors.as_ref(),
                ..scoring
            };
            let compensated = with_terms.score(
                &export.urdf,
                &format!("{} + {file}", self.with_registration(compensated_name)),
                validation,
                stiffness.map(|(_, source)| source),
                gravity,
            )?;
            if let Some(alone_judged) = worse {
                let flexibility = stiffness.map(|(f, _)| f);
                let (rigid_export, rigid_alone) =
                    self.rigid_only(flexibility, &alone_name, validation)?;
                findings.push(rigid_only_finding(
                    file,
                    [&alone, &rigid_alone, &compensated],
                    alone_judged,
                ));
                judged = self.judged(
                    &rigid_alone,
                    &rigid_export,
                    &alone_name,
                    judged_rows.as_deref(),
                )?;
                replaced = Some((rigid_export, export.urdf.clone()));
                alone = rigid_alone;
            }
            with_compensation = Some(compensated);
        }
        findings.extend(alone_worse_finding(&alone, judged, companion.as_deref()));
        let how_to_use = how_to_use(
            self.fitted,
            compensation_file,
            joint_errors.is_some(),
            replaced.is_some(),
        );
        Ok(Scores {
            urdf_alone: alone,
            with_compensation,
            replaced,
            findings,
            how_to_use,
        })
    }

    /// The validation rows (as scored) the comparisons judge, when some are set aside.
    fn judged_rows(&self, validation: &[Measurement]) -> Option<Vec<Measurement>> {
        self.set_aside.iter().any(|&f| f).then(|| {
            validation
                .iter()
                .zip(&self.set_aside)
                .filter(|(_, &aside)| !aside)
                .map(|(m, _)| m.clone())
                .collect()
        })
    }

    /// `urdf` alone (scored `score` over every row) against the registered nominal robot, over
    /// the judged rows (`judged_rows`; every row when `None`).
    fn judged(
        &self,
        score: &ArtifactScore,
        export: &ExportReport,
        name: &str,
        judged_rows: Option<&[Measurement]>,
    ) -> Result<Option<Judged>> {
        let Some(before) = self.before else {
            return Ok(None);
        };
        let Some(rows) = judged_rows else {
            return Ok(Some(Judged {
                rms: score.errors.rms_position_mm,
                before,
                set_aside: 0,
            }));
        };
        let scoring = Scoring {
            loaded: self.loaded,
            world_from_base: self.frame,
            scored_links: exported_links(self.loaded, export),
            joint_errors: None,
        };
        let rms = scoring
            .score(&export.urdf, name, rows, None, self.config.gravity_frame)?
            .errors
            .rms_position_mm;
        Ok(Some(Judged {
            rms,
            before: judged_before(&self.identified.run, &self.set_aside),
            set_aside: self.set_aside.iter().filter(|&&f| f).count(),
        }))
    }

    /// The rigid-only geometry's URDF and its score alone (named `alone_name`).
    fn rigid_only(
        &self,
        flexibility: Option<&FlexibilityModel>,
        alone_name: &str,
        validation: &[Measurement],
    ) -> Result<(ExportReport, ArtifactScore)> {
        let (loaded, identified) = (self.loaded, self.identified);
        let rigid = rigid_equivalent(loaded, identified, flexibility, &self.data.measurements)?;
        let rigid_export = export_rigid(self.config, loaded, &rigid)?;
        let rigid_scoring = Scoring {
            scored_links: exported_links(loaded, &rigid_export),
            loaded,
            world_from_base: self.frame,
            joint_errors: None,
        };
        let gravity = self.config.gravity_frame;
        let score =
            rigid_scoring.score(&rigid_export.urdf, alone_name, validation, None, gravity)?;
        Ok((rigid_export, score))
    }
}

/// The `rigid-only-urdf` note: the calibrated geometry alone, the rigid-only geometry alone
/// and the calibrated geometry with `file` (`scores` in that order), against `before`.
fn rigid_only_finding(file: &str, scores: [&ArtifactScore; 3], judged: Judged) -> Finding {
    let [_, rigid_alone, compensated] = scores.map(|s| s.errors.rms_position_mm);
    let (rows, every) = if judged.set_aside == 0 {
        ("on the validation rows".to_owned(), "")
    } else {
        (
            format!(
                "on the validation rows without the {} gross blunder(s)",
                judged.set_aside
            ),
            ", every row",
        )
    };
    Finding::note(
        "rigid-only-urdf",
        format!(
            "the calibrated geometry used without {file} is {:.3} mm RMS {rows}, worse than the registered nominal robot ({:.3} mm): calibrated.urdf holds instead the rigid-only geometry fitted to what the compensated model predicts at the identification configurations ({rigid_alone:.3} mm alone{every}); the compensated geometry is {COMPENSATED_URDF}, to be used only with {file} ({compensated:.3} mm{every})",
            judged.rms, judged.before,
        ),
    )
}

/// The registered nominal robot's RMS validation position error (mm) over the rows not set
/// aside.
fn judged_before(run: &crate::calibration::CalibrationRun, set_aside: &[bool]) -> f64 {
    let values: Vec<f64> = run
        .validation
        .iter()
        .flat_map(|arm| arm.rows.iter().zip(&arm.position_mm[0]))
        .filter(|(&row, _)| !set_aside.get(row).copied().unwrap_or(false))
        .map(|(_, &v)| v)
        .collect();
    crate::math::root_mean_square(&values).unwrap_or(0.0)
}

/// The `urdf-alone-worse` warning, when the URDF alone (`alone`, judged as `judged`) is
/// clearly worse than the registered nominal robot; `companion` the files it must go with.
fn alone_worse_finding(
    alone: &ArtifactScore,
    judged: Option<Judged>,
    companion: Option<&str>,
) -> Option<Finding> {
    let judged = judged.filter(|j| clearly_worse(j.rms, j.before))?;
    let rows = if judged.set_aside == 0 {
        "on the validation rows".to_owned()
    } else {
        format!(
            "on the validation rows without the {} gross blunder(s)",
            judged.set_aside
        )
    };
    Some(Finding::warning(
        "urdf-alone-worse",
        format!(
            "calibrated.urdf used alone ({}) is {:.3} mm RMS {rows}, worse than the registered nominal robot ({:.3} mm): do not use it alone{}",
            alone.files,
            judged.rms,
            judged.before,
            companion.map_or(String::new(), |f| format!("; it must accompany {f}"))
        ),
    ))
}

/// Whether an RMS error (mm) is worse than the registered nominal robot's beyond what the
/// noise of fitting moves it: more than 5 % and more than 0.01 mm (a tracker's noise floor). A
/// tie — the nominal robot already exact and the calibration fitting only noise — is not worse
/// (no warning); the rigid-only replacement above still acts on any excess.
fn clearly_worse(rms_mm: f64, nominal_mm: f64) -> bool {
    rms_mm > 1.05 * nominal_mm && rms_mm - nominal_mm > 0.01
}

/// The `unobservable-base` note.
fn unobservable_finding(base: &UnobservableBase) -> Finding {
    Finding::note(
        "unobservable-base",
        format!(
            "the measurement frame was fitted, so {} cannot be seen: calibrated.urdf's root is the fitted (tracker-side) frame, not the physical base; it lies {:.2} mm and {:.3}° from the registered nominal robot's root, which moves the tool positions in the URDF's own root frame by {:.2}–{:.2} mm over the measured configurations. Use calibrated.urdf with {REGISTRATION_FILE} (written beside it; `measurement_frame` {REGISTRATION_FILE} reads it) to reproduce the validated figures, or measure in the robot's base frame",
            base.transform,
            base.translation_mm,
            base.rotation_deg,
            base.tool_shift_mm[0],
            base.tool_shift_mm[1]
        ),
    )
}

/// The URDF of the rigid-only geometry `rigid` (its joint zero offsets in the joint origins).
fn export_rigid(
    config: &CalibrateConfig,
    loaded: &Loaded,
    rigid: &McpcModel,
) -> Result<ExportReport> {
    let tree = loaded.robot.tree();
    let rigid = rigid.with_offsets_absorbed();
    let std_devs = vec![None; rigid.parameter_count()];
    let options = ExportOptions::with_uncertainty(tree, &rigid, &std_devs, config.add_tool_links);
    export_urdf_with(
        &loaded.robot.text,
        &loaded.robot.origin,
        tree,
        &rigid,
        &options,
    )
}

/// How a user applies the outputs, in words: `stiffness_file` the compensation file of the
/// deflections, `joint_errors` whether joint_errors.yaml goes with the URDF, `rigid_only`
/// whether calibrated.urdf holds the rigid-only geometry.
fn how_to_use(
    fitted: bool,
    stiffness_file: Option<&str>,
    joint_errors: bool,
    rigid_only: bool,
) -> String {
    let mut text = String::from("calibrated.urdf replaces the robot's URDF");
    if fitted {
        text.push_str(&format!(
            "; its root link sits at {REGISTRATION_FILE} in the measurement frame (to compare with tracker data, place the root there)"
        ));
    }
    let mut parts = Vec::new();
    if let Some(file) = stiffness_file {
        parts.push(format!(
            "{file} predicts the deflections under gravity (treecal's flexibility model: the URDF, `stiffness` {file})"
        ));
    }
    if joint_errors {
        parts.push(format!(
            "{JOINT_ERRORS_FILE} holds the joint-angle errors, added to the commanded joint angles before the URDF's kinematics"
        ));
    }
    if !parts.is_empty() {
        let companion = parts.join("; ");
        if rigid_only {
            text.push_str(&format!(
                ". It holds the rigid-only geometry (for controllers that model neither); {COMPENSATED_URDF} with the files named here is the better prediction: {companion}"
            ));
        } else {
            text.push_str(&format!(
                ". Its geometry assumes the files named here are applied with it: {companion}; used alone it gives the \"alone\" figure"
            ));
        }
    }
    text.push('.');
    text
}
