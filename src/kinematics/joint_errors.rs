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
use super::model_extras::GravitySigns;
use super::model_extras::{FrameParameters, JointErrors};
use crate::error::{Error, Result};
use crate::math::{rot_x, rot_y, Transform, Vec3};
use crate::tree::{KinematicTree, LinkId};
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

    /// Whether [`Self::fill_extension_columns`] writes any column (joint errors or the
    /// measurement frame as parameters).
    pub(crate) fn has_extension_columns(&self) -> bool {
        self.joint_errors.is_active() || self.frame_parameters.is_some()
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
