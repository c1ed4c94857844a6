//! The identification problem: measurements grouped by payload, one compliance basis per
//! payload, and its linearisation (weighted residual and Jacobian over the free geometry and
//! the compliance scales).

use crate::calibration::options::IdentificationOptions;
use crate::calibration::Termination;
use crate::calibration::{kind_of, Nuisance, RobotState, Tools};
use crate::error::{Error, Result};
use crate::kinematics::{ComplianceBasis, ComplianceParameter};
use crate::kinematics::{FlexibilityModel, McpcModel};
use crate::math::Pose;
use crate::measurement::Measurement;
use crate::tree::KinematicTree;
use nalgebra::{DMatrix, DVector, Vector6};

/// The measurements, grouped by payload, with one compliance basis per payload.
pub(super) struct Problem<'a> {
    pub(super) tree: &'a KinematicTree,
    pub(super) measurements: &'a [Measurement],
    /// Per distinct payload (`None`: the prior's own), its basis.
    pub(super) bases: Vec<(Option<f64>, ComplianceBasis)>,
    /// Per measurement, its basis.
    pub(super) basis_of: Vec<usize>,
    pub(super) free: &'a [usize],
    pub(super) options: &'a IdentificationOptions,
    /// The latest motions (deflected poses, compliance and geometry columns) by the bits of
    /// the parameters and effective scales they were computed at: the fits return to the
    /// same point (the common fit restarts from the start, the covariance relinearises at the
    /// solution), and the motions do not depend on which scales are chosen.
    memo: std::sync::Mutex<Vec<(Vec<u64>, std::sync::Arc<Motions>)>>,
}

/// What a linearisation with its Jacobian needs per (configuration, payload) group: the
/// deflected tool poses, the compliance columns per tool and the geometry's per parameter.
struct Motions {
    poses: Vec<Vec<Pose>>,
    compliance: Vec<Vec<DMatrix<f64>>>,
    geometry: Vec<Vec<Vec<Vector6<f64>>>>,
}

/// How many points [`Problem::motions`] remembers.
const REMEMBERED: usize = 4;

/// A fit of the geometry and the compliance scales (`fit`), with the covariance factor of the
/// chosen scales (`covariance`).
pub(super) struct Fit {
    pub(super) model: McpcModel,
    pub(super) scales: Vec<f64>,
    pub(super) cost: [f64; 2],
    pub(super) iterations: usize,
    pub(super) termination: Termination,
    pub(super) rank: usize,
    pub(super) residual_scale: f64,
    /// A factor `F` of the covariance of the chosen scales (`F·Fᵀ`), one row per chosen scale
    /// in `chosen` order.
    pub(super) factor: DMatrix<f64>,
}

/// A linearisation: weighted residual and Jacobian, columns `[free geometry, compliances]`.
pub(super) struct Linearisation {
    pub(super) residual: DVector<f64>,
    pub(super) jacobian: DMatrix<f64>,
}

impl<'a> Problem<'a> {
    pub(super) fn new(
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
        if let Some(payloads) = payloads {
            if payloads.len() != measurements.len() {
                return Err(bad(format!(
                    "{} payloads for {} measurements",
                    payloads.len(),
                    measurements.len()
                )));
            }
        }
        let mut bases: Vec<(Option<f64>, ComplianceBasis)> = Vec::new();
        let mut basis_of = Vec::with_capacity(measurements.len());
        for (index, m) in measurements.iter().enumerate() {
            // A given list overrides the rows' own payloads (`payload_kg`).
            let payload = payloads.map_or(m.payload, |p| Some(p[index]));
            let basis = match bases.iter().position(|(p, _)| *p == payload) {
                Some(basis) => basis,
                None => {
                    let model = prior.for_payload(payload)?;
                    bases.push((payload, ComplianceBasis::new(&model)));
                    bases.len() - 1
                }
            };
            basis_of.push(basis);
        }
        Ok(Self {
            tree,
            measurements,
            bases,
            basis_of,
            free,
            options,
            memo: std::sync::Mutex::new(Vec::new()),
        })
    }

    pub(super) fn parameters(&self) -> &[ComplianceParameter] {
        self.bases[0].1.parameters()
    }

    /// Each parameter's scale times its group's.
    pub(super) fn effective(&self, scales: &[f64]) -> Vec<f64> {
        let count = self.parameters().len();
        self.parameters()
            .iter()
            .enumerate()
            .map(|(k, p)| scales[k] * scales[count + usize::from(!p.kind.is_joint())])
            .collect()
    }

    /// Weighted residual and, if asked, the Jacobian over the free geometry and the compliance
    /// scales `chosen` (per unit scale; at scale 1 that is per unit of its logarithm too): the compliance columns exact (see `ComplianceBasis::jacobian`), the
    /// geometric ones the analytic derivative of the deflected poses (a deflection changes with
    /// the geometry through its lever arms, which the deflected-chain Jacobian leaves out; with
    /// compliances moving by tens of percent that slows the joint fit to a crawl).
    ///
    /// `fitted`: the individual scales whose effective scale (its own times its group's) is a
    /// parameter of its own; their columns are per unit effective scale, and their group's
    /// column covers only the other members (those that follow the group). With the product
    /// `s·g` as two parameters instead, the sign of both could flip together at no cost.
    pub(super) fn linearise(
        &self,
        model: &McpcModel,
        scales: &[f64],
        chosen: &[usize],
        fitted: &[usize],
        with_jacobian: bool,
    ) -> Result<Linearisation> {
        let rows: usize = self.measurements.iter().map(|m| m.observation.rows()).sum();
        let columns = self.free.len() + chosen.len();
        let mut residual = DVector::zeros(rows);
        let mut jacobian = DMatrix::zeros(if with_jacobian { rows } else { 0 }, columns);
        let effective = self.effective(scales);
        let flexibilities = self
            .bases
            .iter()
            .map(|(_, b)| b.scaled(&effective))
            .collect::<Result<Vec<_>>>()?;
        let (groups, group_of) = self.groups();
        let motions = if with_jacobian {
            self.motions(model, &effective, &flexibilities, &groups)?
        } else {
            let poses = groups
                .iter()
                .map(|&(q, basis)| flexibilities[basis].deflected_tool_poses(self.tree, model, q))
                .collect::<Result<Vec<_>>>()?;
            std::sync::Arc::new(Motions {
                poses,
                compliance: Vec::new(),
                geometry: Vec::new(),
            })
        };
        let Motions {
            poses,
            compliance,
            geometry,
        } = &*motions;
        let count_of = self.parameters().len();
        let is_fitted: Vec<bool> = (0..count_of).map(|j| fitted.contains(&j)).collect();
        let noise = self.options.noise();
        let mut error = Vec::new();
        let mut row = 0;
        for (index, m) in self.measurements.iter().enumerate() {
            let g = group_of[index];
            if m.tool >= poses[g].len() {
                return Err(Error::InvalidData {
                    origin: "stiffness identification".into(),
                    message: format!("measurement {index} names tool {}", m.tool),
                });
            }
            // Through the observation seam: the kind's residual, and its sensitivity to a
            // motion of the tool (the geometry's and the compliances' columns are motions).
            let kind = kind_of(&m.observation);
            let at = RobotState {
                model,
                q: &m.q,
                tool: m.tool,
                tools: Tools::Poses(&poses[g]),
                offset: None,
                nuisance: Nuisance::none(),
            };
            error.resize(kind.rows(), 0.0);
            kind.residual(&at, &mut error)?;
            let sensitivity = with_jacobian.then(|| kind.tool_motion_jacobian(&at, m.tool));
            let geometry_rows: Vec<DVector<f64>> = match &sensitivity {
                Some(s) => geometry[g]
                    .iter()
                    .map(|change| s * change[m.tool])
                    .collect(),
                None => Vec::new(),
            };
            let per_unit = sensitivity.as_ref().map(|s| s * &compliance[g][m.tool]);
            for (k, row_kind) in kind.row_kinds().iter().enumerate() {
                let weight = 1.0 / noise.sigma(*row_kind);
                residual[row + k] = error[k] * weight;
                if let Some(per_unit) = &per_unit {
                    for (column, change) in geometry_rows.iter().enumerate() {
                        jacobian[(row + k, column)] = change[k] * weight;
                    }
                    // Columns per unit scale (the deflections are linear in the effective
                    // scales): a fitted scale per unit of its effective scale, a held one per
                    // unit of its own (times its group's), a group per unit of its own over the
                    // members that follow it.
                    for (column, &c) in chosen.iter().enumerate() {
                        let value = self.compliance_column(per_unit, k, c, scales, &is_fitted);
                        jacobian[(row + k, self.free.len() + column)] = value * weight;
                    }
                }
            }
            row += kind.rows();
        }
        Ok(Linearisation { residual, jacobian })
    }

    /// The deflected poses and the compliance and geometry columns of every group at `model`
    /// and `effective` scales, remembered for the next requests at the same point (the same
    /// bits: results do not change).
    fn motions(
        &self,
        model: &McpcModel,
        effective: &[f64],
        flexibilities: &[FlexibilityModel],
        groups: &[(&[f64], usize)],
    ) -> Result<std::sync::Arc<Motions>> {
        let key: Vec<u64> = model
            .parameters()
            .iter()
            .chain(effective)
            .map(|v| v.to_bits())
            .collect();
        let lock = || {
            self.memo
                .lock()
                .unwrap_or_else(|poisoned| poisoned.into_inner())
        };
        if let Some((_, found)) = lock().iter().find(|(at, _)| *at == key) {
            return Ok(found.clone());
        }
        let mut poses = Vec::with_capacity(groups.len());
        let mut compliance = Vec::with_capacity(groups.len());
        for &(q, basis) in groups {
            let found = self.bases[basis]
                .1
                .jacobian(effective, self.tree, model, q)?;
            poses.push(found.poses);
            compliance.push(found.jacobians);
        }
        let geometry = self.geometry_motions(model, flexibilities, groups)?;
        let motions = std::sync::Arc::new(Motions {
            poses,
            compliance,
            geometry,
        });
        let mut memo = lock();
        if memo.len() == REMEMBERED {
            memo.remove(0);
        }
        memo.push((key, motions.clone()));
        Ok(motions)
    }

    /// The distinct (configuration, payload basis) pairs, which several tools measured there
    /// share, and each measurement's pair.
    fn groups(&self) -> (Vec<(&[f64], usize)>, Vec<usize>) {
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
        (groups, group_of)
    }

    /// Per group and free parameter, the change of every deflected tool pose per unit
    /// parameter (analytic, see `FlexibilityModel::deflected_pose_derivatives`).
    fn geometry_motions(
        &self,
        model: &McpcModel,
        flexibilities: &[FlexibilityModel],
        groups: &[(&[f64], usize)],
    ) -> Result<Vec<Vec<Vec<Vector6<f64>>>>> {
        groups
            .iter()
            .map(|&(q, basis)| {
                flexibilities[basis]
                    .deflected_pose_derivatives(self.tree, model, q, self.free, 1e-7)
            })
            .collect()
    }

    /// Row `k` of compliance column `c` from the motions per unit individual scale
    /// `per_unit`: a fitted scale per unit of its effective scale, a held one per unit of its
    /// own (times its group's), a group (`c` past the individual scales) per unit of its own
    /// over the members that follow it.
    fn compliance_column(
        &self,
        per_unit: &DMatrix<f64>,
        k: usize,
        c: usize,
        scales: &[f64],
        is_fitted: &[bool],
    ) -> f64 {
        let count_of = self.parameters().len();
        let group = |p: &ComplianceParameter| usize::from(!p.kind.is_joint());
        match self.parameters().get(c) {
            Some(_) if is_fitted[c] => per_unit[(k, c)],
            Some(p) => per_unit[(k, c)] * scales[count_of + group(p)],
            None => self
                .parameters()
                .iter()
                .enumerate()
                .filter(|(j, p)| group(p) == c - count_of && !is_fitted[*j])
                .map(|(j, _)| per_unit[(k, j)] * scales[j])
                .sum(),
        }
    }
}
