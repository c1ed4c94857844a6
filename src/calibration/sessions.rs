//! Measurement sessions: one measurement frame per session (the CSV's `session` column).
//!
//! A tracker or a motion-capture system that is moved, re-levelled or re-calibrated between two
//! days measures the same robot in another frame. The first session's frame is the
//! measurement frame of today's fit (closed-form start, absorbed by the MCPC parameters); every
//! other session `s` gets a **per-session nuisance block**: the six parameters of the pose
//! `session_from_first` of its frame in the first session's frame, so that its rows are
//! predicted as `session_from_first · prediction`. The blocks are fitted jointly with the
//! geometry: the least-squares problem over (geometry, blocks) is solved by alternating the
//! calibration (the rows of every session mapped into the first session's frame) with the
//! closed-form-started Gauss–Newton fit of each block at the calibrated geometry, accelerated
//! by Anderson extrapolation; its fixed point is the joint minimum. Later measurement kinds
//! (a plane or a board seen in each session) add their own block per session to the same
//! alternation. See `docs/calibration.md`, "Sessions".
//!
//! Validation rows of a session seen in training use that session's frame (the "training
//! frame"); rows of a new session use the first session's frame, and are also **re-registered**
//! (their block's six parameters refitted with the calibrated geometry fixed): both figures
//! are reported ([`SessionValidation`]).

use super::observation::kind_of;
use super::options::IdentificationOptions;
use super::plan::{Anderson, CalibrationReport, Compensation, Plan};
use super::predictor::{Predictor, Rigid};
use super::robust::{calibrate_robust, RobustReport};
use super::session_frame::fit_session_frame;
use crate::error::Result;
use crate::kinematics::McpcModel;
use crate::math::{pose, Pose, Vec3};
use crate::measurement::Measurement;
use crate::tree::Branches;
use nalgebra::UnitQuaternion;
use std::borrow::Cow;

pub use super::session_findings::session_findings;

/// Parameters of one session's frame block (translation and rotation).
pub const FRAME_BLOCK_PARAMETERS: usize = 6;

/// Most alternations of calibration and frame fits.
pub const MAX_ROUNDS: usize = 40;

/// The alternation stops when no session frame moved by more than this in a round (m, and
/// rad times [`ROTATION_LENGTH`]).
pub const ROUND_TOLERANCE: f64 = 1e-9;

/// The length (m) that turns a rotation (rad) into a comparable displacement: a robot's reach.
pub const ROTATION_LENGTH: f64 = 1.0;

/// The sessions of a data set, in order of first appearance (the first is the reference).
#[derive(Debug, Clone, PartialEq)]
pub struct Sessions {
    /// Session names (`None`: rows without a session label).
    pub names: Vec<Option<String>>,
    /// Per measurement, the index of its session in `names`.
    pub of: Vec<usize>,
}

impl Sessions {
    /// The sessions of `measurements`.
    pub fn of(measurements: &[Measurement]) -> Self {
        let mut names: Vec<Option<String>> = Vec::new();
        let of = measurements
            .iter()
            .map(|m| match names.iter().position(|n| *n == m.session) {
                Some(index) => index,
                None => {
                    names.push(m.session.clone());
                    names.len() - 1
                }
            })
            .collect();
        Self { names, of }
    }

    /// The number of rows of session `index`.
    pub fn rows(&self, index: usize) -> usize {
        self.of.iter().filter(|&&s| s == index).count()
    }

    /// The rows of the first session (all rows, not copied, when there is one session).
    pub fn first_session<'m>(&self, measurements: &'m [Measurement]) -> Cow<'m, [Measurement]> {
        if self.names.len() < 2 && self.of.len() == measurements.len() {
            return Cow::Borrowed(measurements);
        }
        measurements
            .iter()
            .zip(&self.of)
            .filter(|(_, &s)| s == 0)
            .map(|(m, _)| m.clone())
            .collect()
    }
}

/// A session's name for messages: quoted, or `(unnamed)`.
pub fn session_label(name: &Option<String>) -> String {
    match name {
        Some(name) => format!("'{name}'"),
        None => "(unnamed)".into(),
    }
}

/// One session's measurement frame.
#[derive(Debug, Clone, PartialEq)]
pub struct SessionFrame {
    /// The session (`None`: rows without a label).
    pub name: Option<String>,
    /// Its rows.
    pub rows: usize,
    /// Its frame in the first session's: measured ≈ `session_from_first · predicted`
    /// (identity for the first session).
    pub session_from_first: Pose,
    /// How many of the block's six directions its rows determine (6 for the first session).
    pub determined: usize,
    /// How far the frame moves the session's own rows: RMS over them of `‖p − T⁻¹·p‖` (m),
    /// the measured positions `p` (the frame's origin can be metres away, where a small turn
    /// is a large offset).
    pub displacement: f64,
}

/// The sessions of a calibration and of its validation data.
#[derive(Debug, Clone, PartialEq)]
pub struct SessionsReport {
    /// Every training session's frame, the first (the reference) first.
    pub frames: Vec<SessionFrame>,
    /// Alternations of calibration and frame fits (0 with one training session).
    pub rounds: usize,
    /// Whether the frames settled within `MAX_ROUNDS`.
    pub converged: bool,
    /// Per validation session, the held-out figures.
    pub validation: Vec<SessionValidation>,
}

/// A validation session's held-out position errors.
#[derive(Debug, Clone, PartialEq)]
pub struct SessionValidation {
    /// The session.
    pub name: Option<String>,
    /// Its validation rows.
    pub rows: usize,
    /// Whether the session is one of the training sessions: then its training frame is its
    /// own fitted frame; otherwise the first session's.
    pub seen_in_training: bool,
    /// RMS position error (m) in the training frame.
    pub training_frame_rms: f64,
    /// RMS position error (m) re-registered: the session's frame refitted to its validation
    /// rows with the calibrated geometry fixed.
    pub reregistered_rms: f64,
    /// Parameters refitted for the re-registration ([`FRAME_BLOCK_PARAMETERS`]).
    pub refitted_parameters: usize,
    /// The re-registered frame in the first session's frame.
    pub session_from_first: Pose,
}

/// A new validation session was measured in another frame (the tracker or the mocap frame
/// moved between sessions) when its RMS position error in the training frame passes its
/// re-registered one by this factor ...
pub const MOVED_FACTOR: f64 = 3.0;

/// ... and by this much (m).
pub const MOVED_MARGIN: f64 = 1e-3;

impl SessionValidation {
    /// Whether this session is new and was measured in another frame (`MOVED_FACTOR`,
    /// `MOVED_MARGIN`): its rows then count re-registered (placed in the training frame by
    /// [`Self::session_from_first`]) in every validation figure, as `verify` scores a new day.
    pub fn moved(&self) -> bool {
        !self.seen_in_training
            && self.training_frame_rms > MOVED_FACTOR * self.reregistered_rms
            && self.training_frame_rms - self.reregistered_rms > MOVED_MARGIN
    }
}

/// A calibration with one frame per session.
#[derive(Debug, Clone)]
pub struct SessionCalibration {
    /// The plan's outcome.
    pub report: CalibrationReport,
    /// The robust estimation of the last calibration.
    pub robust: RobustReport,
    /// The measurements mapped into the first session's frame (the data the report fits);
    /// `None` with one session: the data as given are in its frame (not copied: at 10⁶
    /// configurations a copy is about 700 MB).
    pub measurements: Option<Vec<Measurement>>,
    /// The session frames (one, the identity, with one session: nothing to fit).
    pub sessions: SessionsReport,
}

/// `measurement` in the first session's frame, given its session's `session_from_first`.
pub fn in_first_frame(measurement: &Measurement, session_from_first: &Pose) -> Measurement {
    let observation = kind_of(&measurement.observation).in_frame(&session_from_first.inverse());
    Measurement {
        observation,
        ..measurement.clone()
    }
}

/// The tool poses the calibration's model predicts (deflected under compensation).
pub fn predictions(
    model: &McpcModel,
    measurements: &[Measurement],
    compensation: Compensation<'_>,
) -> Result<Vec<Pose>> {
    measurements
        .iter()
        .map(|m| {
            let poses = match compensation {
                Compensation::None => Rigid.predict_at(model, &m.q, m.payload)?,
                Compensation::Linear(source) | Compensation::Exact(source) => {
                    source.predict_at(model, &m.q, m.payload)?
                }
            };
            Ok(poses[m.tool])
        })
        .collect()
}

/// A frame as six numbers (translation, rotation vector) for the extrapolation.
fn coordinates(frame: &Pose) -> [f64; 6] {
    let t = frame.translation.vector;
    let r = frame.rotation.scaled_axis();
    [t.x, t.y, t.z, r.x, r.y, r.z]
}

fn from_coordinates(c: &[f64]) -> Pose {
    pose(
        Vec3::new(c[0], c[1], c[2]),
        UnitQuaternion::from_scaled_axis(Vec3::new(c[3], c[4], c[5])),
    )
}

/// RMS over session `s`'s rows of how far `session_from_first` moves their measured
/// positions (m).
fn displacement(
    measurements: &[Measurement],
    sessions: &Sessions,
    s: usize,
    session_from_first: &Pose,
) -> f64 {
    let first_from_session = session_from_first.inverse();
    let moved: Vec<f64> = measurements
        .iter()
        .zip(&sessions.of)
        .filter(|(_, &k)| k == s)
        .filter_map(|(m, _)| {
            let p = super::initial_guess::measured_position(m)?;
            Some((p - first_from_session.transform_point(&p.into()).coords).norm_squared())
        })
        .collect();
    (moved.iter().sum::<f64>() / moved.len().max(1) as f64).sqrt()
}

/// Every session's measurements mapped into the first session's frame.
fn mapped(measurements: &[Measurement], sessions: &Sessions, frames: &[Pose]) -> Vec<Measurement> {
    measurements
        .iter()
        .zip(&sessions.of)
        .map(|(m, &s)| {
            if s == 0 {
                m.clone()
            } else {
                in_first_frame(m, &frames[s])
            }
        })
        .collect()
}

/// Each session's frame (the first: identity) fitted at `model`, with the robust `weights`
/// (empty: all 1); and how many directions each is determined in.
fn fit_frames(
    model: &McpcModel,
    measurements: &[Measurement],
    sessions: &Sessions,
    compensation: Compensation<'_>,
    weights: &[f64],
    options: &IdentificationOptions,
) -> Result<Vec<(Pose, usize)>> {
    let predicted = predictions(model, measurements, compensation)?;
    Ok((0..sessions.names.len())
        .map(|s| {
            if s == 0 {
                return (Pose::identity(), FRAME_BLOCK_PARAMETERS);
            }
            let rows: Vec<usize> = (0..measurements.len())
                .filter(|&i| sessions.of[i] == s)
                .collect();
            let own_weights: Vec<f64> = if weights.is_empty() {
                Vec::new()
            } else {
                rows.iter().map(|&i| weights[i]).collect()
            };
            fit_session_frame(
                &rows.iter().map(|&i| predicted[i]).collect::<Vec<_>>(),
                &rows.iter().map(|&i| &measurements[i]).collect::<Vec<_>>(),
                &own_weights,
                options,
            )
        })
        .collect())
}

/// Calibrates with one measurement frame per session (see the module documentation), from
/// `start` (its measurement frame is the first session's). With one session this is
/// [`calibrate_robust`] on the data as given.
pub fn calibrate_sessions(
    branches: &Branches,
    start: &McpcModel,
    measurements: &[Measurement],
    compensation: Compensation<'_>,
    plan: &Plan,
    options: &IdentificationOptions,
) -> Result<SessionCalibration> {
    let sessions = Sessions::of(measurements);
    if sessions.names.len() < 2 {
        let (report, robust) =
            calibrate_robust(branches, start, measurements, compensation, plan, options)?;
        return Ok(SessionCalibration {
            report,
            robust,
            measurements: None,
            sessions: SessionsReport {
                frames: vec![SessionFrame {
                    name: sessions.names.first().cloned().flatten(),
                    rows: measurements.len(),
                    session_from_first: Pose::identity(),
                    determined: FRAME_BLOCK_PARAMETERS,
                    displacement: 0.0,
                }],
                rounds: 0,
                converged: true,
                validation: Vec::new(),
            },
        });
    }
    let mut fitted = fit_frames(start, measurements, &sessions, compensation, &[], options)?;
    let mut model = start.clone();
    let mut acceleration = Anderson::new(3);
    let mut rounds = 0;
    let converged;
    let flat = |frames: &[(Pose, usize)]| -> Vec<f64> {
        frames.iter().flat_map(|(f, _)| coordinates(f)).collect()
    };
    let (report, robust, data) = loop {
        rounds += 1;
        let frames: Vec<Pose> = fitted.iter().map(|(f, _)| *f).collect();
        let data = mapped(measurements, &sessions, &frames);
        let (report, robust) =
            calibrate_robust(branches, &model, &data, compensation, plan, options)?;
        model = report.model.clone();
        let next = fit_frames(
            &model,
            measurements,
            &sessions,
            compensation,
            &robust.fit_weights(),
            options,
        )?;
        let (before, after) = (flat(&fitted), flat(&next));
        let change = before
            .chunks(3)
            .zip(after.chunks(3))
            .enumerate()
            .map(|(k, (a, b))| {
                let scale = if k % 2 == 0 { 1.0 } else { ROTATION_LENGTH };
                scale
                    * a.iter()
                        .zip(b)
                        .map(|(x, y)| (x - y).abs())
                        .fold(0.0, f64::max)
            })
            .fold(0.0, f64::max);
        if change <= ROUND_TOLERANCE || rounds >= MAX_ROUNDS {
            converged = change <= ROUND_TOLERANCE;
            // The frames the data were mapped with, and what the last fit determined.
            for (frame, (_, determined)) in fitted.iter_mut().zip(&next) {
                frame.1 = *determined;
            }
            break (report, robust, data);
        }
        let extrapolated = acceleration.next(&before, &after);
        fitted = extrapolated
            .chunks(6)
            .zip(&next)
            .map(|(c, (_, determined))| (from_coordinates(c), *determined))
            .collect();
    };
    let frames = fitted
        .iter()
        .enumerate()
        .map(|(s, (frame, determined))| SessionFrame {
            name: sessions.names[s].clone(),
            rows: sessions.rows(s),
            session_from_first: *frame,
            determined: *determined,
            displacement: displacement(measurements, &sessions, s, frame),
        })
        .collect();
    Ok(SessionCalibration {
        report,
        robust,
        measurements: Some(data),
        sessions: SessionsReport {
            frames,
            rounds,
            converged,
            validation: Vec::new(),
        },
    })
}

/// Rows in their training frames: a session seen in training mapped into the first
/// session's frame by its fitted frame, a new session measured in another frame
/// ([`SessionValidation::moved`], once `sessions.validation` holds it) by its re-registered
/// frame, any other new one (and every row without sessions) as given, i.e. taken to be in the
/// first session's frame. Maps validation rows, and the training rows
/// themselves (for a later fit on the same data, e.g. the stiffness identification).
pub fn validation_in_training_frames(
    validation: &[Measurement],
    sessions: Option<&SessionsReport>,
) -> Vec<Measurement> {
    validation
        .iter()
        .map(|m| match validation_frame(m, sessions) {
            Some(frame) => in_first_frame(m, &frame),
            None => m.clone(),
        })
        .collect()
}

/// The frame a validation row is placed by: its training session's fitted frame, or the
/// re-registered frame of a new session measured in another frame ([`SessionValidation::moved`]).
fn validation_frame(m: &Measurement, sessions: Option<&SessionsReport>) -> Option<Pose> {
    training_frame(m, sessions).or_else(|| {
        sessions?
            .validation
            .iter()
            .find(|v| v.moved() && v.name == m.session)
            .map(|v| v.session_from_first)
    })
}

/// The fitted frame of the training session `m` belongs to, if it is one (not the first).
fn training_frame(m: &Measurement, sessions: Option<&SessionsReport>) -> Option<Pose> {
    sessions?
        .frames
        .iter()
        .skip(1)
        .find(|f| f.name == m.session)
        .map(|f| f.session_from_first)
}

/// Per validation session (in order of first appearance): the RMS position error in the
/// training frame and re-registered (its frame's [`FRAME_BLOCK_PARAMETERS`] refitted to its
/// rows, geometry fixed), every row counted. `validation` as given (each session in its own
/// frame).
pub fn validate_sessions(
    model: &McpcModel,
    validation: &[Measurement],
    compensation: Compensation<'_>,
    sessions: &SessionsReport,
    options: &IdentificationOptions,
) -> Result<Vec<SessionValidation>> {
    let groups = Sessions::of(validation);
    let predicted = predictions(model, validation, compensation)?;
    let rms = |rows: &[usize], frame: &Pose| -> f64 {
        let sum: f64 = rows
            .iter()
            .filter_map(|&i| {
                let at = frame * predicted[i];
                let measured = super::initial_guess::measured_position(&validation[i])?;
                Some((measured - at.translation.vector).norm_squared())
            })
            .sum();
        (sum / rows.len().max(1) as f64).sqrt()
    };
    Ok(groups
        .names
        .iter()
        .enumerate()
        .map(|(s, name)| {
            let rows: Vec<usize> = (0..validation.len())
                .filter(|&i| groups.of[i] == s)
                .collect();
            let seen = sessions.frames.iter().any(|f| f.name == *name);
            let training =
                training_frame(&validation[rows[0]], Some(sessions)).unwrap_or_else(Pose::identity);
            // Robust: a gross blunder does not drag the re-registration (without one this
            // is the least-squares frame).
            let refitted = super::robust_frame::fit_session_frame_robust(
                &rows.iter().map(|&i| predicted[i]).collect::<Vec<_>>(),
                &rows.iter().map(|&i| &validation[i]).collect::<Vec<_>>(),
                options,
                options.robust,
            )
            .frame;
            SessionValidation {
                name: name.clone(),
                rows: rows.len(),
                seen_in_training: seen,
                training_frame_rms: rms(&rows, &training),
                reregistered_rms: rms(&rows, &refitted),
                refitted_parameters: FRAME_BLOCK_PARAMETERS,
                session_from_first: refitted,
            }
        })
        .collect())
}

/// Whether any row of either set names a session.
pub(crate) fn labelled(training: &[Measurement], validation: &[Measurement]) -> bool {
    training
        .iter()
        .chain(validation)
        .any(|m| m.session.is_some())
}

/// `report` with the validation sessions' figures at the calibrated `model`, when any row of
/// either set names a session (`None` otherwise: the data know no sessions).
pub fn finish_sessions(
    mut report: SessionsReport,
    model: &McpcModel,
    training: &[Measurement],
    validation: &[Measurement],
    compensation: Compensation<'_>,
    options: &IdentificationOptions,
) -> Result<Option<SessionsReport>> {
    if !labelled(training, validation) {
        return Ok(None);
    }
    report.validation = validate_sessions(model, validation, compensation, &report, options)?;
    Ok(Some(report))
}
