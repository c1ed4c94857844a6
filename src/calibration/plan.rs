//! Calibration plans: which parameters are identified from which measurements, in which order
//! (paper section 5.3.1). A plan is data; the paper's staging is the [`Plan::staged`] preset.

use super::gauge::reference_gauge;
use super::normal_equations::ProductsMemo;
use super::options::IdentificationOptions;
use super::predictor::{Deflected, DeflectedWithDerivative, Rigid};
use super::solver::{identify, identify_reusing, IdentificationReport};
use super::verdict::Finding;
use crate::error::{Error, Result};
use crate::kinematics::{McpcModel, ParameterOwner};
use crate::measurement::Measurement;
use crate::tree::Branches;
use nalgebra::Vector6;
use std::borrow::Cow;

mod anderson;
mod locked_arm;
pub(super) use anderson::Anderson;
use anderson::ANDERSON_DEPTH;
pub use locked_arm::locked_arm_model;

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

/// What every stage of one run of a plan shares.
struct StageContext<'a> {
    /// The model frames of the coupled branch's joints ([`coupled_frames`]).
    coupled_frames: Vec<usize>,
    compensation: Compensation<'a>,
    options: &'a IdentificationOptions,
    /// Eq. (26): the linear D_f of every measurement, once, at the starting model.
    linear_offsets: Option<Vec<Vector6<f64>>>,
    /// One predictor for all stages and cycles, so its Jacobian corrections are reused; it
    /// exists exactly under exact compensation.
    exact_predictor: Option<DeflectedWithDerivative<'a>>,
    /// 1, or [`MAX_CYCLES`] for a staged plan under exact compensation.
    max_cycles: usize,
    /// The last products over the caller's measurements (a robust loop's refits).
    memo: Option<&'a ProductsMemo<'a>>,
}

/// One stage's measurements (indices and copies; the rows given, not a copy, when the stage
/// takes them all: at 10⁶ configurations a copy was ~400 MB) and its options (the observation
/// weights, robust estimation, of its measurements): the same in every cycle.
struct StageInput<'m> {
    selected: Vec<usize>,
    data: Cow<'m, [Measurement]>,
    options: IdentificationOptions,
}

/// A coupled stage's identified reduced model (torso + locked-arm tools), the measurements
/// re-pointed at those tools and their number, from the previous cycle: the next cycle starts
/// from them, so the locked-arm tools need not be built or found again.
type CoupledStart = Option<(McpcModel, Vec<Measurement>, usize)>;

/// Runs `plan`: every stage starts from the previous stage's model.
pub fn calibrate(
    branches: &Branches,
    model: &McpcModel,
    measurements: &[Measurement],
    compensation: Compensation<'_>,
    plan: &Plan,
    options: &IdentificationOptions,
) -> Result<CalibrationReport> {
    calibrate_reusing(
        (branches, model, plan),
        measurements,
        compensation,
        options,
        None,
    )
}

/// [`calibrate`] with the last products over `measurements` kept in `memo`
/// ([`ProductsMemo`]: a robust loop's refits from the previous solution).
pub(crate) fn calibrate_reusing<'a>(
    (branches, model, plan): (&Branches, &McpcModel, &Plan),
    measurements: &'a [Measurement],
    compensation: Compensation<'a>,
    options: &'a IdentificationOptions,
    memo: Option<&'a ProductsMemo<'a>>,
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
    // With exact compensation, a staged plan is repeated: the coupled stage needs the
    // deflections of arms that only the later stage calibrates.
    let staged = plan
        .stages
        .iter()
        .zip(&skipped)
        .any(|(s, &skip)| s.parameters == ParameterSet::Coupled && !skip);
    let context = StageContext {
        coupled_frames,
        compensation,
        options,
        linear_offsets: linear_offsets(compensation, model, measurements)?,
        exact_predictor: match compensation {
            Compensation::Exact(source) => Some(DeflectedWithDerivative::new(source)),
            _ => None,
        },
        max_cycles: if staged && matches!(compensation, Compensation::Exact(_)) {
            MAX_CYCLES
        } else {
            1
        },
        memo,
    };
    let inputs = stage_inputs(plan, &skipped, measurements, options)?;
    let mut current = model.clone();
    let mut reports = Vec::new();
    let mut previous_coupled: Vec<CoupledStart> = vec![None; plan.stages.len()];
    let mut acceleration = Anderson::new(ANDERSON_DEPTH);
    let mut cycles = 0;
    while cycles < context.max_cycles {
        cycles += 1;
        let before = current.parameters();
        reports.clear();
        for (index, stage) in plan.stages.iter().enumerate() {
            if skipped[index] {
                continue;
            }
            let input = &inputs[index];
            reports.push(match stage.parameters {
                ParameterSet::Coupled => coupled_stage(
                    &context,
                    stage,
                    input,
                    &mut current,
                    &mut previous_coupled[index],
                )?,
                ParameterSet::Arms | ParameterSet::All => {
                    free_stage(&context, stage, input, &mut current)?
                }
            });
        }
        let after = current.parameters();
        if largest_change(&after, &before) <= CYCLE_TOLERANCE || cycles == context.max_cycles {
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

/// The largest absolute change between two parameter vectors.
fn largest_change(after: &[f64], before: &[f64]) -> f64 {
    after
        .iter()
        .zip(before)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max)
}

/// Eq. (26): the linear D_f of every measurement, once, at the starting model (under linear
/// compensation only); robust estimation standardises residuals with the same `D_f`.
pub(super) fn linear_offsets(
    compensation: Compensation<'_>,
    model: &McpcModel,
    measurements: &[Measurement],
) -> Result<Option<Vec<Vector6<f64>>>> {
    let Compensation::Linear(source) = compensation else {
        return Ok(None);
    };
    measurements
        .iter()
        .map(|m| {
            Ok(source
                .flexibility
                .for_payload(m.payload)?
                .tool_deflections(source.tree, model, &m.q)?[m.tool])
        })
        .collect::<Result<_>>()
        .map(Some)
}

/// Each stage's measurements and options (empty for a skipped stage).
fn stage_inputs<'m>(
    plan: &Plan,
    skipped: &[bool],
    measurements: &'m [Measurement],
    options: &IdentificationOptions,
) -> Result<Vec<StageInput<'m>>> {
    let mut inputs = Vec::with_capacity(plan.stages.len());
    for (stage, &skip) in plan.stages.iter().zip(skipped) {
        if skip {
            inputs.push(StageInput {
                selected: Vec::new(),
                data: Cow::Owned(Vec::new()),
                options: options.for_measurements(&[]),
            });
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
                    "no measurements labelled '{}'; label them (a 'stage' column) or use the simultaneous plan",
                    stage.measurements.as_deref().unwrap_or("")
                ),
            });
        }
        inputs.push(StageInput {
            data: match selected.len() == measurements.len() {
                true => Cow::Borrowed(measurements),
                false => Cow::Owned(selected.iter().map(|&i| measurements[i].clone()).collect()),
            },
            options: options.for_measurements(&selected),
            selected,
        });
    }
    Ok(inputs)
}

/// A coupled stage: the torso frames (with the locked-arm tools as nuisance parameters) on the
/// reduced model, copied back into `current`. Under exact compensation of a plan run once, it
/// repeats with refreshed deflections until the torso stops moving.
fn coupled_stage(
    context: &StageContext<'_>,
    stage: &Stage,
    input: &StageInput<'_>,
    current: &mut McpcModel,
    previous: &mut CoupledStart,
) -> Result<StageReport> {
    let mut rounds = 0;
    loop {
        rounds += 1;
        let offsets = coupled_offsets(context, input, current)?;
        let (mut stage_model, stage_data, locked_tools) = match previous.take() {
            // Same data, same groups: the locked tools start where the previous round found
            // them, the torso frames (the first parameters of both models) where the model
            // has them now.
            Some((mut previous, stage_data, locked_tools)) => {
                let mut values = previous.parameters();
                let torso = previous.tool_parameter_offset(0);
                values[..torso].copy_from_slice(&current.parameters()[..torso]);
                previous.set_parameters(&values)?;
                (previous, stage_data, locked_tools)
            }
            None => locked_arm_model(current, &context.coupled_frames, &input.data, &stage.name)?,
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
            .filter(|p| !(*p < shared && context.options.frozen.contains(p)))
            .collect();
        let gauge = reference_gauge(&stage_model, &free);
        free.retain(|p| !gauge.contains(p));
        let reduced = IdentificationOptions {
            prior: context
                .options
                .prior
                .as_ref()
                .map(|prior| prior.for_reduced_model(shared, stage_model.parameter_count())),
            ..input.options.clone()
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
        let change = copy_torso_back(context, &identification, &mut stage_model, current)?;
        let frame_parameters = stage_model.has_frame_parameters();
        *previous = Some((stage_model, stage_data, locked_tools));
        // Repeat with refreshed offsets only when the whole plan is not being repeated anyway
        // (the outer cycles refresh them too, more cheaply).
        let again = matches!(context.compensation, Compensation::Exact(_))
            && context.max_cycles == 1
            && change > 1e-13
            && rounds < 8;
        if !again {
            return Ok(StageReport {
                name: stage.name.clone(),
                measurements: input.data.len(),
                locked_tools,
                frame_parameters,
                identification,
                kept,
                gauge,
            });
        }
    }
}

/// The deflections of a coupled stage's measurements. The reduced model cannot carry the
/// flexibility model, so its deflections enter as offsets: fixed for Linear, recomputed at the
/// current torso for Exact until they stop changing.
fn coupled_offsets(
    context: &StageContext<'_>,
    input: &StageInput<'_>,
    current: &McpcModel,
) -> Result<Option<Vec<Vector6<f64>>>> {
    Ok(match context.compensation {
        Compensation::None => None,
        Compensation::Linear(_) => context
            .linear_offsets
            .as_ref()
            .map(|o| input.selected.iter().map(|&i| o[i]).collect()),
        Compensation::Exact(source) => Some(
            input
                .data
                .iter()
                .map(|m| Ok(source.offsets(current, &m.q, m.payload)?[m.tool]))
                .collect::<Result<_>>()?,
        ),
    })
}

/// Copies a coupled stage's identified torso frames (and, from a reference link, its
/// measurement frame) back into the full model; returns how far the full model's parameters
/// moved.
fn copy_torso_back(
    context: &StageContext<'_>,
    identification: &IdentificationReport,
    stage_model: &mut McpcModel,
    current: &mut McpcModel,
) -> Result<f64> {
    let before = current.parameters();
    let mut values = before.clone();
    for (stage_frame, &frame) in context.coupled_frames.iter().enumerate() {
        let count = current.frames()[frame].kind.parameter_count();
        let from = stage_model.frame_parameter_offset(stage_frame);
        let to = current.frame_parameter_offset(frame);
        values[to..to + count].copy_from_slice(&identification.parameters[from..from + count]);
    }
    current.set_parameters(&values)?;
    stage_model.set_parameters(&identification.parameters)?;
    if stage_model.has_frame_parameters() {
        // From a reference link the stage fits the measurement frame too.
        current.set_measurement_frame(&stage_model.world_from_base());
    }
    Ok(largest_change(&values, &before))
}

/// An `Arms` or `All` stage on the full model.
fn free_stage(
    context: &StageContext<'_>,
    stage: &Stage,
    input: &StageInput<'_>,
    current: &mut McpcModel,
) -> Result<StageReport> {
    let data = &input.data;
    let kept = position_only_orientations(current, data);
    let mut free: Vec<usize> = stage_parameters(current, &context.coupled_frames, stage.parameters)
        .into_iter()
        .filter(|p| !kept.contains(p) && !context.options.frozen.contains(p))
        .collect();
    let gauge = reference_gauge(current, &free);
    free.retain(|p| !gauge.contains(p));
    let offsets: Option<Vec<Vector6<f64>>> = context
        .linear_offsets
        .as_ref()
        .map(|o| input.selected.iter().map(|&i| o[i]).collect());
    // The exact predictor exists exactly under exact compensation.
    let identification = match &context.exact_predictor {
        Some(predictor) => identify(current, data, None, predictor, &free, &input.options)?,
        // Rigid, without offsets: the products of a refit at the same model can be updated.
        None => identify_reusing(
            current,
            (data, offsets.as_deref()),
            &Rigid,
            &free,
            &input.options,
            context.memo,
        )?,
    };
    current.set_parameters(&identification.parameters)?;
    Ok(StageReport {
        name: stage.name.clone(),
        measurements: data.len(),
        locked_tools: 0,
        frame_parameters: false,
        identification,
        kept,
        gauge,
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
