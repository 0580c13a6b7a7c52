//! The fused model as the tracker's reference ([`ModelReference`]): after each tracked frame
//! the volume is raycast from the new pose, at a fraction of the camera's resolution, into the
//! [`ReferenceMaps`] the next frame is aligned to. The `sldepth track` command and the Python
//! `Tracker` share it, so both render the model the same way.

use rayon::prelude::*;
use sl_core::{Camera, CameraToWorld, DepthImage, Intrinsics, SensorModel};
use sl_tsdf::{Raycast, RaycastConfig, TsdfVolume};

use super::ReferenceMaps;
use crate::error::{Result, TrackError};

/// The raycast of the fused model that the next frame is tracked against, reusing its buffers
/// from frame to frame.
///
/// The reference need not have the frame's resolution: association projects each frame point
/// into the reference's own intrinsics, and the residual is measured to the reference point's
/// tangent plane, which a coarser raycast samples just as well on smooth surfaces. By default
/// ([`ModelReference::default_scale`]) the model is rendered at one pixel per
/// [`ModelReference::DEFAULT_PITCH_SENSOR_PX`] pixels of the sensor along each axis: a
/// structured-light camera's depth is a block-matching estimate over a window of about 9 × 11 of
/// its pixels (`docs/NOISE_MODEL.md`), so a frame holds no surface detail finer than that
/// window, and a pitch of 4 px samples what it does hold at its Nyquist rate. On the real
/// sequences the trajectories are as accurate as with a reference at the frame's resolution
/// and the raycast costs a small part of it (docs/bench/track.md).
#[derive(Debug, Clone)]
pub struct ModelReference {
    intrinsics: Intrinsics,
    config: RaycastConfig,
    raycast: Raycast,
    maps: ReferenceMaps,
    rendered: bool,
    /// The frame's nearest depth per reference pixel (see [`ModelReference::update_from_frame`]).
    hint: DepthImage,
}

impl ModelReference {
    /// Pixel pitch of the default rendering, pixels of the sensor: at most half the width of
    /// the window over which the sensor's depth is a block-matching average (9 × 11 px for a
    /// Kinect-class camera).
    pub const DEFAULT_PITCH_SENSOR_PX: f64 = 4.0;

    /// The default fraction of `camera`'s resolution the model is rendered at: one reference
    /// pixel per [`ModelReference::DEFAULT_PITCH_SENSOR_PX`] sensor pixels
    /// ([`Camera::pixels_per_sensor_pixel`]), at most the camera's own resolution — 0.25 for a
    /// 640×480 Kinect, 0.5 for its 320×240 stream (the same 160×120 rendering).
    pub fn default_scale(camera: &Camera) -> f64 {
        (1.0 / (Self::DEFAULT_PITCH_SENSOR_PX * camera.pixels_per_sensor_pixel())).min(1.0)
    }

    /// A reference for a camera with intrinsics `camera`, rendered at `scale` of its resolution
    /// (in `(0, 1]`), marching rays with `config`. Nothing is rendered until
    /// [`ModelReference::update`].
    ///
    /// # Errors
    /// `scale` outside `(0, 1]`, intrinsics that do not scale to at least one pixel, or an
    /// invalid `config`.
    pub fn new(camera: &Intrinsics, scale: f64, config: RaycastConfig) -> Result<Self> {
        if !(scale > 0.0 && scale <= 1.0) {
            return Err(TrackError::InvalidConfig(format!(
                "model reference scale {} must be in (0, 1]",
                sl_core::Compact(scale)
            )));
        }
        config.validate()?;
        let intrinsics = if scale == 1.0 {
            *camera
        } else {
            camera.scaled(scale).map_err(|e| {
                TrackError::InvalidConfig(format!(
                    "the model is rendered at {scale} of the camera's {}x{} pixels, which the \
                     camera cannot give ({e}): a larger camera or a model scale closer to 1",
                    camera.width, camera.height
                ))
            })?
        };
        Ok(Self {
            intrinsics,
            config,
            raycast: Raycast::default(),
            maps: ReferenceMaps::empty(&intrinsics),
            rendered: false,
            hint: DepthImage::invalid(intrinsics.width, intrinsics.height),
        })
    }

    /// Renders `volume` from `pose` into the reference maps, with model variances from the
    /// sensor model (see [`ReferenceMaps::set_from_model`]; `z_ref_m` is the volume's
    /// [`sl_tsdf::TsdfConfig::z_ref_m`]).
    ///
    /// # Errors
    /// A pose the raycast rejects (not finite, or beyond the volume's coordinate range).
    pub fn update(
        &mut self,
        volume: &TsdfVolume,
        pose: &CameraToWorld,
        sensor: &SensorModel,
    ) -> Result<()> {
        self.render(volume, pose, sensor, false)
    }

    /// [`ModelReference::update`] right after `depth` (the camera's size, metres, 0 = invalid)
    /// was fused from `pose`: the rays start just before the surface the frame saw
    /// ([`TsdfVolume::raycast_hinted_into`], with the nearest of the frame's depths that fall
    /// in each reference pixel), which skips most of their march through empty space. On the
    /// real sequences the raycast is about 30 % cheaper and the trajectories as accurate
    /// (docs/bench/track.md). Where the frame has no depth (its border, dark or grazing
    /// surfaces, occlusion bands), the hint is where the previous rendering's hits are seen
    /// from `pose`: the model's surface there barely moves in one frame, and those rays took
    /// over half of the march on TUM fr1/rpy (docs/bench/track.md, session 71). So render
    /// another volume (a new fragment, a reset model) with a new `ModelReference`: the hints
    /// would come from the old volume's hits.
    ///
    /// # Errors
    /// As [`ModelReference::update`], and `depth` not of the camera's size.
    pub fn update_from_frame(
        &mut self,
        volume: &TsdfVolume,
        pose: &CameraToWorld,
        sensor: &SensorModel,
        depth: &DepthImage,
        camera: &Intrinsics,
    ) -> Result<()> {
        if depth.width() != camera.width || depth.height() != camera.height {
            return Err(TrackError::SizeMismatch {
                expected_width: camera.width,
                expected_height: camera.height,
                width: depth.width(),
                height: depth.height(),
            });
        }
        nearest_per_pixel(depth, &mut self.hint);
        if self.rendered {
            warp_into_holes(&self.raycast, pose, &self.intrinsics, &mut self.hint);
        }
        self.render(volume, pose, sensor, true)
    }

    /// Raycasts `volume` from `pose` (hinted by `self.hint` when `hinted`) into the maps.
    fn render(
        &mut self,
        volume: &TsdfVolume,
        pose: &CameraToWorld,
        sensor: &SensorModel,
        hinted: bool,
    ) -> Result<()> {
        let z_ref_m = volume.params().z_ref_m;
        volume.raycast_hinted_into(
            pose,
            &self.intrinsics,
            &self.config,
            hinted.then_some(&self.hint),
            &mut self.raycast,
        )?;
        self.maps
            .set_from_model(&self.raycast, pose, &self.intrinsics, sensor, z_ref_m)?;
        self.rendered = true;
        Ok(())
    }

    /// The maps of the last [`ModelReference::update`], or `None` before the first.
    pub fn maps(&self) -> Option<&ReferenceMaps> {
        self.rendered.then_some(&self.maps)
    }

    /// The intrinsics the model is rendered with.
    pub fn intrinsics(&self) -> &Intrinsics {
        &self.intrinsics
    }

    /// The raycast of the last update (depth, points, normals, weights).
    pub fn raycast(&self) -> &Raycast {
        &self.raycast
    }
}

/// Fills `out` (its own size) with, per pixel, the smallest valid depth of `depth`'s pixels
/// that map into it (`x·out_w/in_w`, `y·out_h/in_h`, rounded down), 0 where none is valid.
fn nearest_per_pixel(depth: &DepthImage, out: &mut DepthImage) {
    let (iw, ih) = (depth.width(), depth.height());
    let (ow, oh) = (out.width(), out.height());
    let src = depth.data();
    out.data_mut()
        .par_chunks_mut(ow.max(1))
        .enumerate()
        .for_each(|(v, row)| {
            row.fill(f32::INFINITY);
            let rows = source_run(v, ih, oh);
            // Per output pixel, not per source pixel: two divisions for its run of columns.
            for (u, o) in row.iter_mut().enumerate() {
                let cols = source_run(u, iw, ow);
                for y in rows.clone() {
                    for &z in src
                        .get(y * iw + cols.start..y * iw + cols.end)
                        .unwrap_or(&[])
                    {
                        if z > 0.0 && z < *o {
                            *o = z;
                        }
                    }
                }
            }
            for o in row.iter_mut() {
                if !o.is_finite() {
                    *o = 0.0;
                }
            }
        });
}

/// Where `hint` has no depth (0), the nearest depth at which `last`'s hits (world points of
/// the previous rendering, at the same intrinsics `k`) are seen from `pose`, each at its nearest
/// pixel. The camera moves little between two frames, so a surface the model showed there
/// last time is where a ray of a pixel the frame left empty (its border, a dark or
/// grazing surface, an occlusion band) meets the model now; the ray starts just before it
/// instead of marching its whole range. As with any hint, a hint that is wrong costs steps
/// (the ray marches again from the near end), except one more than a band behind the surface
/// the ray should find: a model surface the previous view did not show and that now hides the
/// warped one would be passed through there (the frame has no depth to say otherwise).
/// [`crate::Reconstruction`] gives every fragment (every volume) its own reference.
fn warp_into_holes(last: &Raycast, pose: &CameraToWorld, k: &Intrinsics, hint: &mut DepthImage) {
    let (w, h) = (hint.width(), hint.height());
    if last.width != w || last.height != h {
        return;
    }
    let world_to_camera = pose.inverse();
    let iso = world_to_camera.isometry();
    let r = iso.rotation.to_rotation_matrix().into_inner().cast::<f32>();
    let t = iso.translation.vector.cast::<f32>();
    let (fx, fy, cx, cy) = (k.fx as f32, k.fy as f32, k.cx as f32, k.cy as f32);
    let out = hint.data_mut();
    // Negative: a warped depth (to tell it from the frame's own hints while taking minima).
    for (p, &z) in last.points.iter().zip(last.depth.data()) {
        if z <= 0.0 {
            continue;
        }
        let q = r * p.coords + t;
        if q.z.is_nan() || q.z <= 0.0 {
            continue;
        }
        // The nearest pixel (`u + 0.5` truncated, for `u > −0.5`; NaN fails the tests).
        let (u, v) = (fx * q.x / q.z + cx + 0.5, fy * q.y / q.z + cy + 0.5);
        let inside = u > 0.0 && v > 0.0 && u < w as f32 && v < h as f32;
        if let Some(o) = out.get_mut(v as usize * w + u as usize).filter(|_| inside)
            && (*o == 0.0 || (*o < 0.0 && -q.z > *o))
        {
            *o = -q.z;
        }
    }
    for o in out.iter_mut() {
        *o = o.abs();
    }
}

/// The source indices `i` (of `n_in`) with `⌊i·n_out/n_in⌋ = o`: a contiguous run, empty when
/// none maps there.
fn source_run(o: usize, n_in: usize, n_out: usize) -> std::ops::Range<usize> {
    let start = (o * n_in).div_ceil(n_out.max(1));
    let end = ((o + 1) * n_in).div_ceil(n_out.max(1)).min(n_in);
    start..end.max(start)
}

#[cfg(test)]
mod tests {
    use super::*;
    use sl_core::nalgebra::Point3;

    /// The default rendering has the same pixels whatever the sensor's decimation: one per
    /// 4×4 sensor pixels, never finer than the camera's own.
    #[test]
    fn the_default_scale_is_a_pitch_in_sensor_pixels() {
        let vga = Camera::kinect_v1();
        let rendered = |c: &Camera| {
            let k = c
                .intrinsics
                .scaled(ModelReference::default_scale(c))
                .unwrap();
            (k.width, k.height)
        };
        assert_eq!(ModelReference::default_scale(&vga), 0.25);
        for f in [0.5, 0.25] {
            assert_eq!(rendered(&vga.resampled(f).unwrap()), (160, 120), "{f}");
        }
        assert_eq!(
            ModelReference::default_scale(&vga.resampled(0.125).unwrap()),
            1.0
        );
    }

    /// The previous rendering's hits hint only the pixels the frame left empty, each with the
    /// nearest of the hits seen there from the new pose; hits behind the camera, outside the
    /// image or not finite hint nothing, and a rendering of another size is not used.
    #[test]
    fn warped_hits_fill_only_the_frame_holes_with_the_nearest() {
        let k = Intrinsics::new(4, 3, 4.0, 4.0, 1.5, 1.0).unwrap();
        let mut last = Raycast::default();
        last.width = 4;
        last.height = 3;
        // Hits in world coordinates (the previous camera at the origin); the new camera is
        // 0.25 m along x, so a hit at depth z moves `4 · 0.25 / z` px to the left, and lands on
        // the nearest pixel (`u = 4·x/z + 1.5`, `v = 4·y/z + 1`).
        let pts = [
            Point3::new(0.0f32, 0.0, 2.0),   // u = 1.0: pixel (1, 1) at 2 m
            Point3::new(0.25, 0.0, 1.0),     // u = 1.5: (2, 1) at 1 m
            Point3::new(0.75, 0.0, 2.0),     // u = 2.5: (3, 1) at 2 m
            Point3::new(0.5, 0.0, 3.0),      // u = 1.83: (2, 1) at 3 m, behind the 1 m hit
            Point3::new(0.0, 0.0, -1.0),     // behind the camera
            Point3::new(10.0, 0.0, 1.0),     // outside the image
            Point3::new(f32::NAN, 0.0, 1.0), // not finite
            Point3::new(0.25, -0.5, 2.0),    // (2, 0), where the frame has a depth
        ];
        let mut depth = vec![0.0f32; 12];
        let mut points = vec![Point3::new(f32::NAN, f32::NAN, f32::NAN); 12];
        for (i, p) in pts.iter().enumerate() {
            depth[i] = 1.0;
            points[i] = *p;
        }
        last.depth = DepthImage::from_vec(4, 3, depth).unwrap();
        last.points = points;
        let pose =
            CameraToWorld::from_isometry(sl_core::nalgebra::Isometry3::translation(0.25, 0.0, 0.0));
        let mut hint = DepthImage::invalid(4, 3);
        hint.data_mut()[2] = 1.7;
        warp_into_holes(&last, &pose, &k, &mut hint);
        let mut want = [0.0f32; 12];
        want[2] = 1.7;
        want[4 + 1] = 2.0;
        want[4 + 2] = 1.0;
        want[4 + 3] = 2.0;
        assert_eq!(hint.data(), &want[..]);
        // Another size: nothing is warped.
        let mut other = DepthImage::invalid(2, 2);
        warp_into_holes(&last, &pose, &k, &mut other);
        assert!(other.data().iter().all(|&z| z == 0.0));
    }

    /// Each reference pixel gets the nearest valid depth of the frame pixels that fall in it,
    /// 0 where none is valid; a frame of the reference's own size is copied.
    #[test]
    fn the_hint_is_the_nearest_valid_depth_per_pixel() {
        let src =
            DepthImage::from_vec(4, 2, vec![2.0, 1.5, 0.0, 0.0, 3.0, 0.0, 0.0, f32::NAN]).unwrap();
        let mut half = DepthImage::invalid(2, 1);
        nearest_per_pixel(&src, &mut half);
        assert_eq!(half.data(), &[1.5, 0.0]);
        let mut same = DepthImage::invalid(4, 2);
        nearest_per_pixel(&src, &mut same);
        assert_eq!(same.data(), &[2.0, 1.5, 0.0, 0.0, 3.0, 0.0, 0.0, 0.0]);
    }

    /// The column runs equal the definition (`⌊x·ow/iw⌋`, `⌊y·oh/ih⌋`, the smallest valid depth)
    /// for sizes that do and do not divide, smaller and larger than the frame.
    #[test]
    fn the_hint_matches_its_definition_at_any_pair_of_sizes() {
        let (iw, ih) = (23usize, 17usize);
        let data: Vec<f32> = (0..iw * ih)
            .map(|i| match i % 11 {
                0 => 0.0,
                5 => f32::NAN,
                7 => f32::INFINITY,
                _ => 0.5 + ((i * 37) % 101) as f32 * 0.03,
            })
            .collect();
        let src = DepthImage::from_vec(iw, ih, data.clone()).unwrap();
        for (ow, oh) in [
            (23, 17),
            (11, 8),
            (6, 4),
            (5, 3),
            (1, 1),
            (40, 30),
            (24, 18),
        ] {
            let mut want = vec![f32::INFINITY; ow * oh];
            for y in 0..ih {
                for x in 0..iw {
                    let z = data[y * iw + x];
                    let o = &mut want[(y * oh / ih) * ow + x * ow / iw];
                    if z > 0.0 && z < *o {
                        *o = z;
                    }
                }
            }
            want.iter_mut()
                .filter(|o| !o.is_finite())
                .for_each(|o| *o = 0.0);
            let mut got = DepthImage::invalid(ow, oh);
            nearest_per_pixel(&src, &mut got);
            assert_eq!(got.data(), &want[..], "{ow}×{oh}");
        }
    }
}
