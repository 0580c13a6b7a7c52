//! PLY point clouds and triangle meshes through `ply-rs` (package `ply-rs-bw`).
//!
//! One type, [`PlyData`], covers clouds and meshes: vertex positions, optional normals,
//! colours and one named per-vertex scalar (e.g. `confidence`, `sigma_z_m`), and triangle faces
//! (empty for a cloud). Files follow the MeshLab / Open3D conventions:
//!
//! ```text
//! element vertex N
//! property float x / y / z
//! property float nx / ny / nz            (with normals)
//! property uchar red / green / blue      (with colours)
//! property float <scalar name>           (with a scalar)
//! element face M                          (only when there are faces)
//! property list uchar int vertex_indices
//! ```
//!
//! [`write_ply`] streams vertices and faces straight from the slices (no per-element
//! allocation); [`read_ply`] accepts any scalar types for coordinates, any integer list type for
//! `vertex_indices` (or `vertex_index`), binary (either endianness) or ASCII, and ignores other
//! elements. Non-triangle faces are rejected with their index.

use std::fmt;
use std::fs::File;
use std::io::{BufReader, Write};
use std::path::Path;
use std::str::FromStr;

use ply_rs::parser::{Parser, Reader};
use ply_rs::ply::{
    Addable, ElementDef, Encoding, Header, PropertyAccess, PropertyAccessResult, PropertyDef,
    PropertyType, ScalarType,
};
use ply_rs::writer::Writer;

use crate::atomic::write_atomic;
use crate::error::{IoError, Result};
use crate::limits::Limits;

/// Vertex property names with a fixed meaning (never taken as the scalar).
const RESERVED: [&str; 10] = [
    "x", "y", "z", "nx", "ny", "nz", "red", "green", "blue", "alpha",
];

/// A named per-vertex scalar: the `sl-core` type, shared with [`sl_core::Mesh`]. Its name must be
/// a PLY identifier (no whitespace, not `x`, `red`, ...).
pub use sl_core::VertexScalar;

/// A point cloud or triangle mesh.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct PlyData {
    /// Vertex positions (metres for our outputs).
    pub positions: Vec<[f32; 3]>,
    /// Optional unit normals, one per vertex.
    pub normals: Option<Vec<[f32; 3]>>,
    /// Optional 8-bit RGB colours, one per vertex.
    pub colors: Option<Vec<[u8; 3]>>,
    /// Optional named scalar, one per vertex.
    pub scalar: Option<VertexScalar>,
    /// Triangles as vertex indices (empty for a point cloud).
    pub faces: Vec<[u32; 3]>,
}

impl PlyData {
    /// A point cloud without attributes.
    pub fn from_positions(positions: Vec<[f32; 3]>) -> Self {
        Self {
            positions,
            ..Self::default()
        }
    }

    /// A point cloud from `sl-core` points (e.g. `DepthImage::to_points`).
    pub fn from_points(points: &[sl_core::nalgebra::Point3<f32>]) -> Self {
        Self::from_positions(points.iter().map(|p| [p.x, p.y, p.z]).collect())
    }

    /// A triangle mesh without attributes.
    pub fn mesh(positions: Vec<[f32; 3]>, faces: Vec<[u32; 3]>) -> Self {
        Self {
            positions,
            faces,
            ..Self::default()
        }
    }

    /// Adds normals.
    pub fn with_normals(self, normals: Vec<[f32; 3]>) -> Self {
        Self {
            normals: Some(normals),
            ..self
        }
    }

    /// Adds colours.
    pub fn with_colors(self, colors: Vec<[u8; 3]>) -> Self {
        Self {
            colors: Some(colors),
            ..self
        }
    }

    /// Adds a named per-vertex scalar.
    pub fn with_scalar(self, name: impl Into<String>, values: Vec<f32>) -> Self {
        Self {
            scalar: Some(VertexScalar {
                name: name.into(),
                values,
            }),
            ..self
        }
    }

    /// A copy of an `sl-core` mesh (positions, normals if present, scalar, triangles).
    pub fn from_mesh(mesh: &sl_core::Mesh) -> Self {
        let xyz = |v: &[f32]| [v[0], v[1], v[2]];
        Self {
            positions: mesh
                .positions
                .iter()
                .map(|p| xyz(p.coords.as_slice()))
                .collect(),
            normals: (!mesh.normals.is_empty())
                .then(|| mesh.normals.iter().map(|n| xyz(n.as_slice())).collect()),
            colors: None,
            scalar: mesh.scalar.clone(),
            faces: mesh.triangles.clone(),
        }
    }

    /// The positions, normals, scalar and faces as an `sl-core` mesh (colours are dropped).
    pub fn into_mesh(self) -> sl_core::Mesh {
        use sl_core::nalgebra::{Point3, Vector3};
        sl_core::Mesh {
            positions: self.positions.into_iter().map(Point3::from).collect(),
            normals: self
                .normals
                .map(|v| v.into_iter().map(Vector3::from).collect())
                .unwrap_or_default(),
            triangles: self.faces,
            scalar: self.scalar,
        }
    }

    /// Number of vertices.
    pub fn vertex_count(&self) -> usize {
        self.positions.len()
    }

    /// Checks that every attribute has one entry per vertex, that face indices are in range
    /// (and fit a PLY `int`), and that the scalar name is a usable PLY identifier.
    pub fn validate(&self) -> std::result::Result<(), String> {
        PlyView::of_data(self).validate()
    }
}

/// PLY payload encodings we write.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum PlyFormat {
    /// `binary_little_endian 1.0` (compact and fast; the default).
    #[default]
    BinaryLittleEndian,
    /// `ascii 1.0` (human-readable, about 3× larger).
    Ascii,
}

impl fmt::Display for PlyFormat {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Self::BinaryLittleEndian => "binary",
            Self::Ascii => "ascii",
        })
    }
}

impl FromStr for PlyFormat {
    type Err = String;

    /// Parses `binary` (or `binary_little_endian`) and `ascii`.
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        match s.trim().to_ascii_lowercase().as_str() {
            "binary" | "binary_little_endian" | "binary-little-endian" | "bin" => {
                Ok(Self::BinaryLittleEndian)
            }
            "ascii" | "text" => Ok(Self::Ascii),
            other => Err(format!(
                "unknown PLY format {other:?} (expected binary or ascii)"
            )),
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Writing

/// One vertex, as the ply-rs writer sees it (built on the stack per vertex).
#[derive(Debug, Clone, Copy, Default)]
struct VertexOut {
    p: [f32; 3],
    n: [f32; 3],
    c: [u8; 3],
    s: f32,
}

impl PropertyAccess for VertexOut {
    fn new() -> Self {
        Self::default()
    }

    fn get_float(&self, name: &str) -> Option<f32> {
        Some(match name {
            "x" => self.p[0],
            "y" => self.p[1],
            "z" => self.p[2],
            "nx" => self.n[0],
            "ny" => self.n[1],
            "nz" => self.n[2],
            // The only other float property we declare is the scalar.
            _ => self.s,
        })
    }

    fn get_uchar(&self, name: &str) -> Option<u8> {
        match name {
            "red" => Some(self.c[0]),
            "green" => Some(self.c[1]),
            "blue" => Some(self.c[2]),
            _ => None,
        }
    }
}

/// One triangle, as the ply-rs writer sees it.
#[derive(Debug, Clone, Copy, Default)]
struct FaceOut {
    idx: [i32; 3],
}

impl PropertyAccess for FaceOut {
    fn new() -> Self {
        Self::default()
    }

    fn get_list_int(&self, name: &str) -> Option<&[i32]> {
        (name == "vertex_indices").then_some(&self.idx[..])
    }
}

fn scalar_prop(name: &str, t: ScalarType) -> PropertyDef {
    PropertyDef::new(name.to_string(), PropertyType::Scalar(t))
}

fn header_for(data: &PlyView<'_>, format: PlyFormat) -> Header {
    let mut header = Header::new();
    header.encoding = match format {
        PlyFormat::BinaryLittleEndian => Encoding::BinaryLittleEndian,
        PlyFormat::Ascii => Encoding::Ascii,
    };
    header
        .comments
        .push("written by sldepth (sl-io)".to_string());
    let mut vertex = ElementDef::new("vertex".to_string());
    vertex.count = data.positions.len();
    for n in ["x", "y", "z"] {
        vertex.properties.add(scalar_prop(n, ScalarType::Float));
    }
    if data.normals.is_some() {
        for n in ["nx", "ny", "nz"] {
            vertex.properties.add(scalar_prop(n, ScalarType::Float));
        }
    }
    if data.colors.is_some() {
        for n in ["red", "green", "blue"] {
            vertex.properties.add(scalar_prop(n, ScalarType::UChar));
        }
    }
    if let Some(s) = &data.scalar {
        vertex
            .properties
            .add(scalar_prop(&s.name, ScalarType::Float));
    }
    header.elements.add(vertex);
    if !data.faces.is_empty() {
        let mut face = ElementDef::new("face".to_string());
        face.count = data.faces.len();
        face.properties.add(PropertyDef::new(
            "vertex_indices".to_string(),
            PropertyType::List(ScalarType::UChar, ScalarType::Int),
        ));
        header.elements.add(face);
    }
    header
}

/// Bytes encoded in memory before each hand-over to the output (keeps ply-rs's per-value writes
/// on a statically dispatched `Vec<u8>` instead of the `dyn Write` of [`write_atomic`]).
const ENCODE_CHUNK_BYTES: usize = 1 << 20;

fn write_body(out: &mut dyn Write, data: &PlyView<'_>, format: PlyFormat) -> std::io::Result<()> {
    let header = header_for(data, format);
    let mut chunk: Vec<u8> = Vec::with_capacity(ENCODE_CHUNK_BYTES + 4096);
    let vw = Writer::<VertexOut>::new();
    vw.write_header(&mut chunk, &header)?;
    let Some(vdef) = header.elements.get("vertex") else {
        return Err(std::io::Error::other("internal: vertex element missing"));
    };
    for i in 0..data.positions.len() {
        let v = VertexOut {
            p: data.positions.get(i),
            n: data.normals.map(|n| n.get(i)).unwrap_or_default(),
            c: data
                .colors
                .as_ref()
                .and_then(|c| c.get(i).copied())
                .unwrap_or_default(),
            s: data
                .scalar
                .as_ref()
                .and_then(|s| s.values.get(i).copied())
                .unwrap_or_default(),
        };
        match format {
            PlyFormat::BinaryLittleEndian => {
                vw.write_little_endian_element(&mut chunk, &v, vdef)?
            }
            PlyFormat::Ascii => vw.write_ascii_element(&mut chunk, &v, vdef)?,
        };
        if chunk.len() >= ENCODE_CHUNK_BYTES {
            out.write_all(&chunk)?;
            chunk.clear();
        }
    }
    if let Some(fdef) = header.elements.get("face") {
        let fw = Writer::<FaceOut>::new();
        for f in data.faces {
            // `validate` checked every index is below the vertex count, which fits in i32.
            let face = FaceOut {
                idx: [f[0] as i32, f[1] as i32, f[2] as i32],
            };
            match format {
                PlyFormat::BinaryLittleEndian => {
                    fw.write_little_endian_element(&mut chunk, &face, fdef)?
                }
                PlyFormat::Ascii => fw.write_ascii_element(&mut chunk, &face, fdef)?,
            };
            if chunk.len() >= ENCODE_CHUNK_BYTES {
                out.write_all(&chunk)?;
                chunk.clear();
            }
        }
    }
    out.write_all(&chunk)
}

/// Encodes a cloud or mesh as PLY into any writer (e.g. a `Vec<u8>` or stdout); invalid data
/// (see [`PlyData::validate`]) is an [`std::io::ErrorKind::InvalidInput`] error. Files should be
/// written with [`write_ply`], which is atomic.
pub fn encode_ply(out: &mut dyn Write, data: &PlyData, format: PlyFormat) -> std::io::Result<()> {
    let data = PlyView::of_data(data);
    data.validate()
        .map_err(|m| std::io::Error::new(std::io::ErrorKind::InvalidInput, m))?;
    write_body(out, &data, format)
}

/// Writes a cloud or mesh atomically. Mismatched attribute lengths, out-of-range face indices or
/// a bad scalar name are [`IoError::InvalidData`].
pub fn write_ply(path: impl AsRef<Path>, data: &PlyData, format: PlyFormat) -> Result<()> {
    write_view(path.as_ref(), &PlyView::of_data(data), format)
}

/// Writes an `sl-core` [`Mesh`](sl_core::Mesh) atomically: the same file as [`write_ply`] of
/// [`PlyData::from_mesh`], read from the mesh in place (no copy of it is made).
pub fn write_mesh_ply(
    path: impl AsRef<Path>,
    mesh: &sl_core::Mesh,
    format: PlyFormat,
) -> Result<()> {
    write_view(path.as_ref(), &PlyView::of_mesh(mesh), format)
}

/// [`write_ply`] of a view.
fn write_view(path: &Path, data: &PlyView<'_>, format: PlyFormat) -> Result<()> {
    data.validate()
        .map_err(|m| IoError::invalid_data(path, m))?;
    write_atomic(path, |w| write_body(w, data, format))
}

/// Reads a PLY file as an `sl-core` [`Mesh`](sl_core::Mesh) (see [`read_ply`]; colours are
/// dropped).
pub fn read_mesh_ply(path: impl AsRef<Path>) -> Result<sl_core::Mesh> {
    read_ply(path).map(PlyData::into_mesh)
}

mod read;
mod view;

use view::PlyView;

pub use read::{read_ply, read_ply_with_limits};

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(n: usize, faces: bool) -> PlyData {
        let positions: Vec<[f32; 3]> = (0..n)
            .map(|i| [i as f32 * 0.25, -(i as f32) / 3.0, 1.0 + i as f32])
            .collect();
        let mut d = PlyData::from_positions(positions);
        if faces {
            d.faces = (0..n.saturating_sub(2))
                .map(|i| [i as u32, i as u32 + 1, i as u32 + 2])
                .collect();
        }
        d
    }

    #[test]
    fn round_trip_variants() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("m.ply");
        for format in [PlyFormat::BinaryLittleEndian, PlyFormat::Ascii] {
            for faces in [false, true] {
                for attrs in 0..4 {
                    let mut d = sample(7, faces);
                    if attrs & 1 == 1 {
                        d = d.with_normals((0..7).map(|i| [0.0, (i as f32).sin(), 1.0]).collect());
                        d = d.with_colors((0..7).map(|i| [i as u8 * 30, 255, 0]).collect());
                    }
                    if attrs & 2 == 2 {
                        d = d.with_scalar("confidence", (0..7).map(|i| i as f32 / 7.0).collect());
                    }
                    write_ply(&p, &d, format).unwrap();
                    assert_eq!(
                        read_ply(&p).unwrap(),
                        d,
                        "{format} faces={faces} attrs={attrs}"
                    );
                }
            }
        }
    }

    #[test]
    fn header_is_conventional() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("m.ply");
        write_ply(
            &p,
            &sample(4, true).with_scalar("sigma_z_m", vec![0.0; 4]),
            PlyFormat::Ascii,
        )
        .unwrap();
        let text = std::fs::read_to_string(&p).unwrap();
        assert!(text.starts_with("ply\nformat ascii 1.0\n"), "{text}");
        assert!(text.contains("element vertex 4\n"));
        assert!(text.contains("property float sigma_z_m\n"));
        assert!(
            text.contains("element face 2\nproperty list uchar int vertex_indices\nend_header\n")
        );
        assert!(text.ends_with("3 0 1 2\n3 1 2 3\n"), "{text}");
    }

    #[test]
    fn invalid_data_rejected() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("bad.ply");
        let cases = [
            sample(3, false).with_normals(vec![[0.0; 3]; 2]),
            sample(3, false).with_colors(vec![[0; 3]; 4]),
            sample(3, false).with_scalar("c", vec![0.0; 2]),
            sample(3, false).with_scalar("x", vec![0.0; 3]),
            sample(3, false).with_scalar("two words", vec![0.0; 3]),
            PlyData::mesh(vec![[0.0; 3]; 3], vec![[0, 1, 3]]),
        ];
        for d in cases {
            let err = write_ply(&p, &d, PlyFormat::BinaryLittleEndian).unwrap_err();
            assert!(matches!(err, IoError::InvalidData { .. }), "{err}");
            assert!(!p.exists());
        }
    }

    #[test]
    fn reads_foreign_layouts() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("f.ply");
        std::fs::write(
            &p,
            "ply\nformat ascii 1.0\ncomment other tool\nelement vertex 3\nproperty double x\nproperty double y\n\
             property double z\nproperty uchar alpha\nproperty float intensity\nproperty float extra\n\
             element face 1\nproperty list uchar uint vertex_index\nelement edge 1\nproperty int a\n\
             end_header\n0 0 0 9 0.5 7\n1 0 0 9 1.5 7\n0 1 0 9 2.5 7\n3 0 1 2\n5\n",
        )
        .unwrap();
        let d = read_ply(&p).unwrap();
        assert_eq!(
            d.positions,
            vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]
        );
        assert_eq!(d.faces, vec![[0, 1, 2]]);
        assert_eq!(
            d.scalar.unwrap(),
            VertexScalar {
                name: "intensity".into(),
                values: vec![0.5, 1.5, 2.5]
            }
        );
        assert!(d.normals.is_none() && d.colors.is_none());
    }

    #[test]
    fn reads_big_endian() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("be.ply");
        let mut bytes = b"ply\nformat binary_big_endian 1.0\nelement vertex 1\nproperty float x\nproperty float y\n\
property float z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n"
            .to_vec();
        for v in [1.5f32, -2.0, 3.25] {
            bytes.extend_from_slice(&v.to_be_bytes());
        }
        bytes.extend_from_slice(&[10, 20, 30]);
        std::fs::write(&p, &bytes).unwrap();
        let d = read_ply(&p).unwrap();
        assert_eq!(d.positions, vec![[1.5, -2.0, 3.25]]);
        assert_eq!(d.colors, Some(vec![[10, 20, 30]]));
    }

    #[test]
    fn malformed_files_rejected() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("bad.ply");
        let cases: [&str; 7] = [
            "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nend_header\n0 0\n",
            "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\nend_header\n0 0 0\n",
            "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n\
             element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n4 0 1 2 0\n",
            "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n\
             element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 5\n",
            "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n\
             element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 -1 2\n",
            "ply\nformat binary_little_endian 1.0\nelement vertex 4000000000\nproperty float x\nproperty float y\n\
             property float z\nend_header\n",
            "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n\
             property float nx\nend_header\n0 0 0 1\n1 0 0 1\n0 1 0 1\n",
        ];
        for text in cases {
            std::fs::write(&p, text).unwrap();
            let err = read_ply(&p).unwrap_err();
            assert!(err.to_string().contains("bad.ply"), "{err}");
        }
    }

    #[test]
    fn core_mesh_round_trip_matches_ply_data() {
        use sl_core::nalgebra::{Point3, Vector3};
        let mesh = sl_core::Mesh::new(
            vec![
                Point3::new(0.0, 0.0, 1.0),
                Point3::new(1.0, 0.0, 1.5),
                Point3::new(0.0, 1.0, 2.0),
            ],
            vec![[0, 1, 2]],
        )
        .with_normals(vec![Vector3::new(0.0, 0.0, -1.0); 3])
        .with_scalar("confidence", vec![0.5, 1.0, 2.0]);
        let dir = tempfile::tempdir().unwrap();
        let (a, b) = (dir.path().join("a.ply"), dir.path().join("b.ply"));
        for format in [PlyFormat::BinaryLittleEndian, PlyFormat::Ascii] {
            write_mesh_ply(&a, &mesh, format).unwrap();
            write_ply(&b, &PlyData::from_mesh(&mesh), format).unwrap();
            assert_eq!(std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap());
            assert_eq!(read_mesh_ply(&a).unwrap(), mesh);
        }
        let cloud = sl_core::Mesh::new(vec![Point3::new(1.0, 2.0, 3.0)], vec![]);
        assert_eq!(PlyData::from_mesh(&cloud).normals, None);
        write_mesh_ply(&a, &cloud, PlyFormat::Ascii).unwrap();
        write_ply(&b, &PlyData::from_mesh(&cloud), PlyFormat::Ascii).unwrap();
        assert_eq!(std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap());
        let mut bad = mesh.clone();
        bad.triangles.push([0, 1, 3]);
        assert!(write_mesh_ply(&a, &bad, PlyFormat::Ascii).is_err());
    }
}
