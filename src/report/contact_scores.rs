//! Contact figures (issue 29): held-out contacts scored with the training session's plane
//! (primary), sessions without training contacts with their plane fitted to their held-out
//! contacts, and every held-out contact with a plane refitted to it (diagnostic); heights,
//! gaps and lengths in mm, tilts in degrees.

use crate::calibration::{identify_with_nuisance, IdentificationOptions, Nuisance, Rigid};
use crate::error::Result;
use crate::kinematics::McpcModel;
use crate::math::Vec3;
use crate::measurement::{Contact, Measurement, Observation};
use crate::workflow::{contact_violations, plane_start, ContactFit, ContactProblem};
use serde_json::json;
use std::collections::{BTreeMap, BTreeSet};

/// Contact violations of one kind of equation, in report units.
#[derive(Debug, Clone, Default)]
pub struct Errors {
    /// Heights above the plane (mm).
    pub heights: Vec<f64>,
    /// Tilts of the face against the plane (degrees).
    pub tilts: Vec<f64>,
    /// Touch gaps (mm, the gap's length).
    pub gaps: Vec<f64>,
    /// Bar length errors (mm).
    pub lengths: Vec<f64>,
}

pub(super) fn rms(values: &[f64]) -> Option<f64> {
    crate::math::root_mean_square(values)
}

fn max_abs(values: &[f64]) -> Option<f64> {
    values.iter().map(|v| v.abs()).reduce(f64::max)
}

impl Errors {
    fn add(&mut self, contact: &Contact, violation: &[f64]) {
        match contact {
            Contact::Flush { .. } => {
                self.heights.push(violation[0] * 1e3);
                let sine = violation[1].hypot(violation[2]).min(1.0);
                self.tilts.push(sine.asin().to_degrees());
            }
            Contact::Point { .. } => self.heights.push(violation[0] * 1e3),
            Contact::Touch { .. } => self
                .gaps
                .push(Vec3::new(violation[0], violation[1], violation[2]).norm() * 1e3),
            Contact::Distance { .. } => self.lengths.push(violation[0] * 1e3),
        }
    }

    /// The number of contacts.
    pub fn count(&self) -> usize {
        self.heights.len().max(self.tilts.len()) + self.gaps.len() + self.lengths.len()
    }

    /// The primary figure: height RMS, else gap RMS, else length RMS (mm).
    pub fn primary(&self) -> Option<f64> {
        rms(&self.heights)
            .or_else(|| rms(&self.gaps))
            .or_else(|| rms(&self.lengths))
    }

    pub(super) fn json(&self) -> serde_json::Value {
        let pair = |v: &[f64]| json!({"count": v.len(), "rms": rms(v), "max": max_abs(v)});
        json!({
            "height_mm": pair(&self.heights),
            "tilt_deg": pair(&self.tilts),
            "gap_mm": pair(&self.gaps),
            "length_mm": pair(&self.lengths),
        })
    }

    pub(super) fn cells(&self) -> String {
        let cell = |v: &[f64], digits: usize| match (rms(v), max_abs(v)) {
            (Some(r), Some(m)) => format!("{r:.digits$} / {m:.digits$}"),
            _ => "—".to_owned(),
        };
        format!(
            "{} | {} | {} | {} | {}",
            self.count(),
            cell(&self.heights, 2),
            cell(&self.tilts, 3),
            cell(&self.gaps, 2),
            cell(&self.lengths, 2)
        )
    }
}

/// Errors overall and per session.
#[derive(Debug, Clone, Default)]
pub struct Scored {
    /// All contacts.
    pub overall: Errors,
    /// Per session.
    pub sessions: BTreeMap<String, Errors>,
    /// Per tool (index among the model's tools; a touch or bar counts for its first tool).
    pub tools: BTreeMap<usize, Errors>,
}

impl Scored {
    fn of(
        model: &McpcModel,
        parameters: &[f64],
        nuisance: &Nuisance,
        rows: &[Measurement],
    ) -> Result<Self> {
        let mut scored = Scored::default();
        for (row, (contact, violation)) in rows
            .iter()
            .zip(contact_violations(model, parameters, nuisance, rows)?)
        {
            scored.overall.add(&contact, &violation);
            let session = row.session.clone().unwrap_or_default();
            scored
                .sessions
                .entry(session)
                .or_default()
                .add(&contact, &violation);
            scored
                .tools
                .entry(row.tool)
                .or_default()
                .add(&contact, &violation);
        }
        Ok(scored)
    }
}

/// The held-out rows scored with the training planes (every row whose session has training
/// rows, and rows without a plane), and the rest (scored only with a refitted plane).
fn scorable(problem: &ContactProblem) -> (Vec<Measurement>, Vec<Measurement>) {
    let trained: BTreeSet<&str> = problem
        .training
        .iter()
        .filter_map(|m| m.session.as_deref())
        .collect();
    problem
        .validation
        .iter()
        .cloned()
        .partition(|m| !has_plane(m) || m.session.as_deref().is_some_and(|s| trained.contains(s)))
}

/// report.md's lines and report.json's entry on calibrated.urdf as written: `written` its
/// held-out scores read back, `after` the calibration's.
pub fn written_contacts(written: &Scored, after: &Scored) -> (String, serde_json::Value) {
    let figure = |e: &Errors| e.primary().map_or("—".to_owned(), |v| format!("{v:.3}"));
    let markdown = format!(
        "**calibrated.urdf as written**, read back and registered with the fitted planes: \
         held-out RMS {} mm (heights, else gaps, else bar lengths) over {} contact(s), the \
         calibration's {} mm.\n\n",
        figure(&written.overall),
        written.overall.count(),
        figure(&after.overall),
    );
    (markdown, written.overall.json())
}

/// The held-out scores of a contact calibration.
#[derive(Debug, Clone)]
pub struct ContactScores {
    /// Registered nominal robot, training planes.
    pub before: Scored,
    /// Calibrated robot, training planes.
    pub after: Scored,
    /// Held-out contacts of sessions without training contacts (a new table set-up), each
    /// session's plane fitted to its held-out contacts with the robot held: registered nominal
    /// robot, calibrated robot. Empty when every held-out session has training contacts.
    pub new_sessions: [Scored; 2],
    /// Registered nominal robot, planes refitted to the held-out contacts (diagnostic).
    pub before_refit: Scored,
    /// Calibrated robot, planes refitted to the held-out contacts (diagnostic).
    pub after_refit: Scored,
    /// Training contacts under the registered nominal robot and the calibrated one.
    pub training: [Scored; 2],
    /// Held-out rows of sessions without training rows (scored in `new_sessions`).
    pub unscored: usize,
}

/// What a contact calibration's verdict compares.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Judged {
    /// Held-out contacts with their training planes (and new sessions' with fitted planes).
    HeldOut,
    /// Only held-out contacts of sessions without training contacts, planes fitted to them.
    NewSessions,
    /// The training contacts (nothing held out).
    Training,
}

impl Judged {
    /// report.json's `held_out.judged`: `held_out`, `new_sessions` or `training`.
    pub fn key(self) -> &'static str {
        match self {
            Judged::HeldOut => "held_out",
            Judged::NewSessions => "new_sessions",
            Judged::Training => "training",
        }
    }

    /// The words of the verdict: "the calibrated robot predicts {words} better …".
    pub fn words(self) -> &'static str {
        match self {
            Judged::HeldOut => "the held-out contacts",
            Judged::NewSessions => {
                "the held-out contacts (all of sessions without training contacts: each \
                 session's plane fitted to its held-out contacts, the robot held)"
            }
            Judged::Training => "its training contacts (no contact was held out)",
        }
    }
}

impl ContactScores {
    /// Scores the fits of `problem` on its held-out contacts.
    pub fn new(
        problem: &ContactProblem,
        fit: &ContactFit,
        options: &IdentificationOptions,
    ) -> Result<Self> {
        let (scorable, rest) = scorable(problem);
        let model = &problem.model;
        let score = |r: &crate::calibration::IdentificationReport, rows: &[Measurement]| {
            Scored::of(model, &r.parameters, &r.nuisance, rows)
        };
        let refit = |r: &crate::calibration::IdentificationReport,
                     rows: &[Measurement]|
         -> Result<Scored> {
            let mut fitted = model.clone();
            fitted.set_parameters(&r.parameters)?;
            refitted(problem, rows, &fitted, &r.nuisance, options)
        };
        let new_sessions = if rest.is_empty() {
            Default::default()
        } else {
            [refit(&fit.before, &rest)?, refit(&fit.after, &rest)?]
        };
        Ok(Self {
            before: score(&fit.before, &scorable)?,
            after: score(&fit.after, &scorable)?,
            new_sessions,
            before_refit: refit(&fit.before, &problem.validation)?,
            after_refit: refit(&fit.after, &problem.validation)?,
            training: [
                score(&fit.before, &problem.training)?,
                score(&fit.after, &problem.training)?,
            ],
            unscored: rest.len(),
        })
    }

    /// The held-out contacts the verdict judges by ([`ContactScores::judged`]), predicted by
    /// `model` at its own parameters (the written calibrated.urdf read back) with the fitted
    /// `nuisance` (new sessions' planes fitted again to their held-out contacts).
    pub fn rescore(
        problem: &ContactProblem,
        model: &McpcModel,
        nuisance: &Nuisance,
        options: &IdentificationOptions,
    ) -> Result<Scored> {
        let (scorable, rest) = scorable(problem);
        if scorable.is_empty() && !rest.is_empty() {
            refitted(problem, &rest, model, nuisance, options)
        } else {
            Scored::of(model, &model.parameters(), nuisance, &scorable)
        }
    }

    /// What the verdict compares, and the calibrated robot's figures there.
    pub fn judged(&self) -> (Judged, &Scored) {
        if self.after.overall.count() > 0 {
            (Judged::HeldOut, &self.after)
        } else if self.new_sessions[1].overall.count() > 0 {
            (Judged::NewSessions, &self.new_sessions[1])
        } else {
            (Judged::Training, &self.training[1])
        }
    }

    /// Whether the calibrated robot beats the registered nominal robot, overall and for every
    /// tool, on the held-out contacts: those with their training planes, and those of new
    /// sessions with their planes fitted to them; on the training contacts when none are held
    /// out.
    pub fn better_than_nominal(&self) -> bool {
        let compare = |before: &Errors, after: &Errors| match (before.primary(), after.primary()) {
            (Some(b), Some(a)) => Some(a < b),
            _ => None,
        };
        // Every tool must gain (both sides of a two-arm fit), not only the total.
        let each = |before: &Scored, after: &Scored| {
            after.tools.iter().all(|(tool, a)| {
                before
                    .tools
                    .get(tool)
                    .and_then(|b| compare(b, a))
                    .unwrap_or(true)
            })
        };
        let gains = |[before, after]: [&Scored; 2]| {
            compare(&before.overall, &after.overall).map(|better| better && each(before, after))
        };
        let known = gains([&self.before, &self.after]);
        let new = gains([&self.new_sessions[0], &self.new_sessions[1]]);
        match (known, new) {
            (None, None) => gains([&self.training[0], &self.training[1]]).unwrap_or(false),
            (known, new) => known.unwrap_or(true) && new.unwrap_or(true),
        }
    }
}

/// The contact rows among `rows` (a mixed fit's training rows also hold tracker rows).
pub(super) fn contact_count(rows: &[Measurement]) -> usize {
    rows.iter()
        .filter(|m| matches!(m.observation, Observation::Contact(_)))
        .count()
}

fn has_plane(m: &Measurement) -> bool {
    matches!(
        m.observation.contact(),
        Some(Contact::Flush { .. } | Contact::Point { .. })
    )
}

/// The held-out contacts `rows` scored with each session's plane refitted to them (the robot
/// and the other nuisance held): planes restart from a closed-form fit to the held-out
/// contacts.
fn refitted(
    problem: &ContactProblem,
    rows: &[Measurement],
    model: &McpcModel,
    nuisance: &Nuisance,
    options: &IdentificationOptions,
) -> Result<Scored> {
    let mut rows = rows.to_vec();
    let mut nuisance = nuisance.clone();
    let mut values = nuisance.values();
    let mut free = Vec::new();
    let count = model.parameter_count();
    for (session, block) in &problem.planes {
        let of_session: Vec<&Measurement> = rows
            .iter()
            .filter(|m| m.session.as_deref() == Some(session) && has_plane(m))
            .collect();
        if of_session.is_empty() {
            continue;
        }
        let setup = problem.setup_planes[session];
        let start = plane_start(model, &nuisance, &of_session, &setup);
        for m in &mut rows {
            if let Some(Contact::Flush { plane, .. } | Contact::Point { plane, .. }) =
                m.observation.contact_mut()
            {
                if plane.block == *block {
                    plane.nominal = start;
                }
            }
        }
        let offset = nuisance.offset(*block);
        for k in 0..3 {
            values[offset + k] = 0.0;
            free.push(count + offset + k);
        }
    }
    nuisance.set_values(&values)?;
    let nuisance = if free.is_empty() {
        nuisance
    } else {
        identify_with_nuisance(model, &nuisance, &rows, None, &Rigid, &free, options)?.nuisance
    };
    Scored::of(model, &model.parameters(), &nuisance, &rows)
}
