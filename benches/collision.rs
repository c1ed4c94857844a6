//! Self-collision benchmarks: one check per robot at collision-free and at colliding
//! configurations, and drawing collision-free configurations of the built-in Robonaut.
//!
//! Issue 6 plans 20 poses from 5,000 collision-free candidates on robonaut.urdf in under 2 s;
//! a check should be a small part of that (a few µs).

use criterion::{criterion_group, criterion_main, Criterion};
use rand::rngs::ChaCha8Rng;
use rand::SeedableRng;
use std::hint::black_box;
use std::path::{Path, PathBuf};
use treecal::math::Pose;
use treecal::sim::CollisionChecker;
use treecal::sim::{sample_configurations, SamplingOptions};
use treecal::{load_urdf, KinematicTree};

fn robots() -> Vec<(&'static str, PathBuf)> {
    let repo = Path::new(env!("CARGO_MANIFEST_DIR"));
    vec![
        ("robonaut", repo.join("robots/robonaut/robonaut.urdf")),
        ("humanoid", repo.join("robots/humanoid/humanoid.urdf")),
        (
            "robonaut2",
            repo.join("../shared/robots/robonaut2/robonaut2.urdf"),
        ),
    ]
}

/// Link poses of 200 uniform configurations, split into collision-free and colliding ones.
fn poses(tree: &KinematicTree, checker: &CollisionChecker) -> (Vec<Vec<Pose>>, Vec<Vec<Pose>>) {
    let all = sample_configurations(
        tree,
        None,
        200,
        &mut ChaCha8Rng::seed_from_u64(7),
        &SamplingOptions::default(),
        &[],
    )
    .expect("configurations");
    all.iter()
        .map(|q| tree.link_poses(q).expect("poses"))
        .partition(|p| !checker.in_collision(p))
}

fn checks(c: &mut Criterion) {
    for (name, path) in robots() {
        let Ok(import) = load_urdf(&path) else {
            eprintln!("skipping {name}: {} not found", path.display());
            continue;
        };
        let tree = import.tree;
        let checker = CollisionChecker::new(&tree).expect("checker");
        let (free, colliding) = poses(&tree, &checker);
        for (kind, set) in [("free", free), ("colliding", colliding)] {
            if set.is_empty() {
                continue;
            }
            let mut next = 0;
            c.bench_function(&format!("in_collision_{kind}_{name}"), |b| {
                b.iter(|| {
                    next = (next + 1) % set.len();
                    checker.in_collision(black_box(&set[next]))
                })
            });
        }
    }
}

fn sampling(c: &mut Criterion) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("robots/robonaut/robonaut.urdf");
    let tree = load_urdf(&path).expect("robonaut.urdf loads").tree;
    let checker = CollisionChecker::new(&tree).expect("checker");
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    c.bench_function("sample_100_collision_free_robonaut", |b| {
        b.iter(|| {
            sample_configurations(
                &tree,
                Some(&checker),
                100,
                &mut rng,
                &SamplingOptions::default(),
                &[],
            )
        })
    });
}

criterion_group!(benches, checks, sampling);
criterion_main!(benches);
