//! `treecal from-mcpc`: the table → [`treecal::workflow::from_mcpc`] → the URDF.

use crate::cli::FromMcpcArgs;
use treecal::io::write_atomically;
use treecal::Result;

pub fn run(args: FromMcpcArgs) -> Result<()> {
    crate::checks::check_outputs(&[crate::checks::Output::File(&args.output)], &[&args.table])?;
    let urdf = treecal::workflow::from_mcpc(&args.table)?;
    write_atomically(&args.output, urdf.as_bytes())?;
    crate::output::note(format_args!("wrote {}", args.output.display()));
    Ok(())
}
