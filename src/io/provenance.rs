//! provenance.yaml: where an output folder came from — treecal's version and commit, the
//! settings as resolved, every input file with its SHA-256, the seeds, and the run's start,
//! duration and threads. The only user of `sha2`.

use crate::error::{Error, Result};
use serde::Serialize;
use sha2::{Digest, Sha256};
use std::path::Path;

/// The file name in every output folder.
pub const PROVENANCE_FILE: &str = "provenance.yaml";

/// The git commit treecal was built from (`build.rs`); empty when not built from a git
/// checkout (a tarball, crates.io).
pub const GIT_COMMIT: &str = match option_env!("TREECAL_GIT_COMMIT") {
    Some(commit) => commit,
    None => "",
};

/// Whether the git checkout treecal was built from had uncommitted changes to tracked files
/// (`build.rs`: `git status --porcelain --untracked-files=no` printed anything); false when
/// not built from a git checkout ([`GIT_COMMIT`] empty).
pub const GIT_DIRTY: bool = option_env!("TREECAL_GIT_DIRTY").is_some();

/// The commit treecal was built from as the reports name it: the commit, `<commit> (dirty:
/// built with uncommitted changes to tracked files)`, or `unknown (not built from a git
/// checkout)` for an empty `commit`.
pub fn commit_description(commit: &str, dirty: bool) -> String {
    match (commit, dirty) {
        ("", _) => "unknown (not built from a git checkout)".to_owned(),
        (commit, false) => commit.to_owned(),
        (commit, true) => {
            format!("{commit} (dirty: built with uncommitted changes to tracked files)")
        }
    }
}

/// One input file.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct InputFile {
    /// As given.
    pub path: String,
    /// Its size (bytes).
    pub bytes: u64,
    /// SHA-256 of its content, lower-case hex (what `sha256sum` prints).
    pub sha256: String,
}

/// One file the command wrote into the folder (every one but provenance.yaml itself).
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct OutputFile {
    /// Its name in the folder.
    pub name: String,
    /// Its size (bytes).
    pub bytes: u64,
    /// SHA-256 of its content as written, lower-case hex.
    pub sha256: String,
}

/// The program that wrote the folder.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct Program {
    /// `treecal`.
    pub name: &'static str,
    /// The crate version.
    pub version: &'static str,
    /// The git commit it was built from, or `unknown (not built from a git checkout)`.
    pub commit: String,
    /// Whether that checkout had uncommitted changes to tracked files when it was built (the
    /// binary may not be the commit's code); `None` outside a git checkout.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub dirty: Option<bool>,
}

/// The part of provenance that differs between two runs of the same inputs and settings.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RunFacts {
    /// Start time, UTC, ISO 8601 to the second.
    pub started_utc: String,
    /// Wall-clock duration (s).
    pub duration_s: f64,
    /// Worker threads available (rayon; `RAYON_NUM_THREADS`).
    pub threads: usize,
}

/// provenance.yaml's content.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ProvenanceRecord {
    /// treecal and its commit.
    pub program: Program,
    /// The command (`calibrate`, `simulate`, `verify`, `compare`).
    pub command: String,
    /// Every setting as resolved (the defaults written out), as the library's config.
    pub settings: String,
    /// The input files, in the order read.
    pub inputs: Vec<InputFile>,
    /// The files written beside provenance.yaml, by name (a file changed after the run no
    /// longer matches: `verify` says so).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub outputs: Vec<OutputFile>,
    /// The seeds of the random choices (held-out rows, simulated noise), by name.
    pub seeds: std::collections::BTreeMap<String, u64>,
    /// Start, duration, threads: the only fields two runs of the same inputs may differ in.
    pub run: RunFacts,
}

/// The record of a file: its size and SHA-256, read in blocks (a 10⁵-row CSV is not held
/// in memory a second time).
pub fn input_file(path: &Path) -> Result<InputFile> {
    use std::io::Read;
    let io_error = |e| Error::Io {
        path: path.to_owned(),
        source: e,
    };
    let mut file = std::fs::File::open(path).map_err(io_error)?;
    let (mut hasher, mut size) = (Sha256::new(), 0u64);
    let mut block = vec![0u8; 1 << 16];
    loop {
        let read = match file.read(&mut block) {
            Ok(0) => break,
            Ok(n) => n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(e) => return Err(io_error(e)),
        };
        hasher.update(&block[..read]);
        size += read as u64;
    }
    Ok(InputFile {
        path: path.display().to_string(),
        bytes: size,
        sha256: hex(&hasher.finalize()),
    })
}

/// The files of an output folder as written, sorted by name, leaving out provenance.yaml.
pub fn output_files(files: &[(String, Vec<u8>)]) -> Vec<OutputFile> {
    let mut outputs: Vec<OutputFile> = files
        .iter()
        .filter(|(name, _)| name != PROVENANCE_FILE)
        .map(|(name, bytes)| OutputFile {
            name: name.clone(),
            bytes: bytes.len() as u64,
            sha256: sha256_hex(bytes),
        })
        .collect();
    outputs.sort_by(|a, b| a.name.cmp(&b.name));
    outputs
}

/// The SHA-256 of every output file a provenance.yaml records, by name (none for a folder
/// written before outputs were recorded); an error naming `origin` when it is not YAML.
pub fn recorded_outputs(
    text: &str,
    origin: &str,
) -> Result<std::collections::BTreeMap<String, String>> {
    let value: serde_yaml::Value = serde_yaml::from_str(text).map_err(|e| Error::InvalidData {
        origin: origin.to_owned(),
        message: format!("not readable as provenance YAML: {e}"),
    })?;
    let entries = value
        .get("outputs")
        .and_then(serde_yaml::Value::as_sequence)
        .map_or(&[][..], Vec::as_slice);
    Ok(entries
        .iter()
        .filter_map(|entry| {
            let field = |key: &str| entry.get(key).and_then(serde_yaml::Value::as_str);
            Some((field("name")?.to_owned(), field("sha256")?.to_owned()))
        })
        .collect())
}

/// SHA-256 of `bytes` in lower-case hex.
pub fn sha256_hex(bytes: &[u8]) -> String {
    hex(&Sha256::digest(bytes))
}

/// `digest` in lower-case hex.
fn hex(digest: &[u8]) -> String {
    use std::fmt::Write;
    digest.iter().fold(String::with_capacity(64), |mut hex, b| {
        let _ = write!(hex, "{b:02x}");
        hex
    })
}

/// `seconds` since the Unix epoch as `YYYY-MM-DDTHH:MM:SSZ` (proleptic Gregorian, UTC).
pub fn utc_iso8601(seconds: u64) -> String {
    let days = (seconds / 86_400) as i64;
    let rest = seconds % 86_400;
    // Howard Hinnant's days-to-civil.
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = doy - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = yoe + era * 400 + i64::from(month <= 2);
    format!(
        "{year:04}-{month:02}-{day:02}T{:02}:{:02}:{:02}Z",
        rest / 3600,
        rest % 3600 / 60,
        rest % 60
    )
}

impl ProvenanceRecord {
    /// provenance.yaml's text, with a header saying what it is.
    pub fn to_yaml(&self) -> Result<String> {
        Ok(format!(
            "# Where this folder came from (docs/workflows.md, \"Provenance\"): two runs of the same inputs and\n# settings write identical folders except the `run` block (start, duration, threads).\n{}",
            super::to_yaml(self)?
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sha256_of_abc_is_the_standard_vector() {
        assert_eq!(
            sha256_hex(b"abc"),
            "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad"
        );
    }

    #[test]
    fn civil_dates() {
        assert_eq!(utc_iso8601(0), "1970-01-01T00:00:00Z");
        assert_eq!(utc_iso8601(951_782_400), "2000-02-29T00:00:00Z");
        assert_eq!(utc_iso8601(1_700_000_000), "2023-11-14T22:13:20Z");
    }
}
