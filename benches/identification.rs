//! Identification benchmarks on the built-in Robonaut (robots/robonaut/robonaut.urdf).
//!
//! Targets (issue 3): the full identification Jacobian of both tools (64 parameters) for one
//! configuration under 2 µs; one full calibration on 20 and on 100 configurations under 5 ms
//! and 17 ms. Issue 14: one Gauss–Newton iteration on 200 configurations × 2 tools within 3×
//! of the compute limit (the difference of the two `identify_…_iterations` benches; see
//! `docs/performance.md`, and `benches/peer/peer.py` for the comparison with Pinocchio).
//! Stiffness identification (issue 13): the joint fit of the geometry and the compliances
//! from 20 configurations, the model 50 % too stiff.

use criterion::{criterion_group, criterion_main, Criterion};
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use std::hint::black_box;
use treecal::calibration::{
    identify, identify_stiffness, IdentificationOptions, Rigid, StiffnessOptions,
};
use treecal::kinematics::FlexibilityModel;
use treecal::measurement::{Measurement, Observation};
use treecal::{detect_branches, load_urdf, KinematicTree, McpcModel};

fn robonaut() -> (KinematicTree, McpcModel) {
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("robots/robonaut/robonaut.urdf");
    let tree = load_urdf(&path).expect("robonaut.urdf loads").tree;
    let branches = detect_branches(&tree, None).expect("branches");
    let model = McpcModel::from_tree(&tree, &branches).expect("model");
    (tree, model)
}

/// The paper's section 5.2 truth (±0.05 rad, ±5 cm) and noise-free full-pose measurements.
fn problem(tree: &KinematicTree, nominal: &McpcModel, configurations: usize) -> Vec<Measurement> {
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let values: Vec<f64> = nominal
        .parameters()
        .iter()
        .map(|v| v + rng.random_range(-0.05..0.05))
        .collect();
    let mut truth = nominal.clone();
    truth.set_parameters(&values).expect("parameters");
    let mut measurements = Vec::new();
    for _ in 0..configurations {
        let q: Vec<f64> = (0..tree.dof_count())
            .map(|_| rng.random_range(-2.9..2.9))
            .collect();
        for (tool, pose) in truth.tool_poses(&q).into_iter().enumerate() {
            measurements.push(Measurement {
                payload: None,
                tool,
                q: q.clone(),
                observation: Observation::Pose(pose),
                stage: None,
                session: None,
            });
        }
    }
    measurements
}

/// Noise-free deflected poses of a truth off by ±0.05 (the stiffness file's flexibility), a
/// start near the true geometry (what the preceding calibration gives) and the prior 50 % too
/// stiff.
fn stiffness_problem(
    tree: &KinematicTree,
    nominal: &McpcModel,
    configurations: usize,
) -> (Vec<Measurement>, McpcModel, FlexibilityModel) {
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("robots/robonaut/stiffness.yaml");
    let stiffness = treecal::io::read_stiffness(&path, tree, nominal).expect("stiffness");
    let truth_flexibility = FlexibilityModel::new(tree, nominal, &stiffness).expect("model");
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    let values: Vec<f64> = nominal
        .parameters()
        .iter()
        .map(|v| v + rng.random_range(-0.05..0.05))
        .collect();
    let mut truth = nominal.clone();
    truth.set_parameters(&values).expect("parameters");
    let mut measurements = Vec::new();
    for _ in 0..configurations {
        let q: Vec<f64> = (0..tree.dof_count())
            .map(|_| rng.random_range(-2.9..2.9))
            .collect();
        let poses = truth_flexibility
            .deflected_tool_poses(tree, &truth, &q)
            .expect("poses");
        for (tool, pose) in poses.into_iter().enumerate() {
            measurements.push(Measurement {
                payload: None,
                tool,
                q: q.clone(),
                observation: Observation::Pose(pose),
                stage: None,
                session: None,
            });
        }
    }
    let start_values: Vec<f64> = values
        .iter()
        .map(|v| v + rng.random_range(-1e-3..1e-3))
        .collect();
    let mut start = truth;
    start.set_parameters(&start_values).expect("parameters");
    let prior = truth_flexibility.scaled(1.0 / 1.5).expect("scaled");
    (measurements, start, prior)
}

fn stiffness_benchmark(c: &mut Criterion) {
    let (tree, model) = robonaut();
    let (measurements, start, prior) = stiffness_problem(&tree, &model, 20);
    let free: Vec<usize> = (0..model.parameter_count()).collect();
    let options = IdentificationOptions::default();
    let mut group = c.benchmark_group("stiffness");
    group.sample_size(10);
    group.bench_function("identify_stiffness_robonaut_20_configurations", |b| {
        b.iter(|| {
            identify_stiffness(
                &tree,
                &start,
                &prior,
                black_box(&measurements),
                None,
                &free,
                &options,
                &StiffnessOptions::default(),
            )
            .expect("identify_stiffness")
        })
    });
    group.finish();
}

fn benchmarks(c: &mut Criterion) {
    let (tree, model) = robonaut();
    let q: Vec<f64> = (0..tree.dof_count())
        .map(|i| 0.1 * i as f64 - 0.5)
        .collect();
    c.bench_function("jacobian_both_tools_robonaut", |b| {
        b.iter(|| model.tool_jacobians(black_box(&q)))
    });
    let mut chain = treecal::kinematics::ChainFrames::default();
    let mut jacobians = Vec::new();
    c.bench_function("jacobian_both_tools_into_robonaut", |b| {
        b.iter(|| model.tool_jacobians_into(black_box(&q), &mut chain, &mut jacobians))
    });
    // Caller-provided buffers, one tool's chain only (issue 14).
    let mut jacobian = nalgebra::DMatrix::zeros(6, model.parameter_count());
    c.bench_function("jacobian_one_tool_into_robonaut", |b| {
        b.iter(|| model.tool_jacobian_into(0, black_box(&q), &mut chain, &mut jacobian))
    });
    let free: Vec<usize> = (0..model.parameter_count()).collect();
    let options = IdentificationOptions::default();
    // One Gauss–Newton iteration on 200 configurations × 2 tools (issue 14): the difference
    // between these two (the second also linearises, analyses, steps and re-evaluates once).
    let measurements = problem(&tree, &model, 200);
    for iterations in [0, 1] {
        let options = IdentificationOptions {
            max_iterations: iterations,
            ..IdentificationOptions::default()
        };
        c.bench_function(
            &format!("identify_robonaut_200_configurations_{iterations}_iterations"),
            |b| {
                b.iter(|| {
                    identify(
                        &model,
                        black_box(&measurements),
                        None,
                        &Rigid,
                        &free,
                        &options,
                    )
                    .expect("identify")
                })
            },
        );
    }
    for configurations in [20, 100] {
        let measurements = problem(&tree, &model, configurations);
        c.bench_function(
            &format!("calibrate_robonaut_{configurations}_configurations"),
            |b| {
                b.iter(|| {
                    identify(
                        &model,
                        black_box(&measurements),
                        None,
                        &Rigid,
                        &free,
                        &options,
                    )
                    .expect("identify")
                })
            },
        );
    }
}

criterion_group!(benches, benchmarks, stiffness_benchmark);
criterion_main!(benches);
