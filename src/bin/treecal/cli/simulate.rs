//! Arguments of `treecal simulate` and its choices.

use super::RobustChoice;
use clap::{Args, ValueEnum};
use std::path::PathBuf;

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

/// How `simulate --write-measurements` writes the CSV.
#[derive(Clone, Copy, ValueEnum)]
pub enum MeasurementFormat {
    /// Poses (or positions), metres and radians.
    Si,
    /// Three targets per tool, millimetres and degrees.
    Tracker,
}
