//! Triangle meshes (and point clouds: a mesh without triangles).
//!
//! [`Mesh`] stores `f32` positions and normals as nalgebra `Point3<f32>` / `Vector3<f32>`, both
//! `#[repr(C)]` arrays of three `f32`, so a position buffer can be viewed as an `(N, 3)` float32
//! array without copying. Per-vertex attributes are either empty (absent) or hold one entry per
//! vertex; [`Mesh::validate`] checks that, and that every triangle index is in range.

use nalgebra::{Point3, Vector3};

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

#[cfg(test)]
mod tests {
    use super::*;
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
