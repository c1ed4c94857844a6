//! Arguments of `treecal plan` and `treecal check` (pose sets and their identifiability).

use super::{
    parse_length_unit, AngleUnit, CollisionCheckChoice, CriterionChoice, Format, PlanChoice,
    StageChoice,
};
use clap::Args;
use std::path::PathBuf;

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
    /// Contact setup (YAML, docs/contacts.md): choose feasible contact configurations of
    /// the nominal robot (--observation kinds) whose contact rows are most informative and
    /// write them as a contacts CSV for `calibrate --contacts`; --tools then names the setup's
    /// tools, --candidates counts feasible contacts (a few hundred suffice).
    #[arg(
        long,
        value_name = "S.yaml",
        requires = "observation",
        conflicts_with_all = ["camera", "stage", "workspace", "noise", "targets"]
    )]
    pub contact_setup: Option<PathBuf>,
    /// Contact kinds to plan, with --contact-setup: flush, plane, touch, bar (comma-separated).
    #[arg(
        long,
        value_delimiter = ',',
        value_name = "KIND,KIND",
        requires = "contact_setup"
    )]
    pub observation: Option<Vec<String>>,
    /// The CSV to write (atomically).
    #[arg(short = 'o', long = "out", alias = "output", value_name = "OUT.csv")]
    pub out: PathBuf,
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
    /// Measurement CSV (docs/file-formats.md): its configurations, tools and stages are analysed;
    /// repeatable (several files are one set, as for calibrate).
    #[arg(long, value_name = "M.csv")]
    pub measurements: Vec<PathBuf>,
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
    /// Contacts CSV (docs/contacts.md): say what these contacts leave undetermined, in words
    /// as the contact calibration's report does; with --contact-setup.
    #[arg(
        long,
        value_name = "C.csv",
        requires = "contact_setup",
        conflicts_with = "camera"
    )]
    pub contacts: Option<PathBuf>,
    /// The contacts' setup (YAML), with --contacts.
    #[arg(long, value_name = "S.yaml", requires = "contacts")]
    pub contact_setup: Option<PathBuf>,
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
