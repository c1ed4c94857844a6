//! The contact calibration's problem and its two fits (`calibrate --contacts`, issue 29):
//! what [`super::calibrate_contacts`] builds and fits and `report::contacts` renders.

use crate::calibration::{contact_violation, Tools};
use crate::calibration::{
    identify_with_nuisance, IdentificationOptions, IdentificationReport, Nuisance, Rigid,
    RobotState,
};
use crate::error::Result;
use crate::io::ContactKind;
use crate::kinematics::McpcModel;
use crate::math::{Pose, Vec3};
use crate::measurement::{Contact, Measurement, Observation};
#[cfg(doc)]
use crate::sim::contact_free_parameters;
use nalgebra::{Matrix3, UnitQuaternion};
use std::collections::BTreeMap;

/// The contacts of one file as measurements of a model, with the nuisance they need.
#[derive(Debug, Clone)]
pub struct ContactProblem {
    /// The model (every tool of the setup, from the reference link).
    pub model: McpcModel,
    /// The nuisance values at their start (setup nominals; planes from closed-form fits).
    pub nuisance: Nuisance,
    /// Nuisance values to fit (indices among the nuisance values).
    pub free_nuisance: Vec<usize>,
    /// Training contacts.
    pub training: Vec<Measurement>,
    /// Held-out contacts.
    pub validation: Vec<Measurement>,
    /// Each session's plane block.
    pub planes: BTreeMap<String, usize>,
    /// Each session's nominal plane of the setup file (before the closed-form start).
    pub setup_planes: BTreeMap<String, Pose>,
    /// The contact kinds present.
    pub kinds: Vec<ContactKind>,
    /// Model parameters other rows add to both fits (tracker rows: the measurement frame and
    /// the measured tools' target offsets).
    pub registration_free: Vec<usize>,
    /// The robot's parameters the second fit frees (default every joint frame's:
    /// [`contact_free_parameters`]; fewer with `model` offsets or `freeze`).
    pub robot_free: Vec<usize>,
}

/// The two fits of a contact calibration.
#[derive(Debug, Clone)]
pub struct ContactFit {
    /// The registered nominal robot: only the nuisance fitted.
    pub before: IdentificationReport,
    /// The joint frames and the nuisance fitted (from `before`).
    pub after: IdentificationReport,
    /// Free columns of `after` (model parameters, then nuisance values).
    pub free: Vec<usize>,
}

/// Fits the nuisance (and the tracker's registration, with tracker rows) on the nominal robot
/// ("before"), then the robot's joint frames with it.
pub fn fit_contacts(
    problem: &ContactProblem,
    options: &IdentificationOptions,
) -> Result<ContactFit> {
    let model = &problem.model;
    let count = model.parameter_count();
    let mut nuisance_free: Vec<usize> = problem.free_nuisance.iter().map(|k| count + k).collect();
    nuisance_free.extend(&problem.registration_free);
    nuisance_free.sort_unstable();
    nuisance_free.dedup();
    let before = identify_with_nuisance(
        model,
        &problem.nuisance,
        &problem.training,
        None,
        &Rigid,
        &nuisance_free,
        options,
    )?;
    let mut free = problem.robot_free.clone();
    free.extend(nuisance_free);
    free.sort_unstable();
    free.dedup();
    let after = identify_with_nuisance(
        model,
        &before.nuisance,
        &problem.training,
        None,
        &Rigid,
        &free,
        options,
    )?;
    Ok(ContactFit {
        before,
        after,
        free,
    })
}

/// The violation (predicted values, m and rad) of each contact of `rows` under `model` with
/// `parameters` and `nuisance`.
pub fn contact_violations(
    model: &McpcModel,
    parameters: &[f64],
    nuisance: &Nuisance,
    rows: &[Measurement],
) -> Result<Vec<(Contact, Vec<f64>)>> {
    let mut model = model.clone();
    model.set_parameters(parameters)?;
    rows.iter()
        .filter_map(|m| match &m.observation {
            Observation::Contact(c) => Some((m, **c)),
            _ => None,
        })
        .map(|(m, contact)| {
            let poses = model.tool_poses(&m.q);
            let state = RobotState {
                model: &model,
                q: &m.q,
                tool: m.tool,
                tools: Tools::Poses(&poses),
                offset: None,
                nuisance,
            };
            Ok((contact, contact_violation(&contact, &state)?))
        })
        .collect()
}

/// A plane through the nominal robot's contacts of one session: the centroid of the face
/// points (or contact points), the normal the mean face normal (flush; its sign that of the
/// setup's normal) or the smallest principal direction of the points when they span a plane,
/// else the setup's normal. The rotation is the setup's turned by the smallest rotation onto
/// that normal. `setup` when there are no rows.
pub fn plane_start(
    model: &McpcModel,
    nuisance: &Nuisance,
    rows: &[&Measurement],
    setup: &Pose,
) -> Pose {
    let n0 = setup.rotation * Vec3::z();
    let (mut points, mut normals) = (Vec::new(), Vec::new());
    for m in rows {
        let Some(contact) = m.observation.contact() else {
            continue;
        };
        let tool = model.tool_poses(&m.q)[m.tool];
        match contact {
            Contact::Flush { face, .. } => {
                let at = tool * face.nominal;
                points.push(at.translation.vector);
                let a = at.rotation * Vec3::z();
                normals.push(if a.dot(&n0) < 0.0 { -a } else { a });
            }
            Contact::Point { point, .. } => {
                if let Ok(c) = nuisance.block_values(*point) {
                    points.push(tool * nalgebra::Point3::new(c[0], c[1], c[2]).coords);
                }
            }
            _ => {}
        }
    }
    if points.is_empty() {
        return *setup;
    }
    let centroid = points.iter().sum::<Vec3>() / points.len() as f64;
    let mean_normal: Vec3 = normals.iter().sum();
    let normal = if mean_normal.norm() > 1e-9 {
        mean_normal.normalize()
    } else {
        principal_normal(&points, &centroid).unwrap_or(n0)
    };
    let normal = if normal.dot(&n0) < 0.0 {
        -normal
    } else {
        normal
    };
    let turn =
        UnitQuaternion::rotation_between(&n0, &normal).unwrap_or_else(UnitQuaternion::identity);
    Pose::from_parts(centroid.into(), turn * setup.rotation)
}

/// The least-squares plane normal of `points`, when they span a plane (smallest spread below
/// a tenth of the middle one).
fn principal_normal(points: &[Vec3], centroid: &Vec3) -> Option<Vec3> {
    if points.len() < 3 {
        return None;
    }
    let scatter: Matrix3<f64> = points
        .iter()
        .map(|p| (p - centroid) * (p - centroid).transpose())
        .sum();
    let eigen = scatter.symmetric_eigen();
    let mut order = [0, 1, 2];
    order.sort_by(|a, b| eigen.eigenvalues[*a].total_cmp(&eigen.eigenvalues[*b]));
    (eigen.eigenvalues[order[0]] < 0.01 * eigen.eigenvalues[order[1]])
        .then(|| eigen.eigenvectors.column(order[0]).into_owned())
}
