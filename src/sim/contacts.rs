//! Simulated contacts (issue 29): configurations where the true robot really makes each
//! contact — its face flush with a plane, its contact point on a plane, its two hands
//! touching, its hands holding a bar — within the joint limits, and trials that identify the
//! robot and the contacts' nuisance parameters from them.
//!
//! Each contact configuration starts from a seed configuration where the contact holds (the
//! plane is placed through the first tool's face or contact point there; the touch seed is
//! found from random starts) moved by a random step, and is projected back onto the contact
//! by damped minimum-norm Newton steps in the joints (numerical joint derivatives: this places
//! data, the calibration's Jacobians are analytic), clamped to the ranges of the stance
//! ([`super::contact_limits`]: a standing robot's support leg near its rest, the joints no
//! frame moves at rest). Every configuration drawn or projected is kept only when the
//! [`ContactCollisions`] of the settings (or of [`collision_free_contact_configurations`],
//! `plan`'s candidates) allows it.

use super::contact_collisions::ContactCollisions;
pub use super::contact_trial::{
    contact_free_parameters, held_out_residual, independent_columns, linear_columns,
    run_contact_trial, ContactTrial, LINEAR_STD,
};
use super::stance::contact_limits;
use super::truth::ErrorRanges;
use crate::calibration::{contact_violation, NuisanceBlock, Tools};
use crate::calibration::{Nuisance, RobotState};
use crate::error::{Error, Result};
use crate::kinematics::McpcModel;
use crate::math::Pose;
use crate::measurement::{Contact, ContactFace, ContactPlane, Measurement, Observation};
use crate::tree::KinematicTree;
use nalgebra::{DMatrix, DVector, Translation3, UnitQuaternion, Vector3};
use rand::rngs::ChaCha8Rng;
use rand::RngExt;
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
    /// Tables (sessions, one plane each) of flush contacts; `per_kind` configurations per table
    /// and tool.
    pub tables: usize,
    /// Tools pressing flush on each table: 1 (the first) or 2 (both hands, one face each).
    pub flush_tools: usize,
    /// Also a tracker's positions of every tool at `per_kind` further configurations, fitted
    /// with the contacts (in the reference link's frame, σ
    /// [`super::contact_tracker::CONTACT_TRACKER_SIGMA`] when there is encoder noise).
    pub tracker_rows: bool,
    /// The self-collision check every generated configuration passes (`None`: not checked).
    pub collisions: Option<ContactCollisions>,
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
            tables: 1,
            flush_tools: 1,
            tracker_rows: false,
            collisions: None,
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
    let mut blocks = Blocks::default();
    let needs_points = settings.kinds.iter().any(|k| *k != ContactChoice::Flush);
    let points: Vec<usize> = (0..if needs_points { tools.min(2) } else { 0 })
        .map(|t| {
            let values = vec![
                rng.random_range(-0.02..0.02),
                rng.random_range(-0.02..0.02),
                0.05 + rng.random_range(-0.02..0.02),
            ];
            blocks.add(format!("point {}", name(t)), &["x", "y", "z"], values, &[])
        })
        .collect();
    let limits = contact_limits(tree, truth);
    let mut groups = Vec::new();
    for &kind in &settings.kinds {
        if kind == ContactChoice::Flush {
            groups.extend(flush_groups(
                truth,
                settings,
                &limits,
                &mut blocks,
                &name,
                rng,
            )?);
        } else {
            let made = (truth, settings, limits.as_slice());
            groups.push(point_group(made, kind, &mut blocks, &points, rng)?);
        }
    }
    let mut rows = SceneRows::default();
    for group in groups {
        rows.sample(truth, &blocks.nuisance, group, settings, &limits, rng)?;
    }
    Ok(ContactScene {
        nuisance: blocks.nuisance,
        free_nuisance: blocks.free,
        measurements: rows.measurements,
        exact: rows.exact,
        validation: rows.validation,
    })
}

/// The contacts of one kind other than flush, made by the first tool (with the second, for
/// touch and bar) at contact points `points`, and a seed configuration where it holds: for
/// `plane`, a plane (added to `blocks`) through the first tool's contact point at a random
/// configuration; for `touch` and `bar`, a configuration projected from random starts.
fn point_group(
    (truth, settings, limits): (&McpcModel, &ContactSimulation, &[(f64, f64)]),
    kind: ContactChoice,
    blocks: &mut Blocks,
    points: &[usize],
    rng: &mut ChaCha8Rng,
) -> Result<Group> {
    let seed = free_configuration(limits, rng, settings.collisions.as_ref())?;
    let contact = match kind {
        ContactChoice::Flush => {
            return Err(Error::Internal(
                "flush contacts are made by flush_groups, not point_group".into(),
            ))
        }
        ContactChoice::Plane => {
            let at = truth.tool_poses(&seed)[0];
            let c = blocks.nuisance.block_values(points[0])?;
            let origin = at
                .transform_point(&Vector3::new(c[0], c[1], c[2]).into())
                .coords;
            let tilt = UnitQuaternion::from_euler_angles(
                rng.random_range(-0.5..0.5),
                rng.random_range(-0.5..0.5),
                0.0,
            );
            let plane = ContactPlane {
                block: blocks.add(
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
            length: blocks.add("bar".into(), &["length"], vec![settings.bar_length], &[0]),
        },
    };
    let seed = match kind {
        ContactChoice::Touch | ContactChoice::Bar => {
            let nuisance = &blocks.nuisance;
            contact_seed(
                truth,
                nuisance,
                (&contact, 0),
                limits,
                (rng, settings.collisions.as_ref()),
                kind.name(),
            )?
        }
        ContactChoice::Flush | ContactChoice::Plane => seed,
    };
    Ok((kind, contact, 0, seed))
}

/// The measurements of a scene: identification rows as recorded (encoder noise included) and
/// at their exact configurations, and held-out validation rows (exact).
#[derive(Default)]
struct SceneRows {
    measurements: Vec<Measurement>,
    exact: Vec<Measurement>,
    validation: Vec<Measurement>,
}

impl SceneRows {
    /// `per_kind` identification rows and a quarter as many held out (at least 5) of `group`'s
    /// contact, each from its seed moved by a random step and projected back onto the contact.
    fn sample(
        &mut self,
        truth: &McpcModel,
        nuisance: &Nuisance,
        (kind, contact, tool, seed): Group,
        settings: &ContactSimulation,
        limits: &[(f64, f64)],
        rng: &mut ChaCha8Rng,
    ) -> Result<()> {
        let held_out = (settings.per_kind / 4).max(5);
        for index in 0..settings.per_kind + held_out {
            let q = (0..100)
                .find_map(|_| {
                    let start: Vec<f64> = seed
                        .iter()
                        .zip(limits)
                        .map(|(v, (lo, hi))| (v + rng.random_range(-0.5..0.5)).clamp(*lo, *hi))
                        .collect();
                    let collisions = settings.collisions.as_ref();
                    project_free(
                        truth,
                        nuisance,
                        (&contact, tool),
                        &start,
                        limits,
                        collisions,
                    )
                })
                .ok_or_else(|| {
                    invalid(format!(
                        "no further configuration found where the {} contact holds{}",
                        kind.name(),
                        collision_hint(settings.collisions.as_ref())
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
                tool,
                q,
                observation: Observation::Contact(Box::new(contact)),
                stage: None,
                payload: None,
                session: None,
            };
            if index < settings.per_kind {
                self.measurements.push(row(recorded));
                self.exact.push(row(q));
            } else {
                self.validation.push(row(q));
            }
        }
        Ok(())
    }
}

/// Contacts of one kind made by one tool from one seed configuration: the kind, the contact,
/// the tool, the seed.
type Group = (ContactChoice, Contact, usize, Vec<f64>);

/// The nuisance blocks of a scene and which of their values the fit frees.
#[derive(Default)]
struct Blocks {
    nuisance: Nuisance,
    free: Vec<usize>,
}

impl Blocks {
    /// Adds a block (values `held` are not freed); its index.
    fn add(&mut self, name: String, names: &[&str], values: Vec<f64>, held: &[usize]) -> usize {
        let start = self.nuisance.len();
        self.free.extend(
            (0..values.len())
                .filter(|k| !held.contains(k))
                .map(|k| start + k),
        );
        self.nuisance.blocks.push(NuisanceBlock {
            name,
            parameter_names: names.iter().map(|s| s.to_string()).collect(),
            values,
        });
        self.nuisance.blocks.len() - 1
    }
}

/// Flush contacts: one face per tool (`flush_tools`, its offset held: it aliases the plane's
/// height), one plane per table (`tables`: sessions `day1`, `day2`, …; one table: `flush`)
/// through the first tool's face at a random configuration, and a seed configuration where
/// each tool's face lies flush on it (the first's: that configuration; the second's: projected
/// from random starts).
fn flush_groups(
    truth: &McpcModel,
    settings: &ContactSimulation,
    limits: &[(f64, f64)],
    blocks: &mut Blocks,
    name: &dyn Fn(usize) -> String,
    rng: &mut ChaCha8Rng,
) -> Result<Vec<Group>> {
    let tools = settings.flush_tools.clamp(1, truth.tools().len().min(2));
    let faces: Vec<ContactFace> = (0..tools)
        .map(|t| ContactFace {
            block: blocks.add(
                format!("face {}", name(t)),
                &["offset", "tilt a", "tilt b"],
                vec![0.0; 3],
                // The first face's offset aliases the planes' heights; the second's, on the
                // same planes, is seen relative to it.
                if t == 0 { &[0] } else { &[] },
            ),
            nominal: Pose::from_parts(
                Translation3::new(0.0, 0.0, 0.05),
                UnitQuaternion::identity(),
            ),
        })
        .collect();
    let tables = settings.tables.max(1);
    let mut groups = Vec::new();
    for table in 0..tables {
        let seed = free_configuration(limits, rng, settings.collisions.as_ref())?;
        let session = if tables > 1 {
            format!("plane day{}", table + 1)
        } else {
            "plane flush".to_owned()
        };
        let plane = ContactPlane {
            block: blocks.add(session, &["height", "tilt a", "tilt b"], vec![0.0; 3], &[]),
            nominal: truth.tool_poses(&seed)[0] * faces[0].nominal,
        };
        for (tool, face) in faces.iter().enumerate() {
            let contact = Contact::Flush { plane, face: *face };
            let seed = if tool == 0 {
                seed.clone()
            } else {
                contact_seed(
                    truth,
                    &blocks.nuisance,
                    (&contact, tool),
                    limits,
                    (rng, settings.collisions.as_ref()),
                    "flush",
                )?
            };
            groups.push((ContactChoice::Flush, contact, tool, seed));
        }
    }
    Ok(groups)
}

/// A configuration where `contact` (of `tool`) holds, projected from random starts.
fn contact_seed(
    truth: &McpcModel,
    nuisance: &Nuisance,
    (contact, tool): (&Contact, usize),
    limits: &[(f64, f64)],
    (rng, collisions): (&mut ChaCha8Rng, Option<&ContactCollisions>),
    what: &str,
) -> Result<Vec<f64>> {
    (0..200)
        .find_map(|_| {
            let start = random_configuration(limits, rng);
            project_free(truth, nuisance, (contact, tool), &start, limits, collisions)
        })
        .ok_or_else(|| {
            invalid(format!(
                "no configuration found where the {what} contact holds{}",
                collision_hint(collisions)
            ))
        })
}

/// A random configuration within `limits` free of self-collision by `collisions` (the first
/// draw when not checked).
fn free_configuration(
    limits: &[(f64, f64)],
    rng: &mut ChaCha8Rng,
    collisions: Option<&ContactCollisions>,
) -> Result<Vec<f64>> {
    let Some(collisions) = collisions else {
        return Ok(random_configuration(limits, rng));
    };
    (0..200)
        .map(|_| random_configuration(limits, rng))
        .find(|q| collisions.allows(None, 0, q))
        .ok_or_else(|| {
            invalid(format!(
                "no configuration free of self-collision found in 200 random draws{}",
                collision_hint(Some(collisions))
            ))
        })
}

/// [`project`], kept only when free of self-collision (but for what the contact touches); the
/// joints no contact moves rest already, `start` being within [`contact_limits`].
fn project_free(
    model: &McpcModel,
    nuisance: &Nuisance,
    (contact, tool): (&Contact, usize),
    start: &[f64],
    limits: &[(f64, f64)],
    collisions: Option<&ContactCollisions>,
) -> Option<Vec<f64>> {
    match collisions {
        None => project(model, nuisance, contact, tool, start, limits),
        Some(c) => project(model, nuisance, contact, tool, start, limits)
            .filter(|q| c.allows(Some(contact), tool, q)),
    }
}

/// The end of a "none found" message when configurations were rejected for self-collision.
fn collision_hint(collisions: Option<&ContactCollisions>) -> String {
    match collisions.map(ContactCollisions::rejected) {
        Some(n) if n > 0 => format!(
            " ({n} configurations where it holds were in self-collision; `collision_check` off \
             skips the check)"
        ),
        _ => String::new(),
    }
}

fn invalid(message: String) -> Error {
    Error::InvalidData {
        origin: "contact simulation".into(),
        message,
    }
}

pub(super) fn random_configuration(limits: &[(f64, f64)], rng: &mut ChaCha8Rng) -> Vec<f64> {
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
pub(super) fn violation(
    model: &McpcModel,
    nuisance: &Nuisance,
    contact: &Contact,
    tool: usize,
    q: &[f64],
) -> Result<Vec<f64>> {
    let poses = model.tool_poses(q);
    let state = RobotState {
        model,
        q,
        tool,
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
    tool: usize,
    start: &[f64],
    limits: &[(f64, f64)],
) -> Option<Vec<f64>> {
    let mut q = start.to_vec();
    let step = 1e-6;
    for _ in 0..60 {
        let v = DVector::from_vec(violation(model, nuisance, contact, tool, &q).ok()?);
        if v.norm() < 1e-12 {
            return Some(q);
        }
        let mut jacobian = DMatrix::zeros(v.len(), q.len());
        for j in 0..q.len() {
            let mut moved = q.clone();
            moved[j] += step;
            let plus = DVector::from_vec(violation(model, nuisance, contact, tool, &moved).ok()?);
            moved[j] -= 2.0 * step;
            let minus = DVector::from_vec(violation(model, nuisance, contact, tool, &moved).ok()?);
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

/// `count` configurations of `model` where `contact` (of `tool`) holds within the joint
/// limits, as simulated contacts are placed: a seed configuration projected from random
/// starts, then each configuration the seed moved by a random step and projected back onto
/// the contact (projections in parallel, kept in draw order: deterministic for a seed).
/// Fewer than `count` when the contact is hard to reach; an error naming `what` when none is
/// found.
pub fn contact_configurations(
    tree: &KinematicTree,
    model: &McpcModel,
    nuisance: &Nuisance,
    (contact, tool): (&Contact, usize),
    count: usize,
    rng: &mut ChaCha8Rng,
    what: &str,
) -> Result<Vec<Vec<f64>>> {
    let at = (contact, tool);
    collision_free_contact_configurations(tree, model, nuisance, at, count, (rng, None), what)
}

/// [`contact_configurations`] that are free of self-collision by `collisions` but for what
/// the contact touches (`None`: not checked).
pub fn collision_free_contact_configurations(
    tree: &KinematicTree,
    model: &McpcModel,
    nuisance: &Nuisance,
    (contact, tool): (&Contact, usize),
    count: usize,
    (rng, collisions): (&mut ChaCha8Rng, Option<&ContactCollisions>),
    what: &str,
) -> Result<Vec<Vec<f64>>> {
    use rayon::prelude::*;
    let limits = contact_limits(tree, model);
    let at = (contact, tool);
    let seed = contact_seed(model, nuisance, at, &limits, (rng, collisions), what)?;
    let mut found = Vec::with_capacity(count);
    let mut tries = 0;
    while found.len() < count && tries < 20 * count.max(1) {
        let batch = (count - found.len()).clamp(16, 256);
        tries += batch;
        let starts: Vec<Vec<f64>> = (0..batch)
            .map(|_| {
                seed.iter()
                    .zip(&limits)
                    .map(|(v, (lo, hi))| (v + rng.random_range(-0.5..0.5)).clamp(*lo, *hi))
                    .collect()
            })
            .collect();
        let projected: Vec<Option<Vec<f64>>> = starts
            .par_iter()
            .map(|start| project_free(model, nuisance, at, start, &limits, collisions))
            .collect();
        found.extend(projected.into_iter().flatten().take(count - found.len()));
    }
    Ok(found)
}

/// `start` moved onto `contact` (of `tool`) on `model` within the joint limits by the
/// simulation's projection (violation below 1e-12), if it converges: how a lab's robot,
/// sent to a planned configuration, ends up touching.
pub fn onto_contact(
    tree: &KinematicTree,
    model: &McpcModel,
    nuisance: &Nuisance,
    (contact, tool): (&Contact, usize),
    start: &[f64],
) -> Option<Vec<f64>> {
    project(
        model,
        nuisance,
        contact,
        tool,
        start,
        &contact_limits(tree, model),
    )
}
