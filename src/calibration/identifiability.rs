//! Identifiability analysis: how well a set of measured configurations determines the MCPC
//! parameters, before any measurement is taken.
//!
//! The identification Jacobian of the configurations is weighted and column-scaled exactly as
//! the solver does it (rows divided by the position / rotation σ, columns by their norms), its
//! singular values give the rank, the condition number and the observability indices O1–O5,
//! and its right singular vectors for the singular values below the rank threshold are the
//! parameter combinations the configurations cannot determine. See `docs/identifiability.md`.

use super::linear_algebra::{column_scales, scale_columns, singular_decomposition};
use super::plan::{locked_arm_model, ParameterSet};
use super::solver::{combination, Combination};
use crate::error::{Error, Result};
use crate::kinematics::{McpcModel, ParameterOwner, ToolJacobian};
use crate::measurement::{Measurement, Observation};
use crate::tree::{Branches, KinematicTree};
use nalgebra::{DMatrix, DVector, Vector3};
use serde::{Deserialize, Serialize};

pub use super::observability::{
    criterion_value, observability_indices, Criterion, ObservabilityIndices,
};

/// One measured tool at one configuration (no measured value: what is analysed is where the
/// robot will be measured, not what will be seen).
#[derive(Debug, Clone, PartialEq)]
pub struct PoseRow {
    /// Index of the tool in [`McpcModel::tools`].
    pub tool: usize,
    /// The configuration (one value per independent joint of the tree).
    pub q: Vec<f64>,
    /// The calibration stage the row belongs to (`torso`, `arms`), if labelled.
    pub stage: Option<String>,
}

/// What the instrument reports for each row.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ObservationKind {
    /// A full tool pose (three targets): six rows per observation.
    Pose,
    /// One target's position: three rows per observation.
    Position,
}

impl ObservationKind {
    /// Rows one observation contributes (6 or 3).
    pub fn rows(self) -> usize {
        match self {
            ObservationKind::Pose => 6,
            ObservationKind::Position => 3,
        }
    }
}

/// The default [`IdentifiabilityOptions::condition_limit`]: random configurations of the
/// Robonaut give condition numbers of 3–5, configurations within a milliradian of zero 10⁴.
pub const DEFAULT_CONDITION_LIMIT: f64 = 100.0;

/// Settings of the analysis; σ's and rank tolerance mean what they mean in
/// [`super::IdentificationOptions`], so the analysis predicts the solver's rank decision.
#[derive(Debug, Clone)]
pub struct IdentifiabilityOptions {
    /// Expected position error of a measurement (m): position rows are divided by it.
    pub position_sigma: f64,
    /// Expected rotation error of a measurement (rad): rotation rows are divided by it.
    pub rotation_sigma: f64,
    /// Singular values below this times the largest count as zero (unidentifiable).
    pub rank_tolerance: f64,
    /// Which parameters are free: the torso stage (arms locked), the arms, or all.
    pub parameters: ParameterSet,
    /// A set whose condition number exceeds this is poorly conditioned, and the directions
    /// with `σ < σ_max / condition_limit` are reported as poorly determined.
    pub condition_limit: f64,
}

impl Default for IdentifiabilityOptions {
    fn default() -> Self {
        let solver = super::IdentificationOptions::default();
        Self {
            position_sigma: solver.position_sigma,
            rotation_sigma: solver.rotation_sigma,
            rank_tolerance: solver.rank_tolerance,
            parameters: ParameterSet::All,
            condition_limit: DEFAULT_CONDITION_LIMIT,
        }
    }
}

/// The weighted identification Jacobian of `rows` over the `free` parameters (columns in
/// `free` order): per row the tool's 6 (pose) or 3 (position) rows, position rows divided by
/// `position_sigma`, rotation rows by `rotation_sigma`, as the solver weights them. Not yet
/// column-scaled: scaling depends on the whole set, so a planner stacks these blocks first.
pub fn weighted_jacobian(
    model: &McpcModel,
    rows: &[PoseRow],
    observation: ObservationKind,
    free: &[usize],
    options: &IdentifiabilityOptions,
) -> Result<DMatrix<f64>> {
    validate(model, rows, free, options)?;
    let per_row = observation.rows();
    let weights = [1.0 / options.position_sigma, 1.0 / options.rotation_sigma];
    let mut jacobian = DMatrix::zeros(rows.len() * per_row, free.len());
    // Rows of several tools at one configuration share one evaluation.
    let mut cached: Option<(&[f64], Vec<ToolJacobian>)> = None;
    for (index, row) in rows.iter().enumerate() {
        let tools = match &cached {
            Some((q, tools)) if *q == row.q.as_slice() => tools,
            _ => &cached.insert((&row.q, model.tool_jacobians(&row.q))).1,
        };
        let tool = &tools[row.tool].jacobian;
        for (column, &parameter) in free.iter().enumerate() {
            for k in 0..per_row {
                jacobian[(index * per_row + k, column)] = tool[(k, parameter)] * weights[k / 3];
            }
        }
    }
    // Every decomposition of identifiability starts from this matrix.
    let squares = jacobian.norm_squared();
    crate::limits::ensure_finite(
        jacobian.iter().chain([&squares]),
        "identifiability: the weighted Jacobian",
    )?;
    Ok(jacobian)
}

/// [`weighted_jacobian`] with its columns scaled to unit norm (the solver's scaling, floored
/// at 1e-6 of the largest column norm).
pub fn scaled_jacobian(
    model: &McpcModel,
    rows: &[PoseRow],
    observation: ObservationKind,
    free: &[usize],
    options: &IdentifiabilityOptions,
) -> Result<DMatrix<f64>> {
    let weighted = weighted_jacobian(model, rows, observation, free, options)?;
    let scales = column_scales(&weighted);
    Ok(scale_columns(&weighted, &scales))
}

/// The singular values of a weighted Jacobian after column scaling, largest first: what
/// [`criterion_value`] and [`observability_indices`] take. One value per column.
/// A matrix with a non-finite entry gives NaN values (its decomposition would never end).
pub fn scaled_singular_values(weighted: &DMatrix<f64>) -> Vec<f64> {
    if !weighted.iter().all(|v| v.is_finite()) {
        return vec![f64::NAN; weighted.ncols()];
    }
    let scales = column_scales(weighted);
    let (values, _) = singular_decomposition(scale_columns(weighted, &scales));
    let mut values: Vec<f64> = values.iter().copied().collect();
    values.sort_by(|a, b| b.total_cmp(a));
    values
}

/// A parameter combination the configurations cannot determine, in words.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct NamedCombination {
    /// `(parameter name, weight)`, largest weights first, unit length in rad and m (JSON: an
    /// object per term with `parameter` and `weight`).
    #[serde(serialize_with = "terms_json")]
    pub terms: Vec<(String, f64)>,
    /// A sentence, e.g. `left_joint1 alpha and right_joint1 alpha move together (+0.71, -0.71)`:
    /// the terms of at least half the largest weight (at most six), then how many are left out.
    pub description: String,
}

fn terms_json<S: serde::Serializer>(
    terms: &[(String, f64)],
    serializer: S,
) -> std::result::Result<S::Ok, S::Error> {
    #[derive(Serialize)]
    struct Term<'a> {
        parameter: &'a str,
        weight: f64,
    }
    serializer.collect_seq(terms.iter().map(|(parameter, weight)| Term {
        parameter,
        weight: *weight,
    }))
}

impl NamedCombination {
    /// Names the terms of `combination` with `names` (indexed by parameter).
    pub fn new(combination: &Combination, names: &[String]) -> Self {
        let terms: Vec<(String, f64)> = combination
            .terms
            .iter()
            .map(|(p, w)| {
                let name = names
                    .get(*p)
                    .cloned()
                    .unwrap_or_else(|| format!("parameter {p}"));
                (name, *w)
            })
            .collect();
        // In words, only the terms that matter: at least half the largest, at most six.
        let largest = terms.first().map_or(0.0, |(_, w)| w.abs());
        let shown = terms
            .iter()
            .take(6)
            .take_while(|(_, w)| w.abs() >= 0.5 * largest)
            .count()
            .max(1)
            .min(terms.len());
        let mut description = describe_terms(&terms[..shown]);
        if terms.len() > shown {
            description.push_str(&format!(", with {} smaller term(s)", terms.len() - shown));
        }
        Self { terms, description }
    }
}

/// A combination in words: one term is "X is not observed by these poses"; several are
/// "A and B move together (+0.71, -0.71)": changing them by those amounts (rad, m) at once
/// leaves every measured tool where it was.
pub fn describe_terms(terms: &[(String, f64)]) -> String {
    match terms {
        [] => "nothing".into(),
        [(name, _)] => format!("{name} is not observed by these poses"),
        _ => {
            let names: Vec<&str> = terms.iter().map(|(n, _)| n.as_str()).collect();
            let (last, first) = names.split_last().unwrap_or((&"", &[]));
            let weights: Vec<String> = terms.iter().map(|(_, w)| format!("{w:+.2}")).collect();
            format!(
                "{} and {last} move together ({})",
                first.join(", "),
                weights.join(", ")
            )
        }
    }
}

/// What [`analyse`] found.
#[derive(Debug, Clone, Serialize)]
pub struct IdentifiabilityReport {
    /// Which parameters were analysed.
    pub parameters: ParameterSet,
    /// Observations (configuration × tool rows): O1's `m`.
    pub observations: usize,
    /// Distinct configurations.
    pub configurations: usize,
    /// Rows of the Jacobian.
    pub rows: usize,
    /// Names of the analysed parameters, in column order (L of them).
    pub parameter_names: Vec<String>,
    /// For the torso stage, the rigid locked-arm tools identified alongside as nuisance
    /// parameters (one per tool and locked arm configuration).
    pub locked_tools: usize,
    /// Scaled singular values, largest first (L of them).
    pub singular_values: Vec<f64>,
    /// Numerical rank: singular values above `rank_tolerance · σ_max`.
    pub rank: usize,
    /// σ_max / σ_min over the retained singular values (the solver's condition number).
    pub condition_number: f64,
    /// O1–O5 over all L singular values, those below the rank threshold counted as zero.
    pub indices: ObservabilityIndices,
    /// O1–O5 over the `rank` retained singular values (the identifiable subspace).
    pub identifiable_indices: ObservabilityIndices,
    /// The combinations the configurations cannot determine (L − rank of them).
    pub unidentifiable: Vec<NamedCombination>,
    /// Combinations above the rank threshold but below `σ_max / condition_limit`: determined
    /// in principle, but with errors amplified more than `condition_limit` times the best.
    pub poorly_determined: Vec<NamedCombination>,
    /// The condition limit the verdict used.
    pub condition_limit: f64,
    /// Unidentifiable directions the observation type explains: with positions only, the
    /// orientation (3 parameters) of every observed tool, which no measured point can see.
    pub expected_unidentifiable: usize,
}

impl IdentifiabilityReport {
    /// The value of `criterion` for the analysed set, from the same singular values as
    /// [`Self::indices`] (those below the rank threshold counted as zero): the one number
    /// `treecal check` and `treecal plan` both report.
    pub fn criterion(&self, criterion: Criterion) -> f64 {
        let thresholded: Vec<f64> = self
            .singular_values
            .iter()
            .enumerate()
            .map(|(i, &s)| if i < self.rank { s } else { 0.0 })
            .collect();
        criterion_value(criterion, &thresholded, self.observations)
    }

    /// Number of parameters analysed (L).
    pub fn parameter_count(&self) -> usize {
        self.parameter_names.len()
    }

    /// Full rank and a condition number within the limit.
    pub fn is_well_conditioned(&self) -> bool {
        self.rank == self.parameter_count() && self.condition_number <= self.condition_limit
    }

    /// What a user must hear about this pose set before measuring it: fewer equations than
    /// identifiable parameters, or a rank deficiency beyond what the observation type explains
    /// ([`Self::expected_unidentifiable`]). Empty when neither.
    pub fn warnings(&self) -> Vec<String> {
        let count = self.parameter_count();
        let identifiable = count.saturating_sub(self.expected_unidentifiable);
        let explained = if self.expected_unidentifiable > 0 {
            format!(
                " (not counting the {} tool orientation parameters that position-only data cannot see)",
                self.expected_unidentifiable
            )
        } else {
            String::new()
        };
        let mut warnings = Vec::new();
        if self.rows < identifiable {
            warnings.push(format!(
                "{} equations for {identifiable} parameters{explained}: too few to identify them; use at least {} configurations",
                self.rows,
                (identifiable * self.configurations.max(1)).div_ceil(self.rows.max(1))
            ));
        }
        if self.rank < identifiable {
            // A measured point on a joint axis does not move when that joint turns.
            let hint = if self.expected_unidentifiable > 0 {
                "; with positions only, a target on the last joint's axis cannot see that axis: place the targets off it"
            } else {
                ""
            };
            warnings.push(format!(
                "rank-deficient: rank {} of {identifiable}{explained}; {} parameter combination(s) cannot be identified from these poses{hint}",
                self.rank,
                identifiable - self.rank
            ));
        }
        warnings
    }

    /// One line: `well conditioned (…)` or `poorly conditioned: …`.
    pub fn verdict(&self) -> String {
        let count = self.parameter_count();
        if self.rank < count {
            format!(
                "poorly conditioned: rank {} of {count}; {} parameter combination(s) cannot be identified from these poses",
                self.rank,
                count - self.rank
            )
        } else if self.condition_number > self.condition_limit {
            format!(
                "poorly conditioned: condition number {:.3e} exceeds {}; {} combination(s) are poorly determined",
                self.condition_number,
                self.condition_limit,
                self.poorly_determined.len()
            )
        } else {
            format!(
                "well conditioned (full rank {count}, condition number {:.1} <= {})",
                self.condition_number, self.condition_limit
            )
        }
    }
}

/// Analyses how well `rows` (measured with `observation`) determine the parameters chosen by
/// `options.parameters` of `model`. For [`ParameterSet::Coupled`] the rows must have the arms
/// locked (as the staged plan's torso stage): the torso frames are analysed with one rigid
/// tool per tool and locked arm configuration, as the plan identifies them.
pub fn analyse(
    tree: &KinematicTree,
    branches: &Branches,
    model: &McpcModel,
    rows: &[PoseRow],
    observation: ObservationKind,
    options: &IdentifiabilityOptions,
) -> Result<IdentifiabilityReport> {
    validate(model, rows, &[], options)?;
    let coupled_frames = super::plan::coupled_frames(model, branches);
    let (analysed, analysed_rows, free, names, locked_tools) = match options.parameters {
        ParameterSet::Coupled => {
            let as_measurements: Vec<Measurement> = rows
                .iter()
                .map(|r| Measurement {
                    payload: None,
                    tool: r.tool,
                    q: r.q.clone(),
                    observation: Observation::Position(Vector3::zeros()),
                    stage: r.stage.clone(),
                    session: None,
                })
                .collect();
            let (stage_model, stage_data, locked_tools) =
                locked_arm_model(model, &coupled_frames, &as_measurements, "torso")?;
            let stage_rows: Vec<PoseRow> = stage_data
                .into_iter()
                .map(|m| PoseRow {
                    tool: m.tool,
                    q: m.q,
                    stage: m.stage,
                })
                .collect();
            let names = locked_names(tree, &stage_model);
            let free: Vec<usize> = (0..stage_model.parameter_count()).collect();
            (stage_model, stage_rows, free, names, locked_tools)
        }
        ParameterSet::Arms | ParameterSet::All => {
            let free = super::plan::stage_parameters(model, &coupled_frames, options.parameters);
            let names = (0..model.parameter_count())
                .map(|p| model.parameter_name(tree, p))
                .collect();
            (model.clone(), rows.to_vec(), free, names, 0)
        }
    };
    // From a reference link the root's placement is a gauge freedom, fixed as calibrate does.
    let gauge = super::gauge::reference_gauge(&analysed, &free);
    let free: Vec<usize> = free.into_iter().filter(|p| !gauge.contains(p)).collect();
    let weighted = weighted_jacobian(&analysed, &analysed_rows, observation, &free, options)?;
    let scales = column_scales(&weighted);
    let (values, v_t) = singular_decomposition(scale_columns(&weighted, &scales));
    let mut order: Vec<usize> = (0..values.len()).collect();
    order.sort_by(|&a, &b| values[b].total_cmp(&values[a]));
    let singular_values: Vec<f64> = order.iter().map(|&i| values[i]).collect();
    let sigma_max = singular_values.first().copied().unwrap_or(0.0);
    let threshold = options.rank_tolerance * sigma_max;
    let rank = singular_values.iter().filter(|&&s| s > threshold).count();
    let condition_number = match singular_values.get(rank.saturating_sub(1)) {
        Some(&smallest) if rank > 0 && smallest > 0.0 => sigma_max / smallest,
        _ => f64::INFINITY,
    };
    let observations = analysed_rows.len();
    let thresholded: Vec<f64> = singular_values
        .iter()
        .map(|&s| if s > threshold { s } else { 0.0 })
        .collect();
    let indices = observability_indices(&thresholded, observations);
    let identifiable_indices = observability_indices(&singular_values[..rank], observations);
    let named = |i: usize| {
        let direction = v_t.row(i).transpose().component_div(&scales);
        NamedCombination::new(&combination(&direction, &free), &names)
    };
    let null_space: Vec<usize> = order[rank..].to_vec();
    let unidentifiable = sparse_null_basis(&v_t, &null_space)
        .into_iter()
        .map(|direction| {
            NamedCombination::new(
                &combination(&direction.component_div(&scales), &free),
                &names,
            )
        })
        .collect();
    let weak = sigma_max / options.condition_limit;
    let poorly_determined = order[..rank]
        .iter()
        .filter(|&&i| values[i] < weak)
        .map(|&i| named(i))
        .collect();
    let mut distinct: Vec<&[f64]> = analysed_rows.iter().map(|r| r.q.as_slice()).collect();
    distinct.dedup();
    let expected_unidentifiable = match observation {
        ObservationKind::Pose => 0,
        ObservationKind::Position => {
            let mut tools: Vec<usize> = analysed_rows.iter().map(|r| r.tool).collect();
            tools.sort_unstable();
            tools.dedup();
            3 * tools.len()
        }
    };
    Ok(IdentifiabilityReport {
        parameters: options.parameters,
        observations,
        configurations: distinct.len(),
        rows: weighted.nrows(),
        parameter_names: free.iter().map(|&p| names[p].clone()).collect(),
        locked_tools,
        singular_values,
        rank,
        condition_number,
        indices,
        identifiable_indices,
        unidentifiable,
        poorly_determined,
        condition_limit: options.condition_limit,
        expected_unidentifiable,
    })
}

/// A readable basis of the null space spanned by the rows `rows` of `v_t`: its reduced row
/// echelon form (Gauss–Jordan with the largest remaining entry as pivot). Any basis of the null
/// space is as valid as another, and the singular vectors mix every parameter involved; in
/// echelon form each direction has one pivot parameter that no other direction contains, and
/// a parameter no configuration observes comes out alone.
fn sparse_null_basis(v_t: &DMatrix<f64>, rows: &[usize]) -> Vec<DVector<f64>> {
    let mut basis: Vec<DVector<f64>> = rows.iter().map(|&i| v_t.row(i).transpose()).collect();
    let columns = v_t.ncols();
    let mut used = vec![false; columns];
    for index in 0..basis.len() {
        // The largest entry of this or a later row, in a column not pivoted yet.
        let mut best: Option<(usize, usize, f64)> = None;
        for (row, vector) in basis.iter().enumerate().skip(index) {
            for (column, value) in vector.iter().enumerate() {
                if !used[column] && best.is_none_or(|(_, _, b)| value.abs() > b) {
                    best = Some((row, column, value.abs()));
                }
            }
        }
        let Some((row, column, size)) = best else {
            break;
        };
        if size < 1e-12 {
            break;
        }
        basis.swap(index, row);
        used[column] = true;
        let pivot = basis[index][column];
        basis[index] /= pivot;
        let pivot_row = basis[index].clone();
        for (other, vector) in basis.iter_mut().enumerate() {
            if other != index {
                let factor = vector[column];
                if factor != 0.0 {
                    vector.axpy(-factor, &pivot_row, 1.0);
                }
            }
        }
    }
    // Entries that are rounding noise after elimination.
    for vector in &mut basis {
        let largest = vector.amax();
        vector.apply(|v| {
            if v.abs() <= 1e-9 * largest {
                *v = 0.0;
            }
        });
    }
    basis
}

/// Parameter names of a locked-arm (torso stage) model: the torso frames by joint, each rigid
/// locked tool by its link and lock number, e.g. `left_tool (lock 2) x`.
fn locked_names(tree: &KinematicTree, stage_model: &McpcModel) -> Vec<String> {
    let tools = stage_model.tools();
    stage_model
        .parameter_layout()
        .iter()
        .enumerate()
        .map(|(index, (owner, kind))| match owner {
            ParameterOwner::Tool(t) => {
                let link = tools[*t].link;
                let lock = tools[..=*t].iter().filter(|o| o.link == link).count();
                format!("{} (lock {lock}) {}", tree.link(link).name, kind.name())
            }
            ParameterOwner::Frame(_) | ParameterOwner::Measurement => {
                stage_model.parameter_name(tree, index)
            }
        })
        .collect()
}

fn validate(
    model: &McpcModel,
    rows: &[PoseRow],
    free: &[usize],
    options: &IdentifiabilityOptions,
) -> Result<()> {
    let bad = |message: String| Error::InvalidData {
        origin: "identifiability".into(),
        message,
    };
    if rows.is_empty() {
        return Err(bad(
            "no configurations to analyse; give at least one pose row".into(),
        ));
    }
    if !(options.position_sigma > 0.0 && options.rotation_sigma > 0.0) {
        return Err(bad(
            "position_sigma and rotation_sigma must be positive".into()
        ));
    }
    if options.condition_limit.is_nan() || options.condition_limit < 1.0 {
        return Err(bad(format!(
            "condition_limit {} must be at least 1",
            options.condition_limit
        )));
    }
    if !(options.rank_tolerance >= 0.0 && options.rank_tolerance < 1.0) {
        return Err(bad(format!(
            "rank_tolerance {} must be in [0, 1)",
            options.rank_tolerance
        )));
    }
    let count = model.parameter_count();
    if let Some(&p) = free.iter().find(|&&p| p >= count) {
        return Err(bad(format!(
            "free parameter {p} does not exist (the model has {count})"
        )));
    }
    // The configuration must reach every joint variable a frame reads.
    let dofs = model
        .frames()
        .iter()
        .map(|f| f.actuation.driver().map_or(0, |dof| dof.0 + 1))
        .max()
        .unwrap_or(0);
    for (index, row) in rows.iter().enumerate() {
        if row.tool >= model.tools().len() {
            return Err(bad(format!(
                "pose row {index} names tool {} of {}",
                row.tool,
                model.tools().len()
            )));
        }
        if row.q.len() < dofs {
            return Err(bad(format!(
                "pose row {index} has {} joint values; the model needs at least {dofs}",
                row.q.len()
            )));
        }
        if !row.q.iter().all(|v| v.is_finite()) {
            return Err(bad(format!(
                "pose row {index} has a non-finite joint value"
            )));
        }
    }
    Ok(())
}
