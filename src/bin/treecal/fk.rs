//! `treecal fk`.

use crate::cli::{AngleUnit, FkArgs};
use treecal::io::{append_poses, configurations, parse_csv, write_atomically};
use treecal::Result;

pub fn run(args: FkArgs) -> Result<()> {
    if let Some(output) = &args.output {
        crate::checks::refuse_overwrite(output, &[&args.robot, &args.joints])?;
    }
    let import = crate::robot::load(Some(&args.robot))?;
    let tree = &import.tree;
    let tip = tree.link_id(&args.tip)?;
    let origin = args.joints.display().to_string();
    let text = treecal::limits::read_text(&args.joints, treecal::limits::MAX_CSV_BYTES)?;
    let table = parse_csv(&text, &origin)?;
    let scale = match args.angle_unit {
        AngleUnit::Rad => 1.0,
        AngleUnit::Deg => std::f64::consts::PI / 180.0,
    };
    let (configurations, mapping) = configurations(&table, tree, scale, &origin)?;
    for column in &mapping.unmatched {
        eprintln!(
            "treecal: note: column '{}' of {origin} matches no joint of '{}'; passed through unchanged",
            table.headers[*column],
            tree.name()
        );
    }
    for (_, reason) in &mapping.implied {
        eprintln!("treecal: note: {origin}: {reason}; the column is not used");
    }
    let poses = configurations
        .iter()
        .map(|q| tree.link_pose(tip, q))
        .collect::<Result<Vec<_>>>()?;
    let output = append_poses(&table, &poses)?;
    match &args.output {
        Some(path) => write_atomically(path, output.as_bytes()),
        None => {
            print!("{output}");
            Ok(())
        }
    }
}
