//! Compliance parameters: scale factors on the joint and link compliances, one per joint and
//! kind (bending, torsion) and one per body and kind (EA, EI_y, EI_z, GI_p), and the exact
//! derivative of the deflected tool poses with respect to them.
//!
//! The deformations are linear in the compliances (the loads are taken at the undeflected
//! pose), so the deformation per unit scale of a parameter is the deformation of a model that
//! keeps only that kind of compliance: four evaluations of the loads give every parameter's.
//! What is not linear is how the deformations enter the chain (as rigid transforms), and that
//! part is differentiated exactly with the Jacobians of the rotation exponential. Derivation:
//! `docs/flexibility.md`, section 11.

use super::apply::Deflection;
use super::beam::BeamCompliance;
use super::model::FlexibilityModel;
use crate::error::{Error, Result};
use crate::kinematics::McpcModel;
use crate::math::{skew, Mat3, Pose, Transform, Vec3};
use crate::tree::KinematicTree;
use nalgebra::DMatrix;

/// What a compliance parameter scales.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ComplianceKind {
    /// The joint's bending compliance 1/k_B (about both axes normal to the joint axis).
    JointBending,
    /// The joint's torsion compliance 1/k_T (about the joint axis).
    JointTorsion,
    /// 1/EA of every segment of the body.
    LinkAxial,
    /// 1/EI_y of every segment of the body.
    LinkBendingY,
    /// 1/EI_z of every segment of the body.
    LinkBendingZ,
    /// 1/GI_p of every segment of the body.
    LinkTorsion,
}

impl ComplianceKind {
    /// Every kind, joints first.
    pub const ALL: [ComplianceKind; 6] = [
        ComplianceKind::JointBending,
        ComplianceKind::JointTorsion,
        ComplianceKind::LinkAxial,
        ComplianceKind::LinkBendingY,
        ComplianceKind::LinkBendingZ,
        ComplianceKind::LinkTorsion,
    ];

    /// Short name: `bending`, `torsion`, `EA`, `EI_y`, `EI_z`, `GI_p`.
    pub fn name(self) -> &'static str {
        match self {
            ComplianceKind::JointBending => "bending",
            ComplianceKind::JointTorsion => "torsion",
            ComplianceKind::LinkAxial => "EA",
            ComplianceKind::LinkBendingY => "EI_y",
            ComplianceKind::LinkBendingZ => "EI_z",
            ComplianceKind::LinkTorsion => "GI_p",
        }
    }

    /// Whether it is a joint compliance (else a link one).
    pub fn is_joint(self) -> bool {
        matches!(
            self,
            ComplianceKind::JointBending | ComplianceKind::JointTorsion
        )
    }

    /// Unit of the stiffness it is the reciprocal of.
    pub fn stiffness_unit(self) -> &'static str {
        match self {
            ComplianceKind::JointBending | ComplianceKind::JointTorsion => "N·m/rad",
            ComplianceKind::LinkAxial => "N",
            _ => "N·m²",
        }
    }

    /// Which of the four component evaluations carries it (see [`ComplianceBasis`]).
    fn component(self) -> usize {
        match self {
            ComplianceKind::JointBending | ComplianceKind::LinkAxial => 0,
            ComplianceKind::JointTorsion | ComplianceKind::LinkBendingY => 1,
            ComplianceKind::LinkBendingZ => 2,
            ComplianceKind::LinkTorsion => 3,
        }
    }
}

/// One compliance parameter: a kind of compliance of the joint of MCPC frame `frame`, or of
/// every segment of that frame's body.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct ComplianceParameter {
    /// The MCPC frame (index in [`McpcModel::frames`]).
    pub frame: usize,
    /// What it scales.
    pub kind: ComplianceKind,
}

impl FlexibilityModel {
    /// Every compliance parameter: per MCPC frame, the joint's bending and torsion, then, for
    /// a body with at least one segment, its EA, EI_y, EI_z and GI_p.
    pub fn compliance_parameters(&self) -> Vec<ComplianceParameter> {
        let mut parameters = Vec::new();
        for frame in 0..self.joint_compliance.len() {
            let has_segment = self.segments.iter().any(|s| s.frame == frame);
            for kind in ComplianceKind::ALL {
                if kind.is_joint() || has_segment {
                    parameters.push(ComplianceParameter { frame, kind });
                }
            }
        }
        parameters
    }

    /// The compliance a parameter scales, SI (rad/(N·m), 1/N or 1/(N·m²)); for a body, that of
    /// its first segment (all its segments share one stiffness).
    pub fn compliance(&self, parameter: &ComplianceParameter) -> f64 {
        let (bending, torsion) = self.joint_compliance[parameter.frame];
        let link = || {
            self.segments
                .iter()
                .find(|s| s.frame == parameter.frame)
                .map(|s| s.compliance)
                .unwrap_or(BeamCompliance {
                    axial: 0.0,
                    bending_y: 0.0,
                    bending_z: 0.0,
                    torsion: 0.0,
                })
        };
        match parameter.kind {
            ComplianceKind::JointBending => bending,
            ComplianceKind::JointTorsion => torsion,
            ComplianceKind::LinkAxial => link().axial,
            ComplianceKind::LinkBendingY => link().bending_y,
            ComplianceKind::LinkBendingZ => link().bending_z,
            ComplianceKind::LinkTorsion => link().torsion,
        }
    }

    /// A copy with each parameter's compliance multiplied by its scale (finite, ≥ 0).
    pub fn with_compliance_scales(
        &self,
        parameters: &[ComplianceParameter],
        scales: &[f64],
    ) -> Result<Self> {
        if let Some(scale) = scales.iter().find(|s| **s < 0.0) {
            return Err(Error::InvalidData {
                origin: "compliance scales".into(),
                message: format!("scale {scale} is not a finite non-negative number"),
            });
        }
        self.with_signed_compliance_scales(parameters, scales)
    }

    /// [`Self::with_compliance_scales`] that also takes negative scales (finite): not a physical
    /// model, but the deflections stay linear in the compliances through zero, which the joint
    /// stiffness fit relies on while it iterates.
    fn with_signed_compliance_scales(
        &self,
        parameters: &[ComplianceParameter],
        scales: &[f64],
    ) -> Result<Self> {
        if parameters.len() != scales.len() {
            return Err(Error::InvalidData {
                origin: "compliance scales".into(),
                message: format!(
                    "{} scales for {} parameters",
                    scales.len(),
                    parameters.len()
                ),
            });
        }
        let mut scaled = self.clone();
        for (parameter, &scale) in parameters.iter().zip(scales) {
            if !scale.is_finite() {
                return Err(Error::InvalidData {
                    origin: "compliance scales".into(),
                    message: format!("scale {scale} is not a finite number"),
                });
            }
            let frame = parameter.frame;
            match parameter.kind {
                ComplianceKind::JointBending => scaled.joint_compliance[frame].0 *= scale,
                ComplianceKind::JointTorsion => scaled.joint_compliance[frame].1 *= scale,
                kind => {
                    for segment in scaled.segments.iter_mut().filter(|s| s.frame == frame) {
                        let c = &mut segment.compliance;
                        match kind {
                            ComplianceKind::LinkAxial => c.axial *= scale,
                            ComplianceKind::LinkBendingY => c.bending_y *= scale,
                            ComplianceKind::LinkBendingZ => c.bending_z *= scale,
                            _ => c.torsion *= scale,
                        }
                    }
                }
            }
        }
        Ok(scaled)
    }

    /// A copy that keeps only the compliances of component `component` (see
    /// [`ComplianceKind::component`]).
    fn component(&self, component: usize) -> Self {
        let mut only = self.clone();
        for (bending, torsion) in &mut only.joint_compliance {
            *bending *= f64::from(u8::from(component == 0));
            *torsion *= f64::from(u8::from(component == 1));
        }
        for segment in &mut only.segments {
            let c = &mut segment.compliance;
            c.axial *= f64::from(u8::from(component == 0));
            c.bending_y *= f64::from(u8::from(component == 1));
            c.bending_z *= f64::from(u8::from(component == 2));
            c.torsion *= f64::from(u8::from(component == 3));
        }
        only
    }
}

/// The compliance parameters of a reference flexibility model (the prior) and what their
/// derivatives need: the reference split into four models that each keep one kind of joint
/// and one kind of link compliance. Scale factors are relative to the reference.
#[derive(Debug, Clone)]
pub struct ComplianceBasis {
    reference: FlexibilityModel,
    parameters: Vec<ComplianceParameter>,
    components: Vec<FlexibilityModel>,
}

/// Deflected tool poses and their derivatives with respect to the compliance scales.
#[derive(Debug, Clone)]
pub struct ComplianceJacobian {
    /// The deflected tool poses, in [`McpcModel::tools`] order.
    pub poses: Vec<Pose>,
    /// Per tool, 6 × parameters: `[dp; δθ]` (base frame, m and rad) per unit scale, the
    /// convention of [`crate::math::pose_error`].
    pub jacobians: Vec<DMatrix<f64>>,
}

impl ComplianceBasis {
    /// The parameters of `reference` ([`FlexibilityModel::compliance_parameters`]).
    pub fn new(reference: &FlexibilityModel) -> Self {
        Self {
            reference: reference.clone(),
            parameters: reference.compliance_parameters(),
            components: (0..4).map(|c| reference.component(c)).collect(),
        }
    }

    /// The parameters, in the order of the scale vectors.
    pub fn parameters(&self) -> &[ComplianceParameter] {
        &self.parameters
    }

    /// The reference model (all scales 1).
    pub fn reference(&self) -> &FlexibilityModel {
        &self.reference
    }

    /// The reference model with every parameter's compliance times its scale. A negative scale
    /// (finite) is accepted: not a physical model, but the deflections are linear in the
    /// compliances through zero, and a least-squares fit may pass there (or end there, which
    /// its caller must then reject).
    pub fn scaled(&self, scales: &[f64]) -> Result<FlexibilityModel> {
        self.reference
            .with_signed_compliance_scales(&self.parameters, scales)
    }

    /// The deflected tool poses of the model with compliance `scales` at configuration `q`,
    /// and their exact derivatives with respect to the scales.
    pub fn jacobian(
        &self,
        scales: &[f64],
        tree: &KinematicTree,
        model: &McpcModel,
        q: &[f64],
    ) -> Result<ComplianceJacobian> {
        if let Some(reference) = model.reference() {
            return Err(Error::InvalidData {
                origin: "stiffness identification".into(),
                message: format!(
                    "the compliance derivatives hold the root link '{}' fixed, not the reference link '{}'; identify the stiffness with the root as the reference link",
                    tree.link(tree.root()).name,
                    tree.link(reference.link).name
                ),
            });
        }
        let current = self.scaled(scales)?;
        let deflection = current.deflect(tree, model, q)?;
        let units = self
            .components
            .iter()
            .map(|c| Ok(c.evaluate(tree, model, q)?.deformations))
            .collect::<Result<Vec<_>>>()?;
        let tools = &deflection.chain.tools;
        let mut jacobians: Vec<DMatrix<f64>> = tools
            .iter()
            .map(|_| DMatrix::zeros(6, self.parameters.len()))
            .collect();
        for (column, parameter) in self.parameters.iter().enumerate() {
            let unit = &units[parameter.kind.component()];
            for (tool, transform) in tools.iter().enumerate() {
                if !model.tool_chain(tool).contains(&parameter.frame) {
                    continue;
                }
                let tip = transform.translation;
                let (dp, dr) = if parameter.kind.is_joint() {
                    let w = unit.joints[parameter.frame]
                        .local
                        .fixed_rows::<3>(3)
                        .into_owned();
                    joint_derivative(&deflection, parameter.frame, &w, &tip)
                } else {
                    let mut sum = (Vec3::zeros(), Vec3::zeros());
                    for index in current.segments_on_path(model, tool) {
                        if current.segments[index].frame != parameter.frame {
                            continue;
                        }
                        let (dp, dr) = segment_derivative(&current, &deflection, unit, index, &tip);
                        sum.0 += dp;
                        sum.1 += dr;
                    }
                    sum
                };
                let mut target = jacobians[tool].column_mut(column);
                target.fixed_rows_mut::<3>(0).copy_from(&dp);
                target.fixed_rows_mut::<3>(3).copy_from(&dr);
            }
        }
        Ok(ComplianceJacobian {
            poses: tools.iter().map(Transform::to_pose).collect(),
            jacobians,
        })
    }
}

impl FlexibilityModel {
    /// The segments between the base and tool `tool`, base side first.
    pub(crate) fn segments_on_path(&self, model: &McpcModel, tool: usize) -> Vec<usize> {
        model
            .tool_chain(tool)
            .iter()
            .filter_map(|&frame| self.segment_to_frame[frame])
            .chain(self.segment_to_tool[tool])
            .collect()
    }
}

/// Joint `frame`'s rotation per unit scale is `w` (moved frame). The deflected moved frame is
/// `D = A·Exp(φ)`, so `dD/ds = D·(J_r(φ)·w)^`: a rotation about D's origin.
fn joint_derivative(deflection: &Deflection, frame: usize, w: &Vec3, tip: &Vec3) -> (Vec3, Vec3) {
    let current = deflection.evaluation.deformations.joints[frame]
        .local
        .fixed_rows::<3>(3)
        .into_owned();
    let moved = &deflection.deflected[frame];
    let omega = moved.rotation * (right_jacobian(&current) * w);
    (omega.cross(&(tip - moved.translation)), omega)
}

/// Segment `index` moves by `S = Trans(e + u)·Exp(ψ)·Trans(−e)` in its proximal deflected moved
/// frame D. Per unit scale (u, ψ change by u₁, ψ₁) a point x moves by
/// `u₁ + J_l(ψ)·ψ₁ × (x − e − u)` in D's coordinates.
fn segment_derivative(
    current: &FlexibilityModel,
    deflection: &Deflection,
    unit: &super::loads::Deformations,
    index: usize,
    tip: &Vec3,
) -> (Vec3, Vec3) {
    let frame = current.segments[index].frame;
    let nominal = &deflection.evaluation.moved[frame];
    let to_local = nominal.rotation.transpose();
    let now = &deflection.evaluation.deformations.segments[index];
    let end = to_local * (now.end - nominal.translation);
    let u = to_local * now.translation;
    let psi = to_local * now.rotation;
    let u1 = to_local * unit.segments[index].translation;
    let psi1 = to_local * unit.segments[index].rotation;
    let moved = &deflection.deflected[frame];
    let omega = moved.rotation * (left_jacobian(&psi) * psi1);
    let pivot = moved.rotation * (end + u) + moved.translation;
    (moved.rotation * u1 + omega.cross(&(tip - pivot)), omega)
}

/// `(1 − cos θ)/θ²` and `(θ − sin θ)/θ³` of `θ = |v|`, by series below 0.05 rad.
fn exp_jacobian_coefficients(v: &Vec3) -> (f64, f64) {
    let t = v.norm_squared();
    if t < 2.5e-3 {
        (
            0.5 - t / 24.0 * (1.0 - t / 30.0 * (1.0 - t / 56.0)),
            1.0 / 6.0 - t / 120.0 * (1.0 - t / 42.0 * (1.0 - t / 72.0)),
        )
    } else {
        let angle = t.sqrt();
        ((1.0 - angle.cos()) / t, (angle - angle.sin()) / (t * angle))
    }
}

/// `J_r(v) = I − a·[v]× + b·[v]×²`: `d/ds Exp(v + s·w) = Exp(v)·(J_r(v)·w)^` at s = 0.
pub(super) fn right_jacobian(v: &Vec3) -> Mat3 {
    let (a, b) = exp_jacobian_coefficients(v);
    let k = skew(v);
    Mat3::identity() - k * a + k * k * b
}

/// `J_l(v) = J_r(−v)`: `d/ds Exp(v + s·w) = (J_l(v)·w)^·Exp(v)` at s = 0.
pub(super) fn left_jacobian(v: &Vec3) -> Mat3 {
    right_jacobian(&-v)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exp_jacobians_match_finite_differences() {
        let exp = super::super::apply::exp;
        for &angle in &[0.0, 1e-3, 0.03, 0.2, 1.5] {
            let v = Vec3::new(0.3, -0.5, 0.8).normalize() * angle;
            let w = Vec3::new(-0.2, 0.7, 0.4);
            let h = 1e-6;
            let derivative = (exp(&(v + w * h)) - exp(&(v - w * h))) / (2.0 * h);
            let right = exp(&v) * skew(&(right_jacobian(&v) * w));
            let left = skew(&(left_jacobian(&v) * w)) * exp(&v);
            assert!((derivative - right).amax() < 1e-8, "right, angle {angle}");
            assert!((derivative - left).amax() < 1e-8, "left, angle {angle}");
        }
    }
}
