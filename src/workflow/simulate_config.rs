//! The settings of `simulate` and what it found: shared by the tracker experiment
//! (`simulate`), the camera and the contact simulations, so it sits below all three.

use super::source::{PlanSource, RobotSource, StiffnessSource};
use super::Note;
use crate::calibration::RobustLoss;
use crate::error::Result;
use crate::sim::{CollisionCheck, SimulationSummary, TrialReport};
use std::path::PathBuf;

/// Where the identification configurations come from.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum PosesFrom {
    /// Uniform random collision-free configurations.
    #[default]
    Random,
    /// Planned (O1, greedy + DETMAX) from `candidates` random ones, with the nominal model.
    Planned,
}

/// The layout of the simulated measurements CSV ([`Simulation::measurements_csv`]).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum MeasurementFormat {
    /// Poses (or positions), metres and radians.
    #[default]
    Si,
    /// Three targets A, B, C per tool in mm, joints in deg (needs three targets).
    Tracker,
}

/// What the simulated calibration observes (`--observation`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum ObservationChoice {
    /// The paper's experiment: a tracker, gravity loads, the staged plan.
    #[default]
    Tracker,
    /// A camera on the coupled branch's last link seeing boards on the tools and in the world
    /// (`crate::sim::camera`; rigid robot).
    Camera,
    /// The camera and the tracker together, each with its own σ.
    Mixed,
    /// The tracker alone at the camera simulation's configurations (rigid robot): the
    /// comparison row.
    RigidTracker,
}

/// Settings of [`simulate`](fn@super::simulate::simulate); `Default` is `treecal simulate` without flags.
#[derive(Debug, Clone)]
pub struct SimulateConfig {
    /// The robot.
    pub robot: RobotSource,
    /// Folders searched for `package://` collision meshes, before `ROS_PACKAGE_PATH`.
    pub package_paths: Vec<PathBuf>,
    /// Which collision shapes the configurations are checked against (stated in summary.md).
    pub collision_check: CollisionCheck,
    /// The stiffness [default: the built-in Robonaut's; required with another robot].
    pub stiffness: Option<StiffnessSource>,
    /// Tool links ending the arms [default: detected].
    pub tools: Option<Vec<String>>,
    /// The link fixed in the world while measuring (a sole, a mobile base) [default: the root].
    pub reference_link: Option<String>,
    /// Configurations measured for the arms.
    pub poses: usize,
    /// Configurations measured for the torso with the arms locked.
    pub torso_poses: usize,
    /// Separate configurations the results are validated on.
    pub validation_poses: usize,
    /// Simulated calibrations, each with a new true robot.
    pub trials: usize,
    /// Master seed.
    pub seed: u64,
    /// Tracker noise: `0`, `at901` or `CONSTANT+PER_METRE` in µm.
    pub noise: String,
    /// The robust loss of both calibrations.
    pub robust: RobustLoss,
    /// Fraction of the measurements turned into blunders.
    pub outliers: f64,
    /// How far a blunder moves its target (mm).
    pub outlier_size_mm: f64,
    /// Targets per tool: 3 (a frame) or 1 (a position).
    pub targets: u8,
    /// The calibration plan (`Auto` is staged: the simulated rows are labelled).
    pub plan: PlanSource,
    /// Half-width of the true robot's angle errors (rad).
    pub angle_error: f64,
    /// Half-width of the true robot's length errors (m).
    pub length_error: f64,
    /// Half-width of the true robot's first-harmonic joint-angle errors (rad; 0: none).
    pub truth_harmonics: f64,
    /// Largest half dead band of the true robot's backlash (rad; 0: none).
    pub truth_backlash: f64,
    /// Payload at every tool (kg), overriding the stiffness file.
    pub payload: Option<f64>,
    /// Payloads (kg at every tool) the identification poses are measured at, in turn (empty:
    /// the stiffness file's).
    pub payloads: Vec<f64>,
    /// Bending and torsion stiffness of every joint (N·m/rad), overriding the stiffness file.
    pub joint_stiffness: Option<f64>,
    /// Stiffness the compensating model assumes, relative to the truth's.
    pub model_stiffness_scale: f64,
    /// Identify the compliances jointly with the geometry in the compensated calibration.
    pub identify_stiffness: bool,
    /// Where the identification configurations come from.
    pub poses_from: PosesFrom,
    /// Candidates each planned pose set is chosen from (`PosesFrom::Planned`).
    pub candidates: usize,
    /// The layout of trial 1's measurements CSV, if wanted.
    pub measurement_format: Option<MeasurementFormat>,
    /// What is observed.
    pub observation: ObservationChoice,
    /// The camera's link (camera observations) [default: the coupled branch's last link].
    pub camera_link: Option<String>,
    /// Pixel noise σ of a detected corner (px).
    pub pixel_sigma: f64,
    /// Whether a board stands in the world in front of the robot (camera observations).
    pub world_board: bool,
    /// Whether the camera's intrinsics are estimated with the robot.
    pub estimate_intrinsics: bool,
    /// Contacts to simulate (`docs/contacts.md`), `poses + torso_poses` configurations per kind:
    /// alone with `Tracker`, else fitted with the camera simulation's observations.
    pub contacts: Vec<crate::sim::ContactChoice>,
    /// σ of the encoder noise on the recorded configurations of a contact simulation (rad).
    pub encoder_noise: f64,
    /// Flush contacts: tables (sessions, one plane each) and tools pressing on each (1 or 2).
    pub contact_tables: (usize, usize),
    /// Contacts with the tracker (`--observation flush,tracker`): trial 1's tracker.csv of
    /// the contact tools is written beside its contact files, the setup's σ's those of the
    /// simulated encoder noise.
    pub contact_tracker: bool,
}

impl Default for SimulateConfig {
    fn default() -> Self {
        Self {
            robot: RobotSource::BuiltIn,
            package_paths: Vec::new(),
            collision_check: CollisionCheck::Meshes,
            stiffness: None,
            tools: None,
            reference_link: None,
            poses: 20,
            torso_poses: 10,
            validation_poses: 20,
            trials: 1,
            seed: 0,
            noise: "at901".into(),
            robust: RobustLoss::Huber,
            outliers: 0.0,
            outlier_size_mm: 50.0,
            targets: 3,
            plan: PlanSource::Auto,
            angle_error: 0.05,
            length_error: 0.05,
            truth_harmonics: 0.0,
            truth_backlash: 0.0,
            payload: None,
            payloads: Vec::new(),
            joint_stiffness: None,
            model_stiffness_scale: 1.0,
            identify_stiffness: false,
            poses_from: PosesFrom::Random,
            candidates: 2000,
            measurement_format: None,
            observation: ObservationChoice::Tracker,
            camera_link: None,
            pixel_sigma: 0.5,
            world_board: true,
            estimate_intrinsics: false,
            contacts: Vec::new(),
            encoder_noise: 0.0,
            contact_tables: (1, 1),
            contact_tracker: false,
        }
    }
}

/// What [`simulate`](fn@super::simulate::simulate) found.
#[derive(Debug, Clone)]
pub struct Simulation {
    /// What the CLI prints on stderr, in order.
    pub notes: Vec<Note>,
    /// Every trial.
    pub reports: Vec<TrialReport>,
    /// Mean ± standard deviation over the trials.
    pub summary: SimulationSummary,
    /// results.json's content.
    pub results: serde_json::Value,
    /// summary.md (also what the CLI prints on stdout).
    pub markdown: String,
    /// Every file written into the output folder (name, bytes).
    pub files: Vec<(String, Vec<u8>)>,
    /// Trial 1's simulated measurements as CSV, when asked for.
    pub measurements_csv: Option<String>,
    /// Every trial of a camera simulation (empty for the tracker experiment, whose trials are
    /// `reports`).
    pub camera_reports: Vec<crate::sim::CameraTrialReport>,
}

impl Simulation {
    /// A simulation without tracker trials (camera, contacts): summary.md and results.json
    /// are its files, `camera_reports` its trials (empty for contacts).
    pub(super) fn without_tracker_trials(
        notes: Vec<Note>,
        results: serde_json::Value,
        markdown: String,
        camera_reports: Vec<crate::sim::CameraTrialReport>,
    ) -> Result<Self> {
        let files = vec![
            ("summary.md".to_owned(), markdown.clone().into_bytes()),
            (
                "results.json".to_owned(),
                crate::io::to_json_rows(&results)?.into_bytes(),
            ),
        ];
        Ok(Simulation {
            notes,
            reports: Vec::new(),
            summary: crate::sim::summarise(&[]),
            results,
            markdown,
            files,
            measurements_csv: None,
            camera_reports,
        })
    }
}
