//! Stiffness identification: compliance scale factors identified jointly with the MCPC
//! parameters (`--identify-stiffness`).
//!
//! The stiffness file is the prior: every compliance starts at scale 1. Which compliance
//! parameters the data determine is decided first, on the linearisation at the start, with
//! the geometric parameters free (a compliance whose effect the geometry can imitate is not
//! determined): a greedy elimination drops, one at a time, a parameter in an exact null
//! direction, else the one the data determine worst, until every remaining one is determined
//! to better than the prior's relative uncertainty. The rest stay at the prior and are
//! reported. Then a Levenberg–Marquardt iteration fits the geometry and the determined
//! compliances together, with the exact deflected kinematics as the model. See
//! `docs/identification.md` (stiffness identification) and `docs/flexibility.md`, section 11.

mod covariance;
mod fit;
mod names;
mod output;
mod problem;
mod selection;
mod sequence;

pub(super) use names::{describe, label, GROUPS};
pub use names::{name, DETERMINED};
pub use output::identified_stiffness;
pub use selection::{analyse_compliance, ComplianceIdentifiability};
pub use sequence::{calibrate_with_stiffness, without_outliers, Fitted, StiffnessSequence};

use super::options::IdentificationOptions;
use super::solver::Termination;
use crate::error::{Error, Result};
use crate::kinematics::ComplianceKind;
use crate::kinematics::{FlexibilityModel, McpcModel};
use crate::measurement::Measurement;
use crate::tree::KinematicTree;
use problem::Problem;
use selection::select;
use serde::Serialize;

/// Settings of the stiffness identification.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct StiffnessOptions {
    /// Relative standard deviation of the prior compliances (0.5: the stiffness file is right
    /// to ±50 %). A compliance is identified when the data determine its scale to
    /// [`DETERMINED`] of this or better.
    pub prior_sigma: f64,
    /// Iteration limit of the joint fit.
    pub max_iterations: usize,
}

impl Default for StiffnessOptions {
    fn default() -> Self {
        Self {
            prior_sigma: 0.5,
            max_iterations: 100,
        }
    }
}

/// One compliance parameter before and after.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ComplianceEstimate {
    /// E.g. `left_joint2 bending` or `left_joint2 EI_y` (the body the joint moves).
    pub name: String,
    /// The joint (joint compliances) or the joint moving the body (link compliances).
    pub owner: String,
    /// What it scales.
    pub kind: ComplianceKind,
    /// Unit of the stiffness values.
    pub unit: String,
    /// Stiffness of the prior (the stiffness file); infinite for rigid.
    pub prior_stiffness: f64,
    /// Identified stiffness (the prior where not identified).
    pub stiffness: f64,
    /// Identified compliance relative to the prior's (1 = as the file says; 1.5 = 50 % softer).
    pub scale: f64,
    /// Standard deviation of `scale` from the joint fit (identified parameters).
    pub scale_std_dev: Option<f64>,
    /// How well the data alone determine `scale` (geometry free), at the start; infinite when
    /// not at all.
    pub data_std_dev: f64,
    /// Whether it was identified (else kept at the prior).
    pub identified: bool,
    /// The scale the joint fit gave it when that was not physical (≤ 0): it was then held at
    /// the prior and the fit redone without it.
    pub fitted_below_zero: Option<f64>,
}

impl ComplianceEstimate {
    /// Standard deviation of the identified stiffness (its unit), first order.
    pub fn stiffness_std_dev(&self) -> Option<f64> {
        self.scale_std_dev
            .map(|sd| self.prior_stiffness * sd / (self.scale * self.scale))
    }
}

/// What the stiffness identification found.
#[derive(Debug, Clone)]
pub struct StiffnessReport {
    /// The geometry fitted jointly with the compliances.
    pub model: McpcModel,
    /// The prior with the identified compliances (payloads as in the prior).
    pub flexibility: FlexibilityModel,
    /// Every compliance parameter.
    pub estimates: Vec<ComplianceEstimate>,
    /// Weighted cost ½‖r‖² at the start and at the solution.
    pub cost: [f64; 2],
    /// Accepted iterations.
    pub iterations: usize,
    /// Why the iteration stopped.
    pub termination: Termination,
    /// Rank of the joint (geometry + identified compliances) Jacobian at the solution.
    pub rank: usize,
    /// Free parameters of the joint fit (geometric + identified compliances).
    pub free: usize,
    /// `σ̂ = √(2·cost / (rows − rank))`.
    pub residual_scale: f64,
    /// The common scale of all joint compliances and of all link compliances, with its
    /// standard deviation (`None`: not identified, kept at 1).
    pub group_scales: [(f64, Option<f64>); 2],
    /// Compliance combinations the data cannot tell from the geometry or from each other, in
    /// words (kept at the prior).
    pub unidentifiable: Vec<String>,
    /// Scales the data determine but the joint fit put at or below zero (not physical), in
    /// words: held at the prior, the fit redone without them. A compliance held elsewhere (or
    /// the geometry) is then likely off; the verdict warns.
    pub held_below_zero: Vec<String>,
}

/// Identifies the compliance scales of `prior` jointly with the `free` MCPC parameters of
/// `start` from `measurements`. Each row is predicted at its own payload
/// ([`Measurement::payload`], kg at every tool; `None`: the prior's payloads); `payloads`, if
/// given, overrides them, one per measurement.
#[allow(clippy::too_many_arguments)]
pub fn identify_stiffness(
    tree: &KinematicTree,
    start: &McpcModel,
    prior: &FlexibilityModel,
    measurements: &[Measurement],
    payloads: Option<&[f64]>,
    free: &[usize],
    options: &IdentificationOptions,
    stiffness: &StiffnessOptions,
) -> Result<StiffnessReport> {
    let problem = Problem::new(tree, prior, measurements, payloads, free, options)?;
    if !(stiffness.prior_sigma.is_finite() && stiffness.prior_sigma > 0.0) {
        return Err(Error::InvalidData {
            origin: "stiffness prior".into(),
            message: format!(
                "relative uncertainty {} must be positive",
                stiffness.prior_sigma
            ),
        });
    }
    let count = problem.parameters().len() + GROUPS;
    let all: Vec<usize> = (0..count).collect();
    let ones = vec![1.0; count];
    let first = problem.linearise(start, &ones, &all, &[], true)?;
    let selection = select(
        &first,
        free.len(),
        problem.parameters(),
        stiffness.prior_sigma,
        options,
    );
    let mut selection = selection;
    let (mut fit, below_zero) = fit_physical(&problem, start, &mut selection.chosen, stiffness)?;
    let chosen = selection.chosen.clone();
    problem.consider(&mut fit, &chosen, stiffness.prior_sigma)?;
    let mut estimates = problem.estimates(tree, start, &fit, &selection)?;
    for &(k, value) in &below_zero {
        if let Some(estimate) = estimates.get_mut(k) {
            estimate.fitted_below_zero = Some(value);
        }
    }
    // The prior's own payloads, whatever the rows carried.
    let flexibility =
        prior.with_compliance_scales(problem.parameters(), &problem.effective(&fit.scales))?;
    let group_scales = [0, 1].map(|g| {
        let index = problem.parameters().len() + g;
        (
            fit.scales[index],
            chosen
                .iter()
                .position(|&c| c == index)
                .map(|c| fit.factor.row(c).norm()),
        )
    });
    Ok(StiffnessReport {
        model: fit.model,
        flexibility,
        estimates,
        cost: fit.cost,
        iterations: fit.iterations,
        termination: fit.termination,
        rank: fit.rank,
        free: free.len() + chosen.len(),
        residual_scale: fit.residual_scale,
        group_scales,
        unidentifiable: selection
            .combinations
            .iter()
            .map(|c| describe(tree, start, problem.parameters(), c))
            .collect(),
        held_below_zero: below_zero
            .iter()
            .map(|&(k, value)| {
                let name = label(tree, start, problem.parameters(), k);
                format!("{name}: fitted at {value:.3}, below zero; held at the prior")
            })
            .collect(),
    })
}

/// The joint fit over the scales `chosen`, again without those it puts at or below zero (not
/// physical: the data, read through the compliances held at the prior, ask for a negative
/// compliance, so a held compliance or the geometry is off and this one absorbs it) until every
/// fitted scale is positive. Returns the fit and the rejected scales with their fitted values;
/// `chosen` loses them.
fn fit_physical(
    problem: &Problem,
    start: &McpcModel,
    chosen: &mut Vec<usize>,
    stiffness: &StiffnessOptions,
) -> Result<(problem::Fit, Vec<(usize, f64)>)> {
    let mut below_zero = Vec::new();
    loop {
        // A group whose members are all fitted on their own moves nothing.
        let count = problem.parameters().len();
        let followed: Vec<usize> = problem
            .parameters()
            .iter()
            .enumerate()
            .filter(|(j, _)| !chosen.contains(j))
            .map(|(_, p)| count + usize::from(!p.kind.is_joint()))
            .collect();
        chosen.retain(|c| *c < count || followed.contains(c));
        let fit = problem.fit(start, chosen, stiffness.max_iterations)?;
        let effective = problem.effective(&fit.scales);
        let below: Vec<(usize, f64)> = chosen
            .iter()
            .map(|&c| (c, effective.get(c).copied().unwrap_or(fit.scales[c])))
            .filter(|&(_, value)| value <= 0.0)
            .collect();
        if below.is_empty() {
            return Ok((fit, below_zero));
        }
        chosen.retain(|c| below.iter().all(|&(b, _)| b != *c));
        below_zero.extend(below);
    }
}
