//! `plan --contact-setup S.yaml --observation flush,touch,…`: choose feasible contact
//! configurations of the nominal robot (a face flush on a setup plane, a contact point on it,
//! the hands touching or holding the bar, within the joint limits: the simulation's
//! generator, [`crate::sim::contact_configurations`]) whose contact rows — weighted by the
//! setup's σ per equation kind, over the robot's joint frames and the nuisance values as
//! `calibrate --contacts` builds them ([`contact_problem`]) — are most informative
//! ([`crate::sim::choose_contacts`]). Computes everything and writes nothing
//! ([`ContactPosePlan::write`] writes the contacts CSV). See docs/contacts.md.

use super::calibrate_contacts::{contact_options, contact_problem};
use super::checker::contact_collisions;
use super::checks::{check_outputs, Output};
use super::contact_fit::{fit_contacts, ContactFit, ContactProblem};
use super::contact_model::{chosen_tools, setup_model};
use super::source::RobotSource;
use super::{Note, Progress, ProgressFn};
use crate::calibration::{weighted_jacobian, Criterion, Rigid};
use crate::error::{Error, Result};
use crate::io::{contacts_to_csv, read_contact_setup, write_atomically, ContactSetup};
use crate::io::{ContactKind, ContactRow};
use crate::kinematics::McpcModel;
use crate::measurement::Contact;
use crate::report::contact_unobservable_markdown;
use crate::sim::{choose_contacts, collision_free_contact_configurations, contact_free_parameters};
use crate::sim::{CollisionCheck, ContactCollisions};
use crate::sim::{ContactChoice, ContactChoiceReport};
use crate::tree::KinematicTree;
use nalgebra::DMatrix;
use rand::rngs::ChaCha8Rng;
use rand::SeedableRng;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Settings of [`plan_contacts`].
#[derive(Debug, Clone)]
pub struct ContactPlanConfig {
    /// The robot.
    pub robot: RobotSource,
    /// The contact setup (YAML): tools, planes, bar, σ's.
    pub setup: PathBuf,
    /// The contact kinds to plan (`simulate --observation`'s names).
    pub kinds: Vec<ContactChoice>,
    /// The setup's tools (by their setup name or link) that make contacts [default: all].
    pub tools: Option<Vec<String>>,
    /// The reference link; overrides the setup's.
    pub reference_link: Option<String>,
    /// Contacts to choose.
    pub poses: usize,
    /// Feasible candidates to choose from.
    pub candidates: usize,
    /// The criterion the sets are scored by.
    pub criterion: Criterion,
    /// Seed of the candidate draws and of the random comparison set.
    pub seed: u64,
    /// Folders searched for `package://` collision meshes.
    pub package_paths: Vec<PathBuf>,
    /// The self-collision check of the candidates (the hands of a touch may meet).
    pub collision_check: CollisionCheck,
}

/// What [`plan_contacts`] chose.
#[derive(Debug, Clone)]
pub struct ContactPosePlan {
    /// What the CLI prints on stderr, in order.
    pub notes: Vec<Note>,
    /// The choice and its scores.
    pub report: ContactChoiceReport,
    /// The chosen contacts (as calibrate's rows; `line` 0).
    pub rows: Vec<ContactRow>,
    /// The random comparison set's contacts.
    pub random_rows: Vec<ContactRow>,
    /// Rank of the chosen contacts as `check --contacts` decides it, and its unknowns.
    pub check_rank: (usize, usize),
    /// The contacts CSV (calibrate's input format, radians and metres).
    pub csv: String,
    /// The summary the CLI prints on stdout.
    pub text: String,
    /// The summary as JSON.
    pub json: serde_json::Value,
}

impl ContactPosePlan {
    /// Writes the contacts CSV to `out`, atomically.
    pub fn write(&self, out: &Path) -> Result<()> {
        write_atomically(out, self.csv.as_bytes())
    }
}

/// Refuses an output that cannot be written or would replace an input.
pub fn check_contact_plan_output(config: &ContactPlanConfig, out: &Path) -> Result<()> {
    let inputs: Vec<&Path> = config
        .robot
        .path()
        .into_iter()
        .chain(std::iter::once(config.setup.as_path()))
        .collect();
    check_outputs(&[Output::File(out)], &inputs)
}

/// Plans the contact configurations; writes nothing.
pub fn plan_contacts(
    config: &ContactPlanConfig,
    progress: ProgressFn<'_>,
) -> Result<ContactPosePlan> {
    if config.poses == 0
        || config.candidates < config.poses
        || config.candidates > crate::limits::MAX_CANDIDATES
        || config.kinds.is_empty()
    {
        return Err(Error::InvalidSetting {
            setting: "poses".into(),
            message: format!(
                "{} contacts of {} candidates ({} kinds): ask for at least one contact kind and \
                 one contact, and between as many candidates and {}",
                config.poses,
                config.candidates,
                config.kinds.len(),
                crate::limits::MAX_CANDIDATES
            ),
        });
    }
    let robot = config.robot.load()?;
    let mut notes = robot.notes();
    let setup = read_contact_setup(&config.setup)?;
    let tree = &robot.import.tree;
    let origin = config.setup.display().to_string();
    let model = setup_model(
        &robot.import,
        (&setup, &config.setup),
        config.reference_link.as_ref(),
        &[],
    )?
    .model;
    let check = (config.package_paths.as_slice(), config.collision_check);
    let collisions = contact_collisions(&config.robot, tree, &model, check, &mut notes)?;
    let tools = chosen_tools(&setup, config.tools.as_deref(), &origin)?;
    let templates = templates(&setup, &tools, &config.kinds, &origin)?;
    let mut rng = ChaCha8Rng::seed_from_u64(config.seed);
    let draws = (&mut rng, collisions.as_ref());
    let candidates = candidate_rows(tree, &model, &setup, &templates, config, draws, progress)?;
    if let Some(collisions) = &collisions {
        notes.push(Note::info(format!(
            "candidates checked for self-collision ({} link pairs; the hands of a touch may \
             meet): {} projected configurations rejected",
            collisions.pair_count(),
            collisions.rejected()
        )));
    }
    let problem = contact_problem(tree, model.clone(), &setup, &candidates, &[], &origin)?;
    let blocks = candidate_blocks(&problem, &setup)?;
    let report = choose_contacts(&blocks, config.poses, config.criterion, &mut rng)?;
    let take = |set: &[usize]| -> Vec<ContactRow> {
        set.iter()
            .enumerate()
            .map(|(k, &c)| ContactRow {
                id: format!("p{}", k + 1),
                ..candidates[c].clone()
            })
            .collect()
    };
    let (rows, random_rows) = (take(&report.chosen), take(&report.random));
    let chosen = contact_problem(tree, model, &setup, &rows, &[], &origin)?;
    let fit = fit_contacts(&chosen, &contact_options(&setup))?;
    let check_rank = (fit.after.rank, fit.free.len());
    let joints: Vec<String> = tree
        .dofs()
        .iter()
        .map(|&j| tree.joint(j).name.clone())
        .collect();
    let csv = contacts_to_csv(&rows, &joints);
    let text = summary(tree, &report, (&chosen, &fit), candidates.len(), config);
    let json = summary_json(tree, &report, (&chosen, &fit), candidates.len());
    Ok(ContactPosePlan {
        notes,
        report,
        rows,
        random_rows,
        check_rank,
        csv,
        text,
        json,
    })
}

/// One row per contact group to plan (its `q` empty): flush and plane per session × tool with
/// a face or point; touch and bar per pair of tools with points.
fn templates(
    setup: &ContactSetup,
    tools: &[String],
    kinds: &[ContactChoice],
    origin: &str,
) -> Result<Vec<ContactRow>> {
    let fail = |message: String| Error::InvalidData {
        origin: origin.to_owned(),
        message,
    };
    let row = |kind, session: &str, tool: &str, tool2: Option<&String>| ContactRow {
        line: 0,
        id: String::new(),
        session: session.to_owned(),
        kind,
        tool: tool.to_owned(),
        spot: None,
        tool2: tool2.cloned(),
        q: Vec::new(),
    };
    let with_point: Vec<&String> = tools
        .iter()
        .filter(|t| setup.tools[*t].point.is_some())
        .collect();
    let mut out = Vec::new();
    for &kind in kinds {
        let before = out.len();
        match kind {
            ContactChoice::Flush | ContactChoice::Plane => {
                if setup.planes.is_empty() {
                    return Err(fail(format!(
                        "{} contacts need a plane: the setup file has no 'planes' (add each \
                         session's nominal plane as a pose in the reference link)",
                        kind.name()
                    )));
                }
                for session in setup.planes.keys() {
                    for tool in tools {
                        let entry = &setup.tools[tool];
                        if kind == ContactChoice::Flush && entry.face.is_some() {
                            out.push(row(ContactKind::Flush, session, tool, None));
                        } else if kind == ContactChoice::Plane && entry.point.is_some() {
                            out.push(row(ContactKind::Point, session, tool, None));
                        }
                    }
                }
            }
            ContactChoice::Touch | ContactChoice::Bar => {
                let kind_of = if kind == ContactChoice::Touch {
                    ContactKind::Touch
                } else {
                    ContactKind::Distance
                };
                for (k, first) in with_point.iter().enumerate() {
                    for second in &with_point[k + 1..] {
                        out.push(row(kind_of, "self", first, Some(second)));
                    }
                }
            }
        }
        if out.len() == before {
            let needs = match kind {
                ContactChoice::Flush => "a tool with a 'face'",
                ContactChoice::Plane => "a tool with a 'point'",
                _ => "two tools with a 'point'",
            };
            return Err(fail(format!(
                "{} contacts need {needs} among the tools planned ({})",
                kind.name(),
                tools.join(", ")
            )));
        }
    }
    Ok(out)
}

/// Feasible candidate rows: each template's contact made by the nominal robot with the
/// setup's nominal planes and contact geometry, `candidates` shared out among the templates.
fn candidate_rows(
    tree: &KinematicTree,
    model: &McpcModel,
    setup: &ContactSetup,
    templates: &[ContactRow],
    config: &ContactPlanConfig,
    (rng, collisions): (&mut ChaCha8Rng, Option<&ContactCollisions>),
    progress: ProgressFn<'_>,
) -> Result<Vec<ContactRow>> {
    // The contacts as calibrate builds them; with no configurations yet, the planes keep the
    // setup's nominal poses (not the closed-form start from rows).
    let origin = config.setup.display().to_string();
    let zero: Vec<ContactRow> = templates
        .iter()
        .map(|t| ContactRow {
            q: vec![0.0; tree.dof_count()],
            ..t.clone()
        })
        .collect();
    let mut problem = contact_problem(tree, model.clone(), setup, &zero, &[], &origin)?;
    for m in &mut problem.training {
        if let Some(Contact::Flush { plane, .. } | Contact::Point { plane, .. }) =
            m.observation.contact_mut()
        {
            let session = m.session.as_deref().unwrap_or_default();
            if let Some(pose) = problem.setup_planes.get(session) {
                plane.nominal = *pose;
            }
        }
    }
    let groups = templates.len().max(1);
    let mut rows = Vec::new();
    for (k, (template, m)) in templates.iter().zip(&problem.training).enumerate() {
        // The candidates shared out: the first `candidates % groups` groups get one more.
        let per_template = config.candidates / groups + usize::from(k < config.candidates % groups);
        let Some(contact) = m.observation.contact() else {
            continue;
        };
        let what = format!(
            "{} contact of tool '{}' (session '{}')",
            template.kind.name(),
            template.tool,
            template.session
        );
        let found = collision_free_contact_configurations(
            tree,
            model,
            &problem.nuisance,
            (contact, m.tool),
            per_template,
            (&mut *rng, collisions),
            &what,
        )?;
        rows.extend(found.into_iter().map(|q| ContactRow {
            q,
            ..template.clone()
        }));
        progress(Progress {
            stage: None,
            done: k + 1,
            total: templates.len(),
            unit: "contact kinds",
        });
    }
    Ok(rows)
}

/// Each candidate's weighted Jacobian rows over the contact fit's unknowns (joint frames and
/// free nuisance values, as [`fit_contacts`] frees them).
fn candidate_blocks(problem: &ContactProblem, setup: &ContactSetup) -> Result<Vec<DMatrix<f64>>> {
    let model = &problem.model;
    let count = model.parameter_count();
    let mut free = contact_free_parameters(model);
    free.extend(problem.free_nuisance.iter().map(|k| count + k));
    free.sort_unstable();
    free.dedup();
    let options = contact_options(setup);
    let (jacobian, _) = weighted_jacobian(
        model,
        &problem.nuisance,
        &problem.training,
        &Rigid,
        &free,
        &options,
    )?;
    let mut row = 0;
    Ok(problem
        .training
        .iter()
        .map(|m| {
            let rows = m.observation.rows();
            let block = jacobian.rows(row, rows).into_owned();
            row += rows;
            block
        })
        .collect())
}

fn summary(
    tree: &KinematicTree,
    report: &ContactChoiceReport,
    (chosen, fit): (&ContactProblem, &ContactFit),
    candidates: usize,
    config: &ContactPlanConfig,
) -> String {
    let mut text = String::new();
    let kinds: Vec<&str> = config.kinds.iter().map(|k| k.name()).collect();
    let _ = writeln!(
        text,
        "contact plan: {} contacts ({}) from {candidates} feasible candidates of the nominal \
         robot (each contact made within the joint limits on the setup's nominal planes and \
         contact geometry; self-collision as the notes say)",
        report.chosen.len(),
        kinds.join(", ")
    );
    let _ = writeln!(
        text,
        "{:?} on the contact Jacobian ({} of {} unknowns determined by the pool): planned \
         {:.4e} (rank {}), random set of the same size {:.4e} (rank {}) ({} exchanges after \
         the greedy pick)",
        report.criterion,
        report.pool_rank,
        report.unknowns,
        report.planned_value,
        report.planned_rank,
        report.random_value,
        report.random_rank,
        report.exchanges
    );
    let _ = writeln!(
        text,
        "the planned contacts as check --contacts sees them: {} equations, {} unknowns, rank {}",
        fit.after.rows,
        fit.free.len(),
        fit.after.rank
    );
    text.push('\n');
    text.push_str(&contact_unobservable_markdown(tree, chosen, fit));
    text
}

fn summary_json(
    tree: &KinematicTree,
    report: &ContactChoiceReport,
    (chosen, fit): (&ContactProblem, &ContactFit),
    candidates: usize,
) -> serde_json::Value {
    serde_json::json!({
        "contacts": report.chosen.len(),
        "candidates": candidates,
        "criterion": report.criterion,
        "planned_value": report.planned_value,
        "random_value": report.random_value,
        "planned_rank": report.planned_rank,
        "random_rank": report.random_rank,
        "pool_rank": report.pool_rank,
        "unknowns": report.unknowns,
        "exchanges": report.exchanges,
        "check": {
            "equations": fit.after.rows,
            "unknowns": fit.free.len(),
            "rank": fit.after.rank,
            "unidentifiable": fit
                .after
                .unidentifiable
                .iter()
                .map(|c| c.describe_with(&chosen.model, tree, &fit.after.nuisance))
                .collect::<Vec<_>>(),
        },
    })
}
