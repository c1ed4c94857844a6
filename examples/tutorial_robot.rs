//! A stand-in for your robot and your tracker, for `docs/tutorial.md`: it "drives" a robot
//! whose true geometry is the URDF's with seeded errors (±1 mm, ±0.2°, the same robot for every
//! session) through a planned pose file, holding each pose 2 s and moving 2 s between poses,
//! and records what a real cell records: a joint-state log (100 Hz, the robot's clock) and one
//! tracker log per tool (a reflector at the tool origin, 120 Hz, in mm, in the tracker's own
//! frame, on the tracker's clock, which is 3.9 s behind plus a per-session few tenths, with
//! 20 µm noise and dropped samples).
//!
//! `cargo run --release --locked --example tutorial_robot -- --robot R.urdf --poses poses.csv
//! --out DIR [--session N]` writes `DIR/joints.csv` and `DIR/tracker_<tool>.csv`.

use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use rand_distr::{Distribution, Normal};
use std::fmt::Write;
use std::path::PathBuf;
use treecal::math::{pose, rotation_from_rpy, Vec3};
use treecal::tree::KinematicTree;
use treecal::{detect_branches, load_urdf, McpcModel};

const HOLD: f64 = 2.0;
const MOVE: f64 = 2.0;
const JOINT_RATE: f64 = 100.0;
const TRACKER_RATE: f64 = 120.0;
/// The robot's clock at the start (a Unix time) and the tracker's clock lag.
const JOINT_CLOCK_START: f64 = 1_700_000_000.0;
const TRACKER_LAG: f64 = 3.9;
/// The tracker's clock at the start, before its lag (its own seconds since it started).
const TRACKER_CLOCK_START: f64 = 50.0;

struct Args {
    robot: PathBuf,
    poses: PathBuf,
    out: PathBuf,
    session: u64,
}

fn args() -> Result<Args, String> {
    let mut words = std::env::args().skip(1);
    let (mut robot, mut poses, mut out, mut session) = (None, None, None, 1);
    while let Some(flag) = words.next() {
        let value = words
            .next()
            .ok_or_else(|| format!("{flag} needs a value"))?;
        match flag.as_str() {
            "--robot" => robot = Some(PathBuf::from(value)),
            "--poses" => poses = Some(PathBuf::from(value)),
            "--out" => out = Some(PathBuf::from(value)),
            "--session" => session = value.parse().map_err(|e| format!("--session: {e}"))?,
            other => return Err(format!("unknown flag {other}")),
        }
    }
    let usage = "usage: tutorial_robot --robot R.urdf --poses poses.csv --out DIR [--session N]";
    Ok(Args {
        robot: robot.ok_or(usage)?,
        poses: poses.ok_or(usage)?,
        out: out.ok_or(usage)?,
        session,
    })
}

/// The tools and the distinct configurations of a pose file (`treecal plan`'s: a `tool`
/// column, joint columns in rad and m, optional `stage`), in file order.
fn read_poses(text: &str, tree: &KinematicTree) -> Result<(Vec<String>, Vec<Vec<f64>>), String> {
    let mut lines = text
        .lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty());
    let header: Vec<&str> = lines.next().ok_or("empty pose file")?.split(',').collect();
    let tool_column = header.iter().position(|h| *h == "tool");
    let joints: Vec<(usize, usize)> = header
        .iter()
        .enumerate()
        .filter_map(|(c, name)| {
            let joint = tree.joint_id(name).ok()?;
            Some((c, tree.dof_of(joint)?.0))
        })
        .collect();
    let (mut tools, mut configurations) = (Vec::<String>::new(), Vec::<Vec<f64>>::new());
    for line in lines {
        let cells: Vec<&str> = line.split(',').collect();
        if let Some(tool) = tool_column.map(|c| cells[c].to_owned()) {
            if !tools.contains(&tool) {
                tools.push(tool);
            }
        }
        let mut q = tree.zero_configuration();
        for &(c, dof) in &joints {
            q[dof] = cells[c].parse().map_err(|e| format!("{line}: {e}"))?;
        }
        if configurations.last() != Some(&q) {
            configurations.push(q);
        }
    }
    Ok((tools, configurations))
}

/// The configuration at time `t` (s from the start): holds, and smooth moves between them.
fn configuration_at(configurations: &[Vec<f64>], t: f64) -> Vec<f64> {
    let period = HOLD + MOVE;
    let index = ((t / period).floor() as usize).min(configurations.len() - 1);
    let phase = t - index as f64 * period;
    let (from, to) = (&configurations[index], configurations.get(index + 1));
    match to {
        Some(to) if phase > HOLD => {
            let s = ((phase - HOLD) / MOVE).clamp(0.0, 1.0);
            let s = s * s * (3.0 - 2.0 * s);
            from.iter().zip(to).map(|(a, b)| a + s * (b - a)).collect()
        }
        _ => from.clone(),
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args = args()?;
    let tree = load_urdf(&args.robot)?.tree;
    let (tools, configurations) = read_poses(&std::fs::read_to_string(&args.poses)?, &tree)?;
    let tool_links = tools
        .iter()
        .map(|t| tree.link_id(t))
        .collect::<Result<Vec<_>, _>>()?;
    let nominal =
        McpcModel::from_tree(&tree, &detect_branches(&tree, Some(tool_links.as_slice()))?)?;
    // The true robot: the same for every session (seed 23).
    let mut truth = nominal.clone();
    let mut rng = ChaCha8Rng::seed_from_u64(23);
    let layout = nominal.parameter_layout();
    let values: Vec<f64> = nominal
        .parameters()
        .iter()
        .zip(&layout)
        .map(|(v, (_, kind))| {
            let range = if kind.is_angle() {
                0.2f64.to_radians()
            } else {
                1e-3
            };
            v + rng.random_range(-range..range)
        })
        .collect();
    truth.set_parameters(&values)?;
    let tracker_from_base = pose(Vec3::new(2.4, -0.6, 0.3), rotation_from_rpy(0.0, 0.0, 2.1));
    truth.set_world_from_base(&tracker_from_base);
    let mut rng = ChaCha8Rng::seed_from_u64(1000 + args.session);
    let lag = TRACKER_LAG + 0.1 * args.session as f64;
    let duration = configurations.len() as f64 * (HOLD + MOVE);
    std::fs::create_dir_all(&args.out)?;

    let names: Vec<&str> = tree
        .dofs()
        .iter()
        .map(|&j| tree.joint(j).name.as_str())
        .collect();
    let mut joints = format!("time,{}\n", names.join(","));
    let steps = (duration * JOINT_RATE) as usize;
    for step in 0..=steps {
        let t = step as f64 / JOINT_RATE;
        let q = configuration_at(&configurations, t);
        let _ = write!(joints, "{:.4}", JOINT_CLOCK_START + t);
        for v in q {
            let _ = write!(joints, ",{v:.9}");
        }
        joints.push('\n');
    }
    std::fs::write(args.out.join("joints.csv"), joints)?;

    let noise = Normal::new(0.0, 20e-6)?;
    for (tool, &link) in tools.iter().zip(&tool_links) {
        let index = truth
            .tool_of_link(link)
            .ok_or("a tool is not in the model")?;
        let mut log = String::from("# units: length=mm\ntime,x,y,z\n");
        let samples = (duration * TRACKER_RATE) as usize;
        for sample in 0..=samples {
            let t = sample as f64 / TRACKER_RATE;
            // About 2 % of the samples are lost (the reflector not seen).
            if rng.random::<f64>() < 0.02 {
                continue;
            }
            let q = configuration_at(&configurations, t);
            let point = truth.tool_pose(index, &q).translation.vector;
            let _ = write!(log, "{:.4}", t + TRACKER_CLOCK_START - lag);
            for coordinate in point.iter() {
                let _ = write!(log, ",{:.4}", (coordinate + noise.sample(&mut rng)) * 1e3);
            }
            log.push('\n');
        }
        std::fs::write(args.out.join(format!("tracker_{tool}.csv")), log)?;
    }
    eprintln!(
        "tutorial_robot: {} poses, {:.0} s, logs in {} (tools: {})",
        configurations.len(),
        duration,
        args.out.display(),
        tools.join(", ")
    );
    Ok(())
}
