//! Simulated contacts (issue 29): configurations where the true robot really makes each
//! contact — its face flush with a plane, its contact point on a plane, its two hands
//! touching, its hands holding a bar — within the joint limits, and trials that identify the
//! robot and the contacts' nuisance parameters from them.
//!
//! Each contact configuration starts from a seed configuration where the contact holds (the
//! plane is placed through the first tool's face or contact point there; the touch seed is
//! found from random starts) moved by a random step, and is projected back onto the contact
//! by damped minimum-norm Newton steps in the joints (numerical joint derivatives: this places
//! data, the calibration's Jacobians are analytic), clamped to the joint limits. Self-collision
//! is not checked here.

use super::truth::{true_model, ErrorRanges};
use crate::calibration::observation::{contact_violation, NuisanceBlock, Tools};
use crate::calibration::{
    identify_with_nuisance, weighted_jacobian, IdentificationOptions, IdentificationReport,
    Nuisance, Rigid, RobotState,
};
use crate::error::{Error, Result};
use crate::kinematics::{McpcModel, ParameterOwner};
use crate::math::Pose;
use crate::measurement::{Contact, ContactFace, ContactPlane, Measurement, Observation};
use crate::tree::KinematicTree;
use nalgebra::{DMatrix, DVector, Translation3, UnitQuaternion, Vector3};
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use rand_distr::{Distribution, StandardNormal};

/// A kind of simulated contact (`simulate --observation`'s contact names).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ContactChoice {
    /// `flush`: the first tool's face flush with a plane.
    Flush,
    /// `plane`: the first tool's contact point on a plane (point contacts).
    Plane,
    /// `touch`: the first two tools' contact points touch.
    Touch,
    /// `bar`: the first two tools' contact points hold a bar of known length.
    Bar,
}

impl ContactChoice {
    /// The name `simulate --observation` takes.
    pub fn name(self) -> &'static str {
        match self {
            ContactChoice::Flush => "flush",
            ContactChoice::Plane => "plane",
            ContactChoice::Touch => "touch",
            ContactChoice::Bar => "bar",
        }
    }

    /// The choice named `name`, if it is a contact.
    pub fn parse(name: &str) -> Option<Self> {
        [Self::Flush, Self::Plane, Self::Touch, Self::Bar]
            .into_iter()
            .find(|c| c.name() == name)
    }
}

/// Settings of a simulated contact experiment.
#[derive(Debug, Clone)]
pub struct ContactSimulation {
    /// The contact kinds, each with `per_kind` configurations.
    pub kinds: Vec<ContactChoice>,
    /// Configurations per kind.
    pub per_kind: usize,
    /// σ of the encoder noise added to the recorded configurations (rad or m; 0: none).
    pub encoder_sigma: f64,
    /// The bar's length (m, known to the fit).
    pub bar_length: f64,
    /// The true robot's parameter errors.
    pub errors: ErrorRanges,
    /// How far the fit's starting nuisance values are from the true ones (m and rad).
    pub nuisance_start_error: f64,
}

impl Default for ContactSimulation {
    fn default() -> Self {
        Self {
            kinds: vec![ContactChoice::Touch, ContactChoice::Bar],
            per_kind: 40,
            encoder_sigma: 0.0,
            bar_length: 0.3,
            errors: ErrorRanges {
                angle: 0.01,
                length: 0.01,
            },
            nuisance_start_error: 0.01,
        }
    }
}

/// Simulated contacts: the true nuisance values, which of them the fit frees (indices among
/// the nuisance values), and the measurements (configurations as recorded, noise included).
#[derive(Debug, Clone)]
pub struct ContactScene {
    /// The true nuisance values (planes, contact points, face, bar).
    pub nuisance: Nuisance,
    /// Nuisance values the fit frees (the face offset, which aliases the plane height exactly,
    /// and the known bar length are held).
    pub free_nuisance: Vec<usize>,
    /// One measurement per contact configuration (configurations as recorded).
    pub measurements: Vec<Measurement>,
    /// The same contacts at their exact configurations (no encoder noise).
    pub exact: Vec<Measurement>,
    /// Held-out contacts of every kind at their exact configurations (validation).
    pub validation: Vec<Measurement>,
}

/// The contacts of `kinds` made by `truth` (tools 0 and 1), `per_kind` configurations each.
pub fn contact_scene(
    tree: &KinematicTree,
    truth: &McpcModel,
    settings: &ContactSimulation,
    rng: &mut ChaCha8Rng,
) -> Result<ContactScene> {
    let tools = truth.tools().len();
    let pairs = settings
        .kinds
        .iter()
        .any(|k| matches!(k, ContactChoice::Touch | ContactChoice::Bar));
    if tools < 1 || (pairs && tools < 2) {
        return Err(invalid(format!(
            "the robot has {tools} tools; touch and bar need two, flush and plane one"
        )));
    }
    let name = |tool: usize| tree.link(truth.tools()[tool].link).name.clone();
    let mut nuisance = Nuisance::default();
    let mut free = Vec::new();
    let mut add = |nuisance: &mut Nuisance,
                   name: String,
                   names: &[&str],
                   values: Vec<f64>,
                   held: &[usize]| {
        let start = nuisance.len();
        free.extend(
            (0..values.len())
                .filter(|k| !held.contains(k))
                .map(|k| start + k),
        );
        nuisance.blocks.push(NuisanceBlock {
            name,
            parameter_names: names.iter().map(|s| s.to_string()).collect(),
            values,
        });
        nuisance.blocks.len() - 1
    };
    let point = |rng: &mut ChaCha8Rng| {
        vec![
            rng.random_range(-0.02..0.02),
            rng.random_range(-0.02..0.02),
            0.05 + rng.random_range(-0.02..0.02),
        ]
    };
    let needs_points = settings.kinds.iter().any(|k| *k != ContactChoice::Flush);
    let points: Vec<usize> = (0..if needs_points { tools.min(2) } else { 0 })
        .map(|t| {
            let values = point(rng);
            add(
                &mut nuisance,
                format!("point {}", name(t)),
                &["x", "y", "z"],
                values,
                &[],
            )
        })
        .collect();
    let limits = limits_of(tree);
    let (mut measurements, mut exact, mut validation) = (Vec::new(), Vec::new(), Vec::new());
    let held_out = (settings.per_kind / 4).max(5);
    for &kind in &settings.kinds {
        let seed = random_configuration(&limits, rng);
        let contact = match kind {
            ContactChoice::Flush => {
                let face = ContactFace {
                    block: add(
                        &mut nuisance,
                        format!("face {}", name(0)),
                        &["offset", "tilt a", "tilt b"],
                        vec![0.0; 3],
                        &[0],
                    ),
                    nominal: Pose::from_parts(
                        Translation3::new(0.0, 0.0, 0.05),
                        UnitQuaternion::identity(),
                    ),
                };
                let plane = ContactPlane {
                    block: add(
                        &mut nuisance,
                        "plane flush".into(),
                        &["height", "tilt a", "tilt b"],
                        vec![0.0; 3],
                        &[],
                    ),
                    nominal: truth.tool_poses(&seed)[0] * face.nominal,
                };
                Contact::Flush { plane, face }
            }
            ContactChoice::Plane => {
                let at = truth.tool_poses(&seed)[0];
                let c = nuisance.block_values(points[0])?;
                let origin = at
                    .transform_point(&Vector3::new(c[0], c[1], c[2]).into())
                    .coords;
                let tilt = UnitQuaternion::from_euler_angles(
                    rng.random_range(-0.5..0.5),
                    rng.random_range(-0.5..0.5),
                    0.0,
                );
                let plane = ContactPlane {
                    block: add(
                        &mut nuisance,
                        "plane table".into(),
                        &["height", "tilt a", "tilt b"],
                        vec![0.0; 3],
                        &[],
                    ),
                    nominal: Pose::from_parts(Translation3::from(origin), tilt),
                };
                Contact::Point {
                    plane,
                    point: points[0],
                }
            }
            ContactChoice::Touch => Contact::Touch {
                point: points[0],
                tool2: 1,
                point2: points[1],
            },
            ContactChoice::Bar => Contact::Distance {
                point: points[0],
                tool2: 1,
                point2: points[1],
                length: add(
                    &mut nuisance,
                    "bar".into(),
                    &["length"],
                    vec![settings.bar_length],
                    &[0],
                ),
            },
        };
        let seed = match kind {
            ContactChoice::Touch | ContactChoice::Bar => (0..200)
                .find_map(|_| {
                    project(
                        truth,
                        &nuisance,
                        &contact,
                        &random_configuration(&limits, rng),
                        &limits,
                    )
                })
                .ok_or_else(|| {
                    invalid(format!(
                        "no configuration found where the {} contact holds",
                        kind.name()
                    ))
                })?,
            _ => seed,
        };
        for index in 0..settings.per_kind + held_out {
            let q = (0..100)
                .find_map(|_| {
                    let start: Vec<f64> = seed
                        .iter()
                        .zip(&limits)
                        .map(|(v, (lo, hi))| (v + rng.random_range(-0.5..0.5)).clamp(*lo, *hi))
                        .collect();
                    project(truth, &nuisance, &contact, &start, &limits)
                })
                .ok_or_else(|| {
                    invalid(format!(
                        "no further configuration found where the {} contact holds",
                        kind.name()
                    ))
                })?;
            let recorded = q
                .iter()
                .map(|v| {
                    let n: f64 = StandardNormal.sample(rng);
                    v + settings.encoder_sigma * n
                })
                .collect();
            let row = |q: Vec<f64>| Measurement {
                tool: 0,
                q,
                observation: Observation::Contact(contact),
                stage: None,
                payload: None,
                session: None,
            };
            if index < settings.per_kind {
                measurements.push(row(recorded));
                exact.push(row(q));
            } else {
                validation.push(row(q));
            }
        }
    }
    Ok(ContactScene {
        nuisance,
        free_nuisance: free,
        measurements,
        exact,
        validation,
    })
}

fn invalid(message: String) -> Error {
    Error::InvalidData {
        origin: "contact simulation".into(),
        message,
    }
}

/// Each joint variable's range (unbounded: [−π, π]).
fn limits_of(tree: &KinematicTree) -> Vec<(f64, f64)> {
    tree.dof_limits()
        .iter()
        .map(|l| {
            l.map_or((-std::f64::consts::PI, std::f64::consts::PI), |l| {
                (l.lower, l.upper)
            })
        })
        .collect()
}

fn random_configuration(limits: &[(f64, f64)], rng: &mut ChaCha8Rng) -> Vec<f64> {
    limits
        .iter()
        .map(|(lo, hi)| {
            if hi > lo {
                rng.random_range(*lo..*hi)
            } else {
                *lo
            }
        })
        .collect()
}

/// The contact's violation at `q` on `model`.
fn violation(
    model: &McpcModel,
    nuisance: &Nuisance,
    contact: &Contact,
    q: &[f64],
) -> Result<Vec<f64>> {
    let poses = model.tool_poses(q);
    let state = RobotState {
        model,
        q,
        tool: 0,
        tools: Tools::Poses(&poses),
        offset: None,
        nuisance,
    };
    contact_violation(contact, &state)
}

/// `start` moved onto the contact (violation below 1e-12) within the limits, if found.
fn project(
    model: &McpcModel,
    nuisance: &Nuisance,
    contact: &Contact,
    start: &[f64],
    limits: &[(f64, f64)],
) -> Option<Vec<f64>> {
    let mut q = start.to_vec();
    let step = 1e-6;
    for _ in 0..60 {
        let v = DVector::from_vec(violation(model, nuisance, contact, &q).ok()?);
        if v.norm() < 1e-12 {
            return Some(q);
        }
        let mut jacobian = DMatrix::zeros(v.len(), q.len());
        for j in 0..q.len() {
            let mut moved = q.clone();
            moved[j] += step;
            let plus = DVector::from_vec(violation(model, nuisance, contact, &moved).ok()?);
            moved[j] -= 2.0 * step;
            let minus = DVector::from_vec(violation(model, nuisance, contact, &moved).ok()?);
            jacobian.set_column(j, &((plus - minus) / (2.0 * step)));
        }
        let gram = &jacobian * jacobian.transpose() + DMatrix::identity(v.len(), v.len()) * 1e-14;
        let mut delta = -(jacobian.transpose() * gram.cholesky()?.solve(&v));
        if delta.norm() > 0.3 {
            delta *= 0.3 / delta.norm();
        }
        for ((value, d), (lo, hi)) in q.iter_mut().zip(delta.iter()).zip(limits) {
            *value = (*value + d).clamp(*lo, *hi);
        }
    }
    None
}

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
    let truth = true_model(nominal, &settings.errors, &mut rng)?;
    let scene = contact_scene(tree, &truth, settings, &mut rng)?;
    let count = nominal.parameter_count();
    let mut free = contact_free_parameters(nominal);
    free.extend(scene.free_nuisance.iter().map(|k| count + k));
    let mut start = scene.nuisance.clone();
    let values: Vec<f64> = start
        .values()
        .iter()
        .enumerate()
        .map(|(k, v)| {
            if scene.free_nuisance.contains(&k) {
                v + settings.nuisance_start_error * rng.random_range(-1.0..1.0)
            } else {
                *v
            }
        })
        .collect();
    start.set_values(&values)?;
    let lever = 0.5;
    let sigma = settings.encoder_sigma.max(1e-6);
    let options = IdentificationOptions {
        max_iterations: 100,
        height_sigma: sigma * lever,
        gap_sigma: sigma * lever,
        length_sigma: sigma * lever,
        tilt_sigma: sigma,
        ..IdentificationOptions::default()
    };
    let fit = |measurements: &[Measurement]| {
        identify_with_nuisance(nominal, &start, measurements, None, &Rigid, &free, &options)
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
    let values = |r: &IdentificationReport| -> Vec<f64> {
        r.parameters
            .iter()
            .copied()
            .chain(r.nuisance.values())
            .collect()
    };
    let (reference, estimated) = (values(&exact), values(&noisy));
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
    let noise_free_held_out = held_out_residual(nominal, &exact, &scene.validation)?;
    let held_out = held_out_residual(nominal, &report, &scene.validation)?;
    Ok(ContactTrial {
        noise_free_held_out,
        held_out,
        report,
        free,
        rank: exact.rank,
        linear_rank,
        observable_error,
        consistency,
        truth_nuisance: scene.nuisance.clone(),
        scene,
    })
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
    while !columns.is_empty() {
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
        if let Observation::Contact(contact) = &m.observation {
            for value in violation(&model, &report.nuisance, contact, &m.q)? {
                largest = largest.max(value.abs());
            }
        }
    }
    Ok(largest)
}
