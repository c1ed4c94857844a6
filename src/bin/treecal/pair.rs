//! `treecal pair`: flags → [`PairConfig`] → [`treecal::workflow::pair`] → the CSV and report.

use crate::cli::PairArgs;
use treecal::pairing::PlateauOptions;
use treecal::workflow::report_path;
use treecal::workflow::{pair, PairConfig, RobotSource};
use treecal::Result;

pub fn run(args: PairArgs) -> Result<()> {
    let report = report_path(&args.out);
    let inputs: Vec<&std::path::Path> = args
        .robot
        .iter()
        .chain([&args.joints, &args.tracker])
        .map(|p| p.as_path())
        .collect();
    use crate::checks::{check_outputs, Output};
    check_outputs(&[Output::File(&args.out), Output::File(&report)], &inputs)?;
    let degree = std::f64::consts::PI / 180.0;
    let mut config = PairConfig {
        robot: RobotSource::from_path(args.robot.clone()),
        tool: args.tool.clone(),
        joints: args.joints.clone(),
        tracker: args.tracker.clone(),
        clock_offset: args.clock_offset,
        plateaus: PlateauOptions {
            joint_speed: args.still_joint_speed * degree,
            prismatic_speed: args.still_joint_speed * 1e-3,
            marker_speed: args.still_marker_speed * 1e-3,
            min_duration: args.min_still,
            max_marker_spread: args.max_marker_spread * 1e-3,
            max_joint_spread: args.max_joint_spread * degree,
            max_prismatic_spread: args.max_joint_spread * 1e-3,
            ..PlateauOptions::default()
        },
        ..PairConfig::default()
    };
    config.joint_log.time_column = args.joints_time_column.clone();
    config.joint_log.topic = args.joint_topic.clone();
    config.joint_log.angle_unit = args.angle_unit;
    config.joint_log.joint_length_unit = args.joint_length_unit;
    if let Some(columns) = &args.tracker_columns {
        config.tracker_log.columns = columns.parse()?;
    }
    config.tracker_log.rate = args.tracker_rate;
    config.tracker_log.length_unit = args.length_unit;
    let pairing = pair(&config)?;
    for note in &pairing.notes {
        crate::output::note(note);
    }
    pairing.write(&args.out, &report)?;
    crate::output::note(format_args!(
        "paired {} plateaus ({} rejected) with clock offset {:+.4} s; wrote {} and {}",
        pairing.kept(),
        pairing.plateaus.len() - pairing.kept(),
        pairing.offset,
        args.out.display(),
        report.display()
    ));
    Ok(())
}
