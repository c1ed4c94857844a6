//! The checks of a measurement CSV's values as a whole: limits, units, repeated rows.

// The parent's types, constants and imports.
use super::*;

/// The note on the rows of a pose file read as positions (every orientation cell empty).
pub(super) fn position_only_note(
    rows: &[String],
    kind: ObservationKind,
    origin: &str,
) -> Option<String> {
    let first = rows.first()?;
    let orientation = kind.columns()[3..].join(",");
    Some(format!(
        "{origin}: {} row(s) have empty {orientation} and are read as positions of the measured point (first: '{}'); the other rows are full poses",
        rows.len(),
        crate::limits::cut(first)
    ))
}

/// A joint value outside its URDF limits, as read.
pub(super) struct OutsideLimits {
    pub(super) place: String,
    pub(super) message: String,
    pub(super) revolute: bool,
    /// A revolute value read as radians that would be within the limits in degrees.
    pub(super) within_in_degrees: bool,
}

/// At most this many values outside their limits are listed one by one.
const LISTED_OUTSIDE: usize = 5;

/// The warnings for values outside their limits: a few listed, the rest counted. When many
/// revolute values read as radians are outside their limits and nearly all of them would be
/// within in degrees, the file is in degrees: one error naming `--angle-unit` instead.
pub(super) fn limit_warnings(
    outside: &[OutsideLimits],
    revolute_values: usize,
    angle: AngleUnit,
    origin: &str,
) -> Result<Vec<String>> {
    let revolute = outside.iter().filter(|o| o.revolute).count();
    let explained = outside.iter().filter(|o| o.within_in_degrees).count();
    // "Many": a tenth of the revolute values (and at least 3), nine in ten of them explained.
    if angle == AngleUnit::Radian
        && revolute >= 3
        && 10 * revolute >= revolute_values
        && 10 * explained >= 9 * revolute
    {
        let first = outside
            .iter()
            .find(|o| o.revolute)
            .map_or(String::new(), |o| {
                format!(" (first: {}: {})", o.place, o.message)
            });
        return Err(Error::InvalidData {
            origin: origin.to_owned(),
            message: format!(
                "{revolute} of {revolute_values} revolute joint values are outside their limits \
                when read as radians{first}, and {explained} of them are within the limits when \
                read as degrees: the joint values look like degrees; give `angle_unit` deg (or \
                state `# units: angle=deg` in the file)"
            ),
        });
    }
    let mut warnings: Vec<String> = outside
        .iter()
        .take(LISTED_OUTSIDE)
        .map(|o| format!("{}: {}", o.place, o.message))
        .collect();
    if outside.len() > LISTED_OUTSIDE {
        warnings.push(format!(
            "{origin}: {} more joint values are outside their limits (the first {LISTED_OUTSIDE} are listed)",
            outside.len() - LISTED_OUTSIDE
        ));
    }
    Ok(warnings)
}

/// Joint values read in degrees that are all within ±2π while the joints could move far more:
/// radians read as degrees (every revolute joint would have moved less than 6.3°, too little
/// to calibrate anything). Only checked with at least 10 revolute values.
pub(super) fn angles_look_like_radians(
    set: &MeasurementSet,
    tree: &KinematicTree,
    angle: AngleUnit,
    origin: &str,
) -> Result<()> {
    if angle != AngleUnit::Degree {
        return Ok(());
    }
    let revolute: Vec<usize> = tree
        .dofs()
        .iter()
        .enumerate()
        .filter(|(_, j)| tree.joint(**j).kind != JointKind::Prismatic)
        .map(|(dof, _)| dof)
        .collect();
    // The count and the largest magnitude of the non-zero values, folded (not collected).
    let (count, largest_in_degrees) = set
        .measurements
        .iter()
        .flat_map(|m| revolute.iter().map(|&d| m.q[d]))
        .filter(|v| *v != 0.0)
        .fold((0usize, 0.0_f64), |(n, a), v| {
            (n + 1, a.max(v.abs().to_degrees()))
        });
    if count >= 10 && largest_in_degrees <= std::f64::consts::TAU {
        return Err(Error::InvalidData {
            origin: origin.to_owned(),
            message: format!(
                "all {} non-zero revolute joint values are within ±{largest_in_degrees:.3} deg, \
                too small a motion to calibrate from: the joint values look like radians; \
                give `angle_unit` rad (or state `# units: angle=rad` in the file)",
                count
            ),
        });
    }
    Ok(())
}

/// Rows that repeat an earlier row in every column but the id: accepted (a repeated
/// measurement is legitimate), with one warning, since an accidentally duplicated row weighs
/// double in the fit. Rows are keyed by a 128-bit fingerprint of their fields (two SipHash
/// digests), not a copy of them: a copy of every field was 200 MB at 10⁵ rows; two different
/// rows share a fingerprint with probability about `n² / 2¹²⁹`.
pub(super) struct Repeats {
    id: Option<usize>,
    first_line: HashMap<(u64, u64), usize, crate::digests::Digests>,
    /// `(line, line it repeats)` of every repeated row.
    found: Vec<(usize, usize)>,
    /// Fingerprints and lines of rows read in blocks, settled together ([`Self::settle`]).
    deferred: Vec<((u64, u64), usize)>,
}

impl Repeats {
    pub(super) fn new(id: Option<usize>) -> Self {
        Self {
            id,
            first_line: HashMap::default(),
            found: Vec::new(),
            deferred: Vec::new(),
        }
    }

    /// Keeps the fingerprints `keys` of the rows at `lines` (in file order, after every row
    /// seen or kept before) for [`Self::settle`].
    pub(super) fn defer(&mut self, keys: &[(u64, u64)], lines: &[usize]) {
        self.deferred
            .extend(keys.iter().copied().zip(lines.iter().copied()));
    }

    /// Finds the repeats among the deferred rows, as [`Self::see_fingerprint`] in file order
    /// would (each repeat with the first line of its fingerprint), by a parallel sort instead
    /// of a hash table filled row by row (the serial step of reading in blocks; a table of
    /// 2·10⁶ rows also held 100 MB).
    pub(super) fn settle(&mut self) {
        use rayon::slice::ParallelSliceMut;
        let mut deferred = std::mem::take(&mut self.deferred);
        if deferred.is_empty() {
            return;
        }
        deferred.par_sort_unstable();
        let mut found = Vec::new();
        for group in deferred.chunk_by(|a, b| a.0 == b.0) {
            let (key, first) = group[0];
            let earlier = self.first_line.get(&key).copied();
            let first = match earlier {
                Some(earlier) => earlier,
                None => first,
            };
            let repeats = if earlier.is_some() {
                group
            } else {
                &group[1..]
            };
            found.extend(repeats.iter().map(|&(_, line)| (line, first)));
        }
        found.sort_unstable();
        self.found.extend(found);
    }

    pub(super) fn see(&mut self, row: CsvRow<'_>) {
        self.see_fingerprint(self.fingerprint(row), row.line);
    }

    /// Sees the row at `line` whose [`Self::fingerprint`] is `key`.
    pub(super) fn see_fingerprint(&mut self, key: (u64, u64), line: usize) {
        match self.first_line.entry(key) {
            std::collections::hash_map::Entry::Occupied(first) => {
                self.found.push((line, *first.get()))
            }
            std::collections::hash_map::Entry::Vacant(slot) => {
                slot.insert(line);
            }
        }
    }

    /// The row's fingerprint, its id left out.
    pub(super) fn fingerprint(&self, fields: CsvRow<'_>) -> (u64, u64) {
        use std::hash::Hasher;
        // Different seeds make the two digests independent.
        let mut digests = [1, 2].map(crate::digests::digest_hasher);
        for digest in &mut digests {
            fields.hash_without(self.id, digest);
        }
        let [a, b] = digests;
        (a.finish(), b.finish())
    }

    pub(super) fn warning(&self, origin: &str, places: Places) -> Option<String> {
        let &(line, first) = self.found.first()?;
        let more = match self.found.len() {
            1 => String::new(),
            n => format!(" ({} repeated rows in all)", n),
        };
        Some(format!(
            "{}: the row repeats {} in every column but the id{more}; \
             a repeated row weighs double in the fit: remove it if it was copied by mistake",
            places.row(origin, line, &line.to_string(), None),
            places.earlier(first)
        ))
    }
}

/// A finite number, or what is wrong with the text.
pub(super) fn number(text: &str, unit: &str) -> std::result::Result<f64, String> {
    match text.parse::<f64>() {
        Ok(value) if value.is_finite() => Ok(value),
        // The unit is worded only for an error: formatting it for every field cost more
        // than parsing the number.
        parsed => {
            let unit = if unit.is_empty() {
                String::new()
            } else {
                format!(" in {unit}")
            };
            Err(match parsed {
                _ if text.is_empty() => format!("the value is missing; give a number{unit}"),
                Ok(_) => format!(
                    "'{}' is not a finite number; give a number{unit}",
                    crate::limits::cut(text)
                ),
                Err(_) => format!(
                    "'{}' is not a number; give a number{unit}",
                    crate::limits::cut(text)
                ),
            })
        }
    }
}

pub(super) fn quoted_list(names: &[&str]) -> String {
    names
        .iter()
        .map(|n| format!("'{n}'"))
        .collect::<Vec<_>>()
        .join(", ")
}
