//! `simulate --observation flush|plane|touch|bar` (a comma list of contacts): seeded contact
//! trials ([`crate::sim::contacts`]) on the robot, with their summary.md and results.json.

use super::simulate::{SimulateConfig, Simulation};
use super::source::branches;
use super::{Note, Progress, ProgressFn};
use crate::sim::contacts::{run_contact_trial, ContactSimulation, ContactTrial};
use crate::sim::experiment::trial_seed;
use crate::sim::truth::ErrorRanges;
use crate::{McpcModel, Result};
use rayon::prelude::*;
use std::fmt::Write as _;
use std::sync::atomic::{AtomicUsize, Ordering};

/// The contact simulation of `config` (its `contacts` are not empty).
pub(super) fn simulate_contacts(
    config: &SimulateConfig,
    progress: ProgressFn<'_>,
) -> Result<Simulation> {
    let mut notes = Vec::new();
    let robot = config.robot.load()?;
    notes.extend(robot.notes());
    let import = robot.import;
    let tree = &import.tree;
    let branches = branches(
        &import,
        config.tools.as_deref(),
        config.reference_link.as_deref(),
    )?;
    let nominal = McpcModel::from_tree(tree, &branches)?;
    let settings = ContactSimulation {
        kinds: config.contacts.clone(),
        per_kind: config.poses + config.torso_poses,
        encoder_sigma: config.encoder_noise,
        errors: ErrorRanges {
            angle: config.angle_error,
            length: config.length_error,
        },
        ..ContactSimulation::default()
    };
    let done = AtomicUsize::new(0);
    let trials: Vec<ContactTrial> = (0..config.trials)
        .into_par_iter()
        .map(|trial| {
            let result =
                run_contact_trial(tree, &nominal, &settings, trial_seed(config.seed, trial));
            progress(Progress {
                stage: None,
                done: done.fetch_add(1, Ordering::SeqCst) + 1,
                total: config.trials,
                unit: "trials",
            });
            result
        })
        .collect::<Result<_>>()?;
    notes.push(Note::info(
        "contacts: self-collision is not checked for contact configurations yet; a flush \
         face's offset along its normal is held at its nominal value (it aliases the plane's \
         height exactly); tools' offsets are held (they alias the contact points)",
    ));
    if let Some(first) = trials.first() {
        let unseen = first.free.len() - first.rank;
        if unseen > 0 {
            notes.push(Note::warning(format!(
                "the contacts cannot determine {unseen} of {} unknowns (kept at their \
                 nominal values): {}",
                first.free.len(),
                first
                    .report
                    .unidentifiable
                    .iter()
                    .take(3)
                    .map(|c| c.describe_with(&nominal, tree, &first.truth_nuisance))
                    .collect::<Vec<_>>()
                    .join("; ")
            )));
        }
    }
    let names: Vec<&str> = config.contacts.iter().map(|c| c.name()).collect();
    let markdown = markdown(tree.name(), &names, &settings, &trials);
    let rows: Vec<serde_json::Value> = trials
        .iter()
        .map(|t| {
            serde_json::json!({
                "rows": t.report.rows,
                "free": t.free.len(),
                "rank": t.rank,
                "noise_free_held_out": t.noise_free_held_out,
                "held_out": t.held_out,
                "observable_error": t.observable_error,
                "consistency": t.consistency,
                "residual_scale": t.report.residual_scale,
                "iterations": t.report.iterations,
            })
        })
        .collect();
    let results = serde_json::json!({
        "schema_version": 1,
        "robot": tree.name(),
        "observation": names,
        "seed": config.seed,
        "configurations_per_kind": settings.per_kind,
        "encoder_sigma": settings.encoder_sigma,
        "trials": rows,
    });
    Simulation::without_tracker_trials(notes, results, markdown, Vec::new())
}

/// summary.md: one row per trial.
fn markdown(
    robot: &str,
    names: &[&str],
    settings: &ContactSimulation,
    trials: &[ContactTrial],
) -> String {
    let mut text = format!(
        "# Contact simulation: {robot}\n\nContacts: {} ({} configurations each, held-out \
         contacts of the true robot for validation); encoder noise σ = {:e} rad.\n\n\
         | trial | rows | unknowns | rank | held-out residual, noise-free | held-out residual \
         | observable error vs noise-free fit | error / covariance | σ̂ |\n\
         |---|---|---|---|---|---|---|---|---|\n",
        names.join(", "),
        settings.per_kind,
        settings.encoder_sigma,
    );
    for (k, t) in trials.iter().enumerate() {
        let _ = writeln!(
            text,
            "| {} | {} | {} | {} | {:.2e} | {:.2e} | {:.2e} | {} | {:.3} |",
            k + 1,
            t.report.rows,
            t.free.len(),
            t.rank,
            t.noise_free_held_out,
            t.held_out,
            t.observable_error,
            if settings.encoder_sigma > 0.0 {
                format!("{:.2}", t.consistency)
            } else {
                "—".to_owned()
            },
            t.report.residual_scale,
        );
    }
    text.push_str(
        "\nResiduals are heights, gaps and lengths in m and tilts in rad. \"error / \
         covariance\" is √(eᵀC⁺e / rank) of the noisy fit's error in the observable subspace \
         against its covariance C (1: as predicted; — without noise).\n",
    );
    text
}
