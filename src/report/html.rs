//! `report.html`: one self-contained page of a calibration — the verdict and its reasons, the
//! paper's Tables 2 and 3, the per-configuration error plots (the SVGs of [`super::plot`],
//! inline), a chart of the parameter changes with their standard deviations
//! ([`super::html_chart`]) and a 3D view of the robot at a chosen configuration with the
//! measured and predicted tool points (`html_viewer.js`, plain JavaScript on a canvas).
//!
//! Nothing is loaded from anywhere: styles, data and script are in the page, so it works
//! opened from a file, offline. The script sets `data-viewer="ready"` on `<body>` once it has
//! drawn, and `data-script-error` with the message if anything throws (the browser check in
//! `tests/report_html.rs` reads both).

use super::calibrate::{ArmReport, CalibrationSummary};
use super::html_chart::parameter_chart_svg;
use super::html_markdown::inline_with;
use crate::calibration::{ParameterEstimate, Status};
use crate::error::Result;
use serde::Serialize;
use std::fmt::Write;

/// The robot drawn at every configuration the viewer offers: points (the base and the link
/// origins), each joined to its parent point by a segment.
#[derive(Debug, Clone, Default, Serialize)]
pub struct Scene {
    /// What the coordinates are in, for the page (e.g. "the measurement frame, m").
    pub frame: String,
    /// A name per point (`base`, then the links).
    pub names: Vec<String>,
    /// The parent point of every point (`None`: the base).
    pub parents: Vec<Option<usize>>,
    /// The configurations, validation rows first.
    pub configurations: Vec<SceneConfiguration>,
}

/// The robot at one measured configuration and the tool point measured and predicted there.
#[derive(Debug, Clone, Serialize)]
pub struct SceneConfiguration {
    /// The measurement row's id.
    pub id: String,
    /// `validation` or `identification`.
    pub set: String,
    /// The tool link observed.
    pub tool: String,
    /// Every point of [`Scene::names`] (m).
    pub points: Vec<[f64; 3]>,
    /// The point the tool hangs from.
    pub tool_parent: usize,
    /// The tool point the calibrated model predicts (m).
    pub predicted: [f64; 3],
    /// The tool point measured (m).
    pub measured: [f64; 3],
    /// Their distance (mm).
    pub error_mm: f64,
    /// Whether the robust fit names the row an outlier.
    pub outlier: bool,
}

/// Everything the page shows.
pub struct HtmlReport<'a> {
    /// The report (what report.json holds).
    pub summary: &'a CalibrationSummary,
    /// The error plots, `(file stem, SVG)`.
    pub plots: &'a [(String, String)],
    /// The deployable outputs, one sentence each (markdown with `code` spans).
    pub deploy: &'a [String],
    /// The robot at the measured configurations.
    pub scene: &'a Scene,
}

/// The pages' style sheet (also `html_page`'s).
pub(super) const STYLE: &str = include_str!("html_style.css");
const VIEWER: &str = include_str!("html_viewer.js");

pub use super::html_escape::escape;

/// Escaped text with markdown `code` spans as `<code>`.
fn inline(text: &str) -> String {
    inline_with(text, escape)
}

/// The page.
pub fn calibration_html(report: &HtmlReport) -> Result<String> {
    let s = report.summary;
    let mut out = String::new();
    let title = format!("Calibration of '{}'", s.context.robot);
    let _ = write!(
        out,
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<title>{}</title>\n<style>\n{STYLE}</style>\n<script>{ERROR_HOOK}</script>\n</head>\n<body>\n<h1>{}</h1>\n",
        escape(&title),
        escape(&title)
    );
    verdict_html(&mut out, s);
    context_html(&mut out, s);
    for (title, arms) in [
        ("measurement configurations", &s.identification),
        ("validation configurations", &s.validation),
    ] {
        table3_html(&mut out, title, arms);
    }
    // report.md's own text for these (the same figures): the validation rows by stratum, and
    // the outputs re-read and scored as written.
    if let Some(strata) = &s.validation_strata {
        super::html_markdown::markdown_body(&mut out, &strata.markdown());
    }
    if let Some(artifact) = &s.artifact {
        super::html_markdown::markdown_body(
            &mut out,
            &artifact.markdown_written(s.verdict.usable()),
        );
    }
    plots_html(&mut out, s, report.plots);
    out.push_str("<h2 id=\"parameter-changes\">Parameter changes</h2>\n<p>Each bar is a calibrated parameter's change from the URDF value; the whisker spans ±1 standard deviation. Grey: not identifiable on its own (kept at its start). The tool frames (where each measured target sits on its tool link) have panels of their own.</p>\n");
    let tools: Vec<&str> = s.identification.iter().map(|a| a.tool.as_str()).collect();
    out.push_str(&parameter_chart_svg(&s.parameters, &tools));
    table2_html(&mut out, &s.parameters);
    viewer_html(&mut out, report.scene)?;
    out.push_str("<h2 id=\"deploy\">Deploying the calibration</h2>\n<ul>\n");
    for line in report.deploy {
        let _ = writeln!(out, "<li>{}</li>", inline(line));
    }
    out.push_str("</ul>\n<p>Written by treecal calibrate; the same figures are in report.md and report.json.</p>\n</body>\n</html>\n");
    Ok(out)
}

/// Marks a script error on `<body>` (and shows it), so that a test and a reader both see it.
const ERROR_HOOK: &str = "window.addEventListener('error',function(e){var m=String(e.message||e);document.documentElement.setAttribute('data-script-error',m);var b=document.body;if(b){b.setAttribute('data-script-error',m);}});";

fn verdict_html(out: &mut String, s: &CalibrationSummary) {
    let verdict = &s.verdict;
    let meaning = match verdict.status {
        Status::Ok => "the result can be used",
        Status::Warning => "the result can be used, but read the warnings",
        Status::Failed => "the result must not be used; calibrated.urdf was not written",
    };
    let _ = writeln!(
        out,
        "<section id=\"verdict\" class=\"verdict {}\">\n<p class=\"verdict-line\"><strong>Verdict: {}</strong> ({meaning}).</p>",
        verdict.status, verdict.status
    );
    if !verdict.reasons.is_empty() {
        out.push_str("<ul class=\"reasons\">\n");
        for reason in &verdict.reasons {
            let label = match reason.status {
                Status::Ok => "note",
                Status::Warning => "warning",
                Status::Failed => "failed",
            };
            let _ = writeln!(
                out,
                "<li class=\"{label}\"><span class=\"label\">{label}</span> <code class=\"finding\">{}</code>: {}</li>",
                escape(&reason.code),
                inline(&reason.message)
            );
        }
        out.push_str("</ul>\n");
    }
    if let Some(headline) = super::calibrate::held_out_headline(s) {
        let _ = writeln!(
            out,
            "<p class=\"headline\"><strong>Held-out accuracy:</strong> RMS position error {:.3} mm over all {} validation rows (before: {:.3} mm, the registered nominal robot){}.</p>",
            headline.rms,
            headline.observations,
            headline.before_rms,
            escape(&headline.flagged_text())
        );
    }
    out.push_str("</section>\n");
}

fn context_html(out: &mut String, s: &CalibrationSummary) {
    let c = &s.context;
    out.push_str("<h2 id=\"inputs\">Inputs</h2>\n<dl class=\"context\">\n");
    for (term, value) in [
        ("Measurements", c.measurements.clone()),
        ("Validation", c.validation.clone()),
        ("Plan", format!("{} ({} cycle(s))", c.plan, s.cycles)),
        ("Flexibility", c.compensation.clone()),
        (
            "Assumed noise",
            format!(
                "σ = {:.4} mm, {:.4} mrad",
                c.sigma[0] * 1e3,
                c.sigma[1] * 1e3
            ),
        ),
        ("Measurement frame", c.measurement_frame.clone()),
    ] {
        let _ = writeln!(out, "<dt>{term}</dt><dd>{}</dd>", inline(&value));
    }
    out.push_str("</dl>\n");
}

fn number(value: Option<f64>, digits: usize) -> String {
    match value {
        Some(v) if v.is_finite() => format!("{v:.digits$}"),
        _ => "—".into(),
    }
}

/// The paper's Table 3 layout for one data set.
fn table3_html(out: &mut String, title: &str, arms: &[ArmReport]) {
    if arms.is_empty() {
        return;
    }
    let _ = writeln!(
        out,
        "<h2>Errors on the {title} (paper Table 3 layout)</h2>\n<table class=\"table3\">\n<thead><tr><th>arm</th><th>n</th><th></th><th>before RMS</th><th>before max</th><th>before mean</th><th>after RMS</th><th>after max</th><th>after mean</th><th>RMS removed</th></tr></thead>\n<tbody>"
    );
    for arm in arms {
        let (b, a) = (&arm.before, &arm.after);
        let _ = writeln!(
            out,
            "<tr><td>{}</td><td>{}</td><td>position (mm)</td><td>{:.4}</td><td>{:.4}</td><td>{:.4}</td><td>{:.4}</td><td>{:.4}</td><td>{:.4}</td><td>{:.2} %</td></tr>",
            escape(&arm.arm),
            arm.observations,
            b.rms_position_mm,
            b.max_position_mm,
            b.mean_position_mm,
            a.rms_position_mm,
            a.max_position_mm,
            a.mean_position_mm,
            arm.position_removed_percent
        );
        if b.mean_orientation_deg.is_some() {
            let _ = writeln!(
                out,
                "<tr><td>{}</td><td>{}</td><td>orientation (deg)</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{} %</td></tr>",
                escape(&arm.arm),
                arm.observations,
                number(b.rms_orientation_deg, 5),
                number(b.max_orientation_deg, 5),
                number(b.mean_orientation_deg, 5),
                number(a.rms_orientation_deg, 5),
                number(a.max_orientation_deg, 5),
                number(a.mean_orientation_deg, 5),
                number(arm.orientation_removed_percent, 2)
            );
        }
    }
    out.push_str("</tbody>\n</table>\n");
}

/// The plots inline, and the flagged rows (outliers, down-weighted) listed.
fn plots_html(out: &mut String, s: &CalibrationSummary, plots: &[(String, String)]) {
    out.push_str("<h2 id=\"plots\">Errors per configuration</h2>\n<p>Before and after calibration at every row, by its id; an outlier is marked <code>*</code> and still counted.</p>\n");
    for (stem, svg) in plots {
        // The plots are our own SVG documents: drop an XML declaration, keep the element.
        let element = svg.find("<svg").map_or(svg.as_str(), |at| &svg[at..]);
        let _ = writeln!(
            out,
            "<figure class=\"plot\" id=\"plot-{}\">{element}<figcaption>{}.svg</figcaption></figure>",
            escape(stem),
            escape(stem)
        );
    }
    let mut flagged: Vec<String> = s
        .outliers
        .iter()
        .map(|o| {
            format!(
                "<li>{} ({:?}, tool {}): outlier, residual {:.3} mm, weight {:.3}</li>",
                escape(&o.id),
                o.set,
                escape(&o.tool),
                o.residual_mm,
                o.weight
            )
        })
        .collect();
    flagged.extend(s.down_weighted().iter().map(|(id, weight, after)| {
        format!(
            "<li>{}: down-weighted to {weight:.3}, error after {after:.3} mm</li>",
            escape(id)
        )
    }));
    if !flagged.is_empty() {
        let _ = writeln!(
            out,
            "<h3>Flagged rows</h3>\n<ul class=\"flagged\">\n{}\n</ul>",
            flagged.join("\n")
        );
    }
}

fn display(p: &ParameterEstimate, value: f64) -> f64 {
    if p.unit == "rad" {
        value.to_degrees()
    } else {
        value * 1e3
    }
}

/// The paper's Table 2 layout.
fn table2_html(out: &mut String, parameters: &[ParameterEstimate]) {
    out.push_str("<h2 id=\"table2\">Calibrated parameters (paper Table 2 layout; deg and mm)</h2>\n<table class=\"table2\">\n<thead><tr><th>frame</th><th>parameter</th><th>nominal</th><th>calibrated</th><th>change</th><th>std. dev.</th><th>identifiable</th></tr></thead>\n<tbody>\n");
    for p in parameters {
        let _ = writeln!(
            out,
            "<tr{}><td>{}</td><td>{} ({})</td><td>{:.4}</td><td>{:.4}</td><td>{:+.4}</td><td>{}</td><td>{}</td></tr>",
            if p.identifiable { "" } else { " class=\"unidentifiable\"" },
            escape(&p.owner),
            escape(&p.kind),
            if p.unit == "rad" { "deg" } else { "mm" },
            display(p, p.nominal),
            display(p, p.calibrated),
            display(p, p.change),
            number(p.std_dev.map(|s| display(p, s)), 4),
            if p.identifiable { "yes" } else { "no" }
        );
    }
    out.push_str("</tbody>\n</table>\n");
}

/// The canvas, its controls, the scene as JSON and the viewer script.
fn viewer_html(out: &mut String, scene: &Scene) -> Result<()> {
    let json = serde_json::to_string(scene).map_err(|e| crate::error::Error::InvalidData {
        origin: "report.html".into(),
        message: e.to_string(),
    })?;
    // `</script>` must not end the data block early; `<\/` reads back as `</` in JSON.
    let json = json.replace("</", "<\\/");
    let _ = writeln!(
        out,
        "<h2 id=\"robot\">The robot at a measured configuration</h2>\n<p>Stick figure of the calibrated model in {}: the base (square), the link origins (dots), the tool point it predicts (blue disc) and the tool point measured (orange cross). The measured point is drawn at predicted + k·(measured − predicted) so that millimetres show next to metres. Drag to turn, wheel to zoom.</p>\n<div class=\"viewer-controls\"><label>configuration <select id=\"viewer-configuration\"></select></label> <label>k <select id=\"viewer-scale\"><option>1</option><option>10</option><option selected>100</option><option>1000</option></select></label> <span id=\"viewer-status\"></span></div>\n<canvas id=\"viewer\" width=\"800\" height=\"560\"></canvas>\n<script type=\"application/json\" id=\"scene-data\">{json}</script>\n<script>\n{VIEWER}</script>",
        escape(&scene.frame)
    );
    Ok(())
}
