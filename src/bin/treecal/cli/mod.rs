//! Command-line arguments (clap derive), one file per group of subcommands. Nothing here does
//! any work.

use clap::builder::{EnumValueParser, PossibleValue, TypedValueParser};
use clap::{Parser, Subcommand, ValueEnum};
use std::path::{Path, PathBuf};

mod calibrate;
mod pair;
mod plan;
mod robot;
mod simulate;

pub use calibrate::{
    CalibrateArgs, GravityFrame, JointErrorArg, MeasurementFrame, ModelArg, NoiseArg, RobustChoice,
};
pub use pair::PairArgs;
pub use plan::{CheckArgs, PlanArgs};
pub use robot::{ExportArgs, FkArgs, FromMcpcArgs, InspectArgs, ToMcpcArgs};
pub use simulate::{
    CollisionCheckChoice, CriterionChoice, MeasurementFormat, ObservationArg, PlanChoice,
    PosesFrom, SimulateArgs, StageChoice,
};

/// A `--plan` value: a plan by name, or (kept for compatibility) a plan file.
#[derive(Clone)]
pub enum PlanArg {
    /// `staged` or `simultaneous`.
    Choice(PlanChoice),
    /// A value ending in `.yaml`/`.yml` or naming an existing file.
    File(PathBuf),
}

/// The parser of `--plan` shared by the commands: `staged` or `simultaneous`, a typo answered
/// by clap with the possible values and a suggestion; a value that ends in `.yaml`/`.yml` or
/// names an existing file is taken as a plan file, as before `--plan-file` existed.
#[derive(Clone, Copy, Default)]
pub struct PlanArgParser;

impl TypedValueParser for PlanArgParser {
    type Value = PlanArg;

    fn parse_ref(
        &self,
        command: &clap::Command,
        arg: Option<&clap::Arg>,
        value: &std::ffi::OsStr,
    ) -> Result<PlanArg, clap::Error> {
        let choices = EnumValueParser::<PlanChoice>::new();
        if let Ok(choice) = choices.parse_ref(command, arg, value) {
            return Ok(PlanArg::Choice(choice));
        }
        let text = value.to_string_lossy();
        let path = Path::new(value);
        if text.ends_with(".yaml") || text.ends_with(".yml") || path.is_file() {
            return Ok(PlanArg::File(path.to_path_buf()));
        }
        choices.parse_ref(command, arg, value).map(PlanArg::Choice)
    }

    fn possible_values(&self) -> Option<Box<dyn Iterator<Item = PossibleValue> + '_>> {
        Some(Box::new(
            PlanChoice::value_variants()
                .iter()
                .filter_map(ValueEnum::to_possible_value),
        ))
    }
}

/// The robot of a command that accepts it as `--robot` and, for compatibility, positionally.
pub fn robot_path(flag: &Option<PathBuf>, positional: &Option<PathBuf>) -> Option<PathBuf> {
    // clap's `conflicts_with` refuses both.
    flag.clone().or_else(|| positional.clone())
}

/// Kinematic calibration of branched robots (a torso carrying two or more arms) described by
/// URDF, after the MCPC method of Chen et al. (Robot, 2017).
#[derive(Parser)]
#[command(name = "treecal", version, about, long_about = None, arg_required_else_help = true)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand)]
pub enum Command {
    /// Print a robot's tree, its detected branches and its MCPC parameter table.
    Inspect(InspectArgs),
    /// Forward kinematics: append the pose of a link to every row of a joint-value CSV.
    Fk(FkArgs),
    /// Generate a URDF from an MCPC parameter table (paper Table 1 layout, YAML).
    FromMcpc(FromMcpcArgs),
    /// Write a robot's MCPC parameter table (YAML, the format from-mcpc reads).
    ToMcpc(ToMcpcArgs),
    /// Simulate the paper's section 5.2 experiment: calibrate a randomly wrong, gravity-loaded
    /// robot from noisy laser-tracker data, without and with flexibility compensation.
    Simulate(SimulateArgs),
    /// Calibrate from laser-tracker measurements: identified parameters with uncertainties,
    /// errors before and after per arm, a corrected URDF.
    Calibrate(CalibrateArgs),
    /// Write calibrated MCPC parameters into the robot's URDF: corrected joint origins (and
    /// axes where needed), everything else in the file unchanged.
    Export(ExportArgs),
    /// Identifiability of a pose set: singular values, rank, condition number, observability
    /// indices O1-O5 and the parameter combinations the poses cannot determine.
    Check(CheckArgs),
    /// Plan calibration poses: choose collision-free configurations that make the parameters
    /// best observable (greedy pick + DETMAX exchanges on an observability index).
    Plan(PlanArgs),
    /// Pair a joint-state log (CSV or ROS 2 bag in MCAP) with a tracker log: find the clock
    /// offset from the motion and the static plateaus, write the measurement CSV and a report.
    Pair(PairArgs),
    /// Verify a deployed calibration on fresh measurements: per-row and summary errors, the
    /// strata against the calibrated ranges, the worst row, a verdict against --max-error.
    Verify(crate::cli_trust::VerifyArgs),
    /// Compare two calibrations: parameters moved beyond k combined σ, the predicted tool
    /// displacement, the validation figures side by side.
    Compare(crate::cli_trust::CompareArgs),
}

#[derive(Clone, Copy, ValueEnum)]
pub enum Format {
    Text,
    Yaml,
    Json,
}

#[derive(Clone, Copy, ValueEnum)]
pub enum AngleUnit {
    Rad,
    Deg,
}

/// A length unit, the error as the library words it with the settings spelled as flags.
pub(crate) fn parse_length_unit(text: &str) -> Result<treecal::io::LengthUnit, String> {
    text.parse()
        .map_err(|e: treecal::Error| crate::settings::with_flags(&e.to_string()))
}

/// An angle unit, the error as the library words it with the settings spelled as flags.
pub(crate) fn parse_angle_unit(text: &str) -> Result<treecal::io::AngleUnit, String> {
    text.parse()
        .map_err(|e: treecal::Error| crate::settings::with_flags(&e.to_string()))
}
