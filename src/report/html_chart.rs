//! The chart of parameter changes in `report.html`: one row per parameter, a bar from zero to
//! its change and a whisker of ±1 standard deviation, lengths (mm) and angles (deg) in panels
//! of their own (their scales differ). Plain SVG text, so the page needs no library.

use super::html_escape::escape;
use crate::calibration::ParameterEstimate;
use std::fmt::Write;

const ROW: f64 = 16.0;
const LABEL_WIDTH: f64 = 260.0;
const PLOT_WIDTH: f64 = 480.0;
const VALUE_WIDTH: f64 = 160.0;
const TOP: f64 = 44.0;
const BOTTOM: f64 = 16.0;

/// The panels as inline SVG elements: the joint frames' lengths (mm) and angles (deg), then
/// the tool frames' (owners among `tools`). A measured body sits centimetres and tens of
/// degrees from its tool link, so on one scale with the joints it flattens every joint
/// correction of a few millimetres to nothing.
pub fn parameter_chart_svg(parameters: &[ParameterEstimate], tools: &[&str]) -> String {
    let (tool_rows, joint_rows): (Vec<&ParameterEstimate>, Vec<&ParameterEstimate>) = parameters
        .iter()
        .partition(|p| tools.contains(&p.owner.as_str()));
    let mut out = String::new();
    for (frames, rows) in [("", &joint_rows), ("Tool frame ", &tool_rows)] {
        let (angles, lengths): (Vec<&ParameterEstimate>, Vec<&ParameterEstimate>) =
            rows.iter().partition(|p| p.unit == "rad");
        let degree = 180.0 / std::f64::consts::PI;
        for (title, unit, scale, set) in [
            ("length parameters", "mm", 1e3, &lengths),
            ("angle parameters", "deg", degree, &angles),
        ] {
            if !set.is_empty() {
                let title = match frames {
                    "" => format!("{}{}", title[..1].to_uppercase(), &title[1..]),
                    _ => format!("{frames}{title}"),
                };
                out.push_str(&panel(&title, unit, scale, set));
            }
        }
    }
    out
}

/// A round step near `range / 4` (1, 2 or 5 times a power of ten).
fn tick_step(range: f64) -> f64 {
    let raw = range / 4.0;
    let power = 10f64.powf(raw.log10().floor());
    [1.0, 2.0, 5.0, 10.0]
        .iter()
        .map(|m| m * power)
        .find(|s| *s >= raw)
        .unwrap_or(10.0 * power)
}

fn panel(title: &str, unit: &str, scale: f64, set: &[&ParameterEstimate]) -> String {
    let extent = set
        .iter()
        .map(|p| (p.change.abs() + p.std_dev.filter(|s| s.is_finite()).unwrap_or(0.0)) * scale)
        .filter(|v| v.is_finite())
        .fold(0.0, f64::max);
    let extent = if extent > 0.0 { extent * 1.05 } else { 1.0 };
    let width = LABEL_WIDTH + PLOT_WIDTH + VALUE_WIDTH;
    let height = TOP + BOTTOM + ROW * set.len() as f64;
    let zero = LABEL_WIDTH + PLOT_WIDTH / 2.0;
    let x = |v: f64| zero + (v / extent).clamp(-1.0, 1.0) * PLOT_WIDTH / 2.0;
    let mut out = String::new();
    let _ = writeln!(
        out,
        "<svg class=\"parameters\" xmlns=\"http://www.w3.org/2000/svg\" width=\"{width}\" height=\"{height}\" viewBox=\"0 0 {width} {height}\" font-family=\"sans-serif\" font-size=\"11\">\n<text x=\"{}\" y=\"16\" font-size=\"14\" text-anchor=\"middle\">{} (change, {unit}; whisker ±1σ)</text>",
        width / 2.0,
        escape(title)
    );
    let step = tick_step(extent);
    let mut tick = -(extent / step).floor() * step;
    while tick <= extent + 1e-12 * step {
        let at = x(tick);
        let _ = writeln!(
            out,
            "<line x1=\"{at:.1}\" y1=\"{:.1}\" x2=\"{at:.1}\" y2=\"{:.1}\" stroke=\"#ddd\"/><text x=\"{at:.1}\" y=\"{:.1}\" text-anchor=\"middle\" fill=\"#555\">{}</text>",
            TOP - 8.0,
            height - BOTTOM,
            TOP - 12.0,
            format_tick(tick, step)
        );
        tick += step;
    }
    let _ = writeln!(
        out,
        "<line x1=\"{zero}\" y1=\"{}\" x2=\"{zero}\" y2=\"{}\" stroke=\"#333\"/>",
        TOP - 8.0,
        height - BOTTOM
    );
    for (row, p) in set.iter().enumerate() {
        let y = TOP + ROW * row as f64;
        let change = p.change * scale;
        let colour = if p.identifiable { "#0072B2" } else { "#aaaaaa" };
        let (left, right) = if change < 0.0 {
            (x(change), zero)
        } else {
            (zero, x(change))
        };
        let sigma = p.std_dev.filter(|s| s.is_finite()).map(|s| s * scale);
        let _ = write!(
            out,
            "<g><title>{} {}: change {change:+.4} {unit}{}</title><text x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"end\">{} {}</text><rect x=\"{left:.2}\" y=\"{:.1}\" width=\"{:.2}\" height=\"{:.1}\" fill=\"{colour}\"/>",
            escape(&p.owner),
            escape(&p.kind),
            sigma.map_or(String::new(), |s| format!(", σ {s:.4} {unit}")),
            LABEL_WIDTH - 6.0,
            y + ROW * 0.7,
            escape(&p.owner),
            escape(&p.kind),
            y + 3.0,
            (right - left).max(0.5),
            ROW - 6.0
        );
        if let Some(s) = sigma {
            let (a, b, mid) = (x(change - s), x(change + s), y + ROW / 2.0);
            let _ = write!(
                out,
                "<line x1=\"{a:.2}\" y1=\"{mid:.1}\" x2=\"{b:.2}\" y2=\"{mid:.1}\" stroke=\"#333\"/><line x1=\"{a:.2}\" y1=\"{:.1}\" x2=\"{a:.2}\" y2=\"{:.1}\" stroke=\"#333\"/><line x1=\"{b:.2}\" y1=\"{:.1}\" x2=\"{b:.2}\" y2=\"{:.1}\" stroke=\"#333\"/>",
                mid - 3.0,
                mid + 3.0,
                mid - 3.0,
                mid + 3.0
            );
        }
        let _ = writeln!(
            out,
            "<text x=\"{:.1}\" y=\"{:.1}\" fill=\"#333\">{change:+.4}{}</text></g>",
            LABEL_WIDTH + PLOT_WIDTH + 8.0,
            y + ROW * 0.7,
            sigma.map_or(String::new(), |s| format!(" ± {s:.4}"))
        );
    }
    out.push_str("</svg>\n");
    out
}

/// A tick label with as many decimals as the step needs.
fn format_tick(value: f64, step: f64) -> String {
    let decimals = (-step.log10().floor()).max(0.0) as usize;
    let text = format!("{value:.decimals$}");
    if text
        .trim_start_matches('-')
        .chars()
        .all(|c| c == '0' || c == '.')
    {
        "0".into()
    } else {
        text
    }
}
