//! Files: meshes to and from PLY, slices and renderings to PNG (through `sl-io`, atomically).

use std::path::Path;

use sl_core::Image;
use sl_io::ply::{PlyData, PlyFormat, read_ply, write_ply};

use crate::error::{Result, TsdfError};
use crate::mesh::Mesh;

/// Name of the per-vertex confidence property in our PLY files.
pub const CONFIDENCE_PROPERTY: &str = "confidence";

/// The mesh as PLY data: positions, faces, normals if present, and the confidence as the
/// per-vertex scalar `confidence` if present.
pub fn mesh_to_ply(mesh: &Mesh) -> PlyData {
    let mut ply = PlyData::mesh(mesh.positions.clone(), mesh.triangles.clone());
    if !mesh.normals.is_empty() {
        ply = ply.with_normals(mesh.normals.clone());
    }
    if !mesh.confidence.is_empty() {
        ply = ply.with_scalar(CONFIDENCE_PROPERTY, mesh.confidence.clone());
    }
    ply
}

/// A mesh from PLY data (normals and a scalar named `confidence` are kept when present).
pub fn mesh_from_ply(ply: PlyData) -> Mesh {
    let confidence = match ply.scalar {
        Some(s) if s.name == CONFIDENCE_PROPERTY => s.values,
        _ => Vec::new(),
    };
    Mesh {
        positions: ply.positions,
        normals: ply.normals.unwrap_or_default(),
        confidence,
        triangles: ply.faces,
    }
}

/// Writes the mesh as binary little-endian PLY (or ASCII), atomically.
pub fn write_mesh_ply(path: impl AsRef<Path>, mesh: &Mesh, format: PlyFormat) -> Result<()> {
    Ok(write_ply(path, &mesh_to_ply(mesh), format)?)
}

/// Reads a triangle mesh from PLY.
pub fn read_mesh_ply(path: impl AsRef<Path>) -> Result<Mesh> {
    let ply = read_ply(path.as_ref())?;
    if ply.faces.is_empty() && !ply.positions.is_empty() {
        return Err(TsdfError::InvalidParameter(format!(
            "{} is a point cloud, not a mesh",
            path.as_ref().display()
        )));
    }
    Ok(mesh_from_ply(ply))
}

/// Writes an RGB image (a slice or a rendering) as PNG, atomically.
pub fn write_png(path: impl AsRef<Path>, image: &Image<[u8; 3]>) -> Result<()> {
    Ok(sl_io::rgb::write_rgb_png(path, image)?)
}
