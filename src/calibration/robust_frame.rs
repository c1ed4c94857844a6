//! A session's measurement frame fitted robustly, for scoring fresh rows (`treecal verify`):
//! the least-squares frame, then frames reweighted by the robust loss until the weights
//! settle (which names the rows that stand out), then the least-squares frame without the
//! gross blunders among them (a bumped target, a mistyped value: [`gross_rows`]). One blunder
//! no longer drags the frame, and with it every other row, off; without one the frame is the
//! plain least-squares frame.

use super::loss::{chi_median, median_scale, RobustLoss, OUTLIER_WEIGHT};
use super::options::IdentificationOptions;
use super::robust::MAX_ROUNDS;
use super::session_frame::{fit_session_frame, weighted_error};
use crate::math::Pose;
use crate::measurement::Measurement;

/// A robustly fitted frame.
#[derive(Debug, Clone)]
pub struct RobustFrame {
    /// The correction applied to the predictions (measured ≈ frame · predicted).
    pub frame: Pose,
    /// How many of the six frame directions the rows determine.
    pub determined: usize,
    /// Per row: whether it stands out from the others (weight below [`OUTLIER_WEIGHT`]).
    pub outliers: Vec<bool>,
    /// Per row: whether it is a gross blunder ([`gross_rows`]), left out of the final fit.
    pub gross: Vec<bool>,
}

/// A flagged row is a gross blunder when its position error is at least this many times the
/// RMS of the rows not flagged: a bumped target, a mistyped value (the real cases: 28× on a
/// second robot, 470× for a mistyped TIAGo joint value), not the model error of an unusual
/// posture (TIAGo's worst held-out postures: 4–6×), which stays in every judgement.
pub const GROSS_FACTOR: f64 = 10.0;

/// Per row: flagged (`flagged`) with a position error (`errors`, any unit) of at least
/// [`GROSS_FACTOR`] times the RMS of the rows not flagged; none while they would be half the
/// rows or more (then they are the data, not blunders).
pub fn gross_rows(errors: &[f64], flagged: &[bool]) -> Vec<bool> {
    let kept: Vec<f64> = errors
        .iter()
        .zip(flagged)
        .filter(|(_, &f)| !f)
        .map(|(&e, _)| e)
        .collect();
    let Some(rms) = crate::math::root_mean_square(&kept) else {
        return vec![false; errors.len()];
    };
    let gross: Vec<bool> = errors
        .iter()
        .zip(flagged)
        .map(|(&e, &f)| f && e >= GROSS_FACTOR * rms)
        .collect();
    if 2 * gross.iter().filter(|&&g| g).count() >= errors.len() {
        vec![false; errors.len()]
    } else {
        gross
    }
}

/// The frame that maps `predicted` onto `measured` (one per row), robust under `loss`
/// ([`RobustLoss::Off`]: the least-squares frame, no row flagged).
pub fn fit_session_frame_robust(
    predicted: &[Pose],
    measured: &[&Measurement],
    options: &IdentificationOptions,
    loss: RobustLoss,
) -> RobustFrame {
    let mut frame = fit_session_frame(predicted, measured, &[], options).0;
    let mut weights = vec![1.0; measured.len()];
    if loss != RobustLoss::Off {
        for _ in 0..MAX_ROUNDS {
            let next = row_weights(loss, &norms(&frame, predicted, measured, options), measured);
            let settled = next.iter().zip(&weights).all(|(a, b)| (a - b).abs() < 1e-3);
            weights = next;
            frame = fit_session_frame(predicted, measured, &weights, options).0;
            if settled {
                break;
            }
        }
    }
    let outliers: Vec<bool> = weights.iter().map(|&w| w < OUTLIER_WEIGHT).collect();
    let gross = gross_rows(&position_errors(&frame, predicted, measured), &outliers);
    // The frame: least squares over every row but the gross blunders (the plain least-squares
    // frame when there is none).
    let kept: Vec<f64> = gross.iter().map(|&g| if g { 0.0 } else { 1.0 }).collect();
    let (frame, determined) = fit_session_frame(predicted, measured, &kept, options);
    RobustFrame {
        frame,
        determined,
        outliers,
        gross,
    }
}

/// Per row: `‖W·r‖` at `frame` (the errors over the declared σ's).
fn norms(
    frame: &Pose,
    predicted: &[Pose],
    measured: &[&Measurement],
    options: &IdentificationOptions,
) -> Vec<f64> {
    let sigma = [options.position_sigma, options.rotation_sigma];
    predicted
        .iter()
        .zip(measured)
        .map(|(p, m)| weighted_error(m, &(frame * p), sigma).1.sqrt())
        .collect()
}

/// Per row: the position error (m) at `frame` (rotation rows weigh nothing).
fn position_errors(frame: &Pose, predicted: &[Pose], measured: &[&Measurement]) -> Vec<f64> {
    predicted
        .iter()
        .zip(measured)
        .map(|(p, m)| {
            weighted_error(m, &(frame * p), [1.0, f64::INFINITY])
                .1
                .sqrt()
        })
        .collect()
}

/// Per row: the loss's weight at the rows' own robust scale (the median of the norms over
/// their clean median, floored like the calibration's robust scale): a row gets less than
/// [`OUTLIER_WEIGHT`] only by standing out from the others.
pub fn row_weights(loss: RobustLoss, norms: &[f64], measured: &[&Measurement]) -> Vec<f64> {
    let scale = median_scale(
        norms
            .iter()
            .zip(measured)
            .map(|(n, m)| n / chi_median(m.observation.rows())),
    );
    norms
        .iter()
        .zip(measured)
        .map(|(n, m)| loss.weight(n / scale, m.observation.rows()))
        .collect()
}

/// Per row: whether it is a gross blunder ([`gross_rows`] of the rows that stand out under
/// `loss`) with the frame as given (nothing refitted).
pub fn gross_blunders(
    predicted: &[Pose],
    measured: &[&Measurement],
    options: &IdentificationOptions,
    loss: RobustLoss,
) -> Vec<bool> {
    let identity = Pose::identity();
    let flagged: Vec<bool> = row_weights(
        loss,
        &norms(&identity, predicted, measured, options),
        measured,
    )
    .iter()
    .map(|&w| w < OUTLIER_WEIGHT)
    .collect();
    gross_rows(&position_errors(&identity, predicted, measured), &flagged)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Vec3;
    use crate::measurement::Observation;
    use nalgebra::{Translation3, UnitQuaternion};
    use rand::rngs::ChaCha8Rng;
    use rand::{RngExt, SeedableRng};

    /// 30 positions seen through `truth` with 0.1 mm noise; row 7 bumped by `bump` (m).
    fn rows(truth: &Pose, bump: f64) -> (Vec<Pose>, Vec<Measurement>) {
        let mut rng = ChaCha8Rng::seed_from_u64(29);
        let mut predicted = Vec::new();
        let mut measured = Vec::new();
        for i in 0..30 {
            let mut r = || rng.random_range(-0.8..0.8);
            let p = Pose::from_parts(
                Translation3::new(r(), r(), r() + 1.0),
                UnitQuaternion::identity(),
            );
            let noise = Vec3::new(r(), r(), r()) * 1.25e-4;
            let mut at = (truth * p).translation.vector + noise;
            if i == 7 {
                at.x += bump;
            }
            predicted.push(p);
            measured.push(Measurement {
                tool: 0,
                q: Vec::new(),
                observation: Observation::Position(at),
                stage: None,
                payload: None,
                session: None,
            });
        }
        (predicted, measured)
    }

    #[test]
    fn a_gross_blunder_does_not_drag_the_frame_and_clean_rows_give_least_squares() {
        let truth = Pose::from_parts(
            Translation3::new(0.4, -1.2, 0.3),
            UnitQuaternion::from_euler_angles(0.1, -0.2, 0.7),
        );
        let options = IdentificationOptions::default();
        let (predicted, clean) = rows(&truth, 0.0);
        let refs: Vec<&Measurement> = clean.iter().collect();
        let robust = fit_session_frame_robust(&predicted, &refs, &options, RobustLoss::Huber);
        let plain = fit_session_frame(&predicted, &refs, &[], &options).0;
        assert_eq!(
            robust.frame, plain,
            "without a blunder: the least-squares frame"
        );
        assert!(robust.gross.iter().all(|g| !g));
        let (predicted, bumped) = rows(&truth, 0.3);
        let refs: Vec<&Measurement> = bumped.iter().collect();
        let robust = fit_session_frame_robust(&predicted, &refs, &options, RobustLoss::Huber);
        let plain = fit_session_frame(&predicted, &refs, &[], &options).0;
        let off = |frame: &Pose| (frame.translation.vector - truth.translation.vector).norm();
        assert_eq!(
            robust.gross.iter().position(|&g| g),
            Some(7),
            "{:?}",
            robust.gross
        );
        assert!(off(&robust.frame) < 2e-4, "{}", off(&robust.frame));
        assert!(off(&plain) > 5.0 * off(&robust.frame), "{}", off(&plain));
        assert_eq!(
            gross_blunders(
                &predicted
                    .iter()
                    .map(|p| robust.frame * p)
                    .collect::<Vec<_>>(),
                &refs,
                &options,
                RobustLoss::Huber
            )
            .iter()
            .filter(|&&g| g)
            .count(),
            1
        );
    }
}
