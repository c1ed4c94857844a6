//! `treecal calibrate`.

use crate::cli::{CalibrateArgs, GravityFrame, MeasurementFrame};
use treecal::calibration::identifiability::NamedCombination;
use treecal::calibration::robust::DataSet;
use treecal::calibration::{
    hold_out_indices, identified_stiffness, identify_stiffness, run_calibration, CalibrationInput,
    ChosenFrame, Finding, IdentificationOptions, Plan, Status, StiffnessOptions,
};
use treecal::io::{
    check_output_folder, read_measurements, read_plan, read_registration, read_stiffness,
    replace_folder, stiffness_to_yaml, to_json, to_yaml, MeasurementReadOptions,
};
use treecal::kinematics::{FlexibilityModel, Stiffness};
use treecal::report::{
    calibration_markdown, calibration_plots, calibration_summary, outlier_rows, parameter_file,
    stiffness_markdown, CalibrationContext, StiffnessSummary,
};
use treecal::urdf::{export_urdf_with, ExportOptions};
use treecal::{Error, McpcModel, Result};

/// Fraction of the configurations held out for validation without `--validation`.
const HOLD_OUT: f64 = 0.2;

const TOOL_PARAMETERS: [&str; 6] = ["alpha", "beta", "gamma", "x", "y", "z"];

/// Whether a file name is one `calibrate` writes (a previous output may be replaced).
fn is_output_file(name: &str) -> bool {
    matches!(
        name,
        "calibrated.urdf" | "params.yaml" | "report.md" | "report.json"
    ) || name.ends_with(".svg")
}

fn invalid(flag: &str, message: String) -> Error {
    Error::InvalidData {
        origin: flag.into(),
        message,
    }
}

pub fn run(args: CalibrateArgs) -> Result<()> {
    crate::checks::sigmas(args.position_sigma, args.rotation_sigma)?;
    let measurement_frame = match &args.measurement_frame {
        MeasurementFrame::Auto => treecal::calibration::MeasurementFrame::Auto,
        MeasurementFrame::Fit => treecal::calibration::MeasurementFrame::Fit,
        MeasurementFrame::Base => treecal::calibration::MeasurementFrame::Base,
        MeasurementFrame::File(path) => {
            treecal::calibration::MeasurementFrame::Known(read_registration(path)?)
        }
    };
    let plan_file = args
        .plan
        .as_deref()
        .filter(|p| !matches!(*p, "staged" | "simultaneous"))
        .map(std::path::Path::new);
    let inputs: Vec<&std::path::Path> = [args.robot.as_deref(), Some(args.measurements.as_path())]
        .into_iter()
        .chain([
            args.validation.as_deref(),
            args.stiffness.as_deref(),
            plan_file,
        ])
        .flatten()
        .collect();
    let written = ["calibrated.urdf", "params.yaml", "report.md", "report.json"];
    crate::checks::refuse_overwrite_in(&args.out, &written, "svg", &inputs)?;
    // The output folder is replaced as a whole at the end: refuse a folder that is not a
    // previous output before computing anything.
    check_output_folder(&args.out, &is_output_file)?;
    let import = crate::robot::load(args.robot.as_deref())?;
    let (original, origin) = crate::robot::original_text(args.robot.as_deref())?;
    let tree = &import.tree;
    let branches =
        crate::robot::measured_branches(&import, args.tools.as_deref(), &args.measurements)?;
    let nominal = McpcModel::from_tree(tree, &branches)?;
    let read_options = MeasurementReadOptions {
        length_unit: args.length_unit,
        angle_unit: args.angle_unit,
        joint_length_unit: args.joint_length_unit,
        ignore_columns: args.ignore_columns.clone(),
        strict_limits: args.strict,
    };
    // Warnings and notes are printed once everything is computed, so that a failure reads as
    // one `treecal: error:` line.
    let mut notes: Vec<String> = Vec::new();
    let read = |path: &std::path::Path,
                notes: &mut Vec<String>|
     -> Result<(Vec<treecal::measurement::Measurement>, Vec<String>)> {
        let set = read_measurements(path, tree, &nominal, &read_options)?;
        notes.extend(
            set.warnings
                .iter()
                .map(|warning| format!("treecal: warning: {warning}")),
        );
        Ok((set.measurements, set.ids))
    };
    let (all, all_ids) = read(&args.measurements, &mut notes)?;
    // `ids`: the row ids of the identification and validation data, for the outlier report.
    let (measurements, validation, validation_source, ids) = match &args.validation {
        Some(path) => {
            let (validation, validation_ids) = read(path, &mut notes)?;
            let source = path.display().to_string();
            (all, validation, source, [all_ids, validation_ids])
        }
        None => {
            let (kept, held) = hold_out_indices(&all, HOLD_OUT, args.seed)?;
            let source = format!(
                "{} of {} observations held out from the measurements (a fifth of the configurations, seed {}; give --validation to use your own)",
                held.len(),
                all.len(),
                args.seed
            );
            notes.push(format!("treecal: note: {source}"));
            let pick = |rows: &[usize]| rows.iter().map(|&i| all[i].clone()).collect();
            let ids = [&kept, &held].map(|rows| rows.iter().map(|&i| all_ids[i].clone()).collect());
            (pick(&kept), pick(&held), source, ids)
        }
    };
    let labelled = measurements
        .iter()
        .any(|m| m.stage.as_deref() == Some("torso"));
    let (plan, plan_name) = match args.plan.as_deref() {
        Some("staged") => (Plan::staged(), "staged".to_owned()),
        Some("simultaneous") => (Plan::simultaneous(), "simultaneous".to_owned()),
        Some(path) => (
            read_plan(std::path::Path::new(path))?,
            format!("plan file {path}"),
        ),
        None if labelled => (Plan::staged(), "staged".to_owned()),
        None => {
            notes.push(
                "treecal: note: no rows are labelled stage=torso, so the simultaneous plan is used (label torso rows, taken with the arms locked, for the staged plan)".into()
            );
            (Plan::simultaneous(), "simultaneous".to_owned())
        }
    };
    if args.identify_stiffness && !(args.stiffness_prior.is_finite() && args.stiffness_prior > 0.0)
    {
        return Err(invalid(
            "--stiffness-prior",
            format!("{} must be a positive number", args.stiffness_prior),
        ));
    }
    // With --identify-stiffness and no file, the library defaults are the prior.
    let stiffness = match &args.stiffness {
        Some(path) => Some(read_stiffness(path, tree, &nominal)?),
        None => args.identify_stiffness.then(Stiffness::default),
    };
    let flexibility = match &stiffness {
        Some(stiffness) => {
            let model = FlexibilityModel::new(tree, &nominal, stiffness)?;
            Some(match args.gravity_frame {
                GravityFrame::Measurement => model.with_gravity_in_measurement_frame(),
                GravityFrame::Base => model,
            })
        }
        None => None,
    };
    let options = IdentificationOptions {
        position_sigma: args.position_sigma,
        rotation_sigma: args.rotation_sigma,
        robust: args.robust.into(),
        ..IdentificationOptions::default()
    };
    let input = CalibrationInput {
        tree,
        branches: &branches,
        nominal: &nominal,
        flexibility: flexibility.as_ref(),
        plan: &plan,
        options: &options,
        measurement_frame,
    };
    let mut run = run_calibration(&input, &measurements, &validation)?;
    // Stiffness identification: the joint fit from the calibrated geometry, then the plan
    // again with the identified stiffness, so that every table below describes it.
    let identified = match (&flexibility, &stiffness, args.identify_stiffness) {
        (Some(prior), Some(stiffness), true) => {
            let stiffness_options = StiffnessOptions {
                prior_sigma: args.stiffness_prior,
                ..StiffnessOptions::default()
            };
            let free: Vec<usize> = (0..run.report.model.parameter_count()).collect();
            let report = identify_stiffness(
                tree,
                &run.report.model,
                prior,
                &measurements,
                None,
                &free,
                &options,
                &stiffness_options,
            )?;
            let again = CalibrationInput {
                flexibility: Some(&report.flexibility),
                ..input
            };
            run = run_calibration(&again, &measurements, &validation)?;
            let file = identified_stiffness(stiffness, tree, &nominal, &report.estimates);
            Some((StiffnessSummary::new(&report, args.stiffness_prior), file))
        }
        _ => None,
    };

    // Everything is computed before anything is written.
    let std_devs: Vec<Option<f64>> = run.parameters.iter().map(|p| p.std_dev).collect();
    let export_options =
        ExportOptions::with_uncertainty(tree, &run.report.model, &std_devs, args.add_tool_links);
    let export =
        match export_urdf_with(&original, &origin, tree, &run.report.model, &export_options) {
            Ok(export) => {
                // In the verdict's reasons, so report.md and report.json name them too.
                run.findings.extend(crate::robot::export_notes(&export));
                Some(export)
            }
            Err(error) => {
                run.findings.push(Finding::failed(
                    "urdf-export",
                    format!("the calibrated model cannot be written as a URDF: {error}"),
                ));
                None
            }
        };
    let unidentifiable: Vec<Vec<String>> = run
        .report
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
        .collect();
    let context = CalibrationContext {
        robot: tree.name().to_owned(),
        measurements: format!(
            "{} ({} observations used for identification)",
            args.measurements.display(),
            measurements.len()
        ),
        validation: validation_source,
        plan: plan_name,
        compensation: match (&args.stiffness, args.identify_stiffness) {
            (Some(path), false) => format!("compensated exactly ({})", path.display()),
            (Some(path), true) => format!(
                "compensated exactly, stiffness identified (prior {})",
                path.display()
            ),
            (None, true) => {
                "compensated exactly, stiffness identified (prior: the defaults)".into()
            }
            (None, false) => "not compensated (no --stiffness)".into(),
        },
        sigma: [args.position_sigma, args.rotation_sigma],
        // Why it was chosen is the verdict's measurement-frame reason, printed once above.
        measurement_frame: match run.frame.chosen {
            ChosenFrame::Root => "the robot's root link frame",
            ChosenFrame::Fitted => "fitted in closed form to the data",
            ChosenFrame::Known => "the registration file's frame",
        }
        .to_owned(),
    };
    let changed: Vec<String> = export
        .iter()
        .flat_map(|e| e.changes.iter().map(|c| c.joint.clone()))
        .collect();
    // The outliers with the rows' own ids; the verdict's `outliers` warning names them too.
    let outliers = outlier_rows(&run, tree, [&ids[0], &ids[1]]);
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
    let mut summary = calibration_summary(context, &run, unidentifiable, changed);
    summary.outliers = outliers;
    summary.name_rows([&ids[0], &ids[1]]);
    summary.stiffness = identified.as_ref().map(|(s, _)| s.clone());
    let mut markdown = calibration_markdown(&summary, &options);
    let mut params = to_yaml(&parameter_file(tree.name(), &run))?;
    let json = to_json(&summary)?;
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
                args.measurements.display(),
                tree.name()
            ),
        ));
    }
    let mut plots = calibration_plots(&summary.identification, "measurement")?;
    plots.extend(calibration_plots(&summary.validation, "validation")?);

    let verdict = &summary.verdict;
    let mut files: Vec<(String, Vec<u8>)> = Vec::new();
    if let (true, Some(export)) = (verdict.usable(), &export) {
        files.push(("calibrated.urdf".into(), export.urdf.clone().into_bytes()));
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

    for note in &notes {
        eprintln!("{note}");
    }
    for reason in &verdict.reasons {
        let label = match reason.status {
            Status::Ok => "note",
            Status::Warning => "warning",
            Status::Failed => "error",
        };
        eprintln!("treecal: {label}: {}", reason.message);
    }
    replace_folder(&args.out, &files)?;
    print!("{markdown}");
    eprintln!("treecal: wrote {}", args.out.display());
    if !verdict.usable() {
        return Err(invalid(
            "calibration",
            format!(
                "verdict failed (see the errors above and {}); calibrated.urdf was not written",
                args.out.join("report.md").display()
            ),
        ));
    }
    Ok(())
}
