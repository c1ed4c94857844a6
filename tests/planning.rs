//! Optimal pose planning (src/sim/planning.rs) on the built-in Robonaut.

use crate::common::*;
use treecal::math::Vec3;
use treecal::sim::CollisionChecker;
use treecal::sim::{
    criterion_value, plan_poses, Criterion, PlanReport, PlanningOptions, PlanningStage,
};
use treecal::tree::{Branches, KinematicTree};
use treecal::McpcModel;

struct Robot {
    tree: KinematicTree,
    branches: Branches,
    model: McpcModel,
    checker: CollisionChecker,
}

fn robonaut() -> Robot {
    let TestRobot {
        tree,
        branches,
        model,
    } = TestRobot::robonaut();
    let checker = CollisionChecker::new(&tree).unwrap();
    Robot {
        tree,
        branches,
        model,
        checker,
    }
}

fn options(criterion: Criterion, stage: PlanningStage, seed: u64) -> PlanningOptions {
    PlanningOptions {
        poses: 12,
        candidates: 400,
        criterion,
        stage,
        seed,
        ..PlanningOptions::default()
    }
}

fn plan(robot: &Robot, options: &PlanningOptions) -> PlanReport {
    plan_poses(
        &robot.tree,
        &robot.branches,
        &robot.model,
        Some(&robot.checker),
        options,
        &|_| {},
    )
    .unwrap_or_else(|e| panic!("planning failed: {e}"))
}

#[test]
fn planned_sets_beat_the_random_set_they_were_picked_from() {
    let robot = robonaut();
    for (criterion, stage) in [
        (Criterion::O1, PlanningStage::All),
        (Criterion::D, PlanningStage::All),
        (Criterion::O3, PlanningStage::All),
        (Criterion::O1, PlanningStage::Arms),
        (Criterion::O1, PlanningStage::Torso),
    ] {
        let report = plan(&robot, &options(criterion, stage, 3));
        assert_eq!(report.poses.len(), 12);
        assert_eq!(report.random_poses.len(), 12);
        assert_eq!(report.candidates, 400);
        assert!(
            report.planned_value.is_finite() && report.random_value.is_finite(),
            "{criterion:?}/{stage:?}: {} vs {}",
            report.planned_value,
            report.random_value
        );
        assert!(
            report.planned_value > report.random_value,
            "{criterion:?}/{stage:?}: planned {} is not above random {}",
            report.planned_value,
            report.random_value
        );
        // Every chosen configuration is a distinct candidate measuring both tools.
        for (i, a) in report.poses.iter().enumerate() {
            assert_eq!(a.tools, vec![0, 1]);
            for b in &report.poses[i + 1..] {
                assert_ne!(a.q, b.q);
            }
        }
    }
}

#[test]
fn planning_is_deterministic_for_a_seed() {
    let robot = robonaut();
    let a = plan(&robot, &options(Criterion::O1, PlanningStage::All, 7));
    let b = plan(&robot, &options(Criterion::O1, PlanningStage::All, 7));
    let c = plan(&robot, &options(Criterion::O1, PlanningStage::All, 8));
    assert_eq!(a.poses, b.poses);
    assert_eq!(a.planned_value.to_bits(), b.planned_value.to_bits());
    assert_ne!(a.poses, c.poses);
    // Collision-free, within limits.
    let limits = robot.tree.dof_limits();
    for pose in &a.poses {
        let poses = robot.tree.link_poses(&pose.q).unwrap();
        assert!(!robot.checker.in_collision(&poses));
        for (value, limit) in pose.q.iter().zip(&limits) {
            if let Some(l) = limit {
                assert!(*value >= l.lower && *value <= l.upper);
            }
        }
    }
}

#[test]
fn workspace_box_rejects_tools_outside_it() {
    let robot = robonaut();
    let all = plan(&robot, &options(Criterion::O1, PlanningStage::All, 1));
    assert_eq!(all.rejected_workspace, 0);
    // Only configurations with both tools in front of the base (x > 0).
    let low = Vec3::new(0.0, -5.0, -5.0);
    let high = Vec3::new(5.0, 5.0, 5.0);
    let boxed = plan(
        &robot,
        &PlanningOptions {
            workspace: Some((low, high)),
            ..options(Criterion::O1, PlanningStage::All, 1)
        },
    );
    assert!(boxed.rejected_workspace > 0, "nothing rejected by the box");
    let tools: Vec<_> = robot.model.tools().iter().map(|t| t.link).collect();
    for pose in boxed.poses.iter().chain(&boxed.random_poses) {
        let poses = robot.tree.link_poses(&pose.q).unwrap();
        for link in &tools {
            let p = poses[link.0].translation.vector;
            assert!(p.x >= 0.0, "tool at {p:?} is outside the box");
        }
    }
    // A box no tool can reach leaves nothing to plan from: a clear error.
    let error = plan_poses(
        &robot.tree,
        &robot.branches,
        &robot.model,
        Some(&robot.checker),
        &PlanningOptions {
            workspace: Some((Vec3::new(50.0, 50.0, 50.0), Vec3::new(51.0, 51.0, 51.0))),
            candidates: 20,
            ..options(Criterion::O1, PlanningStage::All, 1)
        },
        &|_| {},
    )
    .unwrap_err()
    .to_string();
    assert!(error.contains("workspace box"), "{error}");
}

#[test]
fn torso_stage_keeps_the_arms_locked() {
    let robot = robonaut();
    let report = plan(&robot, &options(Criterion::O1, PlanningStage::Torso, 5));
    let torso = robot.branches.coupled.dofs(&robot.tree);
    let arms: Vec<usize> = (0..robot.tree.dof_count())
        .filter(|d| !torso.contains(d))
        .collect();
    let mut locks: Vec<Vec<f64>> = Vec::new();
    for pose in &report.poses {
        let values: Vec<f64> = arms.iter().map(|&d| pose.q[d]).collect();
        if !locks.contains(&values) {
            locks.push(values);
        }
    }
    // The default two locks, both used (each adds rigid tools only it can identify), and the
    // torso really moves.
    assert_eq!(locks.len(), 2, "{locks:?}");
    let first = &report.poses[0].q;
    assert!(report
        .poses
        .iter()
        .any(|p| torso.iter().any(|&d| p.q[d] != first[d])));
}

#[test]
fn bad_options_are_refused_with_the_reason() {
    let robot = robonaut();
    for (options, needle) in [
        (
            PlanningOptions {
                poses: 0,
                ..PlanningOptions::default()
            },
            "at least 1 pose",
        ),
        (
            PlanningOptions {
                poses: 30,
                candidates: 10,
                ..PlanningOptions::default()
            },
            "at least as many candidates",
        ),
        (
            PlanningOptions {
                workspace: Some((Vec3::new(1.0, 0.0, 0.0), Vec3::new(0.0, 1.0, 1.0))),
                ..PlanningOptions::default()
            },
            "minimum corner first",
        ),
    ] {
        let error = plan_poses(
            &robot.tree,
            &robot.branches,
            &robot.model,
            None,
            &options,
            &|_| {},
        )
        .unwrap_err()
        .to_string();
        assert!(error.contains(needle), "{error}");
    }
    assert!("o2".parse::<Criterion>().is_err());
    assert_eq!("O1".parse::<Criterion>().unwrap(), Criterion::O1);
}

#[test]
fn criterion_values_by_hand() {
    let sigma = [4.0, 1.0];
    assert!((criterion_value(Criterion::O1, &sigma, 16) - 2.0 / 4.0).abs() < 1e-15);
    assert!((criterion_value(Criterion::D, &sigma, 16) - 2.0 * 4f64.ln()).abs() < 1e-15);
    assert_eq!(criterion_value(Criterion::O3, &sigma, 16), 1.0);
    assert_eq!(criterion_value(Criterion::O1, &[1.0, 0.0], 4), 0.0);
}
