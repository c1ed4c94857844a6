//! The pinhole camera with Brown–Conrady distortion (OpenCV's five-coefficient model):
//! projection of a point in the camera frame to pixels, and its analytic Jacobians with
//! respect to the point and to the intrinsics. See `docs/camera.md`.
//!
//! ```text
//! x = X/Z, y = Y/Z, r² = x² + y², radial = 1 + k1·r² + k2·r⁴ + k3·r⁶
//! x_d = x·radial + 2·p1·x·y + p2·(r² + 2x²)
//! y_d = y·radial + p1·(r² + 2y²) + 2·p2·x·y
//! u = fx·x_d + cx,  v = fy·y_d + cy
//! ```
//!
//! The camera frame is OpenCV's: z along the optical axis (forward), x right, y down in the
//! image; pixel (0, 0) is the top-left corner of the top-left pixel.

use crate::math::Vec3;
use nalgebra::{Matrix2x3, SMatrix, Vector2};

/// Number of intrinsic parameters: fx, fy, cx, cy, k1, k2, p1, p2, k3.
pub const INTRINSIC_COUNT: usize = 9;

/// Names of the intrinsic parameters, in [`Intrinsics::to_vector`] order.
pub const INTRINSIC_NAMES: [&str; INTRINSIC_COUNT] =
    ["fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3"];

/// Points closer to the image plane than this (m, along the optical axis) are rejected as
/// behind the camera: their projection is numerically meaningless.
pub const MIN_DEPTH: f64 = 1e-3;

/// The intrinsics of one camera (pixels; distortion coefficients dimensionless) and its image
/// size.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Intrinsics {
    /// Focal length along x (px).
    pub fx: f64,
    /// Focal length along y (px).
    pub fy: f64,
    /// Principal point x (px).
    pub cx: f64,
    /// Principal point y (px).
    pub cy: f64,
    /// Radial distortion k1, k2, k3 and tangential p1, p2 (OpenCV's order: k1, k2, p1, p2, k3).
    pub distortion: [f64; 5],
    /// Image width (px).
    pub width: f64,
    /// Image height (px).
    pub height: f64,
}

/// Why a point has no pixel in an image.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Rejection {
    /// The point is behind the camera (or within [`MIN_DEPTH`] of its centre plane).
    BehindCamera,
    /// The point projects outside the image.
    OutsideImage,
    /// The point lies where the distortion polynomial folds back (the radial map stops
    /// increasing): the model does not describe that part of the field of view.
    BeyondDistortionRange,
    /// The board faces away from the camera (its corners would be seen from behind).
    FacingAway,
}

impl Rejection {
    /// The reason in words.
    pub fn describe(self) -> &'static str {
        match self {
            Rejection::BehindCamera => "behind the camera",
            Rejection::OutsideImage => "outside the image",
            Rejection::BeyondDistortionRange => "beyond the range of the distortion model",
            Rejection::FacingAway => "on a board facing away from the camera",
        }
    }
}

/// A projected point with its Jacobians.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Projection {
    /// The pixel (u, v).
    pub pixel: Vector2<f64>,
    /// ∂(u, v)/∂(X, Y, Z) (px/m), the point in the camera frame.
    pub wrt_point: Matrix2x3<f64>,
    /// ∂(u, v)/∂(fx, fy, cx, cy, k1, k2, p1, p2, k3).
    pub wrt_intrinsics: SMatrix<f64, 2, INTRINSIC_COUNT>,
}

impl Intrinsics {
    /// A camera of `width` × `height` px with horizontal field of view `fov` (rad), square
    /// pixels, the principal point at the image centre and no distortion.
    pub fn ideal(width: f64, height: f64, fov: f64) -> Self {
        let f = 0.5 * width / (0.5 * fov).tan();
        Self {
            fx: f,
            fy: f,
            cx: 0.5 * width,
            cy: 0.5 * height,
            distortion: [0.0; 5],
            width,
            height,
        }
    }

    /// fx, fy, cx, cy, k1, k2, p1, p2, k3.
    pub fn to_vector(&self) -> [f64; INTRINSIC_COUNT] {
        let [k1, k2, p1, p2, k3] = self.distortion;
        [self.fx, self.fy, self.cx, self.cy, k1, k2, p1, p2, k3]
    }

    /// The same camera with the intrinsics of `values` ([`Self::to_vector`] order).
    pub fn with_vector(&self, values: &[f64; INTRINSIC_COUNT]) -> Self {
        let [fx, fy, cx, cy, k1, k2, p1, p2, k3] = *values;
        Self {
            fx,
            fy,
            cx,
            cy,
            distortion: [k1, k2, p1, p2, k3],
            ..*self
        }
    }

    /// What is wrong with these intrinsics, if anything (for readers: the message names the
    /// field).
    pub fn problem(&self) -> Option<String> {
        let values = self.to_vector();
        if let Some(k) = values.iter().position(|v| !v.is_finite()) {
            return Some(format!("{} is not a finite number", INTRINSIC_NAMES[k]));
        }
        if !(self.fx > 0.0 && self.fy > 0.0) {
            return Some("fx and fy must be positive (px)".into());
        }
        if !(self.width >= 1.0 && self.height >= 1.0 && self.width.is_finite()) {
            return Some("the image size must be at least 1 × 1 px".into());
        }
        if !self.height.is_finite() {
            return Some("the image height is not a finite number".into());
        }
        None
    }

    /// The pixel of point `point` (m, camera frame), or why it has none.
    pub fn pixel(&self, point: &Vec3) -> Result<Vector2<f64>, Rejection> {
        self.project(point).map(|p| p.pixel)
    }

    /// The pixel of `point` (m, camera frame) with its Jacobians, or why it has none: behind
    /// the camera, beyond the distortion model's monotonic range, or outside the image.
    pub fn project(&self, point: &Vec3) -> Result<Projection, Rejection> {
        let projection = self.project_unbounded(point)?;
        let pixel = projection.pixel;
        if !(pixel.x >= 0.0 && pixel.x <= self.width && pixel.y >= 0.0 && pixel.y <= self.height) {
            return Err(Rejection::OutsideImage);
        }
        Ok(projection)
    }

    /// [`Self::project`] without the image bounds: what a fit needs while its estimate of a
    /// detected corner strays past the image edge.
    pub fn project_unbounded(&self, point: &Vec3) -> Result<Projection, Rejection> {
        // Written so that NaN depths are rejected too.
        if point.z.is_nan() || point.z < MIN_DEPTH {
            return Err(Rejection::BehindCamera);
        }
        let [k1, k2, p1, p2, k3] = self.distortion;
        let (x, y) = (point.x / point.z, point.y / point.z);
        let r2 = x * x + y * y;
        let radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
        // d(radial)/d(r²).
        let slope = k1 + r2 * (2.0 * k2 + 3.0 * r2 * k3);
        // r·radial must still grow with r: d(r·radial)/dr = radial + 2r²·slope.
        let monotonic = radial > 0.0 && radial + 2.0 * r2 * slope > 0.0;
        if !monotonic {
            return Err(Rejection::BeyondDistortionRange);
        }
        let xd = x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x);
        let yd = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y;
        let pixel = Vector2::new(self.fx * xd + self.cx, self.fy * yd + self.cy);
        // ∂(x_d, y_d)/∂(x, y).
        let dxd_dx = radial + 2.0 * x * x * slope + 2.0 * p1 * y + 6.0 * p2 * x;
        let dxd_dy = 2.0 * x * y * slope + 2.0 * p1 * x + 2.0 * p2 * y;
        let dyd_dx = 2.0 * x * y * slope + 2.0 * p1 * x + 2.0 * p2 * y;
        let dyd_dy = radial + 2.0 * y * y * slope + 6.0 * p1 * y + 2.0 * p2 * x;
        // ∂(x, y)/∂(X, Y, Z).
        let inverse = 1.0 / point.z;
        let normalised = Matrix2x3::new(inverse, 0.0, -x * inverse, 0.0, inverse, -y * inverse);
        let distorted = nalgebra::Matrix2::new(
            self.fx * dxd_dx,
            self.fx * dxd_dy,
            self.fy * dyd_dx,
            self.fy * dyd_dy,
        );
        let wrt_point = distorted * normalised;
        let (r4, r6) = (r2 * r2, r2 * r2 * r2);
        #[rustfmt::skip]
        let wrt_intrinsics = SMatrix::<f64, 2, INTRINSIC_COUNT>::from_row_slice(&[
            xd, 0.0, 1.0, 0.0, self.fx * x * r2, self.fx * x * r4, self.fx * 2.0 * x * y,
            self.fx * (r2 + 2.0 * x * x), self.fx * x * r6,
            0.0, yd, 0.0, 1.0, self.fy * y * r2, self.fy * y * r4, self.fy * (r2 + 2.0 * y * y),
            self.fy * 2.0 * x * y, self.fy * y * r6,
        ]);
        Ok(Projection {
            pixel,
            wrt_point,
            wrt_intrinsics,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn camera() -> Intrinsics {
        Intrinsics {
            fx: 525.0,
            fy: 530.0,
            cx: 319.5,
            cy: 241.0,
            distortion: [-0.21, 0.08, 1.2e-3, -8e-4, -0.01],
            width: 640.0,
            height: 480.0,
        }
    }

    #[test]
    fn jacobians_match_finite_differences() {
        let camera = camera();
        for point in [
            Vec3::new(0.05, -0.03, 0.6),
            Vec3::new(-0.2, 0.15, 0.9),
            Vec3::new(0.3, 0.2, 1.1),
        ] {
            let p = camera.project(&point).unwrap();
            let h = 1e-7;
            for k in 0..3 {
                let mut shifted = point;
                shifted[k] += h;
                let moved = camera.project(&shifted).unwrap().pixel;
                let numeric = (moved - p.pixel) / h;
                let analytic = p.wrt_point.column(k);
                assert!((numeric - analytic).norm() < 1e-4 * (1.0 + analytic.norm()));
            }
            let values = camera.to_vector();
            for k in 0..INTRINSIC_COUNT {
                let mut shifted = values;
                shifted[k] += h;
                let moved = camera.with_vector(&shifted).project(&point).unwrap().pixel;
                let numeric = (moved - p.pixel) / h;
                let analytic = p.wrt_intrinsics.column(k);
                assert!(
                    (numeric - analytic).norm() < 1e-4 * (1.0 + analytic.norm()),
                    "{k}: {numeric} {analytic}"
                );
            }
        }
    }

    #[test]
    fn rejections_are_named() {
        let camera = camera();
        assert_eq!(
            camera.project(&Vec3::new(0.0, 0.0, -1.0)),
            Err(Rejection::BehindCamera)
        );
        assert_eq!(
            camera.project(&Vec3::new(0.0, 0.0, f64::NAN)),
            Err(Rejection::BehindCamera)
        );
        assert_eq!(
            camera.project(&Vec3::new(0.8, 0.0, 1.0)),
            Err(Rejection::OutsideImage)
        );
        // Far off-axis, k1 < 0 folds the image back towards the centre.
        assert_eq!(
            camera.project(&Vec3::new(3.0, 0.0, 1.0)),
            Err(Rejection::BeyondDistortionRange)
        );
        assert!(camera.project(&Vec3::new(0.0, 0.0, 1.0)).is_ok());
    }
}
