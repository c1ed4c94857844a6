//! One entry point per loader, from bytes: what each fuzz target in `fuzz/` runs, and what
//! `tests/hardening.rs` replays on the inputs under `tests/data/fuzz/<target>/`. An entry
//! must never panic, hang or abort, whatever the bytes; errors are fine.

use std::sync::OnceLock;
use treecal::io::{
    configurations, mcpc_table_to_yaml, mesh_vertices, parse_csv, parse_mcpc_table,
    parse_measurements, parse_parameters, parse_plan, parse_registration, parse_stiffness,
    pose_rows, AngleUnit, LengthUnit, MeasurementReadOptions,
};
use treecal::kinematics::FlexibilityModel;
use treecal::{
    detect_branches, export_urdf, parse_urdf, urdf_from_mcpc_table, KinematicTree, McpcModel,
    McpcTable,
};

const ROBONAUT_URDF: &str = include_str!("../../robots/robonaut/robonaut.urdf");

/// The fuzz targets, by name (the folder names under `fuzz/fuzz_targets` and
/// `tests/data/fuzz`).
pub const TARGETS: [&str; 12] = [
    "urdf",
    "measurements_csv",
    "joints_csv",
    "mcpc_table",
    "stiffness",
    "params",
    "plan",
    "stl",
    "obj",
    "collada",
    "registration",
    "export",
];

/// Runs the entry of target `name` on `data`.
pub fn run(name: &str, data: &[u8]) {
    match name {
        "urdf" => urdf(data),
        "measurements_csv" => measurements_csv(data),
        "joints_csv" => joints_csv(data),
        "mcpc_table" => mcpc_table(data),
        "stiffness" => stiffness(data),
        "params" => params(data),
        "plan" => plan(data),
        "stl" => mesh(data, "fuzz.stl"),
        "obj" => mesh(data, "fuzz.obj"),
        "collada" => mesh(data, "fuzz.dae"),
        "registration" => registration(data),
        "export" => export(data),
        other => panic!("no fuzz target '{other}'"),
    }
}

/// The built-in Robonaut the data files are read against.
fn robonaut() -> &'static (KinematicTree, McpcModel) {
    static ROBOT: OnceLock<(KinematicTree, McpcModel)> = OnceLock::new();
    ROBOT.get_or_init(|| {
        let tree = parse_urdf(ROBONAUT_URDF, "robonaut.urdf")
            .expect("robonaut loads")
            .tree;
        let branches = detect_branches(&tree, None).expect("robonaut has branches");
        let model = McpcModel::from_tree(&tree, &branches).expect("robonaut has a model");
        (tree, model)
    })
}

fn text(data: &[u8]) -> Option<&str> {
    std::str::from_utf8(data).ok()
}

/// A URDF, then what `inspect` and `to-mcpc` do with it, then reading the table back.
pub fn urdf(data: &[u8]) {
    let Some(text) = text(data) else { return };
    let Ok(import) = parse_urdf(text, "fuzz.urdf") else {
        return;
    };
    let tree = &import.tree;
    let Ok(branches) = detect_branches(tree, None) else {
        return;
    };
    let Ok(model) = McpcModel::from_tree(tree, &branches) else {
        return;
    };
    let _ = tree.link_pose(model.tools()[0].link, &tree.zero_configuration());
    let Ok(table) = McpcTable::from_model(tree, &branches, &model) else {
        return;
    };
    let yaml = mcpc_table_to_yaml(&table, &["fuzz".into()]);
    let _ = parse_mcpc_table(&yaml, "fuzz.yaml");
}

/// A measurement CSV for the Robonaut; the first byte picks the units.
pub fn measurements_csv(data: &[u8]) {
    let Some((&first, rest)) = data.split_first() else {
        return;
    };
    let Some(text) = text(rest) else { return };
    let (tree, model) = robonaut();
    let options = MeasurementReadOptions {
        length_unit: Some(if first & 1 == 0 {
            LengthUnit::Metre
        } else {
            LengthUnit::Millimetre
        }),
        angle_unit: Some(if first & 2 == 0 {
            AngleUnit::Radian
        } else {
            AngleUnit::Degree
        }),
        joint_length_unit: None,
        ignore_columns: vec!["time".into()],
        strict_limits: first & 4 != 0,
    };
    let _ = parse_measurements(text, "fuzz.csv", tree, model, &options);
}

/// A joint CSV (`fk`) and a pose-set CSV (`check --poses`) for the Robonaut.
pub fn joints_csv(data: &[u8]) {
    let Some(text) = text(data) else { return };
    let Ok(table) = parse_csv(text, "fuzz.csv") else {
        return;
    };
    let (tree, model) = robonaut();
    if let Ok((qs, _)) = configurations(&table, tree, std::f64::consts::PI / 180.0, "fuzz.csv") {
        for q in qs.iter().take(100) {
            let _ = tree.link_pose(model.tools()[0].link, q);
        }
    }
    let _ = pose_rows(&table, tree, model, 1.0, "fuzz.csv");
}

/// An MCPC table, then the URDF `from-mcpc` makes of it, read back.
pub fn mcpc_table(data: &[u8]) {
    let Some(text) = text(data) else { return };
    let Ok(table) = parse_mcpc_table(text, "fuzz.yaml") else {
        return;
    };
    let urdf = urdf_from_mcpc_table(&table, "fuzz.yaml");
    let _ = parse_urdf(&urdf, "generated.urdf");
}

/// A stiffness file for the Robonaut, then the flexibility model built from it.
pub fn stiffness(data: &[u8]) {
    let Some(text) = text(data) else { return };
    let (tree, model) = robonaut();
    if let Ok(stiffness) = parse_stiffness(text, "fuzz.yaml", tree, model) {
        let _ = FlexibilityModel::new(tree, model, &stiffness);
    }
}

/// A parameter file for the Robonaut, then the model with those values.
pub fn params(data: &[u8]) {
    let Some(text) = text(data) else { return };
    let (tree, model) = robonaut();
    if let Ok(values) = parse_parameters(text, "fuzz.yaml", tree, model) {
        let _ = model.clone().set_parameters(&values.values);
    }
}

/// A calibration plan file.
pub fn plan(data: &[u8]) {
    let Some(text) = text(data) else { return };
    let _ = parse_plan(text, "fuzz.yaml");
}

/// A collision mesh file (`name`'s extension picks STL, OBJ or COLLADA), as `plan` and
/// `simulate` read it.
pub fn mesh(data: &[u8], name: &str) {
    let _ = mesh_vertices(data, std::path::Path::new(name));
}

/// A registration file (`calibrate --measurement-frame FILE`).
pub fn registration(data: &[u8]) {
    let Some(text) = text(data) else { return };
    let _ = parse_registration(text, "fuzz.yaml");
}

/// The output writer: a parameter file for the Robonaut, the calibrated URDF `export` writes
/// from it, and that URDF read back.
pub fn export(data: &[u8]) {
    let Some(text) = text(data) else { return };
    let (tree, model) = robonaut();
    let Ok(values) = parse_parameters(text, "fuzz.yaml", tree, model) else {
        return;
    };
    let mut calibrated = model.clone();
    if calibrated.set_parameters(&values.values).is_err() {
        return;
    }
    if let Ok(report) = export_urdf(ROBONAUT_URDF, "robonaut.urdf", tree, &calibrated) {
        let _ = parse_urdf(&report.urdf, "exported.urdf");
    }
}
