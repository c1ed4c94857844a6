//! A lab's humanoid with a head camera (red team, round four): Atlas v5 with its boards on the
//! hands, the camera on `head` (moved by the neck, on no branch of the hands), simulated and
//! calibrated through the command line with the primitive collision shapes.

use crate::common::cli::{assert_success, treecal};
use std::path::PathBuf;

/// A robot of `../shared/robots` (or `$TREECAL_SHARED_DIR/robots`), `None` when absent.
fn shared_robot(relative: &str) -> Option<PathBuf> {
    let relative = format!("robots/{relative}");
    let mut candidates = Vec::new();
    if let Some(dir) = std::env::var_os("TREECAL_SHARED_DIR") {
        candidates.push(PathBuf::from(dir).join(&relative));
    }
    candidates.push(
        PathBuf::from(env!("CARGO_MANIFEST_DIR"))
            .join("../shared")
            .join(&relative),
    );
    candidates.into_iter().find(|c| c.is_file())
}

/// Atlas's primitive shapes overlap by design (the hip boxes, pelvis–l_lglut, at every
/// configuration): `simulate --observation camera` with `--collision-check primitives-only`
/// stopped with "could not find a self-collision-free configuration" (meshes had the rule
/// that drops such pairs, primitives not). Its calibration then holds the head's tool frame
/// (the camera's extrinsics place it): report.md said "6 not determined by these images"
/// under "Every unknown is determined"; it now says they are held, not fitted.
#[test]
fn a_head_camera_on_a_humanoid_simulates_and_calibrates_from_files() {
    let Some(atlas) = shared_robot("atlas_v5/atlas_v5.urdf") else {
        eprintln!("skipped: the shared Atlas URDF is not there");
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let (sim, out) = (dir.path().join("sim"), dir.path().join("out"));
    let run = treecal(&[
        "simulate",
        "--robot",
        atlas.to_str().unwrap(),
        "--tools",
        "l_hand,r_hand",
        "--observation",
        "camera",
        "--camera-link",
        "head",
        "--collision-check",
        "primitives-only",
        "--poses",
        "20",
        "-o",
        sim.to_str().unwrap(),
    ]);
    assert_success(&run, "simulate a head camera on Atlas (primitives-only)");
    assert!(
        run.stderr.contains("pelvis–l_lglut") && run.stderr.contains("overlap by design"),
        "{run}"
    );
    let path = |name: &str| sim.join(name).to_str().unwrap().to_owned();
    let run = treecal(&[
        "calibrate",
        "--robot",
        atlas.to_str().unwrap(),
        "--tools",
        "l_hand,r_hand",
        "--camera",
        &path("cameras.yaml"),
        "--detections",
        &path("detections.csv"),
        "--validation",
        &path("validation_detections.csv"),
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_success(&run, "calibrate the head camera's data");
    let markdown = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(
        markdown.contains("Every unknown is determined by these images."),
        "{markdown}"
    );
    assert!(
        markdown.contains("6 held at their nominal values and not fitted")
            && markdown.contains("of the others, all determined by these images")
            && !markdown.contains("not determined by these images (kept nominal: head"),
        "{markdown}"
    );
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    let held: Vec<&str> = json["robot_parameters"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|p| p["held"] == true)
        .map(|p| p["name"].as_str().unwrap())
        .collect();
    assert_eq!(held.len(), 6, "{held:?}");
    assert!(
        held.iter().all(|name| name.starts_with("head ")),
        "{held:?}"
    );
}
