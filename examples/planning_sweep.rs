//! Validation error against the number of arm poses K, planned (O1) against random poses:
//! the numbers and the plot of docs/planning.md ("Does it matter?").
//!
//! ```text
//! cargo run --release --example planning_sweep -- [--trials 30] [--seed 0] \
//!     [--poses 8,12,16,20,30,40] [--candidates 2000] [--out docs/img] [--plot-only]
//! ```
//!
//! For each K it runs the `treecal simulate` defaults (built-in Robonaut, staged plan, 10 torso
//! poses, AT901 noise, three targets, 20 validation configurations) once with random and once
//! with planned identification poses, over the same trial seeds, and takes per trial the mean
//! validation position error of the flexibility-compensated calibration over both arms. It
//! writes `planning_k.csv` (median and quartiles over trials) and `planning_k.svg` to `--out`;
//! `--plot-only` redraws the SVG from an existing CSV.

use std::path::{Path, PathBuf};
use std::time::Instant;
use treecal::io::{parse_stiffness, write_atomically};
use treecal::kinematics::FlexibilityModel;
use treecal::report::{line_plot_svg, Curve, LinePlot};
use treecal::sim::run_trials;
use treecal::sim::CollisionChecker;
use treecal::sim::PlanningOptions;
use treecal::sim::{Setup, SimulationOptions};
use treecal::{detect_branches, parse_urdf, Error, McpcModel, Result};

const ROBOT: &str = include_str!("../robots/robonaut/robonaut.urdf");
const STIFFNESS: &str = include_str!("../robots/robonaut/stiffness.yaml");

struct Args {
    trials: usize,
    seed: u64,
    poses: Vec<usize>,
    candidates: usize,
    out: PathBuf,
    plot_only: bool,
}

/// One row of the CSV: K, then (first quartile, median, third quartile) for random and planned.
struct Row {
    poses: usize,
    trials: usize,
    random: [f64; 3],
    planned: [f64; 3],
}

fn main() {
    if let Err(error) = parse_args().and_then(|args| run(&args)) {
        eprintln!("planning_sweep: {error}");
        std::process::exit(1);
    }
}

fn usage(message: String) -> Error {
    Error::InvalidData {
        origin: "planning_sweep arguments".into(),
        message,
    }
}

fn parse_args() -> Result<Args> {
    let mut args = Args {
        trials: 30,
        seed: 0,
        poses: vec![8, 12, 16, 20, 30, 40],
        candidates: 2000,
        out: PathBuf::from("docs/img"),
        plot_only: false,
    };
    let mut raw = std::env::args().skip(1);
    while let Some(flag) = raw.next() {
        if flag == "--plot-only" {
            args.plot_only = true;
            continue;
        }
        let value = raw
            .next()
            .ok_or_else(|| usage(format!("{flag} needs a value")))?;
        let number = |text: &str| {
            text.trim()
                .parse::<usize>()
                .map_err(|e| usage(format!("{flag} {text}: {e}")))
        };
        match flag.as_str() {
            "--trials" => args.trials = number(&value)?,
            "--seed" => args.seed = number(&value)? as u64,
            "--candidates" => args.candidates = number(&value)?,
            "--poses" => {
                args.poses = value.split(',').map(number).collect::<Result<_>>()?;
            }
            "--out" => args.out = PathBuf::from(value),
            _ => return Err(usage(format!("unknown flag {flag}"))),
        }
    }
    if args.trials == 0 || args.candidates == 0 || args.poses.contains(&0) {
        return Err(usage(
            "--trials, --candidates and every K must be at least 1".into(),
        ));
    }
    Ok(args)
}

fn run(args: &Args) -> Result<()> {
    let csv_path = args.out.join("planning_k.csv");
    let rows = if args.plot_only {
        read_csv(&csv_path)?
    } else {
        let rows = sweep(args)?;
        std::fs::create_dir_all(&args.out).map_err(|source| Error::Io {
            path: args.out.clone(),
            source,
        })?;
        write_atomically(&csv_path, csv(&rows, args).as_bytes())?;
        rows
    };
    let svg = line_plot_svg(&plot(&rows))?;
    let svg_path = args.out.join("planning_k.svg");
    write_atomically(&svg_path, svg.as_bytes())?;
    eprintln!(
        "planning_sweep: wrote {} and {}",
        csv_path.display(),
        svg_path.display()
    );
    Ok(())
}

fn sweep(args: &Args) -> Result<Vec<Row>> {
    let import = parse_urdf(ROBOT, "robots/robonaut/robonaut.urdf")?;
    let tree = &import.tree;
    let branches = detect_branches(tree, None)?;
    let nominal = McpcModel::from_tree(tree, &branches)?;
    let stiffness = parse_stiffness(STIFFNESS, "robots/robonaut/stiffness.yaml", tree, &nominal)?;
    let flexibility = FlexibilityModel::new(tree, &nominal, &stiffness)?;
    // The robot has no collision meshes, so this is the checker `treecal simulate` builds.
    let checker = CollisionChecker::new(tree)?;
    let setup = Setup {
        tree,
        branches: &branches,
        nominal: &nominal,
        truth_flexibility: &flexibility,
        model_flexibility: &flexibility,
        checker: Some(&checker),
    };
    let mut rows = Vec::new();
    for &poses in &args.poses {
        let mut quartiles = [[0.0; 3]; 2];
        for (planned, slot) in [false, true].into_iter().zip(&mut quartiles) {
            let options = SimulationOptions {
                poses,
                seed: args.seed,
                planning: planned.then(|| PlanningOptions {
                    candidates: args.candidates,
                    ..PlanningOptions::default()
                }),
                ..SimulationOptions::default()
            };
            let started = Instant::now();
            let reports = run_trials(&setup, &options, args.trials, &|| {})?;
            let mut errors: Vec<f64> = reports
                .iter()
                .map(|report| {
                    // Every arm is validated on the same number of configurations, so the mean
                    // of the arms' means is the mean over both arms.
                    let arms = &report.validation;
                    arms.iter()
                        .map(|arm| arm.compensated.mean_position_mm)
                        .sum::<f64>()
                        / arms.len() as f64
                })
                .collect();
            errors.sort_by(f64::total_cmp);
            *slot = [0.25, 0.5, 0.75].map(|q| quantile(&errors, q));
            eprintln!(
                "K = {poses:2}, {}: median {:.4} mm (quartiles {:.4}, {:.4}), {} trials in {:.1} s",
                if planned { "planned" } else { "random " },
                slot[1],
                slot[0],
                slot[2],
                args.trials,
                started.elapsed().as_secs_f64()
            );
        }
        rows.push(Row {
            poses,
            trials: args.trials,
            random: quartiles[0],
            planned: quartiles[1],
        });
    }
    Ok(rows)
}

/// The `q` quantile of sorted `values`, interpolated linearly between order statistics.
fn quantile(sorted: &[f64], q: f64) -> f64 {
    let at = q * (sorted.len() - 1) as f64;
    let (low, high) = (at.floor() as usize, at.ceil() as usize);
    sorted[low] + (sorted[high] - sorted[low]) * (at - low as f64)
}

const HEADER: &str = "poses,trials,random_q1_mm,random_median_mm,random_q3_mm,\
                      planned_q1_mm,planned_median_mm,planned_q3_mm";

fn csv(rows: &[Row], args: &Args) -> String {
    let mut text = format!(
        "# planning_sweep: seed {}, {} candidates; mean validation position error (mm) of the \
         compensated calibration, quartiles over trials\n{HEADER}\n",
        args.seed, args.candidates
    );
    for row in rows {
        let [r1, r2, r3] = row.random;
        let [p1, p2, p3] = row.planned;
        text.push_str(&format!(
            "{},{},{r1:.5},{r2:.5},{r3:.5},{p1:.5},{p2:.5},{p3:.5}\n",
            row.poses, row.trials
        ));
    }
    text
}

fn read_csv(path: &Path) -> Result<Vec<Row>> {
    let text = std::fs::read_to_string(path).map_err(|source| Error::Io {
        path: path.to_owned(),
        source,
    })?;
    let bad = |line: usize, message: String| Error::InvalidData {
        origin: format!("{}:{line}", path.display()),
        message,
    };
    text.lines()
        .enumerate()
        .filter(|(_, line)| !line.starts_with('#') && !line.starts_with("poses,"))
        .map(|(index, line)| {
            let fields: Vec<&str> = line.split(',').collect();
            if fields.len() != 8 {
                return Err(bad(index + 1, format!("{} fields, not 8", fields.len())));
            }
            let numbers = fields[2..]
                .iter()
                .map(|f| f.parse::<f64>())
                .collect::<std::result::Result<Vec<_>, _>>()
                .map_err(|e| bad(index + 1, e.to_string()))?;
            let count = |f: &str| {
                f.parse::<usize>()
                    .map_err(|e| bad(index + 1, e.to_string()))
            };
            Ok(Row {
                poses: count(fields[0])?,
                trials: count(fields[1])?,
                random: [numbers[0], numbers[1], numbers[2]],
                planned: [numbers[3], numbers[4], numbers[5]],
            })
        })
        .collect()
}

fn plot(rows: &[Row]) -> LinePlot {
    let curve = |label: &str, pick: fn(&Row) -> [f64; 3]| Curve {
        label: label.into(),
        values: rows.iter().map(|row| pick(row)[1]).collect(),
        spread: Some(
            rows.iter()
                .map(|row| (pick(row)[0], pick(row)[2]))
                .collect(),
        ),
    };
    let trials = rows.first().map_or(0, |row| row.trials);
    LinePlot {
        title: format!("Validation error vs arm poses K (median and quartiles of {trials} trials)"),
        x_label: "arm poses K".into(),
        y_label: "mean validation position error (mm)".into(),
        x: rows.iter().map(|row| row.poses as f64).collect(),
        curves: vec![
            curve("random poses", |row| row.random),
            curve("planned poses (O1)", |row| row.planned),
        ],
    }
}
