//! Forward-kinematics benchmarks on the built-in Robonaut (robots/robonaut/robonaut.urdf).
//!
//! Target (issue 2): under 0.3 µs per tool pose in release mode.

use criterion::{criterion_group, criterion_main, Criterion};
use std::hint::black_box;
use treecal::{detect_branches, load_urdf, McpcModel};

fn robonaut() -> (treecal::KinematicTree, McpcModel) {
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("robots/robonaut/robonaut.urdf");
    let tree = load_urdf(&path).expect("robonaut.urdf loads").tree;
    let branches = detect_branches(&tree, None).expect("branches");
    let model = McpcModel::from_tree(&tree, &branches).expect("model");
    (tree, model)
}

fn forward_kinematics(c: &mut Criterion) {
    let (tree, model) = robonaut();
    let q: Vec<f64> = (0..tree.dof_count())
        .map(|i| 0.1 * i as f64 - 0.5)
        .collect();
    c.bench_function("mcpc_fk_both_tools_robonaut", |b| {
        b.iter(|| {
            let q = black_box(&q);
            model.tool_poses(q)
        })
    });
    let mut forward = treecal::kinematics::ForwardFrames::default();
    c.bench_function("mcpc_fk_both_tools_transforms_robonaut", |b| {
        b.iter(|| {
            model.tool_transforms_into(black_box(&q), &mut forward);
            forward.tools[0].translation
        })
    });
    c.bench_function("mcpc_fk_one_tool_robonaut", |b| {
        b.iter(|| model.tool_pose(0, black_box(&q)))
    });
    c.bench_function("mcpc_fk_all_frames_robonaut", |b| {
        b.iter(|| model.frame_poses(black_box(&q)))
    });
    c.bench_function("urdf_fk_all_links_robonaut", |b| {
        b.iter(|| tree.link_poses(black_box(&q)))
    });
}

criterion_group!(benches, forward_kinematics);
criterion_main!(benches);
