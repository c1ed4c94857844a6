//! Records the git commit treecal is built from (`TREECAL_GIT_COMMIT`, read by
//! `src/io/provenance.rs` for provenance.yaml), and `TREECAL_GIT_DIRTY=1` when tracked files
//! differ from it (`git status --porcelain --untracked-files=no` prints anything: the binary
//! may not be that commit's code). Outside a git checkout (a tarball, crates.io) or without
//! git, both are left unset and provenance says so.

use std::path::Path;
use std::process::Command;

fn git(args: &[&str]) -> Option<String> {
    let output = Command::new("git").args(args).output().ok()?;
    if !output.status.success() {
        return None;
    }
    let text = String::from_utf8(output.stdout).ok()?;
    let text = text.trim();
    (!text.is_empty()).then(|| text.to_owned())
}

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    let Some(commit) = git(&["rev-parse", "HEAD"]) else {
        return;
    };
    println!("cargo:rustc-env=TREECAL_GIT_COMMIT={commit}");
    if git(&["status", "--porcelain", "--untracked-files=no"]).is_some() {
        println!("cargo:rustc-env=TREECAL_GIT_DIRTY=1");
    }
    // Run again when HEAD moves (its file, the branch it names, the packed refs), when the
    // index changes (a commit, `git add`), and when the crate's sources change (an edit makes
    // the tree dirty, undoing it clean again).
    let git_dir = git(&["rev-parse", "--git-dir"]);
    let common_dir = git(&["rev-parse", "--git-common-dir"]);
    let head_ref = git(&["symbolic-ref", "-q", "HEAD"]);
    let mut watched = Vec::new();
    if let Some(dir) = &git_dir {
        watched.push(Path::new(dir).join("HEAD"));
        watched.push(Path::new(dir).join("index"));
    }
    if let Some(dir) = common_dir.as_ref().or(git_dir.as_ref()) {
        if let Some(name) = &head_ref {
            watched.push(Path::new(dir).join(name));
        }
        watched.push(Path::new(dir).join("packed-refs"));
    }
    for source in ["src", "Cargo.toml", "Cargo.lock"] {
        watched.push(Path::new(source).to_path_buf());
    }
    for path in watched.iter().filter(|p| p.exists()) {
        println!("cargo:rerun-if-changed={}", path.display());
    }
}
