//! provenance.yaml in every output folder: the input hashes equal `sha256sum`'s, report.json
//! refers to it, and two runs of the same inputs write identical folders except the `run`
//! block, across thread counts (RAYON_NUM_THREADS=1 and 2).

use crate::common::cli::path_str;
use crate::verify::{session, tiago};
use std::path::Path;
use std::process::Command;

/// Runs `treecal args…` with `RAYON_NUM_THREADS=threads`.
fn treecal_with_threads(threads: &str, args: &[&str]) {
    let output = Command::new(env!("CARGO_BIN_EXE_treecal"))
        .args(args)
        .env("RAYON_NUM_THREADS", threads)
        .output()
        .expect("treecal");
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
}

/// Every file of `dir` by name, provenance.yaml without its `run` block.
fn folder_without_times(dir: &Path) -> Vec<(String, Vec<u8>)> {
    let mut files: Vec<(String, Vec<u8>)> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| {
            let path = e.unwrap().path();
            let name = path.file_name().unwrap().to_string_lossy().into_owned();
            let mut bytes = std::fs::read(&path).unwrap();
            if name == "provenance.yaml" {
                let text = String::from_utf8(bytes).unwrap();
                let kept = text.split("\nrun:").next().unwrap().to_owned();
                bytes = kept.into_bytes();
            }
            (name, bytes)
        })
        .collect();
    files.sort();
    files
}

fn sha256sum(path: &Path) -> String {
    let output = Command::new("sha256sum")
        .arg(path)
        .output()
        .expect("sha256sum");
    String::from_utf8(output.stdout)
        .unwrap()
        .split_whitespace()
        .next()
        .unwrap()
        .to_owned()
}

#[test]
fn calibrate_provenance_hashes_equal_sha256sum_and_runs_repeat_across_threads() {
    let dir = tempfile::tempdir().unwrap();
    let urdf = tiago().join("urdf/tiago_48_schunk.urdf");
    let measurements = session("2021-11-30", "three");
    let validation = session("2021-11-26", "three");
    let mut folders = Vec::new();
    for threads in ["1", "2"] {
        let out = dir.path().join(format!("t{threads}"));
        treecal_with_threads(
            threads,
            &[
                "calibrate",
                "--robot",
                path_str(&urdf),
                "--measurements",
                path_str(&measurements),
                "--validation",
                path_str(&validation),
                "--out",
                path_str(&out),
            ],
        );
        folders.push(out);
    }
    let (one, two) = (
        folder_without_times(&folders[0]),
        folder_without_times(&folders[1]),
    );
    assert_eq!(
        one.iter().map(|f| &f.0).collect::<Vec<_>>(),
        two.iter().map(|f| &f.0).collect::<Vec<_>>()
    );
    for (a, b) in one.iter().zip(&two) {
        assert!(a.1 == b.1, "{} differs between 1 and 2 threads", a.0);
    }
    let text = std::fs::read_to_string(folders[0].join("provenance.yaml")).unwrap();
    for input in [&urdf, &measurements, &validation] {
        let line = format!("sha256: {}", sha256sum(input));
        assert!(text.contains(&line), "{line} missing from\n{text}");
        assert!(text.contains(path_str(input)), "{text}");
    }
    for needle in [
        "version: 0.1.0",
        "command: calibrate",
        "hold_out: 0",
        "threads: 1",
        "position_sigma",
    ] {
        assert!(text.contains(needle), "{needle} missing from\n{text}");
    }
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(folders[0].join("report.json")).unwrap()).unwrap();
    assert_eq!(report["provenance"], "provenance.yaml");
    assert!(
        report["identification_postures"]["tools"][0]["postures"]
            .as_array()
            .unwrap()
            .len()
            > 30
    );
}

#[test]
fn simulate_writes_provenance_with_its_seed() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("sim");
    treecal_with_threads(
        "1",
        &[
            "simulate",
            "--poses",
            "8",
            "--torso-poses",
            "4",
            "--validation-poses",
            "4",
            "--seed",
            "7",
            "--out",
            path_str(&out),
        ],
    );
    let text = std::fs::read_to_string(out.join("provenance.yaml")).unwrap();
    for needle in ["command: simulate", "master: 7", "trials: 1"] {
        assert!(text.contains(needle), "{needle} missing from\n{text}");
    }
    // Built from a git checkout (CI, development): whether tracked files differed from the
    // commit is said beside it.
    if !treecal::io::GIT_COMMIT.is_empty() {
        let line = format!("dirty: {}", treecal::io::GIT_DIRTY);
        assert!(text.contains(&line), "{line} missing from\n{text}");
    }
    let results: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("results.json")).unwrap()).unwrap();
    assert_eq!(results["provenance"], "provenance.yaml");
}

#[test]
fn the_commit_is_described_with_its_dirty_mark() {
    use treecal::io::commit_description;
    assert_eq!(commit_description("abc", false), "abc");
    assert_eq!(
        commit_description("abc", true),
        "abc (dirty: built with uncommitted changes to tracked files)"
    );
    assert_eq!(
        commit_description("", true),
        "unknown (not built from a git checkout)"
    );
}
