//! Joint-angle errors beyond the MCPC geometry, and the measurement frame as parameters.
//!
//! The MCPC parameters describe where each joint axis is; they cannot describe a joint that
//! turns by a different angle than its encoder says. For a revolute frame `i` the effective
//! joint angle is
//!
//! ```text
//! θᵢ = qᵢ + δᵢ + aᵢ·sin qᵢ + bᵢ·cos qᵢ + hᵢ·sign(τᵢ(q))
//! ```
//!
//! with `δ` a zero offset, `(a, b)` the first harmonic of an eccentric encoder or gear, and `h`
//! half the dead band of a backlash, signed by the gravity torque `τᵢ` about the joint axis in
//! the static posture (the load holds the joint against one side of its dead band). Each term
//! is an optional parameter ([`JointErrorTerms`]); a joint's column in the identification
//! Jacobian is the joint's twist times `∂θ/∂(term)`: `1`, `sin q`, `cos q`, `sign τ`.
//!
//! The torque sign comes from the URDF's inertials at the nominal tree and the commanded `q`
//! ([`GravitySigns`]), with gravity along −z of the root link: it does not depend on the
//! parameters being identified. See `docs/identification.md`.

use super::mcpc::{FrameKind, McpcModel, ParameterKind};
use crate::error::{Error, Result};
use crate::math::{rot_x, rot_y, rot_z, Transform, Vec3};
use crate::tree::{JointId, KinematicTree, LinkId};
use std::collections::HashMap;
use std::sync::{Arc, Mutex};

/// The joint-error kinds, in the order they follow a frame's parameters.
pub const JOINT_ERROR_KINDS: [ParameterKind; 4] = [
    ParameterKind::Offset,
    ParameterKind::Sine,
    ParameterKind::Cosine,
    ParameterKind::Backlash,
];

/// Which joint-angle error terms are parameters (revolute joints only).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct JointErrorTerms {
    /// A zero offset `δ` per joint.
    pub offsets: bool,
    /// First-harmonic errors `a·sin q + b·cos q` per joint.
    pub harmonics: bool,
    /// Backlash `h·sign(τ)` per joint (needs the URDF's inertials).
    pub backlash: bool,
}

impl JointErrorTerms {
    /// Whether any term is on.
    pub fn any(self) -> bool {
        self.offsets || self.harmonics || self.backlash
    }

    fn enabled(self) -> [bool; 4] {
        [self.offsets, self.harmonics, self.harmonics, self.backlash]
    }
}

/// The joint-error values of a model: per frame, one optional value per kind of
/// [`JOINT_ERROR_KINDS`] (`None`: not a parameter, zero).
#[derive(Debug, Clone, Default)]
pub(crate) struct JointErrors {
    pub(crate) slots: Vec<[Option<f64>; 4]>,
    pub(crate) gravity: Option<Arc<GravitySigns>>,
}

impl PartialEq for JointErrors {
    fn eq(&self, other: &Self) -> bool {
        self.slots == other.slots && self.gravity.is_some() == other.gravity.is_some()
    }
}

impl JointErrors {
    /// Whether any joint has an error term.
    #[inline]
    pub(crate) fn is_active(&self) -> bool {
        !self.slots.is_empty()
    }
}

/// The measurement frame as six parameters: `world_from_base = (R(α, β, γ)·R₀, p₀ + t)` with
/// `R = Rx(α)·Ry(β)·Rz(γ)` turning about the base origin and `(p₀, R₀)` the reference frame.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct FrameParameters {
    /// α, β, γ (rad), x, y, z (m).
    pub(crate) values: [f64; 6],
    /// The frame the parameters are relative to.
    pub(crate) reference: Transform,
}

impl FrameParameters {
    pub(crate) fn effective(&self) -> Transform {
        let [a, b, c, x, y, z] = self.values;
        Transform {
            rotation: (rot_x(a) * rot_y(b) * rot_z(c))
                .to_rotation_matrix()
                .into_inner()
                * self.reference.rotation,
            translation: self.reference.translation + Vec3::new(x, y, z),
        }
    }
}

/// The sign of the gravity torque about every MCPC joint axis at a configuration, from the
/// URDF's link inertials at the nominal tree (gravity along −z of the root link). Cached per
/// configuration.
#[derive(Debug)]
pub struct GravitySigns {
    tree: KinematicTree,
    /// Per MCPC frame: its joint and the links with a mass that it carries.
    carried: Vec<(JointId, Vec<LinkId>)>,
    cache: Mutex<HashMap<Vec<u64>, Arc<Vec<f64>>>>,
}

/// Standard gravity (m/s²).
const GRAVITY: f64 = 9.806_65;

/// At most this many configurations are cached; beyond it the cache starts over.
const CACHE_LIMIT: usize = 100_000;

impl GravitySigns {
    /// The torque signs of `model`'s joints on `tree`. Fails when no link carried by a joint
    /// has a mass (backlash would have no sign to follow).
    pub fn new(tree: &KinematicTree, model: &McpcModel) -> Result<Self> {
        let mut carried = Vec::new();
        for frame in model.frames() {
            let child = tree.joint(frame.joint).child;
            let links: Vec<LinkId> = (0..tree.links().len())
                .map(LinkId)
                .filter(|&l| tree.is_ancestor(child, l))
                .filter(|&l| tree.link(l).inertial.as_ref().is_some_and(|i| i.mass > 0.0))
                .collect();
            carried.push((frame.joint, links));
        }
        if let Some((joint, _)) = carried.iter().find(|(_, links)| links.is_empty()) {
            return Err(Error::InvalidData {
                origin: format!("robot '{}'", tree.name()),
                message: format!(
                    "joint '{}' carries no link with a mass (<inertial>), so the sign of its backlash cannot follow gravity; add the inertials to the URDF or leave backlash out",
                    tree.joint(*joint).name
                ),
            });
        }
        Ok(Self {
            tree: tree.clone(),
            carried,
            cache: Mutex::new(HashMap::new()),
        })
    }

    /// The gravity torque about every MCPC joint axis at `q` (N·m, one per frame).
    pub fn torques(&self, q: &[f64]) -> Result<Vec<f64>> {
        let poses = self.tree.link_poses(q)?;
        let gravity = Vec3::new(0.0, 0.0, -GRAVITY);
        Ok(self
            .carried
            .iter()
            .map(|(joint, links)| {
                let joint = self.tree.joint(*joint);
                let child = &poses[joint.child.0];
                let axis = child.rotation * joint.axis.into_inner();
                let origin = child.translation.vector;
                links
                    .iter()
                    .filter_map(|l| {
                        let inertial = self.tree.link(*l).inertial.as_ref()?;
                        let com = poses[l.0] * nalgebra::Point3::from(inertial.center_of_mass());
                        Some(axis.dot(&(com.coords - origin).cross(&(gravity * inertial.mass))))
                    })
                    .sum()
            })
            .collect())
    }

    /// The torque signs at `q` (±1, 0 for a torque below 1e-9 N·m or a configuration of the
    /// wrong size).
    pub fn signs(&self, q: &[f64]) -> Arc<Vec<f64>> {
        let key: Vec<u64> = q.iter().map(|v| (v + 0.0).to_bits()).collect();
        let mut cache = self
            .cache
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner());
        if let Some(found) = cache.get(&key) {
            return found.clone();
        }
        let signs = Arc::new(match self.torques(q) {
            Ok(torques) => torques
                .iter()
                .map(|t| if t.abs() < 1e-9 { 0.0 } else { t.signum() })
                .collect(),
            Err(_) => vec![0.0; self.carried.len()],
        });
        if cache.len() >= CACHE_LIMIT {
            cache.clear();
        }
        cache.insert(key, signs.clone());
        signs
    }
}

impl McpcModel {
    /// This model with the joint-error `terms` as parameters of every revolute joint (zero to
    /// start with, appended after the tools). Backlash needs `gravity`.
    pub fn with_joint_errors(
        &self,
        terms: JointErrorTerms,
        gravity: Option<GravitySigns>,
    ) -> Result<McpcModel> {
        if terms.backlash && gravity.is_none() {
            return Err(Error::InvalidData {
                origin: "joint errors".into(),
                message: "backlash needs the gravity torques of the joints (the URDF inertials)"
                    .into(),
            });
        }
        let mut model = self.clone();
        let enabled = terms.enabled();
        model.joint_errors = JointErrors {
            slots: if terms.any() {
                self.frames()
                    .iter()
                    .map(|f| {
                        let on = f.kind == FrameKind::Revolute;
                        enabled.map(|e| (e && on).then_some(0.0))
                    })
                    .collect()
            } else {
                Vec::new()
            },
            gravity: gravity.filter(|_| terms.backlash).map(Arc::new),
        };
        Ok(model)
    }

    /// This model with the measurement frame's six parameters (zero: the current frame) after
    /// every other parameter.
    pub fn with_frame_parameters(&self) -> McpcModel {
        let mut model = self.clone();
        model.frame_parameters = Some(FrameParameters {
            values: [0.0; 6],
            reference: *self.world_from_base_transform(),
        });
        model
    }

    /// Takes `other`'s joint-error and measurement-frame parameters and its reference link
    /// (same frames): a model rebuilt with new tools keeps them.
    pub fn adopt_extra_parameters(&mut self, other: &McpcModel) {
        self.joint_errors = other.joint_errors.clone();
        self.frame_parameters = other.frame_parameters.clone();
        self.reference = other.reference.clone();
    }

    /// Whether the measurement frame is a parameter ([`Self::with_frame_parameters`]).
    pub fn has_frame_parameters(&self) -> bool {
        self.frame_parameters.is_some()
    }

    /// Which joint-error terms the model has.
    pub fn joint_error_terms(&self) -> JointErrorTerms {
        let any = |k: usize| self.joint_errors.slots.iter().any(|s| s[k].is_some());
        JointErrorTerms {
            offsets: any(0),
            harmonics: any(1),
            backlash: any(3),
        }
    }

    /// The joint-error values of frame `frame` ([`JOINT_ERROR_KINDS`] order; `None`: not a
    /// parameter).
    pub fn joint_error_values(&self, frame: usize) -> [Option<f64>; 4] {
        self.joint_errors
            .slots
            .get(frame)
            .copied()
            .unwrap_or([None; 4])
    }

    /// `θ − q` of frame `frame` at joint value `raw` of configuration `q`.
    #[inline]
    pub(crate) fn joint_error(&self, frame: usize, raw: f64, q: &[f64]) -> f64 {
        let Some(slot) = self.joint_errors.slots.get(frame) else {
            return 0.0;
        };
        let mut error = 0.0;
        if let Some(offset) = slot[0] {
            error += offset;
        }
        if let (Some(a), Some(b)) = (slot[1], slot[2]) {
            let (s, c) = raw.sin_cos();
            error += a * s + b * c;
        }
        if let (Some(h), Some(gravity)) = (slot[3], &self.joint_errors.gravity) {
            error += h * gravity.signs(q).get(frame).copied().unwrap_or(0.0);
        }
        error
    }

    /// Per frame, `∂θ/∂(term)` for the terms of [`JOINT_ERROR_KINDS`] at `q`: `[1, sin q,
    /// cos q, sign τ]` (empty without joint errors).
    pub(crate) fn joint_error_factors(&self, q: &[f64], factors: &mut Vec<[f64; 4]>) {
        factors.clear();
        if !self.joint_errors.is_active() {
            return;
        }
        let signs = self.joint_errors.gravity.as_ref().map(|g| g.signs(q));
        for frame in 0..self.frames().len() {
            let raw = self.raw_joint_value(frame, q);
            let sign = signs
                .as_ref()
                .and_then(|s| s.get(frame).copied())
                .unwrap_or(0.0);
            factors.push([1.0, raw.sin(), raw.cos(), sign]);
        }
    }

    /// The index of each frame's joint-error parameters in the flat vector.
    pub(crate) fn joint_error_indices(&self) -> Vec<[Option<usize>; 4]> {
        let mut next = self.frames_parameter_count() + 6 * self.tools().len();
        self.joint_errors
            .slots
            .iter()
            .map(|slot| {
                slot.map(|v| {
                    v.map(|_| {
                        next += 1;
                        next - 1
                    })
                })
            })
            .collect()
    }

    /// The number of MCPC frame parameters (before the tools').
    fn frames_parameter_count(&self) -> usize {
        self.frames().iter().map(|f| f.kind.parameter_count()).sum()
    }

    /// Writes the joint-error and measurement-frame columns of tool `tool` (tool point `tip`).
    pub(crate) fn fill_extension_columns(
        &self,
        tool: usize,
        tip: &Vec3,
        frames: &[Transform],
        factors: &[[f64; 4]],
        data: &mut [f64],
    ) {
        let mut put = |column: usize, values: [f64; 6]| {
            data[6 * column..6 * column + 6].copy_from_slice(&values);
        };
        if self.joint_errors.is_active() {
            let indices = self.joint_error_indices();
            for &frame in self.tool_chain(tool) {
                let axis: Vec3 = frames[frame].rotation.column(2).into_owned();
                let linear = axis.cross(&(tip - frames[frame].translation));
                let twist = [linear.x, linear.y, linear.z, axis.x, axis.y, axis.z];
                let factor = factors.get(frame).copied().unwrap_or([0.0; 4]);
                for (k, index) in indices[frame].iter().enumerate() {
                    if let Some(index) = index {
                        put(*index, twist.map(|v| v * factor[k]));
                    }
                }
            }
        }
        if let Some(parameters) = &self.frame_parameters {
            let first = self.parameter_count() - 6;
            let [a, b, _, x, y, z] = parameters.values;
            let pivot = parameters.reference.translation + Vec3::new(x, y, z);
            let tilt = rot_x(a);
            let axes = [Vec3::x(), tilt * Vec3::y(), tilt * rot_y(b) * Vec3::z()];
            for (k, axis) in axes.iter().enumerate() {
                let linear = axis.cross(&(tip - pivot));
                put(
                    first + k,
                    [linear.x, linear.y, linear.z, axis.x, axis.y, axis.z],
                );
            }
            for k in 0..3 {
                let mut values = [0.0; 6];
                values[k] = 1.0;
                put(first + 3 + k, values);
            }
        }
    }

    /// The same robot with the joint zero offsets folded into the geometry, where a URDF can
    /// carry them: `Q(θ + δ) = Q(θ)·Rz(δ)`, so each child frame's and tool's constant `φ`
    /// turns by `δ` and the joint's URDF child link with it. Forward kinematics is unchanged;
    /// the offsets become zero (and stay parameters).
    pub fn with_offsets_absorbed(&self) -> McpcModel {
        let mut model = self.clone();
        for frame in 0..self.frames().len() {
            let Some(delta) = self.joint_error_values(frame)[0].filter(|d| *d != 0.0) else {
                continue;
            };
            model.absorb_offset(frame, delta);
        }
        model
    }
}
