//! The named steps of [`super::calibrate::calibrate`]: checking the configuration, reading,
//! identifying, exporting, and rendering the outputs.

use super::calibrate::{CalibrateConfig, GravityFrame, MeasurementFrameChoice};
use super::export::export_notes;
use super::note::Note;
use super::source::{measured_branches, LoadedRobot};
use crate::calibration::identifiability::NamedCombination;
use crate::calibration::robust::DataSet;
use crate::calibration::{
    hold_out_indices, identified_stiffness, identify_stiffness, run_calibration, CalibrationInput,
    CalibrationRun, ChosenFrame, Finding, IdentificationOptions, MeasurementFrame,
    StiffnessOptions, Verdict,
};
use crate::error::{Error, Result};
use crate::io::{read_registration, stiffness_to_yaml, to_json, to_yaml, MeasurementReadOptions};
use crate::kinematics::{FlexibilityModel, McpcModel, Stiffness};
use crate::limits::{check_range, POSITION_SIGMA, ROTATION_SIGMA};
use crate::measurement::Measurement;
use crate::report::{
    calibration_markdown, calibration_plots, calibration_summary, outlier_rows, parameter_file,
    stiffness_markdown, CalibrationContext, CalibrationSummary, StiffnessSummary,
};
use crate::tree::Branches;
use crate::urdf::{export_urdf_with, ExportOptions, ExportReport};

/// Fraction of the configurations held out for validation without validation data.
const HOLD_OUT: f64 = 0.2;

const TOOL_PARAMETERS: [&str; 6] = ["alpha", "beta", "gamma", "x", "y", "z"];

fn invalid(origin: &str, message: String) -> Error {
    Error::InvalidData {
        origin: origin.into(),
        message,
    }
}

/// The σ within their bounds (a tiny σ overflows the weighted cost, a huge one hides every
/// residual) and a positive stiffness prior.
pub(super) fn check_config(config: &CalibrateConfig) -> Result<()> {
    check_range(
        config.position_sigma,
        POSITION_SIGMA,
        "--position-sigma",
        "m",
    )?;
    check_range(
        config.rotation_sigma,
        ROTATION_SIGMA,
        "--rotation-sigma",
        "rad",
    )?;
    let prior = config.stiffness_prior;
    if config.identify_stiffness && !(prior.is_finite() && prior > 0.0) {
        return Err(invalid(
            "--stiffness-prior",
            format!("{prior} must be a positive number"),
        ));
    }
    Ok(())
}

/// The robot with its measured branches and nominal model, and the measurement frame.
pub(super) struct Loaded {
    pub robot: LoadedRobot,
    pub branches: Branches,
    pub nominal: McpcModel,
    pub frame: MeasurementFrame,
}

impl Loaded {
    pub fn new(config: &CalibrateConfig) -> Result<Self> {
        let frame = match &config.measurement_frame {
            MeasurementFrameChoice::Auto => MeasurementFrame::Auto,
            MeasurementFrameChoice::Fit => MeasurementFrame::Fit,
            MeasurementFrameChoice::Base => MeasurementFrame::Base,
            MeasurementFrameChoice::File(path) => MeasurementFrame::Known(read_registration(path)?),
        };
        let robot = config.robot.load()?;
        let branches =
            measured_branches(&robot.import, config.tools.as_deref(), &config.measurements)?;
        let nominal = McpcModel::from_tree(robot.tree(), &branches)?;
        Ok(Self {
            robot,
            branches,
            nominal,
            frame,
        })
    }
}

/// The identification and validation measurements, with their row ids.
pub(super) struct Data {
    pub measurements: Vec<Measurement>,
    pub validation: Vec<Measurement>,
    /// Where the validation data come from, for the report.
    pub validation_source: String,
    /// The row ids of the identification and validation data, for the outlier report.
    pub ids: [Vec<String>; 2],
}

/// Reads the measurements, and the validation data or a seeded held-out fifth.
pub(super) fn read_data(
    config: &CalibrateConfig,
    loaded: &Loaded,
    notes: &mut Vec<Note>,
) -> Result<Data> {
    let options = MeasurementReadOptions {
        length_unit: config.length_unit,
        angle_unit: config.angle_unit,
        joint_length_unit: config.joint_length_unit,
        ignore_columns: config.ignore_columns.clone(),
        strict_limits: config.strict,
    };
    let tree = loaded.robot.tree();
    let mut read = |source: &super::source::MeasurementSource| {
        let set = source.read(tree, &loaded.nominal, &options)?;
        notes.extend(set.warnings.iter().map(Note::warning));
        Ok::<_, Error>((set.measurements, set.ids))
    };
    let (all, all_ids) = read(&config.measurements)?;
    if let Some(source) = &config.validation {
        let (validation, validation_ids) = read(source)?;
        return Ok(Data {
            measurements: all,
            validation,
            validation_source: source.origin(),
            ids: [all_ids, validation_ids],
        });
    }
    let (kept, held) = hold_out_indices(&all, HOLD_OUT, config.seed)?;
    let validation_source = format!(
        "{} of {} observations held out from the measurements (a fifth of the configurations, seed {}; give --validation to use your own)",
        held.len(),
        all.len(),
        config.seed
    );
    notes.push(Note::info(validation_source.clone()));
    let pick = |rows: &[usize]| rows.iter().map(|&i| all[i].clone()).collect();
    let ids = [&kept, &held].map(|rows| rows.iter().map(|&i| all_ids[i].clone()).collect());
    Ok(Data {
        measurements: pick(&kept),
        validation: pick(&held),
        validation_source,
        ids,
    })
}

/// A finished identification and how it was set up.
pub(super) struct Identified {
    pub run: CalibrationRun,
    pub plan_name: String,
    pub options: IdentificationOptions,
}

/// With `--identify-stiffness`: the report's summary and the identified stiffness.
pub(super) type IdentifiedStiffness = Option<(StiffnessSummary, Stiffness)>;

/// Chooses the plan, builds the flexibility model and runs the calibration; with stiffness
/// identification, the joint fit from the calibrated geometry and then the plan again with
/// the identified stiffness, so that every table describes it.
pub(super) fn identify(
    config: &CalibrateConfig,
    loaded: &Loaded,
    data: &Data,
    notes: &mut Vec<Note>,
) -> Result<(Identified, IdentifiedStiffness)> {
    let tree = loaded.robot.tree();
    let labelled = data
        .measurements
        .iter()
        .any(|m| m.stage.as_deref() == Some("torso"));
    let (plan, plan_name, plan_note) = config.plan.resolve(labelled)?;
    notes.extend(plan_note);
    // With stiffness identification and no file, the library defaults are the prior.
    let stiffness = match &config.stiffness {
        Some(source) => Some(source.read(tree, &loaded.nominal)?),
        None => config.identify_stiffness.then(Stiffness::default),
    };
    let flexibility = match &stiffness {
        Some(stiffness) => {
            let model = FlexibilityModel::new(tree, &loaded.nominal, stiffness)?;
            Some(match config.gravity_frame {
                GravityFrame::Measurement => model.with_gravity_in_measurement_frame(),
                GravityFrame::Base => model,
            })
        }
        None => None,
    };
    let options = IdentificationOptions {
        position_sigma: config.position_sigma,
        rotation_sigma: config.rotation_sigma,
        robust: config.robust,
        ..IdentificationOptions::default()
    };
    let input = CalibrationInput {
        tree,
        branches: &loaded.branches,
        nominal: &loaded.nominal,
        flexibility: flexibility.as_ref(),
        plan: &plan,
        options: &options,
        measurement_frame: loaded.frame,
    };
    let mut run = run_calibration(&input, &data.measurements, &data.validation)?;
    let mut identified = None;
    if let (Some(prior), Some(stiffness), true) =
        (&flexibility, &stiffness, config.identify_stiffness)
    {
        let stiffness_options = StiffnessOptions {
            prior_sigma: config.stiffness_prior,
            ..StiffnessOptions::default()
        };
        let free: Vec<usize> = (0..run.report.model.parameter_count()).collect();
        let report = identify_stiffness(
            tree,
            &run.report.model,
            prior,
            &data.measurements,
            None,
            &free,
            &options,
            &stiffness_options,
        )?;
        let again = CalibrationInput {
            flexibility: Some(&report.flexibility),
            ..input
        };
        run = run_calibration(&again, &data.measurements, &data.validation)?;
        let file = identified_stiffness(stiffness, tree, &loaded.nominal, &report.estimates);
        identified = Some((StiffnessSummary::new(&report, config.stiffness_prior), file));
    }
    let identified_run = Identified {
        run,
        plan_name,
        options,
    };
    Ok((identified_run, identified))
}

/// The calibrated URDF; what the export dropped or added, or why it failed, goes among the
/// verdict's reasons (so report.md and report.json name them too).
pub(super) fn export_calibrated(
    config: &CalibrateConfig,
    loaded: &Loaded,
    run: &mut CalibrationRun,
) -> Option<ExportReport> {
    let tree = loaded.robot.tree();
    let std_devs: Vec<Option<f64>> = run.parameters.iter().map(|p| p.std_dev).collect();
    let options =
        ExportOptions::with_uncertainty(tree, &run.report.model, &std_devs, config.add_tool_links);
    let robot = &loaded.robot;
    match export_urdf_with(
        &robot.text,
        &robot.origin,
        tree,
        &run.report.model,
        &options,
    ) {
        Ok(export) => {
            run.findings.extend(export_notes(&export));
            Some(export)
        }
        Err(error) => {
            run.findings.push(Finding::failed(
                "urdf-export",
                format!("the calibrated model cannot be written as a URDF: {error}"),
            ));
            None
        }
    }
}

/// The descriptions of the parameter combinations each stage could not determine.
fn unidentifiable(run: &CalibrationRun, loaded: &Loaded) -> Vec<Vec<String>> {
    let tree = loaded.robot.tree();
    run.report
        .stages
        .iter()
        .map(|stage| {
            let id = &stage.identification;
            let torso = stage.full_model_parameters();
            let names: Vec<String> = (0..id.parameters.len())
                .map(|p| {
                    if p >= torso {
                        let k = p - torso;
                        format!("locked arm tool {} {}", k / 6 + 1, TOOL_PARAMETERS[k % 6])
                    } else {
                        run.report.model.parameter_name(tree, p)
                    }
                })
                .collect();
            id.unidentifiable
                .iter()
                .map(|c| NamedCombination::new(c, &names).description)
                .collect()
        })
        .collect()
}

/// What the report says about the inputs.
fn context(
    config: &CalibrateConfig,
    loaded: &Loaded,
    data: &Data,
    result: &Identified,
) -> CalibrationContext {
    let stiffness = config.stiffness.as_ref().map(|s| s.origin());
    CalibrationContext {
        robot: loaded.robot.tree().name().to_owned(),
        measurements: format!(
            "{} ({} observations used for identification)",
            config.measurements.origin(),
            data.measurements.len()
        ),
        validation: data.validation_source.clone(),
        plan: result.plan_name.clone(),
        compensation: match (stiffness, config.identify_stiffness) {
            (Some(origin), false) => format!("compensated exactly ({origin})"),
            (Some(origin), true) => {
                format!("compensated exactly, stiffness identified (prior {origin})")
            }
            (None, true) => {
                "compensated exactly, stiffness identified (prior: the defaults)".into()
            }
            (None, false) => "not compensated (no --stiffness)".into(),
        },
        sigma: [config.position_sigma, config.rotation_sigma],
        // Why it was chosen is the verdict's measurement-frame reason.
        measurement_frame: match result.run.frame.chosen {
            ChosenFrame::Root => "the robot's root link frame",
            ChosenFrame::Fitted => "fitted in closed form to the data",
            ChosenFrame::Known => "the registration file's frame",
        }
        .to_owned(),
    }
}

/// The summary, with the outliers named by their rows' own ids (the verdict's `outliers`
/// warning names them too).
fn summary(
    config: &CalibrateConfig,
    loaded: &Loaded,
    data: &Data,
    result: &mut Identified,
    export: Option<&ExportReport>,
) -> CalibrationSummary {
    let run = &mut result.run;
    let outliers = outlier_rows(run, loaded.robot.tree(), [&data.ids[0], &data.ids[1]]);
    if let Some(finding) = run.findings.iter_mut().find(|f| f.code == "outliers") {
        let rows: Vec<String> = outliers
            .iter()
            .map(|o| match o.set {
                DataSet::Identification => o.id.clone(),
                DataSet::Validation => format!("{} (validation)", o.id),
            })
            .collect();
        finding.message = format!("{}; rows: {}", finding.message, rows.join(", "));
    }
    let changed: Vec<String> = export
        .iter()
        .flat_map(|e| e.changes.iter().map(|c| c.joint.clone()))
        .collect();
    let context = context(config, loaded, data, result);
    let unidentifiable = unidentifiable(&result.run, loaded);
    let mut summary = calibration_summary(context, &result.run, unidentifiable, changed);
    summary.outliers = outliers;
    summary.name_rows([&data.ids[0], &data.ids[1]]);
    summary
}

/// Everything the outcome holds besides the parameters and notes.
pub(super) struct Outputs {
    pub verdict: Verdict,
    pub report: serde_json::Value,
    pub markdown: String,
    pub urdf: Option<String>,
    pub files: Vec<(String, Vec<u8>)>,
}

/// Renders report.md, report.json, params.yaml, the plots and (with stiffness
/// identification) stiffness.yaml; the URDF only when the verdict is usable.
pub(super) fn outputs(
    config: &CalibrateConfig,
    loaded: &Loaded,
    data: &Data,
    result: &mut Identified,
    export: Option<ExportReport>,
    identified: IdentifiedStiffness,
) -> Result<Outputs> {
    let mut summary = summary(config, loaded, data, result, export.as_ref());
    summary.stiffness = identified.as_ref().map(|(s, _)| s.clone());
    let run = &result.run;
    let tree = loaded.robot.tree();
    let mut markdown = calibration_markdown(&summary, &result.options);
    let mut params = to_yaml(&parameter_file(tree.name(), run))?;
    let json_error = |e: serde_json::Error| invalid("report.json", e.to_string());
    let json = to_json(&summary)?;
    let report = serde_json::to_value(&summary).map_err(json_error)?;
    let mut stiffness_file = None;
    if let Some((stiffness_summary, file)) = &identified {
        markdown.push_str(&stiffness_markdown(stiffness_summary));
        params.push_str(&to_yaml(
            &serde_json::json!({ "stiffness": stiffness_summary }),
        )?);
        stiffness_file = Some(stiffness_to_yaml(
            file,
            &format!(
                "Identified by `treecal calibrate --identify-stiffness` from {} (robot '{}'):\nevery calibrated joint and body with its identified stiffness; see report.md.",
                config.measurements.origin(),
                tree.name()
            ),
        ));
    }
    let mut plots = calibration_plots(&summary.identification, "measurement")?;
    plots.extend(calibration_plots(&summary.validation, "validation")?);
    let verdict = summary.verdict;
    let urdf = export.filter(|_| verdict.usable()).map(|e| e.urdf);
    let mut files: Vec<(String, Vec<u8>)> = Vec::new();
    if let Some(urdf) = &urdf {
        files.push(("calibrated.urdf".into(), urdf.clone().into_bytes()));
    }
    files.push(("params.yaml".into(), params.into_bytes()));
    files.push(("report.md".into(), markdown.clone().into_bytes()));
    files.push(("report.json".into(), json.into_bytes()));
    for (stem, svg) in plots {
        files.push((format!("{stem}.svg"), svg.into_bytes()));
    }
    if let Some(text) = stiffness_file {
        files.push(("stiffness.yaml".into(), text.into_bytes()));
    }
    Ok(Outputs {
        verdict,
        report,
        markdown,
        urdf,
        files,
    })
}
