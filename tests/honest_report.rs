//! Issue 28 (items 1, 2, 3, 5, 9): what `calibrate` reports is what the user gets, on
//! simulated truth. "Before" is the registered nominal robot; every validation row counts, by
//! stratum; the written URDF (with the written registration, and with its compensation file)
//! is scored as written; a fitted frame says what it cannot see; σ̂ ≫ 1 says how many mm the
//! model leaves unexplained.

use crate::common::*;
use nalgebra::{UnitQuaternion, Vector3};
use rand::rngs::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use serde_json::Value;
use treecal::calibration::{
    run_calibration, CalibrationInput, CalibrationRun, IdentificationOptions, MeasurementFrame,
    Plan,
};
use treecal::calibration::{strata, Stratum};
use treecal::io::{
    measurements_to_csv_with, parse_registration, read_stiffness, AngleUnit, LengthUnit,
    MeasurementWriteOptions,
};
use treecal::kinematics::FlexibilityModel;
use treecal::math::Pose;
use treecal::measurement::{Measurement, Observation};
use treecal::sim::{true_model, ErrorRanges};
use treecal::urdf::parse_urdf;
use treecal::workflow::{
    calibrate, CalibrateConfig, MeasurementFrameChoice, MeasurementSource, RobotSource,
    StiffnessSource,
};
use treecal::{Branches, KinematicTree, McpcModel};

const NOISE: f64 = 3e-5;
const ROTATION_NOISE: f64 = 3e-4;

struct Scene {
    tree: KinematicTree,
    branches: Branches,
    nominal: McpcModel,
    truth: McpcModel,
    rng: ChaCha8Rng,
}

/// A tracker 2.4 m from the robot, turned about all three axes.
fn tracker() -> Pose {
    Pose::from_parts(
        nalgebra::Translation3::new(2.1, -0.9, 0.7),
        UnitQuaternion::from_euler_angles(0.12, -0.08, 2.3),
    )
}

/// Robonaut with `errors`× the paper's errors (0: none), seen from `world_from_base`.
fn scene(seed: u64, errors: f64, world_from_base: &Pose) -> Scene {
    let crate::common::TestRobot {
        tree,
        branches,
        model: nominal,
    } = crate::common::TestRobot::robonaut();
    let mut rng = rng(seed);
    let ranges = ErrorRanges {
        angle: errors * ErrorRanges::default().angle,
        length: errors * ErrorRanges::default().length,
    };
    let mut truth = if errors > 0.0 {
        true_model(&nominal, &ranges, &mut rng).unwrap()
    } else {
        nominal.clone()
    };
    truth.set_world_from_base(world_from_base);
    Scene {
        tree,
        branches,
        nominal,
        truth,
        rng,
    }
}

/// Every tool at `count` random configurations, full poses with `scale`× the test noise;
/// `poses` gives the true tool poses at a configuration.
fn measure(
    scene: &mut Scene,
    count: usize,
    scale: f64,
    poses: &dyn Fn(&Scene, &[f64]) -> Vec<Pose>,
) -> Vec<Measurement> {
    let position = Normal::new(0.0, NOISE * scale).unwrap();
    let rotation = Normal::new(0.0, ROTATION_NOISE * scale).unwrap();
    let mut out = Vec::new();
    for _ in 0..count {
        let q = random_configuration(&scene.tree, &mut scene.rng);
        for (tool, pose) in poses(scene, &q).iter().enumerate() {
            let rng = &mut scene.rng;
            let mut draw =
                |d: &Normal<f64>| Vector3::new(d.sample(rng), d.sample(rng), d.sample(rng));
            let (dp, dr) = (draw(&position), draw(&rotation));
            out.push(Measurement {
                payload: None,
                tool,
                q: q.clone(),
                observation: Observation::Pose(Pose::from_parts(
                    (pose.translation.vector + dp).into(),
                    UnitQuaternion::from_scaled_axis(dr) * pose.rotation,
                )),
                stage: None,
                session: None,
            });
        }
    }
    out
}

fn rigid(scene: &Scene, q: &[f64]) -> Vec<Pose> {
    scene.truth.tool_poses(q)
}

fn run(
    scene: &Scene,
    frame: MeasurementFrame,
    data: &[Measurement],
    validation: &[Measurement],
) -> CalibrationRun {
    let options = IdentificationOptions {
        position_sigma: NOISE,
        rotation_sigma: ROTATION_NOISE,
        ..Default::default()
    };
    let plan = Plan::simultaneous();
    let input = CalibrationInput {
        tree: &scene.tree,
        branches: &scene.branches,
        nominal: &scene.nominal,
        flexibility: None,
        plan: &plan,
        options: &options,
        measurement_frame: frame,
        diagnose_columns: true,
    };
    run_calibration(&input, data, validation).unwrap_or_else(|e| panic!("{e}"))
}

/// RMS position error (mm) of `model`'s rigid prediction over `data`.
fn rms_mm(model: &McpcModel, data: &[Measurement]) -> f64 {
    let sum: f64 = data
        .iter()
        .map(|m| {
            let measured = match &m.observation {
                Observation::Pose(pose) => pose.translation.vector,
                Observation::Position(p) => *p,
                Observation::Contact(_) => unreachable!("tracker rows only"),
            };
            let p = model.tool_poses(&m.q)[m.tool].translation.vector;
            (measured - p).norm_squared()
        })
        .sum();
    (sum / data.len() as f64).sqrt() * 1e3
}

/// RMS over every row of a data set's arms, before (0) or after (1).
fn arms_rms(arms: &[treecal::calibration::ArmResiduals], k: usize) -> f64 {
    let values: Vec<f64> = arms.iter().flat_map(|a| a.position_mm[k].clone()).collect();
    (values.iter().map(|v| v * v).sum::<f64>() / values.len() as f64).sqrt()
}

/// Item 1: "before" is the nominal robot with the measurement frame and tools fitted by least
/// squares: never worse than the closed-form start on the identification rows, not worse on
/// validation, and at the noise when the robot is the nominal one.
#[test]
fn before_is_the_registered_nominal_robot() {
    // Positions: the registration's objective is the position error alone.
    let points = |data: Vec<Measurement>| -> Vec<Measurement> {
        data.into_iter()
            .map(|m| match m.observation {
                Observation::Pose(pose) => Measurement {
                    observation: Observation::Position(pose.translation.vector),
                    ..m
                },
                Observation::Position(_) | Observation::Contact(_) => m,
            })
            .collect()
    };
    let mut s = scene(2801, 1.0, &tracker());
    let data = points(measure(&mut s, 30, 1.0, &rigid));
    let validation = points(measure(&mut s, 12, 1.0, &rigid));
    let result = run(&s, MeasurementFrame::Fit, &data, &validation);
    let closed_form = [
        rms_mm(&result.guess.model, &data),
        rms_mm(&result.guess.model, &validation),
    ];
    let registered = [
        arms_rms(&result.identification, 0),
        arms_rms(&result.validation, 0),
    ];
    assert!(
        registered[0] <= closed_form[0] + 1e-9,
        "{registered:?} vs {closed_form:?}"
    );
    assert!(
        registered[1] <= closed_form[1] * 1.05,
        "{registered:?} vs {closed_form:?}"
    );
    assert!(arms_rms(&result.validation, 1) < 0.2 * registered[1]);
    // The baseline is a registration: same joint frames as the URDF.
    let nominal = s.nominal.parameters();
    let baseline = result.baseline.parameters();
    for (i, (a, b)) in nominal.iter().zip(&baseline).enumerate() {
        let owner = result.baseline.parameter_layout()[i].0;
        if matches!(owner, treecal::kinematics::ParameterOwner::Frame(_)) {
            assert_eq!(a, b, "joint frame parameter {i} moved");
        }
    }

    // A robot that is exactly nominal, seen from a tracker: the registration finds it, and
    // "before" is at the noise (√3·σ per point), where the closed form is not.
    let mut s = scene(2802, 0.0, &tracker());
    let data = measure(&mut s, 30, 1.0, &rigid);
    let validation = measure(&mut s, 12, 1.0, &rigid);
    let result = run(&s, MeasurementFrame::Fit, &data, &validation);
    let before = arms_rms(&result.validation, 0);
    assert!(before < 3.0 * NOISE * 1e3 * 3f64.sqrt(), "{before} mm");
}

/// Item 2: every validation row falls in one stratum, judged on its tool's chain: a repeated
/// posture, a new one inside the identification ranges, one outside.
#[test]
fn validation_rows_are_stratified() {
    let mut s = scene(2803, 1.0, &Pose::identity());
    let data = measure(&mut s, 20, 1.0, &rigid);
    let mut validation: Vec<Measurement> = data[..4].to_vec();
    // A repeat within a hair of noise on every joint.
    for m in &mut validation {
        for v in &mut m.q {
            *v += 1e-4;
        }
    }
    // Between two identification postures: inside.
    let mut inside = data[0].clone();
    for (v, w) in inside.q.iter_mut().zip(&data[data.len() - 1].q) {
        *v = 0.5 * (*v + w);
    }
    validation.push(inside);
    // One joint of the first tool's chain beyond everything measured: outside.
    let mut outside = data[0].clone();
    let chain = s.nominal.tool_chain(outside.tool).to_vec();
    let frame = &s.nominal.frames()[*chain.last().unwrap()];
    let treecal::tree::Actuation::Independent(dof) = frame.actuation else {
        panic!("the last joint is independent")
    };
    let highest = data.iter().map(|m| m.q[dof.0]).fold(f64::MIN, f64::max);
    outside.q[dof.0] = highest + 0.3;
    validation.push(outside);
    let found = strata(&s.nominal, &data, &validation);
    assert_eq!(
        found,
        [
            Stratum::Repeat,
            Stratum::Repeat,
            Stratum::Repeat,
            Stratum::Repeat,
            Stratum::Inside,
            Stratum::Outside
        ]
    );
}

/// Item 9: with noise 30× what is declared, the σ̂ warning says how many mm the model leaves
/// unexplained and points to --cv / --model auto; the accuracy to trust is the validation RMS.
#[test]
fn a_large_sigma_ratio_says_how_much_is_unexplained() {
    let mut s = scene(2804, 1.0, &Pose::identity());
    let data = measure(&mut s, 30, 30.0, &rigid);
    let validation = measure(&mut s, 8, 30.0, &rigid);
    let result = run(&s, MeasurementFrame::Base, &data, &validation);
    let finding = result
        .findings
        .iter()
        .find(|f| f.code == "sigma-ratio")
        .expect("a sigma-ratio warning");
    let id = &result.report.stages[0].identification;
    let unexplained =
        treecal::calibration::unexplained_mm(id.residual_rms_position, id.residual_scale);
    assert!(unexplained > 0.9 * id.residual_rms_position * 1e3);
    assert!(
        finding
            .message
            .contains(&format!("about {unexplained:.4} mm RMS unexplained"))
            && finding.message.contains("`cv`")
            && finding.message.contains("`model` auto")
            && finding.message.contains("validation RMS in mm"),
        "{}",
        finding.message
    );
    assert!(result
        .findings
        .iter()
        .all(|f| !f.code.ends_with("joint-columns")));
    // Clean data: no such warning.
    let mut s = scene(2804, 1.0, &Pose::identity());
    let data = measure(&mut s, 30, 1.0, &rigid);
    let result = run(&s, MeasurementFrame::Base, &data, &[]);
    assert!(result.findings.iter().all(|f| f.code != "sigma-ratio"));
}

/// Writes `data` as a tracker CSV (mm, rad) in `dir`.
fn csv(
    scene: &Scene,
    dir: &std::path::Path,
    name: &str,
    data: &[Measurement],
) -> std::path::PathBuf {
    let options = MeasurementWriteOptions {
        length_unit: LengthUnit::Millimetre,
        angle_unit: AngleUnit::Radian,
        three_targets: false,
    };
    let text = measurements_to_csv_with(&scene.tree, &scene.nominal, data, &options).unwrap();
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

/// RMS position error (mm) of the URDF text `urdf` placed at `world_from_base`, straight from
/// its links (the reference forward kinematics, no MCPC) of the tool links `links`.
fn rescore(urdf: &str, world_from_base: &Pose, links: &[String], data: &[Measurement]) -> f64 {
    let tree = parse_urdf(urdf, "calibrated.urdf").unwrap().tree;
    let sum: f64 = data
        .iter()
        .map(|m| {
            let Observation::Pose(measured) = &m.observation else {
                unreachable!()
            };
            let link = tree.link_id(&links[m.tool]).unwrap();
            let p = (world_from_base * tree.link_pose(link, &m.q).unwrap())
                .translation
                .vector;
            (measured.translation.vector - p).norm_squared()
        })
        .sum();
    (sum / data.len() as f64).sqrt() * 1e3
}

/// The Robonaut URDF with `data` and `validation` written as CSVs in `dir`, the scene's noise
/// declared (the rest default).
fn robonaut_files(
    s: &Scene,
    dir: &std::path::Path,
    data: &[Measurement],
    validation: &[Measurement],
) -> CalibrateConfig {
    CalibrateConfig {
        robot: RobotSource::File(robot("robonaut/robonaut.urdf")),
        measurements: MeasurementSource::Csv(csv(s, dir, "data.csv", data)),
        validation: Some(MeasurementSource::Csv(csv(
            s,
            dir,
            "validation.csv",
            validation,
        ))),
        position_sigma: NOISE,
        rotation_sigma: ROTATION_NOISE,
        ..CalibrateConfig::default()
    }
}

/// The written calibrated.urdf and the frame of the written registration.yaml.
fn written_urdf_and_registration(files: &[(String, Vec<u8>)]) -> (&str, Pose) {
    let urdf = file(files, "calibrated.urdf").expect("calibrated.urdf");
    let registration = file(files, "registration.yaml").expect("registration.yaml");
    let frame = parse_registration(registration, "registration.yaml").unwrap();
    (urdf, frame)
}

/// The names of the scene's tool links.
fn tool_links(s: &Scene) -> Vec<String> {
    s.nominal
        .tools()
        .iter()
        .map(|t| s.tree.link(t.link).name.clone())
        .collect()
}

fn file<'a>(files: &'a [(String, Vec<u8>)], name: &str) -> Option<&'a str> {
    files
        .iter()
        .find(|(n, _)| n == name)
        .map(|(_, b)| std::str::from_utf8(b).unwrap())
}

fn number(value: &Value) -> f64 {
    value
        .as_f64()
        .unwrap_or_else(|| panic!("not a number: {value}"))
}

/// Items 3 and 5: tracker-frame data. report.json's URDF-alone figure is the written
/// calibrated.urdf with the written registration.yaml, scored again here from the text; it
/// equals the validation figures; the verdict notes the unobservable base and names the
/// registration; clean data raise none of the new alarms.
#[test]
fn the_written_urdf_and_registration_are_what_was_validated() {
    let mut s = scene(2805, 1.0, &tracker());
    let data = measure(&mut s, 30, 1.0, &rigid);
    let validation = measure(&mut s, 12, 1.0, &rigid);
    let dir = tempfile::tempdir().unwrap();
    let config = CalibrateConfig {
        ..robonaut_files(&s, dir.path(), &data, &validation)
    };
    let outcome = calibrate(&config).unwrap_or_else(|e| panic!("{e}"));
    let report = &outcome.report();
    assert!(outcome.usable(), "{:?}", outcome.verdict);
    let codes: Vec<&str> = outcome
        .verdict
        .reasons
        .iter()
        .map(|r| r.code.as_str())
        .collect();
    for alarm in [
        "urdf-alone-worse",
        "down-weighted",
        "outliers",
        "validation-worse",
    ] {
        assert!(!codes.contains(&alarm), "{codes:?}");
    }
    let (urdf, frame) = written_urdf_and_registration(&outcome.files);
    let links = tool_links(&s);
    let again = rescore(urdf, &frame, &links, &validation);
    let artifact = &report["artifact"];
    let alone = number(&artifact["urdf_alone"]["errors"]["rms_position_mm"]);
    assert!(
        (alone - again).abs() < 1e-9 * again.max(1.0),
        "{alone} vs {again}"
    );
    assert_eq!(
        artifact["urdf_alone"]["files"],
        "calibrated.urdf + registration.yaml"
    );
    assert_eq!(
        artifact["urdf_alone"]["observations"].as_u64(),
        Some(validation.len() as u64)
    );
    let all = &report["validation_strata"]["strata"][0];
    assert_eq!(all["stratum"], "all");
    assert!(
        (number(&all["rms_position_mm"]) - again).abs() < 1e-6 * again,
        "{all}"
    );
    let counted: u64 = report["validation_strata"]["strata"].as_array().unwrap()[1..]
        .iter()
        .map(|s| s["observations"].as_u64().unwrap())
        .sum();
    assert_eq!(counted, validation.len() as u64);
    // The fair before is the registered nominal robot, reported with the artifact.
    let before = number(&artifact["registered_nominal"]["errors"]["rms_position_mm"]);
    assert!(alone < 0.2 * before, "{alone} vs {before}");
    // The unobservable base: named, sized, and the registration file named.
    let note = outcome
        .verdict
        .reasons
        .iter()
        .find(|r| r.code == "unobservable-base")
        .expect("an unobservable-base note");
    assert!(
        note.message.contains("registration.yaml") && note.message.contains("cannot be seen"),
        "{}",
        note.message
    );
    let base = &artifact["unobservable_base"];
    assert!(number(&base["tool_shift_mm"]["max"]) >= number(&base["tool_shift_mm"]["min"]));
    assert!(outcome.report_markdown.contains("## What the outputs give"));
}

/// Item 3 with compensation: a robot that bends under gravity and is otherwise nominal. The
/// compensated geometry is nearly the nominal one, so used alone it is worse than the
/// registered nominal robot: calibrated.urdf then holds the rigid-only geometry (no worse than
/// the nominal robot), and calibrated_compensated.urdf + the stiffness file is scored as
/// written and reproduces the compensated validation figure.
#[test]
fn a_compensated_geometry_is_never_shipped_alone_when_worse_than_nominal() {
    let mut s = scene(2806, 0.0, &Pose::identity());
    let stiffness_path = robot("robonaut/stiffness.yaml");
    let stiffness = read_stiffness(&stiffness_path, &s.tree, &s.nominal).unwrap();
    let flexibility = FlexibilityModel::new(&s.tree, &s.truth, &stiffness).unwrap();
    let bent = move |scene: &Scene, q: &[f64]| -> Vec<Pose> {
        flexibility
            .deflected_tool_poses(&scene.tree, &scene.truth, q)
            .unwrap()
    };
    let data = measure(&mut s, 30, 1.0, &bent);
    let validation = measure(&mut s, 12, 1.0, &bent);
    let dir = tempfile::tempdir().unwrap();
    let config = CalibrateConfig {
        stiffness: Some(StiffnessSource::File(stiffness_path)),
        measurement_frame: MeasurementFrameChoice::Base,
        ..robonaut_files(&s, dir.path(), &data, &validation)
    };
    let outcome = calibrate(&config).unwrap_or_else(|e| panic!("{e}"));
    assert!(outcome.usable(), "{:?}", outcome.verdict);
    let report = outcome.report();
    let artifact = &report["artifact"];
    let rms = |key: &str| number(&artifact[key]["errors"]["rms_position_mm"]);
    let (alone, compensated, before) = (
        rms("urdf_alone"),
        rms("with_compensation"),
        rms("registered_nominal"),
    );
    assert!(alone <= before, "{alone} vs {before}");
    assert!(compensated < 0.2 * alone, "{compensated} vs {alone}");
    let codes: Vec<&str> = outcome
        .verdict
        .reasons
        .iter()
        .map(|r| r.code.as_str())
        .collect();
    assert!(codes.contains(&"rigid-only-urdf"), "{codes:?}");
    assert!(!codes.contains(&"urdf-alone-worse"), "{codes:?}");
    assert!(file(&outcome.files, "calibrated_compensated.urdf").is_some());
    assert_eq!(
        artifact["with_compensation"]["files"].as_str().unwrap(),
        format!(
            "calibrated_compensated.urdf + {}",
            robot("robonaut/stiffness.yaml").display()
        )
    );
    // The headline names both written artifacts and their figures.
    let md = file(&outcome.files, "report.md").unwrap();
    let headline = md
        .lines()
        .find(|l| l.starts_with("**Held-out accuracy:**"))
        .unwrap();
    assert!(
        headline.contains("; calibrated.urdf as written: ")
            && headline.contains("; calibrated_compensated.urdf + "),
        "{headline}"
    );
    // calibrated.urdf alone, scored again from its text.
    let links: Vec<String> = s
        .nominal
        .tools()
        .iter()
        .map(|t| s.tree.link(t.link).name.clone())
        .collect();
    let urdf = file(&outcome.files, "calibrated.urdf").unwrap();
    let again = rescore(urdf, &Pose::identity(), &links, &validation);
    assert!(
        (alone - again).abs() < 1e-9 * again.max(1.0),
        "{alone} vs {again}"
    );
    // The compensated prediction reported per row is the compensated pair as written.
    let in_memory = number(&report["validation_strata"]["strata"][0]["rms_position_mm"]);
    assert!(
        (in_memory - compensated).abs() < 1e-6 * compensated,
        "{in_memory} vs {compensated}"
    );
}

/// Item 11: two joint columns swapped in the CSV. The root cause is named by joint, and the
/// σ̂ finding it causes is marked as its probable consequence, not separate advice. Noise far
/// above the declared one (the σ̂ test above) names no columns.
#[test]
fn swapped_joint_columns_are_named_and_their_consequences_marked() {
    let mut s = scene(2807, 0.04, &Pose::identity());
    let mut data = measure(&mut s, 30, 1.0, &rigid);
    let chain: Vec<usize> = s
        .nominal
        .tool_chain(0)
        .iter()
        .filter_map(|&f| match s.nominal.frames()[f].actuation {
            treecal::tree::Actuation::Independent(dof) => Some(dof.0),
            _ => None,
        })
        .collect();
    let (a, b) = (chain[chain.len() - 4], chain[chain.len() - 2]);
    for m in &mut data {
        m.q.swap(a, b);
    }
    let result = run(&s, MeasurementFrame::Base, &data, &[]);
    let name = |dof: usize| s.tree.joint(s.tree.dofs()[dof]).name.clone();
    let cause = result
        .findings
        .iter()
        .find(|f| f.code == "swapped-joint-columns")
        .unwrap_or_else(|| panic!("{:#?}", result.findings));
    assert!(
        cause
            .message
            .contains(&format!("'{}' and '{}'", name(a), name(b)))
            || cause
                .message
                .contains(&format!("'{}' and '{}'", name(b), name(a))),
        "{}",
        cause.message
    );
    let sigma = result
        .findings
        .iter()
        .find(|f| f.code == "sigma-ratio")
        .expect("a sigma-ratio finding");
    assert!(
        sigma.message.starts_with("probable consequence"),
        "{}",
        sigma.message
    );
}

/// Item 11: tracker data declared to be in the root frame. The failed measurement-frame
/// finding is the root cause; the σ̂ failure it causes is marked as its consequence.
#[test]
fn a_wrong_fixed_frame_marks_its_consequences() {
    let mut s = scene(2808, 0.04, &tracker());
    let data = measure(&mut s, 30, 1.0, &rigid);
    let result = run(&s, MeasurementFrame::Base, &data, &[]);
    let frame = &result.findings[0];
    assert_eq!(frame.code, "measurement-frame");
    assert_eq!(
        frame.status,
        treecal::calibration::Status::Failed,
        "{}",
        frame.message
    );
    let consequences: Vec<&str> = result
        .findings
        .iter()
        .filter(|f| f.code == "sigma-ratio")
        .map(|f| f.message.as_str())
        .collect();
    assert!(!consequences.is_empty(), "{:#?}", result.findings);
    for message in consequences {
        assert!(
            message.starts_with(
                "probable consequence of the root cause above (the measurement frame)"
            ),
            "{message}"
        );
    }
    assert!(!frame.message.starts_with("probable"));
}

/// A blunder among the validation rows (a bumped target, a mistyped value: 0.4 m off) is
/// marked and counted in every figure, but it does not decide the verdict: the validation
/// checks judge the rows not flagged (and say so), the headline gives both figures. Without
/// that, one row made a good calibration "no better than the nominal robot" (failed, nothing
/// written).
#[test]
fn a_validation_blunder_is_counted_but_does_not_fail_a_good_calibration() {
    let mut s = scene(2809, 1.0, &tracker());
    let data = measure(&mut s, 30, 1.0, &rigid);
    let mut validation = measure(&mut s, 12, 1.0, &rigid);
    if let Observation::Pose(pose) = &mut validation[5].observation {
        pose.translation.vector += Vector3::new(0.0, 0.4, 0.0);
    }
    let dir = tempfile::tempdir().unwrap();
    let config = CalibrateConfig {
        ..robonaut_files(&s, dir.path(), &data, &validation)
    };
    let outcome = calibrate(&config).unwrap_or_else(|e| panic!("{e}"));
    assert!(outcome.usable(), "{:?}", outcome.verdict);
    let reason = |code: &str| outcome.verdict.reasons.iter().find(|r| r.code == code);
    assert!(
        reason("validation-worse").is_none(),
        "{:?}",
        outcome.verdict
    );
    assert!(
        reason("urdf-alone-worse").is_none(),
        "{:?}",
        outcome.verdict
    );
    let outliers = reason("outliers").expect("the blunder is named");
    assert!(
        outliers
            .message
            .contains(&format!("1 of {} validation", validation.len())),
        "{}",
        outliers.message
    );
    // Every row counts in the headline figure, which says what the flagged row does to it.
    let report = outcome.report();
    let all = number(&report["validation_strata"]["strata"][0]["rms_position_mm"]);
    assert!(all > 50.0, "the blunder counts: {all} mm");
    let unflagged = &report["validation_strata"]["without_flagged"];
    assert_eq!(
        unflagged["observations"].as_u64(),
        Some(validation.len() as u64 - 1)
    );
    assert!(number(&unflagged["rms_position_mm"]) < 0.5, "{unflagged}");
    let headline = outcome
        .report_markdown
        .lines()
        .find(|l| l.starts_with("**Held-out accuracy:**"))
        .expect("a headline");
    assert!(
        headline.contains(&format!("over all {} validation rows", validation.len()))
            && headline.contains("1 of them flagged as outliers"),
        "{headline}"
    );
    // Without the flagged row the calibration is at the noise, the nominal robot is not.
    let clean: Vec<Measurement> = validation
        .iter()
        .enumerate()
        .filter(|(i, _)| *i != 5)
        .map(|(_, m)| m.clone())
        .collect();
    let (urdf, frame) = written_urdf_and_registration(&outcome.files);
    let links = tool_links(&s);
    assert!(
        rescore(urdf, &frame, &links, &clean) < 0.5,
        "calibrated at the noise"
    );
}

/// The same checks on validation data that are all off (another set-up): no row stands out,
/// none is set aside, and the calibration fails as before.
#[test]
fn validation_data_all_off_still_fail() {
    let mut s = scene(2810, 1.0, &Pose::identity());
    let data = measure(&mut s, 30, 1.0, &rigid);
    let mut validation = measure(&mut s, 12, 1.0, &rigid);
    for m in &mut validation {
        m.q.iter_mut().for_each(|q| *q += 0.2);
    }
    let result = run(&s, MeasurementFrame::Fit, &data, &validation);
    let codes: Vec<&str> = result.findings.iter().map(|f| f.code.as_str()).collect();
    assert!(
        codes.contains(&"validation-worse") || codes.contains(&"validation-prediction"),
        "{codes:?}"
    );
    assert!(
        result
            .findings
            .iter()
            .all(|f| !f.message.contains("judged without")),
        "{codes:?}"
    );
}
