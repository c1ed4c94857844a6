//! The stiffness YAML format (`robots/robonaut/stiffness.yaml`): gravity, payloads, joint and
//! link stiffness for the flexibility model. Units are in the key names (SI throughout); every
//! key is optional and defaults to [`Stiffness::default`]. See `docs/flexibility.md`.

use crate::error::{Error, Result};
use crate::kinematics::McpcModel;
use crate::kinematics::Names;
use crate::kinematics::{mass_problem, stiffness_problem};
use crate::kinematics::{JointStiffness, LinkStiffness, Payload, Stiffness};
use crate::limits::{magnitude_problem, Quantity, MAX_MASS, MIN_STIFFNESS};
use crate::math::Vec3;
use crate::tree::KinematicTree;
use serde::{Deserialize, Deserializer};
use std::collections::BTreeMap;
use std::path::Path;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct File {
    #[serde(default, deserialize_with = "checked::gravity_m_per_s2")]
    gravity_m_per_s2: Option<[f64; 3]>,
    #[serde(default)]
    self_weight: Option<bool>,
    #[serde(default)]
    payloads: Entries<PayloadEntry>,
    #[serde(default)]
    joints: Joints,
    #[serde(default)]
    links: Links,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct PayloadEntry {
    #[serde(deserialize_with = "mass")]
    mass_kg: f64,
    #[serde(default, deserialize_with = "checked::center_of_mass_m")]
    center_of_mass_m: Option<[f64; 3]>,
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct Joints {
    #[serde(default)]
    default: JointEntry,
    #[serde(default)]
    overrides: Entries<JointEntry>,
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct JointEntry {
    #[serde(default, deserialize_with = "checked::bending_nm_per_rad")]
    bending_nm_per_rad: Option<f64>,
    #[serde(default, deserialize_with = "checked::torsion_nm_per_rad")]
    torsion_nm_per_rad: Option<f64>,
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct Links {
    #[serde(default)]
    default: LinkEntry,
    #[serde(default)]
    overrides: Entries<LinkEntry>,
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct LinkEntry {
    #[serde(default, deserialize_with = "checked::ea_n")]
    ea_n: Option<f64>,
    #[serde(default, deserialize_with = "checked::ei_y_nm2")]
    ei_y_nm2: Option<f64>,
    #[serde(default, deserialize_with = "checked::ei_z_nm2")]
    ei_z_nm2: Option<f64>,
    #[serde(default, deserialize_with = "checked::gi_p_nm2")]
    gi_p_nm2: Option<f64>,
}

/// A mapping from names to entries, in file order; a name given twice is an error (a plain map
/// would keep the last one silently).
struct Entries<T>(Vec<(String, T)>);

impl<T> Default for Entries<T> {
    fn default() -> Self {
        Self(Vec::new())
    }
}

impl<'de, T: Deserialize<'de>> Deserialize<'de> for Entries<T> {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        struct Visitor<T>(std::marker::PhantomData<T>);
        impl<'de, T: Deserialize<'de>> serde::de::Visitor<'de> for Visitor<T> {
            type Value = Entries<T>;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("a mapping from names to entries")
            }
            fn visit_map<A: serde::de::MapAccess<'de>>(
                self,
                mut map: A,
            ) -> Result<Self::Value, A::Error> {
                let mut entries: Vec<(String, T)> = Vec::new();
                while let Some((name, value)) = map.next_entry::<String, T>()? {
                    if entries.iter().any(|(n, _)| *n == name) {
                        return Err(serde::de::Error::custom(format!(
                            "duplicate key `{name}`; give each name once"
                        )));
                    }
                    entries.push((name, value));
                }
                Ok(Entries(entries))
            }
        }
        deserializer.deserialize_map(Visitor(std::marker::PhantomData))
    }
}

// Checking numbers while deserialising lets serde_yaml attach the line, column and key path.
fn positive<'de, D: Deserializer<'de>>(
    deserializer: D,
    key: &str,
) -> Result<Option<f64>, D::Error> {
    let value = f64::deserialize(deserializer)?;
    match stiffness_problem(value) {
        Some(problem) => Err(serde::de::Error::custom(format!("{key} {problem}"))),
        // Below it the compliance, and the deflections, overflow.
        None if value < MIN_STIFFNESS => Err(serde::de::Error::custom(format!(
            "{key} is {}; must be at least {MIN_STIFFNESS:e} (docs/file-formats.md, \"Limits\")",
            crate::limits::shown(value)
        ))),
        None => Ok(Some(value)),
    }
}

/// One checked reader per key, so that messages name the key.
mod checked {
    use serde::Deserializer;

    macro_rules! positive {
        ($($key:ident),*) => {$(
            pub(super) fn $key<'de, D: Deserializer<'de>>(d: D) -> Result<Option<f64>, D::Error> {
                super::positive(d, stringify!($key))
            }
        )*};
    }
    positive!(
        bending_nm_per_rad,
        torsion_nm_per_rad,
        ea_n,
        ei_y_nm2,
        ei_z_nm2,
        gi_p_nm2
    );

    macro_rules! finite_vector {
        ($($key:ident),*) => {$(
            pub(super) fn $key<'de, D: Deserializer<'de>>(
                d: D,
            ) -> Result<Option<[f64; 3]>, D::Error> {
                super::finite_vector(d, stringify!($key))
            }
        )*};
    }
    finite_vector!(gravity_m_per_s2, center_of_mass_m);
}

fn mass<'de, D: Deserializer<'de>>(deserializer: D) -> Result<f64, D::Error> {
    let value = f64::deserialize(deserializer)?;
    let problem = mass_problem(value).or_else(|| {
        (value > MAX_MASS).then(|| {
            format!(
                "is {}, beyond the limit {MAX_MASS:e} kg (docs/file-formats.md, \"Limits\")",
                crate::limits::shown(value)
            )
        })
    });
    match problem {
        Some(problem) => Err(serde::de::Error::custom(format!("mass_kg {problem}"))),
        None => Ok(value),
    }
}

fn finite_vector<'de, D: Deserializer<'de>>(
    deserializer: D,
    key: &str,
) -> Result<Option<[f64; 3]>, D::Error> {
    let value = <[f64; 3]>::deserialize(deserializer)?;
    let quantity = if key == "gravity_m_per_s2" {
        Quantity::Acceleration
    } else {
        Quantity::Length
    };
    if !value.iter().all(|v| v.is_finite()) {
        Err(serde::de::Error::custom(format!(
            "{key} is {value:?}; must be three finite numbers"
        )))
    } else if let Some(problem) = value.iter().find_map(|&v| magnitude_problem(v, quantity)) {
        Err(serde::de::Error::custom(format!(
            "{key} is {value:?}: {problem}"
        )))
    } else {
        Ok(Some(value))
    }
}

/// Reads a stiffness file for the robot `tree` with MCPC model `model` (names are checked
/// against them).
pub fn read_stiffness(path: &Path, tree: &KinematicTree, model: &McpcModel) -> Result<Stiffness> {
    let text = crate::limits::read_text(path, crate::limits::MAX_YAML_BYTES)?;
    parse_stiffness(&text, &path.display().to_string(), tree, model)
}

/// Parses a stiffness file; `origin` names the source in messages, which carry
/// `origin:line:column` where the problem is.
pub fn parse_stiffness(
    text: &str,
    origin: &str,
    tree: &KinematicTree,
    model: &McpcModel,
) -> Result<Stiffness> {
    // An empty file would read as every default: a model nobody wrote, "compensated exactly".
    let content = text
        .lines()
        .any(|line| !line.trim().is_empty() && !line.trim_start().starts_with('#'));
    if !content {
        return Err(Error::InvalidData {
            origin: origin.to_owned(),
            message: "the stiffness file is empty; give the robot's stiffness and payloads (docs/flexibility.md; `{}` takes every default explicitly), or leave out `stiffness` to calibrate a rigid robot".into(),
        });
    }
    crate::limits::check_yaml_depth(text, origin)?;
    let file: File = serde_yaml::from_str(text).map_err(|e| yaml_error(text, origin, &e))?;
    // serde_yaml keeps no positions for map keys, so a bad name is found in the text again.
    let at = |path: &[&str], name: &str, message: String| Error::InvalidData {
        origin: match locate(text, path, name) {
            Some((line, column)) => format!("{origin}:{line}:{column}"),
            None => origin.to_owned(),
        },
        message: format!("{}: {message}", path.join(".")),
    };
    let names = Names::new(tree, model);
    let defaults = Stiffness::default();

    let mut payloads = Vec::new();
    for (link, entry) in file.payloads.0 {
        names.tool(&link).map_err(|m| at(&["payloads"], &link, m))?;
        payloads.push(Payload {
            link,
            mass: entry.mass_kg,
            center_of_mass: entry.center_of_mass_m.map_or_else(Vec3::zeros, Vec3::from),
        });
    }

    let joints = file.joints;
    let joint_default = joint_stiffness(&joints.default, &defaults.joint_default);
    let mut joint_overrides = Vec::new();
    for (name, entry) in joints.overrides.0 {
        names
            .joint(&name)
            .map_err(|m| at(&["joints", "overrides"], &name, m))?;
        joint_overrides.push((name, joint_stiffness(&entry, &joint_default)));
    }

    let links = file.links;
    let link_default = link_stiffness(&links.default, &defaults.link_default);
    let mut link_overrides = Vec::new();
    let mut bodies: BTreeMap<usize, String> = BTreeMap::new();
    for (name, entry) in links.overrides.0 {
        let path = ["links", "overrides"];
        let frame = names.body(&name).map_err(|m| at(&path, &name, m))?;
        if let Some(other) = bodies.insert(frame, name.clone()) {
            return Err(at(
                &path,
                &name,
                format!("'{other}' and '{name}' name the same body; give its stiffness once"),
            ));
        }
        link_overrides.push((name, link_stiffness(&entry, &link_default)));
    }

    let stiffness = Stiffness {
        gravity: file.gravity_m_per_s2.map_or(defaults.gravity, Vec3::from),
        self_weight: file.self_weight.unwrap_or(defaults.self_weight),
        payloads,
        joint_default,
        joint_overrides,
        link_default,
        link_overrides,
    };
    stiffness.validate().map_err(|e| Error::InvalidData {
        origin: origin.to_owned(),
        message: e.to_string(),
    })?;
    Ok(stiffness)
}

fn joint_stiffness(entry: &JointEntry, fallback: &JointStiffness) -> JointStiffness {
    JointStiffness {
        bending: entry.bending_nm_per_rad.unwrap_or(fallback.bending),
        torsion: entry.torsion_nm_per_rad.unwrap_or(fallback.torsion),
    }
}

fn link_stiffness(entry: &LinkEntry, fallback: &LinkStiffness) -> LinkStiffness {
    LinkStiffness {
        axial: entry.ea_n.unwrap_or(fallback.axial),
        bending_y: entry.ei_y_nm2.unwrap_or(fallback.bending_y),
        bending_z: entry.ei_z_nm2.unwrap_or(fallback.bending_z),
        torsion: entry.gi_p_nm2.unwrap_or(fallback.torsion),
    }
}

/// Keys whose values are checked while deserialising (see `checked`).
const CHECKED_KEYS: [&str; 9] = [
    "bending_nm_per_rad",
    "torsion_nm_per_rad",
    "ea_n",
    "ei_y_nm2",
    "ei_z_nm2",
    "gi_p_nm2",
    "gravity_m_per_s2",
    "center_of_mass_m",
    "mass_kg",
];

/// A serde_yaml error as an [`Error`] at `origin:line:column`.
///
/// serde_yaml places errors raised after a value was read (our range checks) and unknown keys
/// at the start of the enclosing mapping, which in block style can be lines away (or 1:1 for
/// top-level keys); the key is looked up from there so that the place is the key's own line.
fn yaml_error(text: &str, origin: &str, error: &serde_yaml::Error) -> Error {
    let mut message = error.to_string();
    let Some(location) = error.location() else {
        return Error::InvalidData {
            origin: origin.to_owned(),
            message: super::yaml::readable_message(&message),
        };
    };
    let suffix = format!(" at line {} column {}", location.line(), location.column());
    if message.ends_with(&suffix) {
        message.truncate(message.len() - suffix.len());
    }
    let key = CHECKED_KEYS
        .iter()
        .find(|k| message.contains(&format!("{k} is ")))
        .map(|k| k.to_string())
        .or_else(|| quoted_after(&message, "unknown field `"));
    let duplicate = quoted_after(&message, "duplicate key `");
    let mark = offset_of(text, location.line(), location.column());
    let found = match (key, duplicate) {
        (Some(key), _) => find_key(text, mark, &key),
        // The second occurrence is the one to remove.
        (None, Some(key)) => {
            find_key(text, mark, &key).and_then(|first| find_key(text, first + key.len(), &key))
        }
        (None, None) => None,
    };
    let (line, column) = found.map_or((location.line(), location.column()), |at| {
        line_and_column(text, at)
    });
    Error::InvalidData {
        origin: format!("{origin}:{line}:{column}"),
        message: super::yaml::readable_message(&message),
    }
}

/// The text between `opening` (which ends in a backtick) and the next backtick in `message`.
fn quoted_after(message: &str, opening: &str) -> Option<String> {
    let rest = message.split(opening).nth(1)?;
    Some(rest.split('`').next()?.to_owned())
}

/// Byte offset of 1-based `line` and `column` (in characters) in `text`.
fn offset_of(text: &str, line: usize, column: usize) -> usize {
    let line_start = text
        .match_indices('\n')
        .nth(line.saturating_sub(2))
        .map_or(0, |(i, _)| i + 1);
    let line_start = if line <= 1 { 0 } else { line_start };
    text[line_start..]
        .char_indices()
        .nth(column.saturating_sub(1))
        .map_or(text.len(), |(i, _)| line_start + i)
}

/// 1-based line and column (in characters) of byte offset `at`.
fn line_and_column(text: &str, at: usize) -> (usize, usize) {
    let line_start = text[..at].rfind('\n').map_or(0, |i| i + 1);
    let line = text[..at].matches('\n').count() + 1;
    (line, text[line_start..at].chars().count() + 1)
}

/// 1-based line and column of mapping key `name` found after the keys `path`, in order
/// (block or flow style, outside comments).
fn locate(text: &str, path: &[&str], name: &str) -> Option<(usize, usize)> {
    let mut from = 0;
    for key in path.iter().chain([&name]) {
        from = find_key(text, from, key)?;
    }
    Some(line_and_column(text, from))
}

/// Byte offset of the next `key:` (bare or quoted) at or after `from`, not inside a comment.
fn find_key(text: &str, from: usize, key: &str) -> Option<usize> {
    let candidates = [
        format!("{key}:"),
        format!("\"{key}\":"),
        format!("'{key}':"),
    ];
    let mut best: Option<usize> = None;
    for candidate in &candidates {
        let mut search = from;
        while let Some(found) = text[search..].find(candidate.as_str()) {
            let at = search + found;
            let line_start = text[..at].rfind('\n').map_or(0, |i| i + 1);
            let before = text[line_start..at].chars().last();
            let in_comment = text[line_start..at].contains('#');
            if !in_comment && before.is_none_or(|c| c.is_whitespace() || c == '{' || c == ',') {
                best = Some(best.map_or(at, |b| b.min(at)));
                break;
            }
            search = at + candidate.len();
        }
    }
    best
}
