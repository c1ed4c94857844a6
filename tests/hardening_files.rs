//! Hostile files, second round (issue 21, the reading half): COLLADA meshes that crashed
//! mesh-loader, the one bounded reader (FIFOs, devices, sizes), unknown YAML keys, and the
//! read-time checks and messages. Each reproducer in its minimal form, each check also on
//! good data.

use crate::common::cli::*;
use crate::common::*;
use std::path::{Path, PathBuf};
use treecal::io::{mesh_vertices, parse_csv, parse_plan, read_mesh_vertices};
use treecal::limits;
use treecal::sim::MeshLookup;

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

/// A COLLADA file of one geometry: `accessor` (count, stride), `primitive` (the whole
/// primitive element) and `scene` (the visual scene's nodes) filled in.
fn collada(accessor: &str, primitive: &str, scene: &str) -> String {
    format!(
        r##"<?xml version="1.0"?>
<COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1">
  <asset><unit meter="0.1"/></asset>
  <library_geometries><geometry id="g"><mesh>
    <source id="s">
      <float_array id="a" count="12">0 0 0 1 0 0 0 1 0 0 0 1</float_array>
      <technique_common><accessor source="#a" {accessor}/></technique_common>
    </source>
    <vertices id="v"><input semantic="POSITION" source="#s"/></vertices>
    {primitive}
  </mesh></geometry></library_geometries>
  <library_visual_scenes><visual_scene id="scene">{scene}</visual_scene></library_visual_scenes>
  <scene><instance_visual_scene url="#scene"/></scene>
</COLLADA>
"##
    )
}

const GOOD_ACCESSOR: &str = r#"count="4" stride="3""#;
const GOOD_TRIANGLES: &str = r##"<triangles count="2"><input semantic="VERTEX" source="#v" offset="0"/><p>0 1 2 0 2 3</p></triangles>"##;
const PLACED: &str = r##"<node><translate>10 0 0</translate><instance_geometry url="#g"/></node>"##;

fn dae_error(text: &str) -> String {
    match mesh_vertices(text.as_bytes(), Path::new("m.dae")) {
        Ok(v) => panic!("read {} vertices from a bad file", v.len()),
        Err(message) => message,
    }
}

/// Every crash of mesh-loader's COLLADA reader (issue 21), now an error naming the line.
#[test]
fn collada_crashes_are_errors() {
    let good = collada(GOOD_ACCESSOR, GOOD_TRIANGLES, PLACED);
    let vertices = mesh_vertices(good.as_bytes(), Path::new("m.dae")).unwrap();
    // Placed 10 units along x, the unit a decimetre.
    let mut xs: Vec<f64> = vertices.iter().map(|v| v.x).collect();
    xs.sort_by(f64::total_cmp);
    assert_eq!(vertices.len(), 4);
    assert!(
        (xs[0] - 1.0).abs() < 1e-12 && (xs[3] - 1.1).abs() < 1e-12,
        "{xs:?}"
    );

    // An accessor count larger than its array (mesh-loader: assertion panic).
    let long = dae_error(&collada(r#"count="5" stride="3""#, GOOD_TRIANGLES, PLACED));
    assert!(
        long.starts_with("line 7: <accessor count=\"5\" stride=\"3\" offset=\"0\"> needs more values than the 12"),
        "{long}"
    );
    // An index beyond the positions (index out of bounds).
    let beyond = GOOD_TRIANGLES.replace("0 2 3", "0 2 4");
    let index = dae_error(&collada(GOOD_ACCESSOR, &beyond, PLACED));
    assert!(
        index.contains("indexes vertex 4, but its positions source holds 4"),
        "{index}"
    );
    // <polygons> without an input.
    let bare = dae_error(&collada(
        GOOD_ACCESSOR,
        r#"<polygons count="1"><p>0 1 2</p></polygons>"#,
        PLACED,
    ));
    assert!(bare.contains("<polygons> has no <input>"), "{bare}");
    // Huge counts (a 515 GB allocation): refused from the array's real length.
    let huge = dae_error(&collada(
        r#"count="4294967295" stride="4294967295""#,
        &GOOD_TRIANGLES.replace(r#"count="2""#, r#"count="4294967295""#),
        PLACED,
    ));
    assert!(huge.contains("needs more values than the 12"), "{huge}");
    // Deeply nested nodes (a stack overflow).
    let depth = 100_000;
    let nested = format!(
        "{}<instance_geometry url=\"#g\"/>{}",
        "<node>".repeat(depth),
        "</node>".repeat(depth)
    );
    let deep = dae_error(&collada(GOOD_ACCESSOR, GOOD_TRIANGLES, &nested));
    assert!(deep.contains("nest more than 256 levels"), "{deep}");
    // A reference to nothing, a loop of <instance_node>s, and not XML at all.
    let nowhere = dae_error(&collada(
        GOOD_ACCESSOR,
        GOOD_TRIANGLES,
        r##"<node><instance_geometry url="#nothing"/></node>"##,
    ));
    assert!(
        nowhere.contains("url=\"#nothing\" names no element"),
        "{nowhere}"
    );
    let looping = dae_error(&collada(
        GOOD_ACCESSOR,
        GOOD_TRIANGLES,
        r##"<node id="n"><instance_node url="#n"/></node>"##,
    ));
    assert!(looping.contains("nest too deep or loop"), "{looping}");
    assert!(dae_error("<COLLADA><oops").contains("not well-formed XML"));
}

/// treecal's COLLADA reader and mesh-loader's agree (bounding box of the vertices) on every
/// smaller COLLADA mesh of example-robot-data whose nodes place their geometry as is.
/// mesh-loader drops the translation of a node's `<matrix>` (48 of these files have one);
/// there treecal agrees with assimp (checked through coal's loader, fuzz/README.md), as on
/// the camera below.
#[test]
fn collada_reader_agrees_with_mesh_loader_on_real_meshes() {
    let Some(robots) = example_robot_data() else {
        return;
    };
    let mut files = Vec::new();
    let mut stack = vec![robots];
    while let Some(dir) = stack.pop() {
        for entry in std::fs::read_dir(&dir).unwrap().flatten() {
            let path = entry.path();
            if path.is_dir() {
                stack.push(path);
            } else if path
                .extension()
                .is_some_and(|e| e.eq_ignore_ascii_case("dae"))
                && entry.metadata().unwrap().len() < 1 << 20
            {
                files.push(path);
            }
        }
    }
    files.sort();
    assert!(files.len() > 20, "{}", files.len());
    let bounds = |points: &mut dyn Iterator<Item = [f64; 3]>| {
        points.fold([[f64::MAX; 3], [f64::MIN; 3]], |[lo, hi], p| {
            [
                std::array::from_fn(|i| lo[i].min(p[i])),
                std::array::from_fn(|i| hi[i].max(p[i])),
            ]
        })
    };
    let mut compared = 0;
    let mut dump = String::new();
    for path in &files {
        let bytes = std::fs::read(path).unwrap();
        let ours = mesh_vertices(&bytes, path).unwrap_or_else(|e| panic!("{path:?}: {e}"));
        let box_ours = bounds(&mut ours.iter().map(|v| [v.x, v.y, v.z]));
        dump += &format!("{} {:?}\n", path.display(), box_ours);
        if path.ends_with("anymal_c_simple_description/meshes/wide_angle_camera.dae") {
            // assimp's box (coal.MeshLoader): the node's matrix moves it 3.71 mm along x.
            let assimp = [
                [-0.02441035, -0.0198788, -0.033957],
                [0.00371052, 0.01987898, 0.01911681],
            ];
            for k in 0..2 {
                for i in 0..3 {
                    assert!((box_ours[k][i] - assimp[k][i]).abs() < 1e-7, "{box_ours:?}");
                }
            }
        }
        let text = String::from_utf8_lossy(&bytes);
        if ["<matrix", "<translate", "<rotate", "<scale"]
            .iter()
            .any(|t| text.contains(t))
        {
            continue;
        }
        compared += 1;
        let theirs = mesh_loader::Loader::default()
            .load_from_slice(&bytes, path)
            .unwrap();
        let ours = bounds(&mut ours.iter().map(|v| [v.x, v.y, v.z]));
        let theirs = bounds(
            &mut theirs
                .meshes
                .iter()
                .flat_map(|m| &m.vertices)
                .map(|v| [f64::from(v[0]), f64::from(v[1]), f64::from(v[2])]),
        );
        let size = (0..3)
            .map(|i| theirs[1][i] - theirs[0][i])
            .fold(0.0, f64::max);
        for k in 0..2 {
            for i in 0..3 {
                assert!(
                    (ours[k][i] - theirs[k][i]).abs() <= 1e-5 * size.max(1e-3),
                    "{path:?}: {ours:?} vs {theirs:?}"
                );
            }
        }
    }
    if let Some(file) = std::env::var_os("TREECAL_DUMP_COLLADA_BOUNDS") {
        std::fs::write(file, dump).unwrap();
    }
    assert!(compared > 20, "{compared}");
    eprintln!(
        "{compared} of {} COLLADA meshes agree with mesh-loader",
        files.len()
    );
}

/// `plan` on a robot whose collision mesh is one of the crashing COLLADA files: no abort, the
/// mesh is reported with its reason (exit 0 or a clear error, never 101/134).
#[test]
fn plan_survives_a_crashing_collada_mesh() {
    let dir = tempfile::tempdir().unwrap();
    let nested = format!("{}{}", "<node>".repeat(100_000), "</node>".repeat(100_000));
    write(
        dir.path(),
        "deep.dae",
        &collada(GOOD_ACCESSOR, GOOD_TRIANGLES, &nested),
    );
    let urdf = std::fs::read_to_string(robot("robonaut/robonaut.urdf")).unwrap();
    let urdf = urdf.replacen(
        "<link name=\"left_link1\">",
        "<link name=\"left_link1\"><collision><geometry><mesh filename=\"deep.dae\"/></geometry></collision>",
        1,
    );
    assert!(urdf.contains("deep.dae"));
    let robot_path = write(dir.path(), "r.urdf", &urdf);
    let out = dir.path().join("poses.csv");
    let run = treecal(&[
        "plan",
        "--robot",
        robot_path.to_str().unwrap(),
        "--poses",
        "4",
        "--candidates",
        "20",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(matches!(run.code, Some(0..=2)), "{run}");
    assert!(
        run.stderr.contains("deep.dae") && run.stderr.contains("nest more than"),
        "{run}"
    );
}

/// The bounded reader: a FIFO (would block), /dev/zero (would fill memory) and a folder are
/// refused naming the file; an OBJ's `mtllib` naming a FIFO is never opened.
#[cfg(unix)]
#[test]
fn only_regular_files_are_read() {
    let dir = tempfile::tempdir().unwrap();
    let fifo = dir.path().join("pipe.yaml");
    let made = std::process::Command::new("mkfifo").arg(&fifo).status();
    if !made.is_ok_and(|s| s.success()) {
        eprintln!("note: skipped: no mkfifo");
        return;
    }
    for reader in [
        treecal::io::read_registration(&fifo).map(|_| ()),
        treecal::io::read_plan(&fifo).map(|_| ()),
        treecal::io::read_registration(Path::new("/dev/zero")).map(|_| ()),
        treecal::io::read_plan(dir.path()).map(|_| ()),
    ] {
        let error = reader.unwrap_err().to_string();
        assert!(
            error.contains("treecal reads only regular files"),
            "{error}"
        );
    }
    assert!(
        matches!(read_mesh_vertices(&fifo), MeshLookup::Unreadable(m) if m.contains("pipe.yaml: is not a regular file"))
    );
    let mtl_fifo = dir.path().join("materials.mtl");
    std::process::Command::new("mkfifo")
        .arg(&mtl_fifo)
        .status()
        .unwrap();
    let obj = write(
        dir.path(),
        "m.obj",
        "mtllib materials.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
    );
    assert!(matches!(read_mesh_vertices(&obj), MeshLookup::Vertices(v) if v.len() == 3));
    // From the command line: the registration as a FIFO fails at once.
    let run = treecal(&[
        "calibrate",
        "--robot",
        &robot("robonaut/robonaut.urdf").to_string_lossy(),
        "--measurements",
        &robot("robonaut/example/measurements.csv").to_string_lossy(),
        "--measurement-frame",
        fifo.to_str().unwrap(),
        "-o",
        dir.path().join("out").to_str().unwrap(),
    ]);
    assert_eq!(run.code, Some(1), "{run}");
    assert!(
        run.stderr.contains("pipe.yaml: is not a regular file"),
        "{run}"
    );
}

/// A registration of 200 KB (quadratic in the old parser, 18–21 s) is refused or read fast.
#[test]
fn registration_size_and_depth_are_limited() {
    let deep = format!(
        "units: {{length: mm, angle: deg}}\nxyz: {}0{}\nrpy: [0, 0, 0]\n",
        "[".repeat(100_000),
        "]".repeat(100_000)
    );
    let start = std::time::Instant::now();
    let error = treecal::io::parse_registration(&deep, "r.yaml")
        .unwrap_err()
        .to_string();
    assert!(
        error.starts_with("r.yaml:2: the YAML nests more than"),
        "{error}"
    );
    assert!(start.elapsed().as_secs() < 5);
    let big = format!("# {}\n", "x".repeat(limits::MAX_YAML_BYTES as usize));
    let error = treecal::io::parse_registration(&big, "r.yaml")
        .unwrap_err()
        .to_string();
    assert!(error.contains("more than the limit"), "{error}");
}

/// A misspelt plan key is an error naming the closest valid key (it used to be ignored, and
/// every stage then used every row); a plan has at most 32 stages.
#[test]
fn plan_keys_are_checked_and_stages_limited() {
    let typo = "stages:\n  - name: torso\n    parameters: coupled\n    measurement: torso\n";
    let error = parse_plan(typo, "plan.yaml").unwrap_err().to_string();
    assert!(
        error.starts_with("plan.yaml:")
            && error.contains("unknown key 'measurement'; the closest valid key is 'measurements'"),
        "{error}"
    );
    let value = "stages:\n  - name: torso\n    parameters: coupld\n";
    let error = parse_plan(value, "plan.yaml").unwrap_err().to_string();
    assert!(
        error.contains("the closest valid value is 'coupled'"),
        "{error}"
    );
    let good = "stages:\n  - name: torso\n    parameters: coupled\n    measurements: torso\n";
    assert_eq!(parse_plan(good, "plan.yaml").unwrap().stages.len(), 1);
    let many = format!(
        "stages:\n{}",
        "  - name: s\n    parameters: all\n".repeat(limits::MAX_PLAN_STAGES + 1)
    );
    let error = parse_plan(&many, "plan.yaml").unwrap_err().to_string();
    assert!(
        error.contains("33 stages is more than the limit of 32"),
        "{error}"
    );
}

/// Unknown keys of a params file are errors, the keys the calibration writes are not.
#[test]
fn params_keys_are_checked() {
    let (tree, model) = robonaut_model();
    let written = "robot: r2\nunits: SI\nmeasurement_frame: {xyz: [0, 0, 0]}\nparameters:\n  - name: left_joint1 alpha\n    owner: left_joint1\n    kind: alpha\n    unit: rad\n    nominal: 1.5\n    calibrated: 1.5712\n    change: 0.07\n    std_dev: 0.001\n    identifiable: true\n";
    assert!(treecal::io::parse_parameters(written, "p.yaml", &tree, &model).is_ok());
    let typo = written.replace("calibrated:", "calibrate:");
    let error = treecal::io::parse_parameters(&typo, "p.yaml", &tree, &model)
        .unwrap_err()
        .to_string();
    assert!(
        error.contains("the closest valid key is 'calibrated'"),
        "{error}"
    );
}

/// A header of commas is refused by the column limit while it is scanned (it took 4 GB), and a
/// long field by the field limit; good CSV passes.
#[test]
fn csv_limits_apply_while_reading() {
    let commas = format!("a{}\n", ",".repeat(20_000_000));
    let start = std::time::Instant::now();
    let error = parse_csv(&commas, "j.csv").unwrap_err().to_string();
    assert!(
        error.starts_with("j.csv:1: the row has more than the limit of 10000 columns"),
        "{error}"
    );
    assert!(start.elapsed().as_secs() < 5);
    let field = format!("a,b\n1,{}\n", "2".repeat(10_000_000));
    let error = parse_csv(&field, "j.csv").unwrap_err().to_string();
    assert!(
        error.starts_with("j.csv:2: field 2 has 10000000 bytes") && error.len() < 200,
        "{error}"
    );
    assert_eq!(parse_csv("a,b\n1,2\n", "j.csv").unwrap().records.len(), 1);
}

/// Read-time messages: a BOM does not hide the units comment, two units comments are an
/// error, long values are cut, an oversized payload names file, line and column.
#[test]
fn measurement_messages_at_read_time() {
    let (tree, model) = robonaut_model();
    let example = std::fs::read_to_string(robot("robonaut/example/measurements.csv")).unwrap();
    assert!(example.starts_with("# units:"), "{}", &example[..40]);
    let read = |text: &str| {
        treecal::io::parse_measurements(text, "m.csv", &tree, &model, &Default::default())
    };
    let plain = read(&example).unwrap();
    let bom = read(&format!("\u{feff}{example}")).unwrap();
    assert_eq!(bom.units, plain.units);
    let units = example.lines().next().unwrap();
    let twice = read(&format!("{units}\n{example}"))
        .unwrap_err()
        .to_string();
    assert!(
        twice.starts_with("m.csv:2: a second units comment (the first is on line 1)"),
        "{twice}"
    );
    // A 60 KB tool name (under the field limit) is cut in the message.
    let lines: Vec<&str> = example.lines().collect();
    let header: Vec<&str> = lines[1].split(',').collect();
    let tool = header.iter().position(|c| *c == "tool").unwrap();
    let mut row: Vec<String> = lines[2].split(',').map(str::to_owned).collect();
    row[tool] = "t".repeat(60_000);
    let long = format!("{}\n{}\n{}\n", lines[0], lines[1], row.join(","));
    let error = read(&long).unwrap_err().to_string();
    assert!(
        error.len() < 1000 && error.contains("ttt…'"),
        "{}",
        &error[..200.min(error.len())]
    );
    // payload_kg beyond the mass limit, at read time with file, row and column.
    let with_payload = format!(
        "{}\n{},payload_kg\n{},1e300\n",
        lines[0], lines[1], lines[2]
    );
    let error = read(&with_payload).unwrap_err().to_string();
    assert!(
        error.contains("payload_kg") && error.contains("1e300 is beyond the limit ±1e6"),
        "{error}"
    );
    let fine = format!("{}\n{},payload_kg\n{},2.5\n", lines[0], lines[1], lines[2]);
    assert!(read(&fine).is_ok());
}

/// No message prints a number with hundreds of digits (Rust's `{}` of 1e300 does).
#[test]
fn huge_numbers_show_in_exponent_notation() {
    let (tree, model) = robonaut_model();
    for text in [
        "payloads:\n  left_tool: {mass_kg: 1e300}\n",
        "joints:\n  default: {bending_nm_per_rad: -1e300}\n",
        "links:\n  default: {ea_n: -1e300}\n",
    ] {
        let error = treecal::io::parse_stiffness(text, "s.yaml", &tree, &model)
            .unwrap_err()
            .to_string();
        assert!(error.contains("1e300") && error.len() < 300, "{error}");
    }
    let plan = "stages:\n  - name: 1e300\n    parameters: 1e300\n";
    let error = parse_plan(plan, "p.yaml").unwrap_err().to_string();
    assert!(error.len() < 400, "{error}");
}

/// Spreadsheet exports of the measurement CSV: semicolons (with decimal commas, or not) and
/// tabs are named at the header's line with what to do, never a missing column or a field
/// count; UTF-16 with its byte-order mark (a "Unicode text" export) reads as the UTF-8 file,
/// and without it the message names UTF-16 and how to save the file.
#[test]
fn spreadsheet_exports_are_named() {
    let (tree, model) = robonaut_model();
    let example = std::fs::read_to_string(robot("robonaut/example/measurements.csv")).unwrap();
    let read = |text: &str| {
        treecal::io::parse_measurements(text, "m.csv", &tree, &model, &Default::default())
    };
    let plain = read(&example).unwrap();
    let header_line = 1 + example.lines().take_while(|l| l.starts_with('#')).count();
    let resaved = |separator: &str, decimal: &str| -> String {
        let lines = example.lines().map(|l| match l.starts_with('#') {
            true => l.to_owned(),
            false => l.replace(',', separator).replace('.', decimal),
        });
        lines.map(|l| l + "\n").collect()
    };
    for (text, named) in [
        (resaved(";", ","), "semicolons"),
        (resaved(";", "."), "semicolons"),
        (resaved("\t", "."), "tabs"),
    ] {
        let error = read(&text).unwrap_err().to_string();
        assert!(
            error.starts_with(&format!(
                "m.csv:{header_line}: the header row is separated by {named}"
            )) && error.contains("\"CSV (comma delimited)\""),
            "{error}"
        );
    }
    let dir = tempfile::tempdir().unwrap();
    let utf16 = |bom: bool| {
        let path = dir.path().join("m16.csv");
        let mut bytes: Vec<u8> = if bom { vec![0xFF, 0xFE] } else { Vec::new() };
        bytes.extend(example.encode_utf16().flat_map(u16::to_le_bytes));
        std::fs::write(&path, bytes).unwrap();
        treecal::io::read_text(&path, limits::MAX_CSV_BYTES)
    };
    let decoded = utf16(true).unwrap();
    assert_eq!(
        read(&decoded).unwrap().measurements.len(),
        plain.measurements.len()
    );
    let error = utf16(false).unwrap_err().to_string();
    assert!(
        error.contains("m16.csv")
            && error.contains("UTF-16 without a byte-order mark")
            && error.contains("CSV UTF-8"),
        "{error}"
    );
}

/// Xacro leftovers in a URDF (issue 21): a `${…}` expression was "wrong vector element
/// count", and an `<xacro:include>` or a macro call was ignored without a word (the links it
/// would add silently missing). Both now name the line and say to expand the file first.
#[test]
fn xacro_leftovers_are_named_with_their_line() {
    let urdf = std::fs::read_to_string(robot("robonaut/robonaut.urdf")).unwrap();
    let read = |text: &str| treecal::urdf::parse_urdf(text, "r.urdf");
    assert!(read(&urdf).is_ok());
    let line_of =
        |text: &str, needle: &str| 1 + text[..text.find(needle).unwrap()].matches('\n').count();
    let first_origin = urdf.find("<origin xyz=\"").unwrap();
    let value = first_origin + "<origin xyz=\"".len();
    let expression = format!("{}${{offset}} {}", &urdf[..value], &urdf[value..]);
    let include = urdf.replacen(
        "</robot>",
        "  <xacro:include filename=\"$(find robonaut)/urdf/hand.xacro\"/>\n  <xacro:hand side=\"left\"/>\n</robot>",
        1,
    );
    for (text, needle, what) in [
        (&expression, "${offset}", "<origin xyz=\"${offset}"),
        (&include, "<xacro:include", "<xacro:include>"),
    ] {
        let error = read(text).unwrap_err().to_string();
        let place = format!("r.urdf:{}:", line_of(text, needle));
        assert!(
            error.starts_with(&place)
                && error.contains(what)
                && error.contains("expand it first (`xacro robot.urdf.xacro > robot.urdf`"),
            "{place} {error}"
        );
    }
}
