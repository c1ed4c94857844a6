//! Calibrating again from an exported URDF: the flexibility model follows the geometry being
//! calibrated, so the exported robot bends exactly as the calibrated model did.

use crate::common::cli::{assert_success, path_str, treecal};
use crate::common::{random_configuration, rng, robot, TestRobot};
use rand::RngExt;
use serde_json::Value;
use treecal::kinematics::{FlexibilityModel, Stiffness};
use treecal::tree::KinematicTree;
use treecal::urdf::export_urdf;
use treecal::McpcModel;

/// Every MCPC parameter perturbed by ±0.03 (rad, m), exported, re-imported: the re-imported
/// nominal model with a flexibility model built from it predicts the same deflected tool poses
/// as the perturbed model with the original flexibility model (to 1e-9). The tool links carry
/// masses (Robonaut's 0.2 kg tools), which the export moves with the calibrated tool frames. (A
/// tool link with child links, like the humanoid's hands with their fingers, is not moved by the
/// export: its measured frame goes into a marker link, docs/export.md.)
#[test]
fn exported_robot_bends_as_the_calibrated_model() {
    for (file, stiffness_file) in [("robonaut/robonaut.urdf", Some("robonaut/stiffness.yaml"))] {
        let text = std::fs::read_to_string(robot(file)).unwrap();
        let (tree, nominal) = TestRobot::parse(&text).tree_and_model();
        let stiffness = |tree: &KinematicTree, model: &McpcModel| match stiffness_file {
            Some(path) => treecal::io::read_stiffness(&robot(path), tree, model).unwrap(),
            None => Stiffness::default(),
        };
        let flexibility =
            FlexibilityModel::new(&tree, &nominal, &stiffness(&tree, &nominal)).unwrap();
        let mut random = rng(3);
        let mut model = nominal.clone();
        let mut values = model.parameters();
        for v in values.iter_mut() {
            *v += random.random_range(-0.03..0.03);
        }
        model.set_parameters(&values).unwrap();
        let exported = export_urdf(&text, file, &tree, &model).unwrap().urdf;
        let (tree2, nominal2) = TestRobot::parse(&exported).tree_and_model();
        let flexibility2 =
            FlexibilityModel::new(&tree2, &nominal2, &stiffness(&tree2, &nominal2)).unwrap();
        let mut worst: f64 = 0.0;
        for _ in 0..20 {
            let q = random_configuration(&tree, &mut random);
            let a = flexibility.deflected_tool_poses(&tree, &model, &q).unwrap();
            let b = flexibility2
                .deflected_tool_poses(&tree2, &nominal2, &q)
                .unwrap();
            let da = flexibility.tool_deflections(&tree, &model, &q).unwrap();
            let db = flexibility2
                .tool_deflections(&tree2, &nominal2, &q)
                .unwrap();
            for (x, y) in a.iter().zip(&b) {
                let (p, r) = crate::common::pose_difference(x, y);
                worst = worst.max(p).max(r);
            }
            for (x, y) in da.iter().zip(&db) {
                worst = worst.max((x - y).amax());
            }
        }
        eprintln!("{file}: largest difference {worst:.2e}");
        assert!(
            worst < 1e-9,
            "{file}: the exported robot bends differently ({worst:.2e})"
        );
    }
}

fn stage_costs(report: &Value) -> Vec<f64> {
    report["stages"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s["cost"].as_f64().unwrap())
        .collect()
}

fn validation_mean_mm(report: &Value) -> Vec<f64> {
    report["validation"]
        .as_array()
        .unwrap()
        .iter()
        .map(|a| a["after"]["mean_position_mm"].as_f64().unwrap())
        .collect()
}

/// simulate → calibrate (with the stiffness file) → calibrated.urdf → calibrate again from it on
/// the same data: the same stage costs and validation errors (the second run starts at the
/// solution and stays there).
#[test]
fn calibrating_again_from_the_export_reproduces_the_fit() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("m.csv");
    let run = treecal(&[
        "simulate",
        "--trials",
        "1",
        "--write-measurements",
        path_str(&csv),
        "--out",
        path_str(&dir.path().join("simulate")),
    ]);
    assert_success(&run, "simulate");
    let stiffness = robot("robonaut/stiffness.yaml");
    let calibrate = |out: &std::path::Path, urdf: Option<&std::path::Path>| -> Value {
        let mut args = vec![
            "calibrate",
            "--measurements",
            path_str(&csv),
            "--stiffness",
            path_str(&stiffness),
            "--measurement-frame",
            "base",
            "--out",
            path_str(out),
        ];
        if let Some(urdf) = urdf {
            args.extend(["--robot", path_str(urdf)]);
        }
        let run = treecal(&args);
        assert_success(&run, "calibrate");
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap()
    };
    let first_out = dir.path().join("first");
    let first = calibrate(&first_out, None);
    let second = calibrate(
        &dir.path().join("second"),
        Some(&first_out.join("calibrated.urdf")),
    );
    let (a, b) = (stage_costs(&first), stage_costs(&second));
    let (va, vb) = (validation_mean_mm(&first), validation_mean_mm(&second));
    eprintln!("costs {a:?} → {b:?}; validation {va:?} → {vb:?} mm");
    for (x, y) in a.iter().zip(&b) {
        assert!((x - y).abs() <= 1e-4 * x, "stage cost {x} → {y}");
    }
    for (x, y) in va.iter().zip(&vb) {
        assert!((x - y).abs() <= 1e-4, "validation mean {x} → {y} mm");
    }
}
