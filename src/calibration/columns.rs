//! Joint columns that look swapped or shifted (`docs/calibration.md`, "After the solve"): when
//! the residuals are far above the noise, the nominal robot is registered (measurement frame
//! when fitted, tool frames: [`super::baseline::registered_nominal`]) on the data as read and
//! on the data with two joint columns of a chain exchanged, or a chain's columns shifted by
//! one. A rearrangement that the nominal robot fits [`ROOT_CAUSE_RATIO`]× better is the likely
//! root cause, named by joint; the other findings then read as its probable consequences.

use super::baseline::registered_nominal;
use super::initial_guess::{initial_guess, initial_tool_frames};
use super::options::IdentificationOptions;
use super::verdict::{Finding, Status};
use crate::error::Result;
use crate::kinematics::McpcModel;
use crate::math::Pose;
use crate::measurement::Measurement;
use crate::tree::{Actuation, KinematicTree};

/// A rearranged data set must be fitted this many times better (RMS) to be named.
pub const ROOT_CAUSE_RATIO: f64 = 3.0;

/// At most this many rows (evenly spaced) are registered per rearrangement.
pub const DIAGNOSIS_ROWS: usize = 80;

/// The codes of the findings that name a root cause.
pub const ROOT_CAUSES: [&str; 2] = ["swapped-joint-columns", "shifted-joint-columns"];

/// The codes of findings that follow from a wrong data set rather than stand on their own.
pub const CONSEQUENCES: [&str; 11] = [
    "urdf-alone-worse",
    "sigma-ratio",
    "down-weighted",
    "validation-worse",
    "validation-prediction",
    "rank-deficient",
    "ill-conditioned",
    "not-converged",
    "outliers",
    "stiffness-below-zero",
    "joint-errors-implausible",
];

/// The RMS position residual (m) of the nominal robot registered on `data`.
fn registered_rms(
    nominal: &McpcModel,
    data: &[Measurement],
    fit_frame: bool,
    world_from_base: &Pose,
    options: &IdentificationOptions,
) -> Result<f64> {
    let start = if fit_frame {
        initial_guess(nominal, data, 3)?.model
    } else {
        let mut model = nominal.clone();
        model.set_world_from_base(world_from_base);
        initial_tool_frames(&model, data)?.model
    };
    let model = registered_nominal(&start, data, &[], fit_frame, options)?;
    let sum: f64 = data
        .iter()
        .filter_map(|m| {
            let predicted = model.tool_poses(&m.q)[m.tool].translation.vector;
            let measured = super::initial_guess::measured_position(m)?;
            Some((measured - predicted).norm_squared())
        })
        .sum();
    Ok((sum / data.len().max(1) as f64).sqrt())
}

/// The independent joints of every tool's chain, in chain order.
fn chains(model: &McpcModel) -> Vec<Vec<usize>> {
    (0..model.tools().len())
        .map(|tool| {
            let mut dofs = Vec::new();
            for &f in model.tool_chain(tool) {
                if let Actuation::Independent(dof) = model.frames()[f].actuation {
                    if !dofs.contains(&dof.0) {
                        dofs.push(dof.0);
                    }
                }
            }
            dofs
        })
        .collect()
}

/// A rearrangement of the joint columns: the column each dof takes its value from.
struct Rearrangement {
    kind: &'static str,
    joints: Vec<usize>,
    from: Vec<(usize, usize)>,
}

fn candidates(model: &McpcModel) -> Vec<Rearrangement> {
    let mut out: Vec<Rearrangement> = Vec::new();
    for chain in chains(model) {
        for (i, &a) in chain.iter().enumerate() {
            for &b in &chain[i + 1..] {
                if !out
                    .iter()
                    .any(|r| r.kind == "swapped" && r.joints == [a, b])
                {
                    out.push(Rearrangement {
                        kind: "swapped",
                        joints: vec![a, b],
                        from: vec![(a, b), (b, a)],
                    });
                }
            }
        }
        let k = chain.len();
        if k >= 3 {
            for step in [1, k - 1] {
                let from = (0..k).map(|j| (chain[j], chain[(j + step) % k])).collect();
                out.push(Rearrangement {
                    kind: "shifted",
                    joints: chain.clone(),
                    from,
                });
            }
        }
    }
    out
}

/// The finding naming swapped or shifted joint columns, when a rearrangement explains the
/// data [`ROOT_CAUSE_RATIO`]× better than the columns as read.
pub fn diagnose_columns(
    tree: &KinematicTree,
    nominal: &McpcModel,
    data: &[Measurement],
    fit_frame: bool,
    world_from_base: &Pose,
    options: &IdentificationOptions,
) -> Result<Option<Finding>> {
    if data.is_empty() {
        return Ok(None);
    }
    // A column mistake shows on a few dozen rows as well as on all: evenly spaced ones.
    let step = data.len().div_ceil(DIAGNOSIS_ROWS);
    let data: Vec<Measurement> = data.iter().step_by(step).cloned().collect();
    let data = &data[..];
    let as_read = registered_rms(nominal, data, fit_frame, world_from_base, options)?;
    let mut best: Option<(f64, Rearrangement)> = None;
    for candidate in candidates(nominal) {
        let rearranged: Vec<Measurement> = data
            .iter()
            .map(|m| {
                let mut moved = m.clone();
                for &(to, from) in &candidate.from {
                    if let (Some(slot), Some(&value)) = (moved.q.get_mut(to), m.q.get(from)) {
                        *slot = value;
                    }
                }
                moved
            })
            .collect();
        let Ok(rms) = registered_rms(nominal, &rearranged, fit_frame, world_from_base, options)
        else {
            continue;
        };
        if best.as_ref().is_none_or(|(b, _)| rms < *b) {
            best = Some((rms, candidate));
        }
    }
    let Some((rms, found)) = best.filter(|(rms, _)| rms * ROOT_CAUSE_RATIO < as_read) else {
        return Ok(None);
    };
    let name = |dof: usize| -> String {
        tree.dofs()
            .get(dof)
            .map_or_else(|| format!("joint {dof}"), |&j| tree.joint(j).name.clone())
    };
    let joints: Vec<String> = found.joints.iter().map(|&d| name(d)).collect();
    let (code, what) = match found.kind {
        "swapped" => (
            ROOT_CAUSES[0],
            format!(
                "the columns of joints '{}' and '{}' look swapped",
                joints[0], joints[1]
            ),
        ),
        _ => (
            ROOT_CAUSES[1],
            format!(
                "the joint columns of the chain {} look shifted by one",
                joints.join(", ")
            ),
        ),
    };
    Ok(Some(Finding::failed(
        code,
        format!(
            "{what}: so rearranged, the nominal robot registered on the data leaves {:.3} mm RMS instead of {:.3} mm; check which column of the CSV holds which joint (the header)",
            rms * 1e3,
            as_read * 1e3
        ),
    )))
}

/// A finding that names a root cause: swapped or shifted columns, or a fixed measurement
/// frame that cannot explain the data.
fn is_root_cause(finding: &Finding) -> bool {
    ROOT_CAUSES.contains(&finding.code.as_str())
        || (finding.code == "measurement-frame" && finding.status == Status::Failed)
}

/// How a consequence's message starts.
pub const CONSEQUENCE_PREFIX: &str = "probable consequence";

/// Marks the findings that follow from a root cause as its probable consequences (once).
pub fn mark_consequences(findings: &mut [Finding]) {
    let Some(cause) = findings
        .iter()
        .find(|f| is_root_cause(f))
        .map(|f| match f.code.as_str() {
            "measurement-frame" => "the measurement frame".to_owned(),
            _ => f.message.split(':').next().unwrap_or_default().to_owned(),
        })
    else {
        return;
    };
    for finding in findings
        .iter_mut()
        .filter(|f| CONSEQUENCES.contains(&f.code.as_str()))
        .filter(|f| !f.message.starts_with(CONSEQUENCE_PREFIX))
    {
        finding.message = format!(
            "{CONSEQUENCE_PREFIX} of the root cause above ({cause}), not a separate problem: {}",
            finding.message
        );
    }
}
