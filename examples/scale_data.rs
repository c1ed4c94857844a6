//! Measurement data for the scale benchmarks (`docs/performance.md`): `N` random
//! configurations within the joint limits of the built-in Robonaut, both tools measured as
//! three tracker targets (full poses) with the AT901 noise model on a randomly wrong robot
//! (±0.05 rad, ±5 cm), written as `simulate --write-measurements --measurement-format
//! tracker` writes them (mm, deg). No calibration is run, no collision check is made.
//!
//! `cargo run --release --example scale_data -- N OUT.csv [SEED]`

use rand::rngs::ChaCha8Rng;
use rand::SeedableRng;
use treecal::io::{measurements_to_csv_with, AngleUnit, LengthUnit, MeasurementWriteOptions};
use treecal::measurement::Measurement;
use treecal::sim::{observe, NoiseModel, Targets};
use treecal::sim::{sample_configurations, SamplingOptions};
use treecal::sim::{true_model, ErrorRanges};
use treecal::{detect_branches, load_urdf, McpcModel};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (Some(count), Some(out)) = (args.first(), args.get(1)) else {
        return Err("usage: scale_data N OUT.csv [SEED]".into());
    };
    let count: usize = count.parse()?;
    let seed: u64 = args.get(2).map_or(Ok(0), |s| s.parse())?;
    let robot =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("robots/robonaut/robonaut.urdf");
    let tree = load_urdf(&robot)?.tree;
    let branches = detect_branches(&tree, None)?;
    let nominal = McpcModel::from_tree(&tree, &branches)?;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let truth = true_model(&nominal, &ErrorRanges::default(), &mut rng)?;
    let configurations = sample_configurations(
        &tree,
        None,
        count,
        &mut rng,
        &SamplingOptions::default(),
        &[],
    )?;
    let noise = NoiseModel::at901();
    let mut measurements = Vec::with_capacity(2 * count);
    for q in configurations {
        for (tool, pose) in truth.tool_poses(&q).iter().enumerate() {
            measurements.push(Measurement {
                payload: None,
                tool,
                q: q.clone(),
                observation: observe(pose, Targets::Three, &noise, &mut rng),
                stage: None,
                session: None,
            });
        }
    }
    let text = measurements_to_csv_with(
        &tree,
        &nominal,
        &measurements,
        &MeasurementWriteOptions {
            length_unit: LengthUnit::Millimetre,
            angle_unit: AngleUnit::Degree,
            three_targets: true,
        },
    )?;
    std::fs::write(out, text)?;
    eprintln!("scale_data: {} rows to {out}", measurements.len());
    Ok(())
}
