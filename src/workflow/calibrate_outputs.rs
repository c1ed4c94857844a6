//! The outputs of [`super::calibrate::calibrate`]: the summary with the outliers named by
//! their row ids, report.md, report.json, params.yaml, the plots and the calibrated URDF.

use super::calibrate::CalibrateConfig;
use super::calibrate_steps::{Data, Identified, IdentifiedStiffness, Loaded};
use crate::calibration::identifiability::NamedCombination;
use crate::calibration::robust::DataSet;
use crate::calibration::{CalibrationRun, ChosenFrame, Verdict};
use crate::error::{Error, Result};
use crate::io::{stiffness_to_yaml, to_json, to_yaml};
use crate::report::{
    calibration_markdown, calibration_plots, calibration_summary, outlier_rows, parameter_file,
    stiffness_markdown, CalibrationContext, CalibrationSummary,
};
use crate::urdf::ExportReport;

const TOOL_PARAMETERS: [&str; 6] = ["alpha", "beta", "gamma", "x", "y", "z"];

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
    if let Some(sessions) = &summary.sessions {
        markdown.push_str(&crate::report::sessions_markdown(sessions));
    }
    let mut params = to_yaml(&parameter_file(tree.name(), run))?;
    let json_error = |e: serde_json::Error| Error::InvalidData {
        origin: "report.json".into(),
        message: e.to_string(),
    };
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
