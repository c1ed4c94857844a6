//! The camera observation: the pixels of a target's points seen by a camera at one
//! configuration, predicted from the camera's and the target's poses, with the Jacobian of
//! those pixels with respect to the model parameters (through both poses' identification
//! Jacobians) and to the intrinsics. See `docs/camera.md`.
//!
//! With the camera pose `(R_c, t_c)`, the target's tool pose `(R_t, t_t)` and a point `w` of
//! the target in the world, the point in the camera frame is `p_c = R_cᵀ·(w − t_c)`. Small
//! changes of the two poses (translation `δt`, rotation `δθ` in the world frame, the
//! convention of [`crate::kinematics::ToolJacobian`]) move it by
//!
//! ```text
//! δp_c = R_cᵀ·( δt_t − [w − t_t]×·δθ_t − δt_c + [w − t_c]×·δθ_c )
//! ```
//!
//! and the pixel by `∂(u, v)/∂p_c · δp_c`.

use super::model::{Intrinsics, Rejection, INTRINSIC_COUNT};
use super::rig::Rig;
use crate::kinematics::ToolJacobian;
use crate::math::{skew, Mat3, Pose, Vec3};
use nalgebra::{DMatrix, Vector2};

/// One image of one target: the detected points (index into the target's points, pixel).
#[derive(Debug, Clone, PartialEq)]
pub struct View {
    /// The detections' `id` of the image (for findings and reports).
    pub id: String,
    /// The configuration (one value per independent joint).
    pub q: Vec<f64>,
    /// Index of the camera in [`Rig::cameras`].
    pub camera: usize,
    /// Index of the target in [`Rig::targets`].
    pub target: usize,
    /// The detected points: point index and pixel (u, v).
    pub points: Vec<(usize, Vector2<f64>)>,
}

/// The predicted pixels of one view with their Jacobians.
#[derive(Debug, Clone)]
pub struct ViewPrediction {
    /// Per detected point (in [`View::points`] order): the pixel, or why it has none.
    pub pixels: Vec<Result<Vector2<f64>, Rejection>>,
    /// 2 rows per point (u, v) × the model's parameters (zero rows for rejected points).
    pub wrt_model: DMatrix<f64>,
    /// 2 rows per point × the camera's nine intrinsics.
    pub wrt_intrinsics: DMatrix<f64>,
}

/// The world point of target point `point` of `view` and the camera-frame point, from the
/// camera and target tool poses.
fn points(rig: &Rig, view: &View, camera: &Pose, tool: &Pose, point: &Vec3) -> (Vec3, Vec3) {
    let target = &rig.targets[view.target];
    let world = tool * (target.tool_from_target * nalgebra::Point3::from(*point));
    let in_camera = camera.inverse_transform_point(&world);
    (world.coords, in_camera.coords)
}

/// The pixels of `view` predicted from the camera and target tool poses `poses` (all tools
/// of the augmented model at the view's configuration) and the camera's `intrinsics`; the
/// image bounds are checked when `bounded` (simulation, visibility), not when fitting.
pub fn predict_pixels(
    rig: &Rig,
    view: &View,
    poses: &[Pose],
    intrinsics: &Intrinsics,
    bounded: bool,
) -> Vec<Result<Vector2<f64>, Rejection>> {
    let (camera_tool, target) = (rig.cameras[view.camera].tool, &rig.targets[view.target]);
    view.points
        .iter()
        .map(|&(index, _)| {
            let point = target.shape.point(index).unwrap_or_else(Vec3::zeros);
            let (_, p) = points(rig, view, &poses[camera_tool], &poses[target.tool], &point);
            let projected = if bounded {
                intrinsics.project(&p)
            } else {
                intrinsics.project_unbounded(&p)
            };
            projected.map(|p| p.pixel)
        })
        .collect()
}

/// The predicted pixels of `view` and their Jacobians, from the tool poses and
/// identification Jacobians `tools` of the augmented model at the view's configuration.
pub fn linearise_view(
    rig: &Rig,
    view: &View,
    tools: &[ToolJacobian],
    intrinsics: &Intrinsics,
) -> ViewPrediction {
    let (camera_tool, target) = (rig.cameras[view.camera].tool, &rig.targets[view.target]);
    let (camera, carrier) = (&tools[camera_tool], &tools[target.tool]);
    let parameters = camera.jacobian.ncols();
    let rows = 2 * view.points.len();
    let mut wrt_model = DMatrix::zeros(rows, parameters);
    let mut wrt_intrinsics = DMatrix::zeros(rows, INTRINSIC_COUNT);
    let mut pixels = Vec::with_capacity(view.points.len());
    let camera_rotation: Mat3 = *camera.pose.rotation.to_rotation_matrix().matrix();
    let (t_c, t_t) = (
        camera.pose.translation.vector,
        carrier.pose.translation.vector,
    );
    for (k, &(index, _)) in view.points.iter().enumerate() {
        let point = target.shape.point(index).unwrap_or_else(Vec3::zeros);
        let (world, in_camera) = points(rig, view, &camera.pose, &carrier.pose, &point);
        let projection = match intrinsics.project_unbounded(&in_camera) {
            Ok(p) => p,
            Err(reason) => {
                pixels.push(Err(reason));
                continue;
            }
        };
        pixels.push(Ok(projection.pixel));
        // ∂p_c/∂(δt, δθ) of the target tool and of the camera tool (3 × 6 each).
        let rt = camera_rotation.transpose();
        let mut wrt_target = nalgebra::SMatrix::<f64, 3, 6>::zeros();
        wrt_target.fixed_view_mut::<3, 3>(0, 0).copy_from(&rt);
        wrt_target
            .fixed_view_mut::<3, 3>(0, 3)
            .copy_from(&(-rt * skew(&(world - t_t))));
        let mut wrt_camera = nalgebra::SMatrix::<f64, 3, 6>::zeros();
        wrt_camera.fixed_view_mut::<3, 3>(0, 0).copy_from(&(-rt));
        wrt_camera
            .fixed_view_mut::<3, 3>(0, 3)
            .copy_from(&(rt * skew(&(world - t_c))));
        let from_target = projection.wrt_point * wrt_target;
        let from_camera = projection.wrt_point * wrt_camera;
        let rows = wrt_model.rows_mut(2 * k, 2);
        let mut rows = rows;
        rows.copy_from(&(from_target * &carrier.jacobian));
        rows += from_camera * &camera.jacobian;
        wrt_intrinsics
            .rows_mut(2 * k, 2)
            .copy_from(&projection.wrt_intrinsics);
    }
    ViewPrediction {
        pixels,
        wrt_model,
        wrt_intrinsics,
    }
}
