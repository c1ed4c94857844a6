//! Validation of a parsed URDF against the bounds of [`crate::limits`]: before conversion, the
//! robot is not too large and its names are printable and of sane length; after it, every
//! number treecal uses is finite and of a sane magnitude for its quantity.

use crate::error::{Error, Result};
use crate::limits::{magnitude_problem, name_problem, Quantity, MAX_JOINTS};

/// An error about `<tag name="name">`, at its line when the text shows it.
fn at(text: &str, origin: &str, tag: &str, name: &str, message: String) -> Error {
    Error::InvalidRobot {
        origin: match element_line(text, tag, name) {
            Some(line) => format!("{origin}:{line}"),
            None => origin.to_owned(),
        },
        message,
    }
}

/// The joint count and every name of `robot` (parsed from `text`).
pub(super) fn check_sizes(robot: &urdf_rs::Robot, text: &str, origin: &str) -> Result<()> {
    let at = |tag: &str, name: &str, message: String| at(text, origin, tag, name, message);
    if robot.joints.len() > MAX_JOINTS || robot.links.len() > MAX_JOINTS + 1 {
        return Err(Error::InvalidRobot {
            origin: origin.to_owned(),
            message: format!(
                "the robot has {} joints and {} links; at most {MAX_JOINTS} joints are accepted \
                 (docs/file-formats.md, \"Limits\")",
                robot.joints.len(),
                robot.links.len()
            ),
        });
    }
    if let Some(problem) = name_problem(&robot.name) {
        return Err(at("robot", &robot.name, format!("<robot>: {problem}")));
    }
    for link in &robot.links {
        if let Some(problem) = name_problem(&link.name) {
            return Err(at("link", &link.name, format!("<link>: {problem}")));
        }
    }
    for joint in &robot.joints {
        if let Some(problem) = name_problem(&joint.name) {
            return Err(at("joint", &joint.name, format!("<joint>: {problem}")));
        }
    }
    Ok(())
}

/// Every number of `robot` that treecal uses; errors name the element, its line and the
/// attribute.
pub(super) fn check_numbers(robot: &urdf_rs::Robot, text: &str, origin: &str) -> Result<()> {
    let at = |tag: &str, name: &str, message: String| at(text, origin, tag, name, message);
    for link in &robot.links {
        let fail = |what: &str, problem: String| {
            at(
                "link",
                &link.name,
                format!("link '{}' {what}: {problem}", short(&link.name)),
            )
        };
        let inertial = &link.inertial;
        let i = &inertial.inertia;
        check(&[inertial.mass.value], Quantity::Mass)
            .map_err(|p| fail("<inertial><mass value>", p))?;
        check(
            &[i.ixx, i.ixy, i.ixz, i.iyy, i.iyz, i.izz],
            Quantity::Inertia,
        )
        .map_err(|p| fail("<inertial><inertia>", p))?;
        pose(&inertial.origin).map_err(|p| fail("<inertial><origin>", p))?;
        let shapes = link
            .visual
            .iter()
            .map(|v| ("<visual>", &v.origin, &v.geometry))
            .chain(
                link.collision
                    .iter()
                    .map(|c| ("<collision>", &c.origin, &c.geometry)),
            );
        for (tag, placement, shape) in shapes {
            pose(placement).map_err(|p| fail(&format!("{tag}<origin>"), p))?;
            geometry(shape).map_err(|p| fail(&format!("{tag}<geometry>"), p))?;
        }
    }
    for joint in &robot.joints {
        let fail = |what: &str, problem: String| {
            at(
                "joint",
                &joint.name,
                format!("joint '{}' {what}: {problem}", short(&joint.name)),
            )
        };
        pose(&joint.origin).map_err(|p| fail("<origin>", p))?;
        check(&joint.axis.xyz.0, Quantity::Factor).map_err(|p| fail("<axis xyz>", p))?;
        check(
            &[joint.limit.lower, joint.limit.upper],
            Quantity::JointLimit,
        )
        .map_err(|p| fail("<limit>", p))?;
        if let Some(mimic) = &joint.mimic {
            let offset = match joint.joint_type {
                urdf_rs::JointType::Prismatic => Quantity::Length,
                _ => Quantity::Angle,
            };
            check(&[mimic.multiplier.unwrap_or(1.0)], Quantity::Factor)
                .map_err(|p| fail("<mimic multiplier>", p))?;
            check(&[mimic.offset.unwrap_or(0.0)], offset).map_err(|p| fail("<mimic offset>", p))?;
        }
    }
    Ok(())
}

/// The first problem among `values` as `quantity`.
fn check(values: &[f64], quantity: Quantity) -> std::result::Result<(), String> {
    match values.iter().find_map(|&v| magnitude_problem(v, quantity)) {
        Some(problem) => Err(problem),
        None => Ok(()),
    }
}

fn pose(p: &urdf_rs::Pose) -> std::result::Result<(), String> {
    check(&p.xyz.0, Quantity::Length).map_err(|e| format!("xyz: {e}"))?;
    check(&p.rpy.0, Quantity::Angle).map_err(|e| format!("rpy: {e}"))
}

fn geometry(shape: &urdf_rs::Geometry) -> std::result::Result<(), String> {
    use urdf_rs::Geometry;
    match shape {
        Geometry::Box { size } => check(&size.0, Quantity::Length),
        Geometry::Cylinder { radius, length } | Geometry::Capsule { radius, length } => {
            check(&[*radius, *length], Quantity::Length)
        }
        Geometry::Sphere { radius } => check(&[*radius], Quantity::Length),
        Geometry::Mesh { scale, .. } => scale.map_or(Ok(()), |s| check(&s.0, Quantity::Factor)),
    }
}

/// A name shortened for a message.
fn short(name: &str) -> String {
    if name.chars().count() > 60 {
        name.chars().take(60).collect::<String>() + "…"
    } else {
        name.to_owned()
    }
}

/// The 1-based line of `<tag ... name="name"`, if it can be found in the text.
pub(super) fn element_line(text: &str, tag: &str, name: &str) -> Option<usize> {
    for quote in ['"', '\''] {
        let needle = format!("name={quote}{name}{quote}");
        let mut start = 0;
        while let Some(found) = text[start..].find(&needle) {
            let at = start + found;
            let open = text[..at].rfind('<')?;
            let element = text[open + 1..at].trim_start();
            if element.starts_with(tag) && element[tag.len()..].starts_with(char::is_whitespace) {
                return Some(text[..at].matches('\n').count() + 1);
            }
            start = at + needle.len();
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::element_line;

    #[test]
    fn finds_element_lines() {
        let text = "<robot>\n <link name=\"a\"/>\n <joint name=\"a\" type=\"fixed\">\n</robot>";
        assert_eq!(element_line(text, "link", "a"), Some(2));
        assert_eq!(element_line(text, "joint", "a"), Some(3));
        assert_eq!(element_line(text, "joint", "b"), None);
    }
}
