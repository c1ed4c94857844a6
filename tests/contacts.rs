//! Contacts as measurements (issue 29): each contact kind's Jacobian against finite
//! differences (robot and nuisance columns), and simulated contact calibrations on the built-in
//! robot: noise-free recovery in the observable subspace, errors consistent with the
//! covariance under encoder noise, the plane-height/face-offset alias held and named.

use crate::common;
use nalgebra::DMatrix;
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use treecal::calibration::observation::{kind_of, Nuisance, NuisanceBlock, RobotState, Tools};
use treecal::kinematics::ToolJacobian;
use treecal::math::{Pose, Vec3};
use treecal::measurement::{Contact, ContactFace, ContactPlane, Observation};
use treecal::sim::contacts::{run_contact_trial, ContactChoice, ContactSimulation};
use treecal::tree::KinematicTree;
use treecal::{detect_branches, load_urdf, McpcModel};

fn robonaut() -> (KinematicTree, McpcModel) {
    let tree = load_urdf(&common::robot("robonaut/robonaut.urdf"))
        .expect("robonaut loads")
        .tree;
    let branches = detect_branches(&tree, None).expect("branches");
    let model = McpcModel::from_tree(&tree, &branches).expect("model");
    (tree, model)
}

fn frame(t: [f64; 3], r: [f64; 3]) -> Pose {
    treecal::math::pose(
        Vec3::from(t),
        nalgebra::UnitQuaternion::from_scaled_axis(Vec3::from(r)),
    )
}

fn block(name: &str, values: Vec<f64>) -> NuisanceBlock {
    NuisanceBlock {
        name: name.into(),
        parameter_names: (0..values.len()).map(|k| k.to_string()).collect(),
        values,
    }
}

/// A nuisance vector (two contact points, a plane, a face, a bar) and one contact of each kind.
fn contacts(rng: &mut ChaCha8Rng) -> (Nuisance, Vec<Contact>) {
    let mut random = |n: usize, size: f64| -> Vec<f64> {
        (0..n).map(|_| rng.random_range(-size..size)).collect()
    };
    let nuisance = Nuisance {
        blocks: vec![
            block("point left", random(3, 0.1)),
            block("point right", random(3, 0.1)),
            block("plane", random(3, 0.2)),
            block("face", random(3, 0.2)),
            block("bar", vec![0.3]),
        ],
    };
    let plane = ContactPlane {
        block: 2,
        nominal: frame([0.3, -0.1, 0.4], [0.2, -0.3, 0.5]),
    };
    let face = ContactFace {
        block: 3,
        nominal: frame([0.01, 0.02, 0.05], [0.1, 0.2, -0.1]),
    };
    let all = vec![
        Contact::Flush { plane, face },
        Contact::Point { plane, point: 0 },
        Contact::Touch {
            point: 0,
            tool2: 1,
            point2: 1,
        },
        Contact::Distance {
            point: 0,
            tool2: 1,
            point2: 1,
            length: 4,
        },
    ];
    (nuisance, all)
}

fn residual(model: &McpcModel, nuisance: &Nuisance, q: &[f64], contact: &Contact) -> Vec<f64> {
    let poses = model.tool_poses(q);
    let observation = Observation::Contact(*contact);
    let kind = kind_of(&observation);
    let at = RobotState {
        model,
        q,
        tool: 0,
        tools: Tools::Poses(&poses),
        offset: None,
        nuisance,
    };
    let mut out = vec![0.0; kind.rows()];
    kind.residual(&at, &mut out).expect("residual");
    out
}

/// `∂predicted/∂θ` of every contact kind, robot and nuisance columns, against central
/// differences of the residual (`r = −predicted`).
#[test]
fn contact_jacobians_match_finite_differences() {
    let (_, nominal) = robonaut();
    let mut rng = ChaCha8Rng::seed_from_u64(29);
    let mut model = nominal.clone();
    let values: Vec<f64> = model
        .parameters()
        .iter()
        .map(|v| v + rng.random_range(-0.02..0.02))
        .collect();
    model.set_parameters(&values).expect("parameters");
    let (nuisance, all) = contacts(&mut rng);
    let q: Vec<f64> = (0..13).map(|_| rng.random_range(-1.0..1.0)).collect();
    let count = model.parameter_count();
    let columns: Vec<usize> = (0..count + nuisance.len()).collect();
    let tools: Vec<ToolJacobian> = model.tool_jacobians(&q);
    for contact in &all {
        let observation = Observation::Contact(*contact);
        let kind = kind_of(&observation);
        let at = RobotState {
            model: &model,
            q: &q,
            tool: 0,
            tools: Tools::Jacobians(&tools),
            offset: None,
            nuisance: &nuisance,
        };
        let mut analytic = DMatrix::zeros(kind.rows(), columns.len());
        kind.jacobian(
            &at,
            &columns,
            &mut analytic.view_mut((0, 0), (kind.rows(), columns.len())),
        )
        .expect("jacobian");
        let h = 1e-6;
        let mut numeric = DMatrix::zeros(kind.rows(), columns.len());
        for &c in &columns {
            let (mut plus_model, mut minus_model) = (model.clone(), model.clone());
            let (mut plus_nuisance, mut minus_nuisance) = (nuisance.clone(), nuisance.clone());
            if c < count {
                plus_model.set_parameter(c, values[c] + h).expect("set");
                minus_model.set_parameter(c, values[c] - h).expect("set");
            } else {
                let mut v = nuisance.values();
                v[c - count] += h;
                plus_nuisance.set_values(&v).expect("set");
                v[c - count] -= 2.0 * h;
                minus_nuisance.set_values(&v).expect("set");
            }
            let plus = residual(&plus_model, &plus_nuisance, &q, contact);
            let minus = residual(&minus_model, &minus_nuisance, &q, contact);
            for k in 0..kind.rows() {
                numeric[(k, c)] = -(plus[k] - minus[k]) / (2.0 * h);
            }
        }
        let difference = (&analytic - &numeric).amax();
        assert!(
            difference < 1e-7 * numeric.amax().max(1.0),
            "{}: analytic and numeric Jacobians differ by {difference:e}",
            kind.name()
        );
        assert!(analytic.amax() > 0.0, "{}: zero Jacobian", kind.name());
        // The tool motion Jacobian chained with the tool Jacobians gives the robot columns.
        let mut chained = DMatrix::<f64>::zeros(kind.rows(), count);
        for (tool, jacobian) in tools.iter().enumerate() {
            chained += kind.tool_motion_jacobian(&at, tool) * jacobian.jacobian.rows(0, 6);
        }
        assert!((&chained - analytic.columns(0, count)).amax() < 1e-12);
    }
}

fn trial(
    kinds: &[ContactChoice],
    encoder_sigma: f64,
    seed: u64,
) -> treecal::sim::contacts::ContactTrial {
    let (tree, nominal) = robonaut();
    let settings = ContactSimulation {
        kinds: kinds.to_vec(),
        encoder_sigma,
        ..ContactSimulation::default()
    };
    run_contact_trial(&tree, &nominal, &settings, seed).expect("trial")
}

/// Noise-free touch + bar, flush, and point contacts on the built-in robot: the fit predicts
/// held-out contacts of the true robot to 1e-6 (it recovered what contacts determine).
#[test]
fn noise_free_contacts_recover_the_observable_subspace() {
    for (kinds, seed) in [
        (vec![ContactChoice::Touch, ContactChoice::Bar], 1),
        (vec![ContactChoice::Flush], 2),
        (vec![ContactChoice::Plane], 3),
        (
            vec![
                ContactChoice::Touch,
                ContactChoice::Bar,
                ContactChoice::Plane,
            ],
            4,
        ),
    ] {
        let result = trial(&kinds, 0.0, seed);
        eprintln!(
            "{kinds:?}: rank {} of {}, held-out contact residual {:e}, cost {:e}, {:?}",
            result.rank,
            result.free.len(),
            result.noise_free_held_out,
            result.report.costs.last().copied().unwrap_or(f64::NAN),
            result.report.termination,
        );
        assert!(result.rank > 0);
        assert!(
            result.noise_free_held_out < 1e-6,
            "{kinds:?}: held-out contacts off by {:e}",
            result.noise_free_held_out
        );
        assert!(result.observable_error < 1e-9);
    }
}

/// With encoder noise, touch + bar errors in the observable directions are as large as the
/// fit's covariance says (within 1.5×), over five trials. (Flush is not yet: three of five
/// trials are 27–53× off; see `docs/contacts.md`.)
#[test]
fn encoder_noise_errors_match_the_covariance() {
    let kinds = [ContactChoice::Touch, ContactChoice::Bar];
    let ratios: Vec<f64> = (0..5)
        .map(|seed| trial(&kinds, 1e-4, 100 + seed).consistency)
        .collect();
    let mean = (ratios.iter().map(|r| r * r).sum::<f64>() / ratios.len() as f64).sqrt();
    eprintln!("{kinds:?}: consistency per trial {ratios:?}, overall {mean:.3}");
    assert!(
        (1.0 / 1.5..=1.5).contains(&mean),
        "{kinds:?}: observable errors are {mean:.2}× the covariance's"
    );
}

/// A flush contact cannot tell the plane's height from the face's offset along its normal:
/// with both free, the fit names that combination instead of splitting it.
#[test]
fn flush_names_the_height_offset_alias() {
    let (tree, nominal) = robonaut();
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let settings = ContactSimulation {
        kinds: vec![ContactChoice::Flush],
        per_kind: 30,
        ..ContactSimulation::default()
    };
    let scene =
        treecal::sim::contacts::contact_scene(&tree, &nominal, &settings, &mut rng).expect("scene");
    let count = nominal.parameter_count();
    let face = scene.nuisance.block("face left_tool").expect("face block");
    let offset = scene.nuisance.offset(face);
    let mut free: Vec<usize> = scene.free_nuisance.iter().map(|k| count + k).collect();
    free.push(count + offset);
    free.sort_unstable();
    let report = treecal::calibration::identify_with_nuisance(
        &nominal,
        &scene.nuisance,
        &scene.measurements,
        None,
        &treecal::calibration::Rigid,
        &free,
        &Default::default(),
    )
    .expect("fit");
    let named: Vec<String> = report
        .unidentifiable
        .iter()
        .map(|c| c.describe_with(&nominal, &tree, &scene.nuisance))
        .collect();
    assert!(
        named
            .iter()
            .any(|n| n.contains("plane flush height") && n.contains("face left_tool offset")),
        "{named:?}"
    );
}
