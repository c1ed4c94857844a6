//! Line plots (values over an x axis, optionally with a spread), in the error plots' style.

// The parent's types, constants and imports.
use super::*;

/// One named curve of a [`LinePlot`]: a value at each x position, optionally with a spread.
#[derive(Debug, Clone, PartialEq)]
pub struct Curve {
    /// Legend text, e.g. "planned poses".
    pub label: String,
    /// One non-negative value per x position, e.g. a median.
    pub values: Vec<f64>,
    /// `(low, high)` per x position with `low ≤ value ≤ high`, e.g. the quartiles, drawn as an
    /// error bar; `None` for none.
    pub spread: Option<Vec<(f64, f64)>>,
}

/// Curves over shared x values, e.g. validation error against the number of poses K.
#[derive(Debug, Clone, PartialEq)]
pub struct LinePlot {
    /// Title above the plot.
    pub title: String,
    /// X-axis label with its unit, if any.
    pub x_label: String,
    /// Y-axis label with its unit, e.g. "position error (mm)".
    pub y_label: String,
    /// The x positions, strictly increasing; each is also an x tick.
    pub x: Vec<f64>,
    /// The curves; each has one value (and spread) per x position.
    pub curves: Vec<Curve>,
}

/// Renders `plot` as an 800×450 SVG document: one line with point markers per curve, error bars
/// where a spread is given, the y axis from 0.
///
/// Fails, naming the curve and index, on no x values or curves, x values that are not finite
/// and strictly increasing, lengths that differ from the x values', non-finite or negative
/// values, and spreads that do not contain their value.
pub fn line_plot_svg(plot: &LinePlot) -> Result<String> {
    validate_line_plot(plot)?;
    let max = plot
        .curves
        .iter()
        .flat_map(|curve| {
            let highs = curve.spread.iter().flatten().map(|&(_, high)| high);
            curve.values.iter().copied().chain(highs)
        })
        .fold(0.0, f64::max);
    let y_axis = YAxis::covering(max).ok_or_else(|| {
        invalid_titled(
            &plot.title,
            format!("the largest value {max:e} is outside the range a plot can label"),
        )
    })?;
    let mut svg = String::new();
    {
        // The backend borrows `svg` until it is dropped.
        let root = SVGBackend::with_string(&mut svg, (WIDTH, HEIGHT)).into_drawing_area();
        draw_line_plot(&root, plot, &y_axis)
            .and_then(|()| root.present())
            .map_err(|e| invalid_titled(&plot.title, format!("drawing failed: {e}")))?;
    }
    Ok(svg)
}

fn validate_line_plot(plot: &LinePlot) -> Result<()> {
    let fail = |message: String| Err(invalid_titled(&plot.title, message));
    if plot.x.is_empty() {
        return fail("nothing to plot: no x values".into());
    }
    if plot.curves.is_empty() {
        return fail("nothing to plot: no curves".into());
    }
    if let Some(index) = plot.x.iter().position(|x| !x.is_finite()) {
        return fail(format!(
            "x value {} at index {index} is not finite",
            plot.x[index]
        ));
    }
    if let Some(index) = plot.x.windows(2).position(|pair| pair[1] <= pair[0]) {
        return fail(format!(
            "x values must increase strictly, but {} at index {} follows {}",
            plot.x[index + 1],
            index + 1,
            plot.x[index]
        ));
    }
    let count = plot.x.len();
    for curve in &plot.curves {
        let label = &curve.label;
        let spread_count = curve.spread.as_ref().map(Vec::len);
        if curve.values.len() != count || spread_count.is_some_and(|n| n != count) {
            return fail(format!(
                "curve '{label}' has {} values{} for {count} x values; each needs one per x",
                curve.values.len(),
                spread_count.map_or(String::new(), |n| format!(" and {n} spreads")),
            ));
        }
        for (index, &value) in curve.values.iter().enumerate() {
            let problem = if !value.is_finite() {
                format!("the non-finite value {value}")
            } else if value < 0.0 {
                format!("the negative value {value} (the axis starts at 0)")
            } else if let Some(&(low, high)) = curve.spread.as_ref().map(|s| &s[index]) {
                if low.is_finite()
                    && high.is_finite()
                    && 0.0 <= low
                    && low <= value
                    && value <= high
                {
                    continue;
                }
                format!(
                    "the spread ({low}, {high}) around {value}, which is not finite, \
                     non-negative and around the value"
                )
            } else {
                continue;
            };
            return fail(format!(
                "curve '{label}' has {problem} at index {index} (x = {})",
                plot.x[index]
            ));
        }
    }
    Ok(())
}

/// An x tick label: integers without a decimal point.
fn x_label(x: f64) -> String {
    if x.fract() == 0.0 && x.abs() < 1e15 {
        format!("{}", x as i64)
    } else {
        format!("{x}")
    }
}

fn draw_line_plot(
    root: &DrawingArea<SVGBackend<'_>, Shift>,
    plot: &LinePlot,
    y_axis: &YAxis,
) -> DrawResult<()> {
    let labels: Vec<&str> = plot.curves.iter().map(|c| c.label.as_str()).collect();
    let chart_area = draw_title_and_legend(root, &plot.title, &labels)?;
    let y_label_area = y_label_area(root, y_axis)?;
    let plot_width = f64::from(WIDTH - y_label_area - MARGIN_RIGHT - 8);

    let (first, last) = (plot.x[0], plot.x[plot.x.len() - 1]);
    let pad = if last > first {
        (last - first) * 0.04
    } else {
        0.5
    };
    let range = (first - pad)..(last + pad);
    // Every x is a tick unless its label would run into the previous one.
    let per_unit = plot_width / (range.end - range.start);
    let mut ticks: Vec<f64> = Vec::new();
    for &x in &plot.x {
        let room = (x_label(x).len() as f64 * 8.0 + 14.0) / per_unit;
        if ticks.last().is_none_or(|&previous| x - previous >= room) {
            ticks.push(x);
        }
    }
    let chart = axes(
        &chart_area,
        y_label_area,
        TickedAxis::new(range, ticks),
        y_axis,
        [&plot.x_label, &plot.y_label],
        &|x| x_label(*x),
    )?;

    // Curves are drawn in pixels on the whole picture, each shifted sideways a little so that
    // error bars at the same x do not hide one another.
    let curves = plot.curves.len() as f64;
    for (index, curve) in plot.curves.iter().enumerate() {
        let (colour, kind) = style_of(index);
        let dodge = ((index as f64 - (curves - 1.0) / 2.0) * 6.0).round() as i32;
        let pixel = |x: f64, y: f64| {
            let (px, py) = chart.backend_coord(&(x, y));
            (px + dodge, py)
        };
        if let Some(spread) = &curve.spread {
            let bar = colour.stroke_width(1);
            for (&x, &(low, high)) in plot.x.iter().zip(spread) {
                let (bottom, top) = (pixel(x, low), pixel(x, high));
                root.draw(&PathElement::new(vec![bottom, top], bar))?;
                for (cx, cy) in [bottom, top] {
                    root.draw(&PathElement::new(vec![(cx - 4, cy), (cx + 4, cy)], bar))?;
                }
            }
        }
        let points: Vec<(i32, i32)> = plot
            .x
            .iter()
            .zip(&curve.values)
            .map(|(&x, &y)| pixel(x, y))
            .collect();
        root.draw(&PathElement::new(points.clone(), colour.stroke_width(2)))?;
        for point in points {
            draw_marker(root, kind, point, colour)?;
        }
    }
    Ok(())
}
