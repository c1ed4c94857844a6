//! Arguments of `treecal calibrate` and its choices.

use super::{parse_angle_unit, parse_length_unit, PlanArg, PlanArgParser};
use clap::{Args, ValueEnum};
use std::path::PathBuf;

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
    /// Always on for calibrate (kept for scripts): when a tool link is the child of a revolute
    /// joint and its calibrated origin lies off the joint axis by more than the calibration's
    /// uncertainty (which a URDF joint cannot express), the tool link stays where its joint
    /// puts it and a fixed child link `<tool>_marker` is added at the exact calibrated tool
    /// frame (docs/export.md).
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
    /// Repeat the cross-validation over R fold assignments (seeds --seed, --seed + 1, …) and
    /// average each row's squared held-out errors: the choice no longer rests on one split.
    #[arg(long, value_name = "R", default_value_t = treecal::workflow::REPEATS)]
    pub cv_repeats: usize,
    /// After the cross-validation's choice, offer one more joint's harmonics or backlash at a
    /// time (at most two steps; each costs about one more cross-validation): per-joint errors
    /// such as "harmonics on arm_6" chosen by the same rule (docs/identification.md).
    #[arg(long)]
    pub cv_joint_steps: bool,
    /// Measurement CSV (one row per tool observation); repeatable: several files are read as
    /// one set, each file its own session (one measurement frame each) unless its rows name
    /// their `session`; with --camera or --contacts (one file), tracker rows fitted together
    /// with the pixels or the contacts (mixed data, each with its σ).
    #[arg(long, value_name = "M.csv", required_unless_present_any = ["contacts", "camera"])]
    pub measurements: Vec<PathBuf>,
    /// Contacts CSV (docs/contacts.md, docs/file-formats.md): calibrate from contacts — faces
    /// flush on a plane, points on a plane, touches, a bar — instead of --measurements; with
    /// --contact-setup. --validation then takes held-out contacts; with --camera, the contacts
    /// are fitted with the pixels (--validation: held-out detections). The joint frames are
    /// fitted rigid; of the model flags it takes --model (adaptive: the full geometry, or
    /// chosen by cross-validation among offsets, geometry and geometry with the prior when its
    /// residuals exceed twice the setup's σ's), --prior, --prior-scale, --cv, --cv-repeats,
    /// --freeze and --free; --tools keeps the named setup tools (one side) and their contacts.
    #[arg(
        long,
        value_name = "C.csv",
        requires = "contact_setup",
        conflicts_with_all = [
            "stiffness", "identify_stiffness", "plan", "plan_file", "joint_errors",
            "significant", "cv_joint_steps"
        ]
    )]
    pub contacts: Option<PathBuf>,
    /// The contacts' setup (YAML): reference link, tools with their nominal contact faces and
    /// points, each session's nominal plane, the bar, what is fitted.
    #[arg(long, value_name = "S.yaml", requires = "contacts")]
    pub contact_setup: Option<PathBuf>,
    /// Validation measurements (same format) [default: hold out a seeded fifth]; repeatable
    /// as --measurements (each file its own session); with --contacts, held-out contacts;
    /// with --camera, held-out detections (a detections CSV), predicted but not fitted (one
    /// file).
    #[arg(long, value_name = "V.csv")]
    pub validation: Vec<PathBuf>,
    /// Camera file (cameras and targets, docs/file-formats.md): calibrate from the pixels of
    /// --detections, alone or with the tracker rows of --measurements (docs/camera.md).
    #[arg(
        long,
        value_name = "CAMERAS.yaml",
        requires = "detections",
        conflicts_with_all = [
            "stiffness", "identify_stiffness", "plan", "plan_file",
            "reference_link", "joint_errors", "prior", "significant", "cv", "cv_repeats", "cv_joint_steps", "freeze", "free"
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
