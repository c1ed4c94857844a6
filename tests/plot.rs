//! `report::plot`: per-configuration error plots like the paper's Fig. 7–12 are well-formed,
//! complete and deterministic SVG; bad data is refused with a message naming the series and
//! index. Line plots over arbitrary x values (`line_plot_svg`) likewise.
//!
//! Set `TREECAL_PLOT_EXAMPLE=/some/file.svg` to have the Fig. 7 look-alike written there for a
//! visual check.

use treecal::report::{error_plot_svg, line_plot_svg, Curve, ErrorPlot, LinePlot, Series};

fn series(label: &str, values: Vec<f64>) -> Series {
    Series {
        label: label.to_string(),
        values,
    }
}

/// Shaped like the paper's Fig. 7: 20 configurations, three curves.
fn fig7() -> ErrorPlot {
    let before: Vec<f64> = (0..20)
        .map(|i| 14.0 + 6.0 * (f64::from(i) * 0.9).sin().abs())
        .collect();
    let without: Vec<f64> = before.iter().map(|v| v * 0.1 + 0.3).collect();
    let with: Vec<f64> = before.iter().map(|v| v * 0.013).collect();
    ErrorPlot {
        title: "End-effector position error before and after calibration".into(),
        y_label: "position error (mm)".into(),
        series: vec![
            series("before calibration", before),
            series("after calibration, with flexibility compensation", with),
            series(
                "after calibration, without flexibility compensation",
                without,
            ),
        ],
        x_labels: Vec::new(),
    }
}

fn plot_of(values: &[&[f64]]) -> ErrorPlot {
    ErrorPlot {
        title: "test".into(),
        y_label: "error (mm)".into(),
        series: values
            .iter()
            .enumerate()
            .map(|(i, v)| series(&format!("series {i}"), v.to_vec()))
            .collect(),
        x_labels: Vec::new(),
    }
}

/// Checks that `svg` is one balanced element tree: every start tag closed in order, attribute
/// values quoted, no stray `<` or unescaped `&` in text. (A std-only stand-in for an XML parser.)
fn assert_well_formed(svg: &str) {
    let trimmed = svg.trim();
    assert!(trimmed.starts_with("<svg"), "does not start with <svg");
    assert!(trimmed.ends_with("</svg>"), "does not end with </svg>");
    let mut open: Vec<String> = vec![];
    let mut rest = trimmed;
    let mut roots = 0;
    while let Some(start) = rest.find('<') {
        check_text(&rest[..start]);
        rest = &rest[start + 1..];
        // The tag ends at the first '>' outside a quoted attribute value.
        let mut quote = None;
        let end = rest
            .char_indices()
            .find(|&(_, c)| match quote {
                Some(q) if c == q => {
                    quote = None;
                    false
                }
                Some(_) => false,
                None if c == '"' || c == '\'' => {
                    quote = Some(c);
                    false
                }
                None => c == '>',
            })
            .map(|(i, _)| i)
            .unwrap_or_else(|| panic!("unterminated tag at: {}", &rest[..rest.len().min(40)]));
        let tag = &rest[..end];
        rest = &rest[end + 1..];
        if let Some(name) = tag.strip_prefix('/') {
            let expected = open
                .pop()
                .unwrap_or_else(|| panic!("</{name}> closes nothing"));
            assert_eq!(name.trim(), expected, "mismatched closing tag");
        } else {
            let self_closing = tag.ends_with('/');
            let body = tag.trim_end_matches('/');
            let name: String = body.chars().take_while(|c| !c.is_whitespace()).collect();
            assert!(
                !name.is_empty() && name.chars().all(|c| c.is_alphanumeric() || c == '-'),
                "bad tag name in <{tag}>"
            );
            check_attributes(&body[name.len()..]);
            if open.is_empty() {
                roots += 1;
            }
            if !self_closing {
                open.push(name);
            }
        }
    }
    check_text(rest);
    assert!(open.is_empty(), "unclosed elements: {open:?}");
    assert_eq!(roots, 1, "more than one root element");
}

fn check_text(text: &str) {
    let mut parts = text.split('&');
    parts.next();
    for part in parts {
        let entity = part.split(';').next().unwrap_or("");
        assert!(
            part.contains(';')
                && (["amp", "lt", "gt", "quot", "apos"].contains(&entity)
                    || entity.starts_with('#')),
            "unescaped & in text: {text}"
        );
    }
}

fn check_attributes(mut attributes: &str) {
    loop {
        attributes = attributes.trim_start();
        if attributes.is_empty() {
            return;
        }
        let (name, value) = attributes
            .split_once('=')
            .unwrap_or_else(|| panic!("attribute without value: {attributes}"));
        assert!(!name.trim().is_empty() && !name.contains(char::is_whitespace));
        let value = value.trim_start();
        let quote = value.chars().next().expect("attribute value");
        assert!(quote == '"' || quote == '\'', "unquoted attribute {name}");
        let close = value[1..]
            .find(quote)
            .expect("unterminated attribute value");
        assert!(!value[1..1 + close].contains('<'), "< in attribute {name}");
        attributes = &value[close + 2..];
    }
}

/// The text content of every `<text>` element, with its `text-anchor`.
fn texts(svg: &str) -> Vec<(String, String)> {
    svg.split("<text")
        .skip(1)
        .map(|element| {
            let (attributes, rest) = element.split_once('>').expect("text start tag");
            let content = rest.split("</text>").next().expect("text end tag");
            let anchor = attributes
                .split("text-anchor=\"")
                .nth(1)
                .and_then(|a| a.split('"').next())
                .unwrap_or("")
                .to_string();
            // The SVG backend puts the text on a line of its own.
            (anchor, content.trim().to_string())
        })
        .collect()
}

/// The y tick labels: the right-aligned texts (the left of the y axis).
fn y_tick_labels(svg: &str) -> Vec<String> {
    texts(svg)
        .into_iter()
        .filter(|(anchor, _)| anchor == "end")
        .map(|(_, content)| content)
        .collect()
}

/// The x tick labels: the centred texts that are integers.
fn x_tick_labels(svg: &str) -> Vec<usize> {
    texts(svg)
        .into_iter()
        .filter(|(anchor, _)| anchor == "middle")
        .filter_map(|(_, content)| content.parse().ok())
        .collect()
}

/// The `points` of every `<polyline>`, with its stroke colour.
fn polylines(svg: &str) -> Vec<(String, usize)> {
    svg.split("<polyline")
        .skip(1)
        .map(|element| {
            let attribute = |name: &str| {
                element
                    .split(&format!(" {name}=\""))
                    .nth(1)
                    .and_then(|a| a.split('"').next())
                    .unwrap_or("")
                    .to_string()
            };
            (
                attribute("stroke"),
                attribute("points").split_whitespace().count(),
            )
        })
        .collect()
}

fn error_message(plot: &ErrorPlot) -> String {
    error_plot_svg(plot)
        .expect_err("the plot should be refused")
        .to_string()
}

#[test]
fn fig7_look_alike_is_well_formed_and_complete() {
    let plot = fig7();
    let svg = error_plot_svg(&plot).unwrap();
    if let Some(path) = std::env::var_os("TREECAL_PLOT_EXAMPLE") {
        std::fs::write(path, &svg).unwrap();
    }
    assert_well_formed(&svg);
    // Before (up to 20 mm), without compensation (up to 2.3 mm) and with it (up to 0.26 mm)
    // differ by more than 5× each: three panels, 450 + 2 · 280 pixels high.
    assert!(svg.contains("width=\"800\"") && svg.contains("height=\"1010\""));
    let contents: Vec<String> = texts(&svg).into_iter().map(|(_, c)| c).collect();
    for expected in [
        plot.title.as_str(),
        "configuration",
        "position error (mm)",
        "before calibration",
        "after calibration, with flexibility compensation",
        "after calibration, without flexibility compensation",
    ] {
        assert!(
            contents.iter().any(|c| c == expected),
            "no text '{expected}' in {contents:?}"
        );
    }
    let per_panel: Vec<usize> = (1..=20).collect();
    assert_eq!(x_tick_labels(&svg), per_panel.repeat(3));
}

#[test]
fn one_line_per_series_in_distinct_colours() {
    let svg = error_plot_svg(&fig7()).unwrap();
    // Axes, tick marks and marker outlines are short polylines; a curve has a point per
    // configuration.
    let curves: Vec<String> = polylines(&svg)
        .into_iter()
        .filter(|(_, points)| *points == 20)
        .map(|(stroke, _)| stroke)
        .collect();
    assert_eq!(curves.len(), 3, "{curves:?}");
    let mut distinct = curves.clone();
    distinct.sort();
    distinct.dedup();
    assert_eq!(distinct.len(), 3, "curves share a colour: {curves:?}");
}

#[test]
fn output_is_byte_identical_for_the_same_input() {
    let first = error_plot_svg(&fig7()).unwrap();
    let second = error_plot_svg(&fig7().clone()).unwrap();
    assert_eq!(first, second);
}

#[test]
fn y_axis_starts_at_zero_and_covers_the_data() {
    let svg = error_plot_svg(&fig7()).unwrap();
    let panels = y_axes(&svg);
    assert_eq!(panels.len(), 3, "{panels:?}");
    let plot = fig7();
    for (panel, series) in panels.iter().zip(&plot.series) {
        let labels: Vec<f64> = panel.iter().map(|(value, _)| *value).collect();
        assert_eq!(labels[0], 0.0);
        assert!(labels.windows(2).all(|w| w[0] < w[1]), "{labels:?}");
        let max = series.values.iter().copied().fold(0.0, f64::max);
        assert!(labels[labels.len() - 1] >= max, "{labels:?} for {max}");
        assert!((3..=8).contains(&labels.len()), "{labels:?}");
    }
}

/// The y tick labels of each panel, top panel first: `(value, pixel y)` from 0 upwards (a
/// panel's labels start at 0).
fn y_axes(svg: &str) -> Vec<Vec<(f64, f64)>> {
    let mut panels: Vec<Vec<(f64, f64)>> = Vec::new();
    for element in svg.split("<text").skip(1) {
        let (attributes, rest) = element.split_once('>').unwrap();
        if !attributes.contains("text-anchor=\"end\"") {
            continue;
        }
        let y: f64 = attributes
            .split(" y=\"")
            .nth(1)
            .and_then(|a| a.split('"').next())
            .unwrap()
            .parse()
            .unwrap();
        let value: f64 = rest
            .split("</text>")
            .next()
            .unwrap()
            .trim()
            .parse()
            .unwrap();
        if value == 0.0 || panels.is_empty() {
            panels.push(Vec::new());
        }
        panels.last_mut().unwrap().push((value, y));
    }
    panels
}

/// The pixel points of the longest `<polyline>` drawn in `stroke` (a series' curve).
fn curve_points(svg: &str, stroke: &str) -> Vec<(f64, f64)> {
    svg.split("<polyline")
        .skip(1)
        .filter(|element| element.contains(&format!("stroke=\"{stroke}\"")))
        .map(|element| {
            let points = element.split(" points=\"").nth(1).unwrap();
            points
                .split('"')
                .next()
                .unwrap()
                .split_whitespace()
                .map(|p| {
                    let (x, y) = p.split_once(',').unwrap();
                    (x.parse().unwrap(), y.parse().unwrap())
                })
                .collect::<Vec<(f64, f64)>>()
        })
        .max_by_key(Vec::len)
        .unwrap()
}

/// Shaped like a real calibration: 40 configurations named by CSV ids, about 100 mm before
/// and 0.1 mm after.
fn calibration_like() -> ErrorPlot {
    let before: Vec<f64> = (0..40)
        .map(|i| 100.0 + 50.0 * (f64::from(i) * 0.7).sin().abs())
        .collect();
    let after: Vec<f64> = (0..40)
        .map(|i| 0.05 + 0.15 * (f64::from(i) * 1.3).cos().abs())
        .collect();
    ErrorPlot {
        title: "left_arm: position error on the validation configurations".into(),
        y_label: "position error (mm)".into(),
        series: vec![
            series("before calibration", before),
            series("after calibration", after),
        ],
        x_labels: (0..40).map(|i| format!("m{}", 101 + 3 * i)).collect(),
    }
}

#[test]
fn the_after_calibration_curve_fills_a_panel_of_its_own() {
    let plot = calibration_like();
    let svg = error_plot_svg(&plot).unwrap();
    assert_well_formed(&svg);
    let panels = y_axes(&svg);
    assert_eq!(panels.len(), 2, "{panels:?}");
    // The after curve (second colour) lies within the lower panel and its highest point is
    // well up it: on one 0–150 mm axis it would be 0.1 % of the height.
    let after = curve_points(&svg, "#D55E00");
    assert_eq!(after.len(), 40);
    let lower = &panels[1];
    let (zero, top) = (lower[0].1, lower[lower.len() - 1].1);
    let highest = after.iter().map(|p| p.1).fold(f64::INFINITY, f64::min);
    let lowest = after.iter().map(|p| p.1).fold(f64::NEG_INFINITY, f64::max);
    assert!(
        highest >= top - 1.0 && lowest <= zero + 1.0,
        "{after:?} outside {zero}..{top}"
    );
    let fraction = (zero - highest) / (zero - top);
    assert!(
        fraction > 0.5,
        "the after curve reaches {fraction:.3} of its panel"
    );
    let spread = (lowest - highest) / (zero - top);
    assert!(
        spread > 0.3,
        "the after curve spans {spread:.3} of its panel"
    );
    // The before curve stays in the upper panel.
    let upper = &panels[0];
    let before = curve_points(&svg, "#0072B2");
    let upper_zero = upper[0].1;
    assert!(before.iter().all(|p| p.1 <= upper_zero + 1.0));
}

#[test]
fn the_x_axis_is_labelled_by_the_ids_thinned_to_fit() {
    let plot = calibration_like();
    let svg = error_plot_svg(&plot).unwrap();
    let centred: Vec<String> = texts(&svg)
        .into_iter()
        .filter(|(anchor, content)| {
            anchor == "middle" && content.starts_with('m') && content != "measurement id"
        })
        .map(|(_, content)| content)
        .collect();
    let panels = 2;
    assert!(centred.len() % panels == 0, "{centred:?}");
    let shown = &centred[..centred.len() / panels];
    assert!(
        shown.iter().all(|id| plot.x_labels.contains(id)),
        "{shown:?}"
    );
    assert!(shown.contains(&"m101".to_string()), "{shown:?}");
    // 40 ids of 4 characters do not fit 700 pixels: every 2nd or 5th is shown, in order.
    assert!(shown.len() < 40 && shown.len() >= 8, "{shown:?}");
    let positions: Vec<usize> = shown
        .iter()
        .map(|id| plot.x_labels.iter().position(|l| l == id).unwrap())
        .collect();
    assert!(positions.windows(2).all(|w| w[0] < w[1]), "{positions:?}");
    assert!(texts(&svg).iter().any(|(_, c)| c == "measurement id"));
    assert!(!x_tick_labels(&svg).contains(&40), "numbers instead of ids");
}

#[test]
fn series_of_similar_size_share_one_panel() {
    let svg = error_plot_svg(&plot_of(&[&[10.0, 12.0, 9.0], &[3.0, 2.5, 2.4]])).unwrap();
    assert!(svg.contains("height=\"450\""));
    assert_eq!(y_axes(&svg).len(), 1);
}

#[test]
fn x_labels_of_the_wrong_count_are_refused() {
    let mut plot = plot_of(&[&[1.0, 2.0, 3.0]]);
    plot.x_labels = vec!["a".into(), "b".into()];
    let message = error_message(&plot);
    assert!(
        message.contains("2 x labels for 3 configurations"),
        "{message}"
    );
}

#[test]
fn markup_in_text_is_escaped() {
    let mut plot = fig7();
    plot.title = "left & right arm <test>".into();
    plot.series[0].label = "before \"calibration\" & <after>".into();
    let svg = error_plot_svg(&plot).unwrap();
    assert_well_formed(&svg);
    assert!(svg.contains("left &amp; right arm &lt;test&gt;"));
}

#[test]
fn a_single_configuration_is_plotted() {
    let svg = error_plot_svg(&plot_of(&[&[3.0], &[0.5]])).unwrap();
    assert_well_formed(&svg);
    // Two panels (3 against 0.5), each with the one configuration labelled.
    assert_eq!(x_tick_labels(&svg), vec![1, 1]);
}

#[test]
fn all_zero_values_give_a_valid_axis() {
    let svg = error_plot_svg(&plot_of(&[&[0.0; 5], &[0.0; 5]])).unwrap();
    assert_well_formed(&svg);
    assert!(!svg.contains("NaN") && !svg.contains("inf"));
    let labels = y_tick_labels(&svg);
    assert_eq!(labels.first().map(String::as_str), Some("0.0"));
    assert_eq!(labels.last().map(String::as_str), Some("1.0"));
}

#[test]
fn tiny_values_get_scientific_tick_labels() {
    let svg = error_plot_svg(&plot_of(&[&[1e-6, 1.2e-6, 0.8e-6]])).unwrap();
    assert_well_formed(&svg);
    assert_eq!(
        y_tick_labels(&svg),
        ["0", "2.0e-7", "4.0e-7", "6.0e-7", "8.0e-7", "1.0e-6", "1.2e-6"]
    );
}

#[test]
fn large_and_fractional_values_get_exact_tick_labels() {
    let svg = error_plot_svg(&plot_of(&[&[1000.0, 350.0, 720.5]])).unwrap();
    assert_eq!(
        y_tick_labels(&svg),
        ["0", "200", "400", "600", "800", "1000"]
    );
    let svg = error_plot_svg(&plot_of(&[&[0.3, 0.17, 0.21]])).unwrap();
    assert_eq!(
        y_tick_labels(&svg),
        ["0.00", "0.05", "0.10", "0.15", "0.20", "0.25", "0.30"]
    );
}

#[test]
fn many_configurations_get_fewer_x_labels() {
    let values: Vec<f64> = (0..100).map(f64::from).collect();
    let svg = error_plot_svg(&plot_of(&[&values])).unwrap();
    let labels = x_tick_labels(&svg);
    assert!(labels.len() <= 25, "{labels:?}");
    assert_eq!(labels.first(), Some(&1));
    assert_eq!(labels.last(), Some(&100));
}

#[test]
fn more_series_than_colours_stay_distinct() {
    let rows: Vec<Vec<f64>> = (0..8).map(|i| vec![f64::from(i); 4]).collect();
    let refs: Vec<&[f64]> = rows.iter().map(Vec::as_slice).collect();
    let svg = error_plot_svg(&plot_of(&refs)).unwrap();
    assert_well_formed(&svg);
    for i in 0..8 {
        assert!(svg.contains(&format!("\nseries {i}\n")));
    }
}

#[test]
fn an_empty_plot_is_refused() {
    let message = error_message(&plot_of(&[]));
    assert!(message.contains("no series"), "{message}");
    let message = error_message(&plot_of(&[&[], &[]]));
    assert!(message.contains("'series 0' has no values"), "{message}");
}

#[test]
fn series_of_different_lengths_are_refused() {
    let message = error_message(&plot_of(&[&[1.0, 2.0, 3.0], &[1.0, 2.0]]));
    assert!(
        message.contains("'series 1' has 2 values but series 'series 0' has 3"),
        "{message}"
    );
}

#[test]
fn non_finite_and_negative_values_are_refused_with_their_place() {
    for (bad, what) in [
        (f64::NAN, "NaN"),
        (f64::INFINITY, "inf"),
        (f64::NEG_INFINITY, "-inf"),
        (-0.5, "negative value -0.5"),
    ] {
        let message = error_message(&plot_of(&[&[1.0, 2.0, 3.0], &[1.0, 2.0, bad]]));
        assert!(message.starts_with("plot 'test': "), "{message}");
        assert!(
            message.contains("series 'series 1' has the")
                && message.contains(what)
                && message.contains("at index 2 (configuration 3)"),
            "{message}"
        );
    }
}

#[test]
fn absurdly_large_values_are_refused() {
    let message = error_message(&plot_of(&[&[1e305]]));
    assert!(message.contains("outside the range"), "{message}");
}

/// Shaped like docs/img/planning_k.svg: error against K, medians with quartile bars.
fn k_sweep() -> LinePlot {
    let x = vec![8.0, 12.0, 16.0, 20.0, 30.0, 40.0];
    let curve = |label: &str, scale: f64| Curve {
        label: label.into(),
        values: x.iter().map(|k| scale / k).collect(),
        spread: Some(
            x.iter()
                .map(|k| (0.8 * scale / k, 1.3 * scale / k))
                .collect(),
        ),
    };
    LinePlot {
        title: "Validation error vs K".into(),
        x_label: "arm poses K".into(),
        y_label: "position error (mm)".into(),
        x: x.clone(),
        curves: vec![curve("random", 1.0), curve("planned", 0.7)],
    }
}

fn line_error(plot: &LinePlot) -> String {
    line_plot_svg(plot)
        .expect_err("the plot should be refused")
        .to_string()
}

#[test]
fn line_plot_is_well_formed_complete_and_deterministic() {
    let plot = k_sweep();
    let svg = line_plot_svg(&plot).unwrap();
    assert_well_formed(&svg);
    assert_eq!(svg, line_plot_svg(&plot).unwrap());
    let contents: Vec<String> = texts(&svg).into_iter().map(|(_, c)| c).collect();
    for expected in [
        "Validation error vs K",
        "arm poses K",
        "position error (mm)",
        "random",
        "planned",
    ] {
        assert!(
            contents.iter().any(|c| c == expected),
            "no text '{expected}' in {contents:?}"
        );
    }
    assert_eq!(x_tick_labels(&svg), vec![8, 12, 16, 20, 30, 40]);
    // One curve line per curve, in different colours: the only polylines that span the plot
    // (markers, error bars and ticks are a few pixels wide).
    let lines: Vec<String> = svg
        .split("<polyline")
        .skip(1)
        .filter(|element| {
            let xs: Vec<f64> = element
                .split(" points=\"")
                .nth(1)
                .and_then(|a| a.split('"').next())
                .unwrap_or("")
                .split_whitespace()
                .filter_map(|point| point.split(',').next()?.parse().ok())
                .collect();
            xs.len() == 6 && xs[5] - xs[0] > 400.0
        })
        .map(|element| {
            let stroke = element.split(" stroke=\"").nth(1).unwrap_or("");
            stroke.split('"').next().unwrap_or("").to_string()
        })
        .collect();
    assert_eq!(lines.len(), 2, "{lines:?}");
    assert_ne!(lines[0], lines[1]);
    // The y axis covers the top of the highest error bar (1.3 / 8 = 0.1625).
    let top: f64 = y_tick_labels(&svg)
        .iter()
        .filter_map(|label| label.parse().ok())
        .fold(0.0, f64::max);
    assert!(top >= 0.1625, "top tick {top}");
}

#[test]
fn line_plot_without_spread_and_with_one_point_is_drawn() {
    let mut plot = k_sweep();
    plot.x = vec![3.5];
    for curve in &mut plot.curves {
        curve.values = vec![0.2];
        curve.spread = None;
    }
    let svg = line_plot_svg(&plot).unwrap();
    assert_well_formed(&svg);
    assert!(texts(&svg).iter().any(|(_, c)| c == "3.5"));
}

#[test]
fn line_plot_refuses_bad_data_with_its_place() {
    let mut plot = k_sweep();
    plot.curves[1].values[2] = f64::NAN;
    let message = line_error(&plot);
    assert!(
        message.contains("'planned'") && message.contains("NaN") && message.contains("index 2"),
        "{message}"
    );

    let mut plot = k_sweep();
    plot.curves[0].values.pop();
    let message = line_error(&plot);
    assert!(
        message.contains("'random' has 5 values and 6 spreads for 6 x values"),
        "{message}"
    );

    let mut plot = k_sweep();
    plot.curves[0].spread.as_mut().unwrap().push((0.0, 1.0));
    assert!(line_error(&plot).contains("7 spreads"));

    let mut plot = k_sweep();
    plot.curves[0].spread.as_mut().unwrap()[1] = (0.5, 0.6);
    let message = line_error(&plot);
    assert!(message.contains("spread (0.5, 0.6)"), "{message}");

    let mut plot = k_sweep();
    plot.x[3] = 12.0;
    let message = line_error(&plot);
    assert!(message.contains("increase strictly"), "{message}");

    let mut plot = k_sweep();
    plot.x[0] = f64::INFINITY;
    assert!(line_error(&plot).contains("not finite"));

    let mut plot = k_sweep();
    plot.curves.clear();
    assert!(line_error(&plot).contains("no curves"));

    let mut plot = k_sweep();
    plot.x.clear();
    assert!(line_error(&plot).contains("no x values"));
}
