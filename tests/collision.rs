//! Self-collision checks (src/sim/collision.rs) and the configuration sampler
//! (src/sim/sampling.rs), on tiny hand-written robots whose answers can be worked out by hand
//! and on the repository's robots.

use crate::common::*;
use treecal::sim::{sample_configurations, SamplingOptions};
use treecal::sim::{CollisionChecker, CollisionOptions};
use treecal::tree::{KinematicTree, LinkId};
use treecal::urdf::load_urdf;

const CUBE: &str = r#"<box size="0.2 0.2 0.2"/>"#;

/// A `<link>` with `<collision>` shapes given as (xyz, rpy, geometry).
fn link(name: &str, shapes: &[(&str, &str, &str)]) -> String {
    let mut text = format!("  <link name=\"{name}\">\n");
    for (xyz, rpy, geometry) in shapes {
        text += &format!(
            "    <collision><origin xyz=\"{xyz}\" rpy=\"{rpy}\"/><geometry>{geometry}</geometry></collision>\n"
        );
    }
    text + "  </link>\n"
}

/// A `<joint>`; movable joints get limits [-3, 3] (revolute) or [0, 1] (prismatic).
fn joint(name: &str, kind: &str, parent: &str, child: &str, xyz: &str, axis: &str) -> String {
    let limit = match kind {
        "revolute" => r#"<limit lower="-3" upper="3" effort="1" velocity="1"/>"#,
        "prismatic" => r#"<limit lower="0" upper="1" effort="1" velocity="1"/>"#,
        _ => "",
    };
    format!(
        "  <joint name=\"{name}\" type=\"{kind}\"><parent link=\"{parent}\"/><child link=\"{child}\"/>\
         <origin xyz=\"{xyz}\" rpy=\"0 0 0\"/><axis xyz=\"{axis}\"/>{limit}</joint>\n"
    )
}

fn build(parts: &[String]) -> KinematicTree {
    let text = format!("<robot name=\"test\">\n{}</robot>\n", parts.concat());
    treecal::parse_urdf(&text, "test.urdf")
        .unwrap_or_else(|e| panic!("{e}\n{text}"))
        .tree
}

fn names(tree: &KinematicTree, pairs: &[(LinkId, LinkId)]) -> Vec<(String, String)> {
    pairs
        .iter()
        .map(|&(a, b)| (tree.link(a).name.clone(), tree.link(b).name.clone()))
        .collect()
}

fn pairs_at(checker: &CollisionChecker, tree: &KinematicTree, q: &[f64]) -> Vec<(String, String)> {
    names(tree, &checker.colliding_pairs(&tree.link_poses(q).unwrap()))
}

fn collides(checker: &CollisionChecker, tree: &KinematicTree, q: &[f64]) -> bool {
    checker.in_collision(&tree.link_poses(q).unwrap())
}

fn with_margin(tree: &KinematicTree, margin: f64) -> CollisionChecker {
    CollisionChecker::with_options(tree, &CollisionOptions { margin }).unwrap()
}

/// Two 0.2 m cubes on separate branches of a base without geometry: `a` at the origin on a
/// revolute joint about z, `b` starting 1 m away along x on a prismatic joint that moves it
/// towards `a` by q[1]. The faces meet at q[1] = 1 − 0.1 − 0.1 = 0.8 while `a` is square to x;
/// turned by 45°, `a`'s edge reaches x = 0.1·√2 and they meet at q[1] = 0.9 − 0.1·√2 ≈ 0.7586.
fn sliding_boxes(b_geometry: &str) -> KinematicTree {
    build(&[
        link("base", &[]),
        link("a", &[("0 0 0", "0 0 0", CUBE)]),
        link("b", &[("0 0 0", "0 0 0", b_geometry)]),
        joint("spin", "revolute", "base", "a", "0 0 0", "0 0 1"),
        joint("slide", "prismatic", "base", "b", "1 0 0", "-1 0 0"),
    ])
}

#[test]
fn boxes_collide_only_past_the_hand_computed_threshold() {
    let tree = sliding_boxes(CUBE);
    let checker = CollisionChecker::new(&tree).unwrap();
    assert_eq!(checker.pair_count(), 1);
    assert_eq!(checker.skipped_meshes(), 0);
    let ab = vec![("a".to_owned(), "b".to_owned())];
    // Apart, then overlapping.
    assert!(!collides(&checker, &tree, &[0.0, 0.0]));
    assert!(pairs_at(&checker, &tree, &[0.0, 0.0]).is_empty());
    assert!(collides(&checker, &tree, &[0.0, 0.9]));
    assert_eq!(pairs_at(&checker, &tree, &[0.0, 0.9]), ab);
    // Either side of the faces meeting at 0.8.
    assert!(!collides(&checker, &tree, &[0.0, 0.799]));
    assert!(collides(&checker, &tree, &[0.0, 0.801]));
    // Turned by 45°, `a` reaches further: either side of 0.9 − 0.1·√2.
    let threshold = 0.9 - 0.1 * 2f64.sqrt();
    let quarter = std::f64::consts::FRAC_PI_4;
    assert!(!collides(&checker, &tree, &[quarter, threshold - 1e-3]));
    assert!(collides(&checker, &tree, &[quarter, threshold + 1e-3]));
    assert!(!collides(&checker, &tree, &[0.0, threshold + 1e-3]));
}

#[test]
fn adjacent_links_may_touch_but_links_two_joints_apart_may_not() {
    // `arm` overlaps `base` and hangs from it by one joint; `hand` hangs from `arm` at the same
    // place, so it overlaps both but is two joints from `base`.
    let tree = build(&[
        link("base", &[("0 0 0", "0 0 0", CUBE)]),
        link("arm", &[("0 0 0", "0 0 0", CUBE)]),
        link("hand", &[("0 0 0", "0 0 0", CUBE)]),
        joint("shoulder", "revolute", "base", "arm", "0 0 0.15", "0 0 1"),
        joint("wrist", "revolute", "arm", "hand", "0 0 0", "0 0 1"),
    ]);
    let checker = CollisionChecker::new(&tree).unwrap();
    assert_eq!(
        names(&tree, &checker.pairs().collect::<Vec<_>>()),
        [("base".to_owned(), "hand".to_owned())]
    );
    assert_eq!(
        pairs_at(&checker, &tree, &[0.3, -0.2]),
        [("base".to_owned(), "hand".to_owned())]
    );
}

#[test]
fn links_welded_by_fixed_joints_are_one_body() {
    // base ⊕ cover (fixed) — upper ⊕ plate (fixed) — lower: every neighbour overlaps or touches.
    let tree = build(&[
        link("base", &[("0 0 0", "0 0 0", CUBE)]),
        link("cover", &[("0 0 0", "0 0 0", CUBE)]),
        link("upper", &[("0 0 0", "0 0 0", CUBE)]),
        link("plate", &[("0 0 0", "0 0 0", CUBE)]),
        link("lower", &[("0 0 0", "0 0 0", CUBE)]),
        joint("cover_weld", "fixed", "base", "cover", "0 0 0.15", "1 0 0"),
        joint("lift", "revolute", "base", "upper", "0 0 0.5", "0 0 1"),
        joint("plate_weld", "fixed", "upper", "plate", "0 0 0.1", "1 0 0"),
        joint("elbow", "revolute", "plate", "lower", "0 0 0.05", "0 0 1"),
    ]);
    let checker = CollisionChecker::new(&tree).unwrap();
    // Only links of `base`'s body against links of `lower`'s body, two movable joints apart.
    assert_eq!(
        names(&tree, &checker.pairs().collect::<Vec<_>>()),
        [
            ("base".to_owned(), "lower".to_owned()),
            ("cover".to_owned(), "lower".to_owned())
        ]
    );
    assert!(!collides(&checker, &tree, &[0.0, 0.0]));
    assert!(!collides(&checker, &tree, &[1.0, -2.0]));
}

/// A thin rod (cylinder along URDF z, 1 m long) on a joint about x, a cube above the origin on
/// the z axis and one beside it on the y axis, each on its own branch.
fn rod_and_cubes(rod_rpy: &str) -> KinematicTree {
    build(&[
        link("base", &[]),
        link(
            "rod",
            &[(
                "0 0 0",
                rod_rpy,
                r#"<cylinder radius="0.01" length="1.0"/>"#,
            )],
        ),
        link("above", &[("0 0 0", "0 0 0", CUBE)]),
        link("beside", &[("0 0 0", "0 0 0", CUBE)]),
        joint("tilt", "revolute", "base", "rod", "0 0 0", "1 0 0"),
        joint(
            "above_joint",
            "revolute",
            "base",
            "above",
            "0 0 0.4",
            "0 0 1",
        ),
        joint(
            "beside_joint",
            "revolute",
            "base",
            "beside",
            "0 0.4 0",
            "0 0 1",
        ),
    ])
}

/// URDF cylinders run along z and parry's along y: forgetting the turn swaps every answer here.
#[test]
fn cylinders_lie_along_urdf_z() {
    let rod_above = vec![("rod".to_owned(), "above".to_owned())];
    let rod_beside = vec![("rod".to_owned(), "beside".to_owned())];
    let tree = rod_and_cubes("0 0 0");
    let checker = CollisionChecker::new(&tree).unwrap();
    let quarter = std::f64::consts::FRAC_PI_2;
    assert_eq!(pairs_at(&checker, &tree, &[0.0, 0.0, 0.0]), rod_above);
    // Tilted a quarter turn about x, the rod lies along ∓y and reaches the other cube.
    assert_eq!(pairs_at(&checker, &tree, &[quarter, 0.0, 0.0]), rod_beside);
    assert_eq!(pairs_at(&checker, &tree, &[-quarter, 0.0, 0.0]), rod_beside);
    // Half-way it misses both (its tip is at 0.35 m along both axes, outside both cubes).
    assert!(pairs_at(&checker, &tree, &[quarter / 2.0, 0.0, 0.0]).is_empty());
    // The <origin> rpy of the shape turns it too: rolled 90° about x, it lies along y at zero.
    let tree = rod_and_cubes("1.5707963267948966 0 0");
    let checker = CollisionChecker::new(&tree).unwrap();
    assert_eq!(pairs_at(&checker, &tree, &[0.0, 0.0, 0.0]), rod_beside);
}

#[test]
fn margin_counts_near_misses_as_collisions() {
    // At q = 0.75 the cubes' faces are 0.05 m apart.
    let tree = sliding_boxes(CUBE);
    let q = [0.0, 0.75];
    assert!(!collides(&with_margin(&tree, 0.0), &tree, &q));
    assert!(!collides(&with_margin(&tree, 0.04), &tree, &q));
    assert!(collides(&with_margin(&tree, 0.06), &tree, &q));
    assert_eq!(with_margin(&tree, 0.06).pair_count(), 1);
    // A sphere of radius 0.1 in place of cube `b`: 0.05 m apart at the same q; a capsule too.
    for b in [
        r#"<sphere radius="0.1"/>"#,
        r#"<cylinder radius="0.1" length="0.3"/>"#,
        r#"<capsule radius="0.1" length="0.3"/>"#,
    ] {
        let tree = sliding_boxes(b);
        assert!(!collides(&with_margin(&tree, 0.0), &tree, &q), "{b}");
        assert!(!collides(&with_margin(&tree, 0.04), &tree, &q), "{b}");
        assert!(collides(&with_margin(&tree, 0.06), &tree, &q), "{b}");
        assert!(
            collides(&with_margin(&tree, 0.0), &tree, &[0.0, 0.81]),
            "{b}"
        );
    }
    for bad in [-0.01, f64::NAN, f64::INFINITY] {
        let error = CollisionChecker::with_options(&tree, &CollisionOptions { margin: bad })
            .unwrap_err()
            .to_string();
        assert!(error.contains("collision margin"), "{error}");
    }
}

#[test]
fn bad_shapes_are_errors_and_meshes_are_counted() {
    let tree = sliding_boxes(r#"<box size="0.2 -0.2 0.2"/>"#);
    let error = CollisionChecker::new(&tree).unwrap_err().to_string();
    assert!(
        error.contains("link 'b'") && error.contains("box size y"),
        "{error}"
    );
    let tree = sliding_boxes(r#"<mesh filename="package://robot/b.stl"/>"#);
    let checker = CollisionChecker::new(&tree).unwrap();
    assert_eq!(checker.skipped_meshes(), 1);
    assert_eq!(checker.pair_count(), 0);
    assert!(!collides(&checker, &tree, &[0.0, 0.9]));
}

/// Poses with NaN in them (a NaN joint value) count as colliding instead of reaching parry.
#[test]
fn non_finite_poses_count_as_colliding() {
    let tree = sliding_boxes(CUBE);
    let checker = CollisionChecker::new(&tree).unwrap();
    assert!(collides(&checker, &tree, &[0.0, f64::NAN]));
}

/// The zero configuration of every robot in robots/ and of Robonaut 2, with what it collides.
#[test]
fn robots_at_the_zero_configuration() {
    let mut robots = all_repo_robots();
    robots.push(robonaut2());
    for path in robots {
        let tree = load_urdf(&path).unwrap().tree;
        let checker = CollisionChecker::new(&tree).unwrap();
        let colliding = pairs_at(&checker, &tree, &tree.zero_configuration());
        let file = path.file_name().unwrap().to_string_lossy().into_owned();
        eprintln!(
            "{file}: {} pairs checked, {} meshes skipped, colliding at zero: {colliding:?}",
            checker.pair_count(),
            checker.skipped_meshes()
        );
        let expected: Vec<(String, String)> = match file.as_str() {
            // Table 1's left arm folds back on itself at zero (rows 1–3 are parallel joints
            // with y = −135, −135, +245 mm), so left_link3's tube lies over left_link1's.
            "robonaut.urdf" => vec![("left_link1".into(), "left_link3".into())],
            _ => vec![],
        };
        assert_eq!(colliding, expected, "{file}");
        if file == "robonaut2.urdf" {
            // Only the two ankle cylinders are primitives; the rest are meshes, not loaded yet.
            assert_eq!(checker.skipped_meshes(), 69);
            assert_eq!(checker.pair_count(), 1);
        }
    }
}

#[test]
fn sampler_keeps_to_limits_and_fixed_values() {
    let tree = load_urdf(&robot("humanoid/humanoid.urdf")).unwrap().tree;
    let checker = CollisionChecker::new(&tree).unwrap();
    let dof = |name: &str| tree.dof_of(tree.joint_id(name).unwrap()).unwrap().0;
    let fixed = [(dof("l_elbow"), -1.0), (dof("r_wrist_roll"), 2.5)];
    let options = SamplingOptions {
        limits_margin: 0.05,
        ..Default::default()
    };
    let samples =
        sample_configurations(&tree, Some(&checker), 50, &mut rng(3), &options, &fixed).unwrap();
    assert_eq!(samples.len(), 50);
    let limits = tree.dof_limits();
    for q in &samples {
        assert_eq!(q.len(), tree.dof_count());
        for (i, (value, limit)) in q.iter().zip(&limits).enumerate() {
            if let Some(&(_, held)) = fixed.iter().find(|(d, _)| *d == i) {
                assert_eq!(*value, held);
            } else if let Some(l) = limit {
                assert!(
                    *value >= l.lower + 0.05 && *value < l.upper - 0.05,
                    "{i}: {value}"
                );
            } else {
                assert!((-std::f64::consts::PI..std::f64::consts::PI).contains(value));
            }
        }
        assert!(!collides(&checker, &tree, q));
    }
    // The continuous left wrist roll is drawn over a full turn.
    let roll: Vec<f64> = samples.iter().map(|q| q[dof("l_wrist_roll")]).collect();
    assert!(roll.iter().any(|&v| v < -2.0) && roll.iter().any(|&v| v > 2.0));
}

#[test]
fn sampler_rejects_colliding_configurations() {
    let tree = load_urdf(&robot("robonaut/robonaut.urdf")).unwrap().tree;
    let checker = CollisionChecker::new(&tree).unwrap();
    let options = SamplingOptions::default();
    let free =
        sample_configurations(&tree, Some(&checker), 300, &mut rng(5), &options, &[]).unwrap();
    assert!(free.iter().all(|q| !collides(&checker, &tree, q)));
    // Without the checker the same draws include collisions, so the rejection did something.
    let any = sample_configurations(&tree, None, 300, &mut rng(5), &options, &[]).unwrap();
    let colliding = any.iter().filter(|q| collides(&checker, &tree, q)).count();
    eprintln!(
        "robonaut.urdf: {:.1} % of uniform configurations are free of self-collision",
        100.0 * (300 - colliding) as f64 / 300.0
    );
    assert!(colliding > 100, "{colliding} of 300");
}

#[test]
fn sampler_is_deterministic_for_a_seed() {
    let tree = load_urdf(&robot("robonaut/robonaut.urdf")).unwrap().tree;
    let checker = CollisionChecker::new(&tree).unwrap();
    let options = SamplingOptions::default();
    let draw = |seed| {
        sample_configurations(&tree, Some(&checker), 20, &mut rng(seed), &options, &[]).unwrap()
    };
    assert_eq!(draw(11), draw(11));
    assert_ne!(draw(11), draw(12));
}

#[test]
fn sampler_explains_a_robot_that_always_collides() {
    // Two cubes on joints about their own z axes, 5 cm apart: they overlap at every angle.
    let tree = build(&[
        link("base", &[]),
        link("a", &[("0 0 0", "0 0 0", CUBE)]),
        link("b", &[("0 0 0", "0 0 0", CUBE)]),
        joint("ja", "revolute", "base", "a", "0 0 0", "0 0 1"),
        joint("jb", "revolute", "base", "b", "0.05 0 0", "0 0 1"),
    ]);
    let checker = CollisionChecker::new(&tree).unwrap();
    let options = SamplingOptions {
        max_attempts_per_sample: 20,
        ..Default::default()
    };
    let error = sample_configurations(&tree, Some(&checker), 3, &mut rng(0), &options, &[])
        .unwrap_err()
        .to_string();
    assert!(
        error.contains("could not find a self-collision-free configuration in 20 attempts")
            && error.contains("sample 1 of 3")
            && error.contains("at the zero configuration: a–b"),
        "{error}"
    );
}

/// Robonaut's stage-1 poses (arms locked, torso moving) cannot lock the left arm at zero: its
/// links 1 and 3 overlap there whatever the torso does.
#[test]
fn robonaut_arms_locked_at_zero_always_collide() {
    let tree = load_urdf(&robot("robonaut/robonaut.urdf")).unwrap().tree;
    let checker = CollisionChecker::new(&tree).unwrap();
    let arm_dofs: Vec<usize> = (0..tree.dof_count())
        .filter(|&dof| !tree.joint(tree.dofs()[dof]).name.starts_with("torso"))
        .collect();
    assert_eq!(arm_dofs.len(), 11);
    let arms: Vec<(usize, f64)> = arm_dofs.iter().map(|&dof| (dof, 0.0)).collect();
    let options = SamplingOptions {
        max_attempts_per_sample: 50,
        ..Default::default()
    };
    let error = sample_configurations(&tree, Some(&checker), 1, &mut rng(0), &options, &arms)
        .unwrap_err()
        .to_string();
    assert!(
        error.contains("zero configuration with the fixed joints: left_link1–left_link3"),
        "{error}"
    );
    // Locked at a collision-free arm configuration instead, the torso samples fine.
    let free = sample_configurations(&tree, Some(&checker), 1, &mut rng(1), &options, &[])
        .unwrap()
        .remove(0);
    let arms: Vec<(usize, f64)> = arm_dofs.iter().map(|&dof| (dof, free[dof])).collect();
    let torso = sample_configurations(&tree, Some(&checker), 10, &mut rng(2), &options, &arms);
    assert_eq!(torso.unwrap().len(), 10);
}

#[test]
fn sampler_rejects_bad_requests() {
    let tree = sliding_boxes(CUBE);
    let options = SamplingOptions::default();
    let error = |options: &SamplingOptions, fixed: &[(usize, f64)]| {
        sample_configurations(&tree, None, 1, &mut rng(0), options, fixed)
            .unwrap_err()
            .to_string()
    };
    assert!(error(&options, &[(2, 0.0)]).contains("index 2 is out of range"));
    assert!(error(&options, &[(1, 1.5)]).contains("outside its limits"));
    assert!(error(&options, &[(0, 0.1), (0, 0.2)]).contains("fixed twice"));
    assert!(error(&options, &[(0, f64::NAN)]).contains("finite"));
    let wide = SamplingOptions {
        limits_margin: 0.6,
        ..Default::default()
    };
    assert!(error(&wide, &[]).contains("leaves nothing to sample of joint 'slide'"));
    let none = SamplingOptions {
        max_attempts_per_sample: 0,
        ..Default::default()
    };
    assert!(error(&none, &[]).contains("at least 1"));
    // A prismatic joint without limits has no range, unless it is held.
    let tree = build(&[
        link("base", &[]),
        link("carriage", &[]),
        "  <joint name=\"rail\" type=\"prismatic\"><parent link=\"base\"/><child link=\"carriage\"/>\
         <axis xyz=\"1 0 0\"/></joint>\n"
            .to_owned(),
    ]);
    let error = sample_configurations(&tree, None, 1, &mut rng(0), &options, &[])
        .unwrap_err()
        .to_string();
    assert!(
        error.contains("prismatic joint 'rail' has no limits"),
        "{error}"
    );
    let held = sample_configurations(&tree, None, 2, &mut rng(0), &options, &[(0, 0.3)]);
    assert_eq!(held.unwrap(), [[0.3], [0.3]]);
    // A checker built for another robot.
    let other = CollisionChecker::new(&sliding_boxes(CUBE)).unwrap();
    let robonaut = load_urdf(&robot("robonaut/robonaut.urdf")).unwrap().tree;
    let error = sample_configurations(&robonaut, Some(&other), 1, &mut rng(0), &options, &[])
        .unwrap_err()
        .to_string();
    assert!(error.contains("built for a robot with 3 links"), "{error}");
}

/// A unit cube (±0.5 m) as a binary STL.
fn cube_stl() -> Vec<u8> {
    let mut bytes = vec![0u8; 80];
    let corners: Vec<[f32; 3]> = (0..8)
        .map(|c| {
            let s = |bit: usize| if c & bit == 0 { -0.5 } else { 0.5 };
            [s(1), s(2), s(4)]
        })
        .collect();
    // Twelve triangles are not needed for a hull: four triangles covering all eight corners.
    let triangles = [[0, 1, 2], [3, 4, 5], [6, 7, 0], [1, 3, 5]];
    bytes.extend((triangles.len() as u32).to_le_bytes());
    for triangle in triangles {
        bytes.extend([0u8; 12]);
        for corner in triangle {
            for value in corners[corner] {
                bytes.extend(value.to_le_bytes());
            }
        }
        bytes.extend([0u8; 2]);
    }
    bytes
}

/// The same cube as OBJ text.
fn cube_obj() -> String {
    let mut text = String::from("# unit cube\n");
    for c in 0..8 {
        let s = |bit: usize| if c & bit == 0 { -0.5 } else { 0.5 };
        text += &format!("v {} {} {}\n", s(1), s(2), s(4));
    }
    // Faces that use all eight corners (a reader keeps the vertices its faces use).
    text + "f 1 2 3\nf 4 5 6\nf 7 8 1\nf 2 4 6\n"
}

/// STL, OBJ and COLLADA meshes (a unit cube scaled to 0.2 m; the COLLADA one in decimetres,
/// scaled by 2) collide exactly like the 0.2 m box: the faces meet at q[1] = 0.8 with `a`
/// square to x. Found next to the URDF, through file://, through package:// search directories
/// (holding the package, or the package folder itself); a mesh not found or not readable is
/// skipped and listed, the unreadable one with its reason.
#[test]
fn stl_obj_and_collada_meshes_collide_like_the_box_they_describe() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("cube.stl"), cube_stl()).unwrap();
    std::fs::create_dir_all(dir.path().join("robot/meshes")).unwrap();
    std::fs::write(dir.path().join("robot/meshes/cube.obj"), cube_obj()).unwrap();
    std::fs::copy(
        repo().join("tests/data/cube.dae"),
        dir.path().join("robot/meshes/cube.dae"),
    )
    .unwrap();
    let absolute = dir.path().join("cube.stl");
    let package = dir.path().join("robot");
    let names = [
        ("cube.stl".to_owned(), "0.2", dir.path().to_owned()),
        (
            format!("file://{}", absolute.display()),
            "0.2",
            dir.path().to_owned(),
        ),
        (
            "package://robot/meshes/cube.obj".to_owned(),
            "0.2",
            dir.path().to_owned(),
        ),
        (
            "package://robot/meshes/cube.dae".to_owned(),
            "2",
            dir.path().to_owned(),
        ),
        ("package://robot/meshes/cube.dae".to_owned(), "2", package),
    ];
    for (name, scale, packages) in &names {
        let tree = sliding_boxes(&format!(
            r#"<mesh filename="{name}" scale="{scale} {scale} {scale}"/>"#
        ));
        let loader = treecal::io::mesh_file_loader(dir.path().to_owned(), vec![packages.clone()]);
        let checker =
            CollisionChecker::with_meshes(&tree, &CollisionOptions::default(), &loader).unwrap();
        assert_eq!(checker.loaded_meshes(), 1, "{name}");
        assert_eq!(checker.skipped_meshes(), 0, "{name}");
        assert!(!collides(&checker, &tree, &[0.0, 0.79]), "{name}: apart");
        assert!(
            collides(&checker, &tree, &[0.0, 0.81]),
            "{name}: overlapping"
        );
        // Turned by 45°, a's edge reaches further: they meet at 0.9 − 0.1·√2 ≈ 0.7586.
        let turned = std::f64::consts::FRAC_PI_4;
        assert!(
            !collides(&checker, &tree, &[turned, 0.75]),
            "{name}: turned, apart"
        );
        assert!(
            collides(&checker, &tree, &[turned, 0.77]),
            "{name}: turned, overlapping"
        );
    }
    // Not found: skipped and listed, no reason.
    for name in ["missing.stl", "missing.dae", "package://other/cube.obj"] {
        let tree = sliding_boxes(&format!(r#"<mesh filename="{name}"/>"#));
        let loader = treecal::io::mesh_file_loader(dir.path().to_owned(), vec![dir.path().into()]);
        let checker =
            CollisionChecker::with_meshes(&tree, &CollisionOptions::default(), &loader).unwrap();
        assert_eq!(checker.skipped_mesh_files(), [name.to_owned()]);
        assert!(checker.unreadable_meshes().is_empty());
        assert_eq!(checker.pair_count(), 0);
    }
    // Found but not a mesh: skipped and listed with the reason.
    std::fs::write(dir.path().join("bad.obj"), "v 0 0 x\nf 1 1 1\n").unwrap();
    std::fs::write(dir.path().join("bad.dae"), "<COLLADA><oops").unwrap();
    std::fs::write(dir.path().join("notes.txt"), "not a mesh").unwrap();
    for name in ["bad.obj", "bad.dae", "notes.txt"] {
        let tree = sliding_boxes(&format!(r#"<mesh filename="{name}"/>"#));
        let loader = treecal::io::mesh_file_loader(dir.path().to_owned(), Vec::new());
        let checker =
            CollisionChecker::with_meshes(&tree, &CollisionOptions::default(), &loader).unwrap();
        assert_eq!(checker.skipped_mesh_files(), [name.to_owned()]);
        let unreadable = checker.unreadable_meshes();
        assert!(
            unreadable.len() == 1 && unreadable[0].0 == name && !unreadable[0].1.is_empty(),
            "{name}: {unreadable:?}"
        );
    }
}

/// A mesh file used by several links is read and its hull computed once per scale (a loader
/// that counts its calls), and every link gets it.
#[test]
fn a_mesh_shared_by_links_is_loaded_once() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("cube.stl"), cube_stl()).unwrap();
    let mesh = r#"<mesh filename="cube.stl" scale="0.2 0.2 0.2"/>"#;
    let tree = build(&[
        link("base", &[]),
        link("a", &[("0 0 0", "0 0 0", mesh)]),
        link("b", &[("0 0 0", "0 0 0", mesh)]),
        joint("spin", "revolute", "base", "a", "0 0 0", "0 0 1"),
        joint("slide", "prismatic", "base", "b", "1 0 0", "-1 0 0"),
    ]);
    let reader = treecal::io::mesh_file_loader(dir.path().to_owned(), Vec::new());
    let calls = std::cell::Cell::new(0);
    let counting = |name: &str| {
        calls.set(calls.get() + 1);
        reader(name)
    };
    let checker =
        CollisionChecker::with_meshes(&tree, &CollisionOptions::default(), &counting).unwrap();
    assert_eq!(calls.get(), 1);
    assert_eq!(checker.loaded_meshes(), 2);
    assert!(!collides(&checker, &tree, &[0.0, 0.79]));
    assert!(collides(&checker, &tree, &[0.0, 0.81]));
}

/// Real ROS descriptions of example-robot-data: Romeo and Kinova (COLLADA), Panda and PR2
/// (STL): every `<collision>` mesh resolves through `package://` (the search directory holds
/// the package, or is the package folder itself), loads and gets a hull; nothing is skipped.
#[test]
fn example_robot_data_collision_meshes_all_load() {
    let Some(robots) = example_robot_data() else {
        return;
    };
    let share = robots.parent().unwrap().parent().unwrap().to_owned();
    let package = robots.parent().unwrap().to_owned();
    for (relative, search) in [
        ("romeo_description/urdf/romeo_small.urdf", &share),
        ("kinova_description/robots/kinova.urdf", &package),
        ("panda_description/urdf/panda.urdf", &package),
        ("pr2_description/urdf/pr2.urdf", &share),
    ] {
        let path = robots.join(relative);
        let tree = load_urdf(&path).unwrap_or_else(|e| panic!("{e}")).tree;
        let meshes = tree
            .links()
            .iter()
            .flat_map(|l| &l.geometry.collisions)
            .filter(|(_, s)| matches!(s, treecal::tree::Shape::Mesh { .. }))
            .count();
        assert!(meshes > 5, "{relative}: {meshes}");
        let loader =
            treecal::io::mesh_file_loader(path.parent().unwrap().to_owned(), vec![search.clone()]);
        let checker =
            CollisionChecker::with_meshes(&tree, &CollisionOptions::default(), &loader).unwrap();
        assert_eq!(
            (checker.loaded_meshes(), checker.skipped_mesh_files()),
            (meshes, &[][..]),
            "{relative}: {:?}",
            checker.unreadable_meshes()
        );
    }
}

/// Robonaut 2's description names 69 COLLADA collision meshes that are not shipped with it:
/// `plan` stops with one error that says how many were not found, names them and the flags;
/// with `--package-path` pointing at a folder that holds one of them (the test cube as
/// `Body.dae`), that one loads and the others are still named; `--collision-check
/// primitives-only` plans without them and says so in the pose file.
#[test]
fn plan_names_the_collision_meshes_it_cannot_find() {
    use crate::common::cli::*;
    let dir = tempfile::tempdir().unwrap();
    let robot = robonaut2();
    let out = dir.path().join("poses.csv");
    let args = |extra: &[&str]| {
        let mut args = vec![
            "plan",
            "--robot",
            robot.to_str().unwrap(),
            "--poses",
            "2",
            "--candidates",
            "20",
            "-o",
            path_str(&out),
        ];
        args.extend_from_slice(extra);
        args.iter().map(|s| s.to_string()).collect::<Vec<_>>()
    };
    let first = args(&[]);
    let run = treecal(&first.iter().map(String::as_str).collect::<Vec<_>>());
    assert_error(
        &run,
        &[
            "69 of 69 collision meshes cannot be used",
            "files not found",
            "package://r2_description/meshes/r2_upperbody/Backpack.dae",
            "--package-path",
            "--collision-check primitives-only",
        ],
        "plan",
    );
    assert!(!out.exists());
    let meshes = dir.path().join("r2_description/meshes/r2_upperbody");
    std::fs::create_dir_all(&meshes).unwrap();
    std::fs::copy(repo().join("tests/data/cube.dae"), meshes.join("Body.dae")).unwrap();
    let second = args(&["--package-path", path_str(dir.path())]);
    let run = treecal(&second.iter().map(String::as_str).collect::<Vec<_>>());
    assert_error(
        &run,
        &["68 of 69", "r2_upperbody/Backpack.dae"],
        "plan --package-path",
    );
    assert!(!run.stderr.contains("r2_upperbody/Body.dae"), "{run}");
    let third = args(&["--collision-check", "primitives-only"]);
    let run = treecal(&third.iter().map(String::as_str).collect::<Vec<_>>());
    assert_success(&run, "plan --collision-check primitives-only");
    let csv = std::fs::read_to_string(&out).unwrap();
    assert!(
        csv.starts_with("# self-collision check: primitives-only (")
            && csv
                .lines()
                .next()
                .unwrap()
                .contains("69 collision meshes NOT checked"),
        "{csv}"
    );
}

/// Romeo's COLLADA meshes overlap by design between neighbouring wrist links (elbow yaw and
/// wrist yaw, two joints apart across a wrist roll link that has its own mesh): such pairs
/// collide at every random configuration, so with them no configuration could be planned.
/// They are dropped after 100 random configurations, and then collision-free configurations
/// are found; the boxes of `sliding_boxes`, which can be apart, keep their pair. `plan` says
/// which pairs it does not check.
#[test]
fn pairs_that_always_collide_are_not_checked() {
    use treecal::sim::{sample_configurations, SamplingOptions};
    let mut tree = sliding_boxes(CUBE);
    let mut checker = CollisionChecker::new(&tree).unwrap();
    let mut random = rng(5);
    let poses = |tree: &KinematicTree, random: &mut rand::rngs::ChaCha8Rng| -> Vec<_> {
        (0..100)
            .map(|_| {
                tree.link_poses(&random_configuration(tree, random))
                    .unwrap()
            })
            .collect()
    };
    assert!(checker
        .ignore_pairs_always_colliding(&poses(&tree, &mut random))
        .is_empty());
    assert_eq!(checker.pair_count(), 1);

    let Some(robots) = example_robot_data() else {
        return;
    };
    let share = robots.parent().unwrap().parent().unwrap().to_owned();
    let path = robots.join("romeo_description/urdf/romeo_small.urdf");
    tree = load_urdf(&path).unwrap().tree;
    let loader =
        treecal::io::mesh_file_loader(path.parent().unwrap().to_owned(), vec![share.clone()]);
    checker = CollisionChecker::with_meshes(&tree, &CollisionOptions::default(), &loader).unwrap();
    let options = SamplingOptions::default();
    assert!(sample_configurations(&tree, Some(&checker), 5, &mut rng(6), &options, &[]).is_err());
    let removed = names(
        &tree,
        &checker.ignore_pairs_always_colliding(&poses(&tree, &mut random)),
    );
    for pair in [
        ("LElbowYawLink", "LWristYawLink"),
        ("RElbowYawLink", "RWristYawLink"),
    ] {
        assert!(
            removed.contains(&(pair.0.into(), pair.1.into())),
            "{removed:?}"
        );
    }
    assert!(removed.len() <= 6, "{removed:?}");
    let found =
        sample_configurations(&tree, Some(&checker), 5, &mut rng(6), &options, &[]).unwrap();
    assert_eq!(found.len(), 5);

    use crate::common::cli::*;
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("poses.csv");
    let run = treecal(&[
        "plan",
        "--robot",
        path.to_str().unwrap(),
        "--package-path",
        share.to_str().unwrap(),
        "--poses",
        "3",
        "--candidates",
        "30",
        "-o",
        path_str(&out),
    ]);
    assert_success(&run, "plan on romeo_small");
    assert!(
        run.stderr
            .contains("collide in at least 95 % of 100 random configurations")
            && run.stderr.contains("LElbowYawLink–LWristYawLink"),
        "{run}"
    );
}

/// A URDF without `<collision>` elements (the second robot's arm) leaves the check nothing to
/// test: `plan` warns on stderr that its poses are not checked, and names the way out. The
/// built-in robot, whose links carry shapes, plans without that warning (no false alarm).
#[test]
fn plan_warns_when_the_urdf_has_no_collision_shapes() {
    use crate::common::cli::*;
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("poses.csv");
    let bare = repo().join("tests/data/second_robot_arm.urdf");
    let plan = |robot: Option<&std::path::Path>| {
        let mut args = vec!["plan", "--poses", "8", "--candidates", "200", "-o"];
        args.push(path_str(&out));
        if let Some(robot) = robot {
            args.extend(["--robot", robot.to_str().unwrap()]);
        }
        treecal(&args)
    };
    let run = plan(Some(&bare));
    assert_success(&run, "plan on a URDF without collision shapes");
    for text in [
        "warning: 'second_robot_arm' has 0 collision shape(s)",
        "NOT checked for self-collision",
        "--collision-check off",
    ] {
        assert!(run.stderr.contains(text), "{text}: {run}");
    }
    let run = plan(None);
    assert_success(&run, "plan on the built-in robot");
    assert!(!run.stderr.contains("NOT checked"), "{run}");
}
