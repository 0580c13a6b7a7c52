//! Renderings for reports and the CLI: [`normals`] (shaded surface normals of a depth map, where
//! depth noise is easy to see) and [`mesh`] (a z-buffered software renderer for fused meshes).

pub mod mesh;
pub mod normals;

pub use mesh::{BACKGROUND_RGB, framing_camera, render_mesh};
pub use normals::{shaded_normals, side_by_side};
