//! Repeatability without a model: validation rows that repeat an identification posture,
//! compared with the identification rows measured at that posture.
//!
//! At a repeated posture every model predicts the same point twice, so the difference of the
//! two measurements is what no calibration can remove: the instrument's noise, the robot's
//! repeatability, and any shift between the two data sets (a tracker bumped, the robot
//! warmer, a marker re-seated). Its RMS is a floor under the held-out error of those rows;
//! a mean shift well above its scatter says the validation data were taken in another frame
//! or robot state (`docs/calibration.md`, "Repeatability").

#[cfg(doc)]
use super::validation::PostureIndex;
use super::validation::{places, Stratum};
use super::verdict::Finding;
use crate::kinematics::McpcModel;
use crate::math::Vec3;
use crate::measurement::{Measurement, Observation};
use serde::Serialize;

/// Fewer repeated pairs than this give no figure.
pub const MIN_PAIRS: usize = 5;

/// The model-free comparison of repeated postures (positions in mm, in the frame the
/// validation figures use).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Repeatability {
    /// Validation rows paired with an identification row at the same posture.
    pub pairs: usize,
    /// RMS of the position differences (validation minus identification).
    pub rms_mm: f64,
    /// Their mean (x, y, z).
    pub mean_shift_mm: [f64; 3],
    /// RMS about that mean.
    pub scatter_mm: f64,
    /// Whether the mean shift stands out of the scatter (over 3 standard errors and over half
    /// the scatter): the two data sets were taken in different frames or robot states.
    pub shifted: bool,
    /// How the paired rows name their sessions: what a shift's advice may ask for (not in
    /// report.json).
    #[serde(skip)]
    pub sessions: SessionLabels,
    /// Pairs whose two measurements are the same to 1 nm (`IDENTICAL_MM`): no instrument repeats
    /// itself that closely, so the validation row is the identification row again (the same
    /// file given twice, copied rows).
    pub identical: usize,
}

/// Two measured positions closer than this (mm, 1 nm) are one measurement written twice.
pub const IDENTICAL_MM: f64 = 1e-6;

/// How the repeated pairs name their measurement sessions (the `session` column, or one file
/// per session): a shift between the data sets is fitted away only when the validation rows
/// are a session of their own.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SessionLabels {
    /// No row of either set names a session.
    #[default]
    Unnamed,
    /// Every validation row of a pair is in another session than its identification row: each
    /// validation session has its own frame (re-registered in the sessions' figures).
    Separate,
    /// Sessions are named, but some validation rows share their identification row's session.
    Shared,
}

/// The measured position of a tracker row (a pose's origin), `None` for contacts.
fn position(m: &Measurement) -> Option<Vec3> {
    match &m.observation {
        Observation::Pose(pose) => Some(pose.translation.vector),
        Observation::Position(p) => Some(*p),
        Observation::Contact(_) => None,
    }
}

/// Pairs every validation row with the first identification row of the same tool at the same
/// posture (on its chain's joints, [`PostureIndex::repeat_of`], as the strata judge it) and
/// summarises the position differences; both sets in the frame the validation figures use.
/// `None` with fewer than `MIN_PAIRS` (5) pairs.
pub fn repeatability(
    model: &McpcModel,
    identification: &[Measurement],
    validation: &[Measurement],
) -> Option<Repeatability> {
    let places = places(model, identification, validation);
    repeatability_of(identification, validation, &places)
}

/// [`repeatability`] from the validation rows' places ([`places`]: what the strata are read
/// from, so that the postures are looked up once for both).
pub fn repeatability_of(
    identification: &[Measurement],
    validation: &[Measurement],
    places: &[(Stratum, Option<usize>)],
) -> Option<Repeatability> {
    let mut shared = false;
    let differences: Vec<Vec3> = validation
        .iter()
        .zip(places)
        .filter_map(|(v, (_, repeat))| {
            let repeat = &identification[(*repeat)?];
            let difference = (position(v)? - position(repeat)?) * 1e3;
            shared |= v.session == repeat.session;
            Some(difference)
        })
        .collect();
    let named = identification
        .iter()
        .chain(validation)
        .any(|m| m.session.is_some());
    let sessions = match (named, shared) {
        (false, _) => SessionLabels::Unnamed,
        (true, false) => SessionLabels::Separate,
        (true, true) => SessionLabels::Shared,
    };
    summarise(&differences).map(|r| Repeatability { sessions, ..r })
}

/// The strata of the validation rows ([`super::strata`]) and their [`repeatability`], the
/// postures looked up once for both.
pub fn strata_and_repeatability(
    model: &McpcModel,
    identification: &[Measurement],
    validation: &[Measurement],
) -> (Vec<Stratum>, Option<Repeatability>) {
    let places = places(model, identification, validation);
    let repeatability = repeatability_of(identification, validation, &places);
    (places.into_iter().map(|(s, _)| s).collect(), repeatability)
}

/// The figures of the position differences `d` (mm).
fn summarise(d: &[Vec3]) -> Option<Repeatability> {
    if d.len() < MIN_PAIRS {
        return None;
    }
    let n = d.len() as f64;
    let mean = d.iter().sum::<Vec3>() / n;
    let rms = (d.iter().map(|v| v.norm_squared()).sum::<f64>() / n).sqrt();
    let scatter = (d.iter().map(|v| (v - mean).norm_squared()).sum::<f64>() / n).sqrt();
    // The mean's standard error: the scatter (three components) over √n, per component √3.
    let standard_error = scatter / n.sqrt();
    let shifted = mean.norm() > 3.0 * standard_error && mean.norm() > 0.5 * scatter;
    Some(Repeatability {
        pairs: d.len(),
        rms_mm: rms,
        mean_shift_mm: [mean.x, mean.y, mean.z],
        scatter_mm: scatter,
        shifted,
        sessions: SessionLabels::Unnamed,
        identical: d.iter().filter(|v| v.norm() < IDENTICAL_MM).count(),
    })
}

impl Repeatability {
    /// A warning when the validation rows are largely the identification rows again
    /// ([`Self::identical`]: at least `MIN_PAIRS` (5) and half the pairs): their "held-out"
    /// figures are fit residuals, not a test.
    pub fn not_held_out(&self) -> Option<Finding> {
        (self.identical >= MIN_PAIRS && 2 * self.identical >= self.pairs).then(|| {
            Finding::warning(
                "validation-not-held-out",
                format!(
                    "{} of the {} validation rows at an identification posture are the identification row again (the same configuration and the same measurement to 1 nm, which no instrument repeats): the same file given as `validation`, or copied rows; they are not held out, so the validation figures flatter the calibration: give rows measured apart, or leave `validation` out to hold out a seeded fifth",
                    self.identical, self.pairs
                ),
            )
        })
    }

    /// One sentence for reports: the pairs, the RMS, the shift and the scatter.
    pub fn describe(&self) -> String {
        let [x, y, z] = self.mean_shift_mm;
        let shift = (x * x + y * y + z * z).sqrt();
        let mut text = format!(
            "{} validation rows repeat an identification posture; measured there twice, without any model, the positions differ by {:.3} mm RMS: a mean shift of {:.3} mm ({:.2}, {:.2}, {:.2}) and {:.3} mm about it. No calibration removes this: it is the floor under the held-out error of those rows",
            self.pairs, self.rms_mm, shift, x, y, z, self.scatter_mm
        );
        if self.shifted {
            text.push_str(
                "; the shift stands out of the scatter, so the validation data were taken in another frame or robot state than the identification data (a moved or re-calibrated tracker, a re-seated marker, a warmer robot)",
            );
            text.push_str(match self.sessions {
                SessionLabels::Unnamed => ": give each day its `session` so its frame is fitted, and read the re-registered validation figures",
                SessionLabels::Separate => ": each validation session is also re-registered (its own frame fitted): read those figures under \"Sessions\"",
                SessionLabels::Shared => ": some validation rows name the session of the identification rows they repeat; give each day a `session` of its own so its frame is fitted, and read the re-registered validation figures",
            });
        }
        text
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_common_shift_stands_out_of_the_scatter() {
        let scatter: Vec<Vec3> = (0..40)
            .map(|i| {
                let t = i as f64;
                Vec3::new((t * 1.3).sin(), (t * 2.1).cos(), (t * 0.7).sin()) * 0.5
            })
            .collect();
        let plain = summarise(&scatter).unwrap();
        assert!(!plain.shifted, "{plain:?}");
        assert!(plain.rms_mm < 0.7, "{plain:?}");
        let shifted: Vec<Vec3> = scatter
            .iter()
            .map(|v| v + Vec3::new(0.4, -0.8, -0.4))
            .collect();
        let moved = summarise(&shifted).unwrap();
        assert!(moved.shifted, "{moved:?}");
        assert!((moved.mean_shift_mm[1] - (plain.mean_shift_mm[1] - 0.8)).abs() < 1e-12);
        assert!((moved.scatter_mm - plain.scatter_mm).abs() < 1e-12);
        assert!(summarise(&scatter[..4]).is_none());
    }

    /// Validation rows that are the identification rows again (the same file given twice)
    /// are named as not held out; a real repeat (another measurement, 1 mm apart) is not.
    #[test]
    fn validation_rows_that_are_identification_rows_are_not_held_out() {
        let (identification, _) = shifted_sets(None, None);
        let places: Vec<(Stratum, Option<usize>)> =
            (0..20).map(|i| (Stratum::Repeat, Some(i))).collect();
        let same = repeatability_of(&identification, &identification, &places).unwrap();
        assert_eq!((same.identical, same.pairs), (20, 20));
        let finding = same.not_held_out().expect("a warning");
        assert!(
            finding.message.starts_with("20 of the 20 validation rows"),
            "{finding:?}"
        );
        let (_, held) = shifted_sets(None, None);
        let places: Vec<(Stratum, Option<usize>)> = (0..20)
            .map(|i| (Stratum::Repeat, Some(i * 7 % 20)))
            .collect();
        let apart = repeatability_of(&identification, &held, &places).unwrap();
        assert_eq!(apart.identical, 0);
        assert!(apart.not_held_out().is_none());
    }

    /// Rows at one posture each, the validation rows shifted by 1 mm, the sessions named
    /// `training` and `validation`.
    fn shifted_sets(
        training: Option<&str>,
        validation: Option<&str>,
    ) -> (Vec<Measurement>, Vec<Measurement>) {
        let row = |i: usize, offset: f64, session: Option<&str>| {
            let t = i as f64;
            let p = Vec3::new((t * 1.3).sin(), (t * 2.1).cos(), (t * 0.7).sin()) * 5e-4;
            Measurement {
                tool: 0,
                q: vec![t],
                observation: Observation::Position(p + Vec3::new(offset, 0.0, 0.0)),
                stage: None,
                payload: None,
                session: session.map(str::to_owned),
            }
        };
        let identification = (0..20).map(|i| row(i, 0.0, training)).collect();
        let validation = (0..20).map(|i| row(i * 7 % 20, 1e-3, validation)).collect();
        (identification, validation)
    }

    /// The advice of a shift asks only for what the user has not done: a `session` per day
    /// when no row names one or a validation row shares its training row's session, never
    /// when every validation session is its own (then re-registered).
    #[test]
    fn a_shift_asks_for_sessions_only_when_they_are_missing() {
        let describe = |training, validation| {
            let (identification, held) = shifted_sets(training, validation);
            let places: Vec<(Stratum, Option<usize>)> = (0..20)
                .map(|i| (Stratum::Repeat, Some(i * 7 % 20)))
                .collect();
            let r = repeatability_of(&identification, &held, &places).unwrap();
            assert!(r.shifted, "{r:?}");
            (r.sessions, r.describe())
        };
        let (labels, text) = describe(None, None);
        assert_eq!(labels, SessionLabels::Unnamed);
        assert!(text.contains("give each day its `session`"), "{text}");
        for (training, validation) in [(None, Some("day2")), (Some("day1"), Some("day2"))] {
            let (labels, text) = describe(training, validation);
            assert_eq!(labels, SessionLabels::Separate);
            assert!(!text.contains("`session`"), "{text}");
            assert!(
                text.contains("each validation session is also re-registered"),
                "{text}"
            );
        }
        let (labels, text) = describe(Some("day1"), Some("day1"));
        assert_eq!(labels, SessionLabels::Shared);
        assert!(text.contains("a `session` of its own"), "{text}");
    }
}
