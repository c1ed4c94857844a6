//! Pose planning benchmark (issue 6): 20 poses from 5,000 collision-free candidates on
//! robots/robonaut/robonaut.urdf, collision checks and Jacobians included (target: under 2 s
//! on 2 cores).

use criterion::{criterion_group, criterion_main, Criterion};
use std::hint::black_box;
use std::path::Path;
use std::time::Duration;
use treecal::sim::CollisionChecker;
use treecal::sim::{plan_poses, PlanningOptions};
use treecal::{detect_branches, load_urdf, McpcModel};

fn planning(c: &mut Criterion) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("robots/robonaut/robonaut.urdf");
    let tree = load_urdf(&path).expect("robonaut.urdf").tree;
    let branches = detect_branches(&tree, None).expect("branches");
    let model = McpcModel::from_tree(&tree, &branches).expect("model");
    let checker = CollisionChecker::new(&tree).expect("checker");
    let mut group = c.benchmark_group("planning");
    group
        .sample_size(10)
        .measurement_time(Duration::from_secs(20));
    group.bench_function("robonaut_20_of_5000", |b| {
        b.iter(|| {
            let options = PlanningOptions {
                poses: 20,
                candidates: 5000,
                ..PlanningOptions::default()
            };
            black_box(
                plan_poses(&tree, &branches, &model, Some(&checker), &options, &|_| {})
                    .expect("plan"),
            )
        })
    });
    group.finish();
}

criterion_group!(benches, planning);
criterion_main!(benches);
