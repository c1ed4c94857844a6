//! `treecal fk`: flags → [`FkCsvConfig`] → [`treecal::workflow::fk_csv`] → the pose CSV.

use crate::cli::{AngleUnit, FkArgs};
use treecal::io::write_atomically;
use treecal::workflow::{fk_csv, FkCsvConfig, RobotSource};
use treecal::Result;

pub fn run(args: FkArgs) -> Result<()> {
    let robot = crate::cli::robot_path(&args.robot, &args.robot_file);
    if let Some(output) = &args.output {
        let inputs: Vec<&std::path::Path> = robot
            .iter()
            .chain([&args.joints])
            .map(|p| p.as_path())
            .collect();
        crate::checks::check_outputs(&[crate::checks::Output::File(output)], &inputs)?;
    }
    let table = fk_csv(&FkCsvConfig {
        robot: RobotSource::from_path(robot),
        tip: args.tip.clone(),
        joints: args.joints.clone(),
        angle_unit: match args.angle_unit {
            AngleUnit::Rad => treecal::io::AngleUnit::Radian,
            AngleUnit::Deg => treecal::io::AngleUnit::Degree,
        },
    })?;
    for note in &table.notes {
        crate::output::note(note);
    }
    match &args.output {
        Some(path) => write_atomically(path, table.csv.as_bytes()),
        None => {
            crate::output::print(&table.csv)?;
            Ok(())
        }
    }
}
