//! The outputs of [`super::calibrate::calibrate`]: the summary with the outliers named by
//! their row ids, report.md, report.json, params.yaml, the plots and the calibrated URDF.

use super::artifact_scoring::CompensationFile;
use super::calibrate_artifact::{assess, COMPENSATED_URDF, REGISTRATION_FILE};
use super::calibrate_config::CalibrateConfig;
pub(super) use super::calibrate_products::Outputs;
use super::calibrate_steps::{Data, Identified, IdentifiedStiffness, Loaded};
use crate::calibration::NamedCombination;
use crate::calibration::{CalibrationRun, ChosenFrame, Finding};
use crate::calibration::{DataSet, OUTLIER_WEIGHT};
use crate::error::Result;
use crate::io::{stiffness_to_yaml, to_yaml};
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
        compensation: match (
            stiffness,
            config.identify_stiffness || result.spec.identify_stiffness,
        ) {
            (Some(origin), false) => format!("compensated exactly ({origin})"),
            (Some(origin), true) => {
                format!("compensated exactly, stiffness identified (prior {origin})")
            }
            (None, true) => format!(
                "compensated exactly, stiffness identified (prior: the defaults){}",
                if config.identify_stiffness {
                    ""
                } else {
                    "; chosen by cross-validation"
                }
            ),
            (None, false) => "not compensated (no `stiffness`)".into(),
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
                DataSet::Identification => format!(
                    "{} (weight {:.3}, {:.2} mm off)",
                    o.id, o.weight, o.residual_mm
                ),
                DataSet::Validation => {
                    format!("{} (validation, {:.2} mm off)", o.id, o.residual_mm)
                }
            })
            .collect();
        // One stderr line: the first rows, and how many in all (report.md lists every one).
        let shown = rows.len().min(2 * FIRST_IDS);
        finding.message = format!(
            "{}; rows: {}{}",
            finding.message,
            rows[..shown].join(", "),
            if rows.len() > shown {
                format!(", … ({} in all, every one in report.md)", rows.len())
            } else {
                String::new()
            }
        );
    }
    run.findings
        .extend(down_weighted_finding(run, &data.ids[0]));
    crate::calibration::mark_consequences(&mut run.findings);
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

/// How many identification rows shown at once in a stderr line.
const FIRST_IDS: usize = 5;

/// The identification rows the robust loss down-weighted but kept in the fit (the outliers
/// have their own warning): counted, the first named with their weights, never silently.
fn down_weighted_finding(run: &CalibrationRun, ids: &[String]) -> Option<Finding> {
    let weights = &run.robust.weights;
    let mut rows: Vec<(usize, f64)> = weights
        .iter()
        .enumerate()
        .filter(|(_, &w)| (OUTLIER_WEIGHT..1.0).contains(&w))
        .map(|(i, &w)| (i, w))
        .collect();
    if rows.is_empty() {
        return None;
    }
    // The lightest first: they pulled least and are the likeliest blunders.
    rows.sort_by(|a, b| a.1.total_cmp(&b.1));
    let named: Vec<String> = rows
        .iter()
        .take(FIRST_IDS)
        .map(|&(i, w)| {
            let id = ids.get(i).cloned().unwrap_or_else(|| format!("#{}", i + 1));
            let residual = run
                .robust
                .residuals
                .get(i)
                .map_or(String::new(), |r| format!(", {:.2} mm", r.position * 1e3));
            format!("{id} (weight {w:.3}{residual})")
        })
        .collect();
    Some(Finding::warning(
        "down-weighted",
        format!(
            "{} of {} identification rows were down-weighted by the robust {} loss and kept in the fit with less weight: {}{}; check them (a bumped target, a wrong row), every one is listed with its weight in report.md and report.json (`weight`); compare with `robust` off or `robust` cauchy",
            rows.len(),
            weights.len(),
            run.robust.loss,
            named.join(", "),
            if rows.len() > FIRST_IDS { ", …" } else { "" }
        ),
    ))
}

/// Renders report.md, report.json, params.yaml, the plots, registration.yaml (a fitted
/// frame) and (with stiffness identification) stiffness.yaml; scores the URDF as written
/// (`calibrate_artifact`); the URDF only when the verdict is usable.
pub(super) fn outputs(
    config: &CalibrateConfig,
    loaded: &Loaded,
    data: &Data,
    result: &mut Identified,
    export: Option<ExportReport>,
    identified: IdentifiedStiffness,
) -> Result<Outputs> {
    let tree = loaded.robot.tree();
    let stiffness_file = identified.as_ref().map(|(_, file)| {
        stiffness_to_yaml(
            file,
            &format!(
                "Identified by {} from {} (robot '{}'):\nevery calibrated joint and body with its identified stiffness; see report.md.",
                if config.identify_stiffness {
                    "`treecal calibrate --identify-stiffness`"
                } else {
                    "`treecal calibrate` (its cross-validation chose geometry + identified stiffness)"
                },
                config.measurements.origin(),
                tree.name()
            ),
        )
    });
    let compensation = match (&stiffness_file, &config.stiffness) {
        (Some(text), _) => Some(CompensationFile::Written(text)),
        (None, Some(source)) => Some(CompensationFile::Source(source)),
        (None, None) => None,
    };
    let artifact = assess(config, loaded, data, result, export.as_ref(), compensation)?;
    result
        .run
        .findings
        .extend(artifact.findings.iter().cloned());
    let (export, compensated_urdf) = match artifact.replaced {
        Some((rigid, compensated)) => (Some(rigid), Some(compensated)),
        None => (export, None),
    };
    let mut summary = summary(config, loaded, data, result, export.as_ref());
    summary.stiffness = identified.as_ref().map(|(s, _)| s.clone());
    summary.artifact = Some(artifact.report);
    // The per-row residuals live on in the summary's typed rows: freed before the plots, the
    // page and report.json are rendered (at 10⁶ configurations some 200 MB at the peak).
    let run = &mut result.run;
    (run.identification, run.validation) = (Vec::new(), Vec::new());
    run.robust.residuals = Vec::new();
    run.validation_strata = Vec::new();
    let run = &result.run;
    let mut markdown = calibration_markdown(&summary, &result.options);
    if let Some(sessions) = &summary.sessions {
        markdown.push_str(&crate::report::sessions_markdown(sessions));
    }
    let mut params = to_yaml(&parameter_file(tree.name(), run))?;
    // The links the export added (marker frames, measured points): `treecal export` rebuilds
    // the measured points from this list.
    if let Some(added) = export
        .as_ref()
        .map(|e| &e.added_links)
        .filter(|a| !a.is_empty())
    {
        params.push_str(&to_yaml(&serde_json::json!({ "added_links": added }))?);
    }
    if let Some((stiffness_summary, _)) = &identified {
        markdown.push_str(&stiffness_markdown(stiffness_summary));
        params.push_str(&to_yaml(
            &serde_json::json!({ "stiffness": stiffness_summary }),
        )?);
    }
    let mut plots = calibration_plots(&summary.identification, "measurement")?;
    plots.extend(calibration_plots(&summary.validation, "validation")?);
    let verdict = summary.verdict.clone();
    let export = export.filter(|_| verdict.usable());
    // The overlay and offsets (issue 23), and the page that shows all of it.
    let deploy = super::calibrate_deploy::deployable(tree, &loaded.nominal, run, export.as_ref())?;
    markdown.push_str(&deploy.markdown);
    let html = super::calibrate_html::report_html(loaded, data, result, &summary, &plots, &deploy)?;
    let urdf = export.map(|e| e.urdf);
    // report.json's rows stay typed until the file is rendered (`report_json`).
    let (report, report_parts) = super::report_json::summary_value(summary)?;
    let mut files: Vec<(String, Vec<u8>)> = Vec::new();
    if let Some(urdf) = &urdf {
        files.push(("calibrated.urdf".into(), urdf.clone().into_bytes()));
        if let Some(text) = compensated_urdf {
            files.push((COMPENSATED_URDF.into(), text.into_bytes()));
        }
    }
    if let Some(text) = artifact.registration {
        files.push((REGISTRATION_FILE.into(), text.into_bytes()));
    }
    files.push(("params.yaml".into(), params.into_bytes()));
    files.push(("report.md".into(), markdown.clone().into_bytes()));
    // Rendered from `report` once it is complete (the calibration's last step, provenance).
    files.push(("report.json".into(), Vec::new()));
    for (stem, svg) in plots {
        files.push((format!("{stem}.svg"), svg.into_bytes()));
    }
    if let Some(text) = stiffness_file {
        files.push(("stiffness.yaml".into(), text.into_bytes()));
    }
    files.extend(deploy.files);
    files.push((super::calibrate_deploy::HTML_FILE.into(), html.into_bytes()));
    Ok(Outputs {
        verdict,
        report,
        report_parts,
        markdown,
        urdf,
        files,
    })
}
