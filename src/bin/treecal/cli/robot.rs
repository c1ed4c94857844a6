//! Arguments of the commands on one robot file: `inspect`, `fk`, `from-mcpc`, `to-mcpc`,
//! `export`.

use super::{AngleUnit, Format};
use clap::Args;
use std::path::PathBuf;

/// Arguments of `treecal inspect`.
#[derive(Args)]
#[command(
    after_help = "Without --robot, the built-in Robonaut (robots/robonaut/robonaut.urdf, generated from the paper's Table 1) is inspected.\n\nExamples:\n  treecal inspect\n  treecal inspect --robot robots/humanoid/humanoid.urdf --format yaml\n  treecal inspect --robot ../shared/robots/robonaut2/robonaut2.urdf --tools r2/left_palm,r2/right_palm"
)]
pub struct InspectArgs {
    /// The robot's URDF file [default: the built-in Robonaut]; the same as --robot.
    #[arg(value_name = "ROBOT", conflicts_with = "robot")]
    pub robot_file: Option<PathBuf>,
    /// The robot's URDF file [default: the built-in Robonaut].
    #[arg(long, value_name = "ROBOT.urdf")]
    pub robot: Option<PathBuf>,
    /// Tool links ending the arms, comma-separated. Left and right are told apart by names, else by
    /// the tips' y (+y is left); the order given only decides when neither does. Without this, the
    /// two arm end links are found automatically and the rule that decided is printed.
    #[arg(long, value_delimiter = ',', value_name = "LINK,LINK")]
    pub tools: Option<Vec<String>>,
    /// The link fixed in the world while measuring (a sole on the floor, a mobile base):
    /// measurements are relative to it, paths from it may run up a leg [default: the URDF root].
    #[arg(long, value_name = "LINK")]
    pub reference_link: Option<String>,
    /// Output format.
    #[arg(long, value_enum, default_value = "text")]
    pub format: Format,
}

/// Arguments of `treecal fk`.
#[derive(Args)]
#[command(
    after_help = "The input CSV has a header row naming joints as in the URDF; joints without a column are 0; lines starting with # are comments. Columns that match no joint are passed through unchanged and listed on stderr, so a typo is visible. The output repeats every input row and appends x,y,z (metres) and r11..r33 (rotation matrix, row-major) of the tip link's pose in the root link frame.\n\nExample:\n  treecal fk --robot robots/robonaut/robonaut.urdf --tip left_tool --joints joints.csv -o poses.csv"
)]
pub struct FkArgs {
    /// The robot's URDF file [default: the built-in Robonaut]; the same as --robot.
    #[arg(value_name = "ROBOT", conflicts_with = "robot")]
    pub robot_file: Option<PathBuf>,
    /// The robot's URDF file [default: the built-in Robonaut].
    #[arg(long, value_name = "ROBOT.urdf")]
    pub robot: Option<PathBuf>,
    /// The link whose pose is computed.
    #[arg(long)]
    pub tip: String,
    /// CSV of joint values, one configuration per row.
    #[arg(long, value_name = "IN.csv")]
    pub joints: PathBuf,
    /// Output CSV [default: standard output] (`--output` is accepted too).
    #[arg(short = 'o', long = "out", alias = "output", value_name = "OUT.csv")]
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
    /// The URDF file to write (written atomically; `--output` is accepted too).
    #[arg(short = 'o', long = "out", alias = "output", value_name = "OUT.urdf")]
    pub output: PathBuf,
}

/// Arguments of `treecal to-mcpc`.
#[derive(Args)]
#[command(
    after_help = "The table lists the detected (or named) branches only, with the constant phi of every row; `treecal from-mcpc` turns it back into a URDF whose tool poses and joint axes equal the original's. Mimic relations and joints off the branches are not part of a table; continuous joints get limits of +-180 deg.\n\nExample:\n  treecal to-mcpc --robot robots/humanoid/humanoid.urdf -o humanoid_mcpc.yaml"
)]
pub struct ToMcpcArgs {
    /// The robot's URDF file [default: the built-in Robonaut]; the same as --robot.
    #[arg(value_name = "ROBOT", conflicts_with = "robot")]
    pub robot_file: Option<PathBuf>,
    /// The robot's URDF file [default: the built-in Robonaut].
    #[arg(long, value_name = "ROBOT.urdf")]
    pub robot: Option<PathBuf>,
    /// Tool links ending the arms, comma-separated (see `inspect --help`).
    #[arg(long, value_delimiter = ',', value_name = "LINK,LINK")]
    pub tools: Option<Vec<String>>,
    /// The YAML file to write [default: standard output] (`--output` is accepted too).
    #[arg(short = 'o', long = "out", alias = "output", value_name = "OUT.yaml")]
    pub output: Option<PathBuf>,
}

/// Arguments of `treecal export`.
#[derive(Args)]
#[command(
    after_help = "The parameter file lists `parameters:` entries with `name` (as `treecal inspect` names them, e.g. \"left_joint1 alpha\") and `calibrated` (rad, m); other keys are ignored and parameters not listed keep their nominal value (with a warning). Only the <origin> (and, for a tool link carried directly by a moving joint, the <axis>) of the joints that change are rewritten; every other byte of the URDF is kept. The tracker (world) frame is not exported: poses are in the root link frame. See docs/export.md.\n\nExample:\n  treecal export --robot robots/robonaut/robonaut.urdf --params params.yaml -o calibrated.urdf"
)]
pub struct ExportArgs {
    /// The robot's URDF file [default: the built-in Robonaut].
    #[arg(long)]
    pub robot: Option<PathBuf>,
    /// The calibrated MCPC parameters (YAML).
    #[arg(long, value_name = "PARAMS.yaml")]
    pub params: PathBuf,
    /// Tool links ending the arms, comma-separated (see `inspect --help`); must be the ones
    /// the parameters were calibrated with.
    #[arg(long, value_delimiter = ',', value_name = "LINK,LINK")]
    pub tools: Option<Vec<String>>,
    /// The reference link the parameters were calibrated from (`calibrate --reference-link`):
    /// without it the joints up the supporting leg are not in the model and keep their URDF
    /// values [default: the URDF root].
    #[arg(long, value_name = "LINK")]
    pub reference_link: Option<String>,
    /// The URDF file to write (written atomically; `--output` is accepted too).
    #[arg(short = 'o', long = "out", alias = "output", value_name = "OUT.urdf")]
    pub output: PathBuf,
    /// When a tool link is the child of a revolute joint and its calibrated origin lies off
    /// the joint axis by more than the calibration's uncertainty (which a URDF joint cannot
    /// express), leave the tool link where its joint puts it and add a fixed child link
    /// `<tool>_marker` at the exact calibrated tool frame instead of failing (docs/export.md).
    #[arg(long)]
    pub add_tool_links: bool,
}
