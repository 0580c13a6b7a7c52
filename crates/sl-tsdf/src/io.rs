//! Files: meshes to and from PLY, slices and renderings to PNG (through `sl-io`, atomically).
//! Writing keeps normals and the `confidence` scalar; reading keeps any normals and scalar.

use std::path::Path;

use sl_core::Image;
use sl_core::Mesh;
use sl_io::ply::PlyFormat;

use crate::error::{Result, TsdfError};

/// Name of the per-vertex scalar that holds the confidence in extracted meshes and in our PLY
/// files.
pub const CONFIDENCE_PROPERTY: &str = "confidence";

/// Writes the mesh as binary little-endian PLY (or ASCII), atomically.
pub fn write_mesh_ply(path: impl AsRef<Path>, mesh: &Mesh, format: PlyFormat) -> Result<()> {
    Ok(sl_io::ply::write_mesh_ply(path, mesh, format)?)
}

/// Reads a triangle mesh from PLY.
pub fn read_mesh_ply(path: impl AsRef<Path>) -> Result<Mesh> {
    let mesh = sl_io::ply::read_mesh_ply(path.as_ref())?;
    if mesh.triangles.is_empty() && !mesh.positions.is_empty() {
        return Err(TsdfError::InvalidParameter(format!(
            "{} is a point cloud, not a mesh",
            path.as_ref().display()
        )));
    }
    Ok(mesh)
}

/// Writes an RGB image (a slice or a rendering) as PNG, atomically.
pub fn write_png(path: impl AsRef<Path>, image: &Image<[u8; 3]>) -> Result<()> {
    Ok(sl_io::rgb::write_rgb_png(path, image)?)
}
