//! The plots' axes: a y axis with round steps and exact labels, x ticks that fit, and a
//! plotters axis with given tick positions.

use plotters::coord::ranged1d::{DefaultFormatting, KeyPointHint, Ranged};
use plotters::coord::types::RangedCoordf64;

/// The y axis: 0 to a round top value in 4–6 round steps, with labels built from integers so
/// that they are exact ("0.3", not "0.30000000000000004").
pub(super) struct YAxis {
    pub(super) top: f64,
    pub(super) ticks: Vec<(f64, String)>,
}

impl YAxis {
    /// The axis for data whose largest value is `max` (≥ 0); `None` beyond 1e±300.
    pub(super) fn covering(max: f64) -> Option<YAxis> {
        if max == 0.0 {
            // All zero: any range shows the points on the axis; 0 to 1 reads best.
            return Some(YAxis::from_step(20, -2, 5));
        }
        if !(1e-300..=1e300).contains(&max) {
            return None;
        }
        // A step is `mantissa · 10^exponent`, the mantissa 10, 20, 25 or 50 (1, 2, 2.5, 5 in
        // tenths) so that every tick is an integer times a power of ten.
        let mut exponent = (max / 6.0).log10().floor() as i32 - 2;
        loop {
            for mantissa in [10_u64, 20, 25, 50] {
                let step = mantissa as f64 * 10f64.powi(exponent);
                // A hair of tolerance so that a value equal to a tick in exact arithmetic does
                // not get an extra, empty interval.
                let intervals = (max / step * (1.0 - 1e-12)).ceil().max(1.0);
                if intervals <= 6.0 {
                    return Some(YAxis::from_step(mantissa, exponent, intervals as u64));
                }
            }
            exponent += 1;
        }
    }

    /// Ticks at `k · mantissa · 10^exponent` for k = 0..=intervals.
    fn from_step(mantissa: u64, exponent: i32, intervals: u64) -> YAxis {
        let integers: Vec<u64> = (0..=intervals).map(|k| k * mantissa).collect();
        let top_digits = integers[integers.len() - 1].to_string().len() as i32;
        // Fixed notation between steps of 0.001 and tops below a million, as "2.0e-7" otherwise.
        let scientific = exponent + 1 < -3 || top_digits + exponent > 6;
        let labels = if scientific {
            scientific_labels(&integers, exponent)
        } else {
            fixed_labels(&integers, exponent)
        };
        let ticks = integers
            .iter()
            .zip(labels)
            .map(|(&n, label)| (scaled(n, exponent), label))
            .collect::<Vec<_>>();
        YAxis {
            top: ticks[ticks.len() - 1].0,
            ticks,
        }
    }

    pub(super) fn label(&self, value: f64) -> String {
        self.ticks
            .iter()
            .min_by(|a, b| (a.0 - value).abs().total_cmp(&(b.0 - value).abs()))
            .map(|tick| tick.1.clone())
            .unwrap_or_default()
    }
}

/// `n · 10^exponent`, dividing by an exact power of ten where possible.
fn scaled(n: u64, exponent: i32) -> f64 {
    if exponent >= 0 {
        n as f64 * 10f64.powi(exponent)
    } else {
        n as f64 / 10f64.powi(-exponent)
    }
}

/// Decimal labels with the same number of decimals on every tick ("0.0", "0.5", "1.0").
fn fixed_labels(integers: &[u64], exponent: i32) -> Vec<String> {
    let shift = (-exponent).max(0) as usize;
    let digits: Vec<String> = integers
        .iter()
        .map(|&n| {
            if exponent > 0 && n != 0 {
                format!("{n}{}", "0".repeat(exponent as usize))
            } else {
                format!("{n:0>width$}", width = shift + 1)
            }
        })
        .collect();
    let decimals = digits
        .iter()
        .map(|d| d[d.len() - shift..].trim_end_matches('0').len())
        .max()
        .unwrap_or(0);
    digits
        .iter()
        .map(|d| {
            let (whole, fraction) = d.split_at(d.len() - shift);
            if decimals == 0 {
                whole.to_string()
            } else {
                format!("{whole}.{}", &fraction[..decimals])
            }
        })
        .collect()
}

/// Scientific labels with the same number of mantissa decimals on every tick ("2.0e-7").
fn scientific_labels(integers: &[u64], exponent: i32) -> Vec<String> {
    let parts: Vec<Option<(String, i32)>> = integers
        .iter()
        .map(|&n| {
            (n != 0).then(|| {
                let digits = n.to_string();
                let fraction = digits[1..].trim_end_matches('0').to_string();
                (
                    format!("{}{fraction}", &digits[..1]),
                    exponent + digits.len() as i32 - 1,
                )
            })
        })
        .collect();
    let decimals = parts
        .iter()
        .flatten()
        .map(|(m, _)| m.len() - 1)
        .max()
        .unwrap_or(0)
        .max(1);
    parts
        .into_iter()
        .map(|part| match part {
            None => "0".to_string(),
            Some((mantissa, power)) => {
                format!("{}.{:0<decimals$}e{power}", &mantissa[..1], &mantissa[1..])
            }
        })
        .collect()
}

/// X ticks: every configuration while the labels (of up to `characters` characters) fit, else
/// every 2nd, 5th, 10th, ... (and 1).
pub(super) fn x_ticks(configurations: usize, characters: usize, plot_width: u32) -> Vec<f64> {
    let room_per_label = characters as f64 * 8.0 + 14.0;
    let per_configuration = f64::from(plot_width) / configurations as f64;
    let step = [1_u64, 2, 5]
        .iter()
        .flat_map(|&m| (0..19).map(move |e| m * 10_u64.pow(e)))
        .filter(|&s| s as f64 * per_configuration >= room_per_label)
        .min()
        .unwrap_or(u64::MAX);
    let mut ticks: Vec<usize> = (1..=configurations)
        .filter(|&c| c as u64 % step == 0)
        .collect();
    // "1" marks the start; it would crowd "2" when every second configuration is labelled.
    if step != 2 && ticks.first() != Some(&1) {
        ticks.insert(0, 1);
    }
    ticks.into_iter().map(|c| c as f64).collect()
}

/// A linear axis with the tick positions given, and no minor ticks.
///
/// plotters' own `with_key_points` wrapper has no label formatter for `f64`, so the mesh cannot
/// be drawn with it; this is that wrapper with one.
pub(super) struct TickedAxis {
    linear: RangedCoordf64,
    ticks: Vec<f64>,
}

impl TickedAxis {
    pub(super) fn new(range: std::ops::Range<f64>, ticks: Vec<f64>) -> TickedAxis {
        TickedAxis {
            linear: range.into(),
            ticks,
        }
    }
}

impl Ranged for TickedAxis {
    // Labels always come from our own formatters; Debug is only the fallback plotters requires.
    type FormatOption = DefaultFormatting;
    type ValueType = f64;

    fn map(&self, value: &f64, limit: (i32, i32)) -> i32 {
        self.linear.map(value, limit)
    }

    fn key_points<Hint: KeyPointHint>(&self, hint: Hint) -> Vec<f64> {
        if hint.weight().allow_light_points() {
            Vec::new()
        } else {
            self.ticks.clone()
        }
    }

    fn range(&self) -> std::ops::Range<f64> {
        self.linear.range()
    }
}
