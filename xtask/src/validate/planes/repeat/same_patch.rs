//! The data's own limit of the repeatability benchmark: does the *same surface patch* give the
//! same plane in frame `i` and frame `i + k`?
//!
//! A plane of frame `i` (its labelled pixels with depth) is moved with the ground-truth poses
//! into frame `i + k`; a pixel is *seen* there when frame `i + k` has depth within the
//! benchmark's offset tolerance plus 3 σ_Z (the sensor model at that depth) of the moved
//! point. When at least half the plane's pixels are seen, the seen pixels are fitted alone in
//! each frame (a least-squares plane through their points in world coordinates) and the two
//! fits are compared with the benchmark's own rule ([`super::same_plane`]). No extractor
//! decides anything here: a patch whose two fits disagree cannot be found again by any
//! extractor that labels the same pixels, and a plane mostly out of view can be found again
//! only by a plane elsewhere on its surface. So `same patch agrees` bounds what reproducing
//! frame `i`'s planes exactly in frame `i + k` would score, and the share of planes the
//! extractor *or* the same-patch test finds bounds an extractor that does both.

use sl_core::nalgebra::Point3;
use sl_core::{Camera, CameraToWorld, DepthImage, Image, fit_plane};

use super::{REPEAT_MAX_OFFSET_M, REPEAT_MIN_PIXELS, WorldPlane, same_plane};

/// What a frame keeps for the same-patch test: its depth (after undistortion), labels, pose
/// and world planes.
pub struct PatchFrame {
    /// Depth, metres (0 = invalid).
    pub depth: DepthImage,
    /// Plane label per pixel (0 = none; plane `id` is `planes[id - 1]`).
    pub labels: Image<u16>,
    /// Camera-to-world pose.
    pub pose: CameraToWorld,
    /// The frame's planes in world coordinates, in label order.
    pub planes: Vec<WorldPlane>,
}

/// Same-patch counts at one gap.
#[derive(Debug, Default, Clone, Copy)]
pub struct SamePatch {
    /// Planes ≥ `REPEAT_MIN_PIXELS` of frame `i` tested.
    pub planes: usize,
    /// Of which at least half seen in frame `i + k`.
    pub half_seen: usize,
    /// Of which the seen pixels' fits in both frames are the same plane.
    pub agree: usize,
    /// Planes the extractor found again (as in [`super::repeatability`]).
    pub repeated: usize,
    /// Planes found again by the extractor or agreeing as a patch.
    pub either: usize,
}

impl SamePatch {
    /// Share of the tested planes, for a count.
    pub fn share(&self, n: usize) -> f64 {
        n as f64 / self.planes.max(1) as f64
    }

    /// Adds the planes of frame `a` against frame `b` (`b` is `k` frames later).
    pub fn add(&mut self, a: &PatchFrame, b: &PatchFrame, camera: &Camera) {
        for (i, p) in a.planes.iter().enumerate() {
            if p.pixels < REPEAT_MIN_PIXELS {
                continue;
            }
            let Ok(id) = u16::try_from(i + 1) else {
                break;
            };
            self.planes += 1;
            let found = b.planes.iter().any(|q| same_plane(p, &q.plane));
            let agrees = match patch_fits(a, b, id, camera) {
                Some((fa, fb)) => {
                    self.half_seen += 1;
                    same_plane(&fa, &fb.plane)
                }
                None => false,
            };
            self.repeated += usize::from(found);
            self.agree += usize::from(agrees);
            self.either += usize::from(found || agrees);
        }
    }
}

/// The world-coordinate fits of plane `id`'s pixels of frame `a` that frame `b` sees, in `a` and
/// in `b`; `None` when fewer than half are seen or a fit is degenerate.
fn patch_fits(
    a: &PatchFrame,
    b: &PatchFrame,
    id: u16,
    camera: &Camera,
) -> Option<(WorldPlane, WorldPlane)> {
    let k = &camera.intrinsics;
    let (wa, wb) = (a.pose.isometry(), b.pose.isometry());
    let a_to_b = wb.inverse() * wa;
    let w = a.labels.width();
    let (mut in_a, mut in_b) = (Vec::new(), Vec::new());
    let mut total = 0usize;
    for (idx, (&l, &z)) in a.labels.data().iter().zip(a.depth.data()).enumerate() {
        if l != id || z.is_nan() || z <= 0.0 {
            continue;
        }
        total += 1;
        let p = k.back_project((idx % w) as f64, (idx / w) as f64, f64::from(z));
        let pb = a_to_b * p;
        let Some((x, y)) = k.project_to_pixel(&pb) else {
            continue;
        };
        let zb = b.depth.get(x, y).map_or(0.0, f64::from);
        let tol = REPEAT_MAX_OFFSET_M + 3.0 * camera.sensor.sigma_z(pb.z);
        if zb > 0.0 && (zb - pb.z).abs() <= tol {
            in_a.push(wa * p);
            in_b.push(wb * k.back_project(x as f64, y as f64, zb));
        }
    }
    if in_a.len() * 2 < total.max(1) {
        return None;
    }
    let world = |pts: &[Point3<f64>]| {
        fit_plane(pts).map(|f| WorldPlane {
            plane: f.plane,
            pixels: f.point_count,
            centroid: f.centroid,
            normal_sigma_deg: f64::NAN,
        })
    };
    Some((world(&in_a)?, world(&in_b)?))
}

#[cfg(test)]
mod tests {
    use super::*;
    use sl_core::Plane;
    use sl_core::nalgebra::{Isometry3, Vector3};

    /// A frame looking at the wall z = 2 m (world = camera of frame 0), labelled as one plane,
    /// from a camera moved by `shift_m` along x.
    fn wall_frame(camera: &Camera, shift_m: f64, bend_m: f64) -> PatchFrame {
        let k = &camera.intrinsics;
        let (w, h) = (k.width, k.height);
        let pose = CameraToWorld::from_isometry(Isometry3::translation(shift_m, 0.0, 0.0));
        // In this frame's camera the wall is still at z = 2 m (a sideways move); `bend_m` turns
        // it by adding depth proportional to x/z.
        let depth: Vec<f32> = (0..w * h)
            .map(|i| (2.0 + bend_m * ((i % w) as f64 - k.cx) / k.fx) as f32)
            .collect();
        let plane = Plane::new(Vector3::z(), -2.0).unwrap();
        PatchFrame {
            depth: DepthImage::from_vec(w, h, depth).unwrap(),
            labels: Image::from_vec(w, h, vec![1u16; w * h]).unwrap(),
            pose,
            planes: vec![WorldPlane {
                plane,
                pixels: w * h,
                centroid: Point3::new(shift_m, 0.0, 2.0),
                normal_sigma_deg: 0.1,
            }],
        }
    }

    #[test]
    fn the_same_wall_agrees_and_a_tilted_view_of_it_does_not() {
        let camera = Camera::preset("kinect-v1").unwrap();
        let a = wall_frame(&camera, 0.0, 0.0);
        let b = wall_frame(&camera, 0.1, 0.0);
        let mut s = SamePatch::default();
        s.add(&a, &b, &camera);
        assert_eq!((s.planes, s.half_seen, s.agree, s.either), (1, 1, 1, 1));
        // Frame b's wall turned by about 3.4° (depth + 0.12 m per unit of x/z): the
        // visibility test sees about three quarters of it, the 3° rule refuses it.
        let bent = wall_frame(&camera, 0.1, 0.12);
        let mut s = SamePatch::default();
        s.add(&a, &bent, &camera);
        assert_eq!((s.planes, s.half_seen, s.agree), (1, 1, 0), "{s:?}");
    }

    #[test]
    fn a_wall_out_of_view_is_not_half_seen() {
        let camera = Camera::preset("kinect-v1").unwrap();
        let a = wall_frame(&camera, 0.0, 0.0);
        let far = wall_frame(&camera, 3.0, 0.0);
        let mut s = SamePatch::default();
        s.add(&a, &far, &camera);
        assert_eq!((s.planes, s.half_seen, s.agree), (1, 0, 0));
    }
}
