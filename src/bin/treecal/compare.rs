//! `treecal compare`: two calibrate output folders → [`treecal::workflow::compare`] →
//! report.md on stdout, the files in `--out`.

use crate::cli_trust::CompareArgs;
use treecal::workflow::{compare, CompareConfig};
use treecal::Result;

pub fn run(args: CompareArgs) -> Result<()> {
    let config = CompareConfig {
        a: args.a,
        b: args.b,
        k: args.k,
    };
    let comparison = compare(&config)?;
    comparison.write(&args.out)?;
    crate::output::print(&comparison.markdown)?;
    crate::output::note(format_args!("wrote {}", args.out.display()));
    Ok(())
}
