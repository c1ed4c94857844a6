//! `plan --camera`: every planned configuration shows the cameras whole boards (each corner in
//! the image and in front, the board facing the camera, no line of sight through another
//! link's collision shape), and the planned set is more informative than random feasible ones.

use crate::common::cli::{assert_success, treecal};
use crate::common::simulated_robonaut;
use treecal::calibration::Criterion;
use treecal::camera::predict_pixels;
use treecal::sim::{camera_rig, CameraRigOptions};
use treecal::sim::{plan_camera_poses, CameraPlanningOptions};
use treecal::sim::{rigid_group, Sight, VisibilityRules};

#[test]
fn planned_camera_configurations_are_visible_and_beat_random_ones() {
    let robot = simulated_robonaut();
    let (rig, model) = camera_rig(
        &robot.tree,
        &robot.branches,
        &robot.nominal,
        Some(&robot.checker),
        &CameraRigOptions::default(),
        7,
    )
    .unwrap();
    let rules = VisibilityRules::default();
    let sight = Sight {
        rig: &rig,
        model: &model,
        tree: &robot.tree,
        checker: Some(&robot.checker),
        rules: &rules,
    };
    let options = CameraPlanningOptions {
        poses: 12,
        candidates: 80,
        criterion: Criterion::O1,
        pixel_sigma: 0.5,
        seed: 3,
    };
    let report = plan_camera_poses(&sight, Some(&robot.checker), &options, &|_| {}).unwrap();
    assert_eq!(report.poses.len(), 12);
    // Most random configurations show no board: the checks do reject.
    assert!(report.hidden > 0, "{} draws, none hidden", report.draws);
    for (q, views) in &report.poses {
        assert!(!views.is_empty());
        assert!(!robot
            .checker
            .in_collision(&robot.tree.link_poses(q).unwrap()));
        let tools = model.tool_poses(q);
        let links = robot.tree.link_poses(q).unwrap();
        for view in views {
            let camera = &rig.cameras[view.camera];
            let target = &rig.targets[view.target];
            assert_eq!(
                view.points.len(),
                target.shape.point_count(),
                "a whole board"
            );
            // In the image and in front, with the image bounds checked.
            let pixels = predict_pixels(&rig, view, &tools, &camera.intrinsics, true);
            assert!(pixels.iter().all(Result::is_ok), "{pixels:?}");
            // Facing the camera within 60°.
            let eye = tools[camera.tool].translation.vector;
            let board = tools[target.tool] * target.tool_from_target;
            let to_camera = (eye - board.translation.vector).normalize();
            let normal = board.rotation * -nalgebra::Vector3::z();
            assert!(normal.dot(&to_camera) >= 60f64.to_radians().cos() - 1e-12);
            // No line of sight through another link.
            let carrier = model.tools()[target.tool].link;
            let mut ignore = rigid_group(&robot.tree, model.tools()[camera.tool].link);
            if target.tool < rig.robot_tools {
                ignore.extend(rigid_group(&robot.tree, carrier));
            }
            for k in 0..target.shape.point_count() {
                let corner = board * nalgebra::Point3::from(target.shape.point(k).unwrap());
                let blocked =
                    robot
                        .checker
                        .segment_blocked(&links, &eye, &corner.coords, &ignore, 0.005);
                assert_eq!(blocked, None, "corner {k} hidden");
            }
            assert!(sight.check(q, view.camera, view.target).unwrap().is_ok());
        }
    }
    assert!(
        report.planned_value > 1.2 * report.random_value,
        "planned O1 {} vs random {}",
        report.planned_value,
        report.random_value
    );
}

#[test]
fn plan_with_a_camera_file_writes_the_configurations() {
    let dir = tempfile::tempdir().unwrap();
    let sim = dir.path().join("sim");
    assert_success(
        &treecal(&[
            "simulate",
            "--observation",
            "camera",
            "--trials",
            "1",
            "--poses",
            "10",
            "-o",
            sim.to_str().unwrap(),
        ]),
        "simulate",
    );
    let out = dir.path().join("plan.csv");
    let run = treecal(&[
        "plan",
        "--camera",
        sim.join("cameras.yaml").to_str().unwrap(),
        "--poses",
        "8",
        "--candidates",
        "40",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_success(&run, "plan --camera");
    assert!(
        run.stdout.contains("camera plan: 8 configurations"),
        "{run}"
    );
    let csv = std::fs::read_to_string(&out).unwrap();
    let rows: Vec<&str> = csv.lines().filter(|l| !l.starts_with('#')).collect();
    assert!(rows[0].starts_with("id,targets,torso_joint1"), "{csv}");
    assert_eq!(rows.len(), 9, "{csv}");
    assert!(rows[1..]
        .iter()
        .all(|r| r.split(',').nth(1).is_some_and(|t| t.contains("board"))));
}
