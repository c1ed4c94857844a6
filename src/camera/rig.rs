//! Cameras and targets mounted on a robot: each becomes a frame of the MCPC model so that its
//! pose and its identification Jacobian come from the same kinematics as the tools'.
//!
//! A camera (and a target that is not on a tool) is appended to the model as an extra MCPC
//! tool on the last joint frame before its link (or on the base, for one fixed in the world):
//! its six tool parameters are the camera extrinsics (the target's pose) in its link, estimated
//! or held at the nominal pose. A target on a tool's link is placed at a fixed pose in that
//! tool's frame: the tool's own six parameters already move it, so a separate pose would be
//! the same unknown twice. The rig's [`Rig::robot_model`] drops the extra tools again.

use super::model::{Intrinsics, INTRINSIC_COUNT};
use super::target::TargetShape;
use super::unknown::Unknown;
use crate::error::{Error, Result};
use crate::kinematics::{McpcModel, McpcTool};
use crate::math::Pose;
use crate::tree::{KinematicTree, LinkId};
use std::ops::Range;

/// Where a camera or target is fixed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mount {
    /// On a link of the robot.
    Link(LinkId),
    /// In the world (the measurement frame, the robot's root frame unless registered).
    World,
}

/// A camera as described by the user: where it is and what to estimate.
#[derive(Debug, Clone, PartialEq)]
pub struct CameraSpec {
    /// Its name (the detections' `camera` column).
    pub name: String,
    /// What it is fixed to.
    pub mount: Mount,
    /// The nominal camera frame (OpenCV's: z forward, x right, y down) in the link (or world).
    pub mount_from_camera: Pose,
    /// Its intrinsics (the nominal ones when they are estimated).
    pub intrinsics: Intrinsics,
    /// Whether the extrinsics are estimated (else held at the nominal pose).
    pub estimate_pose: bool,
    /// Whether the intrinsics are estimated.
    pub estimate_intrinsics: bool,
}

/// A target as described by the user.
#[derive(Debug, Clone, PartialEq)]
pub struct TargetSpec {
    /// Its name (the detections' `target` column).
    pub name: String,
    /// What it is fixed to.
    pub mount: Mount,
    /// The nominal target frame in the link (or world).
    pub mount_from_target: Pose,
    /// Board or marker.
    pub shape: TargetShape,
    /// Whether its pose is estimated (a target on a tool's link: always, through the tool).
    pub estimate_pose: bool,
}

/// A camera of the rig.
#[derive(Debug, Clone, PartialEq)]
pub struct RigCamera {
    /// Its name.
    pub name: String,
    /// The model tool that is the camera frame.
    pub tool: usize,
    /// Its intrinsics.
    pub intrinsics: Intrinsics,
    /// Whether its intrinsics are estimated.
    pub estimate_intrinsics: bool,
}

/// A target of the rig.
#[derive(Debug, Clone, PartialEq)]
pub struct RigTarget {
    /// Its name.
    pub name: String,
    /// The model tool that carries it.
    pub tool: usize,
    /// Its frame in that tool's frame (constant).
    pub tool_from_target: Pose,
    /// Board or marker.
    pub shape: TargetShape,
}

/// Cameras and targets resolved against a model.
#[derive(Debug, Clone, PartialEq)]
pub struct Rig {
    /// The cameras.
    pub cameras: Vec<RigCamera>,
    /// The targets.
    pub targets: Vec<RigTarget>,
    /// Tools of the robot model (the extra tools follow them).
    pub robot_tools: usize,
    /// Per extra tool: its name (`camera head`, `target world_board`) and whether its six
    /// parameters are estimated.
    pub extra: Vec<(String, bool)>,
}

impl Rig {
    /// Mounts `cameras` and `targets` on `model` (the nominal model of `tree`): the rig, and
    /// the model with the extra tools appended.
    pub fn build(
        tree: &KinematicTree,
        model: &McpcModel,
        cameras: &[CameraSpec],
        targets: &[TargetSpec],
    ) -> Result<(Rig, McpcModel)> {
        let robot_tools = model.tools().len();
        let mut tools: Vec<McpcTool> = model.tools().to_vec();
        let mut extra = Vec::new();
        let mut rig_cameras = Vec::new();
        for camera in cameras {
            if let Some(problem) = camera.intrinsics.problem() {
                return Err(invalid(format!("camera '{}': {problem}", camera.name)));
            }
            tools.push(mounted_tool(
                tree,
                model,
                camera.mount,
                &camera.mount_from_camera,
            )?);
            extra.push((format!("camera {}", camera.name), camera.estimate_pose));
            rig_cameras.push(RigCamera {
                name: camera.name.clone(),
                tool: tools.len() - 1,
                intrinsics: camera.intrinsics,
                estimate_intrinsics: camera.estimate_intrinsics,
            });
        }
        let q0 = tree.zero_configuration();
        let mut rig_targets = Vec::new();
        for target in targets {
            let on_tool = match target.mount {
                Mount::Link(link) => model.tool_of_link(link),
                Mount::World => None,
            };
            let (tool, tool_from_target) = match (on_tool, target.mount) {
                (Some(tool), Mount::Link(link)) => {
                    let tool_from_link =
                        model.tool_pose(tool, &q0).inverse() * model_link_pose(tree, model, link)?;
                    (tool, tool_from_link * target.mount_from_target)
                }
                _ => {
                    tools.push(mounted_tool(
                        tree,
                        model,
                        target.mount,
                        &target.mount_from_target,
                    )?);
                    extra.push((format!("target {}", target.name), target.estimate_pose));
                    (tools.len() - 1, Pose::identity())
                }
            };
            rig_targets.push(RigTarget {
                name: target.name.clone(),
                tool,
                tool_from_target,
                shape: target.shape.clone(),
            });
        }
        let augmented = with_tools(model, tools)?;
        let rig = Rig {
            cameras: rig_cameras,
            targets: rig_targets,
            robot_tools,
            extra,
        };
        Ok((rig, augmented))
    }

    /// The robot's own model: `augmented` without the extra tools.
    pub fn robot_model(&self, augmented: &McpcModel) -> Result<McpcModel> {
        with_tools(augmented, augmented.tools()[..self.robot_tools].to_vec())
    }

    /// The flat indices of extra tool `extra`'s six parameters in the augmented model.
    pub fn extra_parameters(&self, augmented: &McpcModel, extra: usize) -> Range<usize> {
        let offset = augmented.tool_parameter_offset(self.robot_tools + extra);
        offset..offset + 6
    }

    /// The robot tools on a camera's link (a head named as a tool so that its neck joints are
    /// calibrated): the camera's extrinsics already place that link's frame, so their tool
    /// parameters are not fitted (and a simulation puts no board on them nor scores them).
    pub fn camera_carriers(&self, augmented: &McpcModel) -> Vec<usize> {
        let tools = augmented.tools();
        (0..self.robot_tools)
            .filter(|&t| {
                self.cameras
                    .iter()
                    .any(|c| tools[c.tool].link == tools[t].link)
            })
            .collect()
    }

    /// The unknowns of a fit of `augmented`: every robot parameter but the camera carriers'
    /// tool parameters and, with views, the estimated camera and target poses and the
    /// estimated intrinsics.
    pub fn unknowns(&self, augmented: &McpcModel, with_views: bool) -> Vec<Unknown> {
        let fixed: Vec<usize> = (0..self.extra.len())
            .flat_map(|e| self.extra_parameters(augmented, e))
            .chain(self.camera_carriers(augmented).into_iter().flat_map(|t| {
                let offset = augmented.tool_parameter_offset(t);
                offset..offset + 6
            }))
            .collect();
        let mut unknowns: Vec<Unknown> = (0..augmented.parameter_count())
            .filter(|p| !fixed.contains(p))
            .map(Unknown::Parameter)
            .collect();
        if with_views {
            for (e, (_, free)) in self.extra.iter().enumerate() {
                if *free {
                    unknowns.extend(self.extra_parameters(augmented, e).map(Unknown::Parameter));
                }
            }
            for (camera, spec) in self.cameras.iter().enumerate() {
                if spec.estimate_intrinsics {
                    unknowns.extend(
                        (0..INTRINSIC_COUNT).map(|index| Unknown::Intrinsic { camera, index }),
                    );
                }
            }
        }
        unknowns
    }

    /// The augmented model's index of robot-model parameter `index` (the extra tools' six
    /// parameters each sit between the robot tools and the joint-error terms).
    pub fn augmented_index(&self, robot: &McpcModel, index: usize) -> usize {
        if index < tools_end_of(robot) {
            index
        } else {
            index + 6 * self.extra.len()
        }
    }

    /// A readable name of augmented parameter `index`: the robot's names, and `camera head x`
    /// or `target world_board gamma` for the extra tools.
    pub fn parameter_name(
        &self,
        tree: &KinematicTree,
        augmented: &McpcModel,
        index: usize,
    ) -> String {
        for extra in 0..self.extra.len() {
            let range = self.extra_parameters(augmented, extra);
            if range.contains(&index) {
                let kinds = ["alpha", "beta", "gamma", "x", "y", "z"];
                return format!("{} {}", self.extra[extra].0, kinds[index - range.start]);
            }
        }
        augmented.parameter_name(tree, index)
    }
}

/// The index just past the last tool parameter of `model`.
fn tools_end_of(model: &McpcModel) -> usize {
    match model.tools().len() {
        0 => model
            .frames()
            .iter()
            .map(|f| f.kind.parameter_count())
            .sum(),
        n => model.tool_parameter_offset(n - 1) + 6,
    }
}

/// `model` with `tools` in place of its own, keeping its measurement frame and joint errors.
pub(crate) fn with_tools(model: &McpcModel, tools: Vec<McpcTool>) -> Result<McpcModel> {
    let mut result = McpcModel::new(model.frames().to_vec(), tools)?;
    result.set_world_from_base(&model.world_from_base());
    result.joint_errors = model.joint_errors.clone();
    result.frame_parameters = model.frame_parameters.clone();
    Ok(result)
}

/// The pose (world frame) of `link` at the zero configuration, through the model's last
/// frame before it; an error if a moving joint between that frame and the link is not part of
/// the model.
fn model_link_pose(tree: &KinematicTree, model: &McpcModel, link: LinkId) -> Result<Pose> {
    let (world_from_last, last_from_link) = last_frame_and_offset(tree, model, link)?;
    Ok(world_from_last * last_from_link)
}

/// The moved last model frame before `link` (world frame, zero configuration) and the link's
/// constant pose in it.
fn last_frame_and_offset(
    tree: &KinematicTree,
    model: &McpcModel,
    link: LinkId,
) -> Result<(Pose, Pose)> {
    let q0 = tree.zero_configuration();
    let root_from_link = tree.link_pose(link, &q0)?;
    let path = tree.path_from_root(link);
    let last_movable = path.iter().rposition(|&j| tree.joint(j).kind.is_movable());
    let Some(at) = last_movable else {
        return Ok((model.world_from_base(), root_from_link));
    };
    let joint = path[at];
    let Some(frame) = model.frame_of_joint(joint) else {
        return Err(invalid(format!(
            "link '{}' is moved by joint '{}', which is not on a calibrated branch; name a link \
             beyond it as a tool (`tools`) so that the joint is calibrated",
            tree.link(link).name,
            tree.joint(joint).name
        )));
    };
    // The joint's child link, and the constant chain of fixed joints from it to `link`.
    let child = tree.joint(joint).child;
    let child_from_link = tree.link_pose(child, &q0)?.inverse() * root_from_link;
    let transforms = model.frame_transforms(&q0);
    let world_from_last = model.moved(frame, &q0, &transforms[frame]).to_pose();
    let last_from_link = model.frames()[frame].frame_from_link * child_from_link;
    Ok((world_from_last, last_from_link))
}

/// An MCPC tool at `mount_from_frame` on `mount`.
fn mounted_tool(
    tree: &KinematicTree,
    model: &McpcModel,
    mount: Mount,
    mount_from_frame: &Pose,
) -> Result<McpcTool> {
    match mount {
        Mount::World => Ok(McpcTool::from_relative_pose(
            tree.root(),
            None,
            0.0,
            &(model.world_from_base().inverse() * mount_from_frame),
        )),
        Mount::Link(link) => {
            let (_, last_from_link) = last_frame_and_offset(tree, model, link)?;
            let path = tree.path_from_root(link);
            let parent = path
                .iter()
                .rev()
                .find(|&&j| tree.joint(j).kind.is_movable())
                .and_then(|&j| model.frame_of_joint(j));
            let twist = parent.map_or(0.0, |f| model.frames()[f].twist);
            Ok(McpcTool::from_relative_pose(
                link,
                parent,
                twist,
                &(last_from_link * mount_from_frame),
            ))
        }
    }
}

fn invalid(message: String) -> Error {
    Error::InvalidData {
        origin: "camera set-up".into(),
        message,
    }
}
