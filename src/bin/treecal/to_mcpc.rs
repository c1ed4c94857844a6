//! `treecal to-mcpc`: flags → [`ModelConfig`] → [`treecal::workflow::to_mcpc`] → the YAML.

use crate::cli::ToMcpcArgs;
use treecal::io::write_atomically;
use treecal::workflow::{to_mcpc, ModelConfig, RobotSource};
use treecal::Result;

pub fn run(args: ToMcpcArgs) -> Result<()> {
    let robot = crate::cli::robot_path(&args.robot, &args.robot_file);
    if let Some(output) = &args.output {
        let inputs: Vec<&std::path::Path> = robot.iter().map(|p| p.as_path()).collect();
        crate::checks::check_outputs(&[crate::checks::Output::File(output)], &inputs)?;
    }
    let table = to_mcpc(&ModelConfig {
        robot: RobotSource::from_path(robot),
        tools: args.tools.clone(),
        // An MCPC table is rooted at the URDF root.
        reference_link: None,
    })?;
    for note in &table.notes {
        crate::output::note(note);
    }
    match &args.output {
        Some(path) => {
            write_atomically(path, table.yaml.as_bytes())?;
            crate::output::note(format_args!("wrote {}", path.display()));
            Ok(())
        }
        None => {
            crate::output::print(&table.yaml)?;
            Ok(())
        }
    }
}
