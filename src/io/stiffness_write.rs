//! Writing stiffness data in the stiffness YAML format (`docs/flexibility.md`, section 8), so
//! that an identified stiffness can be given back to `--stiffness`.

use crate::kinematics::{JointStiffness, LinkStiffness, Stiffness};
use std::fmt::Write;

/// `stiffness` as a stiffness file, with `comment` (one or more lines) at the top. Reads back
/// to the same values (shortest round-trip numbers; `.inf` for rigid).
pub fn stiffness_to_yaml(stiffness: &Stiffness, comment: &str) -> String {
    let mut out = String::new();
    for line in comment.lines() {
        let _ = writeln!(out, "# {line}");
    }
    let g = stiffness.gravity;
    let _ = writeln!(
        out,
        "gravity_m_per_s2: [{}, {}, {}]",
        number(g.x),
        number(g.y),
        number(g.z)
    );
    let _ = writeln!(out, "self_weight: {}", stiffness.self_weight);
    if stiffness.payloads.is_empty() {
        out.push_str("payloads: {}\n");
    } else {
        out.push_str("payloads:\n");
        for p in &stiffness.payloads {
            let c = p.center_of_mass;
            let _ = writeln!(
                out,
                "  {}: {{mass_kg: {}, center_of_mass_m: [{}, {}, {}]}}",
                p.link,
                number(p.mass),
                number(c.x),
                number(c.y),
                number(c.z)
            );
        }
    }
    out.push_str("joints:\n");
    let _ = writeln!(out, "  default: {}", joint(&stiffness.joint_default));
    write_overrides(&mut out, &stiffness.joint_overrides, joint);
    out.push_str("links:\n");
    let _ = writeln!(out, "  default: {}", link(&stiffness.link_default));
    write_overrides(&mut out, &stiffness.link_overrides, link);
    out
}

fn write_overrides<T>(out: &mut String, overrides: &[(String, T)], entry: fn(&T) -> String) {
    if overrides.is_empty() {
        out.push_str("  overrides: {}\n");
        return;
    }
    out.push_str("  overrides:\n");
    for (name, value) in overrides {
        let _ = writeln!(out, "    {name}: {}", entry(value));
    }
}

fn joint(s: &JointStiffness) -> String {
    format!(
        "{{bending_nm_per_rad: {}, torsion_nm_per_rad: {}}}",
        number(s.bending),
        number(s.torsion)
    )
}

fn link(s: &LinkStiffness) -> String {
    format!(
        "{{ea_n: {}, ei_y_nm2: {}, ei_z_nm2: {}, gi_p_nm2: {}}}",
        number(s.axial),
        number(s.bending_y),
        number(s.bending_z),
        number(s.torsion)
    )
}

/// A YAML number: shortest round-trip digits, `.inf` for +∞.
fn number(value: f64) -> String {
    if value == f64::INFINITY {
        ".inf".into()
    } else {
        format!("{value:?}")
    }
}
