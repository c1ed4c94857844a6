//! `treecal export`: flags → [`ExportConfig`] → [`treecal::workflow::export`] → the URDF.

use crate::cli::ExportArgs;
use treecal::workflow::{export, ExportConfig, RobotSource};
use treecal::Result;

pub fn run(args: ExportArgs) -> Result<()> {
    let inputs: Vec<&std::path::Path> = args
        .robot
        .iter()
        .chain([&args.params])
        .map(|p| p.as_path())
        .collect();
    crate::checks::check_outputs(&[crate::checks::Output::File(&args.output)], &inputs)?;
    let exported = export(&ExportConfig {
        robot: RobotSource::from_path(args.robot.clone()),
        parameters: args.params.clone(),
        tools: args.tools.clone(),
        reference_link: args.reference_link.clone(),
        add_tool_links: args.add_tool_links,
    })?;
    for note in &exported.notes {
        crate::output::note(note);
    }
    exported.write(&args.output)?;
    crate::output::note(format_args!(
        "wrote {} ({})",
        args.output.display(),
        exported.summary()
    ));
    Ok(())
}
