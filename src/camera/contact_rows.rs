//! Contacts in a camera fit (issue 29, "camera + touch"): touch, bar, flush and point rows
//! enter the same least-squares problem as the pixels and the tracker rows, each row divided
//! by its own σ (heights and gaps in m, tilts in rad: [`Noise`]).
//!
//! The rows come from the observation seam unchanged ([`kind_of`]: the contact's residual and
//! its analytic Jacobian with respect to the model's parameters and its nuisance values), so
//! no contact math lives here. The camera fit is the consumer: it evaluates the augmented
//! model's tool Jacobians at each contact's configuration (the contact's tools are robot
//! tools, numbered before the rig's extra tools), hands them to the kind as a
//! [`RobotState`], and scatters the columns into its own unknowns: a model parameter is
//! `Unknown::Parameter`, a contact's nuisance value (a plane, a contact point, a face, a bar)
//! `Unknown::Nuisance`; intrinsics have no contact column. See `docs/camera.md` §6 and
//! `docs/contacts.md`.

use crate::calibration::Tools;
use crate::calibration::{kind_of, Noise, Nuisance, RobotState, RowKind};
use crate::error::{Error, Result};
use crate::kinematics::{McpcModel, ToolJacobian};
use crate::math::Pose;
use crate::measurement::Measurement;
use nalgebra::{DMatrix, DVector};

/// The contacts of a camera fit and the nuisance values they start from.
#[derive(Debug, Clone, Copy)]
pub struct ContactRows<'a> {
    /// Contact measurements (every observation a [`Observation::Contact`](crate::measurement::Observation::Contact)); tools are robot
    /// tools of the augmented model.
    pub rows: &'a [Measurement],
    /// The nuisance blocks the contacts name, at their starting values.
    pub nuisance: &'a Nuisance,
}

impl Default for ContactRows<'_> {
    /// No contacts.
    fn default() -> Self {
        Self {
            rows: &[],
            nuisance: Nuisance::none(),
        }
    }
}

impl ContactRows<'_> {
    /// The residual rows the contacts contribute.
    pub fn row_count(&self) -> usize {
        self.rows.iter().map(|m| m.observation.rows()).sum()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.rows.is_empty()
    }

    /// An error naming the first contact that is not a contact, names a tool the model does
    /// not have (or a rig tool), or has a bad configuration.
    pub(super) fn validate(&self, robot_tools: usize, dofs: usize) -> Result<()> {
        for (index, m) in self.rows.iter().enumerate() {
            let Some(contact) = m.observation.contact() else {
                return Err(invalid(format!(
                    "contact row {index} is not a contact (tracker rows go in `tracker`)"
                )));
            };
            let second = contact.second_tool().unwrap_or(m.tool);
            if m.tool >= robot_tools || second >= robot_tools {
                return Err(invalid(format!(
                    "contact row {index} names a tool that is not one of the robot's \
                     {robot_tools}"
                )));
            }
            if m.q.len() < dofs || !m.q.iter().all(|v| v.is_finite()) {
                return Err(invalid(format!(
                    "contact row {index} has a bad configuration"
                )));
            }
        }
        Ok(())
    }
}

/// Writes the contacts' weighted residuals (each row over its σ in `noise`) into `residual`
/// from row `start` on and, when `jacobian` has rows, their weighted Jacobian over
/// the unknowns, at `model` and `nuisance`: `(flat, positions)` are the unknowns that are model
/// parameters or nuisance values as flat seam indices (the model's parameters, then the
/// nuisance values) and their positions among the unknowns.
pub(super) fn add_contact_rows(
    contacts: &ContactRows<'_>,
    (model, nuisance): (&McpcModel, &Nuisance),
    (flat, positions): (&[usize], &[usize]),
    noise: &Noise,
    start: usize,
    residual: &mut DVector<f64>,
    jacobian: &mut DMatrix<f64>,
) -> Result<()> {
    let with_jacobian = jacobian.nrows() > 0;
    let mut cached_jacobians: Option<(&[f64], Vec<ToolJacobian>)> = None;
    let mut cached_poses: Option<(&[f64], Vec<Pose>)> = None;
    let mut row = start;
    for m in contacts.rows {
        let kind = kind_of(&m.observation);
        let count = kind.rows();
        let tools = if with_jacobian {
            if cached_jacobians
                .as_ref()
                .is_none_or(|(q, _)| *q != m.q.as_slice())
            {
                cached_jacobians = Some((m.q.as_slice(), model.tool_jacobians(&m.q)));
            }
            Tools::Jacobians(cached_jacobians.as_ref().map_or(&[][..], |(_, j)| j))
        } else {
            if cached_poses
                .as_ref()
                .is_none_or(|(q, _)| *q != m.q.as_slice())
            {
                cached_poses = Some((m.q.as_slice(), model.tool_poses(&m.q)));
            }
            Tools::Poses(cached_poses.as_ref().map_or(&[][..], |(_, p)| p))
        };
        let state = RobotState {
            model,
            q: &m.q,
            tool: m.tool,
            tools,
            offset: None,
            nuisance,
        };
        let mut values = vec![0.0; count];
        kind.residual(&state, &mut values)?;
        let weights: Vec<f64> = kind
            .row_kinds()
            .iter()
            .map(|&k| 1.0 / noise.sigma(k))
            .collect();
        for k in 0..count {
            residual[row + k] = values[k] * weights[k];
        }
        if with_jacobian {
            let mut block = DMatrix::zeros(count, flat.len());
            kind.jacobian(&state, flat, &mut block.as_view_mut())?;
            for k in 0..count {
                for (c, &position) in positions.iter().enumerate() {
                    jacobian[(row + k, position)] = block[(k, c)] * weights[k];
                }
            }
        }
        row += count;
    }
    Ok(())
}

/// `(row kind, contacts, rows, Σ r²)` of the contacts' weighted residual rows `residual`
/// (the contact rows only, in order), one entry per row kind present, in [`RowKind::ALL`]
/// order.
pub(super) fn contact_sums(
    contacts: &ContactRows<'_>,
    residual: &[f64],
) -> Vec<(RowKind, usize, usize, f64)> {
    let mut sums: Vec<(RowKind, usize, usize, f64)> = Vec::new();
    let mut row = 0;
    for m in contacts.rows {
        let kinds = kind_of(&m.observation).row_kinds();
        let mut seen: Vec<RowKind> = Vec::new();
        for &kind in kinds {
            let value = residual.get(row).copied().unwrap_or(0.0);
            row += 1;
            let index = match sums.iter().position(|s| s.0 == kind) {
                Some(index) => index,
                None => {
                    sums.push((kind, 0, 0, 0.0));
                    sums.len() - 1
                }
            };
            let entry = &mut sums[index];
            if !seen.contains(&kind) {
                entry.1 += 1;
                seen.push(kind);
            }
            entry.2 += 1;
            entry.3 += value * value;
        }
    }
    sums.sort_by_key(|s| RowKind::ALL.iter().position(|k| *k == s.0));
    sums
}

fn invalid(message: String) -> Error {
    Error::InvalidData {
        origin: "camera calibration".into(),
        message,
    }
}
