//! Identifiability analysis: index formulas on hand-computed SVDs, good and bad pose sets on
//! the built-in Robonaut, and `treecal check`.

use crate::common::cli::*;
use crate::common::*;
use nalgebra::DMatrix;
use rand::RngExt;
use treecal::calibration::{
    analyse, criterion_value, observability_indices, Criterion, IdentifiabilityOptions,
    IdentifiabilityReport, ObservationKind, ParameterSet, PoseRow,
};
use treecal::calibration::{
    describe_terms, planned_weighted_jacobian as weighted_jacobian, scaled_singular_values,
};
use treecal::kinematics::McpcModel;
use treecal::tree::KinematicTree;

fn close(a: f64, b: f64, what: &str) {
    assert!(
        (a - b).abs() <= 1e-12 * b.abs().max(1.0),
        "{what}: {a} != {b}"
    );
}

// ---------------------------------------------------------------------------------------------
// index formulas

/// diag(3, 2, 1) from m = 4 observations, by hand: O1 = 6^(1/3)/2, O2 = 3, O3 = 1,
/// O4 = 1/3, O5 = 3 / (1/3 + 1/2 + 1) = 18/11.
#[test]
fn indices_of_a_diagonal_matrix() {
    let matrix = DMatrix::from_diagonal(&nalgebra::DVector::from_vec(vec![2.0, 3.0, 1.0]));
    let values: Vec<f64> = matrix
        .svd(false, false)
        .singular_values
        .iter()
        .copied()
        .collect();
    let indices = observability_indices(&values, 4);
    close(indices.o1, 6f64.powf(1.0 / 3.0) / 2.0, "O1");
    close(indices.o2, 3.0, "O2");
    close(indices.o3, 1.0, "O3");
    close(indices.o4, 1.0 / 3.0, "O4");
    close(indices.o5, 18.0 / 11.0, "O5");
    // Order does not matter.
    assert_eq!(observability_indices(&[1.0, 2.0, 3.0], 4), indices);
    close(
        criterion_value(Criterion::O1, &values, 4),
        indices.o1,
        "O1 criterion",
    );
    close(
        criterion_value(Criterion::O3, &values, 4),
        1.0,
        "O3 criterion",
    );
    close(
        criterion_value(Criterion::D, &values, 4),
        2.0 * 6f64.ln(),
        "D",
    );
}

/// [[3, 0], [4, 5]]: AᵀA = [[25, 20], [20, 25]] has eigenvalues 45 and 5, so σ = 3√5, √5.
#[test]
fn indices_of_a_small_full_matrix() {
    let matrix = DMatrix::from_row_slice(2, 2, &[3.0, 0.0, 4.0, 5.0]);
    let values: Vec<f64> = matrix
        .svd(false, false)
        .singular_values
        .iter()
        .copied()
        .collect();
    let (large, small) = (3.0 * 5f64.sqrt(), 5f64.sqrt());
    let indices = observability_indices(&values, 1);
    close(indices.o1, 15f64.sqrt(), "O1 = √(σ₁σ₂)");
    close(indices.o2, 3.0, "O2");
    close(indices.o3, small, "O3");
    close(indices.o4, small * small / large, "O4");
    close(indices.o5, 2.0 / (1.0 / large + 1.0 / small), "O5");
    // O1 falls with √m: the same information spread over more measurements.
    close(
        observability_indices(&values, 9).o1,
        indices.o1 / 3.0,
        "O1, m = 9",
    );
    close(
        criterion_value(Criterion::D, &values, 1),
        2.0 * 15f64.ln(),
        "D = log det AᵀA",
    );
}

/// Any zero singular value: O1 = O3 = O4 = O5 = 0 and O2 = ∞; D = −∞. Nothing at all: the same.
#[test]
fn a_zero_singular_value_zeroes_the_indices() {
    for values in [&[2.0, 1.0, 0.0][..], &[][..]] {
        let indices = observability_indices(values, 5);
        assert_eq!(
            (indices.o1, indices.o3, indices.o4, indices.o5),
            (0.0, 0.0, 0.0, 0.0),
            "{values:?}"
        );
        assert_eq!(indices.o2, f64::INFINITY);
        assert_eq!(criterion_value(Criterion::D, values, 5), f64::NEG_INFINITY);
    }
    assert_eq!(observability_indices(&[1.0], 0).o1, 0.0, "no measurements");
}

/// Column scaling by hand: orthogonal columns of any lengths scale to σ = 1, 1; unit columns
/// at 45° have Gram matrix [[1, c], [c, 1]] (c = 1/√2), so σ = √(1 ± c).
#[test]
fn scaled_singular_values_by_hand() {
    let orthogonal = DMatrix::from_row_slice(3, 2, &[200.0, 0.0, 0.0, 0.5, 0.0, 0.0]);
    let values = scaled_singular_values(&orthogonal);
    close(values[0], 1.0, "σ₁");
    close(values[1], 1.0, "σ₂");
    let c = std::f64::consts::FRAC_1_SQRT_2;
    let skewed = DMatrix::from_row_slice(2, 2, &[3.0, 7.0, 0.0, 7.0]);
    let values = scaled_singular_values(&skewed);
    close(values[0], (1.0 + c).sqrt(), "σ₁");
    close(values[1], (1.0 - c).sqrt(), "σ₂");
    // Fewer rows than columns: one value per column, the missing ones zero.
    let wide = DMatrix::from_row_slice(1, 3, &[1.0, 2.0, 3.0]);
    let values = scaled_singular_values(&wide);
    assert_eq!(values.len(), 3);
    close(values[0], 3f64.sqrt(), "σ₁ of [1 1 1] after scaling");
    assert!(
        values[1].abs() < 1e-12 && values[2].abs() < 1e-12,
        "{values:?}"
    );
}

#[test]
fn criteria_parse_in_any_case() {
    for (text, criterion) in [
        ("o1", Criterion::O1),
        ("O1", Criterion::O1),
        ("D", Criterion::D),
        (" d ", Criterion::D),
        ("o3", Criterion::O3),
    ] {
        assert_eq!(text.parse::<Criterion>().unwrap(), criterion, "{text}");
        assert_eq!(
            criterion.to_string().parse::<Criterion>().unwrap(),
            criterion
        );
    }
    let error = "o2".parse::<Criterion>().unwrap_err().to_string();
    assert!(
        error.contains("'o2'") && error.contains("o1, d or o3"),
        "{error}"
    );
    let json: Criterion = serde_json::from_str("\"o3\"").unwrap();
    assert_eq!(json, Criterion::O3);
}

#[test]
fn combinations_read_as_sentences() {
    let pair = describe_terms(&[
        ("left_joint1 alpha".into(), 0.71),
        ("right_joint1 alpha".into(), -0.71),
    ]);
    assert_eq!(
        pair,
        "left_joint1 alpha and right_joint1 alpha move together (+0.71, -0.71)"
    );
    let three = describe_terms(&[
        ("a x".into(), 0.6),
        ("b y".into(), -0.6),
        ("c z".into(), 0.53),
    ]);
    assert_eq!(
        three,
        "a x, b y and c z move together (+0.60, -0.60, +0.53)"
    );
    assert_eq!(
        describe_terms(&[("left_tool gamma".into(), 1.0)]),
        "left_tool gamma is not observed by these poses"
    );
}

// ---------------------------------------------------------------------------------------------
// Robonaut pose sets

/// Every tool at every configuration.
fn rows(model: &McpcModel, configurations: &[Vec<f64>]) -> Vec<PoseRow> {
    configurations
        .iter()
        .flat_map(|q| {
            (0..model.tools().len()).map(|tool| PoseRow {
                tool,
                q: q.clone(),
                stage: None,
            })
        })
        .collect()
}

fn random_configurations(tree: &KinematicTree, count: usize, seed: u64) -> Vec<Vec<f64>> {
    let mut rng = rng(seed);
    (0..count)
        .map(|_| random_configuration(tree, &mut rng))
        .collect()
}

fn run(
    parameters: ParameterSet,
    observation: ObservationKind,
    configurations: &[Vec<f64>],
) -> IdentifiabilityReport {
    let (_, _, model) = TestRobot::robonaut().parts();
    run_on(&model, parameters, observation, configurations)
}

fn run_on(
    model: &McpcModel,
    parameters: ParameterSet,
    observation: ObservationKind,
    configurations: &[Vec<f64>],
) -> IdentifiabilityReport {
    let (tree, branches, _) = TestRobot::robonaut().parts();
    let options = IdentifiabilityOptions {
        parameters,
        ..IdentifiabilityOptions::default()
    };
    analyse(
        &tree,
        &branches,
        model,
        &rows(model, configurations),
        observation,
        &options,
    )
    .unwrap()
}

/// 20 random configurations determine all 64 parameters from full poses, as the solver finds;
/// from positions only, the 6 tool-orientation directions are lost (rank 58) on a generic
/// robot (the paper's section 5.2 errors). The nominal Robonaut loses 4 more: its special
/// geometry (tool points on joint axes) makes further position directions vanish.
#[test]
fn random_poses_identify_everything_from_full_poses() {
    let (tree, _, nominal) = TestRobot::robonaut().parts();
    let generic = crate::identification::perturbed(&nominal, 2);
    for seed in 0..3 {
        let configurations = random_configurations(&tree, 20, seed);
        let pose = run(ParameterSet::All, ObservationKind::Pose, &configurations);
        eprintln!(
            "seed {seed}: rank {} of {}, condition {:.1}, O1 {:.4e} O3 {:.4e} O4 {:.4e} O5 {:.4e}",
            pose.rank,
            pose.parameter_count(),
            pose.condition_number,
            pose.indices.o1,
            pose.indices.o3,
            pose.indices.o4,
            pose.indices.o5
        );
        assert_eq!(pose.parameter_count(), 64);
        assert_eq!(pose.rank, 64, "{:?}", pose.singular_values);
        assert!(pose.unidentifiable.is_empty());
        assert_eq!(pose.observations, 40);
        assert_eq!(pose.configurations, 20);
        assert_eq!(pose.rows, 240);
        assert_eq!(pose.indices, pose.identifiable_indices);
        assert!(pose.condition_number < 1e3, "{}", pose.condition_number);
        close(
            pose.indices.o2,
            pose.condition_number,
            "O2 is the condition number",
        );

        let position = run_on(
            &generic,
            ParameterSet::All,
            ObservationKind::Position,
            &configurations,
        );
        assert_eq!(position.rank, 58, "{:?}", position.singular_values);
        let nominal_position = run(
            ParameterSet::All,
            ObservationKind::Position,
            &configurations,
        );
        eprintln!(
            "seed {seed}: position only, nominal rank {}, generic rank {}",
            nominal_position.rank, position.rank
        );
        assert_eq!(position.rows, 120);
        assert_eq!(position.unidentifiable.len(), 6);
        for combination in &position.unidentifiable {
            assert!(
                combination
                    .terms
                    .iter()
                    .all(|(name, _)| name.contains("_tool ")),
                "{}",
                combination.description
            );
        }
        assert_eq!(position.indices.o3, 0.0);
        assert_eq!(position.indices.o2, f64::INFINITY);
        assert!(position.identifiable_indices.o3 > 0.0);
    }
}

/// The obviously bad set: every joint within ±1 mrad of zero. Numerically of full rank, but
/// with a condition number of about 10⁴: poorly conditioned, with the weak combinations named.
/// At exactly zero, the rank itself drops.
#[test]
fn poses_near_zero_are_poorly_conditioned() {
    let (tree, _, _) = TestRobot::robonaut().parts();
    let mut rng = rng(7);
    let configurations: Vec<Vec<f64>> = (0..20)
        .map(|_| {
            (0..tree.dof_count())
                .map(|_| rng.random_range(-1e-3..1e-3))
                .collect()
        })
        .collect();
    let report = run(ParameterSet::All, ObservationKind::Pose, &configurations);
    for combination in &report.poorly_determined {
        eprintln!("{}", combination.description);
    }
    eprintln!(
        "near zero: rank {} of {}, O1 {:.3e}, identifiable condition {:.3e}",
        report.rank,
        report.parameter_count(),
        report.indices.o1,
        report.condition_number
    );
    assert!(!report.is_well_conditioned());
    assert!(report.condition_number > 1e3, "{}", report.condition_number);
    assert!(
        report.verdict().starts_with("poorly conditioned"),
        "{}",
        report.verdict()
    );
    assert!(!report.poorly_determined.is_empty());
    let exactly_zero = vec![vec![0.0; tree.dof_count()]; 20];
    let zero = run(ParameterSet::All, ObservationKind::Pose, &exactly_zero);
    eprintln!("exactly zero: rank {} of 64", zero.rank);
    assert!(zero.rank < 64, "rank {}", zero.rank);
    assert_eq!(zero.unidentifiable.len(), 64 - zero.rank);
    assert_eq!(zero.indices.o1, 0.0);
    assert_eq!(zero.indices.o2, f64::INFINITY);
    assert!(
        zero.verdict().contains("cannot be identified"),
        "{}",
        zero.verdict()
    );
    for combination in report.poorly_determined.iter().chain(&zero.unidentifiable) {
        assert!(
            combination.description.contains("move together")
                || combination.description.contains("is not observed"),
            "{}",
            combination.description
        );
        assert!(!combination.terms.is_empty());
    }
}

/// The arms set leaves the torso frames out; the torso stage adds the locked tools.
#[test]
fn stages_analyse_their_own_parameters() {
    let (tree, branches, model) = TestRobot::robonaut().parts();
    let torso_dofs = branches.coupled.dofs(&tree);
    let arms = run(
        ParameterSet::Arms,
        ObservationKind::Pose,
        &random_configurations(&tree, 20, 3),
    );
    let torso_parameters = 64 - arms.parameter_count();
    assert!(torso_parameters > 0);
    assert!(arms.parameter_names.iter().all(|n| !n.starts_with("torso")));
    assert_eq!(arms.rank, arms.parameter_count());

    // Torso configurations: two locked arm configurations, the torso joints random.
    let locks = random_configurations(&tree, 2, 4);
    let free = random_configurations(&tree, 10, 5);
    let configurations: Vec<Vec<f64>> = free
        .iter()
        .enumerate()
        .map(|(index, f)| {
            let mut q = locks[index % 2].clone();
            for &d in &torso_dofs {
                q[d] = f[d];
            }
            q
        })
        .collect();
    let torso = run(
        ParameterSet::Coupled,
        ObservationKind::Pose,
        &configurations,
    );
    assert_eq!(torso.locked_tools, 2 * model.tools().len());
    assert_eq!(
        torso.parameter_count(),
        torso_parameters + 6 * torso.locked_tools
    );
    assert!(
        torso.parameter_names.iter().any(|n| n.contains("(lock 2)")),
        "{:?}",
        torso.parameter_names
    );
    eprintln!(
        "torso stage: rank {} of {}, condition {:.1}",
        torso.rank,
        torso.parameter_count(),
        torso.condition_number
    );
}

/// The weighted Jacobian divides position rows by σ_p and rotation rows by σ_r.
#[test]
fn rows_are_weighted_by_their_sigma() {
    let (tree, _, model) = TestRobot::robonaut().parts();
    let configurations = random_configurations(&tree, 1, 9);
    let rows = rows(&model, &configurations);
    let free: Vec<usize> = (0..model.parameter_count()).collect();
    let options = IdentifiabilityOptions {
        position_sigma: 2e-4,
        rotation_sigma: 5e-5,
        ..IdentifiabilityOptions::default()
    };
    let weighted =
        weighted_jacobian(&model, &rows, ObservationKind::Pose, &free, &options).unwrap();
    let raw = model.tool_jacobian(1, &configurations[0]).jacobian;
    for column in 0..free.len() {
        for k in 0..6 {
            let sigma = if k < 3 { 2e-4 } else { 5e-5 };
            close(
                weighted[(6 + k, column)],
                raw[(k, column)] / sigma,
                "weighted entry",
            );
        }
    }
    let bad = IdentifiabilityOptions {
        position_sigma: 0.0,
        ..IdentifiabilityOptions::default()
    };
    assert!(weighted_jacobian(&model, &rows, ObservationKind::Pose, &free, &bad).is_err());
    let mut wrong_tool = rows.clone();
    wrong_tool[0].tool = 7;
    let error = weighted_jacobian(&model, &wrong_tool, ObservationKind::Pose, &free, &options)
        .unwrap_err()
        .to_string();
    assert!(error.contains("tool 7"), "{error}");
}

// ---------------------------------------------------------------------------------------------
// treecal check

fn write(dir: &std::path::Path, name: &str, text: &str) -> String {
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path_str(&path).to_owned()
}

fn temporary(name: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("treecal-check-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// All joints at zero (a header naming one joint, every value 0): poorly conditioned, exit 0,
/// with the combinations named.
#[test]
fn check_reports_zero_poses_as_poorly_conditioned() {
    let dir = temporary("zero");
    let mut text = String::from("left_joint1\n");
    for _ in 0..10 {
        text.push_str("0\n");
    }
    let poses = write(&dir, "zero.csv", &text);
    let run = treecal(&["check", "--poses", &poses, "--plan", "simultaneous"]);
    assert_success(&run, "check zero poses");
    assert!(run.stdout.contains("poorly conditioned"), "{run}");
    assert!(run.stdout.contains("cannot be identified"), "{run}");
    assert!(
        run.stdout.contains("move together") || run.stdout.contains("is not observed"),
        "{run}"
    );
    assert!(run.stdout.contains("O1 0.000e0"), "{run}");

    // Staged without a stage column: the torso stage is skipped, and says why. (`--plan
    // staged` is now asked for: without it, unlabelled rows are analysed simultaneously.)
    let staged = treecal(&[
        "check", "--poses", &poses, "--plan", "staged", "--format", "json",
    ]);
    assert_success(&staged, "check zero poses, staged");
    let json: serde_json::Value = serde_json::from_str(&staged.stdout).unwrap();
    assert_eq!(json["well_conditioned"], false);
    assert!(json["stages"][0]["skipped"]
        .as_str()
        .unwrap()
        .contains("torso"));
    assert_eq!(json["stages"][1]["analysis"]["parameters"], "arms");
    assert!(!json["stages"][1]["analysis"]["unidentifiable"]
        .as_array()
        .unwrap()
        .is_empty());
    assert!(staged.stderr.contains("no 'stage' column"), "{staged}");
    std::fs::remove_dir_all(&dir).ok();
}

/// The default random set is well conditioned in both plans; one target loses the tool
/// orientations.
#[test]
fn check_default_set_is_well_conditioned() {
    let run = treecal(&["check"]);
    assert_success(&run, "check");
    assert!(run.stderr.contains("no --pose-file given"), "{run}");
    assert!(run.stdout.contains("stage torso:"), "{run}");
    assert!(run.stdout.contains("stage arms:"), "{run}");
    assert!(run.stdout.ends_with("verdict: well conditioned\n"), "{run}");

    let yaml = treecal(&[
        "check",
        "--plan",
        "simultaneous",
        "--targets",
        "1",
        "--format",
        "yaml",
    ]);
    assert_success(&yaml, "check --targets 1");
    assert!(yaml.stdout.contains("observation: position"), "{yaml}");
    assert!(yaml.stdout.contains("well_conditioned: false"), "{yaml}");
    assert!(
        yaml.stdout.contains("_tool gamma") || yaml.stdout.contains("_tool alpha"),
        "{yaml}"
    );
}

/// Tool and stage columns; bad values are clear errors naming file, line and column.
#[test]
fn check_reads_tool_and_stage_columns() {
    let dir = temporary("columns");
    let (tree, _, _) = TestRobot::robonaut().parts();
    let mut text = String::from("tool,stage");
    for joint in tree.dofs() {
        text.push(',');
        text.push_str(&tree.joint(*joint).name);
    }
    text.push('\n');
    let mut rng = rng(11);
    for index in 0..24 {
        let tool = if index % 2 == 0 {
            "left_tool"
        } else {
            "right_tool"
        };
        text.push_str(&format!("{tool},arms"));
        for _ in tree.dofs() {
            text.push_str(&format!(",{:.4}", rng.random_range(-1.0..1.0)));
        }
        text.push('\n');
    }
    let poses = write(&dir, "poses.csv", &text);
    let run = treecal(&["check", "--poses", &poses, "--format", "json"]);
    assert_success(&run, "check tool/stage columns");
    let json: serde_json::Value = serde_json::from_str(&run.stdout).unwrap();
    assert_eq!(json["stages"][1]["analysis"]["observations"], 24);
    assert!(json["stages"][0]["skipped"]
        .as_str()
        .unwrap()
        .contains("no rows labelled torso"));

    let bad_tool = write(&dir, "bad_tool.csv", "tool,left_joint1\nleft_palm,0.1\n");
    let run = treecal(&["check", "--poses", &bad_tool]);
    assert_error(
        &run,
        &["bad_tool.csv:2:tool", "'left_palm'", "left_tool"],
        "bad tool",
    );
    let bad_stage = write(&dir, "bad_stage.csv", "stage,left_joint1\ntosro,0.1\n");
    let run = treecal(&["check", "--poses", &bad_stage]);
    assert_error(
        &run,
        &["bad_stage.csv:2:stage", "'tosro'", "torso"],
        "bad stage",
    );
    let bad_number = write(&dir, "bad_number.csv", "left_joint1\nabc\n");
    let run = treecal(&["check", "--poses", &bad_number]);
    assert_error(
        &run,
        &["bad_number.csv:2:left_joint1", "'abc'"],
        "bad number",
    );
    let empty = write(&dir, "empty.csv", "left_joint1\n");
    let run = treecal(&["check", "--poses", &empty]);
    assert_error(&run, &["empty.csv", "no pose rows"], "no rows");
    let run = treecal(&["check", "--measurements", &empty]);
    assert_error(&run, &["empty.csv"], "empty measurement file");
    let run = treecal(&["check", "--targets", "2"]);
    assert_error(&run, &["--targets", "use 3"], "two targets");
    let run = treecal(&["check", "--position-sigma", "0"]);
    assert_error(&run, &["--position-sigma"], "sigma");
    std::fs::remove_dir_all(&dir).ok();
}

/// `--measurements` analyses a measurement CSV's own configurations, tools and stages (the
/// example data set: three targets in mm and deg, torso and arm rows).
#[test]
fn check_reads_a_measurement_file() {
    let example = repo().join("robots/robonaut/example/measurements.csv");
    let run = treecal(&[
        "check",
        "--measurements",
        example.to_str().unwrap(),
        "--length-unit",
        "mm",
        "--angle-unit",
        "deg",
    ]);
    assert_success(&run, "check --measurements");
    assert!(run.stdout.contains("(60 observations)"), "{run}");
    assert!(run.stdout.contains("stage torso:"), "{run}");
    assert!(run.stdout.contains("rank 56 of 56"), "{run}");
    assert!(run.stdout.ends_with("verdict: well conditioned\n"), "{run}");
    // Without the flags the file's units comment (`# units: length=mm angle=deg`) decides: the
    // same report; a flag that contradicts it is an error.
    let plain = treecal(&["check", "--measurements", example.to_str().unwrap()]);
    assert_success(&plain, "check --measurements without unit flags");
    assert_eq!(plain.stdout, run.stdout);
    let wrong = treecal(&[
        "check",
        "--measurements",
        example.to_str().unwrap(),
        "--angle-unit",
        "rad",
    ]);
    assert_error(
        &wrong,
        &["--angle-unit rad contradicts", "angle=deg"],
        "conflict",
    );
}
