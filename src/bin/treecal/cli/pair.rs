//! Arguments of `treecal pair`.

use super::{parse_angle_unit, parse_length_unit};
use clap::Args;
use std::path::PathBuf;

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
