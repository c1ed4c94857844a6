//! `treecal from-mcpc`: the table → [`treecal::workflow::from_mcpc`] → the URDF.

use crate::cli::FromMcpcArgs;
use treecal::io::write_atomically;
use treecal::Result;

pub fn run(args: FromMcpcArgs) -> Result<()> {
    crate::checks::refuse_overwrite(&args.output, &[&args.table])?;
    let urdf = treecal::workflow::from_mcpc(&args.table)?;
    write_atomically(&args.output, urdf.as_bytes())?;
    eprintln!("treecal: wrote {}", args.output.display());
    Ok(())
}
