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
    let mut comparison = compare(&config)?;
    // report.md and report.html say the flags, as stdout does.
    let flag = |setting: &str| crate::settings::flag(setting).map(str::to_owned);
    treecal::workflow::spell_reports(&mut comparison.files, &flag);
    comparison.write(&args.out)?;
    crate::output::print(&comparison.markdown)?;
    crate::output::note(format_args!("wrote {}", args.out.display()));
    Ok(())
}
