//! Checks shared by the subcommands: the library's (`treecal::workflow::checks`), and the
//! refusal of `-` as a file.

pub use treecal::workflow::{check_outputs, Output};
use treecal::{Error, Result};

/// Refuses `-` (standard input or output, by convention) as any argument's value: treecal
/// reads and writes files only — it names and hashes every input in provenance.yaml, bounds
/// each file's size before reading, and replaces output folders as a whole — so `-` would
/// otherwise be a file named `-` in the working directory, and a missing-file error that does
/// not say why. `args` as the process got them (the program's name first).
pub fn no_standard_streams(args: impl IntoIterator<Item = std::ffi::OsString>) -> Result<()> {
    let args: Vec<String> = args
        .into_iter()
        .map(|a| a.to_string_lossy().into_owned())
        .collect();
    for (i, arg) in args.iter().enumerate().skip(1) {
        let flag = match arg.split_once('=') {
            Some((flag, "-")) if flag.starts_with("--") => Some(flag),
            _ if arg == "-" => args[i - 1].strip_prefix("--").map(|_| args[i - 1].as_str()),
            _ => continue,
        };
        let message = "'-' (standard input or output) is not supported: treecal reads and \
                       writes files only (it names and hashes its inputs in provenance.yaml and \
                       bounds their size); save the stream to a file first (`… > m.csv`) and \
                       give its path (a file really named '-': `./-`)";
        return Err(match flag.and_then(|f| f.strip_prefix("--")) {
            Some(flag) if !flag.is_empty() => Error::setting(&flag.replace('-', "_"), message),
            _ => Error::InvalidData {
                origin: "the command line".into(),
                message: message.into(),
            },
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn check(args: &[&str]) -> Result<()> {
        no_standard_streams(args.iter().map(std::ffi::OsString::from))
    }

    #[test]
    fn a_dash_is_refused_with_its_flag() {
        assert!(check(&["treecal", "calibrate", "--measurements", "m.csv"]).is_ok());
        assert!(check(&["treecal", "fk", "--joints", "./-", "--clock-offset", "-0.5"]).is_ok());
        for args in [
            &["treecal", "calibrate", "--measurements", "-"][..],
            &["treecal", "calibrate", "--measurements=-"][..],
        ] {
            let error = check(args).unwrap_err().to_string();
            assert!(
                error
                    .starts_with("`measurements`: '-' (standard input or output) is not supported"),
                "{error}"
            );
        }
        let error = check(&["treecal", "inspect", "-"]).unwrap_err().to_string();
        assert!(error.contains("the command line"), "{error}");
    }
}
