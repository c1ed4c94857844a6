//! The section 5.2 simulation: library-level checks (the CLI is tested in tests/cli.rs).

use treecal::calibration::Plan;
use treecal::sim::NoiseModel;
use treecal::sim::{run_trial, Setup, SimulationOptions};
use treecal::sim::{run_trials, summarise};

use crate::common::{simulated_robonaut as robonaut, SimulatedRobot as Robot};

fn setup(robot: &Robot) -> Setup<'_> {
    robot.setup()
}

/// Without noise and with the model's flexibility equal to the truth's, compensation removes
/// essentially all of the error, on both plans.
#[test]
fn noise_free_compensated_calibration_removes_the_error() {
    let robot = robonaut();
    for plan in [Plan::staged(), Plan::simultaneous()] {
        let options = SimulationOptions {
            noise: NoiseModel::none(),
            plan,
            ..Default::default()
        };
        let started = std::time::Instant::now();
        let report = run_trial(&setup(&robot), &options, 0).unwrap();
        eprintln!(
            "one trial: {:?}; compensated run {:?}",
            started.elapsed(),
            report.compensated_run
        );
        for arm in &report.validation {
            eprintln!(
                "{}: before {:.3} mm {:.4}°, rigid {:.4} mm, compensated {:.3e} mm {:.3e}°; removed {:?} / {:?}",
                arm.arm,
                arm.before.mean_position_mm,
                arm.before.mean_orientation_deg,
                arm.rigid.mean_position_mm,
                arm.compensated.mean_position_mm,
                arm.compensated.mean_orientation_deg,
                arm.position_removed_percent,
                arm.orientation_removed_percent
            );
            assert!(
                arm.position_removed_percent[1] > 99.99,
                "{}: {:?}",
                arm.arm,
                arm.position_removed_percent
            );
            assert!(
                arm.orientation_removed_percent[1] > 99.99,
                "{}: {:?}",
                arm.arm,
                arm.orientation_removed_percent
            );
            assert!(arm.position_removed_percent[0] < arm.position_removed_percent[1]);
        }
    }
}

/// The same seed gives the same numbers, whatever the thread count.
#[test]
fn results_depend_only_on_the_seed() {
    let robot = robonaut();
    let options = SimulationOptions::default();
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| run_trials(&setup(&robot), &options, 3, &|| {}).unwrap())
    };
    let one = serde_json::to_string(&summarise(&run(1))).unwrap();
    let two = serde_json::to_string(&summarise(&run(2))).unwrap();
    assert_eq!(one, two);
    let other = SimulationOptions {
        seed: 1,
        ..Default::default()
    };
    let different = serde_json::to_string(&summarise(
        &run_trials(&setup(&robot), &other, 3, &|| {}).unwrap(),
    ))
    .unwrap();
    assert_ne!(one, different);
}
