//! Triangle meshes (and point clouds: a mesh without triangles).
//!
//! [`Mesh`] stores `f32` positions and normals as nalgebra `Point3<f32>` / `Vector3<f32>`, both
//! `#[repr(C)]` arrays of three `f32`, so a position buffer can be viewed as an `(N, 3)` float32
//! array without copying. Per-vertex attributes are either empty (absent) or hold one entry per
//! vertex; [`Mesh::validate`] checks that, and that every triangle index is in range.

use nalgebra::{Isometry3, Point3, Vector3};

use crate::error::{CoreError, Result};

/// A named per-vertex scalar, e.g. `confidence` (a PLY property name: no whitespace).
#[derive(Debug, Clone, PartialEq)]
pub struct VertexScalar {
    /// Property name.
    pub name: String,
    /// One value per vertex.
    pub values: Vec<f32>,
}

/// A triangle mesh: positions, optional normals, triangles and an optional per-vertex scalar.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Mesh {
    /// Vertex positions (metres for the workspace's outputs).
    pub positions: Vec<Point3<f32>>,
    /// Unit vertex normals, one per vertex; empty if absent.
    pub normals: Vec<Vector3<f32>>,
    /// Triangles as indices into `positions`; empty for a point cloud.
    pub triangles: Vec<[u32; 3]>,
    /// Optional named per-vertex scalar.
    pub scalar: Option<VertexScalar>,
}

impl Mesh {
    /// A mesh from positions and triangles, without attributes.
    pub fn new(positions: Vec<Point3<f32>>, triangles: Vec<[u32; 3]>) -> Self {
        Self {
            positions,
            triangles,
            ..Self::default()
        }
    }

    /// Moves the mesh rigidly: positions by `iso`, normals by its rotation (computed in f64,
    /// stored as f32).
    pub fn transform(&mut self, iso: &Isometry3<f64>) {
        for p in &mut self.positions {
            *p = (iso * p.cast::<f64>()).cast::<f32>();
        }
        for n in &mut self.normals {
            *n = (iso.rotation * n.cast::<f64>()).cast::<f32>();
        }
    }

    /// Mirrors the mesh in `y` (`F = diag(1, −1, 1)`): positions and normals get `−y`, and each
    /// triangle's winding is reversed so its corners stay counter-clockwise seen from the side
    /// its (mirrored) normal points to. The mesh of a camera trajectory reflected with
    /// [`crate::CameraToWorld::y_reflected`] (a data set that renders with y up, as ICL-NUIM's
    /// TUM-format files): the two stay in one frame. Applying it twice gives the mesh back.
    pub fn reflect_y(&mut self) {
        for p in &mut self.positions {
            p.y = -p.y;
        }
        for n in &mut self.normals {
            n.y = -n.y;
        }
        for t in &mut self.triangles {
            t.swap(1, 2);
        }
    }

    /// Adds vertex normals.
    #[must_use]
    pub fn with_normals(self, normals: Vec<Vector3<f32>>) -> Self {
        Self { normals, ..self }
    }

    /// Adds a named per-vertex scalar.
    #[must_use]
    pub fn with_scalar(self, name: impl Into<String>, values: Vec<f32>) -> Self {
        Self {
            scalar: Some(VertexScalar {
                name: name.into(),
                values,
            }),
            ..self
        }
    }

    /// Number of vertices.
    pub fn vertex_count(&self) -> usize {
        self.positions.len()
    }

    /// Number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.triangles.len()
    }

    /// Bytes the mesh's buffers hold (their capacity, not just their length): positions,
    /// normals, triangles and the scalar's values and name.
    pub fn memory_bytes(&self) -> usize {
        use std::mem::size_of;
        self.positions.capacity() * size_of::<Point3<f32>>()
            + self.normals.capacity() * size_of::<Vector3<f32>>()
            + self.triangles.capacity() * size_of::<[u32; 3]>()
            + self.scalar.as_ref().map_or(0, |s| {
                s.values.capacity() * size_of::<f32>() + s.name.capacity()
            })
    }

    /// `true` when the mesh has no vertices.
    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }

    /// The three corners of triangle `i`, or `None` if `i` or one of its indices is out of range.
    pub fn triangle_corners(&self, i: usize) -> Option<[Point3<f32>; 3]> {
        let [a, b, c] = *self.triangles.get(i)?;
        let at = |k: u32| self.positions.get(k as usize).copied();
        Some([at(a)?, at(b)?, at(c)?])
    }

    /// Unnormalised normal `(b − a) × (c − a)` of triangle `i` (its length is twice the
    /// triangle's area; counter-clockwise corners seen from the side it points to), or `None`
    /// if the triangle does not exist.
    pub fn face_normal(&self, i: usize) -> Option<Vector3<f32>> {
        let [a, b, c] = self.triangle_corners(i)?;
        Some((b - a).cross(&(c - a)))
    }

    /// Checks that normals and the scalar are absent or have one entry per vertex, and that
    /// every triangle index is in range.
    pub fn validate(&self) -> Result<()> {
        let n = self.positions.len();
        if !self.normals.is_empty() && self.normals.len() != n {
            return Err(CoreError::InvalidMesh(format!(
                "{} normals for {n} vertices",
                self.normals.len()
            )));
        }
        if let Some(s) = &self.scalar
            && s.values.len() != n
        {
            return Err(CoreError::InvalidMesh(format!(
                "{} values of scalar {:?} for {n} vertices",
                s.values.len(),
                s.name
            )));
        }
        if let Some((i, t)) = self
            .triangles
            .iter()
            .enumerate()
            .find(|(_, t)| t.iter().any(|&k| k as usize >= n))
        {
            return Err(CoreError::InvalidMesh(format!(
                "triangle {i} {t:?} indexes past {n} vertices"
            )));
        }
        Ok(())
    }

    /// Axis-aligned bounding box `(min, max)` of the positions (non-finite coordinates are
    /// skipped), or `None` if there is no finite position.
    pub fn bounding_box(&self) -> Option<(Point3<f32>, Point3<f32>)> {
        let mut finite = self
            .positions
            .iter()
            .filter(|p| p.iter().all(|c| c.is_finite()));
        let first = *finite.next()?;
        Some(finite.fold((first, first), |(lo, hi), p| (lo.inf(p), hi.sup(p))))
    }
}

/// Edge statistics of a mesh: the checks of a closed, manifold, consistently oriented surface
/// ([`Mesh::topology`]).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Topology {
    /// Undirected edges.
    pub edges: usize,
    /// Edges with one triangle (holes or the border of the observed region).
    pub boundary_edges: usize,
    /// Edges with more than two triangles.
    pub nonmanifold_edges: usize,
    /// Edges with two triangles traversing them in the same direction.
    pub inconsistent_edges: usize,
    /// Triangles with a repeated vertex index.
    pub degenerate_triangles: usize,
}

impl Topology {
    /// No boundary, every edge shared by exactly two triangles in opposite directions.
    pub fn is_closed_oriented_manifold(&self) -> bool {
        self.boundary_edges == 0 && self.nonmanifold_edges == 0 && self.inconsistent_edges == 0
    }
}

impl Mesh {
    /// The values of the per-vertex scalar called `name`, if the mesh has it.
    pub fn scalar_values(&self, name: &str) -> Option<&[f32]> {
        self.scalar
            .as_ref()
            .filter(|s| s.name == name)
            .map(|s| s.values.as_slice())
    }

    /// Edge-based topology checks (one sort of the `3·triangles` directed edges).
    pub fn topology(&self) -> Topology {
        let mut undirected: Vec<(u32, u32, bool)> = Vec::with_capacity(self.triangles.len() * 3);
        let mut degenerate = 0;
        for t in &self.triangles {
            if t[0] == t[1] || t[1] == t[2] || t[0] == t[2] {
                degenerate += 1;
            }
            for i in 0..3 {
                let (a, b) = (t[i], t[(i + 1) % 3]);
                undirected.push(if a < b { (a, b, true) } else { (b, a, false) });
            }
        }
        undirected.sort_unstable();
        let mut topo = Topology {
            degenerate_triangles: degenerate,
            ..Topology::default()
        };
        for run in undirected.chunk_by(|x, y| x.0 == y.0 && x.1 == y.1) {
            topo.edges += 1;
            match run {
                [_] => topo.boundary_edges += 1,
                [x, y] => {
                    if x.2 == y.2 {
                        topo.inconsistent_edges += 1;
                    }
                }
                _ => topo.nonmanifold_edges += 1,
            }
        }
        topo
    }

    /// Signed enclosed volume, in the positions' unit cubed (positive when the triangles face
    /// outwards of a closed surface). Computed in `f64`; triangles with an index out of range
    /// are skipped.
    pub fn signed_volume(&self) -> f64 {
        (0..self.triangles.len())
            .filter_map(|i| self.triangle_corners(i))
            .map(|[a, b, c]| {
                let [a, b, c] = [a, b, c].map(|p| p.coords.cast::<f64>());
                a.dot(&b.cross(&c)) / 6.0
            })
            .sum()
    }

    /// Total surface area, in the positions' unit squared (computed in `f64`; triangles with an
    /// index out of range are skipped).
    pub fn area(&self) -> f64 {
        (0..self.triangles.len())
            .filter_map(|i| self.triangle_corners(i))
            .map(|[a, b, c]| {
                let [a, b, c] = [a, b, c].map(|p| p.coords.cast::<f64>());
                0.5 * (b - a).cross(&(c - a)).norm()
            })
            .sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The mirror keeps each face's normal on the side its vertex normals point to, and undoes
    /// itself.
    #[test]
    fn a_mirrored_mesh_keeps_its_faces_facing_their_normals() {
        let n = Vector3::new(0.2f32, 0.5, -1.0).normalize();
        let mut mesh = Mesh::new(
            vec![
                Point3::new(0.0, 0.0, 2.0),
                Point3::new(1.0, 0.1, 2.0),
                Point3::new(0.0, 1.0, 2.5),
            ],
            vec![[0, 1, 2]],
        )
        .with_normals(vec![n; 3]);
        // Make the face's corners counter-clockwise seen from its normal's side.
        if mesh.face_normal(0).unwrap().dot(&n) < 0.0 {
            mesh.triangles[0].swap(1, 2);
        }
        let original = mesh.clone();
        mesh.reflect_y();
        assert_eq!(mesh.positions[1], Point3::new(1.0, -0.1, 2.0));
        assert_eq!(mesh.normals[0], Vector3::new(n.x, -n.y, n.z));
        assert!(mesh.face_normal(0).unwrap().dot(&mesh.normals[0]) > 0.0);
        mesh.reflect_y();
        assert_eq!(mesh, original);
    }

    /// A rigid move keeps the shape: positions and normals move together, lengths are kept.
    #[test]
    fn transform_moves_positions_and_normals() {
        let mut m = Mesh::new(
            vec![Point3::new(1.0, 0.0, 0.0), Point3::new(0.0, 2.0, 0.0)],
            vec![],
        )
        .with_normals(vec![Vector3::x(), Vector3::z()]);
        let iso = Isometry3::new(
            nalgebra::Vector3::new(0.5, -1.0, 2.0),
            nalgebra::Vector3::z() * std::f64::consts::FRAC_PI_2,
        );
        m.transform(&iso);
        assert!((m.positions[0] - Point3::new(0.5, 0.0, 2.0)).norm() < 1e-6);
        assert!((m.positions[1] - Point3::new(-1.5, -1.0, 2.0)).norm() < 1e-6);
        assert!((m.normals[0] - Vector3::y()).norm() < 1e-6);
        assert!((m.normals[1] - Vector3::z()).norm() < 1e-6);
    }
    use proptest::prelude::*;

    fn square() -> Mesh {
        Mesh::new(
            vec![
                Point3::new(0.0, 0.0, 1.0),
                Point3::new(1.0, 0.0, 1.0),
                Point3::new(1.0, 1.0, 1.0),
                Point3::new(0.0, 1.0, 1.0),
            ],
            vec![[0, 1, 2], [0, 2, 3]],
        )
    }

    /// Every buffer is counted: 12 bytes a position, a normal and a triangle, 4 a scalar value.
    #[test]
    fn memory_bytes_counts_every_buffer() {
        let mut m = square();
        m.positions.shrink_to_fit();
        m.triangles.shrink_to_fit();
        assert_eq!(m.memory_bytes(), 4 * 12 + 2 * 12);
        let m = m
            .with_normals(vec![Vector3::z(); 4])
            .with_scalar(String::from("w"), vec![1.0; 4]);
        assert_eq!(m.memory_bytes(), 4 * 12 + 4 * 12 + 2 * 12 + 4 * 4 + 1);
    }

    #[test]
    fn counts_normals_and_box() {
        let m = square();
        assert_eq!((m.vertex_count(), m.triangle_count()), (4, 2));
        assert_eq!(m.face_normal(0), Some(Vector3::new(0.0, 0.0, 1.0)));
        assert_eq!(m.face_normal(2), None);
        let (lo, hi) = m.bounding_box().unwrap();
        assert_eq!(lo, Point3::new(0.0, 0.0, 1.0));
        assert_eq!(hi, Point3::new(1.0, 1.0, 1.0));
        assert!(Mesh::default().bounding_box().is_none());
        assert!(m.validate().is_ok());
    }

    #[test]
    fn validate_catches_bad_meshes() {
        let mut m = square();
        m.triangles.push([0, 1, 4]);
        assert!(m.validate().is_err());
        let m = square().with_normals(vec![Vector3::z(); 3]);
        assert!(m.validate().is_err());
        let m = square().with_scalar("confidence", vec![1.0; 5]);
        assert!(m.validate().is_err());
        let m = square()
            .with_normals(vec![Vector3::z(); 4])
            .with_scalar("confidence", vec![1.0; 4]);
        assert!(m.validate().is_ok());
    }

    #[test]
    fn positions_are_packed_f32_triples() {
        assert_eq!(std::mem::size_of::<Point3<f32>>(), 12);
        assert_eq!(std::mem::align_of::<Point3<f32>>(), 4);
    }

    proptest! {
        #[test]
        fn validate_matches_index_range(n in 0usize..20, tris in proptest::collection::vec([0u32..25, 0u32..25, 0u32..25], 0..10)) {
            let m = Mesh::new(vec![Point3::origin(); n], tris.clone());
            let in_range = tris.iter().flatten().all(|&k| (k as usize) < n);
            prop_assert_eq!(m.validate().is_ok(), in_range);
        }
    }
}
