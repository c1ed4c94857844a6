//! How the model predicts the tools' poses at a configuration (the robot state the observation
//! seam predicts from): rigid forward kinematics, or the flexibility model's deflected chain,
//! with the Jacobian correction that makes exact compensation converge quadratically.

use crate::error::Result;
use crate::kinematics::{McpcModel, ToolJacobian};
use crate::math::{pose_error, Pose};
use nalgebra::{DMatrix, Vector6};

/// How far (rad, m) the parameters may move before a Jacobian correction of
/// [`DeflectedWithDerivative`] is recomputed.
pub const CORRECTION_RADIUS: f64 = 1e-2;

/// How the model predicts the observed tool poses at a configuration. `Sync`: configurations
/// are evaluated in parallel (`calibration::normal_equations`).
pub trait Predictor: Sync {
    /// Poses of all tools (in `model.tools()` order) at configuration `q`.
    fn predict(&self, model: &McpcModel, q: &[f64]) -> Result<Vec<Pose>>;

    /// Poses and identification Jacobians of all tools at `q`; by default the rigid ones.
    fn jacobians(&self, model: &McpcModel, q: &[f64]) -> Result<Vec<ToolJacobian>> {
        Ok(model.tool_jacobians(q))
    }

    /// [`Self::predict`] for a row measured with `payload` kg at every tool (`None`: the
    /// predictor's own loads). Rigid predictions ignore it.
    fn predict_at(&self, model: &McpcModel, q: &[f64], payload: Option<f64>) -> Result<Vec<Pose>> {
        let _ = payload;
        self.predict(model, q)
    }

    /// [`Self::jacobians`] for a row measured with `payload` kg at every tool.
    fn jacobians_at(
        &self,
        model: &McpcModel,
        q: &[f64],
        payload: Option<f64>,
    ) -> Result<Vec<ToolJacobian>> {
        let _ = payload;
        self.jacobians(model, q)
    }

    /// [`Self::jacobians_at`] where only the columns of the parameters `free` are used: the
    /// other columns may be left inexact (the deflected-chain Jacobian of
    /// [`DeflectedWithDerivative`]).
    fn jacobians_for(
        &self,
        model: &McpcModel,
        q: &[f64],
        payload: Option<f64>,
        free: &[usize],
    ) -> Result<Vec<ToolJacobian>> {
        let _ = free;
        self.jacobians_at(model, q, payload)
    }

    /// [`Self::jacobians_for`] into `out`, its matrices reused where the predictor can (the
    /// rigid one: no allocation per configuration); the same values.
    fn jacobians_for_into(
        &self,
        model: &McpcModel,
        q: &[f64],
        payload: Option<f64>,
        free: &[usize],
        out: &mut Vec<ToolJacobian>,
    ) -> Result<()> {
        *out = self.jacobians_for(model, q, payload, free)?;
        Ok(())
    }
}

/// The rigid MCPC forward kinematics.
#[derive(Debug, Clone, Copy, Default)]
pub struct Rigid;

impl Predictor for Rigid {
    fn predict(&self, model: &McpcModel, q: &[f64]) -> Result<Vec<Pose>> {
        Ok(model.tool_poses(q))
    }

    fn jacobians_for_into(
        &self,
        model: &McpcModel,
        q: &[f64],
        _payload: Option<f64>,
        _free: &[usize],
        out: &mut Vec<ToolJacobian>,
    ) -> Result<()> {
        model.tool_jacobians_reusing(q, out);
        Ok(())
    }
}

/// The MCPC forward kinematics with the flexibility model's deflections inserted into the
/// chain, re-evaluated at the current parameters: exact flexibility compensation.
#[derive(Debug, Clone, Copy)]
pub struct Deflected<'a> {
    /// The tree the flexibility model was built for.
    pub tree: &'a crate::tree::KinematicTree,
    /// The flexibility model (built for the same MCPC model structure).
    pub flexibility: &'a crate::kinematics::FlexibilityModel,
}

impl Predictor for Deflected<'_> {
    fn predict(&self, model: &McpcModel, q: &[f64]) -> Result<Vec<Pose>> {
        self.predict_at(model, q, None)
    }

    /// The Jacobian on the deflected chain: parameter changes move the bent robot, but how the
    /// deflections themselves change with the parameters (through the lever arms of the loads)
    /// is left out. [`DeflectedWithDerivative`] adds it.
    fn jacobians(&self, model: &McpcModel, q: &[f64]) -> Result<Vec<ToolJacobian>> {
        self.jacobians_at(model, q, None)
    }

    fn predict_at(&self, model: &McpcModel, q: &[f64], payload: Option<f64>) -> Result<Vec<Pose>> {
        self.flexibility
            .for_payload(payload)?
            .deflected_tool_poses(self.tree, model, q)
    }

    fn jacobians_at(
        &self,
        model: &McpcModel,
        q: &[f64],
        payload: Option<f64>,
    ) -> Result<Vec<ToolJacobian>> {
        let flexibility = self.flexibility.for_payload(payload)?;
        Ok(model.jacobians_on(&flexibility.deflected_chain(self.tree, model, q)?))
    }
}

impl Deflected<'_> {
    /// The deflection of every tool at `q` with `payload` kg at every tool (`None`: the
    /// model's own loads): `deflected ⊖ rigid` (exact, not the linear map).
    pub fn offsets(
        &self,
        model: &McpcModel,
        q: &[f64],
        payload: Option<f64>,
    ) -> Result<Vec<Vector6<f64>>> {
        let deflected = self.predict_at(model, q, payload)?;
        Ok(deflected
            .iter()
            .zip(model.tool_poses(q))
            .map(|(d, r)| pose_error(d, &r))
            .collect())
    }
}

/// Exact flexibility compensation with a Jacobian that includes how the deflections change
/// with the parameters. At 5000 N·m/rad and 20 kg the deflections are centimetres and
/// degrees, and a 5 cm error in a lever arm changes them by a good fraction, so the Jacobian
/// on the deflected chain alone ([`Deflected`]) makes the iteration converge only linearly.
/// The missing part — the exact derivative of the deflected poses (the loads' change in closed
/// form for frame and tool parameters, forward differences for the others) minus
/// the deflected-chain Jacobian — is computed per configuration once the iterates settle and
/// reused while the parameters stay within [`CORRECTION_RADIUS`] of where it was computed (its
/// own change is second order): two or three times per calibration.
#[derive(Debug)]
pub struct DeflectedWithDerivative<'a> {
    source: Deflected<'a>,
    /// Per configuration (keyed by the bits of `q`: O(1) lookup): where the correction was
    /// computed and the correction.
    cache: std::sync::Mutex<std::collections::HashMap<CorrectionKey, Correction>>,
}

/// Where a row is evaluated: its configuration and payload (rows of several tools measured
/// there share one evaluation).
pub(crate) type RowKey<'a> = (&'a [f64], Option<f64>);

/// The latest evaluation and where it was made.
pub(crate) type Cached<'a, T> = Option<(RowKey<'a>, T)>;

/// The cache key of a correction: the bits of the configuration and of the payload.
type CorrectionKey = (Vec<u64>, Option<u64>);

/// A cached Jacobian correction: parameters where it was computed, parameters of the latest
/// request, `J_exact − J_chain` per tool, and which columns hold it (the others are zero).
type Correction = (Vec<f64>, Vec<f64>, Vec<DMatrix<f64>>, Vec<bool>);

/// The cache key of a configuration: its exact bits (`+ 0.0`: −0 and +0 are one key, as
/// under `==`).
fn configuration_key(q: &[f64]) -> Vec<u64> {
    q.iter().map(|v| (v + 0.0).to_bits()).collect()
}

impl<'a> DeflectedWithDerivative<'a> {
    /// Wraps a deflected predictor.
    pub fn new(source: Deflected<'a>) -> Self {
        Self {
            source,
            cache: std::sync::Mutex::new(std::collections::HashMap::new()),
        }
    }

    /// Adds `J_exact − J_chain` at `q` in the columns `wanted` (the others may be zero), from
    /// the cache or computed now, to the chain's Jacobians `chain`.
    ///
    /// A correction is reused while the parameters stay within [`CORRECTION_RADIUS`] of where
    /// it was computed. Beyond that it is recomputed only once the iterates settle (the last
    /// request was within the radius too): while they still travel, a stale correction steers
    /// as well and costs nothing, and the final one is always within the radius of the
    /// solution, which keeps the solution's bias from a stale Jacobian negligible. A reused
    /// correction that lacks a wanted column gets it computed where the others were.
    fn correction(
        &self,
        model: &McpcModel,
        q: &[f64],
        payload: Option<f64>,
        chain: &mut [ToolJacobian],
        wanted: &[usize],
    ) -> Result<()> {
        let parameters = model.parameters();
        let close = |at: &[f64]| {
            at.iter()
                .zip(&parameters)
                .all(|(a, b)| (a - b).abs() <= CORRECTION_RADIUS)
        };
        let key = (configuration_key(q), payload.map(f64::to_bits));
        let mut stale_at = None;
        {
            let mut cache = self.lock();
            if let Some((at, latest, found, computed)) = cache.get_mut(&key) {
                let settled = close(latest);
                latest.clone_from(&parameters);
                if close(at) || !settled {
                    if wanted.iter().all(|&c| computed[c]) {
                        add_to(chain, found);
                        return Ok(());
                    }
                    stale_at = Some(at.clone());
                }
            } else {
                // First request: far from the solution, the deflected-chain Jacobian alone
                // steers well enough; the correction waits until the iterates settle.
                let zero: Vec<DMatrix<f64>> =
                    chain.iter().map(|c| c.jacobian.map(|_| 0.0)).collect();
                add_to(chain, &zero);
                let computed = vec![true; parameters.len()];
                let at = vec![f64::INFINITY; parameters.len()];
                cache.insert(key, (at, parameters, zero, computed));
                return Ok(());
            }
        }
        if let Some(at) = stale_at {
            // The missing columns where the others were computed.
            let mut there = model.clone();
            there.set_parameters(&at)?;
            let chain_there = self.source.jacobians_at(&there, q, payload)?;
            let mut cache = self.lock();
            let Some((_, _, found, computed)) = cache.get_mut(&key) else {
                return Err(crate::error::Error::InvalidData {
                    origin: "exact flexibility compensation".into(),
                    message: "a cached Jacobian correction went missing".into(),
                });
            };
            let missing: Vec<usize> = wanted.iter().copied().filter(|&c| !computed[c]).collect();
            self.fill(&there, q, payload, &chain_there, &missing, found)?;
            for c in missing {
                computed[c] = true;
            }
            add_to(chain, found);
            return Ok(());
        }
        let mut correction: Vec<DMatrix<f64>> =
            chain.iter().map(|c| c.jacobian.map(|_| 0.0)).collect();
        self.fill(model, q, payload, chain, wanted, &mut correction)?;
        add_to(chain, &correction);
        let mut computed = vec![false; parameters.len()];
        for &c in wanted {
            computed[c] = true;
        }
        self.lock()
            .insert(key, (parameters.clone(), parameters, correction, computed));
        Ok(())
    }

    /// Columns `columns` of `J_exact − J_chain` at `model` into `correction`: the exact
    /// derivative of the deflected poses (`FlexibilityModel::deflected_pose_derivatives`)
    /// minus the chain's.
    fn fill(
        &self,
        model: &McpcModel,
        q: &[f64],
        payload: Option<f64>,
        chain: &[ToolJacobian],
        columns: &[usize],
        correction: &mut [DMatrix<f64>],
    ) -> Result<()> {
        let step = 1e-7;
        let flexibility = self.source.flexibility.for_payload(payload)?;
        let changes =
            flexibility.deflected_pose_derivatives(self.source.tree, model, q, columns, step)?;
        for (&index, tools) in columns.iter().zip(&changes) {
            for (tool, change) in tools.iter().enumerate() {
                let mut target = correction[tool].column_mut(index);
                target.copy_from(&(-chain[tool].jacobian.column(index)));
                target += change;
            }
        }
        Ok(())
    }

    fn lock(
        &self,
    ) -> std::sync::MutexGuard<'_, std::collections::HashMap<CorrectionKey, Correction>> {
        self.cache
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner())
    }
}

impl Predictor for DeflectedWithDerivative<'_> {
    fn predict(&self, model: &McpcModel, q: &[f64]) -> Result<Vec<Pose>> {
        self.source.predict(model, q)
    }

    /// The deflected-chain Jacobian plus the (frozen) effect of the deflections' own change.
    fn jacobians(&self, model: &McpcModel, q: &[f64]) -> Result<Vec<ToolJacobian>> {
        self.jacobians_at(model, q, None)
    }

    fn predict_at(&self, model: &McpcModel, q: &[f64], payload: Option<f64>) -> Result<Vec<Pose>> {
        self.source.predict_at(model, q, payload)
    }

    fn jacobians_at(
        &self,
        model: &McpcModel,
        q: &[f64],
        payload: Option<f64>,
    ) -> Result<Vec<ToolJacobian>> {
        let every: Vec<usize> = (0..model.parameter_count()).collect();
        self.jacobians_for(model, q, payload, &every)
    }

    /// Only the columns `free` carry the correction: each costs a deflected chain per
    /// configuration.
    fn jacobians_for(
        &self,
        model: &McpcModel,
        q: &[f64],
        payload: Option<f64>,
        free: &[usize],
    ) -> Result<Vec<ToolJacobian>> {
        let mut chain = self.source.jacobians_at(model, q, payload)?;
        self.correction(model, q, payload, &mut chain, free)?;
        Ok(chain)
    }
}

/// `J_chain + correction`, tool by tool, in place (the correction's zero columns are added
/// too: `−0 + 0` is `+0`, as in the sum it replaces).
fn add_to(chain: &mut [ToolJacobian], correction: &[DMatrix<f64>]) {
    for (tool, extra) in chain.iter_mut().zip(correction) {
        tool.jacobian += extra;
    }
}
