//! `simulate --observation flush|plane|touch|bar` (a comma list of contacts): seeded contact
//! trials ([`crate::sim::contacts`]) on the robot, with their summary.md and results.json.

use super::checker::contact_collisions;
use super::simulate::{SimulateConfig, Simulation};
use super::source::NominalRobot;
use super::{Note, Progress, ProgressFn};
use crate::io::{
    contact_setup_to_yaml, BarSetup, ContactSetup, FreeSetup, PoseEntry, SigmaSetup, ToolSetup,
};
use crate::io::{contacts_to_csv, ContactKind, ContactRow};
use crate::math::Pose;
use crate::measurement::{Contact, Measurement, Observation};
use crate::sim::trial_seed;
use crate::sim::ErrorRanges;
use crate::sim::{run_contact_trial, ContactScene, ContactSimulation, ContactTrial};
use crate::{McpcModel, Result};
use nalgebra::{Translation3, UnitQuaternion, Vector3};
use rayon::prelude::*;
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::sync::atomic::{AtomicUsize, Ordering};

/// The contact simulation of `config` (its `contacts` are not empty).
pub(super) fn simulate_contacts(
    config: &SimulateConfig,
    progress: ProgressFn<'_>,
) -> Result<Simulation> {
    let mut notes = Vec::new();
    let NominalRobot {
        import,
        model: nominal,
        ..
    } = config.robot.nominal(
        config.tools.as_deref(),
        config.reference_link.as_deref(),
        &mut notes,
    )?;
    let tree = &import.tree;
    // Every generated configuration is free of self-collision (but for the hands of a touch)
    // by the URDF's collision shapes, `--collision-check` as for tracker trials; a standing
    // robot holds its support leg near its stance (`crate::sim::contact_limits`).
    let mut settings = contact_settings(config);
    let check = (config.package_paths.as_slice(), config.collision_check);
    settings.collisions = contact_collisions(&config.robot, tree, &nominal, check, &mut notes)?;
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
    notes.push(Note::info(format!(
        "contacts: {}; a flush face's offset along its normal is held at its nominal value (it \
         aliases the plane's height exactly); tools' offsets are held (they alias the contact \
         points)",
        collision_words(settings.collisions.as_ref())
    )));
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
                "linear_rank": t.linear_rank,
                "noise_free_held_out": t.noise_free_held_out,
                "held_out": t.held_out,
                "observable_error": t.observable_error,
                "consistency": t.consistency,
                "residual_scale": t.report.residual_scale,
                "true_size_ratio": super::contact_scale::size_ratio(&nominal, &t.truth, &t.scene.measurements),
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
    let mut simulation = Simulation::without_tracker_trials(notes, results, markdown, Vec::new())?;
    if let Some(first) = trials.first() {
        let sigma = config
            .contact_tracker
            .then(|| true_sigmas(first))
            .transpose()?;
        simulation.files.extend(lab_files(
            tree,
            &nominal,
            &first.scene,
            config.reference_link.as_deref(),
            sigma,
        )?);
        if config.contact_tracker {
            simulation
                .files
                .push(tracker_file(tree, &nominal, first, config)?);
        }
    }
    Ok(simulation)
}

/// What the notes say about the self-collision check of the generated configurations.
fn collision_words(collisions: Option<&crate::sim::ContactCollisions>) -> String {
    match collisions {
        None => "simulated contact configurations are not checked for self-collision \
                 (`--collision-check off`)"
            .to_owned(),
        Some(c) => format!(
            "every simulated contact configuration is free of self-collision ({} link pairs \
             checked; the hands of a touch may meet, the support leg is held near its stance; \
             {} projected configurations rejected)",
            c.pair_count(),
            c.rejected()
        ),
    }
}

/// tracker.csv beside trial 1's contacts (`--observation flush,tracker`): the true robot's
/// contact tools seen by a tracker ([`crate::sim::contact_tracker_rows`]), `per_kind`
/// configurations, in the tracker's frame ([`crate::sim::contact_tracker_frame`]).
fn tracker_file(
    tree: &crate::tree::KinematicTree,
    nominal: &McpcModel,
    trial: &ContactTrial,
    config: &SimulateConfig,
) -> Result<(String, Vec<u8>)> {
    use rand::SeedableRng;
    let mut tools: Vec<usize> = trial
        .scene
        .measurements
        .iter()
        .flat_map(|m| {
            let second = match &m.observation {
                Observation::Contact(c) => c.second_tool(),
                _ => None,
            };
            std::iter::once(m.tool).chain(second)
        })
        .collect();
    tools.sort_unstable();
    tools.dedup();
    let mut rng = rand::rngs::ChaCha8Rng::seed_from_u64(config.seed ^ 0x0074_7261_636b_6572);
    let rows = crate::sim::contact_tracker_rows(
        tree,
        &trial.truth,
        &tools,
        config.poses + config.torso_poses,
        (
            &crate::sim::contact_tracker_frame(),
            crate::sim::CONTACT_TRACKER_SIGMA,
        ),
        &mut rng,
    );
    let text = crate::io::measurements_to_csv(tree, nominal, &rows)?;
    Ok(("tracker.csv".to_owned(), text.into_bytes()))
}

/// Each contact row kind's σ as trial 1's recorded configurations really make it: the RMS
/// violation of the true robot's training contacts there (encoder noise; the setup's default
/// where a kind is absent or noise-free), so that a mixed fit weighs the contacts against the
/// tracker rows as they are.
fn true_sigmas(trial: &ContactTrial) -> Result<SigmaSetup> {
    let violations = super::contact_fit::contact_violations(
        &trial.truth,
        &trial.truth.parameters(),
        &trial.truth_nuisance,
        &trial.scene.measurements,
    )?;
    let mut sums: BTreeMap<&str, (f64, usize)> = BTreeMap::new();
    for (contact, values) in &violations {
        let kinds =
            crate::calibration::kind_of(&Observation::Contact(Box::new(*contact))).row_kinds();
        for (kind, v) in kinds.iter().zip(values) {
            let entry = sums.entry(kind.name()).or_default();
            entry.0 += v * v;
            entry.1 += 1;
        }
    }
    let rms = |name: &str, default: f64| {
        sums.get(name)
            .map(|(sum, n)| (sum / *n as f64).sqrt())
            .filter(|s| *s > 1e-12)
            .unwrap_or(default)
    };
    let d = SigmaSetup::default();
    Ok(SigmaSetup {
        height: rms("height", d.height),
        tilt: rms("tilt", d.tilt),
        gap: rms("gap", d.gap),
        length: rms("length", d.length),
    })
}

/// How far the setup file's nominal planes are from the true ones: along the normal (m), in
/// the plane (m) and tilted (rad) — a lab's rough nominal (the TALOS data's are 0.29 m off).
const SETUP_PLANE_ERROR: (f64, f64, f64) = (0.3, 0.1, 0.05);

/// How far the setup file's contact points are from the true ones (m, each coordinate).
const SETUP_POINT_ERROR: f64 = 0.01;

/// Trial 1's contacts as a lab would write them: contacts.csv (training, configurations as
/// recorded), contacts-validation.csv (held out, exact) and contact-setup.yaml (the nominal
/// faces, points and planes, the planes [`SETUP_PLANE_ERROR`] off; σ's `sigma`, else the
/// defaults), for `calibrate --contacts`.
pub(super) fn lab_files(
    tree: &crate::tree::KinematicTree,
    model: &McpcModel,
    scene: &ContactScene,
    reference: Option<&str>,
    sigma: Option<SigmaSetup>,
) -> Result<Vec<(String, Vec<u8>)>> {
    let tool_name = |tool: usize| tree.link(model.tools()[tool].link).name.clone();
    let session = |block: usize| {
        scene.nuisance.blocks[block]
            .name
            .trim_start_matches("plane ")
            .to_owned()
    };
    let mut setup = ContactSetup {
        reference_link: reference.map(str::to_owned),
        tools: BTreeMap::new(),
        planes: BTreeMap::new(),
        bar: None,
        free: FreeSetup::default(),
        sigma: sigma.unwrap_or_default(),
    };
    let rows_of = |rows: &[Measurement], setup: &mut ContactSetup| -> Result<Vec<ContactRow>> {
        let mut out = Vec::new();
        for (k, m) in rows.iter().enumerate() {
            let Some(contact) = m.observation.contact() else {
                continue;
            };
            let name = tool_name(m.tool);
            let entry = tool_entry(setup, &name);
            let (kind, plane, tool2) = match *contact {
                Contact::Flush { plane, face } => {
                    entry.face = Some(PoseEntry::of(&face.nominal));
                    (ContactKind::Flush, Some(plane), None)
                }
                Contact::Point { plane, point } => {
                    entry.point = Some(rough_point(scene.nuisance.block_values(point)?, k));
                    (ContactKind::Point, Some(plane), None)
                }
                Contact::Touch {
                    point,
                    tool2,
                    point2,
                }
                | Contact::Distance {
                    point,
                    tool2,
                    point2,
                    ..
                } => {
                    entry.point = Some(rough_point(scene.nuisance.block_values(point)?, 0));
                    let other = tool_name(tool2);
                    tool_entry(setup, &other).point =
                        Some(rough_point(scene.nuisance.block_values(point2)?, 1));
                    let kind = if matches!(contact, Contact::Touch { .. }) {
                        ContactKind::Touch
                    } else {
                        ContactKind::Distance
                    };
                    (kind, None, Some(other))
                }
            };
            if let Contact::Distance { length, .. } = contact {
                setup.bar = Some(BarSetup {
                    length: scene.nuisance.block_values(*length)?[0],
                    free: false,
                });
            }
            let session_name = match plane {
                Some(plane) => {
                    let name = session(plane.block);
                    setup
                        .planes
                        .entry(name.clone())
                        .or_insert_with(|| PoseEntry::of(&rough_plane(&plane.nominal)));
                    name
                }
                None => "self".to_owned(),
            };
            out.push(ContactRow {
                line: 0,
                id: format!("c{}", k + 1),
                session: session_name,
                kind,
                tool: name,
                spot: None,
                tool2,
                q: m.q.clone(),
            });
        }
        Ok(out)
    };
    let training = rows_of(&scene.measurements, &mut setup)?;
    let validation = rows_of(&scene.validation, &mut setup)?;
    let joints: Vec<String> = tree
        .dofs()
        .iter()
        .map(|&j| tree.joint(j).name.clone())
        .collect();
    Ok(vec![
        (
            "contacts.csv".to_owned(),
            contacts_to_csv(&training, &joints).into_bytes(),
        ),
        (
            "contacts-validation.csv".to_owned(),
            contacts_to_csv(&validation, &joints).into_bytes(),
        ),
        (
            "contact-setup.yaml".to_owned(),
            contact_setup_to_yaml(&setup)?.into_bytes(),
        ),
    ])
}

/// The setup's entry of the tool at link `name` (created without face or point).
fn tool_entry<'a>(setup: &'a mut ContactSetup, name: &str) -> &'a mut ToolSetup {
    setup
        .tools
        .entry(name.to_owned())
        .or_insert_with(|| ToolSetup {
            link: name.to_owned(),
            face: None,
            point: None,
        })
}

/// A true contact point as a lab's nominal: [`SETUP_POINT_ERROR`] off, deterministic.
fn rough_point(values: &[f64], salt: usize) -> [f64; 3] {
    let sign = |k: usize| if (k + salt) % 2 == 0 { 1.0 } else { -1.0 };
    [0, 1, 2].map(|k| values[k] + SETUP_POINT_ERROR * sign(k))
}

/// A true plane as a lab's nominal: moved along its normal and in the plane, and tilted
/// ([`SETUP_PLANE_ERROR`]).
fn rough_plane(plane: &Pose) -> Pose {
    let (along, across, tilt) = SETUP_PLANE_ERROR;
    let moved = plane.rotation * Vector3::new(across, 0.0, along);
    Pose::from_parts(
        Translation3::from(plane.translation.vector + moved),
        plane.rotation * UnitQuaternion::from_euler_angles(tilt, 0.0, 0.0),
    )
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
         | observable error vs noise-free fit | directions compared | error / covariance | σ̂ \
         |\n|---|---|---|---|---|---|---|---|---|---|\n",
        names.join(", "),
        settings.per_kind,
        settings.encoder_sigma,
    );
    for (k, t) in trials.iter().enumerate() {
        let _ = writeln!(
            text,
            "| {} | {} | {} | {} | {:.2e} | {:.2e} | {:.2e} | {} | {} | {:.3} |",
            k + 1,
            t.report.rows,
            t.free.len(),
            t.rank,
            t.noise_free_held_out,
            t.held_out,
            t.observable_error,
            t.linear_rank,
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
         against its covariance C (1: as predicted; — without noise), over the directions \
         compared: those whose standard deviation is below 1 cm or 10 mrad (weaker ones are \
         not linear over their spread).\n",
    );
    text
}

/// The contact simulation's settings from the simulate config: per kind `poses + torso_poses`
/// configurations, the encoder noise, the tables and the geometry error ranges.
pub(super) fn contact_settings(config: &SimulateConfig) -> ContactSimulation {
    ContactSimulation {
        kinds: config.contacts.clone(),
        per_kind: config.poses + config.torso_poses,
        encoder_sigma: config.encoder_noise,
        tables: config.contact_tables.0,
        tracker_rows: config.contact_tracker,
        flush_tools: config.contact_tables.1,
        errors: ErrorRanges {
            angle: config.angle_error,
            length: config.length_error,
        },
        ..ContactSimulation::default()
    }
}
