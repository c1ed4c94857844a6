//! Arguments of `treecal verify` and `treecal compare` (trust over time).

use crate::cli::{parse_angle_unit, parse_length_unit, GravityFrame};
use clap::{Args, ValueEnum};
use std::path::PathBuf;

/// How verify finds the measurement frame (`--frame`).
#[derive(Clone, Copy, ValueEnum)]
pub enum FrameArg {
    /// Refit it to the fresh rows, the geometry fixed (6 parameters per session).
    Fit,
    /// The calibration's registration.yaml as written (nothing refitted).
    Registration,
    /// The rows are in the URDF's root link frame (nothing refitted).
    Base,
}

/// Arguments of `treecal verify`.
#[derive(Args)]
#[command(
    after_help = "Scores a calibration as deployed on fresh measurements (any measurement CSV calibrate reads: positions, poses, three targets, points, sessions). Only the measurement frame of the fresh rows is refitted (--frame fit: 6 parameters per session, the geometry fixed); --frame registration uses the calibration's registration.yaml as written and refits nothing, and then gives calibrate's validation figures for the same rows. With --calibration the rows are sorted into the strata of calibrate's report (repeat an identification posture / new inside the calibrated ranges / outside). With --max-error the exit code is 1 when the RMS position error over all rows is above it.\n\nWrites to --out: report.md, report.json, errors.svg (per-row position error) and provenance.yaml.\n\nExamples:\n  treecal verify --calibration out/calibrate --measurements fresh.csv --max-error 5\n  treecal verify --robot deployed.urdf --registration registration.yaml --measurements fresh.csv --frame registration"
)]
pub struct VerifyArgs {
    /// A `treecal calibrate` output folder: its calibrated.urdf, registration.yaml,
    /// stiffness.yaml (when written) and report.json (the calibrated ranges).
    #[arg(long, value_name = "DIR")]
    pub calibration: Option<PathBuf>,
    /// The deployed URDF [default: the calibration's calibrated.urdf].
    #[arg(long, value_name = "R.urdf")]
    pub robot: Option<PathBuf>,
    /// The registration (URDF root in the measurement frame) [default: the calibration's
    /// registration.yaml].
    #[arg(long, value_name = "REGISTRATION.yaml")]
    pub registration: Option<PathBuf>,
    /// The compensation (stiffness) file the calibration was made with [default: the
    /// calibration's stiffness.yaml when written, else rigid].
    #[arg(long, value_name = "S.yaml")]
    pub stiffness: Option<PathBuf>,
    /// The fresh measurements (CSV, as for calibrate); repeatable: several files are one set,
    /// each file its own session (its own frame with --frame fit).
    #[arg(long, value_name = "M.csv", required = true)]
    pub measurements: Vec<PathBuf>,
    /// How the measurement frame is found.
    #[arg(long, value_enum, default_value = "fit")]
    pub frame: FrameArg,
    /// The largest acceptable RMS position error over all rows (mm): above it the exit code
    /// is 1 (after writing the report).
    #[arg(long, value_name = "MM")]
    pub max_error: Option<f64>,
    /// Tool links (see `inspect --help`) [default: the measured tools].
    #[arg(long, value_delimiter = ',', value_name = "LINK,LINK")]
    pub tools: Option<Vec<String>>,
    /// Output folder.
    #[arg(short = 'o', long, default_value = "out/verify")]
    pub out: PathBuf,
    /// Unit of lengths in the CSV [default: the file's `# units:` comment, else m].
    #[arg(long, value_parser = parse_length_unit)]
    pub length_unit: Option<treecal::io::LengthUnit>,
    /// Unit of revolute joint values [default: the file's comment, else rad].
    #[arg(long, value_parser = parse_angle_unit)]
    pub angle_unit: Option<treecal::io::AngleUnit>,
    /// Unit of prismatic joint values [default: the file's comment, else the length unit].
    #[arg(long, value_parser = parse_length_unit)]
    pub joint_length_unit: Option<treecal::io::LengthUnit>,
    /// The frame the stiffness file's gravity vector is given in.
    #[arg(long, value_enum, default_value = "measurement")]
    pub gravity_frame: GravityFrame,
    /// Position noise (m) weighting the frame fit of measured poses.
    #[arg(long, default_value_t = treecal::calibration::DEFAULT_POSITION_SIGMA)]
    pub position_sigma: f64,
    /// Rotation noise (rad) weighting the frame fit of measured poses.
    #[arg(long, default_value_t = treecal::calibration::DEFAULT_ROTATION_SIGMA)]
    pub rotation_sigma: f64,
}

/// Arguments of `treecal compare`.
#[derive(Args)]
#[command(
    after_help = "Compares two `treecal calibrate` output folders of the same robot (two dates, or two model choices on the same data): the parameters that moved by more than K combined standard deviations (|b - a| > K·sqrt(σa² + σb²)), the tool displacement the two calibrated URDFs predict over a configuration set (each tool's identification postures of both folders), and the validation figures side by side.\n\nWrites to --out: report.md, report.json, displacement.svg and provenance.yaml.\n\nExample:\n  treecal compare out/calibrate-2021 out/calibrate-2023"
)]
pub struct CompareArgs {
    /// The first calibration output folder (the reference).
    #[arg(value_name = "A")]
    pub a: PathBuf,
    /// The second calibration output folder.
    #[arg(value_name = "B")]
    pub b: PathBuf,
    /// A parameter moved when |b − a| exceeds K combined standard deviations.
    #[arg(long, value_name = "K", default_value_t = 3.0)]
    pub k: f64,
    /// Output folder.
    #[arg(short = 'o', long, default_value = "out/compare")]
    pub out: PathBuf,
}
