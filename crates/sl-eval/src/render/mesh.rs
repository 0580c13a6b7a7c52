//! A small software renderer: z-buffered, Lambert-shaded triangles to an RGB image, for
//! looking at fused meshes in reports (and the CLI's `sldepth fuse --render-png`) without a 3D
//! viewer.

use sl_core::Mesh;
use sl_core::nalgebra::{self, Point3, Vector3};
use sl_core::{CameraToWorld, Image, Intrinsics};

use crate::error::{EvalError, Result};

/// Background colour.
pub const BACKGROUND_RGB: [u8; 3] = [255, 255, 255];

/// Renders `mesh` seen by a pinhole camera `k` at camera-to-world `pose` (camera looks along
/// +Z, y down). Front faces are light grey, back faces (seen from behind, which reveals
/// orientation errors) tinted blue; shading is a head light, `0.2 + 0.8·|cos|`.
pub fn render_mesh(mesh: &Mesh, k: &Intrinsics, pose: &CameraToWorld) -> Result<Image<[u8; 3]>> {
    k.validate()?;
    let (w, h) = (k.width, k.height);
    if w.saturating_mul(h) > 64 << 20 {
        return Err(EvalError::InvalidParameter(format!(
            "render size {w}x{h} too large"
        )));
    }
    let inv = *pose.inverse().isometry();
    let cam: Vec<Point3<f64>> = mesh
        .positions
        .iter()
        .map(|p| inv * Point3::new(f64::from(p[0]), f64::from(p[1]), f64::from(p[2])))
        .collect();
    let mut zbuf = vec![f64::INFINITY; w * h];
    let mut img = Image::filled(w, h, BACKGROUND_RGB);
    let near = 1e-3;
    for t in &mesh.triangles {
        let [a, b, c] = t.map(|i| cam[i as usize]);
        if a.z < near || b.z < near || c.z < near {
            continue;
        }
        let n = (b - a).cross(&(c - a));
        let nn = n.norm();
        if nn == 0.0 {
            continue;
        }
        let centroid = (a.coords + b.coords + c.coords) / 3.0;
        let view = -centroid.normalize();
        let cos = n.dot(&view) / nn;
        let shade = 0.2 + 0.8 * cos.abs();
        let rgb = if cos >= 0.0 {
            [
                (230.0 * shade) as u8,
                (225.0 * shade) as u8,
                (215.0 * shade) as u8,
            ]
        } else {
            [
                (120.0 * shade) as u8,
                (140.0 * shade) as u8,
                (230.0 * shade) as u8,
            ]
        };
        let proj = |p: &Point3<f64>| (k.fx * p.x / p.z + k.cx, k.fy * p.y / p.z + k.cy, 1.0 / p.z);
        let (pa, pb, pc) = (proj(&a), proj(&b), proj(&c));
        let area = (pb.0 - pa.0) * (pc.1 - pa.1) - (pb.1 - pa.1) * (pc.0 - pa.0);
        if area.abs() < 1e-12 {
            continue;
        }
        let x0 = pa.0.min(pb.0).min(pc.0).floor().max(0.0) as usize;
        let x1 = (pa.0.max(pb.0).max(pc.0).ceil() as i64).min(w as i64 - 1);
        let y0 = pa.1.min(pb.1).min(pc.1).floor().max(0.0) as usize;
        let y1 = (pa.1.max(pb.1).max(pc.1).ceil() as i64).min(h as i64 - 1);
        if x1 < 0 || y1 < 0 {
            continue;
        }
        for y in y0..=y1 as usize {
            for x in x0..=x1 as usize {
                let (px, py) = (x as f64, y as f64);
                let w0 = ((pb.0 - px) * (pc.1 - py) - (pb.1 - py) * (pc.0 - px)) / area;
                let w1 = ((pc.0 - px) * (pa.1 - py) - (pc.1 - py) * (pa.0 - px)) / area;
                let w2 = 1.0 - w0 - w1;
                if w0 < 0.0 || w1 < 0.0 || w2 < 0.0 {
                    continue;
                }
                let inv_z = w0 * pa.2 + w1 * pb.2 + w2 * pc.2;
                let z = 1.0 / inv_z;
                let i = y * w + x;
                if z < zbuf[i] {
                    zbuf[i] = z;
                    img.data_mut()[i] = rgb;
                }
            }
        }
    }
    Ok(img)
}

/// A camera of `width`×`height` pixels (60° horizontal field of view) looking at the mesh's
/// bounding box from direction `view_dir` (world frame, from the camera towards the mesh) with
/// `up` roughly up in the image, placed so that the whole box is visible.
pub fn framing_camera(
    mesh: &Mesh,
    view_dir: Vector3<f64>,
    up: Vector3<f64>,
    width: usize,
    height: usize,
) -> Result<(Intrinsics, CameraToWorld)> {
    let (lo, hi) = mesh
        .bounding_box()
        .ok_or_else(|| EvalError::InvalidParameter("cannot frame an empty mesh".into()))?;
    let lo = Vector3::new(f64::from(lo[0]), f64::from(lo[1]), f64::from(lo[2]));
    let hi = Vector3::new(f64::from(hi[0]), f64::from(hi[1]), f64::from(hi[2]));
    let centre = (lo + hi) / 2.0;
    let radius = ((hi - lo).norm() / 2.0).max(1e-3);
    let f = width as f64 / 2.0 / (30f64.to_radians()).tan();
    let k = Intrinsics::new(
        width,
        height,
        f,
        f,
        (width as f64 - 1.0) / 2.0,
        (height as f64 - 1.0) / 2.0,
    )?;
    let half_fov = ((width.min(height) as f64 / 2.0) / f).atan();
    let dist = radius / half_fov.sin() * 1.05;
    let z = view_dir
        .try_normalize(1e-12)
        .ok_or_else(|| EvalError::InvalidParameter("zero view direction".into()))?;
    let x = (-up)
        .cross(&z)
        .try_normalize(1e-12)
        .ok_or_else(|| EvalError::InvalidParameter("view direction parallel to up".into()))?;
    let y = z.cross(&x);
    let rot =
        nalgebra::Rotation3::from_matrix_unchecked(nalgebra::Matrix3::from_columns(&[x, y, z]));
    let eye = centre - z * dist;
    let pose = CameraToWorld::from_isometry(nalgebra::Isometry3::from_parts(
        nalgebra::Translation3::from(eye),
        nalgebra::UnitQuaternion::from_rotation_matrix(&rot),
    ));
    Ok((k, pose))
}
