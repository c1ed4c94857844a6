//! joint_errors.yaml as the artifact check applies it: the written file is parsed again and its
//! terms are added to the commanded joint angles before the exported URDF's forward
//! kinematics, `θ = q + sine·sin q + cosine·cos q + backlash·sign τ(q)` (`τ` the gravity torque
//! of the URDF's inertials at the commanded posture, as the identification signed it). The
//! rigid-only fit freezes those terms at zero (`docs/calibration.md`, "Outputs").

use super::calibrate_steps::Loaded;
use crate::error::{Error, Result};
use crate::io::{parse_joint_errors, JointErrorEntry};
use crate::kinematics::{GravitySigns, McpcModel, ParameterKind};
use crate::tree::Actuation;

/// The file `calibrate` writes when the model has harmonic or backlash terms.
pub const JOINT_ERRORS_FILE: &str = "joint_errors.yaml";

/// The terms of joint_errors.yaml, per model frame driven by one joint value.
pub(super) struct AppliedJointErrors {
    /// (model frame, index of its joint value in `q`, its terms).
    terms: Vec<(usize, usize, JointErrorEntry)>,
    /// The torque signs for backlash (none without backlash terms).
    gravity: Option<GravitySigns>,
}

impl AppliedJointErrors {
    /// Reads the written `text` for `loaded`'s robot: every joint it names must be a joint of
    /// the model driven by its own joint value.
    pub fn read(text: &str, loaded: &Loaded) -> Result<Self> {
        let entries = parse_joint_errors(text, JOINT_ERRORS_FILE)?;
        let tree = loaded.robot.tree();
        let model = &loaded.nominal;
        let mut terms = Vec::with_capacity(entries.len());
        for (name, entry) in entries {
            let frame = model
                .frames()
                .iter()
                .position(|f| tree.joint(f.joint).name == name);
            let dof = frame.and_then(|i| match model.frames()[i].actuation {
                Actuation::Independent(dof) => Some(dof.0),
                _ => None,
            });
            let (Some(frame), Some(dof)) = (frame, dof) else {
                return Err(Error::InvalidData {
                    origin: format!("{JOINT_ERRORS_FILE}: joints.{name}"),
                    message: "not a calibrated joint driven by its own joint value".into(),
                });
            };
            terms.push((frame, dof, entry));
        }
        let backlash = terms.iter().any(|(_, _, e)| e.backlash != 0.0);
        let gravity = if backlash {
            Some(GravitySigns::new(tree, model)?)
        } else {
            None
        };
        Ok(Self { terms, gravity })
    }

    /// The joint values the joints turn to at commanded `q`.
    pub fn apply(&self, q: &[f64]) -> Vec<f64> {
        let signs = self.gravity.as_ref().map(|g| g.signs(q));
        let mut turned = q.to_vec();
        for &(frame, dof, e) in &self.terms {
            let (s, c) = q[dof].sin_cos();
            let sign = signs
                .as_ref()
                .and_then(|s| s.get(frame).copied())
                .unwrap_or(0.0);
            turned[dof] += e.sine * s + e.cosine * c + e.backlash * sign;
        }
        turned
    }
}

/// `model` with its harmonic and backlash terms at zero, and their parameter indices (to
/// freeze): the rigid geometry a URDF carries. Joint zero offsets stay (a URDF carries them).
pub(super) fn without_joint_angle_terms(model: &McpcModel) -> Result<(McpcModel, Vec<usize>)> {
    let mut parameters = model.parameters();
    let mut frozen = Vec::new();
    for (i, (_, kind)) in model.parameter_layout().iter().enumerate() {
        if matches!(
            kind,
            ParameterKind::Sine | ParameterKind::Cosine | ParameterKind::Backlash
        ) {
            parameters[i] = 0.0;
            frozen.push(i);
        }
    }
    let mut rigid = model.clone();
    rigid.set_parameters(&parameters)?;
    Ok((rigid, frozen))
}
