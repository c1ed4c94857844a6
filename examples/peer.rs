//! The treecal side of the peer benchmark (`benches/peer/peer.py`, `docs/performance.md`):
//! times forward kinematics and the identification Jacobian of the MCPC model on seeded
//! random configurations and prints JSON: the tools, the MCPC frames' URDF joints with their
//! values per configuration (so that Pinocchio can be set to the same state), the tool poses
//! (a cross-check) and the median and minimum nanoseconds per call.
//!
//! `cargo run --release --example peer -- [ROBOT.urdf] [--rounds N] [--gauss-newton]`
//! (`--gauss-newton`: only the Gauss–Newton iteration, e.g. for a profiler).

use nalgebra::DMatrix;
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use std::hint::black_box;
use std::time::Instant;
use treecal::calibration::{identify, IdentificationOptions, Rigid};
use treecal::kinematics::{ChainFrames, ForwardFrames};
use treecal::measurement::{Measurement, Observation};
use treecal::{detect_branches, load_urdf, McpcModel};

const CONFIGURATIONS: usize = 64;

/// Median and minimum over `rounds` of the mean time per call (ns) of `call` over all
/// configurations, in rounds of about 2 ms: on a loaded machine the minimum is the round no
/// other process interrupted.
fn timing_ns(
    rounds: usize,
    configurations: &[Vec<f64>],
    mut call: impl FnMut(&[f64]),
) -> (f64, f64) {
    let start = Instant::now();
    for q in configurations {
        call(q);
    }
    let once = start.elapsed().as_secs_f64() / configurations.len() as f64;
    let repeats = ((0.002 / once.max(1e-9)) as usize / configurations.len()).max(1);
    let mut samples: Vec<f64> = (0..rounds)
        .map(|_| {
            let start = Instant::now();
            for _ in 0..repeats {
                for q in configurations {
                    call(black_box(q));
                }
            }
            start.elapsed().as_secs_f64() * 1e9 / (repeats * configurations.len()) as f64
        })
        .collect();
    samples.sort_by(f64::total_cmp);
    (samples[samples.len() / 2], samples[0])
}

/// Noise-free full poses of every tool at `configurations` from a truth off the nominal model
/// by up to ±0.05 rad / ±5 cm (the paper's section 5.2 errors).
fn measurements(nominal: &McpcModel, configurations: &[Vec<f64>]) -> Vec<Measurement> {
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let values: Vec<f64> = nominal
        .parameters()
        .iter()
        .map(|v| v + rng.random_range(-0.05..0.05))
        .collect();
    let mut truth = nominal.clone();
    if truth.set_parameters(&values).is_err() {
        truth = nominal.clone();
    }
    let mut measurements = Vec::new();
    for q in configurations {
        for (tool, pose) in truth.tool_poses(q).into_iter().enumerate() {
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

/// CPU time of this process so far (ns, all threads), from Linux's `/proc/self/task/*/schedstat`.
fn cpu_ns() -> Option<f64> {
    let mut total = 0.0;
    for task in std::fs::read_dir("/proc/self/task").ok()? {
        let stat = std::fs::read_to_string(task.ok()?.path().join("schedstat")).ok()?;
        total += stat.split_whitespace().next()?.parse::<f64>().ok()?;
    }
    Some(total)
}

/// One Gauss–Newton iteration (linearisation, rank analysis, step, trial cost) with every
/// parameter free on 200 configurations × every tool: `identify` with one iteration allowed
/// minus `identify` with none (both end with an analysis and the RMS). Returns the median and
/// minimum wall ns, and the mean CPU ns (all threads; Linux only, else NaN), which a loaded
/// machine disturbs much less than the wall time.
fn gauss_newton_iteration(model: &McpcModel, dofs: usize, rounds: usize) -> (f64, f64, f64) {
    let mut rng = ChaCha8Rng::seed_from_u64(200);
    let configurations: Vec<Vec<f64>> = (0..200)
        .map(|_| (0..dofs).map(|_| rng.random_range(-2.9..2.9)).collect())
        .collect();
    let data = measurements(model, &configurations);
    let free: Vec<usize> = (0..model.parameter_count()).collect();
    let options = |iterations: usize| IdentificationOptions {
        max_iterations: iterations,
        ..IdentificationOptions::default()
    };
    let (one, none) = (options(1), options(0));
    let run = |options: &IdentificationOptions| {
        black_box(identify(model, &data, None, &Rigid, &free, options).ok());
    };
    let time = |options: &IdentificationOptions| timing_ns(rounds, &[Vec::new()], |_| run(options));
    let (wall_one, wall_none) = (time(&one), time(&none));
    let mut cpu = [0.0; 2];
    for _ in 0..rounds {
        for (total, options) in cpu.iter_mut().zip([&one, &none]) {
            let start = cpu_ns().unwrap_or(f64::NAN);
            run(options);
            *total += cpu_ns().unwrap_or(f64::NAN) - start;
        }
    }
    (
        wall_one.0 - wall_none.0,
        wall_one.1 - wall_none.1,
        (cpu[0] - cpu[1]) / rounds as f64,
    )
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let mut robot =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("robots/robonaut/robonaut.urdf");
    let mut rounds = 101;
    let mut iteration_only = false;
    while let Some(arg) = args.next() {
        match arg.as_str() {
            "--rounds" => rounds = args.next().ok_or("--rounds needs a value")?.parse()?,
            "--gauss-newton" => iteration_only = true,
            path => robot = path.into(),
        }
    }
    let tree = load_urdf(&robot)?.tree;
    let branches = detect_branches(&tree, None)?;
    let model = McpcModel::from_tree(&tree, &branches)?;
    let mut rng = ChaCha8Rng::seed_from_u64(14);
    let configurations: Vec<Vec<f64>> = (0..CONFIGURATIONS)
        .map(|_| {
            (0..tree.dof_count())
                .map(|_| rng.random_range(-1.5..1.5))
                .collect()
        })
        .collect();

    if iteration_only {
        let (median, min, cpu) = gauss_newton_iteration(&model, tree.dof_count(), rounds);
        println!("{{\"gn_iteration_200x2\":[{median:.1},{min:.1}],\"gn_iteration_cpu\":{cpu:.1}}}");
        return Ok(());
    }
    let tools = model.tools().len();
    let iteration = gauss_newton_iteration(&model, tree.dof_count(), rounds);
    let mut chain = ChainFrames::default();
    let mut forward = ForwardFrames::default();
    let mut jacobian = DMatrix::zeros(6, model.parameter_count());
    let mut jacobians = Vec::new();
    let timings = [
        (
            "fk_both_tools",
            timing_ns(rounds, &configurations, |q| {
                model.tool_transforms_into(q, &mut forward);
                black_box(&forward.tools);
            }),
        ),
        (
            "fk_both_tools_as_poses",
            timing_ns(rounds, &configurations, |q| {
                black_box(model.tool_poses(q));
            }),
        ),
        (
            "fk_one_tool",
            timing_ns(rounds, &configurations, |q| {
                black_box(model.tool_pose(0, q));
            }),
        ),
        (
            "jacobian_both_tools",
            timing_ns(rounds, &configurations, |q| {
                model.tool_jacobians_into(q, &mut chain, &mut jacobians);
                black_box(&jacobians);
            }),
        ),
        (
            "jacobian_both_tools_allocating",
            timing_ns(rounds, &configurations, |q| {
                black_box(model.tool_jacobians(q));
            }),
        ),
        (
            "jacobian_one_tool",
            timing_ns(rounds, &configurations, |q| {
                black_box(model.tool_jacobian_into(0, q, &mut chain, &mut jacobian));
            }),
        ),
        ("gn_iteration_200x2", (iteration.0, iteration.1)),
    ];

    let joints: Vec<String> = model
        .frames()
        .iter()
        .map(|f| format!("{:?}", tree.joint(f.joint).name))
        .collect();
    let values: Vec<String> = configurations
        .iter()
        .map(|q| {
            let row: Vec<String> = (0..model.frames().len())
                .map(|f| format!("{:e}", model.joint_value(f, q)))
                .collect();
            format!("[{}]", row.join(","))
        })
        .collect();
    let poses: Vec<String> = configurations
        .iter()
        .map(|q| {
            let row: Vec<String> = model
                .tool_poses(q)
                .iter()
                .map(|p| {
                    let t = p.translation.vector;
                    format!("[{:e},{:e},{:e}]", t.x, t.y, t.z)
                })
                .collect();
            format!("[{}]", row.join(","))
        })
        .collect();
    let tool_links: Vec<String> = model
        .tools()
        .iter()
        .map(|t| format!("{:?}", tree.link(t.link).name))
        .collect();
    let timing_json: Vec<String> = timings
        .iter()
        .map(|(name, (median, min))| format!("{name:?}:[{median:.1},{min:.1}]"))
        .collect();
    println!(
        "{{\"robot\":{:?},\"tools\":[{}],\"parameters\":{},\"joints\":[{}],\"values\":[{}],\"tool_positions\":[{}],\"ns\":{{{}}},\"gn_iteration_cpu\":{:.1},\"tool_count\":{tools}}}",
        robot.display().to_string(),
        tool_links.join(","),
        model.parameter_count(),
        joints.join(","),
        values.join(","),
        poses.join(","),
        timing_json.join(","),
        iteration.2,
    );
    Ok(())
}
