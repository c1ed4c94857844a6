//! `treecal inspect`.

use crate::cli::{Format, InspectArgs};
use treecal::io::{to_json, to_yaml};
use treecal::report::inspect;
use treecal::{McpcModel, Result};

pub fn run(args: InspectArgs) -> Result<()> {
    let import = crate::robot::load(args.robot.as_deref())?;
    let branches = crate::robot::branches(&import, args.tools.as_deref())?;
    let model = McpcModel::from_tree(&import.tree, &branches)?;
    let report = inspect(&import.tree, &import.warnings, &branches, &model);
    let text = match args.format {
        Format::Text => report.to_text(),
        Format::Yaml => to_yaml(&report)?,
        Format::Json => to_json(&report)?,
    };
    print!("{text}");
    Ok(())
}
