//! `treecal to-mcpc`.

use crate::cli::ToMcpcArgs;
use treecal::io::{mcpc_table_to_yaml, write_atomically};
use treecal::{McpcModel, McpcTable, Result};

pub fn run(args: ToMcpcArgs) -> Result<()> {
    if let (Some(output), Some(robot)) = (&args.output, &args.robot) {
        crate::checks::refuse_overwrite(output, &[robot])?;
    }
    let import = crate::robot::load(args.robot.as_deref())?;
    let branches = crate::robot::branches(&import, args.tools.as_deref())?;
    let model = McpcModel::from_tree(&import.tree, &branches)?;
    let table = McpcTable::from_model(&import.tree, &branches, &model)?;
    let source = args
        .robot
        .as_ref()
        .and_then(|p| p.file_name())
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "the built-in robonaut.urdf".into());
    let header = [
        format!("MCPC table of {source}, written by treecal to-mcpc (degrees, millimetres)."),
        "Rows: prev_from_frame = Q(prev) * Rz(phi) * Rx(alpha) * Ry(beta) * Trans(x, y, 0); phi is a constant, see docs/mcpc.md.".to_owned(),
    ];
    let text = mcpc_table_to_yaml(&table, &header);
    match &args.output {
        Some(path) => {
            write_atomically(path, text.as_bytes())?;
            eprintln!("treecal: wrote {}", path.display());
            Ok(())
        }
        None => {
            print!("{text}");
            Ok(())
        }
    }
}
