//! The report of `treecal compare` (report.json, report.md, displacement.svg): two
//! calibrations of one robot side by side.

use super::plot::{error_plot_svg, ErrorPlot, Series};
use crate::error::Result;
use serde::Serialize;
use std::fmt::Write;

/// report.json's `schema_version` for compare.
pub const COMPARE_SCHEMA: &str = "treecal-compare/2";

/// A parameter that moved beyond k combined σ.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MovedParameter {
    /// Its name (params.yaml).
    pub name: String,
    /// Its unit (`rad` or `m`).
    pub unit: String,
    /// Calibrated in A (SI).
    pub a: f64,
    /// B re-expressed in A's measurement frame (SI; as calibrated when it could not be).
    pub b: f64,
    /// Calibrated in B, in B's own measurement frame (SI).
    pub b_calibrated: f64,
    /// `b − a` (SI): what no change of measurement frame explains.
    pub change: f64,
    /// `√(σa² + σb²)` (SI).
    pub combined_std_dev: f64,
    /// `|b − a|` in combined σ.
    pub sigmas: f64,
}

/// How B was re-expressed in A's measurement frame before its parameters were judged: the
/// change of B's root frame that aligns its tools onto A's, pushed into its parameters.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FrameChange {
    /// The change of B's root frame: translation (mm).
    pub translation_mm: f64,
    /// Its rotation (deg).
    pub rotation_deg: f64,
    /// Parameters re-expressed (the others are compared as calibrated).
    pub parameters: usize,
    /// The tool positions' RMS left by the re-expression (mm): how exactly the parameters
    /// hold the change.
    pub residual_mm: f64,
}

/// The predicted displacement of one tool at one configuration.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DisplacementRow {
    /// The tool link.
    pub tool: String,
    /// Between the two URDFs as deployed, each with its registration (mm).
    pub deployed_mm: f64,
    /// After the best rigid alignment of B's predictions onto A's (mm).
    pub aligned_mm: f64,
}

/// The predicted tool displacement over the configuration set.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Displacement {
    /// Configurations: the identification postures recorded in both folders.
    pub configurations: usize,
    /// RMS as deployed (mm).
    pub rms_deployed_mm: f64,
    /// Largest as deployed (mm).
    pub max_deployed_mm: f64,
    /// RMS after the rigid alignment (mm).
    pub rms_aligned_mm: f64,
    /// Largest after the rigid alignment (mm).
    pub max_aligned_mm: f64,
    /// Per configuration.
    pub rows: Vec<DisplacementRow>,
}

impl Displacement {
    /// The summary of `rows`.
    pub fn of(rows: Vec<DisplacementRow>) -> Self {
        let rms = |f: &dyn Fn(&DisplacementRow) -> f64| {
            crate::math::root_mean_square(&rows.iter().map(f).collect::<Vec<_>>()).unwrap_or(0.0)
        };
        let max = |f: &dyn Fn(&DisplacementRow) -> f64| rows.iter().map(f).fold(0.0, f64::max);
        Self {
            configurations: rows.len(),
            rms_deployed_mm: rms(&|r: &DisplacementRow| r.deployed_mm),
            max_deployed_mm: max(&|r: &DisplacementRow| r.deployed_mm),
            rms_aligned_mm: rms(&|r: &DisplacementRow| r.aligned_mm),
            max_aligned_mm: max(&|r: &DisplacementRow| r.aligned_mm),
            rows,
        }
    }
}

/// One folder's validation figures (report.json), `None` where it has none.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ValidationFigures {
    /// The folder.
    pub folder: String,
    /// Its verdict.
    pub verdict: String,
    /// calibrated.urdf (with its registration) on its validation rows: RMS (mm).
    pub urdf_alone_rms_mm: Option<f64>,
    /// The same, largest (mm).
    pub urdf_alone_max_mm: Option<f64>,
    /// The registered nominal robot on the same rows: RMS (mm).
    pub registered_nominal_rms_mm: Option<f64>,
    /// Rows repeating an identification posture: RMS (mm).
    pub repeat_rms_mm: Option<f64>,
    /// New rows inside the calibrated ranges: RMS (mm).
    pub inside_rms_mm: Option<f64>,
    /// Rows outside them: RMS (mm).
    pub outside_rms_mm: Option<f64>,
    /// The position error the measurement noise alone leaves at the validation
    /// configurations, as the calibration's covariance predicts it: RMS (mm).
    pub predicted_rms_mm: Option<f64>,
}

/// report.json of `treecal compare`.
#[derive(Debug, Clone, Serialize)]
pub struct CompareReport {
    /// [`COMPARE_SCHEMA`].
    pub schema_version: &'static str,
    /// The robot's name.
    pub robot: String,
    /// The threshold in combined σ.
    pub k: f64,
    /// Parameters with a σ in both folders (the others are not judged).
    pub parameters_judged: usize,
    /// The parameters that moved beyond k σ, largest first.
    pub moved: Vec<MovedParameter>,
    /// B's re-expression in A's measurement frame (`None`: compared as calibrated, without
    /// configurations or a model of A's URDF).
    pub frame_change: Option<FrameChange>,
    /// The predicted tool displacement (`None`: neither folder records its postures).
    pub displacement: Option<Displacement>,
    /// A's and B's validation figures.
    pub validation: [ValidationFigures; 2],
    /// The provenance file of the folder.
    pub provenance: String,
}

fn in_display_unit(value: f64, unit: &str) -> String {
    match unit {
        "rad" => format!("{:.4}°", value.to_degrees()),
        "m" => format!("{:.4} mm", value * 1e3),
        other => format!("{value:.6} {other}"),
    }
}

impl CompareReport {
    /// Whether the tools moved more than two calibrations of one unchanged robot differ by:
    /// the aligned displacement against `DRIFT_FACTOR` times the noise-only prediction error
    /// of the two combined. Parameter σ's are conditional on the fitted frames (B is
    /// re-expressed in A's measurement frame first, but session frames and the trade between
    /// parameters remain), so a parameter can be listed that moves no tool; the tools are the
    /// figure to judge drift by.
    fn displacement_judgement(&self, d: &Displacement) -> Option<String> {
        /// Two calibrations of one robot differ by about the combined prediction error
        /// (measured 1.25×); a drift at the tools shows well beyond it.
        const DRIFT_FACTOR: f64 = 2.0;
        let [a, b] = &self.validation;
        let combined = a.predicted_rms_mm?.hypot(b.predicted_rms_mm?);
        let limit = DRIFT_FACTOR * combined;
        let moved = d.rms_aligned_mm > limit;
        let (head, tail) = match (moved, self.moved.is_empty()) {
            (true, _) => (
                "**The tools moved:**",
                ": a drift, or a change of the robot, between A and B.",
            ),
            (false, true) => ("The tools did not move beyond the noise:", "."),
            (false, false) => (
                "**The tools did not move beyond the noise:**",
                ". The parameters listed above changed without moving the tools beyond the noise: they trade among themselves (with several sessions, with the session frames too), which their σ's leave out, so read them as no drift.",
            ),
        };
        Some(format!(
            "{head} {:.3} mm RMS after the alignment, {} {DRIFT_FACTOR}× what the measurement noise of the two calibrations explains ({:.3} mm RMS combined{}){tail}",
            d.rms_aligned_mm,
            if moved { "beyond" } else { "within" },
            combined,
            if moved { ", predicted by their covariances" } else { "" },
        ))
    }

    /// report.md.
    pub fn markdown(&self) -> String {
        let [a, b] = &self.validation;
        let mut out = String::new();
        let _ = writeln!(
            out,
            "# Comparison of two calibrations of robot '{}'\n",
            self.robot
        );
        let _ = writeln!(out, "- A: {}\n- B: {}\n", a.folder, b.folder);
        let _ = writeln!(
            out,
            "## Parameters moved beyond {} combined σ\n\n{} of {} parameters with a σ in both folders moved by more than {}·√(σA² + σB²).\n",
            self.k,
            self.moved.len(),
            self.parameters_judged,
            self.k
        );
        let _ = match &self.frame_change {
            Some(f) => writeln!(
                out,
                "B is re-expressed in A's measurement frame first: each calibration fits its own frame, and the first joint frames absorb what separates it from the robot's, so the two differ there by a change of frame that their σ's leave out. B's root frame moved by {:.3} mm and {:.4}° (the rigid alignment of its tools onto A's), pushed into {} parameters (tools left {:.2e} mm RMS from B's); B − A below is what no change of frame explains.\n",
                f.translation_mm, f.rotation_deg, f.parameters, f.residual_mm
            ),
            None => writeln!(
                out,
                "B is compared as calibrated, not re-expressed in A's measurement frame (no configuration set, or A's URDF not rebuilt as a model of the tools): the first joint frames of each chain may differ by the change between the two fitted measurement frames.\n"
            ),
        };
        if !self.moved.is_empty() {
            let _ = writeln!(out, "| parameter | A | B | B − A | combined σ | σ's |");
            let _ = writeln!(out, "|---|---|---|---|---|---|");
            for m in &self.moved {
                let _ = writeln!(
                    out,
                    "| {} | {} | {} | {} | {} | {:.1} |",
                    m.name,
                    in_display_unit(m.a, &m.unit),
                    in_display_unit(m.b, &m.unit),
                    in_display_unit(m.change, &m.unit),
                    in_display_unit(m.combined_std_dev, &m.unit),
                    m.sigmas
                );
            }
            out.push('\n');
        }
        let _ = writeln!(out, "## Predicted tool displacement\n");
        match &self.displacement {
            Some(d) => {
                let _ = writeln!(
                    out,
                    "Over {} configurations (the identification postures of both folders): as deployed (each URDF with its registration) RMS {:.3} mm, max {:.3} mm; after the best rigid alignment of B onto A (what re-registering the tracker cannot remove) RMS {:.3} mm, max {:.3} mm. Per configuration: displacement.svg.\n",
                    d.configurations, d.rms_deployed_mm, d.max_deployed_mm, d.rms_aligned_mm, d.max_aligned_mm
                );
                if let Some(judgement) = self.displacement_judgement(d) {
                    let _ = writeln!(out, "{judgement}\n");
                }
            }
            None => {
                let _ = writeln!(out, "Neither folder records its identification postures (report.json `identification_postures`, written by calibrate since this version): no configuration set.\n");
            }
        }
        let _ = writeln!(
            out,
            "## Validation figures (each on its own validation rows)\n"
        );
        let _ = writeln!(out, "| | A | B |\n|---|---|---|");
        let mm = |v: Option<f64>| v.map_or_else(|| "—".to_owned(), |v| format!("{v:.4}"));
        let _ = writeln!(out, "| verdict | {} | {} |", a.verdict, b.verdict);
        for (label, fa, fb) in [
            (
                "calibrated.urdf, RMS (mm)",
                a.urdf_alone_rms_mm,
                b.urdf_alone_rms_mm,
            ),
            (
                "calibrated.urdf, max (mm)",
                a.urdf_alone_max_mm,
                b.urdf_alone_max_mm,
            ),
            (
                "registered nominal, RMS (mm)",
                a.registered_nominal_rms_mm,
                b.registered_nominal_rms_mm,
            ),
            ("repeat rows, RMS (mm)", a.repeat_rms_mm, b.repeat_rms_mm),
            ("new inside, RMS (mm)", a.inside_rms_mm, b.inside_rms_mm),
            ("outside, RMS (mm)", a.outside_rms_mm, b.outside_rms_mm),
        ] {
            let _ = writeln!(out, "| {label} | {} | {} |", mm(fa), mm(fb));
        }
        let _ = writeln!(out, "\nProvenance: {}.", self.provenance);
        out
    }

    /// displacement.svg: the predicted displacement per configuration; `None` without one.
    pub fn plot(&self) -> Result<Option<String>> {
        let Some(d) = &self.displacement else {
            return Ok(None);
        };
        error_plot_svg(&ErrorPlot {
            title: format!("{}: predicted tool displacement, B against A", self.robot),
            y_label: "displacement (mm)".into(),
            series: vec![
                Series {
                    label: "as deployed".into(),
                    values: d.rows.iter().map(|r| r.deployed_mm).collect(),
                },
                Series {
                    label: "after rigid alignment".into(),
                    values: d.rows.iter().map(|r| r.aligned_mm).collect(),
                },
            ],
            x_labels: Vec::new(),
        })
        .map(Some)
    }
}
