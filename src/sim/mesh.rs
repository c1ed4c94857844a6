//! The vertices of STL (binary and ASCII) and OBJ collision meshes, parsed from bytes (the
//! file is read by the caller, see [`crate::io::mesh_file_loader`]). Only vertices are kept:
//! the collision checker uses each mesh's convex hull.

use crate::error::{Error, Result};
use crate::math::Vec3;

/// Mesh formats the checker can load.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MeshFormat {
    /// STL, binary or ASCII.
    Stl,
    /// Wavefront OBJ (`v x y z` lines).
    Obj,
}

impl MeshFormat {
    /// The format of a file name by its extension (case-insensitive); `None` if unsupported
    /// (e.g. `.dae`).
    pub fn of(filename: &str) -> Option<Self> {
        let extension = filename.rsplit('.').next()?.to_ascii_lowercase();
        match extension.as_str() {
            "stl" => Some(MeshFormat::Stl),
            "obj" => Some(MeshFormat::Obj),
            _ => None,
        }
    }
}

/// The vertices of a mesh file's contents; `origin` names the file in errors.
pub fn mesh_vertices(bytes: &[u8], format: MeshFormat, origin: &str) -> Result<Vec<Vec3>> {
    let vertices = match format {
        MeshFormat::Stl if is_binary_stl(bytes) => binary_stl(bytes),
        MeshFormat::Stl => text_vertices(bytes, origin, "vertex")?,
        MeshFormat::Obj => text_vertices(bytes, origin, "v")?,
    };
    if vertices.is_empty() {
        return Err(Error::InvalidData {
            origin: origin.into(),
            message: "the mesh has no vertices; check that it is an STL or OBJ file".into(),
        });
    }
    Ok(vertices)
}

/// A binary STL is 84 bytes of header and count, then 50 bytes per triangle: trust the size
/// rather than the `solid` keyword (binary files often start with it too).
fn is_binary_stl(bytes: &[u8]) -> bool {
    bytes.len() >= 84 && {
        let count = u32::from_le_bytes([bytes[80], bytes[81], bytes[82], bytes[83]]) as usize;
        count.checked_mul(50).and_then(|n| n.checked_add(84)) == Some(bytes.len())
    }
}

fn binary_stl(bytes: &[u8]) -> Vec<Vec3> {
    let float = |at: usize| {
        f32::from_le_bytes([bytes[at], bytes[at + 1], bytes[at + 2], bytes[at + 3]]) as f64
    };
    bytes[84..]
        .chunks_exact(50)
        .enumerate()
        .flat_map(|(triangle, _)| {
            let start = 84 + triangle * 50 + 12; // after the normal
            (0..3).map(move |v| {
                let at = start + v * 12;
                Vec3::new(float(at), float(at + 4), float(at + 8))
            })
        })
        .collect()
}

/// Vertices from text lines `<keyword> x y z` (ASCII STL `vertex`, OBJ `v`).
fn text_vertices(bytes: &[u8], origin: &str, keyword: &str) -> Result<Vec<Vec3>> {
    let text = std::str::from_utf8(bytes).map_err(|e| Error::InvalidData {
        origin: origin.into(),
        message: format!(
            "not a text mesh file (invalid UTF-8 at byte {}) and not a binary STL either",
            e.valid_up_to()
        ),
    })?;
    let mut vertices = Vec::new();
    for (index, line) in text.lines().enumerate() {
        let mut words = line.split_whitespace();
        if words.next() != Some(keyword) {
            continue;
        }
        let mut xyz = [0.0; 3];
        for (k, value) in xyz.iter_mut().enumerate() {
            let word = words.next().unwrap_or("");
            *value = word
                .parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| Error::InvalidData {
                    origin: format!("{origin}:{}", index + 1),
                    message: format!(
                        "coordinate {} of '{keyword}' is '{word}', not a finite number",
                        ["x", "y", "z"][k]
                    ),
                })?;
        }
        vertices.push(Vec3::new(xyz[0], xyz[1], xyz[2]));
    }
    Ok(vertices)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn binary_and_text_meshes() {
        let mut binary = vec![0u8; 80];
        binary.extend(1u32.to_le_bytes());
        binary.extend([0u8; 12]);
        for v in [1.0f32, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0] {
            binary.extend(v.to_le_bytes());
        }
        binary.extend([0u8; 2]);
        let v = mesh_vertices(&binary, MeshFormat::Stl, "a.stl").unwrap();
        assert_eq!(
            v,
            vec![
                Vec3::new(1., 2., 3.),
                Vec3::new(4., 5., 6.),
                Vec3::new(7., 8., 9.)
            ]
        );
        let ascii = b"solid t\nfacet normal 0 0 1\nouter loop\nvertex 1 2 3\nvertex 0 0 0\nvertex 1 0 0\nendloop\nendfacet\nendsolid t\n";
        assert_eq!(
            mesh_vertices(ascii, MeshFormat::Stl, "a.stl")
                .unwrap()
                .len(),
            3
        );
        let obj = b"# box\nv 0 0 0\nv 1 0 0\nvn 0 0 1\nv 0 1 0\nf 1 2 3\n";
        assert_eq!(
            mesh_vertices(obj, MeshFormat::Obj, "a.obj").unwrap().len(),
            3
        );
        let bad = b"v 0 0 zero\n";
        let error = mesh_vertices(bad, MeshFormat::Obj, "a.obj")
            .unwrap_err()
            .to_string();
        assert!(
            error.contains("a.obj:1") && error.contains("zero"),
            "{error}"
        );
        assert_eq!(MeshFormat::of("package://r2/meshes/x.DAE"), None);
        assert_eq!(MeshFormat::of("x.STL"), Some(MeshFormat::Stl));
    }
}
