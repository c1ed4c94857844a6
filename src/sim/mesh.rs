//! What the collision checker gets for a URDF `<mesh>`: the vertices of the mesh file, found and
//! parsed by the caller (see [`crate::io::mesh_file_loader`], which reads STL, OBJ and COLLADA
//! through the `mesh-loader` crate), or why there are none. Only vertices are needed: the
//! checker uses each mesh's convex hull.

use crate::math::Vec3;

/// What a mesh loader found for a URDF mesh file name.
#[derive(Debug, Clone, PartialEq)]
pub enum MeshLookup {
    /// The mesh's vertices in metres (the file's own unit applied, as COLLADA's
    /// `<unit meter>`), before the URDF `scale`.
    Vertices(Vec<Vec3>),
    /// No such file (relative to the URDF, `file://`, or `package://` in the search path).
    NotFound,
    /// The file exists but is not a mesh that can be read; the reason.
    Unreadable(String),
}
