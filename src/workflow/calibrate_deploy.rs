//! The deployable outputs of `calibrate` besides `calibrated.urdf`: the joint-origin overlay
//! for xacro (`calibration_overlay.yaml`, from the export itself), the joint zero offsets for a
//! controller (`joint_offsets.yaml`, only when offsets alone carry the calibration) and the
//! report section that says which to use (docs/export.md, "Deploying").

use crate::calibration::CalibrationRun;
use crate::error::Result;
use crate::io::{joint_offsets_to_yaml, overlay_to_yaml, JointOffset};
use crate::kinematics::{FrameKind, McpcModel, ParameterKind, ParameterOwner};
use crate::tree::KinematicTree;
use crate::urdf::{ExportReport, JointOverlay};
use std::fmt::Write;

/// The joint-origin overlay.
pub const OVERLAY_FILE: &str = "calibration_overlay.yaml";
/// The joint zero offsets.
pub const OFFSETS_FILE: &str = "joint_offsets.yaml";
/// The self-contained HTML report.
pub const HTML_FILE: &str = "report.html";
/// The files of this module and of the HTML report (for `is_output_file`).
pub const DEPLOY_FILES: [&str; 3] = [OVERLAY_FILE, OFFSETS_FILE, HTML_FILE];

/// A frame geometry parameter that moved less than this (m or rad) is unchanged.
const GEOMETRY_TOLERANCE: f64 = 1e-12;

/// The deployable files and the report.md section about them.
pub(super) struct Deployable {
    pub files: Vec<(String, Vec<u8>)>,
    pub markdown: String,
}

/// The overlay of `export` (the URDF export of `run`, when there is one) and, when the
/// calibrated model differs from `nominal` by joint zero offsets and tool frames only, the
/// offsets file.
pub(super) fn deployable(
    tree: &KinematicTree,
    nominal: &McpcModel,
    run: &CalibrationRun,
    export: Option<&ExportReport>,
) -> Result<Deployable> {
    let mut files = Vec::new();
    let mut markdown = String::from("## Deploying the calibration\n\n");
    let Some(export) = export else {
        markdown
            .push_str("No calibrated URDF, overlay or offsets were written (see the verdict).\n\n");
        return Ok(Deployable { files, markdown });
    };
    let overlay = JointOverlay::of_export(tree, export)?;
    let comment = format!(
        "Calibrated joint origins of robot '{}' (treecal calibrate): the joints whose origin or axis\n\
         calibrated.urdf changes, in URDF convention (m, rad; R = Rz(yaw)·Ry(pitch)·Rx(roll); axis in the\n\
         joint frame), and the links it adds. Applied to the nominal URDF it gives calibrated.urdf.\n\
         In a xacro (docs/export.md, \"Deploying\"):\n\
         \x20 <xacro:property name=\"calibration\" value=\"${{xacro.load_yaml('{OVERLAY_FILE}')}}\"/>\n\
         \x20 <xacro:property name=\"j\" value=\"${{calibration['joints']['JOINT']}}\"/>\n\
         \x20 <origin xyz=\"${{j['x']}} ${{j['y']}} ${{j['z']}}\" rpy=\"${{j['roll']}} ${{j['pitch']}} ${{j['yaw']}}\"/>\n\
         \x20 <axis xyz=\"${{j['axis'][0]}} ${{j['axis'][1]}} ${{j['axis'][2]}}\"/>",
        tree.name()
    );
    files.push((
        OVERLAY_FILE.into(),
        overlay_to_yaml(&overlay, &comment).into_bytes(),
    ));
    let _ = writeln!(
        markdown,
        "- `calibrated.urdf`: the robot's URDF with {} joint origin(s) changed{}.",
        overlay.joints.len(),
        if overlay.added_links.is_empty() {
            String::new()
        } else {
            format!(" and {} link(s) added", overlay.added_links.len())
        }
    );
    let _ = writeln!(
        markdown,
        "- `{OVERLAY_FILE}`: the same changes for a xacro (`xacro.load_yaml`, lines in docs/export.md); applied to the nominal URDF it gives calibrated.urdf."
    );
    let model = &run.report.model;
    let changed = changed_geometry(nominal, model);
    if changed > 0 {
        let why = format!(
            "the calibration changes {changed} geometry parameter(s) of the joint frames, which joint zero offsets alone cannot carry; deploy calibrated.urdf or {OVERLAY_FILE} (calibrate with `model` offsets for an offsets-only result)"
        );
        let _ = writeln!(markdown, "- no `{OFFSETS_FILE}`: {why}.");
    } else {
        let offsets = joint_offsets(tree, model, run);
        let comment = format!(
            "Joint zero offsets of robot '{}' (treecal calibrate, model without geometry changes): the URDF's\n\
             joint value is the reported one plus the offset; add it to the joint position the robot reports\n\
             (equivalently, move the joint's zero by -offset). With these offsets the nominal URDF places every\n\
             link of the calibrated chains as calibrated.urdf does; the measured tool frames are in\n\
             {OVERLAY_FILE}{}.",
            tree.name(),
            if model.joint_error_terms().harmonics || model.joint_error_terms().backlash {
                "; the harmonic and backlash terms are in joint_errors.yaml"
            } else {
                ""
            }
        );
        files.push((
            OFFSETS_FILE.into(),
            joint_offsets_to_yaml(tree.name(), &offsets, &comment).into_bytes(),
        ));
        let _ = writeln!(
            markdown,
            "- `{OFFSETS_FILE}`: {} joint zero offset(s) for the controller (q_urdf = q_reported + offset); the joint frames' geometry is unchanged, so the nominal URDF with these offsets places the calibrated chains as calibrated.urdf does.",
            offsets.len()
        );
    }
    markdown.push('\n');
    Ok(Deployable { files, markdown })
}

/// How many frame geometry parameters of `model` differ from `nominal`'s.
fn changed_geometry(nominal: &McpcModel, model: &McpcModel) -> usize {
    let values = nominal.parameters();
    nominal
        .parameter_layout()
        .iter()
        .zip(values)
        .filter(|((owner, kind), value)| {
            matches!(owner, ParameterOwner::Frame(_))
                && matches!(
                    kind,
                    ParameterKind::Alpha
                        | ParameterKind::Beta
                        | ParameterKind::Gamma
                        | ParameterKind::X
                        | ParameterKind::Y
                        | ParameterKind::Z
                )
                && (model.parameter(*owner, *kind) - value).abs() > GEOMETRY_TOLERANCE
        })
        .count()
}

/// The joint zero offsets of `model`, with their standard deviations from `run`.
fn joint_offsets(
    tree: &KinematicTree,
    model: &McpcModel,
    run: &CalibrationRun,
) -> Vec<JointOffset> {
    let layout = model.parameter_layout();
    model
        .frames()
        .iter()
        .enumerate()
        .filter_map(|(index, frame)| {
            let offset = model.joint_error_values(index)[0]?;
            let std_dev = layout
                .iter()
                .position(|&(o, k)| o == ParameterOwner::Frame(index) && k == ParameterKind::Offset)
                .and_then(|p| run.parameters.get(p))
                .and_then(|p| p.std_dev);
            Some(JointOffset {
                joint: tree.joint(frame.joint).name.clone(),
                offset,
                std_dev,
                unit: match frame.kind {
                    FrameKind::Revolute => "rad",
                    FrameKind::Prismatic => "m",
                },
            })
        })
        .collect()
}
