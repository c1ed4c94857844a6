//! `treecal to-mcpc`: flags → [`ModelConfig`] → [`treecal::workflow::to_mcpc`] → the YAML.

use crate::cli::ToMcpcArgs;
use treecal::io::write_atomically;
use treecal::workflow::{to_mcpc, ModelConfig, RobotSource};
use treecal::Result;

pub fn run(args: ToMcpcArgs) -> Result<()> {
    let robot = crate::cli::robot_path(&args.robot, &args.robot_file);
    if let (Some(output), Some(robot)) = (&args.output, &robot) {
        crate::checks::refuse_overwrite(output, &[robot])?;
    }
    let table = to_mcpc(&ModelConfig {
        robot: RobotSource::from_path(robot),
        tools: args.tools.clone(),
    })?;
    for note in &table.notes {
        eprintln!("treecal: {note}");
    }
    match &args.output {
        Some(path) => {
            write_atomically(path, table.yaml.as_bytes())?;
            eprintln!("treecal: wrote {}", path.display());
            Ok(())
        }
        None => {
            print!("{}", table.yaml);
            Ok(())
        }
    }
}
