//! `treecal export`.

use crate::cli::ExportArgs;
use treecal::io::{read_parameters, write_atomically};
use treecal::urdf::{export_urdf_with, ExportOptions};
use treecal::{McpcModel, Result};

pub fn run(args: ExportArgs) -> Result<()> {
    let inputs: Vec<&std::path::Path> = args
        .robot
        .iter()
        .chain([&args.params])
        .map(|p| p.as_path())
        .collect();
    crate::checks::refuse_overwrite(&args.output, &inputs)?;
    let import = crate::robot::load(args.robot.as_deref())?;
    let branches = crate::robot::branches(&import, args.tools.as_deref())?;
    let mut model = McpcModel::from_tree(&import.tree, &branches)?;
    let parameters = read_parameters(&args.params, &import.tree, &model)?;
    // A file for another branch selection misses every parameter: name a few, count the rest.
    const LISTED: usize = 5;
    for warning in parameters.warnings.iter().take(LISTED) {
        eprintln!("treecal: warning: {warning}");
    }
    if parameters.warnings.len() > LISTED {
        eprintln!(
            "treecal: warning: … and {} more parameters not listed keep their nominal values",
            parameters.warnings.len() - LISTED
        );
    }
    model.set_parameters(&parameters.values)?;
    let (original, origin) = crate::robot::original_text(args.robot.as_deref())?;
    let options = ExportOptions::with_uncertainty(
        &import.tree,
        &model,
        &parameters.std_devs,
        args.add_tool_links,
    );
    let report = export_urdf_with(&original, &origin, &import.tree, &model, &options)?;
    for line in crate::robot::export_notes(&report) {
        eprintln!("{line}");
    }
    write_atomically(&args.output, report.urdf.as_bytes())?;
    eprintln!(
        "treecal: wrote {} ({} joint origins changed{})",
        args.output.display(),
        report.changes.len(),
        match report
            .changes
            .iter()
            .filter(|c| c.new_axis.is_some())
            .count()
        {
            0 => String::new(),
            n => format!(", {n} axes"),
        }
    );
    Ok(())
}
