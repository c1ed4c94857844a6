//! Which measurement frame a calibration uses, and the checks that the data fit it: the
//! scale of the measured positions (a unit mistake) and whether a fixed frame (the root frame
//! or a known registration) explains the data (see `docs/calibration.md`, "What treecal checks
//! and infers").

use super::initial_guess::{
    base_frame_positions, fit_similarity_scale, initial_guess, initial_tool_frames, InitialGuess,
};
use super::verdict::Finding;
use crate::error::{Error, Result};
use crate::kinematics::McpcModel;
use crate::math::Pose;
use crate::measurement::Measurement;
use serde::Serialize;

/// Where the measurements are, relative to the robot's root link frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum MeasurementFrame {
    /// Fit the frame in closed form, and take the root frame instead when it explains the
    /// data ([`frame_explains`]): the exported root is then the physical base.
    Auto,
    /// Fit the frame in closed form and keep it.
    Fit,
    /// The data are in the root frame (a registered base).
    Base,
    /// A known registration: the pose of the robot's root frame in the measurement frame.
    Known(Pose),
}

/// The frame a calibration used.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum ChosenFrame {
    /// The robot's root link frame (identity).
    Root,
    /// Fitted to the data in closed form.
    Fitted,
    /// The registration the user gave.
    Known,
}

/// How the measurement frame was chosen, with the numbers that decided.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FrameDecision {
    /// The frame used.
    pub chosen: ChosenFrame,
    /// Offset of the closed-form fitted frame from the fixed candidate (the root frame, or the
    /// known registration): rotation (rad), translation (m).
    pub fitted_offset: [f64; 2],
    /// Closed-form position RMS (m), tools fitted: with the fixed candidate, with the fitted
    /// frame.
    pub rms: [f64; 2],
    /// Whether the fixed candidate explains the data ([`frame_explains`]).
    pub candidate_explains: bool,
    /// One sentence: which frame and why.
    pub reason: String,
}

/// The largest offset (m) of the fitted frame from a fixed frame that still counts as "the
/// same frame". The complete MCPC model absorbs any frame offset in its first frames, so the
/// data cannot tell a registration offset from a geometric error; this bound only keeps the
/// solver's start within the reach of its linearisation. With the paper's errors (±5 cm,
/// ±0.05 rad on every parameter) the closed-form fit on root-frame data moves by up to 123 mm
/// and 0.155 rad (20 seeds on each robot in `robots/`, `tests/frame.rs`): about 2× margin.
pub const FRAME_TRANSLATION_LIMIT: f64 = 0.3;

/// The same for rotation (rad).
pub const FRAME_ROTATION_LIMIT: f64 = 0.3;

/// How much worse than the fitted frame the fixed one may explain the data: the position RMS
/// it adds in quadrature, `√(rms_fixed² − rms_fitted²)`, at most this many times the fitted
/// RMS (the uncalibrated robot's own error, which the fit cannot remove; at most 1.5× on
/// root-frame data with the paper's errors, `tests/frame.rs`)…
pub const FRAME_EXTRA_RMS_RATIO: f64 = 3.0;

/// …or this much (m), whichever is larger, so that a precise robot with a registration a few
/// millimetres off keeps its base.
pub const FRAME_EXTRA_RMS_FLOOR: f64 = 0.02;

/// Whether a fixed frame explains the data as well as an uncalibrated robot can tell: the
/// fitted frame within [`FRAME_TRANSLATION_LIMIT`] and [`FRAME_ROTATION_LIMIT`] of it, and
/// the RMS the fixed frame adds ([`FRAME_EXTRA_RMS_RATIO`], [`FRAME_EXTRA_RMS_FLOOR`]) no more
/// than the nominal model's own error explains. `rms`: fixed, fitted (m).
pub fn frame_explains(fitted_offset: [f64; 2], rms: [f64; 2]) -> bool {
    let extra = (rms[0] * rms[0] - rms[1] * rms[1]).max(0.0).sqrt();
    fitted_offset[0] <= FRAME_ROTATION_LIMIT
        && fitted_offset[1] <= FRAME_TRANSLATION_LIMIT
        && extra <= (FRAME_EXTRA_RMS_RATIO * rms[1]).max(FRAME_EXTRA_RMS_FLOOR)
}

/// The closed-form start in the frame `requested` asks for, the decision, and the finding to
/// report (a note, or `failed` when a fixed frame the user asked for cannot explain the data).
pub fn choose_measurement_frame(
    nominal: &McpcModel,
    measurements: &[Measurement],
    requested: MeasurementFrame,
) -> Result<(InitialGuess, FrameDecision, Finding)> {
    let fitted = initial_guess(nominal, measurements, 3)?;
    let candidate = match requested {
        MeasurementFrame::Known(world_from_base) => world_from_base,
        _ => Pose::identity(),
    };
    let mut start = nominal.clone();
    start.set_world_from_base(&candidate);
    let fixed = initial_tool_frames(&start, measurements)?;
    let change = candidate.inverse() * fitted.world_from_base;
    let fitted_offset = [change.rotation.angle(), change.translation.vector.norm()];
    let rms = [fixed.rms_after, fitted.rms_after];
    let explains = frame_explains(fitted_offset, rms);
    let (chosen, reason, failed) = decide(
        requested,
        explains,
        &describe(requested, fitted_offset, rms),
    );
    let finding = if failed {
        Finding::failed("measurement-frame", reason.clone())
    } else {
        Finding::note("measurement-frame", reason.clone())
    };
    let guess = if chosen == ChosenFrame::Fitted {
        fitted
    } else {
        fixed
    };
    Ok((
        guess,
        FrameDecision {
            chosen,
            fitted_offset,
            rms,
            candidate_explains: explains,
            reason,
        },
        finding,
    ))
}

/// The numbers that decide, with the limits, for messages.
fn describe(requested: MeasurementFrame, fitted_offset: [f64; 2], rms: [f64; 2]) -> String {
    let extra = (rms[0] * rms[0] - rms[1] * rms[1]).max(0.0).sqrt();
    format!(
        "the fitted frame is {:.1} mm and {:.2}° from {}; closed-form position RMS {:.1} mm \
         there, {:.1} mm fitted, {:.1} mm more in quadrature; limits {:.0} mm, {:.1}°, {:.0} mm \
         more",
        fitted_offset[1] * 1e3,
        fitted_offset[0].to_degrees(),
        match requested {
            MeasurementFrame::Known(_) => "the registration",
            _ => "the root frame",
        },
        rms[0] * 1e3,
        rms[1] * 1e3,
        extra * 1e3,
        FRAME_TRANSLATION_LIMIT * 1e3,
        FRAME_ROTATION_LIMIT.to_degrees(),
        (FRAME_EXTRA_RMS_RATIO * rms[1]).max(FRAME_EXTRA_RMS_FLOOR) * 1e3
    )
}

/// The frame used, the sentence that says why, and whether that is a failure (a fixed frame
/// the user asked for that cannot explain the data).
fn decide(
    requested: MeasurementFrame,
    explains: bool,
    numbers: &str,
) -> (ChosenFrame, String, bool) {
    match requested {
        MeasurementFrame::Auto if explains => (
            ChosenFrame::Root,
            format!(
                "root frame chosen (`measurement_frame` auto): the data are already in the \
                 robot's root frame ({numbers}), so the exported URDF's root is the physical base"
            ),
            false,
        ),
        MeasurementFrame::Auto => (
            ChosenFrame::Fitted,
            format!(
                "fitted frame chosen (`measurement_frame` auto): the root frame cannot explain \
                 the data ({numbers}), so they are in another frame (a tracker's); the exported \
                 URDF's root is the fitted frame"
            ),
            false,
        ),
        MeasurementFrame::Fit if explains => (
            ChosenFrame::Fitted,
            format!(
                "fitted frame (`measurement_frame` fit; {numbers}); the data look as if they \
                 are in the root frame already, and the exported URDF's root is the fitted \
                 frame, off the physical base by the errors it absorbed: `measurement_frame` \
                 auto or base would keep the base"
            ),
            false,
        ),
        MeasurementFrame::Fit => (
            ChosenFrame::Fitted,
            format!("fitted frame (`measurement_frame` fit; {numbers})"),
            false,
        ),
        MeasurementFrame::Base if explains => (
            ChosenFrame::Root,
            format!("root frame (`measurement_frame` base; {numbers})"),
            false,
        ),
        MeasurementFrame::Base => (
            ChosenFrame::Root,
            format!(
                "root frame (`measurement_frame` base) cannot explain the data ({numbers}): the \
                 data are not in the robot's root frame; hint: `measurement_frame` fit (or auto)"
            ),
            true,
        ),
        MeasurementFrame::Known(_) if explains => (
            ChosenFrame::Known,
            format!("registration given (`measurement_frame` FILE; {numbers})"),
            false,
        ),
        MeasurementFrame::Known(_) => (
            ChosenFrame::Known,
            format!(
                "registration given (`measurement_frame` FILE) cannot explain the data \
                 ({numbers}): the registration does not match the data (is it the robot base \
                 in the tracker frame, in the stated units?); hint: `measurement_frame` fit"
            ),
            true,
        ),
    }
}

/// The scale ratio beyond which measured positions cannot be in the unit assumed: the robot's
/// nominal reach against the measured spread is off by more than 30× (a unit mistake is
/// 1000×; nominal errors are a few percent).
pub const LENGTH_SCALE_LIMIT: f64 = 30.0;

/// Fails when the measured positions are about 1000× larger or smaller than the nominal
/// kinematics predict (a closed-form similarity fit with scale, Umeyama): a length unit
/// mistake, named before anything is solved.
pub fn check_length_scale(nominal: &McpcModel, measurements: &[Measurement]) -> Result<()> {
    let (predicted, measured) = base_frame_positions(nominal, measurements);
    let Some(scale) = fit_similarity_scale(&predicted, &measured) else {
        return Ok(());
    };
    if (1.0 / LENGTH_SCALE_LIMIT..=LENGTH_SCALE_LIMIT).contains(&scale) {
        return Ok(());
    }
    let (looks, fix) = if scale > 1.0 {
        ("millimetres read as metres", "`length_unit` mm")
    } else {
        ("metres read as millimetres", "`length_unit` m")
    };
    Err(Error::InvalidData {
        origin: "measurements".into(),
        message: format!(
            "the measured positions are {scale:.3e} times the size the robot's nominal \
             kinematics predict (a closed-form fit with scale): they look like {looks}; give \
             {fix} (or state `# units: length=…` in the file; prismatic joint values may need \
             `joint_length_unit`)"
        ),
    })
}
