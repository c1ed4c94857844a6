//! The observation seam (`calibration::observation`): each kind's row count, residual, Jacobian
//! (against finite differences), tool-motion Jacobian, noise-free observation and frame change.

use crate::common;
use nalgebra::{DMatrix, Vector6};
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use treecal::calibration::{
    kind_of, norms_by_row_kind, standardized_norm, Noise, Nuisance, NuisanceBlock, RobotState,
    RowKind, Tools,
};
use treecal::kinematics::ToolJacobian;
use treecal::math::{pose, Pose, Vec3};
use treecal::measurement::Observation;
use treecal::McpcModel;

/// The built-in Robonaut with every parameter moved off nominal, and a random configuration.
fn robot(seed: u64) -> (McpcModel, Vec<f64>) {
    let (tree, mut model) = common::robonaut_model();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let values: Vec<f64> = model
        .parameters()
        .iter()
        .map(|v| v + rng.random_range(-0.02..0.02))
        .collect();
    model.set_parameters(&values).expect("parameters");
    let q = (0..tree.dof_count())
        .map(|_| rng.random_range(-1.5..1.5))
        .collect();
    (model, q)
}

fn state<'a>(
    model: &'a McpcModel,
    q: &'a [f64],
    tool: usize,
    tools: Tools<'a>,
    offset: Option<&'a Vector6<f64>>,
    nuisance: &'a Nuisance,
) -> RobotState<'a> {
    RobotState {
        model,
        q,
        tool,
        tools,
        offset,
        nuisance,
    }
}

/// Both of today's kinds, measured noise-free at the model's prediction of `tool`.
fn both_kinds(model: &McpcModel, q: &[f64], tool: usize) -> Vec<Observation> {
    let poses = model.tool_poses(q);
    let at = state(model, q, tool, Tools::Poses(&poses), None, Nuisance::none());
    [
        Observation::Position(Vec3::zeros()),
        Observation::Pose(Pose::identity()),
    ]
    .iter()
    .map(|o| kind_of(o).noise_free(&at).expect("noise-free"))
    .collect()
}

#[test]
fn row_counts_and_row_kinds_agree_with_the_observation() {
    let position = Observation::Position(Vec3::new(1.0, 2.0, 3.0));
    let frame = Observation::Pose(pose(
        Vec3::new(1.0, 2.0, 3.0),
        nalgebra::UnitQuaternion::identity(),
    ));
    for observation in [&position, &frame] {
        let kind = kind_of(observation);
        assert_eq!(kind.rows(), observation.rows());
        assert_eq!(kind.row_kinds().len(), observation.rows());
        assert!(kind.is_finite());
        assert_eq!(kind.measured_point(), Some(Vec3::new(1.0, 2.0, 3.0)));
    }
    assert_eq!(kind_of(&position).name(), "position");
    assert_eq!(kind_of(&frame).name(), "pose");
    assert!(!kind_of(&position).row_kinds().contains(&RowKind::Rotation));
    assert_eq!(
        kind_of(&frame)
            .row_kinds()
            .iter()
            .filter(|k| **k == RowKind::Rotation)
            .count(),
        3
    );
    assert!(kind_of(&position).measured_frame().is_none());
    assert!(!kind_of(&Observation::Position(Vec3::new(f64::NAN, 0.0, 0.0))).is_finite());
}

/// `J = ∂predicted/∂θ`: at a noise-free measurement (r = 0), moving parameter p by h changes
/// the residual by −J·h (to first order), for the model's parameters; nuisance columns are 0.
#[test]
fn jacobians_match_finite_differences() {
    let (model, q) = robot(3);
    let count = model.parameter_count();
    let jacobians: Vec<ToolJacobian> = model.tool_jacobians(&q);
    let nuisance = Nuisance {
        blocks: vec![NuisanceBlock {
            name: "unused".into(),
            parameter_names: vec!["a".into(), "b".into()],
            values: vec![0.5, 0.25],
        }],
    };
    for tool in 0..model.tools().len() {
        for observation in both_kinds(&model, &q, tool) {
            let kind = kind_of(&observation);
            let at = state(
                &model,
                &q,
                tool,
                Tools::Jacobians(&jacobians),
                None,
                &nuisance,
            );
            let columns: Vec<usize> = (0..count + nuisance.len()).collect();
            let mut jacobian = DMatrix::zeros(kind.rows(), columns.len());
            kind.jacobian(
                &at,
                &columns,
                &mut jacobian.view_mut((0, 0), jacobian.shape()),
            )
            .expect("jacobian");
            let h = 1e-7;
            for p in 0..count {
                let mut moved = model.clone();
                moved
                    .set_parameter(p, model.parameters()[p] + h)
                    .expect("set");
                let poses = moved.tool_poses(&q);
                let at = state(&moved, &q, tool, Tools::Poses(&poses), None, &nuisance);
                let mut residual = vec![0.0; kind.rows()];
                kind.residual(&at, &mut residual).expect("residual");
                for (k, r) in residual.iter().enumerate() {
                    let numeric = -r / h;
                    assert!(
                        (numeric - jacobian[(k, p)]).abs() < 1e-5 * (1.0 + numeric.abs()),
                        "{} tool {tool} row {k} parameter {p}: {numeric} vs {}",
                        kind.name(),
                        jacobian[(k, p)]
                    );
                }
            }
            assert!(jacobian
                .columns(count, nuisance.len())
                .iter()
                .all(|v| *v == 0.0));
        }
    }
}

/// `∂predicted/∂ξ` for a motion ξ of the tool's predicted pose (about its origin, in the
/// measurement frame), against moving the pose; other tools do not move the prediction.
#[test]
fn tool_motion_jacobians_match_finite_differences() {
    let (model, q) = robot(5);
    let poses = model.tool_poses(&q);
    let tool = 0;
    for observation in both_kinds(&model, &q, tool) {
        let kind = kind_of(&observation);
        let at = state(
            &model,
            &q,
            tool,
            Tools::Poses(&poses),
            None,
            Nuisance::none(),
        );
        let sensitivity = kind.tool_motion_jacobian(&at, tool);
        assert_eq!(sensitivity.shape(), (kind.rows(), 6));
        assert!(kind
            .tool_motion_jacobian(&at, tool + 1)
            .iter()
            .all(|v| *v == 0.0));
        let h = 1e-7;
        for j in 0..6 {
            let mut xi = Vector6::zeros();
            xi[j] = h;
            let rotation =
                nalgebra::UnitQuaternion::from_scaled_axis(xi.fixed_rows::<3>(3).into_owned());
            let mut moved = poses.clone();
            moved[tool] = pose(
                poses[tool].translation.vector + xi.fixed_rows::<3>(0),
                rotation * poses[tool].rotation,
            );
            let at = state(
                &model,
                &q,
                tool,
                Tools::Poses(&moved),
                None,
                Nuisance::none(),
            );
            let mut residual = vec![0.0; kind.rows()];
            kind.residual(&at, &mut residual).expect("residual");
            for (k, r) in residual.iter().enumerate() {
                assert!(
                    (-r / h - sensitivity[(k, j)]).abs() < 1e-6,
                    "row {k} motion {j}"
                );
            }
        }
    }
}

/// A noise-free observation under a linear flexibility offset has residual 0; moving it to
/// another frame and back gives it back; the standardized norm weighs rows by their σ.
#[test]
fn noise_free_offsets_frames_and_norms() {
    let (model, q) = robot(9);
    let poses = model.tool_poses(&q);
    let offset = Vector6::new(1e-3, -2e-3, 3e-3, 1e-3, 2e-3, -1e-3);
    let at = state(
        &model,
        &q,
        1,
        Tools::Poses(&poses),
        Some(&offset),
        Nuisance::none(),
    );
    let frame = pose(
        Vec3::new(0.3, -1.0, 2.0),
        nalgebra::UnitQuaternion::from_scaled_axis(Vec3::new(0.1, 0.2, -0.3)),
    );
    let noise = Noise {
        position: 1e-4,
        rotation: 1e-3,
        ..Noise::default()
    };
    for template in [
        Observation::Position(Vec3::zeros()),
        Observation::Pose(Pose::identity()),
    ] {
        let kind = kind_of(&template);
        let measured = kind.noise_free(&at).expect("noise-free");
        let mut residual = vec![0.0; kind.rows()];
        kind_of(&measured)
            .residual(&at, &mut residual)
            .expect("residual");
        assert!(residual.iter().all(|r| r.abs() < 1e-12), "{residual:?}");
        let back = kind_of(&kind_of(&measured).in_frame(&frame)).in_frame(&frame.inverse());
        let (a, b) = (
            kind_of(&back).measured_point().expect("point"),
            kind_of(&measured).measured_point().expect("point"),
        );
        assert!((a - b).norm() < 1e-12);
        // A residual of 1 σ in every row.
        let unit: Vec<f64> = kind.row_kinds().iter().map(|k| noise.sigma(*k)).collect();
        let norm = standardized_norm(kind, &unit, &noise);
        assert!((norm - (kind.rows() as f64).sqrt()).abs() < 1e-12);
        let norms = norms_by_row_kind(kind, &unit);
        let (position, rotation) = (norms[0], norms[1]);
        assert!((position.expect("position rows") - 3f64.sqrt() * 1e-4).abs() < 1e-15);
        assert_eq!(rotation.is_some(), kind.rows() == 6);
    }
}
