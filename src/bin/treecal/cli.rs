//! Command-line arguments (clap derive). Nothing here does any work.

use clap::builder::{EnumValueParser, PossibleValue, TypedValueParser};
use clap::{Args, Parser, Subcommand, ValueEnum};
use std::path::{Path, PathBuf};

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

#[derive(Clone, Copy, ValueEnum)]
pub enum PlanChoice {
    /// The paper's staging: the torso with the arms locked, then the arms.
    Staged,
    /// Every parameter from every measurement at once.
    Simultaneous,
}

/// Arguments of `treecal simulate`.
#[derive(Args)]
#[command(
    after_help = "Without --robot, the built-in Robonaut and its stiffness file (robots/robonaut/stiffness.yaml: joints 5000 N·m/rad, 20 kg per tool) are used.\n\nOutputs in --out: summary.md (the tables), results.json (every number), and SVG plots of the per-configuration errors of trial 1 (as the paper's Fig. 7-8).\n\nExamples:\n  treecal simulate\n  treecal simulate --trials 100 --plan simultaneous\n  treecal simulate --noise 0 --model-stiffness-scale 1.1"
)]
pub struct SimulateArgs {
    /// The robot's URDF file [default: the built-in Robonaut].
    #[arg(long)]
    pub robot: Option<PathBuf>,
    /// A directory searched for `package://` collision meshes: a folder holding packages, or
    /// a package folder itself; repeatable, searched in order before ROS_PACKAGE_PATH.
    #[arg(long = "package-path", value_name = "DIR")]
    pub package_path: Vec<PathBuf>,
    /// Which collision shapes configurations are checked against: `meshes` (a mesh that
    /// cannot be found or read is an error), `primitives-only` or `off`; stated in the output.
    #[arg(long, value_enum, default_value_t = CollisionCheckChoice::Meshes)]
    pub collision_check: CollisionCheckChoice,
    /// Stiffness YAML (gravity, payloads, joint and link stiffness) [default: the built-in
    /// Robonaut's; required with --robot].
    #[arg(long)]
    pub stiffness: Option<PathBuf>,
    /// Tool links ending the arms (see `inspect --help`).
    #[arg(long, value_delimiter = ',', value_name = "LINK,LINK")]
    pub tools: Option<Vec<String>>,
    /// The link fixed in the world while measuring (a sole on the floor, a mobile base):
    /// measurements are relative to it, paths from it may run up a leg [default: the URDF root].
    #[arg(long, value_name = "LINK")]
    pub reference_link: Option<String>,
    /// Configurations measured for the arms.
    #[arg(long, default_value_t = 20, allow_negative_numbers = true)]
    pub poses: u32,
    /// Configurations measured for the torso with the arms locked (used by both plans).
    #[arg(long, default_value_t = 10, allow_negative_numbers = true)]
    pub torso_poses: u32,
    /// Separate configurations the results are validated on.
    #[arg(long, default_value_t = 20, allow_negative_numbers = true)]
    pub validation_poses: u32,
    /// Simulated calibrations, each with a new true robot.
    #[arg(long, default_value_t = 1, allow_negative_numbers = true)]
    pub trials: u32,
    /// Master seed; the same seed gives the same results.json.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Tracker noise: 0 (none), at901 (15 µm + 6 µm/m per coordinate), or CONSTANT+PER_METRE in µm.
    #[arg(long, default_value = "at901")]
    pub noise: String,
    /// Robust estimation in both calibrations (see `calibrate --help`).
    #[arg(long, value_enum, default_value = "huber")]
    pub robust: RobustChoice,
    /// Fraction of the measurements turned into blunders (one target bumped, or the position
    /// moved, by --outlier-size in a random direction), e.g. 0.03.
    #[arg(long, default_value_t = 0.0, value_name = "FRACTION")]
    pub outliers: f64,
    /// How far a blunder moves its target (mm).
    #[arg(long, default_value_t = 50.0, value_name = "MM")]
    pub outlier_size: f64,
    /// Payloads (kg at every tool) the identification poses are measured at, in turn: the
    /// rows split evenly, each with its `payload_kg` [default: the stiffness file's payload].
    #[arg(long, value_delimiter = ',', value_name = "KG,KG")]
    pub payloads: Option<Vec<f64>>,
    /// Targets per tool: 3 (a frame, as in the paper's section 5.3.1) or 1 (a position).
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u8).range(1..=3))]
    pub targets: u8,
    /// Calibration plan.
    #[arg(long, value_enum, default_value = "staged")]
    pub plan: PlanChoice,
    /// Half-width of the true robot's angle errors (rad).
    #[arg(long, default_value_t = 0.05)]
    pub angle_error: f64,
    /// Half-width of the true robot's length errors (m).
    #[arg(long, default_value_t = 0.05)]
    pub length_error: f64,
    /// First-harmonic joint-angle errors of the true robot: `a·sin q + b·cos q` on every
    /// revolute joint, a and b uniform in ±this (rad) [default: none].
    #[arg(long, default_value_t = 0.0, value_name = "RAD")]
    pub truth_harmonics: f64,
    /// Backlash of the true robot: half the dead band of every revolute joint, uniform in
    /// [this/2, this] (rad), signed by the gravity torque (needs the URDF's inertials)
    /// [default: none].
    #[arg(long, default_value_t = 0.0, value_name = "RAD")]
    pub truth_backlash: f64,
    /// Payload at every tool (kg), overriding the stiffness file.
    #[arg(long)]
    pub payload: Option<f64>,
    /// Bending and torsion stiffness of every joint (N·m/rad), overriding the stiffness file.
    #[arg(long)]
    pub joint_stiffness: Option<f64>,
    /// Stiffness the compensating model assumes, relative to the truth's (1.1 = 10 % too stiff).
    #[arg(long, default_value_t = 1.0)]
    pub model_stiffness_scale: f64,
    /// Identify the compliances jointly with the geometry in the compensated calibration,
    /// starting from the model's stiffness (see --model-stiffness-scale) as a ±50 % prior.
    #[arg(long)]
    pub identify_stiffness: bool,
    /// Output folder.
    #[arg(short = 'o', long, default_value = "out/simulate", value_name = "DIR")]
    pub out: PathBuf,
    /// Also write trial 1's simulated measurements as CSV (docs/file-formats.md).
    #[arg(long, value_name = "FILE")]
    pub write_measurements: Option<PathBuf>,
    /// Layout of --write-measurements: `si` (poses or positions, m and rad) or `tracker`
    /// (three targets A, B, C per tool in mm, joints in deg, as tracker software exports them;
    /// needs --targets 3). Read back with `calibrate --length-unit mm --angle-unit deg`.
    #[arg(long, value_enum, default_value = "si")]
    pub measurement_format: MeasurementFormat,
    /// Where the identification configurations come from: drawn at random, or planned (O1,
    /// greedy + DETMAX) from --candidates random ones with the nominal model in every trial.
    #[arg(long, value_enum, default_value = "random")]
    pub poses_from: PosesFrom,
    /// Candidate configurations each planned pose set is chosen from (--poses-from planned).
    #[arg(long, default_value_t = 2000, allow_negative_numbers = true)]
    pub candidates: u32,
    /// What is observed: `tracker` (the paper's experiment), `camera` (a camera on the
    /// coupled branch's last link sees a board on each tool and one in the world; rigid robot;
    /// --poses + --torso-poses configurations), `mixed` (camera and tracker, each with its
    /// σ) or `rigid-tracker` (the tracker at the camera simulation's configurations); or a
    /// comma list of contacts (docs/contacts.md): `flush` (the first tool's face flush with a
    /// plane), `plane` (its contact point on a plane), `touch` (the first two tools' contact
    /// points touch), `bar` (they hold a 0.3 m bar), --poses + --torso-poses configurations each;
    /// contacts with `camera`, `mixed` or `rigid-tracker` (e.g. `camera,touch`) are fitted with
    /// the camera's observations.
    #[arg(long, value_enum, value_delimiter = ',', default_value = "tracker")]
    pub observation: Vec<ObservationArg>,
    /// Encoder noise σ on the recorded configurations of a contact simulation (rad).
    #[arg(long, default_value_t = 0.0, value_name = "RAD")]
    pub encoder_noise: f64,
    /// Flush contacts on this many tables (sessions `day1`, `day2`, …, one plane each).
    #[arg(long, default_value_t = 1, value_name = "N")]
    pub tables: usize,
    /// Flush contacts of both hands (the first two tools) on every table, not the first's only.
    #[arg(long)]
    pub both_hands: bool,
    /// The camera's link (--observation camera|mixed) [default: the coupled branch's last link].
    #[arg(long, value_name = "LINK")]
    pub camera_link: Option<String>,
    /// Pixel noise σ of a detected board corner (px).
    #[arg(long, default_value_t = 0.5, value_name = "PX")]
    pub pixel_sigma: f64,
    /// No board in the world: the camera then sees the tools only relative to itself, and the
    /// coupled branch's parameters are not determined (named in the output).
    #[arg(long)]
    pub no_world_board: bool,
    /// Estimate the camera's intrinsics (fx, fy, cx, cy, k1, k2, p1, p2, k3) with the robot.
    #[arg(long)]
    pub estimate_intrinsics: bool,
}

#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ObservationArg {
    /// A laser tracker (the paper's experiment).
    Tracker,
    /// The head camera and the boards.
    Camera,
    /// Camera and tracker together.
    Mixed,
    /// The tracker at the camera simulation's configurations (rigid robot).
    RigidTracker,
    /// A tool's face flush with a plane (contact).
    Flush,
    /// A tool's contact point on a plane (contact).
    Plane,
    /// Two tools' contact points touching (contact).
    Touch,
    /// Two tools' contact points holding a bar (contact).
    Bar,
}

#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum CollisionCheckChoice {
    /// Primitives and meshes; a mesh that cannot be found or read is an error.
    Meshes,
    /// Primitive shapes only (box, cylinder, capsule, sphere); meshes are not checked.
    PrimitivesOnly,
    /// No self-collision check.
    Off,
}

impl From<CollisionCheckChoice> for treecal::sim::CollisionCheck {
    fn from(choice: CollisionCheckChoice) -> Self {
        match choice {
            CollisionCheckChoice::Meshes => Self::Meshes,
            CollisionCheckChoice::PrimitivesOnly => Self::PrimitivesOnly,
            CollisionCheckChoice::Off => Self::Off,
        }
    }
}

#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum PosesFrom {
    /// Uniform random collision-free configurations.
    Random,
    /// Planned to maximise the O1 observability index.
    Planned,
}

#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum CriterionChoice {
    /// Geometric mean of the scaled singular values over √(observations).
    O1,
    /// log det of the scaled information matrix (D-optimality).
    D,
    /// Smallest scaled singular value.
    O3,
}

#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum StageChoice {
    /// Every parameter at once (simultaneous plan).
    All,
    /// The arms, with the torso held.
    Arms,
    /// The torso, with the arms locked.
    Torso,
    /// The paper's staging: a torso set (--torso-poses, arms locked) then an arms set (--poses).
    Staged,
}

/// Arguments of `treecal plan`.
#[derive(Args)]
#[command(
    after_help = "Candidates are drawn uniformly within the joint limits; those in self-collision (URDF collision primitives, and STL, OBJ and COLLADA meshes that resolve: relative to the URDF, file://, or package:// through --package-path and ROS_PACKAGE_PATH) or with a tool outside --workspace are rejected. The output CSV has one row per tool per configuration: [stage,]tool,<joint columns> (metres, radians), the measurement CSV without its measured columns (docs/file-formats.md). See docs/planning.md.\n\nExamples:\n  treecal plan --poses 20 -o poses.csv\n  treecal plan --robot robots/humanoid/humanoid.urdf --poses 30 --criterion d --stage staged -o poses.csv\n  treecal plan --poses 20 --workspace 0.2,-1,-0.5,1.5,1,1 -o poses.csv"
)]
pub struct PlanArgs {
    /// The robot's URDF file [default: the built-in Robonaut].
    #[arg(long)]
    pub robot: Option<PathBuf>,
    /// A directory searched for `package://` collision meshes: a folder holding packages, or
    /// a package folder itself; repeatable, searched in order before ROS_PACKAGE_PATH.
    #[arg(long = "package-path", value_name = "DIR")]
    pub package_path: Vec<PathBuf>,
    /// Which collision shapes configurations are checked against: `meshes` (a mesh that
    /// cannot be found or read is an error), `primitives-only` or `off`; stated in the output.
    #[arg(long, value_enum, default_value_t = CollisionCheckChoice::Meshes)]
    pub collision_check: CollisionCheckChoice,
    /// Tool links ending the arms (see `inspect --help`).
    #[arg(long, value_delimiter = ',', value_name = "LINK,LINK")]
    pub tools: Option<Vec<String>>,
    /// The link fixed in the world while measuring (a sole on the floor, a mobile base):
    /// measurements are relative to it, paths from it may run up a leg [default: the URDF root].
    #[arg(long, value_name = "LINK")]
    pub reference_link: Option<String>,
    /// Configurations to choose (for --stage staged: the arms set).
    #[arg(long, allow_negative_numbers = true)]
    pub poses: u32,
    /// Configurations of the torso set for --stage staged (arms locked).
    #[arg(long, default_value_t = 10, allow_negative_numbers = true)]
    pub torso_poses: u32,
    /// Collision-free candidate configurations to choose from.
    #[arg(long, default_value_t = 5000, allow_negative_numbers = true)]
    pub candidates: u32,
    /// Observability index to maximise.
    #[arg(long, value_enum, default_value = "o1")]
    pub criterion: CriterionChoice,
    /// Targets per tool: 3 (a frame, 6 rows) or 1 (a position, 3 rows).
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u8).range(1..=3))]
    pub targets: u8,
    /// Which calibration stage the poses are for.
    #[arg(long, value_enum, default_value = "all")]
    pub stage: StageChoice,
    /// Box every tool origin must lie in, in the base frame (m): xmin,ymin,zmin,xmax,ymax,zmax.
    #[arg(
        long,
        value_delimiter = ',',
        allow_negative_numbers = true,
        value_name = "XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX"
    )]
    pub workspace: Option<Vec<f64>>,
    /// Expected position noise of a measurement (m): position rows are divided by it (as in
    /// check and calibrate).
    #[arg(long, default_value_t = treecal::calibration::DEFAULT_POSITION_SIGMA)]
    pub position_sigma: f64,
    /// Expected rotation noise of a measured frame (rad): rotation rows are divided by it (as
    /// in check and calibrate).
    #[arg(long, default_value_t = treecal::calibration::DEFAULT_ROTATION_SIGMA)]
    pub rotation_sigma: f64,
    /// Weight the rows by a tracker noise model instead of the σ's (as simulate --noise: 0,
    /// at901, or CONSTANT+PER_METRE in µm; the σ's used are printed).
    #[arg(long, conflicts_with_all = ["position_sigma", "rotation_sigma"])]
    pub noise: Option<String>,
    /// Seed of the candidate draws; the same seed gives the same file.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Camera file (cameras and targets, docs/file-formats.md): choose configurations in which
    /// the cameras see the boards (in the image, facing the camera within --max-view-angle,
    /// not hidden by the robot's collision shapes) and that make the pixels most informative
    /// (docs/camera.md); --candidates then counts configurations showing a board.
    #[arg(
        long,
        value_name = "CAMERAS.yaml",
        conflicts_with_all = ["stage", "workspace", "noise", "reference_link", "targets"]
    )]
    pub camera: Option<PathBuf>,
    /// Pixel noise σ of a detected point (px), with --camera.
    #[arg(long, default_value_t = 0.5, value_name = "PX", requires = "camera")]
    pub pixel_sigma: f64,
    /// Largest angle between a board's face normal and the direction to the camera (degrees),
    /// with --camera.
    #[arg(long, default_value_t = 60.0, value_name = "DEG", requires = "camera")]
    pub max_view_angle: f64,
    /// The CSV to write (atomically).
    #[arg(short = 'o', long = "out", alias = "output", value_name = "OUT.csv")]
    pub out: PathBuf,
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
    /// express), add a fixed child link `<tool>_calibrated` at the exact calibrated tool frame
    /// instead of failing (docs/export.md).
    #[arg(long)]
    pub add_tool_links: bool,
}

/// Arguments of `treecal check`.
#[derive(Args)]
#[command(
    after_help = "--pose-file is a CSV with a header naming joints (as for `treecal fk`; joints without a column are 0), an optional `tool` column (the tool link measured in that row; without it every tool is measured at every row) and an optional `stage` column (torso: arms locked, or arms) for the staged plan. Without --pose-file or --measurements, a seeded random collision-free set is analysed (20 configurations; the staged plan adds 10 torso configurations at 2 locked arm configurations).\n\nThe exit code is 0 whenever the report is written, also for a rank-deficient set. See docs/identifiability.md.\n\nExamples:\n  treecal check\n  treecal check --pose-file poses.csv --plan simultaneous --targets 1\n  treecal check --robot robots/humanoid/humanoid.urdf --format yaml"
)]
pub struct CheckArgs {
    /// The robot's URDF file [default: the built-in Robonaut].
    #[arg(long)]
    pub robot: Option<PathBuf>,
    /// Tool links ending the arms (see `inspect --help`).
    #[arg(long, value_delimiter = ',', value_name = "LINK,LINK")]
    pub tools: Option<Vec<String>>,
    /// The link fixed in the world while measuring (a sole on the floor, a mobile base):
    /// measurements are relative to it, paths from it may run up a leg [default: the URDF root].
    #[arg(long, value_name = "LINK")]
    pub reference_link: Option<String>,
    /// CSV of the configurations to be measured (joint columns, optional `tool` and `stage`),
    /// e.g. what `treecal plan` writes.
    #[arg(long, value_name = "P.csv", conflicts_with_all = ["measurements", "poses"])]
    pub pose_file: Option<PathBuf>,
    /// The old spelling of --pose-file (a file, not a count as in simulate and plan).
    #[arg(long, value_name = "P.csv", conflicts_with = "measurements", hide = true, value_parser = parse_pose_file)]
    pub poses: Option<PathBuf>,
    /// Measurement CSV (docs/file-formats.md): its configurations, tools and stages are analysed.
    #[arg(long, value_name = "M.csv")]
    pub measurements: Option<PathBuf>,
    /// Unit of lengths in --measurements (positions, targets, prismatic joints) [default: the
    /// file's `# units:` comment, else m].
    #[arg(long, value_parser = parse_length_unit)]
    pub length_unit: Option<treecal::io::LengthUnit>,
    /// Unit of prismatic joint values in --measurements [default: the file's `# units:`
    /// comment, else --length-unit].
    #[arg(long, value_parser = parse_length_unit)]
    pub joint_length_unit: Option<treecal::io::LengthUnit>,
    /// Columns of --measurements to skip, comma-separated.
    #[arg(long, value_delimiter = ',', value_name = "COLUMN,COLUMN")]
    pub ignore_columns: Vec<String>,
    /// Targets per tool: 3 (a full pose) or 1 (a position).
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u8).range(1..=3))]
    pub targets: u8,
    /// Calibration plan whose stages are analysed [default: staged when the rows are labelled
    /// torso/arms (and for the default random set), else simultaneous].
    #[arg(long, value_enum)]
    pub plan: Option<PlanChoice>,
    /// A calibration plan file (YAML, docs/file-formats.md) whose stages are analysed.
    #[arg(long, value_name = "PLAN.yaml", conflicts_with = "plan")]
    pub plan_file: Option<PathBuf>,
    /// Expected position error of a measurement (m): position rows are divided by it.
    #[arg(long, default_value_t = treecal::calibration::DEFAULT_POSITION_SIGMA)]
    pub position_sigma: f64,
    /// Expected rotation error of a measurement (rad): rotation rows are divided by it.
    #[arg(long, default_value_t = treecal::calibration::DEFAULT_ROTATION_SIGMA)]
    pub rotation_sigma: f64,
    /// Condition number above which a set is reported as poorly conditioned.
    #[arg(long, default_value_t = 100.0)]
    pub condition_limit: f64,
    /// Unit of revolute joint values in --pose-file and --measurements (prismatic values in
    /// --pose-file are always metres) [default: the file's `# units:` comment, else rad].
    #[arg(long, value_enum)]
    pub angle_unit: Option<AngleUnit>,
    /// Seed of the default random pose set.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Output format.
    #[arg(long, value_enum, default_value = "text")]
    pub format: Format,
    /// Also analyse which joint and link compliances the poses determine with the geometry
    /// free (docs/flexibility.md, section 12), with the stiffness of --stiffness.
    #[arg(long)]
    pub identify_stiffness: bool,
    /// Stiffness YAML for --identify-stiffness [default: the built-in Robonaut's, or the
    /// library defaults with --robot].
    #[arg(long)]
    pub stiffness: Option<PathBuf>,
    /// Payloads (kg at every tool) at which every pose is measured, for --identify-stiffness
    /// [default: the stiffness file's payloads].
    #[arg(long, value_delimiter = ',', value_name = "KG,KG")]
    pub payloads: Option<Vec<f64>>,
    /// Relative uncertainty of the prior stiffness (0.5: ±50 %).
    #[arg(long, default_value_t = 0.5)]
    pub stiffness_prior: f64,
    /// Camera file (cameras and targets, docs/file-formats.md): with --detections, say what
    /// the camera detections determine instead of analysing poses (docs/camera.md, section 5).
    #[arg(long, value_name = "FILE", requires = "detections")]
    pub camera: Option<PathBuf>,
    /// Camera detections CSV (with --camera).
    #[arg(long, value_name = "FILE", requires = "camera")]
    pub detections: Option<PathBuf>,
    /// Pixel noise σ of a detected point (px), with --camera.
    #[arg(long, default_value_t = 0.5, value_name = "PX")]
    pub pixel_sigma: f64,
}

/// `--noise`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum NoiseArg {
    /// Declared; estimated as a cross-validation candidate.
    Adaptive,
    /// Always estimated from the residuals.
    Estimated,
    /// Always as declared.
    Declared,
}

/// `--model`.
#[derive(Clone, Copy, ValueEnum)]
pub enum ModelArg {
    /// The full geometry, or as `auto` when its fit leaves residuals over 10× the declared
    /// noise (model error).
    Adaptive,
    /// Joint zero offsets, the tools and the measurement frame.
    Offsets,
    /// The full MCPC geometry.
    Geometry,
    /// Chosen by cross-validation.
    Auto,
}

/// `--joint-errors`.
#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum JointErrorArg {
    /// First-harmonic errors.
    Harmonics,
    /// Backlash signed by gravity.
    Backlash,
}

/// Arguments of `treecal calibrate`.
#[derive(Args)]
#[command(
    after_help = "The measurement CSV (docs/file-formats.md) has a `tool` column, one column per joint of the measured tool's chain (named as in the URDF), optional `id` and `stage` columns, and x,y,z (a target), x,y,z,qw,qx,qy,qz (a pose) or ax,ay,az,bx,by,bz,cx,cy,cz (three targets A, B, C on the tool: origin A, X along AB, Z along AB × AC). Without --tools the measured tools are the links the `tool` column names. Units come from the flags, else the file's `# units: length=mm angle=deg` comment, else m and rad; a flag that contradicts the comment is an error, and positions 1000× off or joint values that look like degrees (or radians) are named before solving. The targets' frame on each tool is fitted; the measurement frame is fitted, or the robot's root frame when the data are already in it (--measurement-frame auto; see docs/calibration.md).\n\nThe staged plan (the default when rows are labelled `stage` = torso / arms) calibrates the torso from the torso rows with the arms locked, then the arms; without labels the simultaneous plan is used. With --stiffness the deflections under gravity are compensated exactly. Without --validation a seeded fifth of the (non-torso) configurations is held out for validation.\n\nWrites to --out: calibrated.urdf, params.yaml, report.md, report.json, per-arm error plots (SVG), report.html (one self-contained page), calibration_overlay.yaml (the changed joint origins for xacro) and, when joint offsets alone carry the calibration, joint_offsets.yaml (docs/export.md).\n\nExample:\n  treecal calibrate --measurements robots/robonaut/example/measurements.csv --stiffness robots/robonaut/stiffness.yaml"
)]
pub struct CalibrateArgs {
    /// The robot's URDF file [default: the built-in Robonaut].
    #[arg(long)]
    pub robot: Option<PathBuf>,
    /// When a tool link is the child of a revolute joint and its calibrated origin lies off
    /// the joint axis by more than the calibration's uncertainty (which a URDF joint cannot
    /// express), add a fixed child link `<tool>_calibrated` at the exact calibrated tool frame
    /// instead of failing (docs/export.md).
    #[arg(long)]
    pub add_tool_links: bool,
    /// Which parameters describe the robot: `offsets` (joint zero offsets, the tools and the
    /// measurement frame), `geometry` (the full MCPC model), `auto` (the candidate with the
    /// lowest cross-validated held-out error; docs/identification.md), `adaptive` (`geometry`,
    /// or `auto` when the geometry fit leaves residuals over 10× the declared noise).
    #[arg(long, value_enum, default_value = "adaptive")]
    pub model: ModelArg,
    /// Joint-angle errors as extra parameters, comma-separated: `harmonics` (a·sin q + b·cos q
    /// per joint), `backlash` (half the dead band, signed by the gravity torque; needs the
    /// URDF's inertials).
    #[arg(long, value_enum, value_delimiter = ',', value_name = "TERM,TERM")]
    pub joint_errors: Vec<JointErrorArg>,
    /// A Gaussian prior on the nominal values (σ: frame angles 0.2°, lengths 2 mm, joint
    /// offsets 1°, harmonics and backlash 0.2°; tools and frame free), weighed at the fit's
    /// residual scale.
    #[arg(long)]
    pub prior: bool,
    /// Multiply every default prior σ by S (0.5: twice as tight); with --prior.
    #[arg(long, value_name = "S", default_value_t = 1.0, requires = "prior")]
    pub prior_scale: f64,
    /// Keep only the geometric corrections of at least K standard deviations (the others
    /// frozen at nominal, the rest refitted).
    #[arg(long, value_name = "K")]
    pub significant: Option<f64>,
    /// How rotation rows weigh against position rows: `estimated` (the σ ratio the fit's
    /// residuals show, by variance components; the position σ kept), `declared`
    /// (the position and rotation σ as given), `adaptive` (declared; the estimated
    /// ratio is a cross-validation candidate when the data choose the model).
    #[arg(long, value_enum, default_value = "adaptive")]
    pub noise: NoiseArg,
    /// Never free the parameters whose name matches PATTERN (glob on the names of params.yaml,
    /// e.g. 'arm_7_joint *'); repeatable.
    #[arg(long, value_name = "PATTERN")]
    pub freeze: Vec<String>,
    /// Free the parameters matching PATTERN even when the model or --freeze would not;
    /// repeatable.
    #[arg(long, value_name = "PATTERN")]
    pub free: Vec<String>,
    /// Cross-validate the model candidates over K folds of the postures (report.md,
    /// report.json `model_choice`); --model auto uses 5 without it.
    #[arg(long, value_name = "K")]
    pub cv: Option<usize>,
    /// Measurement CSV (one row per tool observation); not with --contacts; with --camera,
    /// tracker rows fitted together with the pixels (mixed data, each with its σ).
    #[arg(long, value_name = "M.csv", required_unless_present_any = ["contacts", "camera"])]
    pub measurements: Option<PathBuf>,
    /// Contacts CSV (docs/contacts.md, docs/file-formats.md): calibrate from contacts — faces
    /// flush on a plane, points on a plane, touches, a bar — instead of --measurements; with
    /// --contact-setup. --validation then takes held-out contacts; with --camera, the contacts
    /// are fitted with the pixels (--validation: held-out detections).
    #[arg(
        long,
        value_name = "C.csv",
        requires = "contact_setup",
        conflicts_with = "measurements"
    )]
    pub contacts: Option<PathBuf>,
    /// The contacts' setup (YAML): reference link, tools with their nominal contact faces and
    /// points, each session's nominal plane, the bar, what is fitted.
    #[arg(long, value_name = "S.yaml", requires = "contacts")]
    pub contact_setup: Option<PathBuf>,
    /// Validation measurements (same format) [default: hold out a seeded fifth]; with
    /// --contacts, held-out contacts; with --camera, held-out detections (a detections CSV),
    /// predicted but not fitted.
    #[arg(long, value_name = "V.csv")]
    pub validation: Option<PathBuf>,
    /// Camera file (cameras and targets, docs/file-formats.md): calibrate from the pixels of
    /// --detections, alone or with the tracker rows of --measurements (docs/camera.md).
    #[arg(
        long,
        value_name = "CAMERAS.yaml",
        requires = "detections",
        conflicts_with_all = [
            "stiffness", "identify_stiffness", "plan", "plan_file",
            "reference_link", "joint_errors", "prior", "significant", "cv", "freeze", "free"
        ]
    )]
    pub camera: Option<PathBuf>,
    /// Camera detections CSV (with --camera).
    #[arg(long, value_name = "D.csv", requires = "camera")]
    pub detections: Option<PathBuf>,
    /// Pixel noise σ of a detected point (px), with --camera.
    #[arg(long, default_value_t = 0.5, value_name = "PX")]
    pub pixel_sigma: f64,
    /// Link stiffness, joint compliance and payloads (YAML, docs/flexibility.md): compensate
    /// the deflections under gravity. Without it the robot is treated as rigid.
    #[arg(long, value_name = "S.yaml")]
    pub stiffness: Option<PathBuf>,
    /// Tool links ending the arms (see `inspect --help`).
    #[arg(long, value_delimiter = ',', value_name = "LINK,LINK")]
    pub tools: Option<Vec<String>>,
    /// The link fixed in the world while measuring (a sole on the floor, a mobile base):
    /// measurements are relative to it, paths from it may run up a leg [default: the URDF root].
    #[arg(long, value_name = "LINK")]
    pub reference_link: Option<String>,
    /// Calibration plan [default: staged when rows are labelled torso/arms, else
    /// simultaneous]; a value ending in .yaml is taken as --plan-file.
    #[arg(long, value_parser = PlanArgParser)]
    pub plan: Option<PlanArg>,
    /// A plan file (YAML, docs/file-formats.md) instead of --plan.
    #[arg(long, value_name = "PLAN.yaml", conflicts_with = "plan")]
    pub plan_file: Option<PathBuf>,
    /// Output folder.
    #[arg(short = 'o', long, default_value = "out/calibrate")]
    pub out: PathBuf,
    /// Unit of lengths in the CSV (positions, targets, prismatic joints) [default: the file's
    /// `# units: length=…` comment, else m]; contradicting the comment is an error.
    #[arg(long, value_parser = parse_length_unit)]
    pub length_unit: Option<treecal::io::LengthUnit>,
    /// Unit of revolute joint values in the CSV [default: the file's `# units: angle=…`
    /// comment, else rad]; contradicting the comment is an error.
    #[arg(long, value_parser = parse_angle_unit)]
    pub angle_unit: Option<treecal::io::AngleUnit>,
    /// Unit of prismatic joint values when it differs from --length-unit (a controller logging
    /// metres beside a tracker in mm) [default: the file's `# units: joint_length=…`, else the
    /// length unit].
    #[arg(long, value_parser = parse_length_unit)]
    pub joint_length_unit: Option<treecal::io::LengthUnit>,
    /// Columns to skip (e.g. a timestamp), comma-separated.
    #[arg(long, value_delimiter = ',', value_name = "COLUMN,COLUMN")]
    pub ignore_columns: Vec<String>,
    /// A joint value outside its URDF limits is an error (default: a warning).
    #[arg(long)]
    pub strict: bool,
    /// Expected position noise of a measurement (m): position rows are divided by it.
    #[arg(long, default_value_t = treecal::calibration::DEFAULT_POSITION_SIGMA)]
    pub position_sigma: f64,
    /// Expected rotation noise of a measured frame (rad): rotation rows are divided by it.
    #[arg(long, default_value_t = treecal::calibration::DEFAULT_ROTATION_SIGMA)]
    pub rotation_sigma: f64,
    /// Seed of the held-out validation fifth.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Robust estimation: measurements whose residual is far beyond the others' (a bumped
    /// target) are down-weighted, named in the report and left out (docs/identification.md).
    #[arg(long, value_enum, default_value = "huber")]
    pub robust: RobustChoice,
    /// The frame the stiffness file's gravity vector is given in: the measurement frame (a
    /// levelled tracker) or the robot's root link frame (a level robot base).
    #[arg(long, value_enum, default_value = "measurement")]
    pub gravity_frame: GravityFrame,
    /// `auto`: fitted in closed form, or the robot's root frame when that explains the data
    /// (docs/calibration.md); `fit`: the tracker's own frame, fitted and kept; `base`: already
    /// in the robot's root link frame (as `simulate --write-measurements` writes them); or a
    /// registration file (YAML: the robot base in the tracker frame, docs/file-formats.md).
    #[arg(
        long,
        default_value = "auto",
        value_name = "auto|fit|base|REGISTRATION.yaml"
    )]
    pub measurement_frame: MeasurementFrame,
    /// Identify the joint and link compliances the data determine, jointly with the geometry
    /// (docs/identification.md); the stiffness file (default: the library defaults) is the
    /// prior. Writes the identified stiffness to --out as stiffness.yaml.
    #[arg(long)]
    pub identify_stiffness: bool,
    /// Relative uncertainty of the prior stiffness for --identify-stiffness (0.5: ±50 %): a
    /// compliance is identified when the data determine it better than this.
    #[arg(long, default_value_t = 0.5)]
    pub stiffness_prior: f64,
}

/// The robust loss (`--robust`).
#[derive(Clone, Copy, ValueEnum)]
pub enum RobustChoice {
    /// Huber: weight 1 for residuals within 6.3–7.0 robust σ (clean data keep the
    /// least-squares result exactly), less beyond; convex.
    Huber,
    /// Cauchy: every weight below 1, a blunder's pull vanishing; clean results change slightly.
    Cauchy,
    /// Plain least squares.
    Off,
}

impl From<RobustChoice> for treecal::calibration::RobustLoss {
    fn from(choice: RobustChoice) -> Self {
        match choice {
            RobustChoice::Huber => Self::Huber,
            RobustChoice::Cauchy => Self::Cauchy,
            RobustChoice::Off => Self::Off,
        }
    }
}

/// How the measurement frame is found (`--measurement-frame`).
#[derive(Clone)]
pub enum MeasurementFrame {
    /// Fitted, or the root frame when it explains the data.
    Auto,
    /// Fitted to the data in closed form (Kabsch), then kept.
    Fit,
    /// The robot's root link frame.
    Base,
    /// A registration file.
    File(PathBuf),
}

impl std::str::FromStr for MeasurementFrame {
    type Err = std::convert::Infallible;

    fn from_str(text: &str) -> Result<Self, Self::Err> {
        Ok(match text {
            "auto" => MeasurementFrame::Auto,
            "fit" => MeasurementFrame::Fit,
            "base" => MeasurementFrame::Base,
            path => MeasurementFrame::File(PathBuf::from(path)),
        })
    }
}

/// Where gravity is fixed.
#[derive(Clone, Copy, ValueEnum)]
pub enum GravityFrame {
    /// The measurement (tracker) frame.
    Measurement,
    /// The robot's root link frame.
    Base,
}

/// `check --poses FILE` (the old spelling of --pose-file); a count is refused with directions,
/// since `--poses` is a count in simulate and plan.
fn parse_pose_file(text: &str) -> Result<PathBuf, String> {
    if text.trim().parse::<i64>().is_ok() && !std::path::Path::new(text).exists() {
        return Err(format!(
            "check takes a pose file, not a count: give it with --pose-file FILE (--poses is a \
             count in simulate and plan; to plan {text} poses and check them: treecal plan \
             --poses {text} -o poses.csv, then treecal check --pose-file poses.csv)"
        ));
    }
    Ok(PathBuf::from(text))
}

pub(crate) fn parse_length_unit(text: &str) -> Result<treecal::io::LengthUnit, String> {
    text.parse().map_err(|e: treecal::Error| e.to_string())
}

pub(crate) fn parse_angle_unit(text: &str) -> Result<treecal::io::AngleUnit, String> {
    text.parse().map_err(|e: treecal::Error| e.to_string())
}

/// How `simulate --write-measurements` writes the CSV.
#[derive(Clone, Copy, ValueEnum)]
pub enum MeasurementFormat {
    /// Poses (or positions), metres and radians.
    Si,
    /// Three targets per tool, millimetres and degrees.
    Tracker,
}

/// Arguments of `treecal pair`.
#[derive(Args)]
#[command(
    after_help = "The joint log is a CSV with a time column (seconds) and one column per joint named as in the URDF, or a ROS 2 bag (MCAP) holding sensor_msgs/msg/JointState. The tracker log is a CSV with a time column and x,y,z (a target) or x,y,z,qw,qx,qy,qz (a rigid body); map other column names with --tracker-columns. The clock offset (joint-log time = tracker time + offset) is estimated from the motion unless given; an ambiguous estimate is refused. Only plateaus where both logs are still for --min-still seconds become rows. Writes OUT.csv (the measurement CSV, in the logs' units) and OUT.pairing.md (offset, confidence, plateaus kept and rejected). See docs/file-formats.md and docs/workflows.md.\n\nExample:\n  treecal pair --joints joint_states.mcap --tracker tracker.csv --tool left_tool --length-unit mm --out measurements.csv"
)]
pub struct PairArgs {
    /// The robot's URDF file [default: the built-in Robonaut].
    #[arg(long)]
    pub robot: Option<PathBuf>,
    /// The joint-state log: CSV, or a ROS 2 bag file (.mcap).
    #[arg(long, value_name = "LOG")]
    pub joints: PathBuf,
    /// The tracker / motion-capture log (CSV).
    #[arg(long, value_name = "LOG.csv")]
    pub tracker: PathBuf,
    /// The tool link the tracked target (or rigid body) is on.
    #[arg(long, value_name = "LINK")]
    pub tool: String,
    /// The measurement CSV to write; the report goes beside it as OUT.pairing.md.
    #[arg(short = 'o', long = "out", alias = "output", value_name = "OUT.csv")]
    pub out: PathBuf,
    /// The time column of a joint-log CSV (seconds).
    #[arg(long, default_value = "time", value_name = "COLUMN")]
    pub joints_time_column: String,
    /// The topic of a bag's JointState messages [default: the only topic that has them].
    #[arg(long, value_name = "TOPIC")]
    pub joint_topic: Option<String>,
    /// The tracker CSV's columns for time, x, y, z (and qw, qx, qy, qz) when named otherwise,
    /// e.g. time=Time,x=TX,y=TY,z=TZ.
    #[arg(long, value_name = "KEY=COLUMN,…")]
    pub tracker_columns: Option<String>,
    /// The tracker's time column counts frames at this rate (Hz) instead of seconds.
    #[arg(long, value_name = "HZ")]
    pub tracker_rate: Option<f64>,
    /// Unit of the tracker's positions [default: its `# units: length=…` comment, else m].
    #[arg(long, value_parser = parse_length_unit)]
    pub length_unit: Option<treecal::io::LengthUnit>,
    /// Unit of revolute joint values in a joint-log CSV [default: its `# units:` comment, else rad].
    #[arg(long, value_parser = parse_angle_unit)]
    pub angle_unit: Option<treecal::io::AngleUnit>,
    /// Unit of prismatic joint values in a joint-log CSV [default: its `# units:` comment, else m].
    #[arg(long, value_parser = parse_length_unit)]
    pub joint_length_unit: Option<treecal::io::LengthUnit>,
    /// A known clock offset (s): joint-log time = tracker time + offset. Skips the estimate.
    #[arg(long, allow_negative_numbers = true, value_name = "S")]
    pub clock_offset: Option<f64>,
    /// Fastest joint still enough for a plateau (deg/s; mm/s for a prismatic joint).
    #[arg(long, default_value_t = 0.5, value_name = "DEG_PER_S")]
    pub still_joint_speed: f64,
    /// Fastest target still enough for a plateau (mm/s).
    #[arg(long, default_value_t = 2.0, value_name = "MM_PER_S")]
    pub still_marker_speed: f64,
    /// Shortest plateau (s), after trimming 0.1 s at each end.
    #[arg(long, default_value_t = 1.0, value_name = "S")]
    pub min_still: f64,
    /// Largest RMS spread of the target's samples in a plateau (mm).
    #[arg(long, default_value_t = 0.5, value_name = "MM")]
    pub max_marker_spread: f64,
    /// Largest standard deviation of a joint in a plateau (deg; mm for a prismatic joint).
    #[arg(long, default_value_t = 0.05, value_name = "DEG")]
    pub max_joint_spread: f64,
}
