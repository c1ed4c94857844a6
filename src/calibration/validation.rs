//! Where each validation configuration lies relative to the identification data: a repeat of
//! an identification posture, a new posture inside the identification joint ranges, or one
//! outside them (`docs/calibration.md`, "Errors before and after"). Every validation row is
//! counted in the figures; the strata tell how far the result carries.

use crate::kinematics::{FrameKind, McpcModel};
use crate::measurement::Measurement;
use crate::tree::Actuation;
use serde::Serialize;

/// A validation row repeats an identification posture when every joint of its tool's chain
/// is within this of that posture's value (rad; a plateau average of a repeated posture
/// differs by well under a milliradian).
pub const REPEAT_ANGLE: f64 = 0.01;

/// The same for prismatic joints (m).
pub const REPEAT_LENGTH: f64 = 0.001;

/// A joint value beyond the identification range by less than this still counts as inside
/// (rad): a few degrees do not change what the data determine.
pub const INSIDE_MARGIN_ANGLE: f64 = 0.05;

/// The same for prismatic joints (m).
pub const INSIDE_MARGIN_LENGTH: f64 = 0.005;

/// Where a validation configuration lies relative to the identification configurations.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Stratum {
    /// It repeats an identification posture (within [`REPEAT_ANGLE`], [`REPEAT_LENGTH`]).
    Repeat,
    /// A new posture, every joint of the tool's chain inside the identification range.
    Inside,
    /// A new posture with a joint outside the identification range (extrapolation).
    Outside,
}

impl Stratum {
    /// `repeat`, `inside` or `outside`.
    pub fn as_str(self) -> &'static str {
        match self {
            Stratum::Repeat => "repeat",
            Stratum::Inside => "inside",
            Stratum::Outside => "outside",
        }
    }

    /// In words, for reports.
    pub fn describe(self) -> &'static str {
        match self {
            Stratum::Repeat => "repeat an identification posture",
            Stratum::Inside => "new postures inside the identification joint ranges",
            Stratum::Outside => "postures outside the identification joint ranges",
        }
    }
}

/// The independent joint values a tool's chain depends on, with whether each is an angle.
fn chain_dofs(model: &McpcModel, tool: usize) -> Vec<(usize, bool)> {
    let Some(chain) = (tool < model.tools().len()).then(|| model.tool_chain(tool)) else {
        return Vec::new();
    };
    let mut dofs: Vec<(usize, bool)> = Vec::new();
    for &f in chain {
        let frame = &model.frames()[f];
        let dof = match frame.actuation {
            Actuation::Independent(dof) => dof.0,
            Actuation::Mimic { master, .. } => master.0,
            Actuation::None => continue,
        };
        if !dofs.iter().any(|(d, _)| *d == dof) {
            dofs.push((dof, frame.kind == FrameKind::Revolute));
        }
    }
    dofs
}

/// The stratum of every validation measurement (in order), judged on the joints of its tool's
/// chain against the identification measurements of the same tool.
pub fn strata(
    model: &McpcModel,
    identification: &[Measurement],
    validation: &[Measurement],
) -> Vec<Stratum> {
    validation
        .iter()
        .map(|m| {
            let dofs = chain_dofs(model, m.tool);
            let same_tool: Vec<&Measurement> =
                identification.iter().filter(|i| i.tool == m.tool).collect();
            let value = |x: &Measurement, dof: usize| x.q.get(dof).copied().unwrap_or(0.0);
            let repeats = same_tool.iter().any(|i| {
                dofs.iter().all(|&(d, angle)| {
                    let tolerance = if angle { REPEAT_ANGLE } else { REPEAT_LENGTH };
                    (value(i, d) - value(m, d)).abs() <= tolerance
                })
            });
            if repeats {
                return Stratum::Repeat;
            }
            let inside = !same_tool.is_empty()
                && dofs.iter().all(|&(d, angle)| {
                    let margin = if angle {
                        INSIDE_MARGIN_ANGLE
                    } else {
                        INSIDE_MARGIN_LENGTH
                    };
                    let (low, high) = same_tool
                        .iter()
                        .map(|i| value(i, d))
                        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), v| {
                            (l.min(v), h.max(v))
                        });
                    let v = value(m, d);
                    v >= low - margin && v <= high + margin
                });
            if inside {
                Stratum::Inside
            } else {
                Stratum::Outside
            }
        })
        .collect()
}
