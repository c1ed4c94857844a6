//! The model the data support: which parameters a calibration frees (`--model`, `--freeze`,
//! `--free`, `--prior`, `--joint-errors`), and the cross-validation that compares model
//! levels (`--cv K`) and lets `--model auto` choose. See `docs/identification.md`.

use crate::calibration::validation_in_training_frames;
use crate::calibration::{
    balanced_rotation_sigma, variance_components, NoiseComponent, MAX_NOISE_ROUNDS,
    NOISE_RATIO_TOLERANCE,
};
use crate::calibration::{
    run_calibration, CalibrationInput, CalibrationRun, Deflected, IdentificationOptions, Prior,
    Rigid, RowKind,
};
use crate::calibration::{SIGMA_FAILED, SIGMA_WARNING};
use crate::error::{Error, Result};
use crate::kinematics::{GravitySigns, JointErrorTerms, McpcModel, ParameterOwner};
use crate::measurement::{Measurement, Observation};
use crate::tree::KinematicTree;

/// Which parameters describe the robot.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ModelLevel {
    /// Joint zero offsets, the tools and the measurement frame; the MCPC geometry stays
    /// nominal.
    Offsets,
    /// The full MCPC geometry (every frame and tool parameter).
    #[default]
    Geometry,
}

/// `--model`: a level, the one cross-validation prefers, or (the default) the full geometry
/// unless its fit shows model error.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ModelChoice {
    /// One level.
    Level(ModelLevel),
    /// The candidate with the lowest cross-validated error ([`super::cross_validation::candidates`]).
    Auto,
    /// The full geometry; when its fit shows model error ([`shows_model_error`]: residuals
    /// more than [`SIGMA_WARNING`] times the declared noise), the cross-validation's choice,
    /// as `Auto`.
    #[default]
    Adaptive,
}

/// Whether a fit shows model error: some stage's residual scale σ̂ above
/// [`SIGMA_WARNING`] and none above [`SIGMA_FAILED`] (a mistake such as a unit, not a model
/// to choose: the verdict fails and says so).
pub fn shows_model_error(run: &CalibrationRun) -> bool {
    let scales: Vec<f64> = run
        .report
        .stages
        .iter()
        .map(|stage| &stage.identification)
        .filter(|id| id.rows > id.free.len())
        .map(|id| id.residual_scale)
        .collect();
    scales.iter().any(|s| *s > SIGMA_WARNING) && scales.iter().all(|s| *s <= SIGMA_FAILED)
}

/// One model: a level, joint-angle error terms, the prior, and whether only the corrections
/// of at least `k` standard deviations are kept.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct ModelSpec {
    /// The level.
    pub level: ModelLevel,
    /// Harmonic and backlash terms on top of the level (its offsets are the level's).
    pub harmonics: bool,
    /// Backlash terms.
    pub backlash: bool,
    /// With `harmonics`: only the joints of these frames have harmonic terms (bit `f`: the
    /// model's frame `f`); 0: every revolute joint. Set by the cross-validation's forward steps
    /// ([`super::cross_validation::joint_steps`]).
    pub harmonic_frames: u64,
    /// With `backlash`: only the joints of these frames have backlash terms; 0: every one.
    pub backlash_frames: u64,
    /// The default Gaussian prior on the nominal values ([`Prior::default_for`]).
    pub prior: bool,
    /// The prior's σ times this (1: the documented defaults; 0.5: twice as tight).
    pub prior_scale: f64,
    /// Keep only the MCPC corrections of at least this many standard deviations (the others
    /// frozen at nominal and the rest refitted).
    pub significant: Option<f64>,
    /// With the stiffness in play: compensate the deflections (else rigid).
    pub compensate: bool,
    /// Identify the joint and link compliances with the geometry (`--identify-stiffness`,
    /// the stiffness file or the library defaults as the prior) and compensate with them.
    pub identify_stiffness: bool,
    /// Weigh the rotation rows against the position rows by the σ ratio their residuals show
    /// (variance components, [`run_model_with_noise`]) instead of the declared one.
    pub estimate_noise: bool,
}

impl Default for ModelSpec {
    fn default() -> Self {
        Self {
            level: ModelLevel::default(),
            harmonics: false,
            backlash: false,
            harmonic_frames: 0,
            backlash_frames: 0,
            prior: false,
            prior_scale: 1.0,
            significant: None,
            compensate: false,
            identify_stiffness: false,
            estimate_noise: false,
        }
    }
}

impl ModelSpec {
    /// A short name, e.g. `geometry+prior+harmonics`; `+compensated` when the given
    /// stiffness compensates the deflections, `+identified stiffness` when the compliances are
    /// identified too (a rigid model has neither), so no two candidates share a name.
    pub fn name(&self) -> String {
        self.named(&[])
    }

    /// [`Self::name`] with the joints of per-joint terms named (`joints[f]`: the joint of
    /// frame `f`, [`frame_joints`]; `#f` where missing), e.g. `offsets+backlash(arm_6_joint)`.
    pub fn named(&self, joints: &[String]) -> String {
        let mut name = match self.level {
            ModelLevel::Offsets => "offsets".to_string(),
            ModelLevel::Geometry => "geometry".to_string(),
        };
        if self.prior {
            name.push_str("+prior");
            if self.prior_scale != 1.0 {
                name.push_str(&format!("×{}", self.prior_scale));
            }
        }
        let terms = [
            (self.harmonics, "+harmonics", self.harmonic_frames),
            (self.backlash, "+backlash", self.backlash_frames),
        ];
        for (on, part, frames) in terms {
            if on {
                name.push_str(part);
            }
            if on && frames != 0 {
                let listed: Vec<String> = (0..64)
                    .filter(|f| frames & (1u64 << f) != 0)
                    .map(|f| joints.get(f).cloned().unwrap_or_else(|| format!("#{f}")))
                    .collect();
                name.push_str(&format!("({})", listed.join(",")));
            }
        }
        if self.identify_stiffness {
            name.push_str("+identified stiffness");
        } else if self.compensate {
            name.push_str("+compensated");
        }
        if self.estimate_noise {
            name.push_str("+estimated noise");
        }
        if let Some(k) = self.significant {
            name.push_str(&format!(" (corrections ≥ {k}σ)"));
        }
        name
    }

    fn terms(&self) -> JointErrorTerms {
        JointErrorTerms {
            offsets: self.level == ModelLevel::Offsets,
            harmonics: self.harmonics,
            backlash: self.backlash,
        }
    }
}

/// The user's parameter patterns: `--freeze` globs (never freed) and `--free` globs (freed
/// even when the level or `--freeze` would not), on [`McpcModel::parameter_name`].
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct ParameterPatterns {
    /// Frozen parameter patterns.
    pub freeze: Vec<String>,
    /// Freed parameter patterns (win over `freeze`).
    pub free: Vec<String>,
}

impl ParameterPatterns {
    /// Every parameter name of `model` ([`McpcModel::parameter_name`]); an error naming a
    /// pattern that matches none.
    pub fn checked_names(&self, tree: &KinematicTree, model: &McpcModel) -> Result<Vec<String>> {
        let names: Vec<String> = (0..model.parameter_count())
            .map(|i| model.parameter_name(tree, i))
            .collect();
        for pattern in self.freeze.iter().chain(&self.free) {
            if !names.iter().any(|n| glob_match(pattern, n)) {
                return Err(Error::InvalidSetting {
                    setting: "freeze".into(),
                    message: format!(
                        "'{pattern}' (in `freeze` or `free`) matches no parameter; names are like '{}' (see params.yaml)",
                        names.first().cloned().unwrap_or_default()
                    ),
                });
            }
        }
        Ok(names)
    }

    /// Whether a `freeze` pattern matches `name`.
    pub fn freezes(&self, name: &str) -> bool {
        self.freeze.iter().any(|p| glob_match(p, name))
    }

    /// Whether a `free` pattern matches `name` (it wins over `freeze` and the level).
    pub fn frees(&self, name: &str) -> bool {
        self.free.iter().any(|p| glob_match(p, name))
    }
}

/// A model ready to calibrate: the nominal model with its extra parameters, and the options
/// with the frozen parameters and the prior.
#[derive(Debug, Clone)]
pub struct PreparedModel {
    /// The nominal model (joint-error and frame parameters appended as the level needs).
    pub nominal: McpcModel,
    /// The identification options.
    pub options: IdentificationOptions,
}

/// The nominal model and options of `spec`.
pub fn prepare(
    spec: &ModelSpec,
    tree: &KinematicTree,
    nominal: &McpcModel,
    options: &IdentificationOptions,
    patterns: &ParameterPatterns,
) -> Result<PreparedModel> {
    let terms = spec.terms();
    let gravity = if terms.backlash {
        Some(GravitySigns::new(tree, nominal)?)
    } else {
        None
    };
    let mut model = nominal.with_joint_errors(terms, gravity)?;
    if spec.level == ModelLevel::Offsets {
        model = model.with_frame_parameters();
    }
    let layout = model.parameter_layout();
    let names = patterns.checked_names(tree, &model)?;
    let frozen: Vec<usize> = layout
        .iter()
        .enumerate()
        .filter(|(i, (owner, kind))| {
            let by_level = spec.level == ModelLevel::Offsets
                && matches!(owner, ParameterOwner::Frame(_))
                && !matches!(
                    kind,
                    crate::kinematics::ParameterKind::Offset
                        | crate::kinematics::ParameterKind::Sine
                        | crate::kinematics::ParameterKind::Cosine
                        | crate::kinematics::ParameterKind::Backlash
                );
            let by_frames = match (owner, kind) {
                (
                    ParameterOwner::Frame(f),
                    crate::kinematics::ParameterKind::Sine
                    | crate::kinematics::ParameterKind::Cosine,
                ) => outside(spec.harmonic_frames, *f),
                (ParameterOwner::Frame(f), crate::kinematics::ParameterKind::Backlash) => {
                    outside(spec.backlash_frames, *f)
                }
                _ => false,
            };
            (by_level || by_frames || patterns.freezes(&names[*i])) && !patterns.frees(&names[*i])
        })
        .map(|(i, _)| i)
        .collect();
    let prior = spec
        .prior
        .then(|| Prior::default_for(&model, &model.parameters()).scaled(spec.prior_scale));
    Ok(PreparedModel {
        nominal: model,
        options: IdentificationOptions {
            frozen,
            prior,
            ..options.clone()
        },
    })
}

/// Whether frame `f` is outside the per-joint `mask` (0: every frame is inside).
fn outside(mask: u64, f: usize) -> bool {
    mask != 0 && (f >= 64 || mask & (1u64 << f) == 0)
}

/// The joint of each of the model's frames, by name.
pub fn frame_joints(tree: &KinematicTree, model: &McpcModel) -> Vec<String> {
    model
        .frames()
        .iter()
        .map(|f| tree.joint(f.joint).name.clone())
        .collect()
}

/// Runs the calibration of a prepared model ([`run_model_with_noise`] without its noise
/// estimate).
pub fn run_model(
    input: &CalibrationInput<'_>,
    spec: &ModelSpec,
    measurements: &[Measurement],
    validation: &[Measurement],
) -> Result<CalibrationRun> {
    Ok(run_model_with_noise(input, spec, measurements, validation)?.0)
}

/// Runs the calibration of a prepared model: with `spec.estimate_noise`, reweighed by the
/// variance components of its residuals ([`fit_noise`]); with `spec.significant` (`k`),
/// the MCPC corrections smaller than `k` standard deviations (and the undetermined ones) are
/// then frozen at nominal and the model is run again.
pub fn run_model_with_noise(
    input: &CalibrationInput<'_>,
    spec: &ModelSpec,
    measurements: &[Measurement],
    validation: &[Measurement],
) -> Result<(CalibrationRun, Option<NoiseEstimate>)> {
    let (run, options, noise) = if spec.estimate_noise {
        fit_noise(input, measurements, validation)?
    } else {
        let run = with_fitted_frame(run_calibration(input, measurements, validation)?);
        (run, input.options.clone(), None)
    };
    let Some(k) = spec.significant else {
        return Ok((run, noise));
    };
    let layout = input.nominal.parameter_layout();
    let mut frozen = options.frozen.clone();
    for (i, estimate) in run.parameters.iter().enumerate() {
        let small = match estimate.std_dev {
            Some(sd) => estimate.change.abs() < k * sd,
            None => true,
        };
        if small && matches!(layout[i].0, ParameterOwner::Frame(_)) && !frozen.contains(&i) {
            frozen.push(i);
        }
    }
    let options = IdentificationOptions { frozen, ..options };
    let again = CalibrationInput {
        options: &options,
        ..*input
    };
    let run = with_fitted_frame(run_calibration(&again, measurements, validation)?);
    Ok((run, noise))
}

/// What the noise estimation found ([`fit_noise`]).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct NoiseEstimate {
    /// The declared σ's: position (m), rotation (rad).
    pub declared: [f64; 2],
    /// The rotation σ the rows were weighed by in the end (rad; the position σ is kept).
    pub rotation_sigma: f64,
    /// Calibrations run after the first.
    pub rounds: usize,
    /// Whether the σ ratio settled within [`MAX_NOISE_ROUNDS`].
    pub converged: bool,
    /// The variance components of the first fit (the declared σ's).
    pub first: Vec<NoiseComponent>,
    /// The variance components of the final fit (equal scales when settled).
    pub last: Vec<NoiseComponent>,
}

impl NoiseEstimate {
    /// The estimated σ ratio rotation:position (rad per m) against the declared one.
    pub fn ratio_change(&self) -> f64 {
        self.rotation_sigma / self.declared[1]
    }

    /// One line for the notes and report.md.
    pub fn describe(&self) -> String {
        let part = |c: &NoiseComponent| {
            let (value, unit) = match c.kind {
                RowKind::Rotation => (c.estimated_sigma() * 1e3, "mrad"),
                _ => (c.estimated_sigma() * 1e3, "mm"),
            };
            format!(
                "{} {value:.3} {unit} ({} rows, {:.1} degrees of freedom)",
                c.kind.name(),
                c.rows,
                c.redundancy
            )
        };
        let first: Vec<String> = self.first.iter().map(part).collect();
        format!(
            "noise from the data (variance components of the first fit): {}; the rotation rows are weighed at σ {:.3} mrad instead of the declared {:.3} mrad (position σ {:.3} mm kept) after {} refit(s){}",
            first.join(", "),
            self.rotation_sigma * 1e3,
            self.declared[1] * 1e3,
            self.declared[0] * 1e3,
            self.rounds,
            if self.converged { "" } else { ", not settled" }
        )
    }
}

/// The calibration reweighed by its own residuals: after each fit, the variance components of
/// the position and rotation rows ([`variance_components`]: each kind's residuals over its
/// redundancy, the degrees of freedom split by its share of the hat matrix) give the σ ratio,
/// the rotation σ is set to it (the position σ kept, so a prior keeps its weight) and the model
/// refitted, until the ratio changes by less than [`NOISE_RATIO_TOLERANCE`] (at most
/// [`MAX_NOISE_ROUNDS`] refits). With one row kind nothing changes (no estimate).
pub fn fit_noise(
    input: &CalibrationInput<'_>,
    measurements: &[Measurement],
    validation: &[Measurement],
) -> Result<(CalibrationRun, IdentificationOptions, Option<NoiseEstimate>)> {
    let mut options = input.options.clone();
    let fit = |options: &IdentificationOptions| {
        let input = CalibrationInput { options, ..*input };
        run_calibration(&input, measurements, validation).map(with_fitted_frame)
    };
    let mut run = fit(&options)?;
    let first = noise_components(input, &options, &run, measurements)?;
    if first.is_empty() {
        return Ok((run, options, None));
    }
    let declared = [options.position_sigma, options.rotation_sigma];
    let (mut last, mut rounds, mut converged) = (first.clone(), 0, false);
    while let Some(sigma) = balanced_rotation_sigma(&last) {
        // Within three decades of the declared σ: a kind fitted exactly (no residual) must
        // not get an infinite weight.
        let sigma = sigma.clamp(declared[1] * 1e-3, declared[1] * 1e3);
        if (sigma / options.rotation_sigma - 1.0).abs() <= NOISE_RATIO_TOLERANCE {
            converged = true;
            break;
        }
        if rounds == MAX_NOISE_ROUNDS {
            break;
        }
        options.rotation_sigma = sigma;
        run = fit(&options)?;
        rounds += 1;
        last = noise_components(input, &options, &run, measurements)?;
    }
    let estimate = NoiseEstimate {
        declared,
        rotation_sigma: options.rotation_sigma,
        rounds,
        converged,
        first,
        last,
    };
    Ok((run, options, Some(estimate)))
}

/// The variance components of `run` (its measurements in the first session's frame, its
/// robust weights, every parameter the level frees, each later session's frame block).
fn noise_components(
    input: &CalibrationInput<'_>,
    options: &IdentificationOptions,
    run: &CalibrationRun,
    measurements: &[Measurement],
) -> Result<Vec<NoiseComponent>> {
    let in_first = validation_in_training_frames(measurements, run.sessions.as_ref());
    let weighted = IdentificationOptions {
        observation_weights: run.robust.fit_weights(),
        ..options.clone()
    };
    let model = &run.report.model;
    let free: Vec<usize> = (0..model.parameter_count())
        .filter(|i| !options.frozen.contains(i))
        .collect();
    let blocks: Vec<Vec<usize>> = run
        .sessions
        .iter()
        .flat_map(|s| s.frames.iter().skip(1))
        .map(|frame| {
            (0..measurements.len())
                .filter(|&i| measurements[i].session == frame.name)
                .collect()
        })
        .collect();
    match input.flexibility {
        Some(flexibility) => {
            let predictor = Deflected {
                tree: input.tree,
                flexibility,
            };
            variance_components(model, &in_first, &predictor, &free, &weighted, &blocks)
        }
        None => variance_components(model, &in_first, &Rigid, &free, &weighted, &blocks),
    }
}

/// With the measurement frame as parameters, the frame the reports and the registration give
/// is the fitted one, not the closed-form start.
fn with_fitted_frame(mut run: CalibrationRun) -> CalibrationRun {
    if run.report.model.has_frame_parameters() {
        run.guess.world_from_base = run.report.model.world_from_base();
    }
    run
}

/// Whether `name` matches the glob `pattern` (`*`: any run of characters, `?`: one).
pub fn glob_match(pattern: &str, name: &str) -> bool {
    let (p, n): (Vec<char>, Vec<char>) = (pattern.chars().collect(), name.chars().collect());
    let (mut pi, mut ni, mut star, mut mark) = (0, 0, None, 0);
    while ni < n.len() {
        if pi < p.len() && (p[pi] == '?' || p[pi] == n[ni]) {
            pi += 1;
            ni += 1;
        } else if pi < p.len() && p[pi] == '*' {
            star = Some(pi);
            mark = ni;
            pi += 1;
        } else if let Some(s) = star {
            pi = s + 1;
            mark += 1;
            ni = mark;
        } else {
            return false;
        }
    }
    p[pi..].iter().all(|c| *c == '*')
}

/// Groups of measurement indices that share a posture: configurations within
/// [`POSTURE_TOLERANCE`] (rad or m, every joint) of each other, joined transitively, so a
/// repeated posture (another tool, another session) always falls into one fold.
pub fn posture_groups(measurements: &[Measurement]) -> Vec<Vec<usize>> {
    let mut groups: Vec<Vec<usize>> = Vec::new();
    let mut representative: Vec<Vec<&[f64]>> = Vec::new();
    for (index, m) in measurements.iter().enumerate() {
        let close = |q: &[f64]| {
            q.len() == m.q.len()
                && q.iter()
                    .zip(&m.q)
                    .all(|(a, b)| (a - b).abs() <= POSTURE_TOLERANCE)
        };
        let matching: Vec<usize> = (0..groups.len())
            .filter(|&g| representative[g].iter().any(|q| close(q)))
            .collect();
        match matching.split_first() {
            None => {
                groups.push(vec![index]);
                representative.push(vec![&m.q]);
            }
            Some((&first, rest)) => {
                // Join every group this posture links (transitively one posture).
                for &g in rest.iter().rev() {
                    let moved = groups.remove(g);
                    let qs = representative.remove(g);
                    groups[first].extend(moved);
                    representative[first].extend(qs);
                }
                groups[first].push(index);
                representative[first].push(&m.q);
            }
        }
    }
    for group in &mut groups {
        group.sort_unstable();
    }
    groups
}

/// Two configurations closer than this in every joint (rad or m) are one posture: 0.01 rad
/// (0.57°) is far above encoder repeatability and far below the spacing of planned postures.
pub const POSTURE_TOLERANCE: f64 = 0.01;

/// `k` folds of measurement indices over the posture groups, assigned in a seeded shuffled
/// order so each fold holds about the same number of postures.
pub fn grouped_folds(measurements: &[Measurement], k: usize, seed: u64) -> Vec<Vec<usize>> {
    use rand::seq::SliceRandom;
    use rand::SeedableRng;
    let mut groups = posture_groups(measurements);
    let mut rng = rand::rngs::ChaCha8Rng::seed_from_u64(seed);
    groups.shuffle(&mut rng);
    let mut folds = vec![Vec::new(); k.max(1)];
    for (g, group) in groups.into_iter().enumerate() {
        folds[g % k.max(1)].extend(group);
    }
    for fold in &mut folds {
        fold.sort_unstable();
    }
    folds
}

/// Position error (m) of each measurement at the model of `run` (the deflected prediction
/// under compensation); with full poses the tool frame's origin.
pub fn position_errors(
    input: &CalibrationInput<'_>,
    run: &CalibrationRun,
    data: &[Measurement],
) -> Result<Vec<f64>> {
    data.iter()
        .map(|m| {
            let poses = match input.flexibility {
                Some(flexibility) => flexibility.for_payload(m.payload)?.deflected_tool_poses(
                    input.tree,
                    &run.report.model,
                    &m.q,
                )?,
                None => run.report.model.tool_poses(&m.q),
            };
            let predicted = poses[m.tool].translation.vector;
            Ok(match &m.observation {
                Observation::Pose(p) => (p.translation.vector - predicted).norm(),
                Observation::Position(p) => (p - predicted).norm(),
                // Contacts are not tool positions (issue 29): no position error.
                Observation::Contact(_) => 0.0,
            })
        })
        .collect()
}
