//! `treecal calibrate`.

use crate::cli::{CalibrateArgs, GravityFrame, MeasurementFrame};
use treecal::calibration::identifiability::NamedCombination;
use treecal::calibration::{
    hold_out, identified_stiffness, identify_stiffness, run_calibration, CalibrationInput,
    IdentificationOptions, Plan, StiffnessOptions,
};
use treecal::io::{
    read_measurements, read_plan, read_stiffness, stiffness_to_yaml, to_json, to_yaml,
    write_atomically, MeasurementReadOptions,
};
use treecal::kinematics::{FlexibilityModel, Stiffness};
use treecal::report::{
    calibration_markdown, calibration_plots, calibration_summary, parameter_file,
    stiffness_markdown, CalibrationContext, StiffnessSummary,
};
use treecal::urdf::export_urdf;
use treecal::{Error, McpcModel, Result};

/// Fraction of the configurations held out for validation without `--validation`.
const HOLD_OUT: f64 = 0.2;

const TOOL_PARAMETERS: [&str; 6] = ["alpha", "beta", "gamma", "x", "y", "z"];

fn invalid(flag: &str, message: String) -> Error {
    Error::InvalidData {
        origin: flag.into(),
        message,
    }
}

pub fn run(args: CalibrateArgs) -> Result<()> {
    for (flag, value) in [
        ("--position-sigma", args.position_sigma),
        ("--rotation-sigma", args.rotation_sigma),
    ] {
        if !(value.is_finite() && value > 0.0) {
            return Err(invalid(flag, format!("{value} must be a positive number")));
        }
    }
    let import = crate::robot::load(args.robot.as_deref())?;
    let tree = &import.tree;
    let branches = crate::robot::branches(&import, args.tools.as_deref())?;
    let nominal = McpcModel::from_tree(tree, &branches)?;
    let read_options = MeasurementReadOptions {
        length_unit: args.length_unit,
        angle_unit: args.angle_unit,
        ignore_columns: args.ignore_columns.clone(),
        strict_limits: args.strict,
    };
    // Warnings and notes are printed once everything is computed, so that a failure reads as
    // one `treecal: error:` line.
    let mut notes: Vec<String> = Vec::new();
    let read = |path: &std::path::Path,
                notes: &mut Vec<String>|
     -> Result<Vec<treecal::measurement::Measurement>> {
        let set = read_measurements(path, tree, &nominal, &read_options)?;
        notes.extend(
            set.warnings
                .iter()
                .map(|warning| format!("treecal: warning: {warning}")),
        );
        Ok(set.measurements)
    };
    let all = read(&args.measurements, &mut notes)?;
    let (measurements, validation, validation_source) = match &args.validation {
        Some(path) => (all, read(path, &mut notes)?, path.display().to_string()),
        None => {
            let (identification, validation) = hold_out(&all, HOLD_OUT, args.seed)?;
            let source = format!(
                "{} of {} observations held out from the measurements (a fifth of the configurations, seed {}; give --validation to use your own)",
                validation.len(),
                all.len(),
                args.seed
            );
            notes.push(format!("treecal: note: {source}"));
            (identification, validation, source)
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
        ..IdentificationOptions::default()
    };
    let input = CalibrationInput {
        tree,
        branches: &branches,
        nominal: &nominal,
        flexibility: flexibility.as_ref(),
        plan: &plan,
        options: &options,
        fit_measurement_frame: matches!(args.measurement_frame, MeasurementFrame::Fit),
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
    let (original, origin) = crate::robot::original_text(args.robot.as_deref())?;
    let export = export_urdf(&original, &origin, tree, &run.report.model)?;
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
        measurement_frame: match args.measurement_frame {
            MeasurementFrame::Fit => {
                "fitted in closed form to the nominal model, then kept; the tool frames fitted too"
                    .into()
            }
            MeasurementFrame::Base => {
                "the robot's root link frame (--measurement-frame base); the tool frames fitted"
                    .into()
            }
        },
    };
    let changed: Vec<String> = export.changes.iter().map(|c| c.joint.clone()).collect();
    let summary = calibration_summary(context, &run, unidentifiable, changed);
    let mut markdown = calibration_markdown(&summary, &options);
    let mut params = to_yaml(&parameter_file(tree.name(), &run))?;
    let mut json = to_json(&summary)?;
    let mut stiffness_file = None;
    if let Some((stiffness_summary, file)) = &identified {
        markdown.push_str(&stiffness_markdown(stiffness_summary));
        params.push_str(&to_yaml(
            &serde_json::json!({ "stiffness": stiffness_summary }),
        )?);
        let mut value =
            serde_json::to_value(&summary).map_err(|e| invalid("report.json", e.to_string()))?;
        value["stiffness"] = serde_json::to_value(stiffness_summary)
            .map_err(|e| invalid("report.json", e.to_string()))?;
        json = to_json(&value)?;
        stiffness_file = Some(stiffness_to_yaml(
            file,
            &format!(
                "Identified by `treecal calibrate --identify-stiffness` from {} (robot '{}'):\nevery calibrated joint and body with its identified stiffness; see report.md.",
                args.measurements.display(),
                tree.name()
            ),
        ));
    }
    let mut plots = calibration_plots(&run.identification, "measurement")?;
    plots.extend(calibration_plots(&run.validation, "validation")?);

    for note in &notes {
        eprintln!("{note}");
    }
    std::fs::create_dir_all(&args.out).map_err(|source| Error::Io {
        path: args.out.clone(),
        source,
    })?;
    write_atomically(&args.out.join("calibrated.urdf"), export.urdf.as_bytes())?;
    write_atomically(&args.out.join("params.yaml"), params.as_bytes())?;
    write_atomically(&args.out.join("report.md"), markdown.as_bytes())?;
    write_atomically(&args.out.join("report.json"), json.as_bytes())?;
    if let Some(text) = &stiffness_file {
        write_atomically(&args.out.join("stiffness.yaml"), text.as_bytes())?;
    }
    for (stem, svg) in &plots {
        write_atomically(&args.out.join(format!("{stem}.svg")), svg.as_bytes())?;
    }
    print!("{markdown}");
    eprintln!("treecal: wrote {}", args.out.display());
    Ok(())
}
