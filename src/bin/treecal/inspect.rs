//! `treecal inspect`.

use crate::cli::{Format, InspectArgs};
use treecal::report::inspect;
use treecal::{Error, McpcModel, Result};

pub fn run(args: InspectArgs) -> Result<()> {
    let import = crate::robot::load(args.robot.as_deref())?;
    let branches = crate::robot::branches(&import, args.tools.as_deref())?;
    let model = McpcModel::from_tree(&import.tree, &branches)?;
    let report = inspect(&import.tree, &import.warnings, &branches, &model);
    let text = match args.format {
        Format::Text => report.to_text(),
        Format::Yaml => serde_yaml::to_string(&report).map_err(|e| Error::InvalidData {
            origin: "inspect".into(),
            message: e.to_string(),
        })?,
        Format::Json => {
            serde_json::to_string_pretty(&report).map_err(|e| Error::InvalidData {
                origin: "inspect".into(),
                message: e.to_string(),
            })? + "\n"
        }
    };
    print!("{text}");
    Ok(())
}
