//! Calibration plans: which parameters are identified from which measurements, in which order
//! (paper section 5.3.1). A plan is data; the paper's staging is the [`Plan::staged`] preset.

use super::gauge::reference_gauge;
use super::options::IdentificationOptions;
use super::predictor::{Deflected, DeflectedWithDerivative, Rigid};
use super::solver::{identify, IdentificationReport};
use super::verdict::Finding;
use crate::error::{Error, Result};
use crate::kinematics::{McpcModel, McpcTool, ParameterOwner};
use crate::measurement::Measurement;
use crate::tree::Branches;
use nalgebra::{DMatrix, DVector, Vector6};

/// Which parameters a stage identifies.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ParameterSet {
    /// The coupled branch (torso), from configurations with the arm joints locked: each
    /// locked arm with its tool acts as one rigid tool whose six parameters are identified
    /// alongside as nuisance parameters.
    Coupled,
    /// Every arm's frames and tool, with the coupled branch fixed.
    Arms,
    /// Everything at once.
    All,
}

/// One stage of a plan.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Stage {
    /// Name shown in reports.
    pub name: String,
    /// What it identifies.
    pub parameters: ParameterSet,
    /// Which measurements it uses: those whose `stage` label equals this, or all if `None`.
    #[serde(default)]
    pub measurements: Option<String>,
}

/// An ordered list of stages.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Plan {
    /// The stages, run in order, each starting from the previous one's result.
    pub stages: Vec<Stage>,
}

impl Plan {
    /// The paper's staging: the torso from measurements labelled `torso` (arms locked), then
    /// the arms from measurements labelled `arms`.
    pub fn staged() -> Self {
        Plan {
            stages: vec![
                Stage {
                    name: "torso".into(),
                    parameters: ParameterSet::Coupled,
                    measurements: Some("torso".into()),
                },
                Stage {
                    name: "arms".into(),
                    parameters: ParameterSet::Arms,
                    measurements: Some("arms".into()),
                },
            ],
        }
    }

    /// Every parameter from every measurement at once.
    pub fn simultaneous() -> Self {
        Plan {
            stages: vec![Stage {
                name: "all".into(),
                parameters: ParameterSet::All,
                measurements: None,
            }],
        }
    }
}

/// The outcome of one stage.
#[derive(Debug, Clone)]
pub struct StageReport {
    /// The stage's name.
    pub name: String,
    /// How many measurements it used.
    pub measurements: usize,
    /// For a coupled stage, the number of rigid locked-arm tools it identified alongside.
    pub locked_tools: usize,
    /// The solver's report (parameter indices refer to the stage's own model for a coupled
    /// stage, to the full model otherwise).
    pub identification: IdentificationReport,
    /// Parameters (same indexing) deliberately not freed because the stage's observations
    /// cannot see them: the orientation (α, β, γ) of a tool measured by positions only. They
    /// keep their starting values ([`position_only_orientations`]).
    pub kept: Vec<usize>,
    /// Parameters (same indexing) kept at their starting values to fix the root's placement,
    /// which a reference link other than the root leaves free ([`reference_gauge`]).
    pub gauge: Vec<usize>,
    /// Whether the stage's own model has the six measurement-frame parameters last (a
    /// coupled stage measured from a reference link).
    pub frame_parameters: bool,
}

impl StageReport {
    /// How many of the stage's parameters are parameters of the full model, in the same
    /// order: all of them (`usize::MAX`), except for a coupled stage, whose reduced model has
    /// the torso frames first and then six parameters per locked-arm tool.
    pub fn full_model_parameters(&self) -> usize {
        if self.locked_tools > 0 {
            let frame = if self.frame_parameters { 6 } else { 0 };
            self.identification
                .parameters
                .len()
                .saturating_sub(6 * self.locked_tools + frame)
        } else {
            usize::MAX
        }
    }
}

/// The outcome of a plan.
#[derive(Debug, Clone)]
pub struct CalibrationReport {
    /// The calibrated model.
    pub model: McpcModel,
    /// One report per stage (of the last cycle).
    pub stages: Vec<StageReport>,
    /// How many times the plan ran: 1, except for staged plans with exact flexibility
    /// compensation, which repeat until the parameters stop changing (at most [`MAX_CYCLES`]).
    pub cycles: usize,
    /// What the user should know about how the plan ran (e.g. a torso stage skipped on a robot
    /// without torso joints, code `empty-torso`).
    pub notes: Vec<Finding>,
}

/// The most times a staged plan with exact flexibility compensation is repeated.
pub const MAX_CYCLES: usize = 30;

/// A repeated plan stops when no parameter moved by more than this in a cycle (rad or m):
/// ten nanometres, far below any instrument's noise; the cycles converge by one to two
/// decades each, so the result is then within about a nanometre of the fixed point.
pub const CYCLE_TOLERANCE: f64 = 1e-8;

/// How flexibility enters a calibration.
#[derive(Debug, Clone, Copy)]
pub enum Compensation<'a> {
    /// Ignore it: the rigid model explains the measurements.
    None,
    /// The paper's eq. (26): subtract the linear flexibility error `D_f = J_f·d_f`, computed
    /// once at the starting parameters.
    Linear(Deflected<'a>),
    /// Predict the deflected tool poses (the deformations inserted into the chain) at the
    /// current parameters in every iteration: exact where the flexibility model is right.
    Exact(Deflected<'a>),
}

/// Runs `plan`: every stage starts from the previous stage's model.
pub fn calibrate(
    branches: &Branches,
    model: &McpcModel,
    measurements: &[Measurement],
    compensation: Compensation<'_>,
    plan: &Plan,
    options: &IdentificationOptions,
) -> Result<CalibrationReport> {
    if plan.stages.is_empty() {
        return Err(Error::InvalidData {
            origin: "plan".into(),
            message: "the plan has no stages".into(),
        });
    }
    let coupled_frames = coupled_frames(model, branches);
    // A robot with no movable torso joint (arms straight on the base) has nothing for a
    // coupled stage to identify: such stages are skipped, and said so.
    let skipped: Vec<bool> = plan
        .stages
        .iter()
        .map(|s| s.parameters == ParameterSet::Coupled && coupled_frames.is_empty())
        .collect();
    let notes = skipped_stage_notes(plan, &skipped, measurements);
    // Eq. (26): the linear D_f of every measurement, once, at the starting model.
    let linear_offsets: Option<Vec<Vector6<f64>>> = match compensation {
        Compensation::Linear(source) => Some(
            measurements
                .iter()
                .map(|m| {
                    Ok(source
                        .flexibility
                        .for_payload(m.payload)?
                        .tool_deflections(source.tree, model, &m.q)?[m.tool])
                })
                .collect::<Result<_>>()?,
        ),
        _ => None,
    };
    let mut current = model.clone();
    // With exact compensation, a staged plan is repeated: the coupled stage needs the
    // deflections of arms that only the later stage calibrates.
    let staged = plan
        .stages
        .iter()
        .zip(&skipped)
        .any(|(s, &skip)| s.parameters == ParameterSet::Coupled && !skip);
    let max_cycles = if staged && matches!(compensation, Compensation::Exact(_)) {
        MAX_CYCLES
    } else {
        1
    };
    // One predictor for all stages and cycles, so its Jacobian corrections are reused.
    let exact_predictor = match compensation {
        Compensation::Exact(source) => Some(DeflectedWithDerivative::new(source)),
        _ => None,
    };
    // Each stage's measurements (indices and copies): the same in every cycle.
    let mut stage_inputs: Vec<(Vec<usize>, Vec<Measurement>)> = Vec::new();
    // Each stage's options: the observation weights (robust estimation) of its measurements.
    let mut stage_options: Vec<IdentificationOptions> = Vec::new();
    for (stage, &skip) in plan.stages.iter().zip(&skipped) {
        if skip {
            stage_inputs.push((Vec::new(), Vec::new()));
            stage_options.push(options.for_measurements(&[]));
            continue;
        }
        let selected: Vec<usize> = (0..measurements.len())
            .filter(|&i| {
                stage.measurements.is_none() || measurements[i].stage == stage.measurements
            })
            .collect();
        if selected.is_empty() {
            return Err(Error::InvalidData {
                origin: format!("stage '{}'", stage.name),
                message: format!(
                    "no measurements labelled '{}'; label them (a `stage` column) or use the simultaneous plan",
                    stage.measurements.as_deref().unwrap_or("")
                ),
            });
        }
        let data = selected.iter().map(|&i| measurements[i].clone()).collect();
        stage_options.push(options.for_measurements(&selected));
        stage_inputs.push((selected, data));
    }
    let mut reports = Vec::new();
    // Per coupled stage, its identified reduced model (torso + locked-arm tools), the
    // measurements re-pointed at those tools and their number, from the previous cycle: the
    // next cycle starts from them, so the locked-arm tools need not be built or found again.
    let mut previous_coupled: Vec<Option<(McpcModel, Vec<Measurement>, usize)>> =
        vec![None; plan.stages.len()];
    let mut acceleration = Anderson::new(ANDERSON_DEPTH);
    let mut cycles = 0;
    while cycles < max_cycles {
        cycles += 1;
        let before = current.parameters();
        reports.clear();
        for (index, stage) in plan.stages.iter().enumerate() {
            if skipped[index] {
                continue;
            }
            let (selected, data) = &stage_inputs[index];
            let report = match stage.parameters {
                ParameterSet::Coupled => {
                    let mut rounds = 0;
                    loop {
                        rounds += 1;
                        // The reduced model cannot carry the flexibility model, so its deflections
                        // enter as offsets: fixed for Linear, recomputed at the current torso for
                        // Exact until they stop changing.
                        let offsets: Option<Vec<Vector6<f64>>> = match compensation {
                            Compensation::None => None,
                            Compensation::Linear(_) => linear_offsets
                                .as_ref()
                                .map(|o| selected.iter().map(|&i| o[i]).collect()),
                            Compensation::Exact(source) => Some(
                                data.iter()
                                    .map(|m| Ok(source.offsets(&current, &m.q, m.payload)?[m.tool]))
                                    .collect::<Result<_>>()?,
                            ),
                        };
                        let (mut stage_model, stage_data, locked_tools) = match previous_coupled
                            [index]
                            .take()
                        {
                            // Same data, same groups: the locked tools start where the
                            // previous round found them, the torso frames (the first
                            // parameters of both models) where the model has them now.
                            Some((mut previous, stage_data, locked_tools)) => {
                                let mut values = previous.parameters();
                                let torso = previous.tool_parameter_offset(0);
                                values[..torso].copy_from_slice(&current.parameters()[..torso]);
                                previous.set_parameters(&values)?;
                                (previous, stage_data, locked_tools)
                            }
                            None => locked_arm_model(&current, &coupled_frames, data, &stage.name)?,
                        };
                        let kept = position_only_orientations(&stage_model, &stage_data);
                        // The torso frames' parameters are the first of both models.
                        let shared: usize = stage_model
                            .frames()
                            .iter()
                            .map(|f| f.kind.parameter_count())
                            .sum();
                        let mut free: Vec<usize> = (0..stage_model.parameter_count())
                            .filter(|p| !kept.contains(p))
                            .filter(|p| !(*p < shared && options.frozen.contains(p)))
                            .collect();
                        let gauge = reference_gauge(&stage_model, &free);
                        free.retain(|p| !gauge.contains(p));
                        let reduced = IdentificationOptions {
                            prior: options.prior.as_ref().map(|prior| {
                                prior.for_reduced_model(shared, stage_model.parameter_count())
                            }),
                            ..stage_options[index].clone()
                        };
                        let identification = identify(
                            &stage_model,
                            &stage_data,
                            offsets.as_deref(),
                            // The reduced model is rigid; its deflections come as offsets.
                            &Rigid,
                            &free,
                            &reduced,
                        )?;
                        // Copy the torso frames back into the full model.
                        let before = current.parameters();
                        let mut values = before.clone();
                        for (stage_frame, &frame) in coupled_frames.iter().enumerate() {
                            let count = current.frames()[frame].kind.parameter_count();
                            let from = stage_model.frame_parameter_offset(stage_frame);
                            let to = current.frame_parameter_offset(frame);
                            values[to..to + count]
                                .copy_from_slice(&identification.parameters[from..from + count]);
                        }
                        current.set_parameters(&values)?;
                        stage_model.set_parameters(&identification.parameters)?;
                        if stage_model.has_frame_parameters() {
                            // From a reference link the stage fits the measurement frame too.
                            current.set_measurement_frame(&stage_model.world_from_base());
                        }
                        let frame_parameters = stage_model.has_frame_parameters();
                        previous_coupled[index] = Some((stage_model, stage_data, locked_tools));
                        let change = values
                            .iter()
                            .zip(&before)
                            .map(|(a, b)| (a - b).abs())
                            .fold(0.0, f64::max);
                        // Repeat with refreshed offsets only when the whole plan is not being
                        // repeated anyway (the outer cycles refresh them too, more cheaply).
                        let again = matches!(compensation, Compensation::Exact(_))
                            && max_cycles == 1
                            && change > 1e-13
                            && rounds < 8;
                        if !again {
                            break StageReport {
                                name: stage.name.clone(),
                                measurements: data.len(),
                                locked_tools,
                                frame_parameters,
                                identification,
                                kept,
                                gauge,
                            };
                        }
                    }
                }
                ParameterSet::Arms | ParameterSet::All => {
                    let kept = position_only_orientations(&current, data);
                    let mut free: Vec<usize> =
                        stage_parameters(&current, &coupled_frames, stage.parameters)
                            .into_iter()
                            .filter(|p| !kept.contains(p) && !options.frozen.contains(p))
                            .collect();
                    let gauge = reference_gauge(&current, &free);
                    free.retain(|p| !gauge.contains(p));
                    let offsets: Option<Vec<Vector6<f64>>> = linear_offsets
                        .as_ref()
                        .map(|o| selected.iter().map(|&i| o[i]).collect());
                    // The exact predictor exists exactly under exact compensation.
                    let identification = match &exact_predictor {
                        Some(predictor) => identify(
                            &current,
                            data,
                            None,
                            predictor,
                            &free,
                            &stage_options[index],
                        )?,
                        None => identify(
                            &current,
                            data,
                            offsets.as_deref(),
                            &Rigid,
                            &free,
                            &stage_options[index],
                        )?,
                    };
                    current.set_parameters(&identification.parameters)?;
                    StageReport {
                        name: stage.name.clone(),
                        measurements: data.len(),
                        locked_tools: 0,
                        frame_parameters: false,
                        identification,
                        kept,
                        gauge,
                    }
                }
            };
            reports.push(report);
        }
        let after = current.parameters();
        let change = after
            .iter()
            .zip(&before)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        if change <= CYCLE_TOLERANCE || cycles == max_cycles {
            break;
        }
        // Start the next cycle from the Anderson-extrapolated fixed point rather than from
        // this cycle's result: the cycles converge linearly (the stages are coupled through
        // the deflections), the extrapolation makes that a few cycles.
        let next = acceleration.next(&before, &after);
        current.set_parameters(&next)?;
    }
    Ok(CalibrationReport {
        model: current,
        stages: reports,
        cycles,
        notes,
    })
}

/// The `empty-torso` notes of the stages skipped because the robot has no torso frames.
fn skipped_stage_notes(
    plan: &Plan,
    skipped: &[bool],
    measurements: &[Measurement],
) -> Vec<Finding> {
    plan.stages
        .iter()
        .zip(skipped)
        .filter(|(_, &skip)| skip)
        .map(|(stage, _)| {
            let unused = measurements
                .iter()
                .filter(|m| stage.measurements.is_some() && m.stage == stage.measurements)
                .count();
            Finding::note(
                "empty-torso",
                format!(
                    "the robot has no movable torso joints (its arms start at the base), so the plan's torso stage '{}' is skipped{}",
                    stage.name,
                    match unused {
                        0 => String::new(),
                        n => format!(" and its {n} measurements are not used"),
                    }
                ),
            )
        })
        .collect()
}

/// The model frames of the coupled branch's joints (the torso), parents first (a path up a
/// leg from a reference link lists them the other way).
pub fn coupled_frames(model: &McpcModel, branches: &Branches) -> Vec<usize> {
    let mut frames: Vec<usize> = branches
        .coupled
        .joints
        .iter()
        .filter_map(|j| model.frame_of_joint(*j))
        .collect();
    frames.sort_unstable();
    frames
}

/// The orientation parameters (α, β, γ) of every tool that `data` observe, but by positions
/// only. A measured point does not see how the tool is turned about it, and the tool offsets
/// x, y, z lie along the tool's own axes, so the unobservable directions mix orientation and
/// offset: a minimum-norm step would turn the tool (by tens of degrees) while keeping the
/// point. With the orientation fixed, x, y, z alone place the point and are identifiable, and
/// the orientation stays at its starting (nominal) value.
pub fn position_only_orientations(model: &McpcModel, data: &[Measurement]) -> Vec<usize> {
    let tools = model.tools().len();
    let mut positions = vec![false; tools];
    let mut poses = vec![false; tools];
    for m in data.iter().filter(|m| m.tool < tools) {
        let rows = super::observation::kind_of(&m.observation).row_kinds();
        if rows.contains(&super::observation::RowKind::Rotation) {
            poses[m.tool] = true;
        } else if rows.contains(&super::observation::RowKind::Position) {
            positions[m.tool] = true;
        }
    }
    model
        .parameter_layout()
        .iter()
        .enumerate()
        .filter(|(_, (owner, kind))| {
            matches!(owner, ParameterOwner::Tool(t) if positions[*t] && !poses[*t])
                && kind.is_angle()
        })
        .map(|(i, _)| i)
        .collect()
}

/// The parameters an `Arms` or `All` stage frees: everything, or everything but the torso
/// frames (`coupled_frames`). A `Coupled` stage works on its own reduced model
/// ([`locked_arm_model`]), whose parameters are all free.
pub fn stage_parameters(
    model: &McpcModel,
    coupled_frames: &[usize],
    set: ParameterSet,
) -> Vec<usize> {
    model
        .parameter_layout()
        .iter()
        .enumerate()
        .filter(|(_, (owner, _))| {
            set == ParameterSet::All
                || !matches!(owner, ParameterOwner::Frame(f) if coupled_frames.contains(f))
        })
        .map(|(i, _)| i)
        .collect()
}

/// The coupled-stage model: the torso frames plus one rigid tool per distinct (tool, locked arm
/// configuration), and the measurements re-pointed at those tools; also the number of those
/// tools. Whether the locked tools are determined by the data is left to the solver's rank
/// analysis. `coupled_frames` are the model frames of the coupled branch's joints; the pose
/// planner uses this too, so that it plans for exactly the model the stage identifies.
pub fn locked_arm_model(
    model: &McpcModel,
    coupled_frames: &[usize],
    data: &[Measurement],
    stage: &str,
) -> Result<(McpcModel, Vec<Measurement>, usize)> {
    let frames: Vec<_> = coupled_frames
        .iter()
        .map(|&f| model.frames()[f].clone())
        .collect();
    for (index, frame) in frames.iter().enumerate() {
        if frame.parent.is_some_and(|p| p >= index) || coupled_frames[index] != index {
            return Err(Error::InvalidData {
                origin: format!("stage '{stage}'"),
                message: "the coupled branch's frames must come first in the model".into(),
            });
        }
    }
    // Arm joint values of a measurement: every frame not in the coupled branch on its chain.
    let arm_values = |m: &Measurement| -> Vec<f64> {
        model
            .tool_chain(m.tool)
            .iter()
            .filter(|f| !coupled_frames.contains(f))
            .map(|&f| model.joint_value(f, &m.q))
            .collect()
    };
    let mut groups: Vec<(usize, Vec<f64>, Vec<f64>)> = Vec::new(); // (tool, arm values, one q)
    let mut stage_data = Vec::with_capacity(data.len());
    for m in data {
        let values = arm_values(m);
        let group = match groups.iter().position(|(tool, v, _)| {
            *tool == m.tool && v.iter().zip(&values).all(|(a, b)| (a - b).abs() <= 1e-9)
        }) {
            Some(g) => g,
            None => {
                groups.push((m.tool, values, m.q.clone()));
                groups.len() - 1
            }
        };
        let mut moved = m.clone();
        moved.tool = group;
        stage_data.push(moved);
    }
    let mut tools = Vec::with_capacity(groups.len());
    for (tool, _, q) in &groups {
        // The tool's last coupled frame (the last coupled frame, unless a reference link's
        // path runs through coupled frames off the tool's chain).
        let last = model
            .tool_chain(*tool)
            .iter()
            .rev()
            .find(|f| coupled_frames.contains(f))
            .copied();
        let world_from_tool = model.tool_pose(*tool, q);
        let world_from_last = match last {
            Some(f) => model.moved(f, q, &model.frame_transforms(q)[f]).to_pose(),
            None => model.world_from_root(q),
        };
        let twist = last.map_or(0.0, |f| model.frames()[f].twist);
        let link = model.tools()[*tool].link;
        tools.push(McpcTool::from_relative_pose(
            link,
            last,
            twist,
            &(world_from_last.inverse() * world_from_tool),
        ));
    }
    let mut stage_model = McpcModel::new(frames, tools)?;
    if let Some(reference) = model.reference() {
        if !model
            .reference_chain()
            .iter()
            .all(|f| coupled_frames.contains(f))
        {
            return Err(Error::InvalidData {
                origin: format!("stage '{stage}'"),
                message:
                    "the reference link's path leaves the coupled branch; use the simultaneous plan"
                        .into(),
            });
        }
        stage_model.set_reference(Some(reference.clone()))?;
    }
    stage_model.set_world_from_base(&model.world_from_base());
    Ok((stage_model, stage_data, groups.len()))
}

/// How many earlier cycles the Anderson extrapolation of a repeated plan uses.
const ANDERSON_DEPTH: usize = 3;

/// Anderson acceleration (type II) of the fixed-point iteration `x ← G(x)` formed by the
/// cycles of a repeated plan (Walker & Ni, SIAM J. Numer. Anal. 49, 2011): the next start is
/// `G(xₖ) − ΔG·γ` with `γ` the least-squares fit of the latest residual `fₖ = G(xₖ) − xₖ` by
/// the last residual differences `ΔF`. Falls back to the plain step `G(xₖ)` whenever the
/// residual grew, so it is never worse than repeating the plan.
pub(super) struct Anderson {
    depth: usize,
    /// `(G(x), f)` of the latest cycles, oldest first.
    history: Vec<(DVector<f64>, DVector<f64>)>,
}

impl Anderson {
    pub(super) fn new(depth: usize) -> Self {
        Self {
            depth,
            history: Vec::new(),
        }
    }

    /// The start of the next cycle, given this cycle's start `x` and result `g = G(x)`.
    pub(super) fn next(&mut self, x: &[f64], g: &[f64]) -> Vec<f64> {
        let g = DVector::from_column_slice(g);
        let f = &g - DVector::from_column_slice(x);
        if self
            .history
            .last()
            .is_some_and(|(_, previous)| f.norm() >= previous.norm())
        {
            self.history.clear();
        }
        self.history.push((g.clone(), f.clone()));
        if self.history.len() > self.depth + 1 {
            self.history.remove(0);
        }
        let columns = self.history.len() - 1;
        if columns == 0 {
            return g.as_slice().to_vec();
        }
        let n = g.len();
        let mut delta_f = DMatrix::zeros(n, columns);
        let mut delta_g = DMatrix::zeros(n, columns);
        for k in 0..columns {
            delta_f.set_column(k, &(&self.history[k + 1].1 - &self.history[k].1));
            delta_g.set_column(k, &(&self.history[k + 1].0 - &self.history[k].0));
        }
        // Small least-squares problem: SVD with a relative cut keeps it stable when the
        // differences are nearly parallel.
        if !delta_f.iter().chain(f.iter()).all(|v| v.is_finite()) {
            // No SVD of a non-finite matrix (it never ends): take the plain step.
            return g.as_slice().to_vec();
        }
        let svd = delta_f.svd(true, true);
        match svd.solve(&f, 1e-10 * svd.singular_values.max()) {
            Ok(gamma) if gamma.iter().all(|v| v.is_finite()) => {
                (g - delta_g * gamma).as_slice().to_vec()
            }
            _ => g.as_slice().to_vec(),
        }
    }
}
