//! Reading a URDF the way ROS tools do: only the kinematic elements can stop it loading.
//!
//! urdf-rs deserialises everything it models, so a `<texture/>` without a file name, a
//! `<material>` it does not like or an odd `<safety_controller>` makes the whole robot
//! unreadable, with a message that names neither line nor element. urdfdom (`check_urdf`,
//! Pinocchio, RViz) ignores such things. So urdf-rs is handed a copy of the text in which
//! every element it does not need for the kinematic tree, the inertias and the link geometry
//! is blanked out (replaced by spaces, newlines kept, so lines stay where they were):
//!
//! - under `<robot>`: `<link>` and `<joint>` are kept; `<material>`, `<gazebo>`,
//!   `<transmission>`, `<sensor>`, xacro leftovers and anything unknown are blanked;
//! - under `<link>`: `<inertial>`, `<visual>`, `<collision>`;
//! - under `<inertial>`: `<origin>`, `<mass>`, `<inertia>`;
//! - under `<visual>`/`<collision>`: `<origin>`, `<geometry>` (and what it holds);
//! - under `<joint>`: `<parent>`, `<child>`, `<origin>`, `<axis>`, `<limit>`, `<mimic>`
//!   (`<dynamics>`, `<calibration>`, `<safety_controller>` are blanked).
//!
//! A `<visual>` that urdf-rs still cannot read (an unknown geometry) is dropped with a
//! warning. Any other error is located: each `<link>` and `<joint>` is read on its own to find
//! the one at fault, and the message names its line.

use super::xml::{line_at, position, Element};
use crate::error::{Error, Result};

/// The children kept under an element called `parent` (`None`: keep everything below).
fn kept_children(parent: &str) -> Option<&'static [&'static str]> {
    Some(match parent {
        "robot" => &["link", "joint"],
        "link" => &["inertial", "visual", "collision"],
        "inertial" => &["origin", "mass", "inertia"],
        "visual" | "collision" => &["origin", "geometry"],
        "joint" => &["parent", "child", "origin", "axis", "limit", "mimic"],
        "geometry" => return None,
        _ => &[],
    })
}

/// Reads the robot from `text`, whose `elements` [`scan`](super::xml::scan) has found (so
/// `elements[0]` is the `<robot>` root).
/// Warnings (visuals that had to be dropped) are appended to `warnings`.
pub(crate) fn read_robot(
    text: &str,
    origin: &str,
    elements: &[Element],
    warnings: &mut Vec<String>,
) -> Result<urdf_rs::Robot> {
    let mut blank = vec![false; elements.len()];
    for (index, element) in elements.iter().enumerate() {
        let Some(parent) = element.parent else {
            continue;
        };
        let dropped = blank[parent]
            || kept_children(&elements[parent].name)
                .is_some_and(|kept| !kept.contains(&element.name.as_str()));
        blank[index] = dropped;
    }
    let mut kinematic = text.as_bytes().to_vec();
    let erase = |bytes: &mut Vec<u8>, element: &Element| {
        for b in &mut bytes[element.start..element.end] {
            if *b != b'\n' {
                *b = b' ';
            }
        }
    };
    for (index, element) in elements.iter().enumerate() {
        // Only the outermost blanked element needs erasing.
        if blank[index] && element.parent.is_some_and(|p| !blank[p]) {
            erase(&mut kinematic, element);
        }
    }
    // Every erased range starts at '<' and ends after '>', so the text stays valid UTF-8.
    let mut kinematic = String::from_utf8(kinematic).map_err(|e| Error::UrdfParse {
        origin: origin.to_owned(),
        message: format!("internal error while preparing the text: {e}"),
    })?;

    // Each pass either reads the robot or drops one unreadable visual (or fails).
    loop {
        let error = match urdf_rs::read_from_string(&kinematic) {
            Ok(robot) => return Ok(robot),
            Err(error) => error.to_string(),
        };
        // No single <link> or <joint> fails: the <robot> element itself is at fault.
        let culprit = locate(&kinematic, elements, &blank).ok_or_else(|| Error::UrdfParse {
            origin: format!("{origin}:{}", line_at(text, elements[0].start)),
            message: format!("{}: {error}", describe(text, &elements[0])),
        })?;
        let element = &elements[culprit.element];
        let what = describe(text, element);
        let line = line_at(text, element.start);
        if culprit.visuals.is_empty() {
            // At the attribute at fault when one is found (a tag may span lines).
            return Err(match culprit.attribute {
                Some((e, a)) => {
                    let attribute = &elements[e].attributes[a];
                    let named = format!(
                        "{}=\"{}\"",
                        attribute.name,
                        crate::limits::cut(&text[attribute.value.clone()])
                    );
                    let named = if e == culprit.element {
                        named
                    } else {
                        format!("<{} {named}>", elements[e].name)
                    };
                    Error::UrdfParse {
                        origin: position(text, origin, attribute.value.start),
                        message: format!("{what}: {named}: {}", culprit.message),
                    }
                }
                None => Error::UrdfParse {
                    origin: format!("{origin}:{line}"),
                    message: format!("{what}: {}", culprit.message),
                },
            });
        }
        let mut bytes = std::mem::take(&mut kinematic).into_bytes();
        for &visual in &culprit.visuals {
            erase(&mut bytes, &elements[visual]);
        }
        kinematic = String::from_utf8(bytes).map_err(|e| Error::UrdfParse {
            origin: origin.to_owned(),
            message: format!("internal error while preparing the text: {e}"),
        })?;
        warnings.push(format!(
            "{what} (line {line}): its <visual> cannot be read ({}); ignored (visuals do not affect kinematics)",
            culprit.message
        ));
    }
}

/// The `<link>` or `<joint>` urdf-rs cannot read, with its message, and (for a link that
/// reads without them) the visuals to drop.
struct Culprit {
    element: usize,
    message: String,
    visuals: Vec<usize>,
    /// The attribute at fault, when one is found ([`attribute_at_fault`]): its element and
    /// its index there.
    attribute: Option<(usize, usize)>,
}

/// Reads `snippet` (one `<link>` or `<joint>`) on its own: urdf-rs's message, if it fails.
fn alone(snippet: &str) -> Option<String> {
    urdf_rs::read_from_string(&format!("<robot name=\"located\">{snippet}</robot>"))
        .err()
        .map(|e| e.to_string())
}

/// The attribute of element `index` (a `<link>` or `<joint>` that fails with `message`) or of
/// the elements inside it that is at fault: the one whose value the message quotes
/// (`` `revolutex` ``, `[0 0 x]`), else the one whose value, each word replaced by `0`, makes
/// the element readable (a bad number). `None` when no single attribute is (then the message
/// names the element's line).
fn attribute_at_fault(
    kinematic: &str,
    elements: &[Element],
    blank: &[bool],
    (index, message): (usize, &str),
) -> Option<(usize, usize)> {
    let outer = &elements[index];
    let inside: Vec<usize> = (index..elements.len())
        .take_while(|&e| elements[e].start < outer.end)
        .filter(|&e| !blank[e])
        .collect();
    let attributes = || {
        inside.iter().flat_map(|&e| {
            (0..elements[e].attributes.len()).map(move |a| (e, a, &elements[e].attributes[a]))
        })
    };
    let quoted = attributes().find(|(_, _, attribute)| {
        let value = &kinematic[attribute.value.clone()];
        !value.trim().is_empty()
            && (message.contains(&format!("`{value}`")) || message.contains(&format!("[{value}]")))
    });
    if let Some((e, a, _)) = quoted {
        return Some((e, a));
    }
    attributes()
        .find(|(_, _, attribute)| {
            let value = &kinematic[attribute.value.clone()];
            let zeros = vec!["0"; value.split_whitespace().count().max(1)].join(" ");
            let snippet = format!(
                "{}{zeros}{}",
                &kinematic[outer.start..attribute.value.start],
                &kinematic[attribute.value.end..outer.end]
            );
            alone(&snippet).is_none()
        })
        .map(|(e, a, _)| (e, a))
}

/// Reads each kept `<link>` and `<joint>` of `kinematic` on its own; the first that fails.
fn locate(kinematic: &str, elements: &[Element], blank: &[bool]) -> Option<Culprit> {
    for (index, element) in elements.iter().enumerate() {
        if element.parent != Some(0) || blank[index] {
            continue;
        }
        let snippet = &kinematic[element.start..element.end];
        let Some(message) = alone(snippet) else {
            continue;
        };
        let visuals: Vec<usize> = (index + 1..elements.len())
            .take_while(|&v| elements[v].start < element.end)
            .filter(|&v| elements[v].parent == Some(index) && elements[v].name == "visual")
            .collect();
        let without = if element.name == "link" && !visuals.is_empty() {
            let mut bytes = snippet.as_bytes().to_vec();
            for &v in &visuals {
                let range = elements[v].start - element.start..elements[v].end - element.start;
                bytes[range].fill(b' ');
            }
            String::from_utf8(bytes).ok()
        } else {
            None
        };
        let visuals = match without {
            Some(without) if alone(&without).is_none() => visuals,
            _ => Vec::new(),
        };
        let attribute = visuals
            .is_empty()
            .then(|| attribute_at_fault(kinematic, elements, blank, (index, &message)))
            .flatten();
        return Some(Culprit {
            element: index,
            message,
            visuals,
            attribute,
        });
    }
    None
}

/// `<link name="x">` as written, or `<joint>` if it has no name.
fn describe(text: &str, element: &Element) -> String {
    match element.attribute("name") {
        Some(name) => format!(
            "<{} name=\"{}\">",
            element.name,
            super::xml::unescape(&text[name.value.clone()])
        ),
        None => format!("<{}>", element.name),
    }
}
