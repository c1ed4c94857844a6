//! `treecal check --contacts C.csv --contact-setup S.yaml` (issue 29): what a lab's contacts
//! leave undetermined, in the words of the contact calibration's report, before calibrating.
//!
//! The contacts are built into the calibration's problem (every row a training row, the
//! planes started in closed form) and fitted as `calibrate --contacts` fits them; the rank
//! decision on the actual rows (the SVD, deterministic) names what stays undetermined.

use super::calibrate_contacts::contact_problem;
use super::contact_fit::fit_contacts;
use super::contact_model::setup_model;
use super::note::Note;
use super::source::RobotSource;
use crate::error::Result;
use crate::io::{read_contact_setup, read_contacts};
use crate::report::contact_unobservable_markdown;
use std::fmt::Write as _;
use std::path::PathBuf;

/// Settings of [`check_contacts`].
#[derive(Debug, Clone)]
pub struct ContactCheckConfig {
    /// The robot.
    pub robot: RobotSource,
    /// The contacts CSV.
    pub contacts: PathBuf,
    /// The contacts' setup (YAML).
    pub setup: PathBuf,
    /// The reference link; overrides the setup's.
    pub reference_link: Option<String>,
}

/// What [`check_contacts`] found.
#[derive(Debug, Clone)]
pub struct ContactCheck {
    /// What the CLI prints on stderr, in order.
    pub notes: Vec<Note>,
    /// The text report (markdown).
    pub text: String,
    /// The same as JSON: rows, unknowns, rank, the undetermined combinations.
    pub report: serde_json::Value,
}

/// Reads the robot, the setup and the contacts and says what the contacts determine.
pub fn check_contacts(config: &ContactCheckConfig) -> Result<ContactCheck> {
    let robot = config.robot.load()?;
    let notes = robot.notes();
    let setup = read_contact_setup(&config.setup)?;
    let tree = &robot.import.tree;
    let table = read_contacts(&config.contacts, tree)?;
    let model = setup_model(
        &robot.import,
        (&setup, &config.setup),
        config.reference_link.as_ref(),
        &[],
    )?
    .model;
    let origin = config.contacts.display().to_string();
    let problem = contact_problem(tree, model, &setup, &table.rows, &[], &origin)?;
    let options = super::contact_options(&setup);
    let fit = fit_contacts(&problem, &options)?;
    let after = &fit.after;
    let mut text = format!("# Contact check: {}\n\n", tree.name());
    let _ = writeln!(
        text,
        "{} contacts ({}), {} equations, {} unknowns (joint frames and nuisance), rank {}.\n",
        table.rows.len(),
        problem
            .kinds
            .iter()
            .map(|k| k.name())
            .collect::<Vec<_>>()
            .join(", "),
        after.rows,
        fit.free.len(),
        after.rank
    );
    text.push_str(&contact_unobservable_markdown(tree, &problem, &fit));
    let report = serde_json::json!({
        "schema_version": 1,
        "robot": tree.name(),
        "contacts": table.rows.len(),
        "equations": after.rows,
        "unknowns": fit.free.len(),
        "rank": after.rank,
        "unidentifiable": after
            .unidentifiable
            .iter()
            .map(|c| c.describe_with(&problem.model, tree, &after.nuisance))
            .collect::<Vec<_>>(),
    });
    Ok(ContactCheck {
        notes,
        text,
        report,
    })
}
