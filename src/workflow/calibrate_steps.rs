//! The named steps of [`super::calibrate::calibrate`]: checking the configuration, reading,
//! and exporting (identifying is in `calibrate_identify`, rendering in `calibrate_outputs`).

use super::calibrate::{CalibrateConfig, MeasurementFrameChoice};
use super::cross_validation::{markdown as cross_validation_markdown, CrossValidation};
use super::export::export_notes;
use super::model_choice::{frame_joints, ModelSpec, NoiseEstimate};
use super::note::Note;
use super::source::{add_measured_points_of, measured_branches_of, LoadedRobot, MeasuredPoints};
use crate::calibration::{
    hold_out_indices, CalibrationRun, Finding, IdentificationOptions, MeasurementFrame, Plan,
};
use crate::error::{Error, Result};
use crate::io::{read_registration, MeasurementReadOptions};
use crate::kinematics::{FlexibilityModel, McpcModel, Stiffness};
use crate::measurement::Measurement;
use crate::report::StiffnessSummary;
use crate::tree::Branches;
use crate::urdf::{export_urdf_with, ExportOptions, ExportReport};

/// Fraction of the configurations held out for validation without validation data.
const HOLD_OUT: f64 = 0.2;

pub(super) fn invalid(setting: &str, message: String) -> Error {
    Error::setting(setting, message)
}

/// The σ within their bounds (a tiny σ overflows the weighted cost, a huge one hides every
/// residual) and a positive stiffness prior.
pub(super) fn check_config(config: &CalibrateConfig) -> Result<()> {
    super::checks::sigmas(config.position_sigma, config.rotation_sigma)?;
    let prior = config.stiffness_prior;
    if config.identify_stiffness && !(prior.is_finite() && prior > 0.0) {
        return Err(invalid(
            "stiffness_prior",
            format!("{prior} must be a positive number"),
        ));
    }
    let scale = config.prior_scale;
    if !(scale.is_finite() && scale > 0.0) {
        return Err(invalid(
            "prior_scale",
            format!("{scale} must be a positive number (1: the default σ)"),
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
    /// The measured points added to the robot as marker links.
    pub points: MeasuredPoints,
}

impl Loaded {
    pub fn new(config: &CalibrateConfig) -> Result<Self> {
        let frame = match &config.measurement_frame {
            MeasurementFrameChoice::Auto => MeasurementFrame::Auto,
            MeasurementFrameChoice::Fit => MeasurementFrame::Fit,
            MeasurementFrameChoice::Base => MeasurementFrame::Base,
            MeasurementFrameChoice::File(path) => MeasurementFrame::Known(read_registration(path)?),
        };
        let mut robot = config.robot.load()?;
        // The file's tools and points read once (at 10⁶ configurations a scan is seconds).
        let targets = config.measurements.targets()?;
        let points = add_measured_points_of(
            &mut robot.import,
            config.tools.as_deref(),
            &config.measurements,
            targets.clone(),
        )?;
        let tools = points.tools.as_deref().or(config.tools.as_deref());
        let branches = measured_branches_of(
            &robot.import,
            tools,
            config.reference_link.as_deref(),
            &config.measurements,
            || config.measurements.tool_names_given(&targets),
        )?;
        let tree = robot.tree();
        if config.identify_stiffness && branches.reference != tree.root() {
            return Err(invalid(
                "identify_stiffness",
                format!(
                    "stiffness identification needs the URDF root '{}' as the reference link: the flexibility model's loads flow to the root, not into the sole '{}' the robot stands on, so compliances fitted from it would be wrong; calibrate from '{}' with a given `stiffness` file (its deflections are then approximate, docs/mcpc.md \"Reference link\"), or identify the stiffness from data measured relative to the root",
                    tree.link(tree.root()).name,
                    tree.link(branches.reference).name,
                    tree.link(branches.reference).name,
                ),
            ));
        }
        let nominal = McpcModel::from_tree(tree, &branches)?;
        Ok(Self {
            robot,
            branches,
            nominal,
            frame,
            points,
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
        tool: config
            .tools
            .as_ref()
            .filter(|t| t.len() == 1)
            .map(|t| t[0].trim().to_owned()),
    };
    notes.extend(loaded.points.note());
    let tree = loaded.robot.tree();
    notes.extend(loaded.branches.roles_summary(tree).map(Note::info));
    notes.extend(loaded.branches.reference_summary(tree).map(Note::info));
    let mut read = |source: &super::source::MeasurementSource| {
        let set = source.read(tree, &loaded.nominal, &options)?;
        notes.extend(set.warnings.iter().map(Note::warning));
        notes.extend(set.notes.iter().map(Note::info));
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
        "{} of {} observations held out from the measurements (a fifth of the configurations, seed {}; give `validation` to use your own)",
        held.len(),
        all.len(),
        config.seed
    );
    notes.push(Note::info(validation_source.clone()));
    let (measurements, validation) = split_held(all, &held);
    let (kept_ids, held_ids) = split_held(all_ids, &held);
    debug_assert_eq!(kept.len(), measurements.len());
    let ids = [kept_ids, held_ids];
    Ok(Data {
        measurements,
        validation,
        validation_source,
        ids,
    })
}

/// `items` without the rows `held` (ascending), and those rows, both in order. Moved in
/// place, not copied: at 10⁶ configurations a copy of the measurements is about 700 MB (and a
/// kept set collected anew, grown by doubling, was the peak of the whole run at 10⁶).
fn split_held<T>(items: Vec<T>, held: &[usize]) -> (Vec<T>, Vec<T>) {
    // `Option<T>` has the size of `T` for these types (a niche): the slots and the kept rows
    // reuse the rows' allocation (`map` over a `Vec`'s iterator collects in place).
    let mut slots: Vec<Option<T>> = items.into_iter().map(Some).collect();
    let mut taken = Vec::with_capacity(held.len());
    taken.extend(held.iter().filter_map(|&i| slots.get_mut(i)?.take()));
    slots.retain(Option::is_some);
    let mut kept: Vec<T> = slots
        .into_iter()
        .map(|slot| slot.expect("only filled slots are retained"))
        .collect();
    // The held rows' room back to the system (a large buffer shrinks in place): at 10⁶
    // configurations about 90 MB of resident memory through the identification.
    kept.shrink_to_fit();
    (kept, taken)
}

/// A finished identification and how it was set up.
pub(super) struct Identified {
    pub run: CalibrationRun,
    pub plan_name: String,
    pub options: IdentificationOptions,
    /// The plan the run used.
    pub plan: Plan,
    /// The flexibility model of the final run (with the identified stiffness, if any).
    pub flexibility: Option<FlexibilityModel>,
    /// The model calibrated.
    pub spec: ModelSpec,
    /// The cross-validation table (`--cv`, `--model auto`).
    pub cross_validation: Option<CrossValidation>,
    /// The noise estimated from the residuals (`estimate_noise`), if any.
    pub noise: Option<NoiseEstimate>,
}

/// With `--identify-stiffness`: the report's summary and the identified stiffness.
pub(super) type IdentifiedStiffness = Option<(StiffnessSummary, Stiffness)>;

/// Adds the cross-validation table to report.md and report.json (`"model_choice"`), and the
/// model calibrated (`"model"`).
pub(super) fn add_model_choice(
    tree: &crate::tree::KinematicTree,
    result: &Identified,
    outputs: &mut super::calibrate_outputs::Outputs,
    notes: &mut Vec<Note>,
) -> Result<()> {
    if let Some(text) = joint_errors_yaml(tree, &result.run.report.model) {
        let message = "calibrated.urdf cannot carry the identified joint-angle errors (harmonics, backlash): they are in joint_errors.yaml (docs/file-formats.md), to be added to the commanded joint angles; the validation figures include them";
        notes.push(Note::warning(message));
        outputs
            .markdown
            .push_str(&format!("\n## Joint-angle errors\n\n{message}.\n"));
        outputs
            .files
            .push(("joint_errors.yaml".into(), text.into_bytes()));
    }
    let mut extra = vec![(
        "model".to_string(),
        serde_json::json!({
            "name": result.spec.named(&frame_joints(tree, &result.run.report.model)),
            "spec": result.spec
        }),
    )];
    if let Some(noise) = &result.noise {
        notes.push(Note::info(format!("model: {}", noise.describe())));
        outputs.markdown.push_str(&format!(
            "\n## Noise model\n\nThe {} (docs/identification.md, \"Noise model from the data\").\n",
            noise.describe()
        ));
        extra.push((
            "noise".into(),
            serde_json::to_value(noise).map_err(|e| invalid("report.json", e.to_string()))?,
        ));
    }
    if let Some(cv) = &result.cross_validation {
        extra.push((
            "model_choice".into(),
            serde_json::to_value(cv).map_err(|e| invalid("report.json", e.to_string()))?,
        ));
    }
    add_before_stiffness(&mut outputs.report, &extra);
    if let Some(cv) = &result.cross_validation {
        outputs.markdown.push_str(&cross_validation_markdown(cv));
        notes.extend(
            super::cross_validation::lines(cv)
                .into_iter()
                .map(Note::info),
        );
    }
    if let Some((_, bytes)) = outputs.files.iter_mut().find(|(n, _)| n == "report.md") {
        *bytes = outputs.markdown.clone().into_bytes();
    }
    Ok(())
}

/// Adds `extra` to a report.json object, before the `stiffness` block (which stays last).
fn add_before_stiffness(report: &mut serde_json::Value, extra: &[(String, serde_json::Value)]) {
    if let serde_json::Value::Object(map) = report {
        let stiffness = map.shift_remove("stiffness");
        for (key, value) in extra {
            map.insert(key.clone(), value.clone());
        }
        if let Some(stiffness) = stiffness {
            map.insert("stiffness".into(), stiffness);
        }
    }
}

/// joint_errors.yaml: the harmonic and backlash terms of `model` (none: `None`).
pub(super) fn joint_errors_yaml(
    tree: &crate::tree::KinematicTree,
    model: &McpcModel,
) -> Option<String> {
    let terms = model.joint_error_terms();
    if !(terms.harmonics || terms.backlash) {
        return None;
    }
    let mut text = String::from(
        "# Joint-angle errors identified by treecal calibrate (docs/file-formats.md); a URDF cannot carry them.\n# The joint turns by theta = q + sine*sin(q) + cosine*cos(q) + backlash*sign(tau), q the commanded angle,\n# tau the gravity torque about the joint axis (URDF inertials, gravity along -z of the root link).\n# Joint zero offsets are in calibrated.urdf already.\nunits: {angle: rad}\njoints:\n",
    );
    for (frame, f) in model.frames().iter().enumerate() {
        let [_, sine, cosine, backlash] = model.joint_error_values(frame);
        let mut parts = Vec::new();
        for (name, value) in [("sine", sine), ("cosine", cosine), ("backlash", backlash)] {
            if let Some(value) = value {
                parts.push(format!("{name}: {value:.9}"));
            }
        }
        if !parts.is_empty() {
            text.push_str(&format!(
                "  {}: {{{}}}\n",
                tree.joint(f.joint).name,
                parts.join(", ")
            ));
        }
    }
    Some(text)
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
        // Joint offsets are carried by the URDF's joint origins.
        &run.report.model.with_offsets_absorbed(),
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

#[cfg(test)]
mod tests {
    use super::split_held;

    #[test]
    fn split_held_keeps_both_parts_in_order() {
        let items: Vec<String> = (0..10).map(|i| i.to_string()).collect();
        let (kept, held) = split_held(items, &[0, 4, 5, 9]);
        assert_eq!(kept, ["1", "2", "3", "6", "7", "8"]);
        assert_eq!(held, ["0", "4", "5", "9"]);
        let (kept, held) = split_held(vec![1, 2], &[]);
        assert_eq!((kept, held), (vec![1, 2], vec![]));
    }
}
