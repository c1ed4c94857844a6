//! `treecal inspect`: flags → [`ModelConfig`] → [`treecal::workflow::inspect`] → the report.

use crate::cli::{Format, InspectArgs};
use treecal::io::{to_json, to_yaml};
use treecal::workflow::{inspect, ModelConfig, RobotSource};
use treecal::Result;

pub fn run(args: InspectArgs) -> Result<()> {
    let inspection = inspect(&ModelConfig {
        robot: RobotSource::from_path(crate::cli::robot_path(&args.robot, &args.robot_file)),
        tools: args.tools.clone(),
        reference_link: args.reference_link.clone(),
    })?;
    for note in &inspection.notes {
        crate::output::note(note);
    }
    let report = &inspection.report;
    let text = match args.format {
        Format::Text => report.to_text(),
        Format::Yaml => to_yaml(report)?,
        Format::Json => to_json(report)?,
    };
    crate::output::print(&text)?;
    Ok(())
}
