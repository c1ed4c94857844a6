//! Finding and reading the mesh files a URDF names: STL, OBJ and COLLADA (`.dae`) through the
//! `mesh-loader` crate (openrr's, the parser urdf-viz uses; its only home in treecal). The
//! collision checker gets vertices ([`MeshLookup`]) and builds the convex hulls.

use crate::math::Vec3;
use crate::sim::mesh::MeshLookup;
use std::path::{Path, PathBuf};

/// Where a URDF mesh file name points: `package://pkg/rest` is looked up in each of
/// `package_dirs` in order (as `ROS_PACKAGE_PATH` lists them) as `<dir>/pkg/rest`, or as
/// `<dir>/rest` when the directory is the package itself (named `pkg`); `file:///abs` is that
/// absolute path, and any other name is taken relative to `urdf_dir` (absolute names as they
/// are). `None` when no such file exists.
pub fn resolve_mesh(filename: &str, urdf_dir: &Path, package_dirs: &[PathBuf]) -> Option<PathBuf> {
    let found = |path: PathBuf| path.is_file().then_some(path);
    if let Some(rest) = filename.strip_prefix("package://") {
        let (package, inside) = rest.split_once('/').unwrap_or((rest, ""));
        return package_dirs.iter().find_map(|dir| {
            found(dir.join(rest)).or_else(|| {
                (dir.file_name().is_some_and(|name| name == package))
                    .then(|| found(dir.join(inside)))
                    .flatten()
            })
        });
    }
    if let Some(rest) = filename.strip_prefix("file://") {
        return found(PathBuf::from(rest));
    }
    found(urdf_dir.join(filename))
}

/// A loader for [`crate::sim::collision::CollisionChecker::with_meshes`] that resolves names
/// with [`resolve_mesh`] and reads the file's vertices with [`read_mesh_vertices`].
pub fn mesh_file_loader(
    urdf_dir: PathBuf,
    package_dirs: Vec<PathBuf>,
) -> impl Fn(&str) -> MeshLookup {
    move |filename| match resolve_mesh(filename, &urdf_dir, &package_dirs) {
        None => MeshLookup::NotFound,
        Some(path) => read_mesh_vertices(&path),
    }
}

/// The vertices (m) of every mesh in an STL (binary or ASCII), OBJ or COLLADA file, the format
/// told by the extension or else the contents; [`MeshLookup::Unreadable`] with the reason when
/// the file cannot be read or parsed or holds no vertices.
pub fn read_mesh_vertices(path: &Path) -> MeshLookup {
    let bytes = match std::fs::read(path) {
        Ok(bytes) => bytes,
        Err(error) => return MeshLookup::Unreadable(error.to_string()),
    };
    let scene = match mesh_loader::Loader::default().load_from_slice(&bytes, path) {
        Ok(scene) => scene,
        Err(error) => return MeshLookup::Unreadable(error.to_string()),
    };
    let vertices: Vec<Vec3> = scene
        .meshes
        .iter()
        .flat_map(|mesh| mesh.vertices.iter())
        .map(|v| Vec3::new(f64::from(v[0]), f64::from(v[1]), f64::from(v[2])))
        .collect();
    if vertices.is_empty() {
        return MeshLookup::Unreadable("the file holds no mesh vertices".into());
    }
    if vertices.iter().any(|v| !v.iter().all(|c| c.is_finite())) {
        return MeshLookup::Unreadable("a vertex is not a finite number".into());
    }
    MeshLookup::Vertices(vertices)
}

/// The directories of a `ROS_PACKAGE_PATH`-style list (`:`-separated on Unix, `;` on Windows).
pub fn package_dirs(list: &str) -> Vec<PathBuf> {
    std::env::split_paths(list)
        .filter(|p| !p.as_os_str().is_empty())
        .collect()
}
