//! The coupled stage's reduced model: the torso frames plus one rigid tool per locked arm.

use crate::error::{Error, Result};
use crate::kinematics::{McpcModel, McpcTool};
use crate::measurement::Measurement;

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
