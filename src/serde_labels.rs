//! Serialising fixed-size arrays whose entries mean different things (before / after, rigid /
//! compensated) as objects keyed by those meanings, so that no JSON report depends on position
//! (docs/file-formats.md, "JSON reports"). The Rust types keep their arrays; only their JSON
//! form is labelled.

use serde::ser::{SerializeMap, Serializer};
use serde::Serialize;

/// Serialises `values` as `{labels[0]: values[0], labels[1]: values[1], …}`.
pub(crate) fn labelled<S: Serializer, T: Serialize, const N: usize>(
    values: &[T; N],
    labels: [&str; N],
    serializer: S,
) -> Result<S::Ok, S::Error> {
    let mut map = serializer.serialize_map(Some(N))?;
    for (label, value) in labels.iter().zip(values) {
        map.serialize_entry(label, value)?;
    }
    map.end()
}

/// `[before, after]` as `{"before": …, "after": …}`.
pub(crate) fn before_after<S: Serializer, T: Serialize>(
    values: &[T; 2],
    serializer: S,
) -> Result<S::Ok, S::Error> {
    labelled(values, ["before", "after"], serializer)
}

/// `[rigid, compensated]` as `{"rigid": …, "compensated": …}`.
pub(crate) fn rigid_compensated<S: Serializer, T: Serialize>(
    values: &[T; 2],
    serializer: S,
) -> Result<S::Ok, S::Error> {
    labelled(values, ["rigid", "compensated"], serializer)
}

/// `[before, rigid, compensated]` as `{"before": …, "rigid": …, "compensated": …}`.
pub(crate) fn before_rigid_compensated<S: Serializer, T: Serialize>(
    values: &[T; 3],
    serializer: S,
) -> Result<S::Ok, S::Error> {
    labelled(values, ["before", "rigid", "compensated"], serializer)
}
