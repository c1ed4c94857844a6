//! `treecal`: calibrate the kinematic parameters of branched robots described by URDF.
//!
//! A thin layer over the library: clap parses, `cli` turns raw arguments into checked
//! library inputs, one file per subcommand runs it.

mod calibrate;
mod check;
mod checks;
mod cli;
mod cli_trust;
mod compare;
mod export;
mod fk;
mod from_mcpc;
mod inspect;
mod output;
mod pair;
mod plan;
mod progress;
mod settings;
mod simulate;
mod to_mcpc;
mod verify;

use clap::Parser;
use std::process::ExitCode;

fn main() -> ExitCode {
    // `-` is not standard input or output here: say so before clap or a file open would.
    if let Err(error) = checks::no_standard_streams(std::env::args_os()) {
        output::note(format_args!("error: {error}"));
        return ExitCode::FAILURE;
    }
    let args = cli::Cli::parse();
    let result = match args.command {
        cli::Command::Inspect(a) => inspect::run(a),
        cli::Command::Fk(a) => fk::run(a),
        cli::Command::FromMcpc(a) => from_mcpc::run(a),
        cli::Command::ToMcpc(a) => to_mcpc::run(a),
        cli::Command::Simulate(a) => simulate::run(a),
        cli::Command::Calibrate(a) => calibrate::run(a),
        cli::Command::Export(a) => export::run(a),
        cli::Command::Check(a) => check::run(a),
        cli::Command::Plan(a) => plan::run(a),
        cli::Command::Pair(a) => pair::run(a),
        cli::Command::Verify(a) => verify::run(a),
        cli::Command::Compare(a) => compare::run(a),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => {
            output::note(format_args!("error: {error}"));
            ExitCode::FAILURE
        }
    }
}
