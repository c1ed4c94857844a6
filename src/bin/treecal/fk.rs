//! `treecal fk`: flags → [`FkCsvConfig`] → [`treecal::workflow::fk_csv_stream`] → the pose CSV,
//! streamed row by row (constant memory on any number of rows).

use crate::cli::{AngleUnit, FkArgs};
use treecal::io::write_atomically_with;
use treecal::workflow::{fk_csv_stream, FkCsvConfig, FkStreamSummary, RobotSource};
use treecal::{Error, Result};

pub fn run(args: FkArgs) -> Result<()> {
    let robot = crate::cli::robot_path(&args.robot, &args.robot_file);
    if let Some(output) = &args.output {
        let inputs: Vec<&std::path::Path> = robot
            .iter()
            .chain([&args.joints])
            .map(|p| p.as_path())
            .collect();
        crate::checks::check_outputs(&[crate::checks::Output::File(output)], &inputs)?;
    }
    let config = FkCsvConfig {
        robot: RobotSource::from_path(robot),
        tip: args.tip.clone(),
        joints: args.joints.clone(),
        angle_unit: match args.angle_unit {
            AngleUnit::Rad => treecal::io::AngleUnit::Radian,
            AngleUnit::Deg => treecal::io::AngleUnit::Degree,
        },
    };
    let mut summary = None;
    let mut write = |output: &mut dyn std::io::Write| {
        summary = Some(fk_csv_stream(&config, output)?);
        Ok(())
    };
    let written = match &args.output {
        Some(path) => write_atomically_with(path, &mut write),
        None => {
            let mut buffered = std::io::BufWriter::new(std::io::stdout().lock());
            write(&mut buffered).and_then(|()| {
                std::io::Write::flush(&mut buffered).map_err(|source| Error::Io {
                    path: "standard output".into(),
                    source,
                })
            })
        }
    };
    match written {
        // `treecal fk ... | head`: the reader has what it wanted.
        Err(Error::Io { source, .. }) if source.kind() == std::io::ErrorKind::BrokenPipe => {}
        other => other?,
    }
    if let Some(FkStreamSummary { notes, .. }) = &summary {
        for note in notes {
            crate::output::note(note);
        }
    }
    Ok(())
}
