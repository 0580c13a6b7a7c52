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
//!
//! The planes the extractor misses although their patch agrees are the extractor's own
//! misses; they are counted by where most of the patch's seen pixels went in frame `i + k`:
//! into a plane with more pixels than the tested one (the patch was joined with another
//! surface, or with more of a bent one, and the union's fit fails the rule), into a plane with
//! no more pixels (it was cut differently: bands, or a piece of another split), or into no
//! plane at all.

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
    /// Planes whose patch agrees but the extractor did not find again, by where most of the
    /// seen pixels went in frame `i + k`.
    pub missed: MissedPatches,
}

/// The extractor's own misses (the patch agrees), by the label most of its seen pixels have in
/// frame `i + k`.
#[derive(Debug, Default, Clone, Copy)]
pub struct MissedPatches {
    /// A plane with more pixels than the tested plane.
    pub into_larger: usize,
    /// A plane with at most as many pixels.
    pub into_smaller: usize,
    /// No plane.
    pub unlabelled: usize,
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
                Some(fits) => {
                    self.half_seen += 1;
                    let agrees = same_plane(&fits.in_a, &fits.in_b.plane);
                    if agrees && !found {
                        let m = &mut self.missed;
                        match fits.majority_label.checked_sub(1).map(|l| b.planes.get(l)) {
                            Some(Some(q)) if q.pixels > p.pixels => m.into_larger += 1,
                            Some(Some(_)) => m.into_smaller += 1,
                            _ => m.unlabelled += 1,
                        }
                    }
                    agrees
                }
                None => false,
            };
            self.repeated += usize::from(found);
            self.agree += usize::from(agrees);
            self.either += usize::from(found || agrees);
        }
    }
}

/// A tested plane's patch: the fits of its seen pixels in both frames, and where they went.
struct PatchFits {
    /// The world-coordinate fit of the seen pixels in frame `a`.
    in_a: WorldPlane,
    /// The same in frame `b`.
    in_b: WorldPlane,
    /// The label most of the seen pixels have in frame `b` (0: none).
    majority_label: usize,
}

/// The world-coordinate fits of plane `id`'s pixels of frame `a` that frame `b` sees, in `a` and
/// in `b`, and the label most of them have in `b`; `None` when fewer than half are seen or a
/// fit is degenerate.
fn patch_fits(a: &PatchFrame, b: &PatchFrame, id: u16, camera: &Camera) -> Option<PatchFits> {
    let k = &camera.intrinsics;
    let (wa, wb) = (a.pose.isometry(), b.pose.isometry());
    let a_to_b = wb.inverse() * wa;
    let w = a.labels.width();
    let (mut in_a, mut in_b) = (Vec::new(), Vec::new());
    let mut total = 0usize;
    // Seen pixels per label of frame `b` (0 = none).
    let mut by_label = vec![0usize; b.planes.len() + 1];
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
            let l = b.labels.get(x, y).map_or(0, |&l| usize::from(l));
            if let Some(n) = by_label.get_mut(l) {
                *n += 1;
            }
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
    let majority_label = (0..by_label.len())
        .max_by_key(|&l| (by_label[l], std::cmp::Reverse(l)))
        .unwrap_or(0);
    Some(PatchFits {
        in_a: world(&in_a)?,
        in_b: world(&in_b)?,
        majority_label,
    })
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
    fn a_missed_patch_is_counted_by_where_its_pixels_went() {
        let camera = Camera::preset("kinect-v1").unwrap();
        let a = wall_frame(&camera, 0.0, 0.0);
        // Frame b sees the same wall, but its plane 1 is turned by 10° about the y axis: the
        // patch agrees, the extractor's plane does not.
        let turned = |pixels: usize| {
            let mut b = wall_frame(&camera, 0.1, 0.0);
            let n = Vector3::new(10f64.to_radians().sin(), 0.0, 10f64.to_radians().cos());
            b.planes[0].plane = Plane::new(n, -2.0 * n.z).unwrap();
            b.planes[0].pixels = pixels;
            b
        };
        let all = a.planes[0].pixels;
        for (b, want) in [
            (turned(all + 1), (1, 0, 0)),
            (turned(all), (0, 1, 0)),
            (
                {
                    let mut b = turned(all);
                    b.labels = b.labels.map(|_| 0);
                    b
                },
                (0, 0, 1),
            ),
        ] {
            let mut s = SamePatch::default();
            s.add(&a, &b, &camera);
            let m = s.missed;
            assert_eq!((s.agree, s.repeated), (1, 0), "{s:?}");
            assert_eq!((m.into_larger, m.into_smaller, m.unlabelled), want, "{s:?}");
        }
        // Found again: not a miss.
        let mut s = SamePatch::default();
        s.add(&a, &wall_frame(&camera, 0.1, 0.0), &camera);
        let m = s.missed;
        assert_eq!((m.into_larger, m.into_smaller, m.unlabelled), (0, 0, 0));
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
