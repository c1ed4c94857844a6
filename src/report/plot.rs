//! SVG plots of per-configuration errors, in the style of the paper's Fig. 7–12.
//!
//! One plot has the configurations on the x axis (labelled by the measurement rows' ids, or
//! 1..n) and an error magnitude on the y axis from 0, one line with point markers per series
//! (before calibration, after calibration, ...), a legend and a title. The SVG comes back as a
//! string; writing it is the caller's job.
//!
//! Errors after calibration are often a thousandth of those before (0.05 mm against 50 mm): on
//! one linear axis they would lie flat on the zero line. So a series much smaller than the
//! ones before it gets a panel of its own below, with its own linear axis from 0 (see
//! [`error_plot_svg`]). Panels rather than a log axis: values read directly in mm on every
//! panel, a zero (a noise-free simulation) stays drawable, and the before curve keeps the
//! paper's linear look.
//!
//! Text is emitted as SVG `<text>` elements in a generic `sans-serif` family, so no font is read
//! here or needed to view the file; layout uses plotters' built-in width estimate (its `ttf`
//! feature, which would read system fonts, is off).
//!
//! [`line_plot_svg`] draws the same look over arbitrary x values (e.g. validation error against
//! the number of poses), with an optional spread per point drawn as an error bar.

use crate::error::{Error, Result};
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

mod axes;
use axes::{x_ticks, TickedAxis, YAxis};

mod line;
pub use line::{line_plot_svg, Curve, LinePlot};

/// One curve: a value per configuration, in configuration order.
#[derive(Debug, Clone, PartialEq)]
pub struct Series {
    /// Legend text, e.g. "before calibration".
    pub label: String,
    /// One non-negative value per configuration.
    pub values: Vec<f64>,
}

/// A per-configuration error plot such as the paper's Fig. 7.
#[derive(Debug, Clone, PartialEq)]
pub struct ErrorPlot {
    /// Title above the plot.
    pub title: String,
    /// Y-axis label with its unit, e.g. "position error (mm)".
    pub y_label: String,
    /// The curves; all of the same length.
    pub series: Vec<Series>,
    /// One x label per configuration, e.g. the measurement rows' ids; empty: 1..n.
    pub x_labels: Vec<String>,
}

const WIDTH: u32 = 800;
const HEIGHT: u32 = 450;
/// Height added per panel after the first.
const PANEL_HEIGHT: u32 = 280;
/// A series opens a new panel when its largest value and the panel's differ more than this
/// many times (it would use less than a fifth of the panel's height).
const PANEL_RATIO: f64 = 5.0;
const FONT: FontFamily = FontFamily::SansSerif;
// plotters font sizes; the SVG backend writes `font-size` as these divided by 1.24.
const TITLE_SIZE: f64 = 22.0;
const AXIS_DESC_SIZE: f64 = 17.0;
const LABEL_SIZE: f64 = 15.0;
const TITLE_HEIGHT: u32 = 34;
const LEGEND_ROW_HEIGHT: u32 = 22;
const LEGEND_SAMPLE: i32 = 30;
const LEGEND_GAP: i32 = 28;
const X_LABEL_AREA: u32 = 50;
const MARGIN_RIGHT: u32 = 24;
// Colour-blind-safe (Okabe–Ito) colours of different lightness; marker shapes differ as well,
// so the series stay apart when printed in greyscale.
const COLOURS: [RGBColor; 6] = [
    RGBColor(0x00, 0x72, 0xB2),
    RGBColor(0xD5, 0x5E, 0x00),
    RGBColor(0x00, 0x9E, 0x73),
    RGBColor(0xCC, 0x79, 0xA7),
    RGBColor(0x56, 0xB4, 0xE9),
    RGBColor(0x33, 0x33, 0x33),
];
const GRID: RGBColor = RGBColor(0xDD, 0xDD, 0xDD);

#[derive(Debug, Clone, Copy)]
enum Marker {
    Circle,
    Square,
    TriangleUp,
    Diamond,
    TriangleDown,
    Cross,
}

const MARKERS: [Marker; 6] = [
    Marker::Circle,
    Marker::Square,
    Marker::TriangleUp,
    Marker::Diamond,
    Marker::TriangleDown,
    Marker::Cross,
];
// Markers closer than this (pixels) are drawn only on every k-th configuration.
const MARKER_SPACING: f64 = 12.0;

/// The position and orientation plots of one arm (paper Fig. 7–12 style): one curve per
/// label, `position_mm[k]` and `orientation_deg[k]` per configuration. Returns
/// `(file stem, SVG)` pairs, `<stem>_<quantity>` with `/` replaced; a quantity without values
/// (orientation of position-only data) is left out.
pub fn arm_error_plots(
    arm: &str,
    stem: &str,
    title: &str,
    labels: &[&str],
    position_mm: &[Vec<f64>],
    orientation_deg: &[Vec<f64>],
) -> Result<Vec<(String, String)>> {
    arm_error_plots_by_id(arm, stem, title, labels, &[], position_mm, orientation_deg)
}

/// [`arm_error_plots`] with the x axis labelled by `ids` (one per configuration; empty: 1..n).
pub fn arm_error_plots_by_id(
    arm: &str,
    stem: &str,
    title: &str,
    labels: &[&str],
    ids: &[String],
    position_mm: &[Vec<f64>],
    orientation_deg: &[Vec<f64>],
) -> Result<Vec<(String, String)>> {
    let mut plots = Vec::new();
    for (what, unit, values) in [
        ("position", "position error (mm)", position_mm),
        ("orientation", "orientation error (deg)", orientation_deg),
    ] {
        if values.iter().all(Vec::is_empty) {
            continue;
        }
        let title = format!("{arm}: {what} error {title}");
        let plot = PlotView {
            title: &title,
            y_label: unit,
            series: labels
                .iter()
                .zip(values)
                .map(|(label, values)| SeriesView { label, values })
                .collect(),
            x_labels: ids,
        };
        plots.push((
            format!("{}_{what}", stem.replace('/', "_")),
            view_svg(&plot)?,
        ));
    }
    Ok(plots)
}

/// Renders `plot` as an SVG document 800 pixels wide: 450 high for one panel, 280 more per
/// further panel.
///
/// The first series opens the first panel; each later series joins the current panel unless
/// its largest value and the panel's differ by more than 5×, in which case it opens a new
/// panel below with its own y axis from 0. Every panel has the same x axis, labelled by
/// `x_labels` (thinned so that they do not overlap).
///
/// Fails, naming the series and index, on an empty plot, series of different lengths, `x_labels`
/// of another length, and non-finite or negative values (errors are magnitudes and the y axis
/// starts at 0).
pub fn error_plot_svg(plot: &ErrorPlot) -> Result<String> {
    view_svg(&PlotView {
        title: &plot.title,
        y_label: &plot.y_label,
        series: plot
            .series
            .iter()
            .map(|s| SeriesView {
                label: &s.label,
                values: &s.values,
            })
            .collect(),
        x_labels: &plot.x_labels,
    })
}

/// An [`ErrorPlot`] of borrowed parts: an arm's plots share its labels and columns (at 10⁶
/// configurations, copies of 8·10⁵ labels per plot).
struct PlotView<'a> {
    title: &'a str,
    y_label: &'a str,
    series: Vec<SeriesView<'a>>,
    x_labels: &'a [String],
}

/// A [`Series`] of borrowed parts.
struct SeriesView<'a> {
    label: &'a str,
    values: &'a [f64],
}

/// [`error_plot_svg`] of a [`PlotView`].
fn view_svg(plot: &PlotView<'_>) -> Result<String> {
    let configurations = validate(plot)?;
    let mut panels = Vec::new();
    for (series, max) in panel_groups(plot) {
        let y_axis = YAxis::covering(max).ok_or_else(|| {
            invalid(
                plot,
                format!("the largest value {max:e} is outside the range a plot can label"),
            )
        })?;
        panels.push(Panel { series, y_axis });
    }
    render(plot, configurations, &panels).map_err(|e| invalid(plot, format!("drawing failed: {e}")))
}

/// The series of one panel (indices into the plot's) and its y axis.
struct Panel {
    series: Vec<usize>,
    y_axis: YAxis,
}

/// The series grouped into panels, with each panel's largest value.
fn panel_groups(plot: &PlotView<'_>) -> Vec<(Vec<usize>, f64)> {
    let mut groups: Vec<(Vec<usize>, f64)> = Vec::new();
    for (index, series) in plot.series.iter().enumerate() {
        let max = series.values.iter().copied().fold(0.0, f64::max);
        match groups.last_mut() {
            Some((members, panel_max))
                if max * PANEL_RATIO >= *panel_max && *panel_max * PANEL_RATIO >= max =>
            {
                members.push(index);
                *panel_max = panel_max.max(max);
            }
            _ => groups.push((vec![index], max)),
        }
    }
    groups
}

fn invalid(plot: &PlotView<'_>, message: String) -> Error {
    invalid_titled(plot.title, message)
}

fn invalid_titled(title: &str, message: String) -> Error {
    Error::InvalidData {
        origin: format!("plot '{title}'"),
        message,
    }
}

/// Checks the data and returns the number of configurations.
fn validate(plot: &PlotView<'_>) -> Result<usize> {
    let Some(first) = plot.series.first() else {
        return Err(invalid(plot, "nothing to plot: no series".into()));
    };
    let configurations = first.values.len();
    if configurations == 0 {
        return Err(invalid(
            plot,
            format!("nothing to plot: series '{}' has no values", first.label),
        ));
    }
    if !plot.x_labels.is_empty() && plot.x_labels.len() != configurations {
        return Err(invalid(
            plot,
            format!(
                "{} x labels for {configurations} configurations; give one per configuration, \
                 or none",
                plot.x_labels.len()
            ),
        ));
    }
    for series in &plot.series {
        if series.values.len() != configurations {
            return Err(invalid(
                plot,
                format!(
                    "series '{}' has {} values but series '{}' has {}; every series needs one \
                     value per configuration",
                    series.label,
                    series.values.len(),
                    first.label,
                    configurations
                ),
            ));
        }
        for (index, &value) in series.values.iter().enumerate() {
            let problem = if !value.is_finite() {
                format!("the non-finite value {value}")
            } else if value < 0.0 {
                format!("the negative value {value} (errors are magnitudes; the axis starts at 0)")
            } else {
                continue;
            };
            return Err(invalid(
                plot,
                format!(
                    "series '{}' has {problem} at index {index} (configuration {})",
                    series.label,
                    index + 1
                ),
            ));
        }
    }
    Ok(configurations)
}

/// Draws one marker centred on `at`, in pixels of `area`.
///
/// Markers are outlines, as in MATLAB's figures: where two series coincide (after calibration
/// with and without flexibility compensation, when the robot is stiff) both shapes stay visible.
fn draw_marker<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    kind: Marker,
    at: (i32, i32),
    colour: RGBColor,
) -> DrawResult<(), DB> {
    let line = colour.stroke_width(2);
    let origin = EmptyElement::at(at);
    // Outlines repeat their first edge so that the stroke joins at the first corner too.
    let outline = |corners: [(i32, i32); 4]| {
        let mut points = corners.to_vec();
        points.extend_from_slice(&corners[..2]);
        points.dedup();
        PathElement::new(points, line)
    };
    match kind {
        Marker::Circle => area.draw(&(origin + Circle::new((0, 0), 4, line))),
        // (An SVG `<rect>` from plotters ignores the stroke width.)
        Marker::Square => area.draw(&(origin + outline([(-4, -4), (4, -4), (4, 4), (-4, 4)]))),
        Marker::TriangleUp => area.draw(&(origin + outline([(0, -6), (5, 3), (-5, 3), (0, -6)]))),
        Marker::Diamond => area.draw(&(origin + outline([(0, -6), (5, 0), (0, 6), (-5, 0)]))),
        Marker::TriangleDown => area.draw(&(origin + outline([(0, 6), (-5, -3), (5, -3), (0, 6)]))),
        Marker::Cross => area.draw(&(origin + Cross::new((0, 0), 4, line))),
    }
}

fn style_of(index: usize) -> (RGBColor, Marker) {
    // Colour and marker advance together; past six series the markers shift by one per round,
    // which keeps 36 combinations distinct.
    (
        COLOURS[index % COLOURS.len()],
        MARKERS[(index + index / COLOURS.len()) % MARKERS.len()],
    )
}

type DrawResult<T, DB = SVGBackend<'static>> =
    std::result::Result<T, DrawingAreaErrorKind<<DB as DrawingBackend>::ErrorType>>;

fn render(plot: &PlotView<'_>, configurations: usize, panels: &[Panel]) -> DrawResult<String> {
    let mut svg = String::new();
    {
        let height = HEIGHT + PANEL_HEIGHT * (panels.len().max(1) as u32 - 1);
        // The backend borrows `svg` until it is dropped.
        let root = SVGBackend::with_string(&mut svg, (WIDTH, height)).into_drawing_area();
        draw_on(&root, plot, configurations, panels)?;
        root.present()?;
    }
    Ok(svg)
}

/// Fills `root`, draws the title and a legend row (or rows) with one entry per label in series
/// style order, and returns the area left for the chart below them.
fn draw_title_and_legend<'a>(
    root: &DrawingArea<SVGBackend<'a>, Shift>,
    title: &str,
    labels: &[&str],
) -> DrawResult<DrawingArea<SVGBackend<'a>, Shift>> {
    root.fill(&WHITE)?;

    // Title, shrunk when it would not fit the width.
    let (title_width, _) =
        root.estimate_text_size(title, &(FONT, TITLE_SIZE).into_text_style(root))?;
    let room = f64::from(WIDTH - 40);
    let title_size = if f64::from(title_width) > room {
        (TITLE_SIZE * room / f64::from(title_width)).max(9.0)
    } else {
        TITLE_SIZE
    };
    let centred = Pos::new(HPos::Center, VPos::Center);
    root.draw_text(
        title,
        &TextStyle::from((FONT, title_size).into_font()).pos(centred),
        ((WIDTH / 2) as i32, (TITLE_HEIGHT / 2 + 4) as i32),
    )?;

    // The legend sits between title and plot, so it never hides data.
    let label_font = (FONT, LABEL_SIZE).into_text_style(root);
    let mut rows: Vec<Vec<(usize, i32)>> = vec![vec![]];
    let mut row_width = 0;
    for (index, label) in labels.iter().enumerate() {
        let (text_width, _) = root.estimate_text_size(label, &label_font)?;
        let width = LEGEND_SAMPLE + 6 + text_width as i32;
        let needed = if row_width == 0 {
            width
        } else {
            row_width + LEGEND_GAP + width
        };
        if row_width > 0 && needed > (WIDTH - 40) as i32 {
            rows.push(vec![]);
            row_width = width;
        } else {
            row_width = needed;
        }
        // `rows` starts with one empty row, so there is always a last one.
        if let Some(row) = rows.last_mut() {
            row.push((index, width));
        }
    }
    let legend_height = rows.len() as u32 * LEGEND_ROW_HEIGHT + 6;
    let (_, below_title) = root.split_vertically(TITLE_HEIGHT);
    let (legend, chart_area) = below_title.split_vertically(legend_height);
    let left_centred = Pos::new(HPos::Left, VPos::Center);
    for (row_index, row) in rows.iter().enumerate() {
        let total: i32 =
            row.iter().map(|(_, w)| w).sum::<i32>() + LEGEND_GAP * (row.len() as i32 - 1);
        let mut x = (WIDTH as i32 - total) / 2;
        let y = (row_index as u32 * LEGEND_ROW_HEIGHT + LEGEND_ROW_HEIGHT / 2 + 4) as i32;
        for &(index, width) in row {
            let (colour, kind) = style_of(index);
            legend.draw(&Rectangle::new(
                [(x, y - 1), (x + LEGEND_SAMPLE, y + 1)],
                colour.filled(),
            ))?;
            draw_marker(&legend, kind, (x + LEGEND_SAMPLE / 2, y), colour)?;
            legend.draw_text(
                labels[index],
                &label_font.pos(left_centred),
                (x + LEGEND_SAMPLE + 6, y),
            )?;
            x += width + LEGEND_GAP;
        }
    }

    Ok(chart_area)
}

/// Room left of the chart for the widest y tick label, the tick, and the rotated axis
/// description (pixels).
fn y_label_area(root: &DrawingArea<SVGBackend<'_>, Shift>, y_axis: &YAxis) -> DrawResult<u32> {
    let label_font = (FONT, LABEL_SIZE).into_text_style(root);
    let mut widest_tick = 0;
    for (_, label) in &y_axis.ticks {
        widest_tick = widest_tick.max(root.estimate_text_size(label, &label_font)?.0);
    }
    Ok(widest_tick + 44)
}

/// The chart both plots draw into: margins, the given x axis, the y axis from 0, the grid and
/// the axis descriptions `[x, y]`.
fn axes<'a, 'b>(
    chart_area: &'a DrawingArea<SVGBackend<'b>, Shift>,
    y_label_area: u32,
    x_axis: TickedAxis,
    y_axis: &YAxis,
    descriptions: [&str; 2],
    x_format: &dyn Fn(&f64) -> String,
) -> DrawResult<ChartContext<'a, SVGBackend<'b>, Cartesian2d<TickedAxis, TickedAxis>>> {
    let mut chart = ChartBuilder::on(chart_area)
        .margin_top(10)
        .margin_left(8)
        .margin_right(MARGIN_RIGHT)
        .margin_bottom(6)
        .x_label_area_size(X_LABEL_AREA)
        .y_label_area_size(y_label_area)
        .build_cartesian_2d(
            x_axis,
            TickedAxis::new(0.0..y_axis.top, y_axis.ticks.iter().map(|t| t.0).collect()),
        )?;
    chart
        .configure_mesh()
        .disable_x_mesh()
        .bold_line_style(GRID)
        .x_desc(descriptions[0])
        .y_desc(descriptions[1])
        .axis_desc_style((FONT, AXIS_DESC_SIZE))
        .label_style((FONT, LABEL_SIZE))
        .x_label_formatter(x_format)
        .y_label_formatter(&|y| y_axis.label(*y))
        .draw()?;
    Ok(chart)
}

fn draw_on(
    root: &DrawingArea<SVGBackend<'_>, Shift>,
    plot: &PlotView<'_>,
    configurations: usize,
    panels: &[Panel],
) -> DrawResult<()> {
    let labels: Vec<&str> = plot.series.iter().map(|s| s.label).collect();
    let chart_area = draw_title_and_legend(root, plot.title, &labels)?;
    // One y-label width for all panels, so that their x axes line up.
    let mut y_label_width = 0;
    for panel in panels {
        y_label_width = y_label_width.max(y_label_area(root, &panel.y_axis)?);
    }
    for (panel, area) in panels
        .iter()
        .zip(chart_area.split_evenly((panels.len(), 1)))
    {
        draw_panel(root, &area, plot, configurations, panel, y_label_width)?;
    }
    Ok(())
}

/// The x tick label of configuration `x` (1-based): its label, or its number.
fn configuration_label(plot: &PlotView<'_>, x: f64) -> String {
    let number = x.round() as i64;
    usize::try_from(number - 1)
        .ok()
        .and_then(|i| plot.x_labels.get(i).cloned())
        .unwrap_or_else(|| number.to_string())
}

/// One panel: its series over the shared x axis, with the panel's own y axis.
fn draw_panel(
    root: &DrawingArea<SVGBackend<'_>, Shift>,
    area: &DrawingArea<SVGBackend<'_>, Shift>,
    plot: &PlotView<'_>,
    configurations: usize,
    panel: &Panel,
    y_label_area: u32,
) -> DrawResult<()> {
    let plot_width = WIDTH - y_label_area - MARGIN_RIGHT - 8;
    let last = configurations as f64;
    let characters = if plot.x_labels.is_empty() {
        configurations.to_string().len()
    } else {
        plot.x_labels
            .iter()
            .map(|l| l.chars().count())
            .max()
            .unwrap_or(1)
    };
    let mut chart = axes(
        area,
        y_label_area,
        TickedAxis::new(
            0.5..last + 0.5,
            x_ticks(configurations, characters, plot_width),
        ),
        &panel.y_axis,
        [
            if plot.x_labels.is_empty() {
                "configuration"
            } else {
                "measurement id"
            },
            plot.y_label,
        ],
        &|x| configuration_label(plot, *x),
    )?;

    let spacing = f64::from(plot_width) / configurations as f64;
    let marker_every = (MARKER_SPACING / spacing).ceil().max(1.0) as usize;
    for &index in &panel.series {
        let series = &plot.series[index];
        let (colour, kind) = style_of(index);
        let line = pixel_envelope(series.values, 2 * WIDTH as usize);
        chart.draw_series(LineSeries::new(line, colour.stroke_width(2)))?;
        // Markers go on the whole picture in pixels: one drawing routine serves the legend too.
        for (i, &v) in series.values.iter().enumerate().step_by(marker_every) {
            draw_marker(
                root,
                kind,
                chart.backend_coord(&((i + 1) as f64, v)),
                colour,
            )?;
        }
    }
    Ok(())
}

/// The points `(k + 1, values[k])` of a curve, or, when there are more than four per one of
/// `columns` equal slices of the x range (finer than the plot's pixels), each slice's first,
/// lowest, highest and last point in order (M4 aggregation): the polyline through them
/// colours the same pixels as the one through every point, in a fraction of the SVG (an arm's
/// 8·10⁵ configurations were a 12.8 MB file).
fn pixel_envelope(values: &[f64], columns: usize) -> Vec<(f64, f64)> {
    let point = |k: usize| ((k + 1) as f64, values[k]);
    if values.len() <= 4 * columns.max(1) {
        return (0..values.len()).map(point).collect();
    }
    let mut kept = Vec::with_capacity(4 * columns);
    let mut start = 0;
    for column in 0..columns {
        let end = (values.len() * (column + 1)).div_ceil(columns);
        if end <= start {
            continue;
        }
        let slice = &values[start..end];
        let by_value = |a: &(usize, &f64), b: &(usize, &f64)| a.1.total_cmp(b.1);
        let low = slice
            .iter()
            .enumerate()
            .min_by(by_value)
            .map_or(0, |(k, _)| k);
        let high = slice
            .iter()
            .enumerate()
            .max_by(by_value)
            .map_or(0, |(k, _)| k);
        let mut picks = [0, low, high, slice.len() - 1];
        picks.sort_unstable();
        let mut previous = None;
        for k in picks {
            if previous != Some(k) {
                kept.push(point(start + k));
                previous = Some(k);
            }
        }
        start = end;
    }
    kept
}

#[cfg(test)]
mod tests {
    use super::pixel_envelope;

    /// A short curve keeps every point; a long one keeps, per slice of the x range, its first,
    /// lowest, highest and last point, in order, each a real point of the curve.
    #[test]
    fn the_envelope_keeps_each_slices_extremes_in_order() {
        let short = [1.0, 3.0, 2.0];
        assert_eq!(
            pixel_envelope(&short, 10),
            [(1.0, 1.0), (2.0, 3.0), (3.0, 2.0)]
        );
        let values: Vec<f64> = (0..100_003)
            .map(|k| (k as f64 * 0.37).sin().abs() + if k % 9973 == 0 { 5.0 } else { 0.0 })
            .collect();
        let columns = 300;
        let kept = pixel_envelope(&values, columns);
        assert!(kept.len() <= 4 * columns && kept.len() >= 2 * columns);
        assert!(kept.windows(2).all(|pair| pair[0].0 < pair[1].0));
        for &(x, v) in &kept {
            assert_eq!(values[x as usize - 1], v);
        }
        assert_eq!(kept.first(), Some(&(1.0, values[0])));
        assert_eq!(
            kept.last(),
            Some(&(values.len() as f64, values[values.len() - 1]))
        );
        let mut start = 0;
        for column in 0..columns {
            let end = (values.len() * (column + 1)).div_ceil(columns);
            let inside: Vec<f64> = kept
                .iter()
                .filter(|(x, _)| (start + 1..=end).contains(&(*x as usize)))
                .map(|&(_, v)| v)
                .collect();
            let slice = &values[start..end];
            let extreme =
                |pick: fn(f64, f64) -> f64, of: &[f64]| of.iter().copied().fold(of[0], pick);
            assert_eq!(extreme(f64::min, &inside), extreme(f64::min, slice));
            assert_eq!(extreme(f64::max, &inside), extreme(f64::max, slice));
            start = end;
        }
    }
}
