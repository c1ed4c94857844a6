//! The flexibility model: cantilever formulas against integrated curvature, joint-compliance
//! direction, hand-checked single-link cases, linear map vs deflected kinematics (O(ε²)),
//! stiffness-file errors, and the size of the effect on Robonaut.

use crate::common::*;
use nalgebra::Vector6;
use rand::RngExt;
use treecal::kinematics::McpcModel;
use treecal::kinematics::{
    point_load_deflection, uniform_load_deflection, BeamCompliance, FlexibilityModel,
    JointStiffness, LinkStiffness, Payload, Stiffness,
};
use treecal::math::{pose, pose_error, rot_x, rot_z, Vec3};
use treecal::tree::{detect_branches, KinematicTree};
use treecal::Error;

const G: f64 = treecal::kinematics::STANDARD_GRAVITY;

fn robonaut_stiffness(tree: &KinematicTree, model: &McpcModel) -> Stiffness {
    treecal::io::read_stiffness(&robot("robonaut/stiffness.yaml"), tree, model).unwrap()
}

// ---------------------------------------------------------------------------------------------
// Cantilever formulas against an independent computation: the section rotation ψ(s) is the
// integral of the curvature C·m(s), m(s) the moment about the section of the loads beyond it
// (statics only), and the displacement is the integral of ψ(s) × x plus the axial strain.

/// Tip [u; ψ] of a cantilever by integrating, with the trapezoid rule on `steps` intervals per
/// piece, the internal moment `moment(s)` and axial force `axial(s)`; `breaks` split the beam
/// where the load is discontinuous.
fn integrate(
    length: f64,
    compliance: &BeamCompliance,
    breaks: &[f64],
    moment: impl Fn(f64) -> Vec3,
    axial: impl Fn(f64) -> f64,
) -> Vector6<f64> {
    let curvature = |s: f64| {
        let m = moment(s);
        Vec3::new(
            m.x * compliance.torsion,
            m.y * compliance.bending_y,
            m.z * compliance.bending_z,
        )
    };
    let mut points = vec![0.0];
    points.extend(breaks.iter().copied().filter(|b| *b > 0.0 && *b < length));
    points.push(length);
    let steps = 4000;
    let (mut psi, mut u) = (Vec3::zeros(), Vec3::zeros());
    for piece in points.windows(2) {
        let h = (piece[1] - piece[0]) / steps as f64;
        // Evaluate just inside the piece so a point load at its end belongs to it.
        let inside = |k: usize| piece[0] + h * k as f64 - if k == steps { 1e-12 } else { -1e-12 };
        for k in 0..steps {
            let (s0, s1) = (inside(k), inside(k + 1));
            let psi_next = psi + (curvature(s0) + curvature(s1)) * h / 2.0;
            let slope =
                |p: &Vec3, s: f64| p.cross(&Vec3::x()) + Vec3::x() * axial(s) * compliance.axial;
            u += (slope(&psi, s0) + slope(&psi_next, s1)) * h / 2.0;
            psi = psi_next;
        }
    }
    Vector6::new(u.x, u.y, u.z, psi.x, psi.y, psi.z)
}

fn random_compliance(rng: &mut impl RngExt) -> BeamCompliance {
    BeamCompliance {
        axial: rng.random_range(0.5..2.0) * 1e-6,
        bending_y: rng.random_range(0.5..2.0) * 1e-3,
        bending_z: rng.random_range(0.5..2.0) * 1e-3,
        torsion: rng.random_range(0.5..2.0) * 1e-3,
    }
}

fn random_vector(rng: &mut impl RngExt, scale: f64) -> Vec3 {
    Vec3::new(
        rng.random_range(-scale..scale),
        rng.random_range(-scale..scale),
        rng.random_range(-scale..scale),
    )
}

#[track_caller]
fn assert_close(a: &Vector6<f64>, b: &Vector6<f64>, relative: f64, what: &str) {
    let error = (a - b).norm();
    assert!(
        error <= relative * b.norm().max(1e-12),
        "{what}: {a:?} vs {b:?} (error {error:e})"
    );
}

#[test]
fn point_load_formulas_match_integrated_curvature() {
    let mut rng = rng(31);
    for _ in 0..20 {
        let length = rng.random_range(0.1..1.0);
        let station = if rng.random_bool(0.3) {
            length
        } else {
            rng.random_range(0.0..length)
        };
        let compliance = random_compliance(&mut rng);
        let force = random_vector(&mut rng, 200.0);
        let moment = random_vector(&mut rng, 50.0);
        let closed = point_load_deflection(length, &compliance, station, &force, &moment);
        let numeric = integrate(
            length,
            &compliance,
            &[station],
            |s| {
                if s < station {
                    moment + (Vec3::x() * (station - s)).cross(&force)
                } else {
                    Vec3::zeros()
                }
            },
            |s| if s < station { force.x } else { 0.0 },
        );
        assert_close(&closed, &numeric, 1e-6, "point load");
    }
}

#[test]
fn uniform_load_formulas_match_integrated_curvature() {
    let mut rng = rng(32);
    for _ in 0..10 {
        let length = rng.random_range(0.1..1.0);
        let compliance = random_compliance(&mut rng);
        let per_length = random_vector(&mut rng, 300.0);
        let closed = uniform_load_deflection(length, &compliance, &per_length);
        let numeric = integrate(
            length,
            &compliance,
            &[],
            |s| (Vec3::x() * (length - s)).cross(&per_length) * (length - s) / 2.0,
            |s| per_length.x * (length - s),
        );
        assert_close(&closed, &numeric, 1e-6, "uniform load");
    }
}

/// The textbook tip-load values, one load at a time, with EI_y ≠ EI_z so a swapped pairing
/// (as in the paper's eq. (21)) would show.
#[test]
fn tip_load_formulas_are_the_textbook_ones() {
    let (l, ea, eiy, eiz, gj) = (0.4, 4e7, 2e4, 3e4, 1.5e4);
    let c = BeamCompliance::from_stiffness(&LinkStiffness {
        axial: ea,
        bending_y: eiy,
        bending_z: eiz,
        torsion: gj,
    });
    let tip = |f: Vec3, m: Vec3| point_load_deflection(l, &c, l, &f, &m);
    let (f, m) = (100.0, 30.0);
    let cases = [
        (
            tip(Vec3::x() * f, Vec3::zeros()),
            [f * l / ea, 0., 0., 0., 0., 0.],
        ),
        (
            tip(Vec3::y() * f, Vec3::zeros()),
            [
                0.,
                f * l.powi(3) / (3. * eiz),
                0.,
                0.,
                0.,
                f * l * l / (2. * eiz),
            ],
        ),
        (
            tip(Vec3::z() * f, Vec3::zeros()),
            [
                0.,
                0.,
                f * l.powi(3) / (3. * eiy),
                0.,
                -f * l * l / (2. * eiy),
                0.,
            ],
        ),
        (
            tip(Vec3::zeros(), Vec3::x() * m),
            [0., 0., 0., m * l / gj, 0., 0.],
        ),
        (
            tip(Vec3::zeros(), Vec3::y() * m),
            [0., 0., -m * l * l / (2. * eiy), 0., m * l / eiy, 0.],
        ),
        (
            tip(Vec3::zeros(), Vec3::z() * m),
            [0., m * l * l / (2. * eiz), 0., 0., 0., m * l / eiz],
        ),
    ];
    for (index, (got, expected)) in cases.iter().enumerate() {
        assert_close(
            got,
            &Vector6::from_row_slice(expected),
            1e-14,
            &format!("case {index}"),
        );
    }
    let q = 50.0;
    assert_close(
        &uniform_load_deflection(l, &c, &(Vec3::z() * q)),
        &Vector6::new(
            0.,
            0.,
            q * l.powi(4) / (8. * eiy),
            0.,
            -q * l.powi(3) / (6. * eiy),
            0.,
        ),
        1e-14,
        "uniform z",
    );
}

/// Maxwell–Betti: the tip compliance matrix (tip [u; ψ] per unit tip [force; moment]) is
/// symmetric and positive definite. The paper's eq. (21) is not symmetric: it has ∂Δγ/∂f_y =
/// l²/2EI but ∂Δy/∂τ_z = 0, and ∂Δβ/∂f_z = +l²/2EI against ∂Δz/∂τ_y = 0.
#[test]
fn tip_compliance_is_symmetric_and_positive() {
    let mut rng = rng(33);
    for _ in 0..10 {
        let length = rng.random_range(0.1..1.0);
        let compliance = random_compliance(&mut rng);
        let columns: Vec<Vector6<f64>> = (0..6)
            .map(|k| {
                let mut load = Vector6::zeros();
                load[k] = 1.0;
                point_load_deflection(
                    length,
                    &compliance,
                    length,
                    &load.fixed_rows::<3>(0).into_owned(),
                    &load.fixed_rows::<3>(3).into_owned(),
                )
            })
            .collect();
        let matrix = nalgebra::Matrix6::from_columns(&columns);
        let asymmetry = (matrix - matrix.transpose()).norm();
        assert!(asymmetry <= 1e-15 * matrix.norm(), "{matrix}");
        assert!(
            matrix.cholesky().is_some(),
            "not positive definite: {matrix}"
        );
    }
}

// ---------------------------------------------------------------------------------------------
// Hand-checkable robots: one revolute joint, one link of length L along x, a tool at its end.

const L: f64 = 0.6;

/// A single link along x with its joint at the origin turning about `axis`; the tool sits at
/// the far end, optionally `tool_offset` further, and the link has mass `link_mass` at L/2.
fn single_link(axis: &str, tool_offset: &str, link_mass: f64) -> (KinematicTree, McpcModel) {
    let inertial = if link_mass > 0.0 {
        format!(
            r#"<inertial><origin xyz="{} 0 0" rpy="0 0 0"/><mass value="{link_mass}"/>
               <inertia ixx="1e-3" ixy="0" ixz="0" iyy="1e-3" iyz="0" izz="1e-3"/></inertial>"#,
            L / 2.0
        )
    } else {
        String::new()
    };
    let text = format!(
        r#"<robot name="single">
             <link name="base_link"/>
             <link name="link1">{inertial}</link>
             <link name="tool"/>
             <joint name="joint1" type="revolute">
               <parent link="base_link"/><child link="link1"/>
               <origin xyz="0 0 0" rpy="0 0 0"/><axis xyz="{axis}"/>
               <limit lower="-3" upper="3" effort="1" velocity="1"/>
             </joint>
             <joint name="tool_joint" type="fixed">
               <parent link="link1"/><child link="tool"/>
               <origin xyz="{tool_offset}" rpy="0 0 0"/>
             </joint>
           </robot>"#
    );
    let tree = treecal::parse_urdf(&text, "single").unwrap().tree;
    let tool = tree.link_id("tool").unwrap();
    let branches = detect_branches(&tree, Some(&[tool])).unwrap();
    let model = McpcModel::from_tree(&tree, &branches).unwrap();
    (tree, model)
}

const KB: f64 = 3000.0;
const KT: f64 = 7000.0;
const LINK: LinkStiffness = LinkStiffness {
    axial: 2e7,
    bending_y: 1.0e4,
    bending_z: 2.5e4,
    torsion: 8e3,
};

fn single_link_stiffness(payload: f64, center_of_mass: Vec3, self_weight: bool) -> Stiffness {
    Stiffness {
        self_weight,
        payloads: vec![Payload {
            link: "tool".into(),
            mass: payload,
            center_of_mass,
        }],
        joint_default: JointStiffness {
            bending: KB,
            torsion: KT,
        },
        link_default: LINK,
        ..Stiffness::default()
    }
}

fn deflection_of(tree: &KinematicTree, model: &McpcModel, stiffness: &Stiffness) -> Vector6<f64> {
    let flexibility = FlexibilityModel::new(tree, model, stiffness).unwrap();
    let q = tree.zero_configuration();
    let linear = flexibility.tool_deflections(tree, model, &q).unwrap()[0];
    // The deflected kinematics agree to first order; at these loads that is ~1e-7.
    let deflected = flexibility.deflected_tool_poses(tree, model, &q).unwrap()[0];
    let exact = pose_error(&deflected, &model.tool_poses(&q)[0]);
    assert_close(&exact, &linear, 0.05, "deflected vs linear");
    linear
}

/// Horizontal link, horizontal joint axis (y): the payload's moment m·g·L is torsion of the
/// joint (k_T), and the link bends in the plane of the joint's motion, about the beam z = the
/// joint axis (EI_z):  drop = m g (L²/k_T + L³/3EI_z),  tilt about +y = m g (L/k_T + L²/2EI_z).
#[test]
fn horizontal_link_about_a_horizontal_axis_by_hand() {
    let (tree, model) = single_link("0 1 0", &format!("{L} 0 0"), 0.0);
    let m = 20.0;
    let got = deflection_of(
        &tree,
        &model,
        &single_link_stiffness(m, Vec3::zeros(), false),
    );
    let (w, l) = (m * G, L);
    let expected = Vector6::new(
        0.0,
        0.0,
        -w * (l * l / KT + l.powi(3) / (3.0 * LINK.bending_z)),
        0.0,
        w * (l / KT + l * l / (2.0 * LINK.bending_z)),
        0.0,
    );
    println!("horizontal axis: D_f = {got:?}, by hand {expected:?}");
    assert_close(&got, &expected, 1e-12, "horizontal axis");
}

/// Horizontal link, vertical joint axis (z): the moment bends the joint (k_B) and the link
/// bends out of the plane of the joint's motion, about the beam y (EI_y).
#[test]
fn horizontal_link_about_a_vertical_axis_by_hand() {
    let (tree, model) = single_link("0 0 1", &format!("{L} 0 0"), 0.0);
    let m = 20.0;
    let got = deflection_of(
        &tree,
        &model,
        &single_link_stiffness(m, Vec3::zeros(), false),
    );
    let (w, l) = (m * G, L);
    let expected = Vector6::new(
        0.0,
        0.0,
        -w * (l * l / KB + l.powi(3) / (3.0 * LINK.bending_y)),
        0.0,
        w * (l / KB + l * l / (2.0 * LINK.bending_y)),
        0.0,
    );
    assert_close(&got, &expected, 1e-12, "vertical axis");
}

/// The link's own weight m_l at L/2, as a point load at its centre of mass: the joint carries
/// m_l g L/2, the beam P a²(3L − a)/6EI = 5 P L³/48EI of drop and P a²/2EI = P L²/8EI of tilt.
#[test]
fn self_weight_by_hand() {
    let (tree, model) = single_link("0 1 0", &format!("{L} 0 0"), 3.0);
    let got = deflection_of(
        &tree,
        &model,
        &single_link_stiffness(0.0, Vec3::zeros(), true),
    );
    let (p, l) = (3.0 * G, L);
    let expected = Vector6::new(
        0.0,
        0.0,
        -p * (l / 2.0 * l / KT + 5.0 * l.powi(3) / (48.0 * LINK.bending_z)),
        0.0,
        p * (l / 2.0 / KT + l * l / (8.0 * LINK.bending_z)),
        0.0,
    );
    assert_close(&got, &expected, 1e-12, "self weight");
    // Switched off, the same robot does not deflect.
    let off = deflection_of(
        &tree,
        &model,
        &single_link_stiffness(0.0, Vec3::zeros(), false),
    );
    assert_eq!(off, Vector6::zeros());
}

/// A vertical link shortens by m g L/EA; the joint carries no moment.
#[test]
fn axial_compression_by_hand() {
    let (tree, model) = single_link("1 0 0", &format!("0 0 {L}"), 0.0);
    let m = 20.0;
    let got = deflection_of(
        &tree,
        &model,
        &single_link_stiffness(m, Vec3::zeros(), false),
    );
    let expected = Vector6::new(0.0, 0.0, -m * G * L / LINK.axial, 0.0, 0.0, 0.0);
    assert_close(&got, &expected, 1e-10, "axial");
}

/// A payload offset sideways by d twists the link (m g d L/GI_p about the link axis) and bends
/// the joint about both transverse axes.
#[test]
fn torsion_by_hand() {
    let (tree, model) = single_link("0 0 1", &format!("{L} 0 0"), 0.0);
    let (m, d) = (20.0, 0.1);
    let got = deflection_of(
        &tree,
        &model,
        &single_link_stiffness(m, Vec3::new(0.0, d, 0.0), false),
    );
    let (w, l) = (m * G, L);
    let expected = Vector6::new(
        0.0,
        0.0,
        -w * (l * l / KB + l.powi(3) / (3.0 * LINK.bending_y)),
        -w * d * (1.0 / KB + l / LINK.torsion),
        w * (l / KB + l * l / (2.0 * LINK.bending_y)),
        0.0,
    );
    assert_close(&got, &expected, 1e-12, "torsion");
}

/// Joint compliance turns each joint in the direction of the moment it carries (δ = C·τ with
/// C positive definite), and a tip load always lowers the tool.
#[test]
fn joints_deflect_in_the_direction_of_their_moment() {
    let (tree, model) = robot_model("robonaut/robonaut.urdf");
    let stiffness = robonaut_stiffness(&tree, &model);
    let flexibility = FlexibilityModel::new(&tree, &model, &stiffness).unwrap();
    let mut rng = rng(7);
    for _ in 0..20 {
        let q = random_configuration(&tree, &mut rng);
        let deformations = flexibility.deformations(&tree, &model, &q).unwrap();
        for (index, joint) in deformations.joints.iter().enumerate() {
            let along = joint.rotation.dot(&joint.moment);
            assert!(
                along >= 0.0,
                "joint {index}: rotation {:?} against moment {:?}",
                joint.rotation,
                joint.moment
            );
            // Under k_B = k_T = 5000 N·m/rad the rotation is exactly the moment over 5000.
            assert!(
                (joint.rotation - joint.moment / 5000.0).norm()
                    < 1e-15 * joint.moment.norm().max(1.0)
            );
        }
    }
    // The single link: a payload lowers the tool whichever way the joint axis points.
    for axis in ["0 1 0", "0 0 1", "1 0 1", "0 -1 0"] {
        let (tree, model) = single_link(axis, &format!("{L} 0 0"), 0.0);
        let got = deflection_of(
            &tree,
            &model,
            &single_link_stiffness(10.0, Vec3::zeros(), false),
        );
        assert!(got.z < 0.0 && got[4] > 0.0, "axis {axis}: {got:?}");
    }
}

// ---------------------------------------------------------------------------------------------
// Loads and the two ways of applying the deformations.

/// Every joint carries the weight of everything after it: at the robot's first joints that is
/// every mass that is not part of the base, head and fingers included.
#[test]
fn joints_carry_everything_distal() {
    let (tree, model) = robot_model("humanoid/humanoid.urdf");
    let flexibility = FlexibilityModel::new(&tree, &model, &Stiffness::default()).unwrap();
    let q = random_configuration(&tree, &mut rng(3));
    let deformations = flexibility.deformations(&tree, &model, &q).unwrap();
    let waist = tree.link_id("waist_link").unwrap();
    let distal: f64 = tree
        .links()
        .iter()
        .enumerate()
        .filter(|(i, _)| tree.is_ancestor(waist, treecal::tree::LinkId(*i)))
        .filter_map(|(_, l)| l.inertial.as_ref().map(|i| i.mass))
        .sum();
    assert!(
        (flexibility.total_mass() - distal).abs() < 1e-12,
        "{distal}"
    );
    let first = model
        .frame_of_joint(tree.joint_id("waist_yaw").unwrap())
        .unwrap();
    let force = deformations.joints[first].force;
    assert!(
        (force - Vec3::new(0.0, 0.0, -distal * G)).norm() < 1e-9,
        "{force:?}"
    );
    // The head is off the calibrated branches but its weight still bends the waist: moving
    // the neck changes the tools' deflections.
    let mut moved = q.clone();
    let neck = tree.dof_of(tree.joint_id("neck_pitch").unwrap()).unwrap();
    moved[neck.0] += 0.5;
    let before = flexibility.tool_deflections(&tree, &model, &q).unwrap();
    let after = flexibility.tool_deflections(&tree, &model, &moved).unwrap();
    assert!((before[0] - after[0]).norm() > 1e-9);
}

/// ‖deflected − nominal − D_f‖ for every tool at `q` with compliances scaled by `epsilon`.
fn second_order_residual(
    tree: &KinematicTree,
    model: &McpcModel,
    flexibility: &FlexibilityModel,
    q: &[f64],
    epsilon: f64,
) -> (f64, f64) {
    let scaled = flexibility.scaled(epsilon).unwrap();
    let linear = scaled.tool_deflections(tree, model, q).unwrap();
    let deflected = scaled.deflected_tool_poses(tree, model, q).unwrap();
    let nominal = model.tool_poses(q);
    let mut residual: f64 = 0.0;
    let mut size: f64 = 0.0;
    for tool in 0..nominal.len() {
        residual =
            residual.max((pose_error(&deflected[tool], &nominal[tool]) - linear[tool]).norm());
        size = size.max(linear[tool].norm());
    }
    (residual, size)
}

fn check_first_order(tree: &KinematicTree, model: &McpcModel, stiffness: &Stiffness, what: &str) {
    let flexibility = FlexibilityModel::new(tree, model, stiffness).unwrap();
    let mut rng = rng(11);
    let mut worst = (0.0_f64, 0.0_f64, f64::INFINITY, 0.0_f64);
    for _ in 0..10 {
        let q = random_configuration(tree, &mut rng);
        let (r1, size) = second_order_residual(tree, model, &flexibility, &q, 1.0);
        let (r2, _) = second_order_residual(tree, model, &flexibility, &q, 0.1);
        let (r3, _) = second_order_residual(tree, model, &flexibility, &q, 0.01);
        worst = (
            worst.0.max(r1 / size),
            worst.1.max(r1),
            worst.2.min((r1 / r2).min(r2 / r3)),
            worst.3.max((r1 / r2).max(r2 / r3)),
        );
        assert!(size > 1e-6, "{what}: no deflection at all");
        // Second order: 10× smaller compliance, ~100× smaller residual.
        for (ratio, pair) in [(r1 / r2, "1 → 0.1"), (r2 / r3, "0.1 → 0.01")] {
            assert!(
                (70.0..140.0).contains(&ratio),
                "{what}: residual ratio {ratio} for ε {pair} (residuals {r1:e} {r2:e} {r3:e}, D_f {size:e})"
            );
        }
        assert!(r1 < 0.1 * size, "{what}: residual {r1:e} vs D_f {size:e}");
    }
    println!(
        "{what}: at ε = 1 the second-order part is up to {:.1} % of D_f ({:.2} mm); residual ratios per 10× in ε: {:.0}–{:.0}",
        worst.0 * 100.0,
        worst.1 * 1e3,
        worst.2,
        worst.3
    );
}

#[test]
fn linear_map_agrees_with_deflected_kinematics_to_first_order() {
    let (tree, model) = robot_model("robonaut/robonaut.urdf");
    check_first_order(
        &tree,
        &model,
        &robonaut_stiffness(&tree, &model),
        "robonaut",
    );
    let (tree, model) = robot_model("humanoid/humanoid.urdf");
    check_first_order(&tree, &model, &Stiffness::default(), "humanoid");
    let (tree, model) = robot_model("dual_arm_prismatic/dual_arm_prismatic.urdf");
    let stiffness = Stiffness {
        link_overrides: vec![(
            model_joint_name(&tree, &model, 0),
            LinkStiffness {
                bending_y: 1e4,
                ..LinkStiffness::default()
            },
        )],
        ..Stiffness::default()
    };
    check_first_order(&tree, &model, &stiffness, "dual arm prismatic");
}

fn model_joint_name(tree: &KinematicTree, model: &McpcModel, frame: usize) -> String {
    tree.joint(model.frames()[frame].joint).name.clone()
}

/// D_f is linear in the compliances, so scaling them scales D_f exactly.
#[test]
fn scaling_compliance_scales_the_linear_deflection() {
    let (tree, model) = robot_model("robonaut/robonaut.urdf");
    let flexibility =
        FlexibilityModel::new(&tree, &model, &robonaut_stiffness(&tree, &model)).unwrap();
    let q = random_configuration(&tree, &mut rng(2));
    let base = flexibility.tool_deflections(&tree, &model, &q).unwrap();
    let softer = flexibility
        .scaled(1.1)
        .unwrap()
        .tool_deflections(&tree, &model, &q)
        .unwrap();
    for (a, b) in base.iter().zip(&softer) {
        assert_close(b, &(a * 1.1), 1e-12, "scaled");
    }
    let rigid = flexibility.scaled(0.0).unwrap();
    assert!(rigid
        .tool_deflections(&tree, &model, &q)
        .unwrap()
        .iter()
        .all(|d| d.norm() == 0.0));
    assert!(flexibility.scaled(-1.0).is_err() && flexibility.scaled(f64::NAN).is_err());
}

#[test]
fn zero_gravity_means_no_deflection() {
    for (relative, stiffness) in [
        ("robonaut/robonaut.urdf", true),
        ("humanoid/humanoid.urdf", false),
    ] {
        let (tree, model) = robot_model(relative);
        let mut stiffness = if stiffness {
            robonaut_stiffness(&tree, &model)
        } else {
            Stiffness::default()
        };
        stiffness.gravity = Vec3::zeros();
        let flexibility = FlexibilityModel::new(&tree, &model, &stiffness).unwrap();
        let q = random_configuration(&tree, &mut rng(4));
        for d in flexibility.tool_deflections(&tree, &model, &q).unwrap() {
            assert_eq!(d, Vector6::zeros());
        }
        for (deflected, nominal) in flexibility
            .deflected_tool_poses(&tree, &model, &q)
            .unwrap()
            .iter()
            .zip(model.tool_poses(&q))
        {
            assert_pose_eq(deflected, &nominal, 1e-15, relative);
        }
    }
}

/// With a measurement frame set on the model, D_f is in that frame (like the identification
/// Jacobian) and gravity still points down in the root frame: D_f turns with the frame.
#[test]
fn deflection_follows_the_measurement_frame() {
    let (tree, mut model) = robot_model("robonaut/robonaut.urdf");
    let flexibility =
        FlexibilityModel::new(&tree, &model, &robonaut_stiffness(&tree, &model)).unwrap();
    let q = random_configuration(&tree, &mut rng(9));
    let in_base = flexibility.tool_deflections(&tree, &model, &q).unwrap();
    let world_from_base = pose(Vec3::new(1.0, -2.0, 0.5), rot_z(0.7) * rot_x(-0.4));
    model.set_world_from_base(&world_from_base);
    let in_world = flexibility.tool_deflections(&tree, &model, &q).unwrap();
    let rotation = world_from_base.rotation;
    for (b, w) in in_base.iter().zip(&in_world) {
        let turned = Vector6::from_iterator(
            (rotation * b.fixed_rows::<3>(0).into_owned())
                .iter()
                .chain((rotation * b.fixed_rows::<3>(3).into_owned()).iter())
                .copied(),
        );
        assert_close(w, &turned, 1e-12, "measurement frame");
    }
    let deflected = flexibility.deflected_tool_poses(&tree, &model, &q).unwrap();
    let nominal = model.tool_poses(&q);
    for tool in 0..2 {
        let error = pose_error(&deflected[tool], &nominal[tool]);
        assert_close(&error, &in_world[tool], 0.1, "deflected in world");
    }
}

#[test]
fn wrong_configuration_or_model_is_an_error() {
    let (tree, model) = robot_model("robonaut/robonaut.urdf");
    let flexibility = FlexibilityModel::new(&tree, &model, &Stiffness::default()).unwrap();
    let short = vec![0.0; tree.dof_count() - 1];
    assert!(matches!(
        flexibility.tool_deflections(&tree, &model, &short),
        Err(Error::ConfigurationSize { .. })
    ));
    let (other_tree, other_model) = robot_model("humanoid/humanoid.urdf");
    let q = other_tree.zero_configuration();
    let error = flexibility
        .tool_deflections(&other_tree, &other_model, &q)
        .unwrap_err()
        .to_string();
    assert!(error.contains("build it again"), "{error}");
}

// ---------------------------------------------------------------------------------------------
// The stiffness file.

#[test]
fn robonaut_stiffness_file_is_the_papers_setup() {
    let (tree, model) = robot_model("robonaut/robonaut.urdf");
    let stiffness = robonaut_stiffness(&tree, &model);
    assert_eq!(stiffness.gravity, Vec3::new(0.0, 0.0, -9.81));
    assert!(stiffness.self_weight);
    let mut payloads: Vec<(&str, f64)> = stiffness
        .payloads
        .iter()
        .map(|p| (p.link.as_str(), p.mass))
        .collect();
    payloads.sort_by(|a, b| a.0.cmp(b.0));
    assert_eq!(payloads, [("left_tool", 20.0), ("right_tool", 20.0)]);
    assert_eq!(
        stiffness.joint_default,
        JointStiffness {
            bending: 5000.0,
            torsion: 5000.0
        }
    );
    // The file's link numbers are the Ø70 × 3 mm aluminium tube, rounded to 4 digits.
    let tube = LinkStiffness::tube(0.070, 0.003, 70e9, 26e9);
    let link = stiffness.link_default;
    for (file, exact) in [
        (link.axial, tube.axial),
        (link.bending_y, tube.bending_y),
        (link.bending_z, tube.bending_z),
        (link.torsion, tube.torsion),
    ] {
        assert!((file / exact - 1.0).abs() < 1e-3, "{file} vs {exact}");
    }
}

const ROBONAUT_YAML: &str = "\
gravity_m_per_s2: [0, 0, -9.81]
self_weight: true
payloads:
  left_tool: {mass_kg: 20}
joints:
  default: {bending_nm_per_rad: 5000, torsion_nm_per_rad: 5000}
  overrides:
    left_joint2: {bending_nm_per_rad: 8000}
links:
  default: {ea_n: 4.4e7, ei_y_nm2: 2.5e4, ei_z_nm2: 2.5e4, gi_p_nm2: 1.8e4}
  overrides:
    left_link3: {ei_y_nm2: 3.0e4}
";

fn parse(text: &str) -> Result<Stiffness, Error> {
    let (tree, model) = robot_model("robonaut/robonaut.urdf");
    treecal::io::parse_stiffness(text, "stiffness.yaml", &tree, &model)
}

#[track_caller]
fn assert_error(text: &str, place: &str, words: &[&str]) {
    let error = parse(text).expect_err("should fail").to_string();
    println!("{error}");
    assert!(
        error.starts_with(place),
        "expected '{place}' at the start of: {error}"
    );
    for word in words {
        assert!(error.contains(word), "expected '{word}' in: {error}");
    }
}

#[test]
fn stiffness_file_overrides_and_defaults() {
    let stiffness = parse(ROBONAUT_YAML).unwrap();
    assert_eq!(
        stiffness.joint_overrides,
        [(
            "left_joint2".to_owned(),
            JointStiffness {
                bending: 8000.0,
                torsion: 5000.0
            }
        )]
    );
    let (name, link) = &stiffness.link_overrides[0];
    assert_eq!(
        (name.as_str(), link.bending_y, link.bending_z),
        ("left_link3", 3.0e4, 2.5e4)
    );
    // Everything optional: an empty mapping is the library default.
    assert_eq!(parse("{}").unwrap(), Stiffness::default());
    // `.inf` is rigid.
    let rigid = parse("links: {default: {ea_n: .inf}}").unwrap();
    assert_eq!(rigid.link_default.axial, f64::INFINITY);
    // Links may be named by the joint that moves them.
    let by_joint = parse("links: {overrides: {left_joint3: {ei_z_nm2: 1.0e4}}}").unwrap();
    assert_eq!(by_joint.link_overrides[0].1.bending_z, 1.0e4);
}

/// The example in docs/flexibility.md reads.
#[test]
fn documented_example_reads() {
    let doc = std::fs::read_to_string(repo().join("docs/flexibility.md")).unwrap();
    let example = doc
        .split("```yaml\n")
        .nth(1)
        .and_then(|rest| rest.split("```").next())
        .unwrap();
    let stiffness = parse(example).unwrap();
    assert_eq!(
        stiffness.payloads[1].center_of_mass,
        Vec3::new(0.0, 0.0, 0.05)
    );
    assert_eq!(stiffness.joint_overrides[0].1.bending, 20000.0);
    assert_eq!(stiffness.link_overrides[0].1.bending_y, 3.0e4);
}

#[test]
fn stiffness_file_errors_name_file_line_and_fix() {
    let replace = |from: &str, to: &str| ROBONAUT_YAML.replace(from, to);
    // Unknown names, with did-you-mean, at the key's line.
    assert_error(
        &replace("    left_joint2:", "    left_jiont2:"),
        "stiffness.yaml:8:5",
        &[
            "joints.overrides",
            "unknown joint 'left_jiont2'",
            "did you mean 'left_joint2'?",
        ],
    );
    assert_error(
        &replace("  left_tool:", "  left_tol:"),
        "stiffness.yaml:4:3",
        &[
            "payloads",
            "unknown link 'left_tol'",
            "did you mean 'left_tool'?",
        ],
    );
    assert_error(
        &replace("  left_tool:", "  left_link6:"),
        "stiffness.yaml:4:3",
        &["not a tool link", "left_tool, right_tool"],
    );
    assert_error(
        &replace("    left_link3:", "    left_lnk3:"),
        "stiffness.yaml:12:5",
        &[
            "links.overrides",
            "unknown link or joint 'left_lnk3'",
            "did you mean 'left_link3'?",
        ],
    );
    assert_error(
        &replace("    left_link3:", "    base_link:"),
        "stiffness.yaml:12:5",
        &["part of the base"],
    );
    assert_error(
        &replace(
            "    left_link3: {ei_y_nm2: 3.0e4}",
            "    left_link3: {ei_y_nm2: 3.0e4}\n    left_joint3: {ei_y_nm2: 3.0e4}",
        ),
        "stiffness.yaml:13:5",
        &["'left_link3' and 'left_joint3' name the same body"],
    );
    // Bad numbers, at the value.
    assert_error(
        &replace("bending_nm_per_rad: 8000", "bending_nm_per_rad: -8000"),
        "stiffness.yaml:8:",
        &["joints.overrides.left_joint2: bending_nm_per_rad is -8000; must be positive (use .inf for rigid)"],
    );
    assert_error(
        &replace("torsion_nm_per_rad: 5000}", "torsion_nm_per_rad: 0}"),
        "stiffness.yaml:6:",
        &["joints.default: torsion_nm_per_rad is 0; must be positive"],
    );
    assert_error(
        &replace("ei_z_nm2: 2.5e4", "ei_z_nm2: .nan"),
        "stiffness.yaml:10:",
        &["links.default: ei_z_nm2 is NaN; must be positive"],
    );
    assert_error(
        &replace("{mass_kg: 20}", "{mass_kg: -20}"),
        "stiffness.yaml:4:",
        &["payloads.left_tool: mass_kg is -20; must be a finite number ≥ 0"],
    );
    assert_error(
        &replace("[0, 0, -9.81]", "[0, 0, .inf]"),
        "stiffness.yaml:1:",
        &["gravity_m_per_s2 is [0.0, 0.0, inf]; must be three finite numbers"],
    );
    assert_error(
        "self_weight: true\ngravity_m_per_s2: [0, 0, .nan]\n",
        "stiffness.yaml:2:",
        &["gravity_m_per_s2 is [0.0, 0.0, NaN]"],
    );
    assert_error(
        "payloads:\n  left_tool: {mass_kg: 1}\n  left_tool: {mass_kg: 2}\n",
        "stiffness.yaml:3:3",
        &["payloads: duplicate key `left_tool`"],
    );
    // Block style: the place is the bad key's own line, not its mapping's first line.
    assert_error(
        "joints:\n  default:\n    bending_nm_per_rad: 5000\n    torsion_nm_per_rad: -1\n",
        "stiffness.yaml:4:5",
        &["torsion_nm_per_rad is -1"],
    );
    assert_error(
        "links:\n  default:\n    ea_n: 4.0e7\n    # a comment\n    ei_q_nm2: 1.0\n",
        "stiffness.yaml:5:5",
        &["unknown key 'ei_q_nm2'"],
    );
    // Unknown keys and wrong types.
    assert_error(
        &replace("ei_y_nm2: 3.0e4", "ei_x_nm2: 3.0e4"),
        "stiffness.yaml:12:",
        &["unknown key 'ei_x_nm2'", "ei_y_nm2"],
    );
    assert_error(
        &replace("self_weight: true", "self_weigth: true"),
        "stiffness.yaml:2:",
        &["unknown key 'self_weigth'"],
    );
    assert_error(
        &replace("{mass_kg: 20}", "{mass_kg: heavy}"),
        "stiffness.yaml:4:",
        &["invalid type", "mass_kg"],
    );
    assert_error(
        &replace("[0, 0, -9.81]", "[0, -9.81]"),
        "stiffness.yaml:1:",
        &["gravity_m_per_s2"],
    );
}

#[test]
fn stiffness_names_off_the_calibrated_branches_are_errors() {
    let (tree, model) = robot_model("humanoid/humanoid.urdf");
    let parse = |text: &str| {
        treecal::io::parse_stiffness(text, "humanoid.yaml", &tree, &model)
            .unwrap_err()
            .to_string()
    };
    let head = parse("links:\n  overrides:\n    head: {ea_n: 1.0e6}\n");
    assert!(
        head.starts_with("humanoid.yaml:3:5") && head.contains("neck_pitch"),
        "{head}"
    );
    let neck = parse("joints:\n  overrides:\n    neck_yaw: {bending_nm_per_rad: 1.0e3}\n");
    assert!(neck.contains("not on a calibrated branch"), "{neck}");
    // The library type is checked too, by the model.
    let stiffness = Stiffness {
        joint_overrides: vec![("l_elbw".into(), JointStiffness::default())],
        ..Stiffness::default()
    };
    let error = FlexibilityModel::new(&tree, &model, &stiffness)
        .unwrap_err()
        .to_string();
    assert!(error.contains("did you mean 'l_elbow'?"), "{error}");
    let stiffness = Stiffness {
        joint_default: JointStiffness {
            bending: 0.0,
            torsion: 1.0,
        },
        ..Stiffness::default()
    };
    assert!(FlexibilityModel::new(&tree, &model, &stiffness).is_err());
}

// ---------------------------------------------------------------------------------------------
// How large is it? Robonaut with the paper's 20 kg payloads.

/// The paper's section 5.2 set-up (5000 N·m/rad, 20 kg per tool) is soft: every arm joint
/// carries ~100 N·m and turns ~0.02 rad, so the tools sag by centimetres and degrees, almost
/// all of it from the joints; the Ø70 mm tubes add about a millimetre.
#[test]
fn robonaut_deflection_magnitudes() {
    let (tree, model) = robot_model("robonaut/robonaut.urdf");
    let stiffness = robonaut_stiffness(&tree, &model);
    let flexibility = FlexibilityModel::new(&tree, &model, &stiffness).unwrap();
    let rigid = LinkStiffness {
        axial: f64::INFINITY,
        bending_y: f64::INFINITY,
        bending_z: f64::INFINITY,
        torsion: f64::INFINITY,
    };
    let joints_only = Stiffness {
        link_default: rigid,
        ..stiffness.clone()
    };
    let joints_only = FlexibilityModel::new(&tree, &model, &joints_only).unwrap();
    // Stretched out: the largest horizontal reach of the two tools among 2000 configurations.
    let mut rng = rng(5);
    let reach = |q: &[f64]| -> f64 {
        let poses = model.tool_poses(q);
        poses.iter().map(|p| p.translation.vector.xy().norm()).sum()
    };
    let mut stretched = tree.zero_configuration();
    let mut sizes = Vec::new();
    for _ in 0..2000 {
        let q = random_configuration(&tree, &mut rng);
        if reach(&q) > reach(&stretched) {
            stretched = q.clone();
        }
        for d in flexibility.tool_deflections(&tree, &model, &q).unwrap() {
            sizes.push(d.fixed_rows::<3>(0).norm() * 1e3);
        }
    }
    sizes.sort_by(f64::total_cmp);
    println!(
        "2000 random configurations: D_f position median {:.1} mm, 95th percentile {:.1} mm, max {:.1} mm",
        sizes[sizes.len() / 2],
        sizes[sizes.len() * 95 / 100],
        sizes[sizes.len() - 1]
    );
    let configurations = [
        ("zero", tree.zero_configuration()),
        ("stretched", stretched),
        ("random 1", random_configuration(&tree, &mut self::rng(1))),
        ("random 2", random_configuration(&tree, &mut self::rng(2))),
    ];
    for (name, q) in &configurations {
        let all = flexibility.tool_deflections(&tree, &model, q).unwrap();
        let joints = joints_only.tool_deflections(&tree, &model, q).unwrap();
        for (tool, (d, j)) in all.iter().zip(&joints).enumerate() {
            let position = d.fixed_rows::<3>(0).norm() * 1e3;
            let angle = d.fixed_rows::<3>(3).norm().to_degrees();
            let links = (d - j).fixed_rows::<3>(0).norm() * 1e3;
            let link_angle = (d - j).fixed_rows::<3>(3).norm().to_degrees();
            println!(
                "{name:9} tool {tool}: D_f {position:6.1} mm {angle:5.2}°; of which links {links:5.2} mm {link_angle:5.3}°"
            );
            // Joints: 2–8 joints × ~0.01–0.07 rad × 0.3–1 m; links: ~1 mm.
            assert!(
                (5.0..250.0).contains(&position),
                "{name} tool {tool}: {position} mm"
            );
            assert!((0.1..20.0).contains(&angle), "{name} tool {tool}: {angle}°");
            assert!(
                (0.01..10.0).contains(&links),
                "{name} tool {tool}: links {links} mm"
            );
        }
    }
    assert!((10.0..100.0).contains(&sizes[sizes.len() / 2]));
}
