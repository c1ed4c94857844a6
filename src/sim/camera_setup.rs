//! The camera simulation's set-up, as Agile Justin's calibration was done: a camera on the
//! coupled branch's last link (or a given link), a board on each tool, and one board fixed in
//! the world in front of the robot. Where the camera looks and how each board sits on its tool
//! are chosen from the robot itself: the viewing direction that sees the tools most often over
//! random configurations, and the board orientation that faces the camera most often.

use super::collision::CollisionChecker;
use super::sampling::{sample_configurations, SamplingOptions};
use crate::camera::{CameraSpec, Intrinsics, Mount, Rig, TargetShape, TargetSpec};
use crate::error::Result;
use crate::kinematics::McpcModel;
use crate::math::{Pose, Rotation, Vec3};
use crate::tree::{Branches, KinematicTree, LinkId};
use nalgebra::{Matrix3, Rotation3, Translation3};
use rand::rngs::ChaCha8Rng;
use rand::SeedableRng;

/// The physical set-up of a camera simulation.
#[derive(Debug, Clone, PartialEq)]
pub struct CameraRigOptions {
    /// The camera's link (`None`: the coupled branch's last link).
    pub camera_link: Option<LinkId>,
    /// How far above the link's origin the camera sits, along the world's z (m): a head.
    pub camera_height: f64,
    /// The camera's intrinsics.
    pub intrinsics: Intrinsics,
    /// The board on each tool.
    pub tool_board: TargetShape,
    /// The board in the world (`None`: no world board).
    pub world_board: Option<TargetShape>,
    /// Distance of the world board from the camera along its optical axis at the zero
    /// configuration (m).
    pub world_board_distance: f64,
    /// Whether the world board's pose is estimated (else known in the root frame).
    pub estimate_world_board: bool,
    /// Whether the intrinsics are estimated.
    pub estimate_intrinsics: bool,
    /// Largest angle between a board's face normal and the direction to the camera at which
    /// it is detected (rad).
    pub max_view_angle: f64,
    /// Smallest share of a board's corners in the image for the board to be detected (only
    /// those corners are): 1 asks for whole boards; below it, boards are detected in part as
    /// ChArUco boards are.
    pub min_detected_fraction: f64,
}

impl Default for CameraRigOptions {
    fn default() -> Self {
        Self {
            camera_link: None,
            camera_height: 0.2,
            // A 640 × 480 camera with a 62° horizontal field of view (fx ≈ 533 px) and the
            // mild barrel distortion of a typical RGB-D colour camera.
            intrinsics: Intrinsics {
                distortion: [0.05, -0.1, 0.0, 0.0, 0.0],
                ..Intrinsics::ideal(640.0, 480.0, 62f64.to_radians())
            },
            tool_board: TargetShape::Board {
                rows: 5,
                columns: 7,
                spacing: 0.025,
            },
            world_board: Some(TargetShape::Board {
                rows: 7,
                columns: 10,
                spacing: 0.06,
            }),
            world_board_distance: 0.8,
            estimate_world_board: false,
            estimate_intrinsics: false,
            max_view_angle: 60f64.to_radians(),
            min_detected_fraction: 0.5,
        }
    }
}

/// Configurations drawn to choose the viewing direction and the board orientations.
const SURVEY_CONFIGURATIONS: usize = 200;

/// Candidate directions (viewing directions, board normals).
const DIRECTIONS: usize = 200;

/// The rig of the camera simulation on `nominal` (the model of `tree`, `branches`) and the
/// augmented nominal model. `seed` seeds the survey configurations.
pub fn camera_rig(
    tree: &KinematicTree,
    branches: &Branches,
    nominal: &McpcModel,
    checker: Option<&CollisionChecker>,
    options: &CameraRigOptions,
    seed: u64,
) -> Result<(Rig, McpcModel)> {
    let (cameras, targets) = camera_specs(tree, branches, nominal, checker, options, seed)?;
    Rig::build(tree, nominal, &cameras, &targets)
}

/// The camera and targets of [`camera_rig`] as a user would describe them (a camera file,
/// `crate::io::camera_yaml`).
pub fn camera_specs(
    tree: &KinematicTree,
    branches: &Branches,
    nominal: &McpcModel,
    checker: Option<&CollisionChecker>,
    options: &CameraRigOptions,
    seed: u64,
) -> Result<(Vec<CameraSpec>, Vec<TargetSpec>)> {
    let link = options.camera_link.unwrap_or(branches.divergence);
    let survey = Survey::new(tree, nominal, checker, options, link, seed)?;
    let look = survey.best_look(nominal);
    let link_from_camera = looking(
        survey.eye_in_link.coords,
        look,
        survey.world_from_link.rotation.inverse() * -Vec3::z(),
    );
    let world_from_camera = survey.world_from_link * link_from_camera;
    let mut targets = Vec::new();
    for (tool, spec) in nominal.tools().iter().enumerate() {
        if spec.link != link {
            targets.push(tool_board(tree, nominal, &survey, options, look, tool)?);
        }
    }
    if let Some(board) = &options.world_board {
        targets.push(world_board(board, survey.eye, &world_from_camera, options));
    }
    let camera = CameraSpec {
        name: "head".into(),
        mount: Mount::Link(link),
        mount_from_camera: link_from_camera,
        intrinsics: options.intrinsics,
        estimate_pose: true,
        estimate_intrinsics: options.estimate_intrinsics,
    };
    Ok((vec![camera], targets))
}

/// Where the camera sits on its link and where the tools go over random configurations, in
/// the camera link's frame (the camera moves with it).
struct Survey {
    /// The camera's link.
    link: LinkId,
    /// The link's pose at the zero configuration.
    world_from_link: Pose,
    /// The camera's position at the zero configuration (world frame).
    eye: Vec3,
    /// The camera's position in the link's frame.
    eye_in_link: nalgebra::Point3<f64>,
    /// Half the camera's narrower field of view (rad).
    half_fov: f64,
    /// Per survey configuration, each tool's pose in the link's frame.
    tools: Vec<Vec<(usize, Pose)>>,
}

impl Survey {
    /// The camera [`CameraRigOptions::camera_height`] above `link` and the tools over
    /// [`SURVEY_CONFIGURATIONS`] configurations drawn with `seed`.
    fn new(
        tree: &KinematicTree,
        nominal: &McpcModel,
        checker: Option<&CollisionChecker>,
        options: &CameraRigOptions,
        link: LinkId,
        seed: u64,
    ) -> Result<Self> {
        let q0 = tree.zero_configuration();
        let world_from_link = nominal.world_from_base() * tree.link_pose(link, &q0)?;
        let eye = world_from_link.translation.vector + Vec3::z() * options.camera_height;
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let survey = sample_configurations(
            tree,
            checker,
            SURVEY_CONFIGURATIONS,
            &mut rng,
            &SamplingOptions::default(),
            &[],
        )?;
        let tools: Vec<Vec<(usize, Pose)>> = survey
            .iter()
            .map(|q| {
                let link_from_world =
                    (nominal.world_from_base() * tree.link_pose(link, q)?).inverse();
                Ok(nominal
                    .tool_poses(q)
                    .into_iter()
                    .enumerate()
                    .map(|(t, p)| (t, link_from_world * p))
                    .collect())
            })
            .collect::<Result<_>>()?;
        let eye_in_link = world_from_link.inverse() * nalgebra::Point3::from(eye);
        let half_fov = (0.5 * options.intrinsics.width / options.intrinsics.fx)
            .atan()
            .min((0.5 * options.intrinsics.height / options.intrinsics.fy).atan());
        Ok(Self {
            link,
            world_from_link,
            eye,
            eye_in_link,
            half_fov,
            tools,
        })
    }

    /// Whether a tool at `tool` (link frame) is in view of the camera looking along
    /// `direction`: far enough, and well inside the field of view.
    fn seen(&self, direction: &Vec3, tool: &Pose) -> bool {
        let d = tool.translation.vector - self.eye_in_link.coords;
        d.norm() > 0.25 && d.normalize().dot(direction) > (0.8 * self.half_fov).cos()
    }

    /// The direction that sees the least-seen tool most often (then the most tools).
    fn best_look(&self, nominal: &McpcModel) -> Vec3 {
        best_direction(|direction| {
            let mut counts = vec![0; nominal.tools().len()];
            for (tool, pose) in self.tools.iter().flatten() {
                if self.seen(direction, pose) {
                    counts[*tool] += 1;
                }
            }
            // A tool that carries the camera (a head named as a tool so that its neck is
            // calibrated) is never in view of it.
            for (tool, spec) in nominal.tools().iter().enumerate() {
                if spec.link == self.link {
                    counts[tool] = usize::MAX / 4;
                }
            }
            let least = counts.iter().copied().min().unwrap_or(0);
            least * (SURVEY_CONFIGURATIONS * counts.len() + 1) + counts.iter().sum::<usize>()
        })
    }
}

/// The board on `tool`, its face normal (−z of the board) along the tool-frame direction that
/// faces the camera (looking along `look`) most often over the survey, centred on the tool.
fn tool_board(
    tree: &KinematicTree,
    nominal: &McpcModel,
    survey: &Survey,
    options: &CameraRigOptions,
    look: Vec3,
    tool: usize,
) -> Result<TargetSpec> {
    let spec = &nominal.tools()[tool];
    let cos_max = options.max_view_angle.cos();
    let facing = best_direction(|normal| {
        survey
            .tools
            .iter()
            .flatten()
            .filter(|(t, p)| *t == tool && survey.seen(&look, p))
            .filter(|(_, p)| {
                let to_camera = (survey.eye_in_link.coords - p.translation.vector).normalize();
                (p.rotation * normal).dot(&to_camera) > cos_max
            })
            .count()
    });
    let centre = options.tool_board.centre();
    let rotation = looking(Vec3::zeros(), -facing, Vec3::z()).rotation;
    let tool_from_board = Pose::from_parts(Translation3::from(-(rotation * centre)), rotation);
    let q0 = tree.zero_configuration();
    let link_from_tool = tree.link_pose(spec.link, &q0)?.inverse()
        * nominal.world_from_base().inverse()
        * nominal.tool_pose(tool, &q0);
    Ok(TargetSpec {
        name: format!("{}_board", tree.link(spec.link).name),
        mount: Mount::Link(spec.link),
        mount_from_target: link_from_tool * tool_from_board,
        shape: options.tool_board.clone(),
        estimate_pose: true,
    })
}

/// The world board: on the camera's optical axis from `eye`, facing the camera, its centre on
/// the axis [`CameraRigOptions::world_board_distance`] away.
fn world_board(
    board: &TargetShape,
    eye: Vec3,
    world_from_camera: &Pose,
    options: &CameraRigOptions,
) -> TargetSpec {
    let camera_axis = world_from_camera.rotation * Vec3::z();
    let centre = eye + camera_axis * options.world_board_distance;
    let facing = looking(
        Vec3::zeros(),
        camera_axis,
        world_from_camera.rotation * -Vec3::y(),
    );
    let world_from_board = Pose::from_parts(
        Translation3::from(centre - facing.rotation * board.centre()),
        facing.rotation,
    );
    TargetSpec {
        name: "world_board".into(),
        mount: Mount::World,
        mount_from_target: world_from_board,
        shape: board.clone(),
        estimate_pose: options.estimate_world_board,
    }
}

/// The unit direction (of [`DIRECTIONS`] spread evenly over the sphere) with the highest
/// score; the first of equals.
fn best_direction(score: impl Fn(&Vec3) -> usize) -> Vec3 {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    (0..DIRECTIONS)
        .map(|k| {
            let z = 1.0 - 2.0 * (k as f64 + 0.5) / DIRECTIONS as f64;
            let r = (1.0 - z * z).sqrt();
            let a = golden * k as f64;
            Vec3::new(r * a.cos(), r * a.sin(), z)
        })
        .fold((Vec3::z(), 0), |(best, most), d| {
            let s = score(&d);
            if s > most {
                (d, s)
            } else {
                (best, most)
            }
        })
        .0
}

/// A frame at `origin` whose z looks along `forward` and whose y points as close to `down` as
/// it can (OpenCV's camera frame: x right, y down).
fn looking(origin: Vec3, forward: Vec3, down: Vec3) -> Pose {
    let z = forward.normalize();
    let mut y = down - z * z.dot(&down);
    if y.norm() < 1e-6 {
        // Looking straight along `down`: any perpendicular will do.
        y = z.cross(&Vec3::x());
        if y.norm() < 1e-6 {
            y = z.cross(&Vec3::y());
        }
    }
    let y = y.normalize();
    let x = y.cross(&z);
    let rotation = Rotation3::from_matrix_unchecked(Matrix3::from_columns(&[x, y, z]));
    Pose::from_parts(
        Translation3::from(origin),
        Rotation::from_rotation_matrix(&rotation),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn looking_frames_are_right_handed() {
        let pose = looking(Vec3::zeros(), Vec3::new(1.0, 0.0, 0.0), -Vec3::z());
        assert!((pose.rotation * Vec3::z() - Vec3::x()).norm() < 1e-12);
        assert!((pose.rotation * Vec3::y() + Vec3::z()).norm() < 1e-12);
        let straight = looking(Vec3::zeros(), -Vec3::z(), -Vec3::z());
        assert!((straight.rotation * Vec3::z() + Vec3::z()).norm() < 1e-12);
    }
}
