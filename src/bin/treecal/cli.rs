//! Command-line arguments (clap derive). Nothing here does any work.

use clap::{Args, Parser, Subcommand, ValueEnum};
use std::path::PathBuf;

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

/// Arguments of `treecal inspect`.
#[derive(Args)]
#[command(
    after_help = "Without ROBOT, the built-in Robonaut (robots/robonaut/robonaut.urdf, generated from the paper's Table 1) is inspected.\n\nExamples:\n  treecal inspect\n  treecal inspect robots/humanoid/humanoid.urdf --format yaml\n  treecal inspect ../shared/robots/robonaut2/robonaut2.urdf --tools r2/left_palm,r2/right_palm"
)]
pub struct InspectArgs {
    /// The robot's URDF file [default: the built-in Robonaut].
    pub robot: Option<PathBuf>,
    /// Tool links ending the arms, comma-separated. Left and right are told apart by names, else by
    /// the tips' y (+y is left); the order given only decides when neither does. Without this, the
    /// two arm end links are found automatically and the rule that decided is printed.
    #[arg(long, value_delimiter = ',', value_name = "LINK,LINK")]
    pub tools: Option<Vec<String>>,
    /// Output format.
    #[arg(long, value_enum, default_value = "text")]
    pub format: Format,
}

/// Arguments of `treecal fk`.
#[derive(Args)]
#[command(
    after_help = "The input CSV has a header row naming joints as in the URDF; joints without a column are 0; lines starting with # are comments. Columns that match no joint are passed through unchanged and listed on stderr, so a typo is visible. The output repeats every input row and appends x,y,z (metres) and r11..r33 (rotation matrix, row-major) of the tip link's pose in the root link frame.\n\nExample:\n  treecal fk robots/robonaut/robonaut.urdf --tip left_tool --joints joints.csv -o poses.csv"
)]
pub struct FkArgs {
    /// The robot's URDF file.
    pub robot: PathBuf,
    /// The link whose pose is computed.
    #[arg(long)]
    pub tip: String,
    /// CSV of joint values, one configuration per row.
    #[arg(long, value_name = "IN.csv")]
    pub joints: PathBuf,
    /// Output CSV [default: standard output].
    #[arg(short, long, value_name = "OUT.csv")]
    pub output: Option<PathBuf>,
    /// Unit of revolute joint values in the CSV (prismatic values are always metres).
    #[arg(long, value_enum, default_value = "rad")]
    pub angle_unit: AngleUnit,
}

/// Arguments of `treecal from-mcpc`.
#[derive(Args)]
#[command(
    after_help = "The table format is described in docs/file-formats.md; robots/robonaut/table1.yaml is the paper's Table 1.\n\nExample:\n  treecal from-mcpc robots/robonaut/table1.yaml -o robots/robonaut/robonaut.urdf"
)]
pub struct FromMcpcArgs {
    /// The MCPC table (YAML).
    pub table: PathBuf,
    /// The URDF file to write (written atomically).
    #[arg(short, long, value_name = "OUT.urdf")]
    pub output: PathBuf,
}

/// Arguments of `treecal to-mcpc`.
#[derive(Args)]
#[command(
    after_help = "The table lists the detected (or named) branches only, with the constant phi of every row; `treecal from-mcpc` turns it back into a URDF whose tool poses and joint axes equal the original's. Mimic relations and joints off the branches are not part of a table; continuous joints get limits of +-180 deg.\n\nExample:\n  treecal to-mcpc robots/humanoid/humanoid.urdf -o humanoid_mcpc.yaml"
)]
pub struct ToMcpcArgs {
    /// The robot's URDF file [default: the built-in Robonaut].
    pub robot: Option<PathBuf>,
    /// Tool links ending the arms, comma-separated (see `inspect --help`).
    #[arg(long, value_delimiter = ',', value_name = "LINK,LINK")]
    pub tools: Option<Vec<String>>,
    /// The YAML file to write [default: standard output].
    #[arg(short, long, value_name = "OUT.yaml")]
    pub output: Option<PathBuf>,
}
