//! Which targets a camera sees at a configuration, by the rules a planner must respect
//! (`plan --camera`, docs/camera.md section 7): every point of the target has a pixel (in front
//! of the camera, within the distortion model's range, inside the image), a board faces the
//! camera within [`VisibilityRules::max_view_angle`], and no line of sight from the camera's
//! centre to a point crosses another link's collision shape.

use super::collision::CollisionChecker;
use crate::camera::{predict_pixels, Rejection, Rig, View};
use crate::error::Result;
use crate::kinematics::McpcModel;
use crate::math::{Pose, Vec3};
use crate::tree::{KinematicTree, LinkId};
use nalgebra::Vector2;

/// The rules of `visible_views`.
#[derive(Debug, Clone, PartialEq)]
pub struct VisibilityRules {
    /// A board is seen when the angle between its face normal and the direction to the
    /// camera is at most this (rad); 60° by default (corner detectors fail beyond ~60–70°).
    pub max_view_angle: f64,
    /// The last part of a line of sight (m) not checked for occlusion, so that a point on a
    /// surface does not hide itself.
    pub clearance: f64,
}

impl Default for VisibilityRules {
    fn default() -> Self {
        Self {
            max_view_angle: 60f64.to_radians(),
            clearance: 0.005,
        }
    }
}

/// Why a target is not seen.
#[derive(Debug, Clone, PartialEq)]
pub enum Hidden {
    /// A point has no pixel.
    NoPixel {
        /// The target point.
        point: usize,
        /// Why.
        reason: Rejection,
    },
    /// The board turns away from the camera by more than the rule allows.
    FacingAway {
        /// The angle between its face normal and the direction to the camera (rad).
        angle: f64,
    },
    /// A line of sight crosses a link's collision shape.
    Occluded {
        /// The target point.
        point: usize,
        /// The link in the way.
        link: LinkId,
    },
}

/// What one configuration shows the cameras.
pub struct Sight<'a> {
    /// The cameras and targets.
    pub rig: &'a Rig,
    /// The rig's augmented model (camera and target frames from its kinematics).
    pub model: &'a McpcModel,
    /// The robot (its link poses for the occlusion test).
    pub tree: &'a KinematicTree,
    /// The robot's collision shapes; `None`: occlusion is not tested.
    pub checker: Option<&'a CollisionChecker>,
    /// The rules.
    pub rules: &'a VisibilityRules,
}

impl Sight<'_> {
    /// Every (camera, target) pair seen at `q`, with its exact pixels, in rig order.
    pub fn visible_views(&self, q: &[f64]) -> Result<Vec<View>> {
        let tools = self.model.tool_poses(q);
        let links = self.tree.link_poses(q)?;
        let mut views = Vec::new();
        for camera in 0..self.rig.cameras.len() {
            for target in 0..self.rig.targets.len() {
                if let Ok(view) = self.view(q, camera, target, &tools, &links) {
                    views.push(view);
                }
            }
        }
        Ok(views)
    }

    /// Whether `camera` sees `target` at `q`: its view, or why not (an error only for a
    /// configuration that does not fit the robot).
    pub fn check(
        &self,
        q: &[f64],
        camera: usize,
        target: usize,
    ) -> Result<std::result::Result<View, Hidden>> {
        let tools = self.model.tool_poses(q);
        let links = self.tree.link_poses(q)?;
        Ok(self.view(q, camera, target, &tools, &links))
    }

    fn view(
        &self,
        q: &[f64],
        camera: usize,
        target: usize,
        tools: &[Pose],
        links: &[Pose],
    ) -> std::result::Result<View, Hidden> {
        let rig_camera = &self.rig.cameras[camera];
        let rig_target = &self.rig.targets[target];
        // Root frame: the model's world frame without its registration.
        let root = self.model.world_from_base().inverse();
        let camera_pose = root * tools[rig_camera.tool];
        let board = root * tools[rig_target.tool] * rig_target.tool_from_target;
        if rig_target.shape.has_face() {
            let to_camera = (camera_pose.translation.vector - board.translation.vector).normalize();
            let face = board.rotation * -Vec3::z();
            let angle = face.dot(&to_camera).clamp(-1.0, 1.0).acos();
            if angle.is_nan() || angle > self.rules.max_view_angle {
                return Err(Hidden::FacingAway { angle });
            }
        }
        let mut view = View {
            id: String::new(),
            q: q.to_vec(),
            camera,
            target,
            points: (0..rig_target.shape.point_count())
                .map(|k| (k, Vector2::zeros()))
                .collect(),
        };
        let pixels = predict_pixels(self.rig, &view, tools, &rig_camera.intrinsics, true);
        for ((point, pixel), p) in view.points.iter_mut().zip(pixels) {
            *pixel = p.map_err(|reason| Hidden::NoPixel {
                point: *point,
                reason,
            })?;
        }
        if let Some(checker) = self.checker {
            // The camera's and the target's carriers; a target in the world (an extra tool on
            // the root) has none.
            let target_link = self.model.tools()[rig_target.tool].link;
            let in_world =
                rig_target.tool >= self.rig.robot_tools && target_link == self.tree.root();
            let ignore: Vec<LinkId> = std::iter::once(self.model.tools()[rig_camera.tool].link)
                .chain((!in_world).then_some(target_link))
                .flat_map(|l| rigid_group(self.tree, l))
                .collect();
            let eye = camera_pose.translation.vector;
            for (point, _) in &view.points {
                let corner = rig_target.shape.point(*point).unwrap_or_else(Vec3::zeros);
                let at = board * nalgebra::Point3::from(corner);
                if let Some(link) =
                    checker.segment_blocked(links, &eye, &at.coords, &ignore, self.rules.clearance)
                {
                    return Err(Hidden::Occluded {
                        point: *point,
                        link,
                    });
                }
            }
        }
        Ok(view)
    }
}

/// `link` and every link joined to it by fixed joints only: one rigid body (a board's
/// carrier, a camera's housing), never in the way of its own lines of sight.
pub fn rigid_group(tree: &KinematicTree, link: LinkId) -> Vec<LinkId> {
    (0..tree.links().len())
        .map(LinkId)
        .filter(|&other| {
            tree.path_between(link, other)
                .iter()
                .all(|&j| !tree.joint(j).kind.is_movable())
        })
        .collect()
}
