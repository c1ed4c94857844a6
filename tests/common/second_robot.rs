//! A simulated "second robot", shaped like the hidden data set of issue 28: a 7-DoF arm
//! (`tests/data/second_robot_arm.urdf`), motion-capture body poses (6-DoF) in one session of 48
//! postures plus two position-only sessions of 14 postures whose frames moved by about 8 mm and
//! 0.5°, series-elastic joints (gravity compliance, `tests/data/second_robot_stiffness.yaml`),
//! the measured body 138 mm beyond `arm_tool_link` (a link with child links), and one 57 mm
//! blunder. Seeded and deterministic; nothing read from `../shared`.
//!
//! Use [`second_robot`] for the data and the truth, [`SecondRobot::split`] for a 36/12
//! held-out split of the pose session, and [`SecondRobot::write_csv`] for CLI runs.

use super::{repo, rng};
use rand::seq::SliceRandom;
use rand::RngExt;
use std::path::{Path, PathBuf};
use treecal::kinematics::FlexibilityModel;
use treecal::math::{pose, Pose, Vec3};
use treecal::measurement::{Measurement, Observation};
use treecal::sim::{true_model, ErrorRanges};
use treecal::tree::KinematicTree;
use treecal::{detect_branches, load_urdf, McpcModel};

/// The measured tool link (it has child links: the gripper).
pub const TOOL: &str = "arm_tool_link";

/// Postures of the pose session, and of each position-only session.
pub const POSE_POSTURES: usize = 48;
/// Postures of each position-only session.
pub const POSITION_POSTURES: usize = 14;

/// Distance of the measured body beyond the tool link (m).
pub const BODY_OFFSET: f64 = 0.138;

/// The blunder's size (m).
pub const BLUNDER: f64 = 0.057;

/// Motion-capture noise: position (m) and rotation (rad) standard deviations.
pub const NOISE: [f64; 2] = [2e-4, 5e-4];

/// The session names, the pose session first.
pub const SESSIONS: [&str; 3] = ["day1_poses", "day2_points", "day3_points"];

/// The data and the truth they were made from.
pub struct SecondRobot {
    /// The URDF.
    pub urdf: PathBuf,
    /// The true stiffness (series-elastic joints).
    pub stiffness: PathBuf,
    /// The tree.
    pub tree: KinematicTree,
    /// The nominal MCPC model of the arm ending at [`TOOL`].
    pub nominal: McpcModel,
    /// The true geometry (tool: [`TOOL`] itself; the body is `tool_from_body` beyond it).
    pub truth: McpcModel,
    /// The measured body in the tool link's frame.
    pub tool_from_body: Pose,
    /// The robot base in the first session's motion-capture frame.
    pub world_from_base: Pose,
    /// Each session's frame in the first session's (the first: identity).
    pub session_from_first: [Pose; 3],
    /// Every row, session by session, labelled with its session.
    pub measurements: Vec<Measurement>,
    /// The rows' ids (`<session>-<posture>`).
    pub ids: Vec<String>,
    /// The index of the blunder row (in the pose session).
    pub blunder: usize,
}

/// The arm's files in `tests/data`.
fn data(name: &str) -> PathBuf {
    repo().join("tests/data").join(name)
}

/// A random posture within the joint limits (70 % of each range: away from the stops).
fn posture(tree: &KinematicTree, rng: &mut rand::rngs::ChaCha8Rng) -> Vec<f64> {
    tree.dofs()
        .iter()
        .map(|&j| {
            let limits = tree.joint(j).limits.expect("the arm's joints have limits");
            let (middle, half) = (
                0.5 * (limits.lower + limits.upper),
                0.35 * (limits.upper - limits.lower),
            );
            rng.random_range(middle - half..middle + half)
        })
        .collect()
}

/// A small random rigid motion: `translation` (m) and `angle` (rad) in random directions.
fn random_motion(rng: &mut rand::rngs::ChaCha8Rng, translation: f64, angle: f64) -> Pose {
    let direction = |rng: &mut rand::rngs::ChaCha8Rng| {
        Vec3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        )
        .normalize()
    };
    let t = direction(rng) * translation;
    let axis = direction(rng);
    pose(t, nalgebra::UnitQuaternion::from_scaled_axis(axis * angle))
}

/// Gaussian noise by Box–Muller (version-stable: only uniform draws).
fn gaussian(rng: &mut rand::rngs::ChaCha8Rng, sigma: f64) -> f64 {
    let (u, v): (f64, f64) = (rng.random_range(1e-12..1.0), rng.random_range(0.0..1.0));
    sigma * (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
}

/// The simulated second robot from `seed`.
pub fn second_robot(seed: u64) -> SecondRobot {
    let urdf = data("second_robot_arm.urdf");
    let stiffness_path = data("second_robot_stiffness.yaml");
    let tree = load_urdf(&urdf)
        .expect("the second robot's URDF loads")
        .tree;
    let tool = tree.link_id(TOOL).expect("tool link");
    let branches = detect_branches(&tree, Some(&[tool])).expect("branches");
    let nominal = McpcModel::from_tree(&tree, &branches).expect("model");
    let mut rng = rng(seed);
    // A well-made robot: errors of a few tenths of a degree and a couple of millimetres.
    let ranges = ErrorRanges {
        angle: 0.004,
        length: 0.002,
    };
    let truth = true_model(&nominal, &ranges, &mut rng).expect("truth");
    let text = std::fs::read_to_string(&stiffness_path).expect("stiffness file");
    let stiffness = treecal::io::parse_stiffness(&text, "second robot stiffness", &tree, &truth)
        .expect("stiffness parses");
    let flexibility = FlexibilityModel::new(&tree, &truth, &stiffness).expect("flexibility");
    // The body: 138 mm beyond the tool link, turned (a motion-capture body's own axes).
    let tool_from_body = pose(
        Vec3::new(0.011, -0.006, BODY_OFFSET),
        nalgebra::UnitQuaternion::from_euler_angles(0.02, -0.03, 1.2),
    );
    // A levelled motion-capture frame two metres away, turned about the vertical.
    let world_from_base = pose(
        Vec3::new(1.9, -0.7, 0.05),
        nalgebra::UnitQuaternion::from_euler_angles(0.0, 0.0, 0.6),
    );
    // The later days' frames: a few millimetres and about half a degree, turned about a point
    // at the robot (where the markers are), so that the rows move by 7–9 mm as on the real
    // robot, not by the lever arm of the camera system's origin.
    let about_robot = |motion: Pose| {
        let centre = pose(
            (world_from_base * nalgebra::Point3::new(0.05, -0.6, 1.0)).coords,
            nalgebra::UnitQuaternion::identity(),
        );
        centre * motion * centre.inverse()
    };
    let session_from_first = [
        Pose::identity(),
        about_robot(random_motion(&mut rng, 0.0065, 0.5f64.to_radians())),
        about_robot(random_motion(&mut rng, 0.006, 0.45f64.to_radians())),
    ];
    let poses: Vec<Vec<f64>> = (0..POSE_POSTURES)
        .map(|_| posture(&tree, &mut rng))
        .collect();
    // Day 2 repeats 14 postures of day 1; day 3 has new ones.
    let repeated: Vec<Vec<f64>> = poses[..POSITION_POSTURES].to_vec();
    let new: Vec<Vec<f64>> = (0..POSITION_POSTURES)
        .map(|_| posture(&tree, &mut rng))
        .collect();
    let mut measurements = Vec::new();
    let mut ids = Vec::new();
    for (session, postures) in [&poses, &repeated, &new].into_iter().enumerate() {
        for (k, q) in postures.iter().enumerate() {
            let bent = flexibility
                .deflected_tool_poses(&tree, &truth, q)
                .expect("deflected pose")[0];
            let body = session_from_first[session] * world_from_base * bent * tool_from_body;
            let noisy_position = body.translation.vector
                + Vec3::new(
                    gaussian(&mut rng, NOISE[0]),
                    gaussian(&mut rng, NOISE[0]),
                    gaussian(&mut rng, NOISE[0]),
                );
            let observation = if session == 0 {
                let turn = nalgebra::UnitQuaternion::from_scaled_axis(Vec3::new(
                    gaussian(&mut rng, NOISE[1]),
                    gaussian(&mut rng, NOISE[1]),
                    gaussian(&mut rng, NOISE[1]),
                ));
                Observation::Pose(pose(noisy_position, turn * body.rotation))
            } else {
                Observation::Position(noisy_position)
            };
            measurements.push(Measurement {
                tool: 0,
                q: q.clone(),
                observation,
                stage: None,
                payload: None,
                session: Some(SESSIONS[session].into()),
            });
            ids.push(format!("{}-{}", SESSIONS[session], k + 1));
        }
    }
    // One blunder in the pose session: the body 57 mm off.
    let blunder = 17;
    if let Observation::Pose(p) = &mut measurements[blunder].observation {
        p.translation.vector += Vec3::new(0.6, -0.48, 0.64).normalize() * BLUNDER;
    }
    SecondRobot {
        urdf,
        stiffness: stiffness_path,
        tree,
        nominal,
        truth,
        tool_from_body,
        world_from_base,
        session_from_first,
        measurements,
        ids,
        blunder,
    }
}

impl SecondRobot {
    /// A seeded 36/12 split of the pose session's postures: `(identification, validation)`
    /// as indices into [`Self::measurements`]; the position-only sessions are all in the
    /// identification set.
    pub fn split(&self, seed: u64) -> (Vec<usize>, Vec<usize>) {
        let mut postures: Vec<usize> = (0..POSE_POSTURES).collect();
        postures.shuffle(&mut rng(seed));
        let mut held = postures[..POSE_POSTURES / 4].to_vec();
        held.sort_unstable();
        let kept = (0..self.measurements.len())
            .filter(|i| !held.contains(i))
            .collect();
        (kept, held)
    }

    /// The rows at `indices`, without their session labels when `sessions` is false (as a
    /// user without a `session` column would give them).
    pub fn rows(&self, indices: &[usize], sessions: bool) -> Vec<Measurement> {
        indices
            .iter()
            .map(|&i| {
                let mut m = self.measurements[i].clone();
                if !sessions {
                    m.session = None;
                }
                m
            })
            .collect()
    }

    /// How far `session_from_first` moves the measured positions of session `s` (RMS, m).
    pub fn rows_moved(&self, s: usize, session_from_first: &Pose) -> f64 {
        let back = session_from_first.inverse();
        let moved: Vec<f64> = self
            .measurements
            .iter()
            .filter(|m| m.session.as_deref() == Some(SESSIONS[s]))
            .map(|m| {
                let p = match &m.observation {
                    Observation::Pose(p) => p.translation.vector,
                    Observation::Position(p) => *p,
                    Observation::Contact(_) => unreachable!("tracker rows only"),
                };
                (p - back.transform_point(&p.into()).coords).norm_squared()
            })
            .collect();
        (moved.iter().sum::<f64>() / moved.len() as f64).sqrt()
    }

    /// Every row with the pose session's rows reduced to the body's position (one observation
    /// layout for every row, as one CSV file needs).
    pub fn clone_rows_as_positions(&self) -> Vec<Measurement> {
        self.measurements
            .iter()
            .map(|m| match &m.observation {
                Observation::Pose(p) => Measurement {
                    observation: Observation::Position(p.translation.vector),
                    ..m.clone()
                },
                Observation::Position(_) | Observation::Contact(_) => m.clone(),
            })
            .collect()
    }

    /// Writes the rows at `indices` as a measurement CSV (`id,stage,tool,<joints>,x,y,z…`,
    /// `session` when labelled); poses and positions go to separate files, since one file
    /// holds one observation layout: returns the paths written (`<stem>_poses.csv`,
    /// `<stem>_points.csv`, each only when it has rows).
    pub fn write_csv(
        &self,
        indices: &[usize],
        sessions: bool,
        dir: &Path,
        stem: &str,
    ) -> Vec<PathBuf> {
        let rows = self.rows(indices, sessions);
        let mut written = Vec::new();
        for (suffix, poses) in [("poses", true), ("points", false)] {
            let part: Vec<(usize, Measurement)> = indices
                .iter()
                .zip(&rows)
                .filter(|(_, m)| matches!(m.observation, Observation::Pose(_)) == poses)
                .map(|(&i, m)| (i, m.clone()))
                .collect();
            if part.is_empty() {
                continue;
            }
            let data: Vec<Measurement> = part.iter().map(|(_, m)| m.clone()).collect();
            let text =
                treecal::io::measurements_to_csv(&self.tree, &self.nominal, &data).expect("CSV");
            // Keep the generator's ids (the writer numbers rows 1…).
            let mut lines: Vec<String> = text.lines().map(String::from).collect();
            for (line, (i, _)) in lines.iter_mut().skip(1).zip(&part) {
                if let Some(comma) = line.find(',') {
                    *line = format!("{}{}", self.ids[*i], &line[comma..]);
                }
            }
            let path = dir.join(format!("{stem}_{suffix}.csv"));
            std::fs::write(&path, lines.join("\n") + "\n").expect("write CSV");
            written.push(path);
        }
        written
    }
}
