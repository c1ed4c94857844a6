//! Judging a camera calibration from files ([`super::calibrate_camera`]): the pixel
//! residuals of the fit and of held-out images, and the verdict's findings on the fit (σ̂
//! overall and per kind of observation, iterations, points without a pixel, held-out images).

use crate::calibration::{Finding, Termination};
use crate::camera::{predict_pixels, CameraFitReport, Intrinsics, RejectedPoint, Rig, View};
use crate::report::{HeldOut, PixelResiduals, TargetResiduals};
use crate::McpcModel;
use std::path::Path;

/// σ̂ above which the pixel residuals are flagged (they are this many times the declared σ).
pub const PIXEL_SIGMA_WARNING: f64 = 3.0;

/// σ̂ above which the calibration fails: the model or the detections are wrong, not noisy.
pub const PIXEL_SIGMA_FAILED: f64 = 30.0;

/// Pixel residuals of `views` predicted by `model` and `intrinsics`: all, per target, and
/// the points without a pixel.
pub(super) fn pixel_residuals(
    rig: &Rig,
    views: &[View],
    model: &McpcModel,
    intrinsics: &[Intrinsics],
) -> (PixelResiduals, Vec<TargetResiduals>, Vec<RejectedPoint>) {
    let mut all = Vec::new();
    let mut per_target: Vec<Vec<f64>> = vec![Vec::new(); rig.targets.len()];
    let mut images = vec![0; rig.targets.len()];
    let mut rejected = Vec::new();
    for view in views {
        let poses = model.tool_poses(&view.q);
        let pixels = predict_pixels(rig, view, &poses, &intrinsics[view.camera], false);
        images[view.target] += 1;
        for (pixel, (point, measured)) in pixels.iter().zip(&view.points) {
            match pixel {
                Ok(p) => {
                    let d = (measured - p).norm();
                    all.push(d);
                    per_target[view.target].push(d);
                }
                Err(reason) => rejected.push(RejectedPoint {
                    view: view.id.clone(),
                    point: *point,
                    reason: *reason,
                }),
            }
        }
    }
    let targets = rig
        .targets
        .iter()
        .zip(per_target.iter().zip(&images))
        .filter(|(_, (_, n))| **n > 0)
        .map(|(t, (d, n))| TargetResiduals {
            target: t.name.clone(),
            residuals: statistics(d, *n),
        })
        .collect();
    (statistics(&all, views.len()), targets, rejected)
}

fn statistics(lengths: &[f64], images: usize) -> PixelResiduals {
    let n = lengths.len().max(1) as f64;
    PixelResiduals {
        images,
        points: lengths.len(),
        rms_px: (lengths.iter().map(|d| d * d).sum::<f64>() / n).sqrt(),
        mean_px: lengths.iter().sum::<f64>() / n,
        max_px: lengths.iter().copied().fold(0.0, f64::max),
    }
}

/// The held-out images before (`nominal`, the rig's augmented nominal model) and after
/// calibration.
pub(super) fn held_out(
    rig: &Rig,
    nominal: &McpcModel,
    views: &[View],
    path: &Path,
    fit: &CameraFitReport,
) -> HeldOut {
    let intrinsics: Vec<Intrinsics> = rig.cameras.iter().map(|c| c.intrinsics).collect();
    let (before, _, _) = pixel_residuals(rig, views, nominal, &intrinsics);
    let (after, _, rejected) = pixel_residuals(rig, views, &fit.model, &fit.intrinsics);
    HeldOut {
        file: path.display().to_string(),
        before,
        after,
        rejected,
    }
}

/// The verdict's findings on the fit itself (`pixel_sigma`: the declared one, px).
pub(super) fn verdict_findings(
    fit: &CameraFitReport,
    residuals: &PixelResiduals,
    held_out: Option<&HeldOut>,
    pixel_sigma: f64,
) -> Vec<Finding> {
    let mut findings = Vec::new();
    let scale = fit.residual_scale;
    let rms = format!("RMS pixel residual {:.3} px", residuals.rms_px);
    if !scale.is_finite() || scale > PIXEL_SIGMA_FAILED {
        findings.push(Finding::failed(
            "pixel-sigma-ratio",
            format!(
                "σ̂ = {scale:.3e}: the pixel residuals ({rms}) are far beyond any detector noise; \
                 typical causes: a wrong camera link or a nominal camera pose far off (fix \
                 `pose` in the camera file), a board's corner order or size unlike the camera \
                 file's, joint angles in degrees read as radians (`angle_unit`), images matched \
                 to the wrong configurations"
            ),
        ));
    } else if scale > PIXEL_SIGMA_WARNING {
        findings.push(Finding::warning(
            "pixel-sigma-ratio",
            format!(
                "σ̂ = {scale:.1}: the pixel residuals ({rms}) are {scale:.0}× the declared \
                 `pixel_sigma` {} px: the detector is noisier than declared (the standard \
                 deviations are scaled by σ̂), or the model misses something (flexibility, \
                 distortion: estimate the intrinsics with `estimate: [pose, intrinsics]`)",
                pixel_sigma
            ),
        ));
    }
    if fit.termination == Termination::MaxIterations {
        findings.push(Finding::warning(
            "camera-iterations",
            format!(
                "the fit stopped at its iteration limit ({}) before converging: check the \
                 nominal camera pose in the camera file",
                fit.iterations
            ),
        ));
    }
    if let Some(point) = fit.rejected.first() {
        findings.push(Finding::warning(
            "camera-rejected-points",
            format!(
                "{} detected point(s) were left out because the nominal robot and camera give \
                 them no pixel (first: image '{}', point {}: {}); check the camera's nominal \
                 pose and the target's link in the camera file",
                fit.rejected.len(),
                point.view,
                point.point,
                point.reason.describe()
            ),
        ));
    }
    if let Some(held) = held_out {
        if let Some(point) = held.rejected.first() {
            findings.push(Finding::warning(
                "held-out-rejected-points",
                format!(
                    "{} held-out point(s) have no pixel with the calibrated robot (first: image \
                     '{}', point {}: {})",
                    held.rejected.len(),
                    point.view,
                    point.point,
                    point.reason.describe()
                ),
            ));
        }
        let limit = 3.0 * residuals.rms_px.max(pixel_sigma);
        if held.after.points > 0 && held.after.rms_px > limit {
            findings.push(Finding::warning(
                "held-out-pixels",
                format!(
                    "the held-out images are predicted to {:.2} px RMS, more than 3× the fit's \
                     {:.2} px: the calibration does not carry over to other configurations \
                     (too few or too similar images, or a model error)",
                    held.after.rms_px, residuals.rms_px
                ),
            ));
        }
    }
    findings
}
