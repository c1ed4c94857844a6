//! The length scale of a contact calibration. Flush faces and points on planes, and touching
//! points, fix no length: a mechanism whose joint axes are all scaled about the planes'
//! common point (their intersection, for up to three planes) makes the same contacts, up to
//! the few fixed offsets the model does not scale (the contact faces on the tools, the sole).
//! Encoder noise then pulls a free fit towards a smaller robot (its noise moves the contacts
//! less), down to a collapsed one whose joint axes all pass through one point: measured on a
//! simulated TALOS standing on its left sole, one hand flush on three tables, the full geometry
//! fitted every held-out height to 0.00 mm with the hand at one point in every configuration.
//! Held-out contacts on the same planes cannot see it.
//!
//! So a contact calibration without a length reference (a bar of known length, tracker rows)
//! compares the calibrated robot's size with the nominal robot's: the spread of each tool's
//! points over the training configurations (RMS distance from their centroid). Off by more
//! than [`SCALE_TOLERANCE`] (15 %), the default model choice refits with the prior on the nominal
//! values (which holds the scale), and a result still off fails the verdict.

use super::contact_cv::{ContactCv, ContactModelSpec};
use super::contact_fit::{ContactFit, ContactProblem};
use super::model_choice::{ModelChoice, ModelLevel};
use super::note::Note;
use crate::error::Result;
use crate::kinematics::McpcModel;
use crate::measurement::{Contact, Measurement, Observation};
use std::collections::BTreeMap;

/// How far the calibrated robot's size may be from the nominal robot's (relative): 15 %. A
/// real robot's lengths are known to a few millimetres on a metre; the simulated truths of the
/// tests (±1 cm on every 5–30 cm offset of a small arm) reach ±8 %, and flush contacts on one
/// table hold the scale only through the offsets the model does not scale. The failures this
/// guards against are gross: 0.09–0.11× (collapsed) and 1.19× measured on TALOS.
pub const SCALE_TOLERANCE: f64 = 0.15;

/// Whether the problem's rows fix a length: a bar (`distance`) or rows that are not contacts
/// (tracker positions).
pub(super) fn has_length_reference(problem: &ContactProblem) -> bool {
    problem.training.iter().any(|m| {
        !matches!(
            m.observation.contact(),
            Some(Contact::Flush { .. } | Contact::Point { .. } | Contact::Touch { .. })
        )
    })
}

/// The calibrated robot's size over the nominal robot's: the RMS spread of the tools' origins
/// over the training configurations (each tool about its own centroid), `calibrated` over
/// `nominal`; `None` when the nominal points do not spread.
pub(super) fn size_ratio(
    nominal: &McpcModel,
    calibrated: &McpcModel,
    rows: &[Measurement],
) -> Option<f64> {
    let mut points: BTreeMap<usize, (Vec<_>, Vec<_>)> = BTreeMap::new();
    for m in rows {
        if !matches!(m.observation, Observation::Contact(_)) {
            continue;
        }
        let entry = points.entry(m.tool).or_default();
        entry
            .0
            .push(nominal.tool_pose(m.tool, &m.q).translation.vector);
        entry
            .1
            .push(calibrated.tool_pose(m.tool, &m.q).translation.vector);
    }
    let spread = |p: &[crate::math::Vec3]| {
        let centroid = p.iter().sum::<crate::math::Vec3>() / p.len() as f64;
        p.iter().map(|x| (x - centroid).norm_squared()).sum::<f64>()
    };
    let (nominal, calibrated) = points
        .values()
        .fold((0.0, 0.0), |(n, c), (a, b)| (n + spread(a), c + spread(b)));
    (nominal > 0.0).then(|| (calibrated / nominal).sqrt())
}

/// Whether `ratio` is within [`SCALE_TOLERANCE`] of 1.
pub(super) fn scale_held(ratio: Option<f64>) -> bool {
    ratio.is_none_or(|r| (r - 1.0).abs() <= SCALE_TOLERANCE)
}

/// What [`hold_scale`] found: the kept fit's size over the nominal robot's ([`size_ratio`]),
/// and why the verdict fails when that size is off.
pub(super) struct ScaleCheck {
    /// The kept fit's size ratio (`None`: the nominal tool points do not spread).
    pub ratio: Option<f64>,
    /// Why the verdict fails, when the size stays off.
    pub refused: Option<String>,
}

/// A contact fit: the problem of its model, the fit, the model, the cross-validation.
pub(super) type Fitted = (
    ContactProblem,
    ContactFit,
    ContactModelSpec,
    Option<ContactCv>,
);

/// `fitted` (of the `model` and `prior` asked for) when it keeps the robot's size (the module
/// documentation), or, where the model was the data's choice, `refit` with the prior on the
/// nominal values (which holds the scale); with the reason the verdict fails when the size is
/// still off.
pub(super) fn hold_scale(
    (model, prior): (ModelChoice, Option<f64>),
    base: &ContactProblem,
    fitted: Fitted,
    refit: impl FnOnce(ModelChoice, Option<f64>, &mut Vec<Note>) -> Result<Fitted>,
    notes: &mut Vec<Note>,
) -> Result<(Fitted, ScaleCheck)> {
    let ratio = |(problem, fit, ..): &Fitted| {
        let mut calibrated = problem.model.clone();
        calibrated.set_parameters(&fit.after.parameters).ok()?;
        size_ratio(&problem.model, &calibrated, &problem.training)
    };
    let measured = ratio(&fitted);
    if has_length_reference(base) || scale_held(measured) {
        let check = ScaleCheck {
            ratio: measured,
            refused: None,
        };
        return Ok((fitted, check));
    }
    let first = measured.unwrap_or(1.0);
    let why = "flush, point and touch contacts fix no length, and encoder noise pulls a free \
               fit towards a smaller robot (docs/contacts.md, \"The length scale\")";
    let data_choose = matches!(model, ModelChoice::Adaptive | ModelChoice::Auto);
    if fitted.2.prior || !data_choose {
        let reason = format!(
            "the calibrated robot is {first:.3}× the nominal robot's size (its tools' spread \
             over the training configurations): {why}; use the default model or `prior`, or add \
             a bar of known length or tracker rows"
        );
        notes.push(Note::warning(reason.clone()));
        let check = ScaleCheck {
            ratio: measured,
            refused: Some(reason),
        };
        return Ok((fitted, check));
    }
    let level = if fitted.2.offsets {
        ModelLevel::Offsets
    } else {
        ModelLevel::Geometry
    };
    let refit = refit(ModelChoice::Level(level), Some(prior.unwrap_or(1.0)), notes)?;
    let second = ratio(&refit);
    notes.push(Note::warning(format!(
        "the '{}' fit made the robot {first:.3}× its nominal size (its tools' spread over the \
         training configurations): {why}; refitted with the prior on the nominal values, which \
         holds the scale: '{}', {:.3}×; a bar of known length or tracker rows fix the scale",
        fitted.2.name(),
        refit.2.name(),
        second.unwrap_or(1.0)
    )));
    let refused = (!scale_held(second)).then(|| {
        format!(
            "the calibrated robot is {:.3}× the nominal robot's size even with the prior: {why}",
            second.unwrap_or(1.0)
        )
    });
    let (problem, fit, spec, _) = refit;
    let check = ScaleCheck {
        ratio: second,
        refused,
    };
    Ok(((problem, fit, spec, fitted.3), check))
}
