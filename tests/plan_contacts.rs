//! `plan --contact-setup` (issue 29 item 6): planned contacts beat a random set of the same
//! candidates, are feasible on the nominal robot, calibrate at least as well, and run on a
//! standing Atlas; bad setups are errors naming the culprit.

use crate::common;
use rand::rngs::ChaCha8Rng;
use rand::SeedableRng;
use rand_distr::{Distribution, StandardNormal};
use treecal::calibration::Criterion;
use treecal::io::{parse_contacts, ContactRow, PoseEntry};
use treecal::measurement::{Contact, Measurement};
use treecal::sim::{contact_configurations, onto_contact, true_model, ContactChoice, ErrorRanges};
use treecal::workflow::{
    branches, contact_options, contact_problem, contact_violations, fit_contacts, no_progress,
    plan_contacts, ContactPlanConfig, ContactPosePlan, RobotSource,
};
use treecal::McpcModel;

/// A setup YAML for `links` (the first with a face 5 cm out and a point; the others with a
/// point) whose plane passes through the first tool's face at a random configuration of the
/// nominal robot (reachable by construction), and the robot's source.
fn setup_file(
    dir: &std::path::Path,
    robot: &RobotSource,
    links: &[&str],
    reference: Option<&str>,
    seed: u64,
) -> std::path::PathBuf {
    let loaded = robot.load().unwrap();
    let names: Vec<String> = links.iter().map(|s| s.to_string()).collect();
    let b = branches(&loaded.import, Some(&names), reference).unwrap();
    let model = McpcModel::from_tree(&loaded.import.tree, &b).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let limits = loaded.import.tree.dof_limits();
    let q: Vec<f64> = limits
        .iter()
        .map(|l| {
            l.map_or(0.3, |l| {
                rand::RngExt::random_range(&mut rng, l.lower..=l.upper) * 0.5
            })
        })
        .collect();
    let face = PoseEntry {
        xyz: [0.0, 0.0, 0.05],
        rpy: [0.0; 3],
    };
    let plane = PoseEntry::of(&(model.tool_poses(&q)[0] * face.pose()));
    let mut yaml = String::new();
    if let Some(r) = reference {
        yaml.push_str(&format!("reference_link: {r}\n"));
    }
    yaml.push_str("tools:\n");
    for (k, link) in links.iter().enumerate() {
        yaml.push_str(&format!(
            "  {link}:\n    link: {link}\n    point: [0.01, -0.02, 0.06]\n"
        ));
        if k == 0 {
            yaml.push_str("    face: {xyz: [0.0, 0.0, 0.05]}\n");
        }
    }
    yaml.push_str(&format!(
        "planes:\n  table: {{xyz: {:?}, rpy: {:?}}}\nbar: {{length: 0.3}}\n",
        plane.xyz, plane.rpy
    ));
    let path = dir.join("setup.yaml");
    std::fs::write(&path, yaml).unwrap();
    path
}

fn config(
    robot: RobotSource,
    setup: std::path::PathBuf,
    kinds: &[ContactChoice],
) -> ContactPlanConfig {
    ContactPlanConfig {
        robot,
        setup,
        kinds: kinds.to_vec(),
        tools: None,
        reference_link: None,
        poses: 24,
        candidates: 240,
        criterion: Criterion::O1,
        seed: 5,
        package_paths: Vec::new(),
        collision_check: treecal::sim::CollisionCheck::PrimitivesOnly,
    }
}

fn builtin(kinds: &[ContactChoice]) -> (tempfile::TempDir, ContactPlanConfig, ContactPosePlan) {
    let dir = tempfile::tempdir().unwrap();
    let robot = RobotSource::BuiltIn;
    let setup = setup_file(dir.path(), &robot, &["left_tool", "right_tool"], None, 2);
    let config = config(robot, setup, kinds);
    let plan = plan_contacts(&config, &no_progress).unwrap();
    (dir, config, plan)
}

#[test]
fn planned_contacts_beat_a_random_set_of_the_same_candidates() {
    for kinds in [
        &[ContactChoice::Touch, ContactChoice::Bar][..],
        &[ContactChoice::Flush][..],
    ] {
        let (_dir, _config, plan) = builtin(kinds);
        let r = &plan.report;
        assert_eq!(plan.rows.len(), 24);
        assert!(r.planned_value > r.random_value, "{kinds:?}: {r:?}");
        assert!(r.planned_rank >= r.random_rank, "{kinds:?}: {r:?}");
        assert!(
            plan.text.contains("What the contacts cannot determine"),
            "{}",
            plan.text
        );
    }
}

/// The setup's contacts of `rows` with the setup's nominal planes (not the closed-form start).
fn contacts_on_setup_planes(
    config: &ContactPlanConfig,
    rows: &[ContactRow],
) -> treecal::workflow::ContactProblem {
    let loaded = config.robot.load().unwrap();
    let setup = treecal::io::read_contact_setup(&config.setup).unwrap();
    let links: Vec<String> = setup.tools.values().map(|t| t.link.clone()).collect();
    let b = branches(
        &loaded.import,
        Some(&links),
        setup.reference_link.as_deref(),
    )
    .unwrap();
    let model = McpcModel::from_tree(&loaded.import.tree, &b).unwrap();
    let mut problem =
        contact_problem(&loaded.import.tree, model, &setup, rows, &[], "plan").unwrap();
    for m in &mut problem.training {
        if let Some(Contact::Flush { plane, .. } | Contact::Point { plane, .. }) =
            m.observation.contact_mut()
        {
            plane.nominal = problem.setup_planes[m.session.as_deref().unwrap()];
        }
    }
    problem
}

#[test]
fn the_written_csv_parses_and_every_contact_holds_on_the_nominal_robot() {
    let (dir, config, plan) = builtin(&[
        ContactChoice::Flush,
        ContactChoice::Touch,
        ContactChoice::Bar,
    ]);
    let out = dir.path().join("planned.csv");
    plan.write(&out).unwrap();
    let tree = config.robot.load().unwrap().import.tree;
    let table = parse_contacts(&std::fs::read_to_string(&out).unwrap(), "planned", &tree).unwrap();
    assert_eq!(table.rows.len(), plan.rows.len());
    assert!(table.missing_joints.is_empty());
    let problem = contacts_on_setup_planes(&config, &table.rows);
    let violations = contact_violations(
        &problem.model,
        &problem.model.parameters(),
        &problem.nuisance,
        &problem.training,
    )
    .unwrap();
    for (contact, v) in violations {
        let worst = v.iter().fold(0.0f64, |a, b| a.max(b.abs()));
        assert!(worst < 1e-6, "{contact:?}: {v:?}");
    }
}

/// Held-out RMS heights, gaps and lengths (m) and tilts (rad) after calibrating from `rows`
/// measured on a perturbed true robot (each planned configuration moved onto the contact by
/// the true robot, encoder noise added), scored on contacts the true robot makes near them.
fn round_trip(
    config: &ContactPlanConfig,
    rows: &[ContactRow],
    truth: &McpcModel,
    seed: u64,
) -> (f64, f64) {
    let tree = config.robot.load().unwrap().import.tree;
    let setup = treecal::io::read_contact_setup(&config.setup).unwrap();
    let problem = contacts_on_setup_planes(config, rows);
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let (mut training, mut validation) = (Vec::new(), Vec::new());
    for (row, m) in rows.iter().zip(&problem.training) {
        let Some(contact) = m.observation.contact() else {
            continue;
        };
        let Some(q) = onto_contact(&tree, truth, &problem.nuisance, (contact, m.tool), &row.q)
        else {
            continue;
        };
        let noisy = q
            .iter()
            .map(|v| {
                let n: f64 = StandardNormal.sample(&mut rng);
                v + 2e-4 * n
            })
            .collect();
        training.push(ContactRow {
            q: noisy,
            ..row.clone()
        });
        if validation.len() < 40 {
            let held = contact_configurations(
                &tree,
                truth,
                &problem.nuisance,
                (contact, m.tool),
                2,
                &mut rng,
                "held out",
            )
            .unwrap();
            validation.extend(held.into_iter().map(|q| ContactRow { q, ..row.clone() }));
        }
    }
    assert!(
        training.len() >= rows.len() * 9 / 10,
        "{} of {}",
        training.len(),
        rows.len()
    );
    let problem = contact_problem(
        &tree,
        problem.model.clone(),
        &setup,
        &training,
        &validation,
        "trip",
    )
    .unwrap();
    let fit = fit_contacts(&problem, &contact_options(&setup)).unwrap();
    let scored: Vec<Measurement> = problem.validation.clone();
    let v = contact_violations(
        &problem.model,
        &fit.after.parameters,
        &fit.after.nuisance,
        &scored,
    )
    .unwrap();
    let (mut lengths, mut tilts) = (Vec::new(), Vec::new());
    for (contact, v) in v {
        match contact {
            Contact::Flush { .. } => {
                lengths.push(v[0]);
                tilts.extend_from_slice(&v[1..]);
            }
            _ => lengths.extend(v),
        }
    }
    let rms = |x: &[f64]| {
        if x.is_empty() {
            0.0
        } else {
            (x.iter().map(|v| v * v).sum::<f64>() / x.len() as f64).sqrt()
        }
    };
    (rms(&lengths), rms(&tilts))
}

/// A true robot off `plan`'s nominal one (seeded).
fn truth_of(config: &ContactPlanConfig, plan: &ContactPosePlan, seed: u64) -> McpcModel {
    let nominal = contacts_on_setup_planes(config, &plan.rows).model;
    let ranges = ErrorRanges {
        angle: 0.005,
        length: 0.005,
    };
    true_model(&nominal, &ranges, &mut ChaCha8Rng::seed_from_u64(seed)).unwrap()
}

#[test]
fn planned_contacts_calibrate_at_least_as_well_as_random_ones() {
    let kinds = [
        ContactChoice::Flush,
        ContactChoice::Touch,
        ContactChoice::Bar,
    ];
    let (_dir, config, plan) = builtin(&kinds);
    let truth = truth_of(&config, &plan, 11);
    let planned = round_trip(&config, &plan.rows, &truth, 1);
    let random = round_trip(&config, &plan.random_rows, &truth, 1);
    eprintln!("held-out RMS (m, rad): planned {planned:.3?}, random {random:.3?}");
    assert!(
        planned.0 <= random.0,
        "planned {planned:?} vs random {random:?}"
    );
}

/// The table of docs/contacts.md "Planning contact configurations" (run by hand:
/// `cargo test --test tests plan_contacts::measure -- --ignored --nocapture`).
#[test]
#[ignore]
fn measure_planned_against_random() {
    let atlas = shared_robot("atlas_v5/atlas_v5.urdf").expect("the shared Atlas");
    let both = vec!["left_tool", "right_tool"];
    let cases = vec![
        (
            "built-in",
            RobotSource::BuiltIn,
            both.clone(),
            None,
            vec![ContactChoice::Touch, ContactChoice::Bar],
        ),
        (
            "built-in",
            RobotSource::BuiltIn,
            both.clone(),
            None,
            vec![ContactChoice::Flush],
        ),
        (
            "built-in",
            RobotSource::BuiltIn,
            both,
            None,
            vec![
                ContactChoice::Flush,
                ContactChoice::Touch,
                ContactChoice::Bar,
            ],
        ),
        (
            "Atlas on l_foot",
            RobotSource::File(atlas),
            vec!["l_hand", "r_hand"],
            Some("l_foot"),
            vec![ContactChoice::Flush],
        ),
    ];
    println!("| robot | kinds | criterion planned / random | rank planned / random | held-out length RMS (mm) planned / random | held-out tilt RMS (mrad) planned / random |");
    for (name, robot, links, reference, kinds) in cases {
        let seeds = 5;
        let mut sums = [0.0; 8];
        for seed in 0..seeds {
            let dir = tempfile::tempdir().unwrap();
            let setup = setup_file(dir.path(), &robot, &links, reference, seed + 2);
            let mut c = config(robot.clone(), setup, &kinds);
            c.seed = seed;
            let plan = plan_contacts(&c, &no_progress).unwrap();
            let truth = truth_of(&c, &plan, 100 + seed);
            let p = round_trip(&c, &plan.rows, &truth, seed);
            let r = round_trip(&c, &plan.random_rows, &truth, seed);
            let values = [
                plan.report.planned_value,
                plan.report.random_value,
                plan.report.planned_rank as f64,
                plan.report.random_rank as f64,
                p.0 * 1e3,
                r.0 * 1e3,
                p.1 * 1e3,
                r.1 * 1e3,
            ];
            for (s, v) in sums.iter_mut().zip(values) {
                *s += v / seeds as f64;
            }
        }
        let k: Vec<&str> = kinds.iter().map(|k| k.name()).collect();
        let s = sums;
        println!(
            "| {name} | {} | {:.3} / {:.3} | {:.1} / {:.1} | {:.3} / {:.3} | {:.3} / {:.3} |",
            k.join(","),
            s[0],
            s[1],
            s[2],
            s[3],
            s[4],
            s[5],
            s[6],
            s[7]
        );
    }
}

/// A robot of the shared robots (`TREECAL_SHARED_DIR`, `../shared`, `/work/shared`).
fn shared_robot(relative: &str) -> Option<std::path::PathBuf> {
    let mut candidates = Vec::new();
    if let Some(dir) = std::env::var_os("TREECAL_SHARED_DIR") {
        candidates.push(std::path::PathBuf::from(dir).join("robots").join(relative));
    }
    candidates.push(common::repo().join("../shared/robots").join(relative));
    candidates.push(std::path::Path::new("/work/shared/robots").join(relative));
    candidates.into_iter().find(|c| c.is_file())
}

#[test]
fn flush_contacts_of_atlas_standing_on_its_left_foot_are_planned() {
    let Some(atlas) = shared_robot("atlas_v5/atlas_v5.urdf") else {
        eprintln!("skipped: the shared Atlas URDF is not there");
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let robot = RobotSource::File(atlas);
    let setup = setup_file(dir.path(), &robot, &["l_hand", "r_hand"], Some("l_foot"), 4);
    let config = config(robot, setup, &[ContactChoice::Flush]);
    let plan = plan_contacts(&config, &no_progress).unwrap();
    let r = &plan.report;
    assert!(r.planned_value > r.random_value, "{r:?}");
    assert!(r.planned_rank >= r.random_rank, "{r:?}");
    assert!(plan.csv.contains(",table,flush,l_hand,"), "{}", plan.csv);
}

#[test]
fn a_bad_setup_is_an_error_naming_the_tool_or_link() {
    let dir = tempfile::tempdir().unwrap();
    let robot = RobotSource::BuiltIn;
    let setup = setup_file(dir.path(), &robot, &["left_tool", "right_tool"], None, 2);
    let mut unknown_tool = config(robot.clone(), setup.clone(), &[ContactChoice::Touch]);
    unknown_tool.tools = Some(vec!["left_tool".into(), "third_hand".into()]);
    let message = plan_contacts(&unknown_tool, &no_progress)
        .unwrap_err()
        .to_string();
    assert!(message.contains("third_hand"), "{message}");
    let text = std::fs::read_to_string(&setup)
        .unwrap()
        .replace("link: right_tool", "link: right_toool");
    let bad_link = dir.path().join("bad-link.yaml");
    std::fs::write(&bad_link, text).unwrap();
    let message = plan_contacts(
        &config(robot.clone(), bad_link, &[ContactChoice::Touch]),
        &no_progress,
    )
    .unwrap_err()
    .to_string();
    assert!(message.contains("right_toool"), "{message}");
    let no_plane = dir.path().join("no-plane.yaml");
    let text = std::fs::read_to_string(&setup).unwrap();
    std::fs::write(&no_plane, text.split("planes:").next().unwrap()).unwrap();
    let message = plan_contacts(
        &config(robot, no_plane, &[ContactChoice::Flush]),
        &no_progress,
    )
    .unwrap_err()
    .to_string();
    assert!(message.contains("plane"), "{message}");
}

#[test]
fn the_cli_plans_contacts_that_calibrate_contacts_reads() {
    use common::cli::{assert_success, path_str, treecal};
    let dir = tempfile::tempdir().unwrap();
    let setup = setup_file(
        dir.path(),
        &RobotSource::BuiltIn,
        &["left_tool", "right_tool"],
        None,
        2,
    );
    let planned = dir.path().join("planned.csv");
    let run = treecal(&[
        "plan",
        "--contact-setup",
        path_str(&setup),
        "--observation",
        "flush,touch,bar",
        "--poses",
        "30",
        "--candidates",
        "150",
        "-o",
        path_str(&planned),
    ]);
    assert_success(&run, "plan --contact-setup");
    let stdout = &run.stdout;
    assert!(stdout.contains("random set of the same size"), "{stdout}");
    let run = treecal(&[
        "calibrate",
        "--contacts",
        path_str(&planned),
        "--contact-setup",
        path_str(&setup),
        "-o",
        path_str(&dir.path().join("cal")),
    ]);
    // Exact contacts of the nominal robot: calibrate reads them all; nothing beats the nominal
    // robot there, so the verdict is "not usable" (exit 1), with the report printed.
    assert!(
        run.stdout
            .contains("Contacts: 24 training, 6 held out (flush, touch, distance)"),
        "{}{}",
        run.stdout,
        run.stderr
    );
    let run = treecal(&[
        "plan",
        "--contact-setup",
        path_str(&setup),
        "--observation",
        "flush,tuch",
        "--poses",
        "30",
        "-o",
        path_str(&dir.path().join("x.csv")),
    ]);
    assert!(!run.success);
    assert!(run.stderr.contains("'tuch'"), "{}", run.stderr);
}

/// Planned touches on the built-in robot (collision cylinders on every link): candidates in
/// self-collision are rejected (the note counts them), and every planned configuration is free
/// of self-collision but for the two hands that touch; with the check off none is rejected.
#[test]
fn planned_touches_are_free_of_self_collision_but_for_the_hands() {
    let (_dir, config, plan) = builtin(&[ContactChoice::Touch]);
    let rejected = |notes: &[treecal::workflow::Note]| -> usize {
        let note = notes
            .iter()
            .find(|n| n.text.contains("projected configurations rejected"))
            .unwrap_or_else(|| panic!("{notes:?}"));
        let words: Vec<&str> = note.text.split_whitespace().collect();
        let at = words.iter().position(|w| *w == "projected").unwrap();
        words[at - 1].parse().unwrap()
    };
    assert!(rejected(&plan.notes) > 0, "{:?}", plan.notes);
    let loaded = config.robot.load().unwrap();
    let tree = &loaded.import.tree;
    let checker = treecal::sim::CollisionChecker::new(tree).unwrap();
    let problem = contacts_on_setup_planes(&config, &plan.rows);
    let hands = treecal::sim::ContactCollisions::new(tree, &problem.model, checker.clone());
    let mut touching = 0;
    for m in &problem.training {
        let Some(contact) = m.observation.contact() else {
            continue;
        };
        assert!(hands.allows(Some(contact), m.tool, &m.q), "{:?}", m.q);
        touching += usize::from(checker.in_collision(&tree.link_poses(&m.q).unwrap()));
    }
    eprintln!(
        "{touching} of {} planned touches have the hands in contact",
        plan.rows.len()
    );
    let off = ContactPlanConfig {
        collision_check: treecal::sim::CollisionCheck::Off,
        ..config.clone()
    };
    let unchecked = plan_contacts(&off, &no_progress).unwrap();
    assert!(
        !unchecked
            .notes
            .iter()
            .any(|n| n.text.contains("projected configurations rejected")),
        "{:?}",
        unchecked.notes
    );
}
