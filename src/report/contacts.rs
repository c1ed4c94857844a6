//! The report of `calibrate --contacts` (issue 29): held-out contacts scored with the training
//! session's plane (primary) and with a plane refitted to them (diagnostic), the registered
//! nominal robot (only the nuisance fitted) as "before"; heights, gaps and lengths in mm, tilts
//! in degrees — contact rows are never called position errors.

use crate::calibration::Nuisance;
use crate::io::ContactKind;
use crate::math::{Pose, Vec3};
use crate::measurement::Contact;
use crate::tree::KinematicTree;
use crate::workflow::{ContactFit, ContactProblem};
use serde_json::json;
use std::fmt::Write as _;

use super::contact_scores::{contact_count, rms, ContactScores, Errors};

/// The plane of `block` at its fitted values, as `(point, normal)` in the reference link.
fn fitted_plane(
    problem: &ContactProblem,
    nuisance: &Nuisance,
    block: usize,
) -> Option<(Vec3, Vec3)> {
    let nominal = problem
        .training
        .iter()
        .chain(&problem.validation)
        .find_map(|m| match m.observation.contact() {
            Some(Contact::Flush { plane, .. } | Contact::Point { plane, .. })
                if plane.block == block =>
            {
                Some(plane.nominal)
            }
            _ => None,
        })?;
    let v = nuisance.block_values(block).ok()?;
    let tilt = nalgebra::Rotation3::from_axis_angle(&Vec3::x_axis(), v[1])
        * nalgebra::Rotation3::from_axis_angle(&Vec3::y_axis(), v[2]);
    let normal = nominal.rotation * (tilt * Vec3::z());
    Some((nominal.translation.vector + normal * v[0], normal))
}

/// report.md and report.json of a contact calibration (`urdf_changes`: joints the exported
/// URDF changes, `None` when it was not written).
pub fn contact_report(
    tree: &KinematicTree,
    problem: &ContactProblem,
    fit: &ContactFit,
    scores: &ContactScores,
    reference: &str,
    urdf_changes: Option<usize>,
    refused: Option<&str>,
) -> (String, serde_json::Value) {
    let usable = urdf_changes.is_some();
    let mut md = format!("# Contact calibration: {}\n\n", tree.name());
    let _ = writeln!(
        md,
        "**Verdict: {}**\n",
        if let Some(reason) = refused {
            format!("not usable — {reason}; calibrated.urdf was not written")
        } else if usable {
            format!(
                "usable — the calibrated robot predicts {} better than the registered nominal \
                 robot, overall and for every tool; calibrated.urdf written (one URDF for all \
                 chains)",
                scores.judged().0.words()
            )
        } else {
            format!(
                "not usable — the calibrated robot does not predict {} better than the \
                 registered nominal robot, overall and for every tool; calibrated.urdf was not \
                 written",
                scores.judged().0.words()
            )
        }
    );
    let kinds: Vec<&str> = problem.kinds.iter().map(|k| k.name()).collect();
    let _ = writeln!(
        md,
        "Reference link: {reference}. Tools: {}. Contacts: {} training, {} held out ({}); \
         sessions: {}.\n",
        tool_words(problem, tree),
        contact_count(&problem.training),
        problem.validation.len(),
        kinds.join(", "),
        sessions_words(problem),
    );
    let tool_names: Vec<String> = problem
        .model
        .tools()
        .iter()
        .map(|t| tree.link(t.link).name.clone())
        .collect();
    md.push_str(&held_out_markdown(scores, HEADER, &tool_names));
    if !problem.planes.is_empty() {
        md.push_str(&refitted_plane_markdown(scores, HEADER));
    }
    md.push_str("## Training fit\n\n");
    let after = &fit.after;
    let _ = writeln!(
        md,
        "{} equations, {} unknowns (joint frames and nuisance), rank {}, σ̂ = {:.3} (the \
         residuals against the setup's σ's), {} iterations ({:?}).\n",
        after.rows,
        fit.free.len(),
        after.rank,
        after.residual_scale,
        after.iterations,
        after.termination,
    );
    md.push_str(HEADER);
    let _ = writeln!(
        md,
        "| registered nominal robot, training contacts | {} |",
        scores.training[0].overall.cells()
    );
    let _ = writeln!(
        md,
        "| calibrated, training contacts | {} |\n",
        scores.training[1].overall.cells()
    );
    md.push_str(&planes_markdown(problem, fit));
    md.push_str(&contact_unobservable_markdown(tree, problem, fit));
    let json = contact_json(tree, problem, fit, scores, reference, urdf_changes);
    (md, json)
}

/// The columns of every contact figure table.
const HEADER: &str = "| robot | contacts | height RMS / max (mm) | tilt RMS / max (°) | gap RMS / \
                      max (mm) | bar length RMS / max (mm) |\n|---|---|---|---|---|---|\n";

/// The held-out figures: each session's training plane (primary, per session when several),
/// then a plane refitted to the held-out contacts (diagnostic).
fn held_out_markdown(scores: &ContactScores, header: &str, tools: &[String]) -> String {
    let mut md = String::new();
    md.push_str(
        "## Held-out contacts, each session's plane as the training fit found it (primary)\n\n",
    );
    if scores.after.overall.count() > 0 || scores.unscored == 0 {
        md.push_str(header);
        let _ = writeln!(
            md,
            "| registered nominal robot (only the nuisance fitted) | {} |",
            scores.before.overall.cells()
        );
        let _ = writeln!(md, "| calibrated | {} |\n", scores.after.overall.cells());
    } else {
        md.push_str("No held-out contact belongs to a session with training contacts.\n\n");
    }
    if scores.unscored > 0 {
        let _ = writeln!(
            md,
            "{} held-out contacts belong to sessions without training contacts (a new table \
             set-up): their plane is unknown to the training fit, so each such session's plane \
             (3 parameters) is fitted to its held-out contacts with the robot held, for both \
             robots below; the verdict counts them.\n",
            scores.unscored
        );
        md.push_str(header);
        let [before, after] = &scores.new_sessions;
        let _ = writeln!(
            md,
            "| registered nominal robot, new sessions (plane fitted to them) | {} |",
            before.overall.cells()
        );
        let _ = writeln!(
            md,
            "| calibrated, new sessions (plane fitted to them) | {} |\n",
            after.overall.cells()
        );
    }
    if scores.after.sessions.len() > 1 {
        let rows = scores
            .after
            .sessions
            .iter()
            .map(|(s, after)| (s.clone(), &scores.before.sessions[s], after));
        md.push_str(&breakdown("session", rows));
    }
    if scores.after.tools.len() > 1 {
        let rows = scores.after.tools.iter().filter_map(|(t, after)| {
            let name = tools
                .get(*t)
                .cloned()
                .unwrap_or_else(|| format!("tool {t}"));
            Some((name, scores.before.tools.get(t)?, after))
        });
        md.push_str(&breakdown("tool", rows));
    }
    md
}

/// The sessions (one plane each) named; touches and bars have none.
fn sessions_words(problem: &ContactProblem) -> String {
    if problem.planes.is_empty() {
        return "none (no plane: touches and bars need no session)".to_owned();
    }
    problem
        .planes
        .keys()
        .cloned()
        .collect::<Vec<_>>()
        .join(", ")
}

/// The diagnostic with a plane refitted to the held-out contacts (only with planes: without
/// one it would repeat the primary table).
fn refitted_plane_markdown(scores: &ContactScores, header: &str) -> String {
    let mut md = String::from(
        "## Diagnostic: a plane refitted to the held-out contacts\n\n(Not the figure to judge \
         by: a refitted plane absorbs a plane that moved and part of the robot's error.)\n\n",
    );
    md.push_str(header);
    let _ = writeln!(
        md,
        "| registered nominal robot | {} |",
        scores.before_refit.overall.cells()
    );
    let _ = writeln!(
        md,
        "| calibrated | {} |\n",
        scores.after_refit.overall.cells()
    );
    md
}

/// The tools by link name, each without a contact in the data marked so (a set-up that names
/// both hands, data of one).
fn tool_words(problem: &ContactProblem, tree: &KinematicTree) -> String {
    let used: std::collections::BTreeSet<usize> = problem
        .training
        .iter()
        .chain(&problem.validation)
        .flat_map(|m| {
            [
                Some(m.tool),
                m.observation.contact().and_then(|c| c.second_tool()),
            ]
        })
        .flatten()
        .collect();
    problem
        .model
        .tools()
        .iter()
        .enumerate()
        .map(|(k, t)| {
            let name = &tree.link(t.link).name;
            if used.contains(&k) {
                name.clone()
            } else {
                format!("{name} (no contacts)")
            }
        })
        .collect::<Vec<_>>()
        .join(", ")
}

/// A table of the held-out height and tilt RMS per `what` (session, tool), before and after.
fn breakdown<'a>(
    what: &str,
    rows: impl Iterator<Item = (String, &'a Errors, &'a Errors)>,
) -> String {
    let mut md = format!(
        "Per {what} (height RMS, tilt RMS):\n\n| {what} | contacts | before | after |\n|---|---|---|---|\n"
    );
    let figure = |e: &Errors| {
        format!(
            "{} mm, {}°",
            rms(&e.heights).map_or("—".into(), |v| format!("{v:.2}")),
            rms(&e.tilts).map_or("—".into(), |v| format!("{v:.3}"))
        )
    };
    for (name, before, after) in rows {
        let _ = writeln!(
            md,
            "| {name} | {} | {} | {} |",
            after.count(),
            figure(before),
            figure(after)
        );
    }
    md.push('\n');
    md
}

/// report.json of a contact calibration (see [`contact_report`]).
fn contact_json(
    tree: &KinematicTree,
    problem: &ContactProblem,
    fit: &ContactFit,
    scores: &ContactScores,
    reference: &str,
    urdf_changes: Option<usize>,
) -> serde_json::Value {
    let after = &fit.after;
    let kinds: Vec<&str> = problem.kinds.iter().map(|k| k.name()).collect();
    json!({
        "schema_version": 1,
        "robot": tree.name(),
        "reference_link": reference,
        "usable": urdf_changes.is_some(),
        "kinds": kinds,
        "training_contacts": contact_count(&problem.training),
        "held_out_contacts": problem.validation.len(),
        "held_out": {
            "training_plane": {"before": scores.before.overall.json(), "after": scores.after.overall.json()},
            "refitted_plane_diagnostic": {"before": scores.before_refit.overall.json(), "after": scores.after_refit.overall.json()},
            "new_sessions_fitted_plane": {"contacts": scores.unscored, "before": scores.new_sessions[0].overall.json(), "after": scores.new_sessions[1].overall.json()},
            "judged": scores.judged().0.key(),
            "sessions": scores.after.sessions.iter().map(|(s, e)| (s.clone(), json!({"before": scores.before.sessions[s].json(), "after": e.json()}))).collect::<serde_json::Map<_, _>>(),
            "tools": scores.after.tools.iter().filter_map(|(t, e)| Some((tree.link(problem.model.tools().get(*t)?.link).name.clone(), json!({"before": scores.before.tools.get(t)?.json(), "after": e.json()})))).collect::<serde_json::Map<_, _>>(),
        },
        "training": {"before": scores.training[0].overall.json(), "after": scores.training[1].overall.json()},
        "rows": after.rows,
        "unknowns": fit.free.len(),
        "rank": after.rank,
        "residual_scale": after.residual_scale,
        "nuisance": (0..after.nuisance.len()).map(|k| json!({"name": after.nuisance.value_name(k), "value": after.nuisance.values()[k]})).collect::<Vec<_>>(),
        "parameters": problem.model.parameter_layout().iter().enumerate().map(|(k, _)| json!({"name": problem.model.parameter_name(tree, k), "value": after.parameters[k]})).collect::<Vec<_>>(),
        "unidentifiable": after.unidentifiable.iter().map(|c| c.describe_with(&problem.model, tree, &after.nuisance)).collect::<Vec<_>>(),
        "urdf_joints_changed": urdf_changes,
    })
}

fn planes_markdown(problem: &ContactProblem, fit: &ContactFit) -> String {
    if problem.planes.is_empty() {
        return String::new();
    }
    let mut md = String::from(
        "## Planes (reference link frame)\n\n| session | fitted point (m) | fitted normal | \
         from the setup's nominal: along its normal (mm), tilt (°) |\n|---|---|---|---|\n",
    );
    let mut fitted = problem.model.clone();
    if fitted.set_parameters(&fit.after.parameters).is_err() {
        return String::new();
    }
    let reference_from_fitted = fitted.world_from_base().inverse();
    let reference_from_start = problem.model.world_from_base().inverse();
    for (session, block) in &problem.planes {
        let Some((point, normal)) = fitted_plane(problem, &fit.after.nuisance, *block) else {
            continue;
        };
        // The planes live in the measurement frame (the tracker's with tracker rows): carried
        // into the reference link through the fitted frame, the setup's through the start's.
        let point = reference_from_fitted.transform_point(&point.into()).coords;
        let normal = reference_from_fitted.rotation * normal;
        let setup: Pose = reference_from_start * problem.setup_planes[session];
        let n0 = setup.rotation * Vec3::z();
        let along = n0.dot(&(point - setup.translation.vector)) * 1e3;
        let tilt = n0.angle(&normal).to_degrees();
        let _ = writeln!(
            md,
            "| {session} | ({:.4}, {:.4}, {:.4}) | ({:.4}, {:.4}, {:.4}) | {along:+.1}, {tilt:.2} |",
            point.x, point.y, point.z, normal.x, normal.y, normal.z
        );
    }
    md.push('\n');
    md
}

/// What the contacts of `problem` cannot determine, in words, and the first combinations the
/// rank decision of `fit` found (report.md's section; `check --contacts` prints it too).
pub fn contact_unobservable_markdown(
    tree: &KinematicTree,
    problem: &ContactProblem,
    fit: &ContactFit,
) -> String {
    let mut md = String::from("## What the contacts cannot determine\n\n");
    let has = |k: ContactKind| problem.kinds.contains(&k);
    if has(ContactKind::Flush) {
        md.push_str(
            "- A plane's height and a contact face's offset along its normal alias exactly: \
             the face offset is held at the setup's value and the plane height absorbs it \
             (a face offset that is wrong moves the fitted plane, not the robot). Where two \
             tools press on the same planes, only the first tool's offset is held; the \
             other's is fitted relative to it (their difference is seen).\n",
        );
    }
    if has(ContactKind::Flush) || has(ContactKind::Point) {
        md.push_str(
            "- A plane sees the contacts relative to itself only: where on the plane and the \
             yaw about its normal carry nothing, and robot errors that move every contact \
             along the plane or rigidly with it are not determined.\n",
        );
    }
    if !has(ContactKind::Flush) && !has(ContactKind::Point) {
        md.push_str(
            "- Touch and bar contacts see the two hands relative to each other only: the \
             common chain (torso, legs) and the robot's placement are not determined and keep \
             their nominal values.\n",
        );
    }
    let unseen = &fit.after.unidentifiable;
    let _ = writeln!(
        md,
        "- {} of {} unknowns are not determined by these contacts (kept at their nominal \
         values){}",
        fit.free.len() - fit.after.rank,
        fit.free.len(),
        if unseen.is_empty() { "." } else { ", e.g.:" }
    );
    for c in unseen.iter().take(5) {
        let _ = writeln!(
            md,
            "  - {}",
            c.describe_with(&problem.model, tree, &fit.after.nuisance)
        );
    }
    md
}
