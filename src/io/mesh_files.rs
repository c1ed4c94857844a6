//! Finding and reading the mesh files a URDF names: STL, OBJ and COLLADA (`.dae`) through the
//! `mesh-loader` crate (openrr's, the parser urdf-viz uses; its only home in treecal). The
//! collision checker gets vertices ([`MeshLookup`]) and builds the convex hulls.

use crate::limits::{MAX_MESH_BYTES, MAX_MESH_VERTICES};
use crate::math::Vec3;
use crate::sim::MeshLookup;
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

/// A loader for [`crate::sim::CollisionChecker::with_meshes`] that resolves names
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
///
/// The file is read through the bounded reader ([`crate::io::read_text`]: regular files only, at
/// most [`MAX_MESH_BYTES`]). COLLADA goes to treecal's own reader (`src/io/collada.rs`), STL and
/// OBJ to `mesh-loader`, which opens no other file: an OBJ's `mtllib` (materials, not needed
/// for a hull) is never read, so it cannot name a FIFO that blocks the command.
pub fn read_mesh_vertices(path: &Path) -> MeshLookup {
    let bytes = match super::bounded::read_bytes(path, MAX_MESH_BYTES) {
        Ok(bytes) => bytes,
        Err(error) => return MeshLookup::Unreadable(error.to_string()),
    };
    match mesh_vertices(&bytes, path) {
        Ok(vertices) => MeshLookup::Vertices(vertices),
        Err(reason) => MeshLookup::Unreadable(reason),
    }
}

/// The vertices of mesh file contents `bytes` (`path` tells the format by its extension, else
/// the contents do), or why there are none.
pub fn mesh_vertices(bytes: &[u8], path: &Path) -> std::result::Result<Vec<Vec3>, String> {
    let vertices = if is_collada(bytes, path) {
        let text = std::str::from_utf8(bytes.strip_prefix(b"\xef\xbb\xbf").unwrap_or(bytes))
            .map_err(|e| format!("a COLLADA file must be UTF-8 text ({e})"))?;
        super::collada::collada_vertices(text)?
    } else {
        let no_other_files = |_: &Path| -> std::io::Result<Vec<u8>> {
            Err(std::io::Error::other("treecal reads no material files"))
        };
        let scene = mesh_loader::Loader::default()
            .load_from_slice_with_reader(bytes, path, no_other_files)
            .map_err(|e| crate::limits::cut(&e.to_string()).into_owned())?;
        let count: usize = scene.meshes.iter().map(|m| m.vertices.len()).sum();
        if count > MAX_MESH_VERTICES {
            return Err(format!(
                "the file has {count} vertices, more than the limit of {MAX_MESH_VERTICES} \
                 (docs/file-formats.md, \"Limits\")"
            ));
        }
        scene
            .meshes
            .iter()
            .flat_map(|mesh| mesh.vertices.iter())
            .map(|v| Vec3::new(f64::from(v[0]), f64::from(v[1]), f64::from(v[2])))
            .collect()
    };
    if vertices.is_empty() {
        return Err("the file holds no mesh vertices".into());
    }
    if vertices.iter().any(|v| !v.iter().all(|c| c.is_finite())) {
        return Err("a vertex is not a finite number".into());
    }
    Ok(vertices)
}

/// COLLADA by the extension `.dae`, or (without a known extension) by `<COLLADA` before any
/// `solid` in the first 1024 bytes, as `mesh-loader` tells formats apart.
fn is_collada(bytes: &[u8], path: &Path) -> bool {
    match path.extension().and_then(|e| e.to_str()) {
        Some(e) if e.eq_ignore_ascii_case("dae") => true,
        Some(e) if e.eq_ignore_ascii_case("stl") || e.eq_ignore_ascii_case("obj") => false,
        _ => {
            let head = &bytes[..bytes.len().min(1024)];
            let solid = head.windows(5).position(|w| w == b"solid");
            let collada = head.windows(8).position(|w| w == b"<COLLADA");
            collada.is_some_and(|c| solid.is_none_or(|s| c < s))
        }
    }
}

/// The directories of a `ROS_PACKAGE_PATH`-style list (`:`-separated on Unix, `;` on Windows).
pub fn package_dirs(list: &str) -> Vec<PathBuf> {
    std::env::split_paths(list)
        .filter(|p| !p.as_os_str().is_empty())
        .collect()
}
