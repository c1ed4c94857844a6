//! `treecal from-mcpc`.

use crate::cli::FromMcpcArgs;
use treecal::io::{read_mcpc_table, write_atomically};
use treecal::{urdf_from_mcpc_table, Result};

pub fn run(args: FromMcpcArgs) -> Result<()> {
    crate::checks::refuse_overwrite(&args.output, &[&args.table])?;
    let table = read_mcpc_table(&args.table)?;
    // Name the source by its file name only, so the output does not depend on where it ran.
    let source = args
        .table
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| args.table.display().to_string());
    let urdf = urdf_from_mcpc_table(&table, &source);
    // Check the result loads before writing it.
    treecal::parse_urdf(&urdf, "generated URDF")?;
    write_atomically(&args.output, urdf.as_bytes())?;
    eprintln!("treecal: wrote {}", args.output.display());
    Ok(())
}
