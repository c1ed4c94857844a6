//! `compare`: two `calibrate` output folders of one robot (two dates, or two model choices on
//! the same data) → the parameters that moved beyond k combined standard deviations, the tool
//! displacement the two calibrated URDFs predict over a configuration set, and the validation
//! figures side by side (docs/workflows.md, "Compare").

use super::compare_gauge::{reexpress, Configuration, Reexpression};
use super::postures::RecordedPostures;
use super::provenance::Started;
use super::verify::{postures_of, scored_link};
use crate::calibration::fit_rigid_transform;
use crate::error::{Error, Result};
use crate::io::read_registration;
use crate::math::{Pose, Vec3};
use crate::report::{
    CompareReport, Displacement, DisplacementRow, FrameChange, MovedParameter, ValidationFigures,
};
use crate::tree::KinematicTree;
use crate::urdf::parse_urdf;
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// The files [`Comparison::write`] writes.
pub const COMPARE_FILES: [&str; 5] = [
    "report.md",
    "report.html",
    "report.json",
    "displacement.svg",
    "provenance.yaml",
];

/// Two calibrations to compare.
#[derive(Debug, Clone, PartialEq)]
pub struct CompareConfig {
    /// The first calibrate output folder (the reference).
    pub a: PathBuf,
    /// The second.
    pub b: PathBuf,
    /// A parameter moved when `|b − a| > k·√(σa² + σb²)` [default: 3].
    pub k: f64,
}

impl Default for CompareConfig {
    fn default() -> Self {
        Self {
            a: PathBuf::new(),
            b: PathBuf::new(),
            k: 3.0,
        }
    }
}

/// The outcome of a comparison.
#[derive(Debug, Clone)]
pub struct Comparison {
    /// report.json's content.
    pub report: CompareReport,
    /// report.md.
    pub markdown: String,
    /// Every output file.
    pub files: Vec<(String, Vec<u8>)>,
    /// The files read.
    pub inputs: Vec<PathBuf>,
}

impl Comparison {
    /// Replaces the folder `out` with the output files; refuses a folder holding an input or
    /// files that are not a previous compare output.
    pub fn write(&self, out: &Path) -> Result<()> {
        let inputs: Vec<&Path> = self.inputs.iter().map(PathBuf::as_path).collect();
        super::checks::check_outputs(&[super::checks::Output::Folder(out)], &inputs)?;
        crate::io::check_output_folder(out, &|name| COMPARE_FILES.contains(&name))?;
        crate::io::replace_folder(out, &self.files)
    }
}

fn invalid(origin: &Path, message: impl Into<String>) -> Error {
    Error::InvalidData {
        origin: origin.display().to_string(),
        message: message.into(),
    }
}

/// One parameter as report.json lists it.
#[derive(Debug, Clone, serde::Deserialize)]
struct Parameter {
    name: String,
    unit: String,
    calibrated: f64,
    std_dev: Option<f64>,
}

/// One calibration folder as read.
struct Folder {
    dir: PathBuf,
    report: serde_json::Value,
    parameters: Vec<Parameter>,
    tree: KinematicTree,
    world_from_base: Pose,
    postures: Option<RecordedPostures>,
    /// Calibrated from a reference link other than the URDF root.
    from_reference_link: bool,
    inputs: Vec<PathBuf>,
}

/// Whether the calibration in `dir` was measured from a reference link: report.json's
/// `reference_link` (contact calibrations), or the settings recorded in provenance.yaml (the
/// debug text of `CalibrateConfig`, which names `reference_link: Some(..)`).
fn from_reference_link(dir: &Path, report: &serde_json::Value) -> bool {
    if report.get("reference_link").is_some_and(|v| !v.is_null()) {
        return true;
    }
    let provenance = dir.join(super::provenance::PROVENANCE_FILE);
    provenance.is_file()
        && crate::limits::read_text(&provenance, crate::limits::MAX_YAML_BYTES)
            .is_ok_and(|text| text.contains("reference_link: Some("))
}

impl Folder {
    fn read(dir: &Path) -> Result<Self> {
        if !dir.is_dir() {
            return Err(invalid(
                dir,
                "not a folder: give two `treecal calibrate` output folders",
            ));
        }
        let report_path = dir.join("report.json");
        let urdf_path = dir.join("calibrated.urdf");
        for path in [&report_path, &urdf_path] {
            if !path.is_file() {
                return Err(invalid(
                    path,
                    "missing: not a calibrate output folder with a usable verdict",
                ));
            }
        }
        let report = super::report_json::read_calibration_report(&report_path)?;
        let parameters: Vec<Parameter> = report
            .get("parameters")
            .map(|v| serde_json::from_value(v.clone()))
            .transpose()
            .map_err(|e| invalid(&report_path, format!("parameters: {e}")))?
            .unwrap_or_default();
        let urdf = crate::limits::read_text(&urdf_path, crate::limits::MAX_URDF_BYTES)?;
        let tree = parse_urdf(&urdf, &urdf_path.display().to_string())?.tree;
        let registration = dir.join(super::calibrate_artifact::REGISTRATION_FILE);
        let mut inputs = vec![report_path.clone(), urdf_path];
        let world_from_base = if registration.is_file() {
            inputs.push(registration.clone());
            read_registration(&registration)?
        } else {
            Pose::identity()
        };
        Ok(Self {
            dir: dir.to_owned(),
            postures: postures_of(&report, &report_path)?,
            from_reference_link: from_reference_link(dir, &report),
            report,
            parameters,
            tree,
            world_from_base,
            inputs,
        })
    }

    /// The validation figures of report.json.
    fn figures(&self) -> ValidationFigures {
        let number = |path: &[&str]| {
            path.iter()
                .try_fold(&self.report, |v, key| v.get(key))
                .and_then(serde_json::Value::as_f64)
        };
        let stratum = |name: &str| {
            self.report
                .get("validation_strata")
                .and_then(|s| s.get("strata"))
                .and_then(serde_json::Value::as_array)
                .and_then(|rows| {
                    rows.iter()
                        .find(|r| r.get("stratum").and_then(|s| s.as_str()) == Some(name))
                })
                .and_then(|r| r.get("rms_position_mm"))
                .and_then(serde_json::Value::as_f64)
        };
        ValidationFigures {
            folder: self.dir.display().to_string(),
            verdict: self
                .report
                .get("verdict")
                .and_then(|v| v.get("status"))
                .and_then(|s| s.as_str())
                .unwrap_or("—")
                .to_owned(),
            urdf_alone_rms_mm: number(&["artifact", "urdf_alone", "errors", "rms_position_mm"]),
            urdf_alone_max_mm: number(&["artifact", "urdf_alone", "errors", "max_position_mm"]),
            registered_nominal_rms_mm: number(&[
                "artifact",
                "registered_nominal",
                "errors",
                "rms_position_mm",
            ]),
            repeat_rms_mm: stratum("repeat"),
            inside_rms_mm: stratum("inside"),
            outside_rms_mm: stratum("outside"),
            predicted_rms_mm: number(&["predicted_validation_rms_mm"]),
        }
    }
}

/// The parameters of `b` that moved from `a`'s by more than `k` combined σ, largest first
/// (in σ); parameters without a σ in either folder are not judged. `reexpressed`: B − A per
/// parameter name with B in A's measurement frame (the others are compared as calibrated).
fn moved(
    a: &[Parameter],
    b: &[Parameter],
    k: f64,
    reexpressed: Option<&HashMap<String, f64>>,
) -> (Vec<MovedParameter>, usize) {
    let mut judged = 0;
    let mut moved: Vec<MovedParameter> = a
        .iter()
        .filter_map(|pa| {
            let pb = b.iter().find(|p| p.name == pa.name)?;
            let sigma = pa.std_dev?.hypot(pb.std_dev?);
            judged += 1;
            let change = reexpressed
                .and_then(|r| r.get(&pa.name).copied())
                .unwrap_or(pb.calibrated - pa.calibrated);
            (sigma > 0.0 && change.abs() > k * sigma).then(|| MovedParameter {
                name: pa.name.clone(),
                unit: pa.unit.clone(),
                a: pa.calibrated,
                b: pa.calibrated + change,
                b_calibrated: pb.calibrated,
                change,
                combined_std_dev: sigma,
                sigmas: change.abs() / sigma,
            })
        })
        .collect();
    moved.sort_by(|x, y| y.sigmas.total_cmp(&x.sigmas));
    (moved, judged)
}

/// The configurations of both folders' recorded identification postures, per tool link name.
fn configurations(a: &Folder, b: &Folder) -> Vec<Configuration> {
    let mut out = Vec::new();
    for folder in [a, b] {
        let Some(recorded) = &folder.postures else {
            continue;
        };
        for tool in &recorded.tools {
            for posture in &tool.postures {
                let joints = tool
                    .joints
                    .iter()
                    .enumerate()
                    .filter_map(|(i, joint)| {
                        Some((joint.name.clone(), posture.value(i, &joint.name)?))
                    })
                    .collect();
                out.push((tool.tool.clone(), joints));
            }
        }
    }
    out
}

/// The position of `tool`'s calibrated frame in `folder`'s measurement frame at `joints`.
fn tool_position(folder: &Folder, tool: &str, joints: &[(String, f64)]) -> Result<Vec3> {
    let tree = &folder.tree;
    let q = super::compare_gauge::joint_vector(tree, joints);
    let link = tree.link_id(&scored_link(tree, tree.link_id(tool)?))?;
    Ok((folder.world_from_base * tree.link_pose(link, &q)?)
        .translation
        .vector)
}

/// The displacement between the two calibrations' predictions at every configuration: as
/// deployed (each URDF with its registration), and after the best rigid alignment of B's
/// predictions onto A's (what no re-registration of the tracker removes); with the alignment
/// (A's measurement frame from B's).
fn displacement(
    a: &Folder,
    b: &Folder,
    configurations: &[Configuration],
) -> Result<Option<(Displacement, Pose)>> {
    if configurations.is_empty() {
        return Ok(None);
    }
    let mut pa = Vec::new();
    let mut pb = Vec::new();
    for (tool, joints) in configurations {
        pa.push(tool_position(a, tool, joints)?);
        pb.push(tool_position(b, tool, joints)?);
    }
    let aligned = fit_rigid_transform(&pb, &pa).unwrap_or_else(Pose::identity);
    let rows = configurations
        .iter()
        .zip(pa.iter().zip(&pb))
        .map(|((tool, _), (x, y))| DisplacementRow {
            tool: tool.clone(),
            deployed_mm: (y - x).norm() * 1e3,
            aligned_mm: (aligned.transform_point(&(*y).into()).coords - x).norm() * 1e3,
        })
        .collect();
    Ok(Some((Displacement::of(rows), aligned)))
}

/// B re-expressed in A's measurement frame (see `compare_gauge`): the change of B's root frame
/// the tool alignment `aligned` implies, pushed into B's parameters.
fn reexpression(
    a: &Folder,
    b: &Folder,
    aligned: &Pose,
    configurations: &[Configuration],
) -> Result<Option<Reexpression>> {
    if a.from_reference_link || b.from_reference_link {
        // The root is then a gauge of its own, fixed by parameters of the reference path that
        // a model of the tools' branches does not hold: compared as calibrated.
        return Ok(None);
    }
    let root_change = a.world_from_base.inverse() * aligned * b.world_from_base;
    reexpress(&a.tree, &b.tree, root_change, configurations)
}

/// Compares two calibrate output folders. Writes nothing.
pub fn compare(config: &CompareConfig) -> Result<Comparison> {
    let started = Started::now();
    if !(config.k.is_finite() && config.k > 0.0) {
        return Err(Error::InvalidSetting {
            setting: "k".into(),
            message: format!(
                "{} must be a positive number of standard deviations",
                config.k
            ),
        });
    }
    let a = Folder::read(&config.a)?;
    let b = Folder::read(&config.b)?;
    if a.tree.name() != b.tree.name() {
        return Err(invalid(
            &config.b,
            format!(
                "robot '{}' is not robot '{}' of {}",
                b.tree.name(),
                a.tree.name(),
                config.a.display()
            ),
        ));
    }
    let configurations = configurations(&a, &b);
    let displacement = displacement(&a, &b, &configurations)?;
    let reexpressed = match &displacement {
        Some((_, aligned)) => reexpression(&a, &b, aligned, &configurations)?,
        None => None,
    };
    let (moved, judged) = moved(
        &a.parameters,
        &b.parameters,
        config.k,
        reexpressed.as_ref().map(|r| &r.change),
    );
    let frame_change = reexpressed.as_ref().map(|r| FrameChange {
        translation_mm: r.root_change.translation.vector.norm() * 1e3,
        rotation_deg: r.root_change.rotation.angle().to_degrees(),
        parameters: a
            .parameters
            .iter()
            .filter(|p| r.change.contains_key(&p.name))
            .count(),
        residual_mm: r.residual_m * 1e3,
    });
    let mut report = CompareReport {
        schema_version: crate::report::COMPARE_SCHEMA,
        robot: a.tree.name().to_owned(),
        k: config.k,
        parameters_judged: judged,
        moved,
        frame_change,
        displacement: displacement.map(|(d, _)| d),
        validation: [a.figures(), b.figures()],
        provenance: super::provenance::PROVENANCE_FILE.into(),
    };
    let inputs: Vec<PathBuf> = a.inputs.iter().chain(&b.inputs).cloned().collect();
    let record = super::provenance::record(
        "compare",
        super::provenance::settings_text(config),
        &inputs,
        &[],
        started,
    )?;
    report.provenance = super::provenance::PROVENANCE_FILE.into();
    let markdown = report.markdown();
    let mut files = vec![
        ("report.md".to_owned(), markdown.clone().into_bytes()),
        (
            "report.json".to_owned(),
            crate::io::to_json(&report)?.into_bytes(),
        ),
    ];
    let plot = report.plot()?;
    let plots: Vec<&str> = plot.iter().map(String::as_str).collect();
    files.push((
        "report.html".to_owned(),
        crate::report::markdown_page("treecal compare", &markdown, &plots).into_bytes(),
    ));
    if let Some(svg) = plot {
        files.push(("displacement.svg".to_owned(), svg.into_bytes()));
    }
    files.push((
        super::provenance::PROVENANCE_FILE.to_owned(),
        record.to_yaml()?.into_bytes(),
    ));
    Ok(Comparison {
        report,
        markdown,
        files,
        inputs,
    })
}
