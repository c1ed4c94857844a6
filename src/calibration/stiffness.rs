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

use super::solver::{column_scales, scale_columns, singular_decomposition};
use super::solver::{IdentificationOptions, Termination};
use crate::error::{Error, Result};
use crate::kinematics::flexibility::{
    ComplianceBasis, ComplianceKind, ComplianceParameter, JointStiffness, LinkStiffness, Stiffness,
};
use crate::kinematics::{FlexibilityModel, McpcModel};
use crate::math::{pose_error, Pose};
use crate::measurement::{Measurement, Observation};
use crate::tree::KinematicTree;
use nalgebra::{DMatrix, DVector, Vector6};
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
}

/// Identifies the compliance scales of `prior` jointly with the `free` MCPC parameters of
/// `start` from `measurements`. `payloads`, if given, is the payload at every tool for each
/// measurement (kg; replaces the prior's payloads for that row).
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
    let first = problem.linearise(start, &ones, &all, true)?;
    let selection = select(
        &first,
        free.len(),
        problem.parameters(),
        stiffness.prior_sigma,
        options,
    );
    let chosen = selection.chosen.clone();
    let fit = problem.fit(start, &chosen, stiffness.max_iterations)?;
    let estimates = problem.estimates(tree, start, &fit, &selection)?;
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
                .map(|c| fit.scales[index] * fit.log_covariance[(c, c)].max(0.0).sqrt()),
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
    })
}

/// Common scale factors after the individual ones: all joint compliances, all link compliances.
/// A compliance's scale is its own times its group's, so a stiffness file that is off by the
/// same factor everywhere is corrected everywhere, also where the data cannot tell one joint or
/// link from another.
const GROUPS: usize = 2;

/// A compliance is identified when the data alone determine its scale to this fraction of the
/// prior's uncertainty or better (a third: the data carry nine times the prior's information),
/// so that what is identified is determined by the data rather than fitted to their noise.
pub const DETERMINED: f64 = 1.0 / 3.0;

/// The groups in words.
const GROUP_NAMES: [&str; GROUPS] = ["all joints", "all links"];

/// "left_joint1 bending (+0.71) with torso_joint2 EI_z (−0.71)".
fn describe(
    tree: &KinematicTree,
    model: &McpcModel,
    parameters: &[ComplianceParameter],
    terms: &[(usize, f64)],
) -> String {
    terms
        .iter()
        .map(|&(k, w)| {
            let name = match parameters.get(k) {
                Some(parameter) => name(tree, model, parameter),
                None => GROUP_NAMES[k - parameters.len()].to_owned(),
            };
            format!("{name} ({w:+.2})")
        })
        .collect::<Vec<_>>()
        .join(" with ")
}

/// `left_joint2 bending`, `left_joint2 EI_y`.
pub fn name(tree: &KinematicTree, model: &McpcModel, parameter: &ComplianceParameter) -> String {
    format!(
        "{} {}",
        tree.joint(model.frames()[parameter.frame].joint).name,
        parameter.kind.name()
    )
}

/// The measurements, grouped by payload, with one compliance basis per payload.
struct Problem<'a> {
    tree: &'a KinematicTree,
    measurements: &'a [Measurement],
    /// Per distinct payload (`None`: the prior's own), its basis.
    bases: Vec<(Option<f64>, ComplianceBasis)>,
    /// Per measurement, its basis.
    basis_of: Vec<usize>,
    free: &'a [usize],
    options: &'a IdentificationOptions,
}

/// A linearisation: weighted residual and Jacobian, columns `[free geometry, compliances]`.
struct Linearisation {
    residual: DVector<f64>,
    jacobian: DMatrix<f64>,
}

struct Fit {
    model: McpcModel,
    scales: Vec<f64>,
    cost: [f64; 2],
    iterations: usize,
    termination: Termination,
    rank: usize,
    residual_scale: f64,
    /// Covariance of the logarithms of the chosen scales, in `chosen` order.
    log_covariance: DMatrix<f64>,
}

impl<'a> Problem<'a> {
    fn new(
        tree: &'a KinematicTree,
        prior: &FlexibilityModel,
        measurements: &'a [Measurement],
        payloads: Option<&[f64]>,
        free: &'a [usize],
        options: &'a IdentificationOptions,
    ) -> Result<Self> {
        let bad = |message: String| Error::InvalidData {
            origin: "stiffness identification".into(),
            message,
        };
        if measurements.is_empty() {
            return Err(bad("no measurements".into()));
        }
        let mut bases: Vec<(Option<f64>, ComplianceBasis)> = Vec::new();
        let mut basis_of = Vec::with_capacity(measurements.len());
        match payloads {
            None => {
                bases.push((None, ComplianceBasis::new(prior)));
                basis_of.resize(measurements.len(), 0);
            }
            Some(payloads) => {
                if payloads.len() != measurements.len() {
                    return Err(bad(format!(
                        "{} payloads for {} measurements",
                        payloads.len(),
                        measurements.len()
                    )));
                }
                for &mass in payloads {
                    let index = match bases.iter().position(|(m, _)| *m == Some(mass)) {
                        Some(index) => index,
                        None => {
                            let model = prior.with_payload_at_every_tool(mass)?;
                            bases.push((Some(mass), ComplianceBasis::new(&model)));
                            bases.len() - 1
                        }
                    };
                    basis_of.push(index);
                }
            }
        }
        Ok(Self {
            tree,
            measurements,
            bases,
            basis_of,
            free,
            options,
        })
    }

    fn parameters(&self) -> &[ComplianceParameter] {
        self.bases[0].1.parameters()
    }

    /// Each parameter's scale times its group's.
    fn effective(&self, scales: &[f64]) -> Vec<f64> {
        let count = self.parameters().len();
        self.parameters()
            .iter()
            .enumerate()
            .map(|(k, p)| scales[k] * scales[count + usize::from(!p.kind.is_joint())])
            .collect()
    }

    /// Weighted residual and, if asked, the Jacobian over the free geometry and the compliance
    /// scales `chosen`: the compliance columns exact (see `ComplianceBasis::jacobian`), the
    /// geometric ones by forward differences of the deflected poses (a deflection changes with
    /// the geometry through its lever arms, which the deflected-chain Jacobian leaves out; with
    /// compliances moving by tens of percent that slows the joint fit to a crawl).
    fn linearise(
        &self,
        model: &McpcModel,
        scales: &[f64],
        chosen: &[usize],
        with_jacobian: bool,
    ) -> Result<Linearisation> {
        let rows: usize = self.measurements.iter().map(|m| m.observation.rows()).sum();
        let columns = self.free.len() + chosen.len();
        let mut residual = DVector::zeros(rows);
        let mut jacobian = DMatrix::zeros(if with_jacobian { rows } else { 0 }, columns);
        let weights = [
            1.0 / self.options.position_sigma,
            1.0 / self.options.rotation_sigma,
        ];
        let effective = self.effective(scales);
        let flexibilities = self
            .bases
            .iter()
            .map(|(_, b)| b.scaled(&effective))
            .collect::<Result<Vec<_>>>()?;
        // Distinct (configuration, payload) pairs: several tools measured there share them.
        let mut groups: Vec<(&[f64], usize)> = Vec::new();
        let group_of: Vec<usize> = self
            .measurements
            .iter()
            .zip(&self.basis_of)
            .map(|(m, &basis)| {
                let key = (m.q.as_slice(), basis);
                match groups.iter().rposition(|g| *g == key) {
                    Some(g) => g,
                    None => {
                        groups.push(key);
                        groups.len() - 1
                    }
                }
            })
            .collect();
        let mut poses: Vec<Vec<Pose>> = Vec::with_capacity(groups.len());
        let mut compliance: Vec<Vec<DMatrix<f64>>> = Vec::new();
        for &(q, basis) in &groups {
            if with_jacobian {
                let found = self.bases[basis]
                    .1
                    .jacobian(&effective, self.tree, model, q)?;
                poses.push(found.poses);
                compliance.push(found.jacobians);
            } else {
                poses.push(flexibilities[basis].deflected_tool_poses(self.tree, model, q)?);
            }
        }
        // Per group and free parameter, the change of every tool pose per unit parameter.
        let mut geometry: Vec<Vec<Vec<Vector6<f64>>>> = Vec::new();
        if with_jacobian {
            geometry = vec![Vec::with_capacity(self.free.len()); groups.len()];
            let step = 1e-7;
            let values = model.parameters();
            let mut shifted = model.clone();
            for &p in self.free {
                shifted.set_parameter(p, values[p] + step)?;
                for (g, &(q, basis)) in groups.iter().enumerate() {
                    let moved =
                        flexibilities[basis].deflected_tool_poses(self.tree, &shifted, q)?;
                    geometry[g].push(
                        moved
                            .iter()
                            .zip(&poses[g])
                            .map(|(a, b)| pose_error(a, b) / step)
                            .collect(),
                    );
                }
                shifted.set_parameter(p, values[p])?;
            }
        }
        let mut row = 0;
        for (index, m) in self.measurements.iter().enumerate() {
            let g = group_of[index];
            let predicted = poses[g].get(m.tool).ok_or_else(|| Error::InvalidData {
                origin: "stiffness identification".into(),
                message: format!("measurement {index} names tool {}", m.tool),
            })?;
            let error = raw_residual(&m.observation, predicted);
            let count = m.observation.rows();
            for k in 0..count {
                let weight = weights[k / 3];
                residual[row + k] = error[k] * weight;
                if with_jacobian {
                    for (column, change) in geometry[g].iter().enumerate() {
                        jacobian[(row + k, column)] = change[m.tool][k] * weight;
                    }
                    // Columns per unit log-scale (d/d ln s = s·d/ds): the fit moves ln s, so a
                    // compliance never turns negative and a large step is a factor, not a jump.
                    let per_unit = &compliance[g][m.tool];
                    for (column, &c) in chosen.iter().enumerate() {
                        let value = match self.parameters().get(c) {
                            Some(_) => per_unit[(k, c)] * effective[c],
                            // A group: the sum over its members.
                            None => self
                                .parameters()
                                .iter()
                                .enumerate()
                                .filter(|(_, p)| {
                                    usize::from(!p.kind.is_joint()) == c - self.parameters().len()
                                })
                                .map(|(j, _)| per_unit[(k, j)] * effective[j])
                                .sum(),
                        };
                        jacobian[(row + k, self.free.len() + column)] = value * weight;
                    }
                }
            }
            row += count;
        }
        Ok(Linearisation { residual, jacobian })
    }

    /// Levenberg–Marquardt over the free geometry and the logarithms of the compliance scales
    /// `chosen`, with SVD-truncated steps (directions the data cannot determine stay where they
    /// start).
    fn fit(&self, start: &McpcModel, chosen: &[usize], max_iterations: usize) -> Result<Fit> {
        let count = self.parameters().len() + GROUPS;
        let mut model = start.clone();
        let mut scales = vec![1.0; count];
        let mut lin = self.linearise(&model, &scales, chosen, true)?;
        let mut cost = 0.5 * lin.residual.norm_squared();
        let initial_cost = cost;
        let mut damping = 0.0;
        let mut iterations = 0;
        let mut termination = Termination::MaxIterations;
        let tolerance = self.options.rank_tolerance;
        while iterations < max_iterations {
            let columns = column_scales(&lin.jacobian);
            let scaled = scale_columns(&lin.jacobian, &columns);
            let gradient = scaled.tr_mul(&lin.residual);
            let (singular, v_t) = singular_decomposition(scaled);
            let largest = singular.max();
            let step_for = |damping: f64| -> DVector<f64> {
                let mut step = DVector::zeros(columns.len());
                for (i, &sigma) in singular.iter().enumerate() {
                    if sigma > tolerance * largest {
                        let v = v_t.row(i).transpose();
                        step += &v * (v.dot(&gradient) / (sigma * sigma + damping));
                    }
                }
                step.component_div(&columns)
            };
            if step_for(0.0).component_mul(&columns).norm() <= 1e-12 * (1.0 + largest) {
                termination = Termination::StepConverged;
                break;
            }
            let mut accepted = None;
            for _ in 0..30 {
                let step = step_for(damping);
                let (trial_model, trial_scales) = self.moved(&model, &scales, chosen, &step)?;
                let trial_cost = match &trial_scales {
                    Some(s) => {
                        0.5 * self
                            .linearise(&trial_model, s, chosen, false)?
                            .residual
                            .norm_squared()
                    }
                    None => f64::INFINITY,
                };
                if trial_cost < cost {
                    accepted = Some((trial_model, trial_scales, trial_cost));
                    damping *= 0.1;
                    break;
                }
                damping = if damping == 0.0 {
                    1e-6 * largest * largest
                } else {
                    damping * 10.0
                };
            }
            let Some((trial_model, Some(trial_scales), trial_cost)) = accepted else {
                termination = Termination::NoDecrease;
                break;
            };
            let decrease = cost - trial_cost;
            model = trial_model;
            scales = trial_scales;
            cost = trial_cost;
            iterations += 1;
            lin = self.linearise(&model, &scales, chosen, true)?;
            if decrease <= 1e-12 * cost.max(f64::MIN_POSITIVE) || cost < 1e-24 {
                termination = Termination::CostConverged;
                break;
            }
        }
        let (rank, residual_scale, full) = covariance(&lin, cost, tolerance);
        let offset = self.free.len();
        let log_covariance = full
            .view((offset, offset), (chosen.len(), chosen.len()))
            .into_owned();
        Ok(Fit {
            model,
            scales,
            cost: [initial_cost, cost],
            iterations,
            termination,
            rank,
            residual_scale,
            log_covariance,
        })
    }

    /// The model and scales after `step` (geometry additive, compliance scales by the factor
    /// `exp(step)`; `None` scales if one is not finite).
    fn moved(
        &self,
        model: &McpcModel,
        scales: &[f64],
        chosen: &[usize],
        step: &DVector<f64>,
    ) -> Result<(McpcModel, Option<Vec<f64>>)> {
        let mut values = model.parameters();
        for (k, &p) in self.free.iter().enumerate() {
            values[p] += step[k];
        }
        let mut moved = model.clone();
        moved.set_parameters(&values)?;
        let mut next = scales.to_vec();
        for (k, &c) in chosen.iter().enumerate() {
            next[c] *= step[self.free.len() + k].exp();
        }
        let valid = next.iter().all(|s| s.is_finite() && *s >= 0.0);
        Ok((moved, valid.then_some(next)))
    }

    fn estimates(
        &self,
        tree: &KinematicTree,
        model: &McpcModel,
        fit: &Fit,
        selection: &Selection,
    ) -> Result<Vec<ComplianceEstimate>> {
        let reference = self.bases[0].1.reference();
        Ok(self
            .parameters()
            .iter()
            .enumerate()
            .map(|(k, parameter)| {
                let prior = reference.compliance(parameter).recip();
                let effective = self.effective(&fit.scales);
                let scale = effective[k];
                let position = |index: usize| selection.chosen.iter().position(|&c| c == index);
                let chosen = position(k);
                let group =
                    position(self.parameters().len() + usize::from(!parameter.kind.is_joint()));
                // var(ln s·g) = var(ln s) + var(ln g) + 2·cov.
                let c = &fit.log_covariance;
                let variance = match (chosen, group) {
                    (Some(a), Some(b)) => Some(c[(a, a)] + c[(b, b)] + 2.0 * c[(a, b)]),
                    (Some(a), None) | (None, Some(a)) => Some(c[(a, a)]),
                    (None, None) => None,
                };
                ComplianceEstimate {
                    name: name(tree, model, parameter),
                    owner: tree
                        .joint(model.frames()[parameter.frame].joint)
                        .name
                        .clone(),
                    kind: parameter.kind,
                    unit: parameter.kind.stiffness_unit().into(),
                    prior_stiffness: prior,
                    stiffness: prior / scale,
                    scale,
                    scale_std_dev: variance
                        .map(|v| scale * v.max(0.0).sqrt())
                        .filter(|s| s.is_finite()),
                    data_std_dev: selection.data_std_dev[k],
                    identified: chosen.is_some(),
                }
            })
            .collect())
    }
}

fn raw_residual(measured: &Observation, predicted: &Pose) -> Vector6<f64> {
    match measured {
        Observation::Pose(pose) => pose_error(pose, predicted),
        Observation::Position(p) => {
            let d = p - predicted.translation.vector;
            Vector6::new(d.x, d.y, d.z, 0.0, 0.0, 0.0)
        }
    }
}

/// Rank, `σ̂` and the covariance `σ̂²·(JᵀJ)⁺` of the columns.
fn covariance(lin: &Linearisation, cost: f64, tolerance: f64) -> (usize, f64, DMatrix<f64>) {
    let columns = column_scales(&lin.jacobian);
    let (singular, v_t) = singular_decomposition(scale_columns(&lin.jacobian, &columns));
    let largest = singular.max();
    let kept: Vec<usize> = (0..singular.len())
        .filter(|&i| singular[i] > tolerance * largest)
        .collect();
    let rows = lin.jacobian.nrows();
    let residual_scale = if rows > kept.len() {
        (2.0 * cost / (rows - kept.len()) as f64).sqrt()
    } else {
        f64::NAN
    };
    // W = S⁻¹·V_k·Σ_k⁻¹; covariance σ̂²·W·Wᵀ.
    let n = columns.len();
    let w = DMatrix::from_fn(n, kept.len(), |k, j| {
        v_t[(kept[j], k)] / singular[kept[j]] / columns[k]
    });
    let covariance = (&w * w.transpose()) * residual_scale.powi(2);
    (kept.len(), residual_scale, covariance)
}

/// Which compliances the data determine, and how well.
struct Selection {
    /// Indices of the identified compliance parameters.
    chosen: Vec<usize>,
    /// Per parameter: how well the data determine its scale with the geometry free (and the
    /// other chosen compliances free), infinite when not at all.
    data_std_dev: Vec<f64>,
    /// Null directions met on the way, as (parameter, weight) lists.
    combinations: Vec<Vec<(usize, f64)>>,
}

/// Greedy elimination on the compliance information left after the geometry has taken its
/// share (the Schur complement): drop a parameter of an exact null direction first, else the
/// least determined one, until all left are determined to better than `prior_sigma`. Uses the
/// assumed σ's (the rows are weighted by them), not the residuals: the choice does not depend
/// on the noise realised.
fn select(
    lin: &Linearisation,
    geometry: usize,
    parameters: &[ComplianceParameter],
    prior_sigma: f64,
    options: &IdentificationOptions,
) -> Selection {
    let compliance_count = lin.jacobian.ncols() - geometry;
    let individual = compliance_count - GROUPS;
    let geometric = lin.jacobian.columns(0, geometry).into_owned();
    let compliance = lin
        .jacobian
        .columns(geometry, compliance_count)
        .into_owned();
    // An orthonormal basis of what the geometry can explain.
    let basis = if geometry > 0 {
        let scaled = scale_columns(&geometric, &column_scales(&geometric));
        let svd = scaled.svd(true, false);
        let largest = svd.singular_values.max();
        match svd.u {
            Some(u) => {
                let kept: Vec<usize> = (0..svd.singular_values.len())
                    .filter(|&i| svd.singular_values[i] > options.rank_tolerance * largest)
                    .collect();
                DMatrix::from_fn(u.nrows(), kept.len(), |r, c| u[(r, kept[c])])
            }
            None => DMatrix::zeros(lin.jacobian.nrows(), 0),
        }
    } else {
        DMatrix::zeros(lin.jacobian.nrows(), 0)
    };
    let left = &compliance - &basis * basis.tr_mul(&compliance);
    let largest_column = compliance
        .column_iter()
        .map(|c| c.norm())
        .fold(0.0, f64::max);
    let mut data_std_dev = vec![f64::INFINITY; compliance_count];
    let mut chosen: Vec<usize> = (0..compliance_count)
        .filter(|&k| compliance.column(k).norm() > 1e-12 * largest_column && largest_column > 0.0)
        .collect();
    let mut combinations = Vec::new();
    while !chosen.is_empty() {
        let columns = DMatrix::from_fn(left.nrows(), chosen.len(), |r, c| left[(r, chosen[c])]);
        let information = columns.tr_mul(&columns);
        let eigen = information.clone().symmetric_eigen();
        let (smallest, largest) = (eigen.eigenvalues.min(), eigen.eigenvalues.max());
        if largest <= 0.0 || smallest <= 1e-12 * largest {
            let index = eigen.eigenvalues.imin();
            let direction = eigen.eigenvectors.column(index);
            let peak = direction.amax();
            let mut terms: Vec<(usize, f64)> = direction
                .iter()
                .enumerate()
                .filter(|(_, w)| w.abs() >= 0.1 * peak)
                .map(|(c, &w)| (chosen[c], w))
                .collect();
            terms.sort_by(|a, b| b.1.abs().total_cmp(&a.1.abs()));
            // A group only goes when its members cannot.
            let worst = terms
                .iter()
                .map(|t| t.0)
                .find(|&k| k < individual)
                .unwrap_or(terms[0].0);
            if terms.len() > 1 {
                combinations.push(terms);
            }
            chosen.retain(|&c| c != worst);
            continue;
        }
        let Some(inverse) = information.cholesky().map(|c| c.inverse()) else {
            break;
        };
        let deviations: Vec<f64> = (0..chosen.len())
            .map(|c| inverse[(c, c)].max(0.0).sqrt())
            .collect();
        for (c, &k) in chosen.iter().enumerate() {
            data_std_dev[k] = deviations[c];
        }
        // The least determined individual compliance goes first. Then, while a group is not
        // determined, its least determined member goes (the common scale matters more than
        // one member's deviation from it), and the group itself only when it has none left.
        let group_of = |c: usize| usize::from(!parameters[chosen[c]].kind.is_joint());
        let worst = |keep: &dyn Fn(usize) -> bool, limit: f64| {
            deviations
                .iter()
                .enumerate()
                .filter(|(c, _)| keep(*c))
                .max_by(|a, b| a.1.total_cmp(b.1))
                .filter(|(_, &d)| d > limit)
                .map(|(c, _)| c)
        };
        let limit = prior_sigma * DETERMINED;
        let undetermined_group = worst(&|c| chosen[c] >= individual, limit);
        let drop = worst(&|c| chosen[c] < individual, limit).or_else(|| {
            let group = chosen[undetermined_group?] - individual;
            worst(&|c| chosen[c] < individual && group_of(c) == group, 0.0).or(undetermined_group)
        });
        match drop {
            Some(c) => {
                chosen.remove(c);
            }
            None => break,
        }
    }
    chosen.sort_unstable();
    Selection {
        chosen,
        data_std_dev,
        combinations,
    }
}

/// What a set of measurements (their configurations, tools and payloads; the observed values
/// do not matter) can determine of the compliances, with the geometric parameters `free`:
/// the identifiability analysis of the compliance parameters, before measuring.
#[derive(Debug, Clone, Serialize)]
pub struct ComplianceIdentifiability {
    /// Per compliance parameter: its name, how well the data determine its scale (relative,
    /// infinite: not at all), and whether it would be identified (JSON: an object per
    /// parameter with `name`, `relative_std_dev` (`null`: infinite) and `identified`).
    #[serde(serialize_with = "compliance_parameters_json")]
    pub parameters: Vec<(String, f64, bool)>,
    /// Combinations the data cannot tell apart from the geometry or each other, in words.
    pub unidentifiable: Vec<String>,
}

fn compliance_parameters_json<S: serde::Serializer>(
    parameters: &[(String, f64, bool)],
    serializer: S,
) -> std::result::Result<S::Ok, S::Error> {
    #[derive(Serialize)]
    struct Parameter<'a> {
        name: &'a str,
        relative_std_dev: Option<f64>,
        identified: bool,
    }
    serializer.collect_seq(parameters.iter().map(|(name, sd, identified)| Parameter {
        name,
        relative_std_dev: sd.is_finite().then_some(*sd),
        identified: *identified,
    }))
}

/// The compliance part of the identifiability analysis at `model` (see
/// [`ComplianceIdentifiability`]).
#[allow(clippy::too_many_arguments)]
pub fn analyse_compliance(
    tree: &KinematicTree,
    model: &McpcModel,
    prior: &FlexibilityModel,
    measurements: &[Measurement],
    payloads: Option<&[f64]>,
    free: &[usize],
    options: &IdentificationOptions,
    prior_sigma: f64,
) -> Result<ComplianceIdentifiability> {
    let problem = Problem::new(tree, prior, measurements, payloads, free, options)?;
    let count = problem.parameters().len() + GROUPS;
    let all: Vec<usize> = (0..count).collect();
    let lin = problem.linearise(model, &vec![1.0; count], &all, true)?;
    let selection = select(&lin, free.len(), problem.parameters(), prior_sigma, options);
    Ok(ComplianceIdentifiability {
        parameters: (0..count)
            .map(|k| {
                let name = match problem.parameters().get(k) {
                    Some(p) => name(tree, model, p),
                    None => GROUP_NAMES[k - problem.parameters().len()].to_owned(),
                };
                (
                    name,
                    selection.data_std_dev[k],
                    selection.chosen.contains(&k),
                )
            })
            .collect(),
        unidentifiable: selection
            .combinations
            .iter()
            .map(|c| describe(tree, model, problem.parameters(), c))
            .collect(),
    })
}

/// The prior stiffness data with the identified stiffness of every calibrated joint and body
/// as overrides (by joint name): a stiffness file ready for reuse.
pub fn identified_stiffness(
    prior: &Stiffness,
    tree: &KinematicTree,
    model: &McpcModel,
    estimates: &[ComplianceEstimate],
) -> Stiffness {
    let value = |frame: usize, kind: ComplianceKind| -> Option<f64> {
        let name = &tree.joint(model.frames()[frame].joint).name;
        estimates
            .iter()
            .find(|e| e.kind == kind && &e.owner == name)
            .map(|e| e.stiffness)
    };
    let mut joint_overrides = Vec::new();
    let mut link_overrides = Vec::new();
    for (frame, f) in model.frames().iter().enumerate() {
        let name = tree.joint(f.joint).name.clone();
        if let (Some(bending), Some(torsion)) = (
            value(frame, ComplianceKind::JointBending),
            value(frame, ComplianceKind::JointTorsion),
        ) {
            joint_overrides.push((name.clone(), JointStiffness { bending, torsion }));
        }
        let link = [
            ComplianceKind::LinkAxial,
            ComplianceKind::LinkBendingY,
            ComplianceKind::LinkBendingZ,
            ComplianceKind::LinkTorsion,
        ]
        .map(|k| value(frame, k));
        if let [Some(axial), Some(bending_y), Some(bending_z), Some(torsion)] = link {
            link_overrides.push((
                name,
                LinkStiffness {
                    axial,
                    bending_y,
                    bending_z,
                    torsion,
                },
            ));
        }
    }
    Stiffness {
        joint_overrides,
        link_overrides,
        ..prior.clone()
    }
}
