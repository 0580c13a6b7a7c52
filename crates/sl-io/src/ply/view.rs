//! A borrowed view of a cloud or mesh for writing: [`PlyData`]'s fields or an `sl-core`
//! [`Mesh`](sl_core::Mesh)'s, read in place, so writing a mesh does not first copy it (a
//! fused mesh can hold as many bytes as the volume it came from).

use sl_core::VertexScalar;
use sl_core::nalgebra::{Point3, Vector3};

use super::{PlyData, RESERVED};

/// Per-vertex triples, in whichever layout their owner keeps them.
#[derive(Clone, Copy)]
pub(super) enum Triples<'a> {
    Arrays(&'a [[f32; 3]]),
    Points(&'a [Point3<f32>]),
    Vectors(&'a [Vector3<f32>]),
}

impl Triples<'_> {
    pub(super) fn len(&self) -> usize {
        match self {
            Self::Arrays(v) => v.len(),
            Self::Points(v) => v.len(),
            Self::Vectors(v) => v.len(),
        }
    }

    /// Triple `i` (zeros beyond the end; [`PlyView::validate`] rules that out).
    pub(super) fn get(&self, i: usize) -> [f32; 3] {
        match self {
            Self::Arrays(v) => v.get(i).copied(),
            Self::Points(v) => v.get(i).map(|p| [p.x, p.y, p.z]),
            Self::Vectors(v) => v.get(i).map(|n| [n.x, n.y, n.z]),
        }
        .unwrap_or_default()
    }
}

/// What [`super::write_ply`] and [`super::write_mesh_ply`] write.
#[derive(Clone, Copy)]
pub(super) struct PlyView<'a> {
    pub(super) positions: Triples<'a>,
    pub(super) normals: Option<Triples<'a>>,
    pub(super) colors: Option<&'a [[u8; 3]]>,
    pub(super) scalar: Option<&'a VertexScalar>,
    pub(super) faces: &'a [[u32; 3]],
}

impl<'a> PlyView<'a> {
    pub(super) fn of_data(d: &'a PlyData) -> Self {
        Self {
            positions: Triples::Arrays(&d.positions),
            normals: d.normals.as_deref().map(Triples::Arrays),
            colors: d.colors.as_deref(),
            scalar: d.scalar.as_ref(),
            faces: &d.faces,
        }
    }

    /// The mesh as [`PlyData::from_mesh`] would have it (no normals when it has none).
    pub(super) fn of_mesh(m: &'a sl_core::Mesh) -> Self {
        Self {
            positions: Triples::Points(&m.positions),
            normals: (!m.normals.is_empty()).then_some(Triples::Vectors(&m.normals)),
            colors: None,
            scalar: m.scalar.as_ref(),
            faces: &m.triangles,
        }
    }

    /// See [`PlyData::validate`].
    pub(super) fn validate(&self) -> std::result::Result<(), String> {
        let n = self.positions.len();
        if let Some(v) = &self.normals
            && v.len() != n
        {
            return Err(format!("{} normals for {n} vertices", v.len()));
        }
        if let Some(v) = &self.colors
            && v.len() != n
        {
            return Err(format!("{} colours for {n} vertices", v.len()));
        }
        if let Some(s) = &self.scalar {
            if s.values.len() != n {
                return Err(format!(
                    "{} values of scalar {:?} for {n} vertices",
                    s.values.len(),
                    s.name
                ));
            }
            let bad_char = s.name.chars().any(|c| c.is_whitespace() || c.is_control());
            if s.name.is_empty() || bad_char || RESERVED.contains(&s.name.as_str()) {
                return Err(format!(
                    "scalar name {:?} must be a non-empty PLY identifier without whitespace and not one of {RESERVED:?}",
                    s.name
                ));
            }
        }
        if n > i32::MAX as usize && !self.faces.is_empty() {
            return Err(format!(
                "{n} vertices cannot be indexed by PLY int face indices"
            ));
        }
        if let Some((i, f)) = self
            .faces
            .iter()
            .enumerate()
            .find(|(_, f)| f.iter().any(|&v| v as usize >= n))
        {
            return Err(format!(
                "face {i} {f:?} refers to a vertex beyond the {n} vertices"
            ));
        }
        Ok(())
    }
}
