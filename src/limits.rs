//! The bounds on every number and size treecal reads, in one place (see `docs/file-formats.md`,
//! "Limits").
//!
//! Numbers from files and flags are checked against the bound of their quantity where they
//! are read (URDF, CSV, YAML, command line), so that nothing downstream meets a value whose
//! square overflows; sizes are checked before anything is parsed, so that no input makes a
//! command run for hours or take the machine's memory. Every bound is far beyond any real
//! robot or measurement, and named here with its reason.

use crate::error::{Error, Result};

/// Largest length (m): link offsets, positions, targets, prismatic joint values, geometry.
/// 10 km: a robot or a tracker set-up is metres (millimetres read as metres still pass), and
/// 1e4² is far from overflow.
pub const MAX_LENGTH: f64 = 1e4;
/// Largest angle (rad): joint values, rpy, MCPC angles. About 1,600 turns.
pub const MAX_ANGLE: f64 = 1e4;
/// Largest joint limit (rad or m). Real URDFs write ±1e16 for "unbounded"; beyond this the
/// width of the sampling range overflows.
pub const MAX_JOINT_LIMIT: f64 = 1e16;
/// Largest mass (kg): link masses and payloads.
pub const MAX_MASS: f64 = 1e6;
/// Largest inertia tensor entry (kg·m²).
pub const MAX_INERTIA: f64 = 1e6;
/// Largest acceleration (m/s²): gravity.
pub const MAX_ACCELERATION: f64 = 1e3;
/// Largest dimensionless factor: mimic multipliers, mesh scales.
pub const MAX_FACTOR: f64 = 1e6;
/// Smallest stiffness (N·m/rad, N, N·m²): below it the deflections overflow. Infinity (rigid)
/// is allowed.
pub const MIN_STIFFNESS: f64 = 1e-3;
/// Range of a measurement's expected position error (m): 1 nm to 1 m. The rows are divided
/// by it, so a smaller value overflows the cost.
pub const POSITION_SIGMA: (f64, f64) = (1e-9, 1.0);
/// Range of a measurement's expected rotation error (rad): 1 nrad to 1 rad.
pub const ROTATION_SIGMA: (f64, f64) = (1e-9, 1.0);

/// Largest URDF file (bytes). Real URDFs are under 1 MB; urdf-rs needs about 7× the text.
pub const MAX_URDF_BYTES: u64 = 64 << 20;
/// Largest YAML file (bytes): stiffness, parameters, plans, MCPC tables.
pub const MAX_YAML_BYTES: u64 = 16 << 20;
/// Largest CSV file (bytes): measurements, joint values, pose sets.
pub const MAX_CSV_BYTES: u64 = 1 << 30;
/// Most data rows of a CSV file.
pub const MAX_CSV_ROWS: usize = 10_000_000;
/// Most columns of a CSV file.
pub const MAX_CSV_COLUMNS: usize = 10_000;
/// Deepest YAML nesting (mappings, sequences). treecal's files nest at most 5 deep; the YAML
/// parser's time grows faster than linearly with depth.
pub const MAX_YAML_DEPTH: usize = 64;
/// Most joints of a URDF. Large humanoids have about 100.
pub const MAX_JOINTS: usize = 1_000;
/// Most MCPC parameters of a model (about 250 joints on the selected branches): identification
/// decomposes a square matrix of this size (Robonaut has 64).
pub const MAX_PARAMETERS: usize = 1_000;
/// Longest link, joint or robot name (characters).
pub const MAX_NAME_CHARS: usize = 1_000;
/// Most candidate configurations of a pose plan (each costs a Jacobian block in memory, about
/// 6 KB per 64 parameters).
pub const MAX_CANDIDATES: usize = 100_000;
/// Most configurations, validation poses or trials asked for on the command line.
pub const MAX_POSES: usize = 100_000;
/// Largest field of a CSV file (bytes), checked while the text is scanned, before any record
/// is built: a joint value, name or label is a few dozen bytes.
pub const MAX_CSV_FIELD_BYTES: usize = 64 << 10;
/// Longest record (a row, its quoted line breaks included) of a CSV read as a stream (bytes):
/// `treecal fk` holds one record at a time.
pub const MAX_CSV_RECORD_BYTES: usize = 16 << 20;
/// Most stages of a calibration plan: each stage is a whole calibration (the paper's plan has
/// two).
pub const MAX_PLAN_STAGES: usize = 32;
/// Largest mesh file (bytes): STL, OBJ, COLLADA. ROS collision meshes are under 10 MB.
pub const MAX_MESH_BYTES: u64 = 128 << 20;
/// Most vertices one mesh file may place (a COLLADA file's instances included); a convex hull
/// of more is no better.
pub const MAX_MESH_VERTICES: usize = 10_000_000;
/// Deepest element nesting of a COLLADA file; exporters nest a few dozen levels at most.
pub const MAX_XML_DEPTH: usize = 256;
/// Most XML nodes (elements, attributes' holders, text) of a COLLADA file.
pub const MAX_XML_NODES: u32 = 4_000_000;
/// Longest value quoted in a message (characters); longer ones are cut with "…".
pub const MAX_QUOTED_CHARS: usize = 80;

/// What a number measures, which decides its bound.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Quantity {
    /// Metres, up to [`MAX_LENGTH`].
    Length,
    /// Radians, up to [`MAX_ANGLE`].
    Angle,
    /// A joint limit (rad or m), up to [`MAX_JOINT_LIMIT`].
    JointLimit,
    /// Kilograms, 0 to [`MAX_MASS`].
    Mass,
    /// kg·m², up to [`MAX_INERTIA`].
    Inertia,
    /// m/s², up to [`MAX_ACCELERATION`].
    Acceleration,
    /// A dimensionless factor, up to [`MAX_FACTOR`].
    Factor,
    /// Dimensionless, finite only (unit quaternion components, tolerances).
    Unitless,
}

impl Quantity {
    /// The largest magnitude accepted.
    pub fn bound(self) -> f64 {
        match self {
            Quantity::Length => MAX_LENGTH,
            Quantity::Angle => MAX_ANGLE,
            Quantity::JointLimit => MAX_JOINT_LIMIT,
            Quantity::Mass => MAX_MASS,
            Quantity::Inertia => MAX_INERTIA,
            Quantity::Acceleration => MAX_ACCELERATION,
            Quantity::Factor => MAX_FACTOR,
            Quantity::Unitless => f64::MAX,
        }
    }

    fn describe(self) -> &'static str {
        match self {
            Quantity::Length => "m (a length)",
            Quantity::Angle => "rad (an angle)",
            Quantity::JointLimit => "(a joint limit)",
            Quantity::Mass => "kg (a mass)",
            Quantity::Inertia => "kg·m² (an inertia)",
            Quantity::Acceleration => "m/s² (an acceleration)",
            Quantity::Factor => "(a factor)",
            Quantity::Unitless => "",
        }
    }
}

/// What is wrong with `value` (in SI units) as a `quantity`, or `None` if it is acceptable:
/// it must be finite and within ±[`Quantity::bound`] (a mass also ≥ 0).
pub fn magnitude_problem(value: f64, quantity: Quantity) -> Option<String> {
    if !value.is_finite() {
        return Some(format!("{} is not a finite number", shown(value)));
    }
    if quantity == Quantity::Mass && value < 0.0 {
        return Some(format!(
            "{} is negative; a mass must be ≥ 0 kg",
            shown(value)
        ));
    }
    let bound = quantity.bound();
    (value.abs() > bound).then(|| {
        format!(
            "{} is beyond the limit ±{} {} (docs/file-formats.md, \"Limits\"); check the unit",
            shown(value),
            shown(bound),
            quantity.describe()
        )
    })
}

/// A number for a message: in exponent notation when very large or small (never 309 digits).
pub fn shown(value: f64) -> String {
    if value != 0.0 && value.is_finite() && !(1e-4..1e6).contains(&value.abs()) {
        format!("{value:e}")
    } else {
        format!("{value}")
    }
}

/// A value quoted in a message, cut to [`MAX_QUOTED_CHARS`] characters and "…" (a 100 MB
/// field must not become a 100 MB message).
pub fn cut(text: &str) -> std::borrow::Cow<'_, str> {
    match text.char_indices().nth(MAX_QUOTED_CHARS) {
        None => std::borrow::Cow::Borrowed(text),
        Some((end, _)) => std::borrow::Cow::Owned(format!("{}…", &text[..end])),
    }
}

/// `value` if it is a sane `quantity`, else an [`Error::InvalidData`] at `origin` (the file,
/// line and key, or the flag).
pub fn check(value: f64, quantity: Quantity, origin: impl FnOnce() -> String) -> Result<f64> {
    match magnitude_problem(value, quantity) {
        None => Ok(value),
        Some(message) => Err(Error::InvalidData {
            origin: origin(),
            message,
        }),
    }
}

/// `value` if it lies in `range` (inclusive), else an [`Error::InvalidSetting`] naming
/// `setting` (snake_case, e.g. `position_sigma`).
pub fn check_range(value: f64, range: (f64, f64), setting: &str, unit: &str) -> Result<f64> {
    if value >= range.0 && value <= range.1 {
        Ok(value)
    } else {
        Err(Error::setting(
            setting,
            format!(
                "{} {unit} is outside [{}, {}] {unit} (docs/file-formats.md, \"Limits\")",
                shown(value),
                shown(range.0),
                shown(range.1)
            ),
        ))
    }
}

/// `count` if it is at most `max`, else an error naming `what` (e.g. "data rows") at `origin`.
pub fn check_count(count: usize, max: usize, origin: &str, what: &str) -> Result<usize> {
    if count <= max {
        Ok(count)
    } else {
        Err(Error::InvalidData {
            origin: origin.to_owned(),
            message: format!(
                "{count} {what} is more than the limit of {max} (docs/file-formats.md, \"Limits\")"
            ),
        })
    }
}

/// What is wrong with a name (of a link, joint, robot or tool), or `None`: longer than
/// [`MAX_NAME_CHARS`], or containing control characters (no file format can carry them).
pub fn name_problem(name: &str) -> Option<String> {
    let length = name.chars().count();
    if length > MAX_NAME_CHARS {
        let start: String = name.chars().take(40).collect();
        return Some(format!(
            "the name '{start}…' has {length} characters; at most {MAX_NAME_CHARS} are accepted"
        ));
    }
    name.chars().any(char::is_control).then(|| {
        format!("the name {name:?} contains control characters; use printable characters only")
    })
}

/// Reads a UTF-8 text file of at most `max_bytes`: [`crate::io::read_text`], the one
/// bounded reader (regular files only, size checked before reading).
pub use crate::io::read_text;

/// Fails if `text` is longer than `max_bytes` (for text given as a string, not a file).
pub fn check_text_size(text: &str, max_bytes: u64, origin: &str) -> Result<()> {
    if text.len() as u64 > max_bytes {
        return Err(Error::InvalidData {
            origin: origin.to_owned(),
            message: format!(
                "the text has {} bytes, more than the limit of {max_bytes} for this kind of \
                 file (docs/file-formats.md, \"Limits\")",
                text.len()
            ),
        });
    }
    Ok(())
}

/// Fails, naming the line, if YAML `text` nests deeper than [`MAX_YAML_DEPTH`] (and checks its
/// size against [`MAX_YAML_BYTES`]), before a parser sees it.
///
/// An over-estimate, not a parser: block nesting counts the indentation levels open on each
/// line plus its compact `- ` entries and `key:` prefixes, flow nesting counts `[` and `{`
/// outside quotes and comments; any real treecal file is far below the limit either way.
pub fn check_yaml_depth(text: &str, origin: &str) -> Result<()> {
    check_text_size(text, MAX_YAML_BYTES, origin)?;
    let mut indents: Vec<usize> = Vec::new();
    let mut flow = 0usize;
    for (index, line) in text.lines().enumerate() {
        let content = line.trim_start_matches([' ', '\t']);
        if content.is_empty() || content.starts_with('#') {
            continue;
        }
        let indent = line.len() - content.len();
        if flow == 0 {
            while indents.last().is_some_and(|&i| i > indent) {
                indents.pop();
            }
            if indents.last().is_none_or(|&i| i < indent) {
                indents.push(indent);
            }
        }
        let mut inline = 0;
        let mut rest = content;
        while let Some(after) = rest.strip_prefix("- ").or_else(|| rest.strip_prefix("? ")) {
            inline += 1;
            rest = after.trim_start();
        }
        let mut peak = flow;
        let mut quote: Option<char> = None;
        let mut previous = ' ';
        for c in rest.chars() {
            match (quote, c) {
                (Some(q), _) if c == q => quote = None,
                (Some(_), _) => {}
                (None, '"' | '\'') if flow > 0 || previous.is_whitespace() || previous == ':' => {
                    quote = Some(c)
                }
                (None, '#') if previous.is_whitespace() => break,
                (None, '[' | '{') => {
                    flow += 1;
                    peak = peak.max(flow);
                }
                (None, ']' | '}') => flow = flow.saturating_sub(1),
                (None, ':') => inline += 1,
                _ => {}
            }
            previous = c;
        }
        if indents.len() + inline + peak > MAX_YAML_DEPTH {
            return Err(Error::InvalidData {
                origin: format!("{origin}:{}", index + 1),
                message: format!(
                    "the YAML nests more than {MAX_YAML_DEPTH} levels deep here; treecal's \
                     files need only a few levels (docs/file-formats.md, \"Limits\")"
                ),
            });
        }
    }
    Ok(())
}

/// Fails unless every value is finite: checked before every matrix decomposition, whose
/// iterations never end on NaN or infinity. `what` names the matrix and how it came about.
pub fn ensure_finite<'a>(values: impl IntoIterator<Item = &'a f64>, what: &str) -> Result<()> {
    if values.into_iter().all(|v| v.is_finite()) {
        Ok(())
    } else {
        Err(Error::InvalidData {
            origin: what.to_owned(),
            message: "a value is not finite (overflow or NaN): the inputs are beyond what \
                      can be computed; check the units and magnitudes of the robot, the \
                      measurements and the sigmas (docs/file-formats.md, \"Limits\")"
                .into(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn magnitudes() {
        assert!(magnitude_problem(0.5, Quantity::Length).is_none());
        assert!(magnitude_problem(-999.0, Quantity::Length).is_none());
        assert!(magnitude_problem(1e200, Quantity::Length).is_some());
        assert!(magnitude_problem(f64::NAN, Quantity::Angle).is_some());
        assert!(magnitude_problem(-1.0, Quantity::Mass).is_some());
        assert!(magnitude_problem(-1e16, Quantity::JointLimit).is_none());
        assert!(magnitude_problem(1e308, Quantity::JointLimit).is_some());
    }

    #[test]
    fn yaml_depth() {
        let plan = "stages:\n  - name: torso\n    parameters: coupled\n    measurements: torso\n";
        assert!(check_yaml_depth(plan, "p").is_ok());
        let flow = "a: {b: [1, 2, {c: \"[[[[\"}]}\n";
        assert!(check_yaml_depth(flow, "p").is_ok());
        let deep = format!("a: {}{}\n", "[".repeat(100), "]".repeat(100));
        let error = check_yaml_depth(&deep, "p").unwrap_err().to_string();
        assert!(error.starts_with("p:1:"), "{error}");
        let mut block = String::new();
        for level in 0..100 {
            block += &format!("{}k{level}:\n", " ".repeat(level));
        }
        assert!(check_yaml_depth(&block, "p").is_err());
        let dashes = format!("{}1\n", "- ".repeat(100));
        assert!(check_yaml_depth(&dashes, "p").is_err());
    }

    #[test]
    fn names() {
        assert!(name_problem("left_joint1").is_none());
        assert!(name_problem("r2/left palm").is_none());
        assert!(name_problem("a\u{1}b").is_some());
        assert!(name_problem(&"x".repeat(MAX_NAME_CHARS + 1)).is_some());
    }
}
