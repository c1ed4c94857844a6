//! `report.html` of `calibrate`: the robot drawn at the measured configurations (the scene of
//! [`crate::report::html`]) and the page itself.

use super::calibrate_deploy::Deployable;
use super::calibrate_steps::{Data, Identified, Loaded};
use crate::error::Result;
use crate::math::Vec3;
use crate::measurement::{Measurement, Observation};
use crate::report::{calibration_html, CalibrationSummary, HtmlReport, Scene, SceneConfiguration};

/// At most this many configurations in the viewer (validation rows first): enough to browse,
/// small enough that the page stays light on thousands of rows.
pub const MAX_SCENE_CONFIGURATIONS: usize = 300;

/// The page of a calibration.
pub(super) fn report_html(
    loaded: &Loaded,
    data: &Data,
    result: &Identified,
    summary: &CalibrationSummary,
    plots: &[(String, String)],
    deploy: &Deployable,
) -> Result<String> {
    let scene = scene(loaded, data, result, summary);
    let lines: Vec<String> = deploy
        .markdown
        .lines()
        .filter(|l| !l.is_empty() && !l.starts_with('#'))
        .map(|l| l.strip_prefix("- ").unwrap_or(l).to_owned())
        .collect();
    calibration_html(&HtmlReport {
        summary,
        plots,
        deploy: &lines,
        scene: &scene,
    })
}

/// Rounded to a micrometre: the page stays small, the drawing is unchanged.
fn micrometres(v: &Vec3) -> [f64; 3] {
    [v.x, v.y, v.z].map(|c| (c * 1e6).round() / 1e6)
}

/// The calibrated model (with its predicted deflections when compensated) at the validation
/// rows, then the identification rows, in the measurement frame.
fn scene(loaded: &Loaded, data: &Data, result: &Identified, summary: &CalibrationSummary) -> Scene {
    let tree = loaded.robot.tree();
    let model = &result.run.report.model;
    let frames = model.frames();
    let mut names = vec!["base".to_owned()];
    let mut parents = vec![None];
    for frame in frames {
        names.push(tree.link(tree.joint(frame.joint).child).name.clone());
        parents.push(Some(frame.parent.map_or(0, |p| p + 1)));
    }
    let outlier = |set: &str, id: &str| {
        summary
            .outliers
            .iter()
            .any(|o| o.id == id && format!("{:?}", o.set).eq_ignore_ascii_case(set))
    };
    let base = micrometres(&model.world_from_base().translation.vector);
    let mut configurations = Vec::new();
    let sets: [(&str, &[Measurement], &[String]); 2] = [
        ("validation", &data.validation, &data.ids[1]),
        ("identification", &data.measurements, &data.ids[0]),
    ];
    for (set, measurements, ids) in sets {
        for (index, m) in measurements.iter().enumerate() {
            if configurations.len() >= MAX_SCENE_CONFIGURATIONS {
                break;
            }
            let id = ids
                .get(index)
                .cloned()
                .unwrap_or_else(|| format!("#{}", index + 1));
            let mut points = vec![base];
            points.extend(
                model
                    .link_poses(&m.q)
                    .iter()
                    .map(|p| micrometres(&p.translation.vector)),
            );
            let predicted = result
                .flexibility
                .as_ref()
                .and_then(|f| f.deflected_tool_poses(tree, model, &m.q).ok())
                .and_then(|poses| poses.get(m.tool).copied())
                .unwrap_or_else(|| model.tool_pose(m.tool, &m.q))
                .translation
                .vector;
            let measured = match &m.observation {
                Observation::Pose(pose) => pose.translation.vector,
                Observation::Position(point) => *point,
                // A contact measures no point: drawn at its prediction.
                Observation::Contact(_) => predicted,
            };
            let tool = &model.tools()[m.tool];
            configurations.push(SceneConfiguration {
                outlier: outlier(set, &id),
                id,
                set: set.to_owned(),
                tool: tree.link(tool.link).name.clone(),
                points,
                tool_parent: tool.parent.map_or(0, |p| p + 1),
                predicted: micrometres(&predicted),
                measured: micrometres(&measured),
                error_mm: (measured - predicted).norm() * 1e3,
            });
        }
    }
    Scene {
        frame: if summary.sessions.is_some() {
            "the first session's measurement frame (m; rows of other sessions were measured in frames of their own)".into()
        } else {
            "the measurement frame (m)".into()
        },
        names,
        parents,
        configurations,
    }
}
