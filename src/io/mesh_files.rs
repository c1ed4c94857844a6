//! Finding and reading the mesh files a URDF names (the collision checker parses the bytes).

use std::path::{Path, PathBuf};

/// Where a URDF mesh file name points: `package://pkg/rest` is looked up as `<dir>/pkg/rest`
/// in each of `package_dirs` (as `ROS_PACKAGE_PATH` lists them), `file:///abs` is that absolute
/// path, and any other name is taken relative to `urdf_dir` (absolute names as they are).
/// `None` when no such file exists.
pub fn resolve_mesh(filename: &str, urdf_dir: &Path, package_dirs: &[PathBuf]) -> Option<PathBuf> {
    let found = |path: PathBuf| path.is_file().then_some(path);
    if let Some(rest) = filename.strip_prefix("package://") {
        return package_dirs.iter().find_map(|dir| found(dir.join(rest)));
    }
    if let Some(rest) = filename.strip_prefix("file://") {
        return found(PathBuf::from(rest));
    }
    found(urdf_dir.join(filename))
}

/// A loader for [`crate::sim::collision::CollisionChecker::with_meshes`] that resolves names
/// with [`resolve_mesh`] and reads the file; files that cannot be found or read give `None`
/// (the checker then lists them as skipped).
pub fn mesh_file_loader(
    urdf_dir: PathBuf,
    package_dirs: Vec<PathBuf>,
) -> impl Fn(&str) -> Option<Vec<u8>> {
    move |filename| {
        resolve_mesh(filename, &urdf_dir, &package_dirs).and_then(|path| std::fs::read(path).ok())
    }
}

/// The directories of a `ROS_PACKAGE_PATH`-style list (`:`-separated on Unix, `;` on Windows).
pub fn package_dirs(list: &str) -> Vec<PathBuf> {
    std::env::split_paths(list)
        .filter(|p| !p.as_os_str().is_empty())
        .collect()
}
