//! Contacts fitted with the pixels from files (`calibrate --camera … --detections …
//! --contacts C.csv --contact-setup S.yaml`, issue 29): the contacts CSV and setup YAML of
//! `calibrate --contacts` read against the camera fit's model (the robot with the rig's
//! frames), their rows and nuisance values handed to the camera fit
//! ([`crate::camera::ContactRows`]), each row kind divided by the setup's σ.

use super::calibrate_contacts::contact_problem;
use super::contact_fit::ContactProblem;
use super::Note;
use crate::calibration::Noise;
use crate::camera::{ContactRows, Unknown};
use crate::error::{Error, Result};
use crate::io::read_contact_setup;
use crate::io::read_contacts;
use crate::kinematics::McpcModel;
use crate::tree::KinematicTree;
use std::path::PathBuf;

/// Contacts given with a camera calibration.
#[derive(Debug, Clone, PartialEq)]
pub struct CameraContactsInput {
    /// The contacts CSV (`docs/file-formats.md` §4e).
    pub contacts: PathBuf,
    /// The contact setup YAML (tools' nominal contact points and faces, planes, bar, σ's).
    pub setup: PathBuf,
}

/// The contacts of a camera calibration, read: their rows and nuisance, and their σ's.
#[derive(Debug, Clone)]
pub(super) struct CameraContacts {
    problem: ContactProblem,
    noise: Noise,
}

impl CameraContacts {
    /// Reads `input` against `model` (the camera fit's augmented model of `tree`). The camera
    /// fit measures from the URDF root: a setup whose reference link is another link is refused.
    pub(super) fn read(
        input: &CameraContactsInput,
        tree: &KinematicTree,
        model: &McpcModel,
        notes: &mut Vec<Note>,
    ) -> Result<Self> {
        let setup = read_contact_setup(&input.setup)?;
        let root = tree.link(tree.root()).name.as_str();
        if let Some(reference) = setup.reference_link.as_deref().filter(|r| r.trim() != root) {
            return Err(Error::InvalidData {
                origin: input.setup.display().to_string(),
                message: format!(
                    "reference link '{reference}': the camera fit measures from the URDF root \
                     '{root}'; leave reference_link out of the setup to fit contacts with pixels"
                ),
            });
        }
        let table = read_contacts(&input.contacts, tree)?;
        if !table.ignored_columns.is_empty() {
            notes.push(Note::warning(format!(
                "{}: columns that are no joint of the robot are ignored: {}",
                input.contacts.display(),
                table.ignored_columns.join(", ")
            )));
        }
        let origin = input.contacts.display().to_string();
        let problem = contact_problem(tree, model.clone(), &setup, &table.rows, &[], &origin)?;
        notes.push(Note::info(format!(
            "{} contacts fitted with the pixels (each row kind by the setup's σ); held-out \
             contacts are not scored in a camera calibration",
            problem.training.len()
        )));
        let noise = Noise {
            height: setup.sigma.height,
            tilt: setup.sigma.tilt,
            gap: setup.sigma.gap,
            length: setup.sigma.length,
            ..Noise::default()
        };
        Ok(Self { problem, noise })
    }

    /// [`Self::read`] of `input`, if given.
    pub(super) fn read_optional(
        input: Option<&CameraContactsInput>,
        (tree, model): (&KinematicTree, &McpcModel),
        notes: &mut Vec<Note>,
    ) -> Result<Option<Self>> {
        input
            .map(|input| Self::read(input, tree, model, notes))
            .transpose()
    }

    /// The rows and their σ's for the camera fit (none, default σ's, without contacts).
    pub(super) fn parts(contacts: Option<&Self>) -> (ContactRows<'_>, Noise) {
        contacts.map_or_else(Default::default, |c| (c.rows(), c.noise()))
    }

    /// The rows for the camera fit.
    pub(super) fn rows(&self) -> ContactRows<'_> {
        ContactRows {
            rows: &self.problem.training,
            nuisance: &self.problem.nuisance,
        }
    }

    /// The nuisance values the fit frees.
    pub(super) fn unknowns(&self) -> impl Iterator<Item = Unknown> + '_ {
        self.problem
            .free_nuisance
            .iter()
            .map(|&k| Unknown::Nuisance(k))
    }

    /// The contact rows' σ's.
    pub(super) fn noise(&self) -> Noise {
        self.noise
    }
}
