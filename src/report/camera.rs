//! The report of `calibrate --camera` (report.json and report.md): the fit in pixels, the
//! held-out images in pixels, what the images cannot determine said in words, the fitted
//! camera extrinsics and intrinsics, the robot's parameters and the verdict.

use crate::calibration::{Termination, Verdict};
use crate::camera::{CameraIdentifiability, KindScale, RejectedPoint};
use serde::Serialize;

/// Pixel residuals (measured − predicted) of a set of images.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct PixelResiduals {
    /// Images (one target seen by one camera at one configuration).
    pub images: usize,
    /// Detected points with a predicted pixel.
    pub points: usize,
    /// RMS of the residual's length (px).
    pub rms_px: f64,
    /// Mean of the residual's length (px).
    pub mean_px: f64,
    /// Largest residual length (px).
    pub max_px: f64,
}

/// The residuals of one target's images.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TargetResiduals {
    /// The target's name (the camera file's).
    pub target: String,
    /// Its residuals at the solution.
    pub residuals: PixelResiduals,
}

/// The held-out images, predicted by the nominal and by the calibrated robot and cameras.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct HeldOut {
    /// The held-out detections file.
    pub file: String,
    /// Residuals with the nominal robot and camera file.
    pub before: PixelResiduals,
    /// Residuals with the calibrated ones.
    pub after: PixelResiduals,
    /// Held-out points without a predicted pixel (after calibration), and why.
    pub rejected: Vec<RejectedPoint>,
}

/// How the fit went.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CameraFitSummary {
    /// Accepted iterations.
    pub iterations: usize,
    /// Why it stopped.
    pub termination: Termination,
    /// Residual rows (two per detected point).
    pub rows: usize,
    /// Unknowns fitted (robot, camera and target poses, intrinsics).
    pub unknowns: usize,
    /// Numerical rank.
    pub rank: usize,
    /// `σ̂`: the RMS weighted residual per degree of freedom (1 when the pixel noise is the
    /// declared `--pixel-sigma`).
    pub residual_scale: f64,
    /// The declared pixel σ (px).
    pub pixel_sigma: f64,
}

/// The tracker's frame as fitted: the robot's root frame in the tracker frame.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TrackerRegistration {
    /// The measurement CSV.
    pub file: String,
    /// Its rows.
    pub rows: usize,
    /// Whether the frame was fitted (else the rows are in the root frame).
    pub fitted: bool,
    /// The root frame's origin in the tracker frame (m).
    pub xyz: [f64; 3],
    /// Its roll, pitch, yaw (rad).
    pub rpy: [f64; 3],
}

/// A fitted pose: nominal and calibrated, in its mount (a link or the world).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FittedPose {
    /// The camera's or target's name.
    pub name: String,
    /// Its link in the calibrated URDF, or `world`.
    pub link: String,
    /// Nominal `[x, y, z]` (m) in the link.
    pub nominal_xyz: [f64; 3],
    /// Calibrated `[x, y, z]` (m) in the calibrated URDF's link.
    pub calibrated_xyz: [f64; 3],
    /// Nominal roll, pitch, yaw (rad).
    pub nominal_rpy: [f64; 3],
    /// Calibrated roll, pitch, yaw (rad).
    pub calibrated_rpy: [f64; 3],
    /// Standard deviations of the six pose parameters (α, β, γ rad; x, y, z m), where fitted.
    pub std_dev: Option<[f64; 6]>,
}

/// One intrinsic of one camera.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FittedIntrinsic {
    /// `camera fx`, `camera k1`, ….
    pub name: String,
    /// The camera file's value.
    pub nominal: f64,
    /// The calibrated value.
    pub calibrated: f64,
    /// Its standard deviation, when estimated and determined.
    pub std_dev: Option<f64>,
}

/// One robot parameter.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RobotParameter {
    /// Its name (as in params.yaml).
    pub name: String,
    /// Nominal value (rad or m).
    pub nominal: f64,
    /// Calibrated value.
    pub calibrated: f64,
    /// Standard deviation, when fitted and determined.
    pub std_dev: Option<f64>,
    /// Whether the images determine it.
    pub determined: bool,
    /// Not fitted at all: a tool frame of the link that carries a camera (the camera's
    /// extrinsics place that link), kept at its nominal value.
    pub held: bool,
}

/// Everything report.json holds.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CameraCalibrationReport {
    /// Version of this layout.
    pub schema_version: u32,
    /// The robot's name.
    pub robot: String,
    /// The camera file, the detections file.
    pub inputs: Vec<String>,
    /// The fit.
    pub fit: CameraFitSummary,
    /// The rows of each kind of observation (pixels, tracker positions and rotations) and
    /// each kind's own σ̂.
    pub kinds: Vec<KindScale>,
    /// The tracker rows' file and fitted frame, with mixed data.
    pub tracker: Option<TrackerRegistration>,
    /// The fit's residuals at the solution.
    pub residuals: PixelResiduals,
    /// Per target.
    pub targets: Vec<TargetResiduals>,
    /// The held-out images, if given.
    pub held_out: Option<HeldOut>,
    /// Detected points left out because the nominal model gives them no pixel, and why.
    pub rejected: Vec<RejectedPoint>,
    /// What the images cannot determine, by name and in words.
    pub unobservable: CameraIdentifiability,
    /// The cameras' extrinsics.
    pub cameras: Vec<FittedPose>,
    /// The cameras' intrinsics.
    pub intrinsics: Vec<FittedIntrinsic>,
    /// The poses of targets not on a tool (a board in the world, on a link).
    pub target_poses: Vec<FittedPose>,
    /// Every robot parameter.
    pub robot_parameters: Vec<RobotParameter>,
    /// `ok`, `warning` or `failed`, with its reasons.
    pub verdict: Verdict,
}

/// Robot parameters listed in report.md (the largest changes relative to their σ).
const LISTED_PARAMETERS: usize = 15;

/// report.md.
pub fn camera_markdown(report: &CameraCalibrationReport) -> String {
    let fit = &report.fit;
    let mut text = format!(
        "# Camera calibration of {}\n\nVerdict: **{}**\n\n",
        report.robot, report.verdict.status
    );
    for reason in &report.verdict.reasons {
        text.push_str(&format!("- {}: {}\n", reason.status, reason.message));
    }
    text.push_str(&format!(
        "\nInputs: {}.\n\n## Fit\n\n{} images, {} detected points ({} rejected); {} unknowns, \
         rank {}; {} iterations ({:?}); σ̂ = {:.3} (pixel σ declared {} px).\n\n",
        report.inputs.join(", "),
        report.residuals.images,
        report.residuals.points,
        report.rejected.len(),
        fit.unknowns,
        fit.rank,
        fit.iterations,
        fit.termination,
        fit.residual_scale,
        fit.pixel_sigma
    ));
    text.push_str(
        "| images | points | RMS (px) | mean (px) | max (px) |\n| --- | --- | --- | --- | --- |\n",
    );
    let mut row = |label: &str, r: &PixelResiduals| {
        text.push_str(&format!(
            "| {label} | {} / {} | {:.3} | {:.3} | {:.3} |\n",
            r.images, r.points, r.rms_px, r.mean_px, r.max_px
        ))
    };
    row("fit, all targets", &report.residuals);
    for target in &report.targets {
        row(&format!("fit, {}", target.target), &target.residuals);
    }
    if let Some(held) = &report.held_out {
        row(&format!("held out ({}), nominal", held.file), &held.before);
        row(
            &format!("held out ({}), calibrated", held.file),
            &held.after,
        );
    }
    text.push_str(&kinds_markdown(&report.kinds, report.tracker.as_ref()));
    text.push_str("\n## What the images cannot determine\n\n");
    if report.unobservable.findings.is_empty() {
        text.push_str("Every unknown is determined by these images.\n");
    }
    for finding in &report.unobservable.findings {
        text.push_str(&format!("- {finding}\n"));
    }
    text.push_str(&poses_markdown("Cameras (extrinsics)", &report.cameras));
    if !report.intrinsics.is_empty() {
        text.push_str(
            "\n## Intrinsics\n\n| | nominal | calibrated | σ |\n| --- | --- | --- | --- |\n",
        );
        for i in &report.intrinsics {
            text.push_str(&format!(
                "| {} | {:.6} | {:.6} | {} |\n",
                i.name,
                i.nominal,
                i.calibrated,
                i.std_dev.map_or("—".into(), |s| format!("{s:.3e}"))
            ));
        }
    }
    text.push_str(&poses_markdown("Targets", &report.target_poses));
    text.push_str(&parameters_markdown(&report.robot_parameters));
    text
}

/// The rows of each kind and their σ̂, and the tracker's frame (mixed data: a camera's or a
/// contact calibration's).
pub fn kinds_markdown(kinds: &[KindScale], tracker: Option<&TrackerRegistration>) -> String {
    let mut text = String::from(
        "\n## Rows by kind\n\n| kind | observations | rows | σ̂ |\n| --- | --- | --- | --- |\n",
    );
    for kind in kinds {
        text.push_str(&format!(
            "| {} | {} | {} | {:.3} |\n",
            kind.kind, kind.observations, kind.rows, kind.residual_scale
        ));
    }
    if let Some(tracker) = tracker {
        let [x, y, z] = tracker.xyz.map(|v| v * 1e3);
        let [r, p, w] = tracker.rpy.map(f64::to_degrees);
        text.push_str(&format!(
            "\nTracker rows: {} from {}; the robot's root frame in the tracker frame: xyz \
             ({x:.2}, {y:.2}, {z:.2}) mm, rpy ({r:.3}, {p:.3}, {w:.3})° ({}).\n",
            tracker.rows,
            tracker.file,
            if tracker.fitted {
                "fitted with the rest"
            } else {
                "given: the rows are in the root frame"
            }
        ));
    }
    text
}

fn poses_markdown(title: &str, poses: &[FittedPose]) -> String {
    if poses.is_empty() {
        return String::new();
    }
    let mut text = format!(
        "\n## {title}\n\n| name | link | xyz nominal (mm) | xyz calibrated (mm) | rpy nominal (deg) \
         | rpy calibrated (deg) | σ xyz (mm) |\n| --- | --- | --- | --- | --- | --- | --- |\n"
    );
    let mm = |v: &[f64]| {
        v.iter()
            .map(|x| format!("{:.2}", x * 1e3))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let deg = |v: &[f64; 3]| {
        v.iter()
            .map(|x| format!("{:.3}", x.to_degrees()))
            .collect::<Vec<_>>()
            .join(", ")
    };
    for p in poses {
        text.push_str(&format!(
            "| {} | {} | {} | {} | {} | {} | {} |\n",
            p.name,
            p.link,
            mm(&p.nominal_xyz),
            mm(&p.calibrated_xyz),
            deg(&p.nominal_rpy),
            deg(&p.calibrated_rpy),
            p.std_dev.map_or("—".into(), |s| mm(&s[3..]))
        ));
    }
    text
}

fn parameters_markdown(parameters: &[RobotParameter]) -> String {
    let names = |held: bool| -> Vec<String> {
        parameters
            .iter()
            .filter(|p| !p.determined && p.held == held)
            .map(|p| p.name.clone())
            .collect()
    };
    let (undetermined, held) = (names(false), names(true));
    let mut undetermined = if undetermined.is_empty() {
        "all determined by these images".to_owned()
    } else {
        format!(
            "{} not determined by these images (kept nominal: {})",
            undetermined.len(),
            super::first_few(&undetermined)
        )
    };
    if !held.is_empty() {
        // A camera's link placed by the camera's extrinsics: not an unknown of the fit, so
        // "What the images cannot determine" rightly does not list them.
        undetermined = format!(
            "{} held at their nominal values and not fitted (the frame of a link that carries \
             a camera, which the camera's extrinsics place: {}); of the others, {undetermined}",
            held.len(),
            super::first_few(&held)
        );
    }
    let mut listed: Vec<&RobotParameter> = parameters.iter().filter(|p| p.determined).collect();
    let significance = |p: &RobotParameter| {
        (p.calibrated - p.nominal).abs() / p.std_dev.unwrap_or(f64::INFINITY).max(1e-15)
    };
    listed.sort_by(|a, b| significance(b).total_cmp(&significance(a)));
    let mut text = format!(
        "\n## Robot parameters\n\n{} parameters, {undetermined}; \
         the {} largest changes relative to their σ (all in report.json):\n\n| parameter | \
         nominal | calibrated | change | σ |\n| --- | --- | --- | --- | --- |\n",
        parameters.len(),
        LISTED_PARAMETERS.min(listed.len())
    );
    for p in listed.iter().take(LISTED_PARAMETERS) {
        text.push_str(&format!(
            "| {} | {:.6} | {:.6} | {:.3e} | {} |\n",
            p.name,
            p.nominal,
            p.calibrated,
            p.calibrated - p.nominal,
            p.std_dev.map_or("—".into(), |s| format!("{s:.2e}"))
        ));
    }
    text
}
