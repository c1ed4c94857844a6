//! A simulated contact calibration (issue 29): a true robot off the nominal, the contacts it
//! makes ([`super::contacts::contact_scene`]), a fit from the nominal robot, and its error in
//! the observable subspace against the fit's covariance (`docs/contacts.md`, "Encoder noise
//! and the covariance").

use super::contact_tracker::{contact_tracker_rows, CONTACT_TRACKER_SIGMA};
use super::contacts::{contact_scene, violation, ContactScene, ContactSimulation};
use super::truth::true_model;
use crate::calibration::{
    identify_with_nuisance, weighted_jacobian, IdentificationOptions, IdentificationReport,
    Nuisance, Rigid,
};
use crate::error::Result;
use crate::kinematics::{McpcModel, ParameterOwner};
use crate::math::{Pose, Vec3};
use crate::measurement::{Measurement, Observation};
use crate::tree::KinematicTree;
use nalgebra::{DMatrix, DVector};
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use rand_distr::StandardNormal;

/// One simulated contact calibration: what the fit recovered in the observable subspace.
#[derive(Debug, Clone)]
pub struct ContactTrial {
    /// The identification (model parameters and nuisance at the solution).
    pub report: IdentificationReport,
    /// Free columns (model parameters, then nuisance values).
    pub free: Vec<usize>,
    /// Rank of the scaled Jacobian at the solution.
    pub rank: usize,
    /// Largest residual (m or rad) of held-out contacts made by the true robot, predicted by
    /// the noise-free fit (what the contacts determine: 0 when the fit recovered it).
    pub noise_free_held_out: f64,
    /// The same for the fit with encoder noise.
    pub held_out: f64,
    /// Directions of the noisy fit compared with its covariance: those whose standard
    /// deviation is below [`LINEAR_STD`] (the fit is linear over their spread).
    pub linear_rank: usize,
    /// Largest error (m or rad) in the observable subspace of the noisy data's fit started
    /// from the noise-free fit's solution (the truth's representative along the directions
    /// the contacts cannot see), against that solution.
    pub observable_error: f64,
    /// `√(eᵀ C⁺ e / rank)` of the observable error against the fit's covariance (1: as
    /// predicted).
    pub consistency: f64,
    /// The true nuisance values.
    pub truth_nuisance: Nuisance,
    /// The true robot.
    pub truth: McpcModel,
    /// The simulated contacts (the true nuisance, training and held-out rows).
    pub scene: ContactScene,
}

/// The free model parameters of a contact fit: every joint frame's (tools' offsets alias the
/// contact points exactly; the measurement frame is the reference link's).
pub fn contact_free_parameters(model: &McpcModel) -> Vec<usize> {
    model
        .parameter_layout()
        .iter()
        .enumerate()
        .filter(|(_, (owner, _))| matches!(owner, ParameterOwner::Frame(_)))
        .map(|(k, _)| k)
        .collect()
}

/// A trial: a true robot off `nominal`, contacts it makes, a fit from the nominal robot and
/// nuisance values `nuisance_start_error` off, and its error in the observable subspace.
pub fn run_contact_trial(
    tree: &KinematicTree,
    nominal: &McpcModel,
    settings: &ContactSimulation,
    seed: u64,
) -> Result<ContactTrial> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    // With a tracker, its frame is six parameters more (as `calibrate` fits it): what the
    // contacts leave of the root's placement, the tracker sees.
    let nominal = &if settings.tracker_rows {
        nominal.with_frame_parameters()
    } else {
        nominal.clone()
    };
    let truth = true_model(nominal, &settings.errors, &mut rng)?;
    let mut scene = contact_scene(tree, &truth, settings, &mut rng)?;
    if settings.tracker_rows {
        add_tracker_rows(tree, &truth, settings, &mut scene, &mut rng);
    }
    let (free, nuisance_only) = trial_columns(nominal, &scene, settings.tracker_rows);
    let start = nuisance_start(&scene, settings.nuisance_start_error, &mut rng)?;
    let options = trial_options(settings, nominal, &start, &scene.measurements)?;
    let fit = |measurements: &[Measurement]| {
        fit_in_two_steps(
            nominal,
            &start,
            measurements,
            (&nuisance_only, &free),
            &options,
        )
    };
    let exact = fit(&scene.exact)?;
    let report = fit(&scene.measurements)?;
    // The noise's effect alone: the noisy data fitted from the noise-free solution (minimum-norm
    // steps then move in the observable directions only, where the covariance applies).
    let mut reference_model = nominal.clone();
    reference_model.set_parameters(&exact.parameters)?;
    // What the contacts cannot see is a curved set (e.g. the plane turning with the torso
    // about the base): steps along it are not linear, so an error measured across it is not
    // the covariance's. The noisy fit frees one independent set of columns (as many as the
    // rank, the rest held at the noise-free solution): no step leaves the observable
    // directions.
    let (at_exact, _) = weighted_jacobian(
        &reference_model,
        &exact.nuisance,
        &scene.measurements,
        &Rigid,
        &free,
        &options,
    )?;
    // Directions the noise moves beyond LINEAR_STD are not linear over their spread: their
    // excursion bends the well-determined directions through the curvature (measured: the
    // linearised estimate is consistent to 1–1.5× where the fit was 6–742×), so the noisy fit
    // holds them at the noise-free solution too.
    let independent: Vec<usize> = linear_columns(
        &at_exact,
        independent_columns(&at_exact, options.rank_tolerance),
        report.residual_scale,
        LINEAR_STD,
    )
    .into_iter()
    .map(|k| free[k])
    .collect();
    let noisy = identify_with_nuisance(
        &reference_model,
        &exact.nuisance,
        &scene.measurements,
        None,
        &Rigid,
        &independent,
        &options,
    )?;
    let mut estimate = nominal.clone();
    estimate.set_parameters(&noisy.parameters)?;
    let (jacobian, _) = weighted_jacobian(
        &estimate,
        &noisy.nuisance,
        &scene.measurements,
        &Rigid,
        &independent,
        &options,
    )?;
    let (reference, estimated) = (all_values(&exact), all_values(&noisy));
    let error = DVector::from_iterator(
        independent.len(),
        independent.iter().map(|&p| estimated[p] - reference[p]),
    );
    let (_, linear_rank, observable_error, consistency) = observable_part(
        &jacobian,
        &error,
        options.rank_tolerance,
        noisy.residual_scale,
    );
    Ok(ContactTrial {
        noise_free_held_out: held_out_residual(nominal, &exact, &scene.validation)?,
        held_out: held_out_residual(nominal, &report, &scene.validation)?,
        report,
        free,
        rank: exact.rank,
        linear_rank,
        observable_error,
        consistency,
        truth_nuisance: scene.nuisance.clone(),
        truth,
        scene,
    })
}

/// As `calibrate --contacts` does (`workflow::contact_fit`): the `first` columns (the
/// nuisance, and a tracker's registration) alone on the nominal robot, then `all` from there.
fn fit_in_two_steps(
    nominal: &McpcModel,
    start: &Nuisance,
    measurements: &[Measurement],
    (first, all): (&[usize], &[usize]),
    options: &IdentificationOptions,
) -> Result<IdentificationReport> {
    let registered = if first.is_empty() {
        start.clone()
    } else {
        identify_with_nuisance(nominal, start, measurements, None, &Rigid, first, options)?.nuisance
    };
    identify_with_nuisance(
        nominal,
        &registered,
        measurements,
        None,
        &Rigid,
        all,
        options,
    )
}

/// The model parameters then the nuisance values of `report`.
fn all_values(report: &IdentificationReport) -> Vec<f64> {
    report
        .parameters
        .iter()
        .copied()
        .chain(report.nuisance.values())
        .collect()
}

/// The options of a trial's fits: contact σ's from the encoder noise through a 0.5 m lever
/// (1e-6 rad when noise-free), the tracker's σ, and with encoder noise each contact weighted
/// by its own chain ([`encoder_weights`]).
fn trial_options(
    settings: &ContactSimulation,
    nominal: &McpcModel,
    start: &Nuisance,
    measurements: &[Measurement],
) -> Result<IdentificationOptions> {
    let lever = 0.5;
    let sigma = settings.encoder_sigma.max(1e-6);
    let mut options = IdentificationOptions {
        max_iterations: 100,
        height_sigma: sigma * lever,
        gap_sigma: sigma * lever,
        length_sigma: sigma * lever,
        tilt_sigma: sigma,
        position_sigma: CONTACT_TRACKER_SIGMA,
        ..IdentificationOptions::default()
    };
    if settings.encoder_sigma > 0.0 {
        options.observation_weights =
            encoder_weights(nominal, start, measurements, sigma, &options)?;
    }
    Ok(options)
}

/// The free columns of a trial (joint frames, with a tracker its frame and the tools' targets,
/// then the free nuisance values), and those of its first fit: the nuisance and the tracker's
/// registration.
fn trial_columns(
    model: &McpcModel,
    scene: &ContactScene,
    tracker: bool,
) -> (Vec<usize>, Vec<usize>) {
    let count = model.parameter_count();
    let registration: Vec<usize> = if tracker {
        tool_offsets(model)
            .into_iter()
            .chain(frame_parameters(model))
            .collect()
    } else {
        Vec::new()
    };
    let mut free = contact_free_parameters(model);
    free.extend(&registration);
    free.sort_unstable();
    free.extend(scene.free_nuisance.iter().map(|k| count + k));
    let first = free
        .iter()
        .copied()
        .filter(|&k| k >= count || registration.contains(&k))
        .collect();
    (free, first)
}

/// The measurement frame's parameters of `model` (flat indices; none without them).
fn frame_parameters(model: &McpcModel) -> Vec<usize> {
    model
        .parameter_layout()
        .iter()
        .enumerate()
        .filter(|(_, (owner, _))| matches!(owner, ParameterOwner::Measurement))
        .map(|(k, _)| k)
        .collect()
}

/// The x, y, z parameters of every tool of `model` (flat indices).
fn tool_offsets(model: &McpcModel) -> Vec<usize> {
    use crate::kinematics::ParameterKind;
    model
        .parameter_layout()
        .iter()
        .enumerate()
        .filter(|(_, (owner, kind))| {
            matches!(owner, ParameterOwner::Tool(_))
                && matches!(kind, ParameterKind::X | ParameterKind::Y | ParameterKind::Z)
        })
        .map(|(k, _)| k)
        .collect()
}

/// A tracker's positions of every tool of `truth` at `settings.per_kind` configurations, in the
/// reference link's frame: exact in `scene.exact`, with [`CONTACT_TRACKER_SIGMA`] noise (when
/// the contacts have encoder noise) in `scene.measurements`.
fn add_tracker_rows(
    tree: &KinematicTree,
    truth: &McpcModel,
    settings: &ContactSimulation,
    scene: &mut ContactScene,
    rng: &mut ChaCha8Rng,
) {
    let tools: Vec<usize> = (0..truth.tools().len()).collect();
    let exact = contact_tracker_rows(
        tree,
        truth,
        &tools,
        settings.per_kind,
        (&Pose::identity(), 0.0),
        rng,
    );
    let sigma = if settings.encoder_sigma > 0.0 {
        CONTACT_TRACKER_SIGMA
    } else {
        0.0
    };
    for row in &exact {
        let mut noisy = row.clone();
        if let Observation::Position(p) = &mut noisy.observation {
            *p += Vec3::from_fn(|_, _| sigma * rng.sample::<f64, _>(StandardNormal));
        }
        scene.measurements.push(noisy);
    }
    scene.exact.extend(exact);
}

/// Finite-difference step of the joint values for [`encoder_weights`] (rad, m).
const ENCODER_STEP: f64 = 1e-6;

/// Per contact, the weight that gives its rows the variance encoder noise `sigma_q` on every
/// joint gives them, on average over its rows, against the σ's of `options`: `w = k / Σ_r
/// (σ_q² ‖∂r_r/∂q‖² / σ_r²)` for its `k` rows (`∂r/∂q` by central differences on `model` with
/// `nuisance`). One lever for every contact misweighs a long chain (a humanoid's hand seen
/// from its sole) against a short one; the covariance then no longer describes the error.
fn encoder_weights(
    model: &McpcModel,
    nuisance: &Nuisance,
    measurements: &[Measurement],
    sigma_q: f64,
    options: &IdentificationOptions,
) -> Result<Vec<f64>> {
    let noise = options.noise();
    measurements
        .iter()
        .map(|m| {
            let Some(contact) = m.observation.contact() else {
                return Ok(1.0);
            };
            let kinds = crate::calibration::kind_of(&m.observation).row_kinds();
            let mut variance = vec![0.0; kinds.len()];
            let mut q = m.q.clone();
            for d in 0..q.len() {
                let value = q[d];
                q[d] = value + ENCODER_STEP;
                let up = violation(model, nuisance, contact, m.tool, &q)?;
                q[d] = value - ENCODER_STEP;
                let down = violation(model, nuisance, contact, m.tool, &q)?;
                q[d] = value;
                for (v, (u, w)) in variance.iter_mut().zip(up.iter().zip(&down)) {
                    let slope = (u - w) / (2.0 * ENCODER_STEP);
                    *v += slope * slope * sigma_q * sigma_q;
                }
            }
            let scaled: f64 = variance
                .iter()
                .zip(kinds)
                .map(|(v, &kind)| v / noise.sigma(kind).powi(2))
                .sum();
            Ok(if scaled > 0.0 {
                kinds.len() as f64 / scaled
            } else {
                1.0
            })
        })
        .collect()
}

/// The true nuisance values, the freed ones moved up to `error` (m, rad) off: the fit's start.
pub(super) fn nuisance_start(
    scene: &ContactScene,
    error: f64,
    rng: &mut ChaCha8Rng,
) -> Result<Nuisance> {
    let mut start = scene.nuisance.clone();
    let values: Vec<f64> = start
        .values()
        .iter()
        .enumerate()
        .map(|(k, v)| {
            if scene.free_nuisance.contains(&k) {
                v + error * rng.random_range(-1.0..1.0)
            } else {
                *v
            }
        })
        .collect();
    start.set_values(&values)?;
    Ok(start)
}

/// An independent set of columns of `jacobian` as large as its rank (the singular values above
/// `tolerance` times the largest, columns scaled to unit norm as the solver does), chosen
/// greedily by the largest norm left after projecting out the columns chosen before; in
/// increasing order. Deterministic.
pub fn independent_columns(jacobian: &DMatrix<f64>, tolerance: f64) -> Vec<usize> {
    let mut columns: Vec<DVector<f64>> = jacobian
        .column_iter()
        .map(|c| {
            let norm = c.norm();
            if norm > 0.0 {
                c / norm
            } else {
                c.into_owned()
            }
        })
        .collect();
    let scaled = DMatrix::from_columns(&columns);
    let singular = scaled.singular_values();
    let largest = singular.max();
    let rank = singular
        .iter()
        .filter(|&&s| s > tolerance * largest)
        .count();
    let mut chosen = Vec::with_capacity(rank);
    for _ in 0..rank {
        let Some((best, _)) = columns
            .iter()
            .enumerate()
            .filter(|(k, _)| !chosen.contains(k))
            .map(|(k, c)| (k, c.norm()))
            .max_by(|a, b| a.1.total_cmp(&b.1))
        else {
            break;
        };
        let basis = columns[best].normalize();
        for column in &mut columns {
            let along = basis.dot(column);
            column.axpy(-along, &basis, 1.0);
        }
        chosen.push(best);
    }
    chosen.sort_unstable();
    chosen
}

/// `columns` of `jacobian` (weighted, independent) without those whose standard deviation
/// `scale·√((JᵀJ)⁻¹ₖₖ)` (m, rad) exceeds `max_std`: the largest is dropped and the rest
/// recomputed until none does. Deterministic.
pub fn linear_columns(
    jacobian: &DMatrix<f64>,
    mut columns: Vec<usize>,
    scale: f64,
    max_std: f64,
) -> Vec<usize> {
    // At least one column stays: the noisy fit needs something to move.
    while columns.len() > 1 {
        let sub = DMatrix::from_columns(
            &columns
                .iter()
                .map(|&k| jacobian.column(k).into_owned())
                .collect::<Vec<_>>(),
        );
        let Some(inverse) = (sub.transpose() * &sub).try_inverse() else {
            break;
        };
        let (worst, std) = (0..columns.len())
            .map(|k| (k, scale * inverse[(k, k)].abs().sqrt()))
            .max_by(|a, b| a.1.total_cmp(&b.1))
            .unwrap_or((0, 0.0));
        if std <= max_std {
            break;
        }
        columns.remove(worst);
    }
    columns
}

/// The largest standard deviation (m, rad) of a direction whose error is compared with the
/// covariance: weaker directions (a few nearly unobservable combinations of a flush fit, which
/// the encoder noise moves by centimetres to metres) are not linear over their spread.
pub const LINEAR_STD: f64 = 1e-2;

/// Rank, largest observable error and its consistency with `σ̂²(JᵀJ)⁺`, from the SVD of the
/// column-scaled weighted Jacobian (the solver's rank decision).
fn observable_part(
    jacobian: &DMatrix<f64>,
    error: &DVector<f64>,
    tolerance: f64,
    scale: f64,
) -> (usize, usize, f64, f64) {
    let norms: Vec<f64> = jacobian.column_iter().map(|c| c.norm()).collect();
    let floor = norms.iter().copied().fold(0.0, f64::max) * 1e-6;
    let scales = DVector::from_iterator(
        norms.len(),
        norms
            .iter()
            .map(|&n| if n > floor { n } else { floor.max(1e-300) }),
    );
    let mut scaled = jacobian.clone();
    for (k, mut column) in scaled.column_iter_mut().enumerate() {
        column /= scales[k];
    }
    let svd = scaled.svd(false, true);
    let Some(v_t) = svd.v_t else {
        return (0, 0, f64::NAN, f64::NAN);
    };
    let largest = svd.singular_values.max();
    let scaled_error = error.component_mul(&scales);
    let mut projected = DVector::zeros(error.len());
    let (mut rank, mut compared, mut chi) = (0, 0, 0.0);
    for (i, &sigma) in svd.singular_values.iter().enumerate() {
        let v = v_t.row(i).transpose();
        // The direction's standard deviation in parameter units (m, rad): beyond
        // LINEAR_STD the fit is not linear there and the covariance does not apply.
        let spread = v.component_div(&scales).amax() * scale / sigma;
        if sigma > tolerance * largest {
            rank += 1;
        }
        if sigma > tolerance * largest && spread < LINEAR_STD {
            compared += 1;
            let along = v.dot(&scaled_error);
            projected += v * along;
            chi += (along * sigma / scale).powi(2);
        }
    }
    let observable = projected.component_div(&scales).amax();
    (
        rank,
        compared,
        observable,
        (chi / compared.max(1) as f64).sqrt(),
    )
}

/// The largest residual of the held-out contacts `validation` under the fitted robot and
/// nuisance of `report` (`nominal` gives the model's structure).
pub fn held_out_residual(
    nominal: &McpcModel,
    report: &IdentificationReport,
    validation: &[Measurement],
) -> Result<f64> {
    let mut model = nominal.clone();
    model.set_parameters(&report.parameters)?;
    let mut largest: f64 = 0.0;
    for m in validation {
        if let Some(contact) = m.observation.contact() {
            for value in violation(&model, &report.nuisance, contact, m.tool, &m.q)? {
                largest = largest.max(value.abs());
            }
        }
    }
    Ok(largest)
}
