//! The MCPC table YAML format (`robots/robonaut/table1.yaml`): the paper's Table 1 layout in
//! the units the paper prints (degrees and millimetres by default). See `docs/file-formats.md`.

use crate::error::{Error, Result};
use crate::kinematics::{FrameKind, McpcTable, TableBranch, TableRow, TableTool};
use crate::limits::{magnitude_problem, name_problem, Quantity};
use serde::Deserialize;
use std::path::Path;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct File {
    robot: String,
    #[serde(default = "default_base")]
    base_link: String,
    units: Units,
    /// Default limits of revolute joints, in the angle unit.
    #[serde(default)]
    joint_limits: Option<[f64; 2]>,
    branches: Vec<Branch>,
}

fn default_base() -> String {
    "base_link".into()
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Units {
    angle: String,
    length: String,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Branch {
    name: String,
    #[serde(default)]
    parent: Option<String>,
    #[serde(default)]
    rows: Vec<Row>,
    #[serde(default)]
    tool: Option<Tool>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Row {
    joint: String,
    link: String,
    #[serde(default, rename = "type")]
    kind: Option<String>,
    #[serde(default)]
    phi: f64,
    alpha: f64,
    beta: f64,
    #[serde(default)]
    x: Option<f64>,
    #[serde(default)]
    y: Option<f64>,
    #[serde(default)]
    limits: Option<[f64; 2]>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Tool {
    link: String,
    #[serde(default)]
    phi: f64,
    alpha: f64,
    beta: f64,
    gamma: f64,
    x: f64,
    y: f64,
    z: f64,
}

/// Reads an MCPC table file.
pub fn read_mcpc_table(path: &Path) -> Result<McpcTable> {
    let text = crate::limits::read_text(path, crate::limits::MAX_YAML_BYTES)?;
    parse_mcpc_table(&text, &path.display().to_string())
}

/// Parses an MCPC table; `origin` names the source in messages.
pub fn parse_mcpc_table(text: &str, origin: &str) -> Result<McpcTable> {
    let file: File = super::yaml::parse_yaml(text, origin, "").map_err(|e| match e {
        Error::InvalidData { origin, message } => Error::InvalidTable { origin, message },
        other => other,
    })?;
    let bad = |message: String| Error::InvalidTable {
        origin: origin.to_owned(),
        message,
    };
    let angle = match file.units.angle.as_str() {
        "deg" | "degree" | "degrees" => std::f64::consts::PI / 180.0,
        "rad" | "radian" | "radians" => 1.0,
        other => return Err(bad(format!("units.angle is '{other}'; use deg or rad"))),
    };
    let length = match file.units.length.as_str() {
        "mm" | "millimetre" | "millimeter" => 1e-3,
        "m" | "metre" | "meter" => 1.0,
        other => return Err(bad(format!("units.length is '{other}'; use mm or m"))),
    };
    let default_limits = file.joint_limits.unwrap_or([
        -180.0_f64.to_radians() / angle,
        180.0_f64.to_radians() / angle,
    ]);

    let mut branches = Vec::new();
    for branch in file.branches {
        let mut rows = Vec::new();
        for row in branch.rows {
            let kind = match row.kind.as_deref() {
                None | Some("revolute") => FrameKind::Revolute,
                Some("prismatic") => FrameKind::Prismatic,
                Some(other) => {
                    return Err(bad(format!(
                        "joint '{}' has type '{other}'; use revolute or prismatic",
                        row.joint
                    )))
                }
            };
            let (x, y) = (row.x.unwrap_or(0.0), row.y.unwrap_or(0.0));
            if kind == FrameKind::Prismatic && (x != 0.0 || y != 0.0) {
                return Err(bad(format!(
                    "prismatic joint '{}' has x or y: a prismatic MCPC frame has only alpha and beta (its origin is the previous frame's)",
                    row.joint
                )));
            }
            if kind == FrameKind::Revolute && (row.x.is_none() || row.y.is_none()) {
                return Err(bad(format!(
                    "revolute joint '{}' needs both x and y",
                    row.joint
                )));
            }
            let limits = match (row.limits, kind) {
                (Some([lo, hi]), FrameKind::Revolute) => (lo * angle, hi * angle),
                (Some([lo, hi]), FrameKind::Prismatic) => (lo * length, hi * length),
                (None, FrameKind::Revolute) => {
                    (default_limits[0] * angle, default_limits[1] * angle)
                }
                (None, FrameKind::Prismatic) => {
                    return Err(bad(format!("prismatic joint '{}' needs limits", row.joint)))
                }
            };
            rows.push(TableRow {
                joint: row.joint,
                link: row.link,
                kind,
                phi: row.phi * angle,
                alpha: row.alpha * angle,
                beta: row.beta * angle,
                x: x * length,
                y: y * length,
                limits,
            });
        }
        let tool = branch.tool.map(|t| TableTool {
            link: t.link,
            phi: t.phi * angle,
            alpha: t.alpha * angle,
            beta: t.beta * angle,
            gamma: t.gamma * angle,
            x: t.x * length,
            y: t.y * length,
            z: t.z * length,
        });
        branches.push(TableBranch {
            name: branch.name,
            parent: branch.parent,
            rows,
            tool,
        });
    }
    let table = McpcTable {
        robot: file.robot,
        base_link: file.base_link,
        branches,
    };
    check_bounds(&table, origin)?;
    table.validate(origin)?;
    Ok(table)
}

/// Every name printable and of sane length, every number (converted to rad and m) finite and
/// within the bound of its quantity ([`crate::limits`]); errors name the joint or tool and key.
fn check_bounds(table: &McpcTable, origin: &str) -> Result<()> {
    let bad = |message: String| Error::InvalidTable {
        origin: origin.to_owned(),
        message,
    };
    let named = [("robot", &table.robot), ("base_link", &table.base_link)];
    for (key, name) in named {
        if let Some(problem) = name_problem(name) {
            return Err(bad(format!("{key}: {problem}")));
        }
    }
    let number = |what: &str, key: &str, value: f64, quantity: Quantity| match magnitude_problem(
        value, quantity,
    ) {
        Some(problem) => Err(bad(format!(
            "{what}, {key}: {problem} (after unit conversion)"
        ))),
        None => Ok(()),
    };
    for branch in &table.branches {
        let mut names = vec![&branch.name];
        names.extend(&branch.parent);
        for row in &branch.rows {
            names.extend([&row.joint, &row.link]);
            let what = format!("joint '{}'", row.joint);
            for (key, value) in [("phi", row.phi), ("alpha", row.alpha), ("beta", row.beta)] {
                number(&what, key, value, Quantity::Angle)?;
            }
            for (key, value) in [("x", row.x), ("y", row.y)] {
                number(&what, key, value, Quantity::Length)?;
            }
            // URDFs write ±1e16 for "unbounded", and to-mcpc passes it on.
            number(&what, "limits", row.limits.0, Quantity::JointLimit)?;
            number(&what, "limits", row.limits.1, Quantity::JointLimit)?;
        }
        if let Some(t) = &branch.tool {
            names.push(&t.link);
            let what = format!("tool '{}'", t.link);
            let angles = [
                ("phi", t.phi),
                ("alpha", t.alpha),
                ("beta", t.beta),
                ("gamma", t.gamma),
            ];
            for (key, value) in angles {
                number(&what, key, value, Quantity::Angle)?;
            }
            for (key, value) in [("x", t.x), ("y", t.y), ("z", t.z)] {
                number(&what, key, value, Quantity::Length)?;
            }
        }
        for name in names {
            if let Some(problem) = name_problem(name) {
                return Err(bad(format!("branch '{}': {problem}", branch.name)));
            }
        }
    }
    Ok(())
}

/// Writes a table in the YAML format [`parse_mcpc_table`] reads, in degrees and millimetres,
/// numbers at full precision; `header` lines become comments at the top.
pub fn mcpc_table_to_yaml(table: &McpcTable, header: &[String]) -> String {
    use std::fmt::Write;
    let deg = |v: f64| number(v.to_degrees());
    let mm = |v: f64| number(v * 1e3);
    let mut out = String::new();
    for line in header {
        // A line break in a header line (a file name can hold one) would end the comment.
        let _ = writeln!(out, "# {}", line.replace(char::is_control, " "));
    }
    let _ = writeln!(out, "robot: {}", quoted(&table.robot));
    let _ = writeln!(out, "base_link: {}", quoted(&table.base_link));
    let _ = writeln!(out, "units: {{angle: deg, length: mm}}");
    let _ = writeln!(out, "branches:");
    for branch in &table.branches {
        let _ = writeln!(out, "  - name: {}", quoted(&branch.name));
        if let Some(parent) = &branch.parent {
            let _ = writeln!(out, "    parent: {}", quoted(parent));
        }
        let _ = writeln!(
            out,
            "    rows:{}",
            if branch.rows.is_empty() { " []" } else { "" }
        );
        for row in &branch.rows {
            let (limits, position) = match row.kind {
                FrameKind::Revolute => (
                    format!("[{}, {}]", deg(row.limits.0), deg(row.limits.1)),
                    format!(", x: {}, y: {}", mm(row.x), mm(row.y)),
                ),
                FrameKind::Prismatic => (
                    format!("[{}, {}]", mm(row.limits.0), mm(row.limits.1)),
                    String::new(),
                ),
            };
            let kind = match row.kind {
                FrameKind::Revolute => "revolute",
                FrameKind::Prismatic => "prismatic",
            };
            let _ = writeln!(
                out,
                "      - {{joint: {}, link: {}, type: {kind}, phi: {}, alpha: {}, beta: {}{position}, limits: {limits}}}",
                quoted(&row.joint),
                quoted(&row.link),
                deg(row.phi),
                deg(row.alpha),
                deg(row.beta),
            );
        }
        if let Some(t) = &branch.tool {
            let _ = writeln!(
                out,
                "    tool: {{link: {}, phi: {}, alpha: {}, beta: {}, gamma: {}, x: {}, y: {}, z: {}}}",
                quoted(&t.link),
                deg(t.phi),
                deg(t.alpha),
                deg(t.beta),
                deg(t.gamma),
                mm(t.x),
                mm(t.y),
                mm(t.z)
            );
        }
    }
    out
}

/// Shortest round-trip decimal; float noise below 1e-12 (deg or mm) written as 0.
fn number(value: f64) -> String {
    if value.abs() < 1e-12 {
        "0".into()
    } else {
        format!("{value}")
    }
}

/// A YAML string scalar, quoted so that names like `r2/left_palm` or `yes` stay strings;
/// characters YAML does not allow raw (control characters, line and paragraph separators,
/// byte-order marks) are written as escapes, so that the file reads back.
fn quoted(text: &str) -> String {
    let mut out = String::with_capacity(text.len() + 2);
    out.push('"');
    for c in text.chars() {
        match c {
            '\\' => out.push_str("\\\\"),
            '"' => out.push_str("\\\""),
            c if c.is_control() || matches!(c, '\u{2028}' | '\u{2029}' | '\u{feff}') => {
                out.push_str(&format!("\\u{:04x}", u32::from(c)))
            }
            c => out.push(c),
        }
    }
    out.push('"');
    out
}
