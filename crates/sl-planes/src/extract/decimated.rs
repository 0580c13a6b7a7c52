//! Frames of a sensor decimated by a whole factor (a 320×240 stream of a 640×480 Kinect,
//! `sl_core::Camera::resampled`): the extractor's scales — the LoG's, the 4×4 cells, the
//! 16-cell patches, `min_pixels` — are the sensor's, tuned and validated on its pixels, so
//! such a frame is replicated (nearest neighbour) back onto the sensor's grid, extracted there
//! and its labels sampled back.
//!
//! Why not run on the decimated pixels: there every scale covers `n²` times the solid angle,
//! a real surface's curvature and the Kinect's low-frequency distortion bend the disparity
//! `n²` times as much per pixel², and the LoG (already at its smallest box, one pixel) rejects
//! most of a real frame — TUM's desk frame 120 gave 4 planes instead of 16, person-depth.png 2
//! instead of 14. Replication is exact for the LoG's half-resolution map at `n = 2` (a block of
//! four equal pixels averages to the decimated pixel) and keeps every plane's disparity affine
//! on the sensor's grid up to the replication steps; the cost is that of a frame at the
//! sensor's resolution.

use super::*;

/// Largest decimation factor handled on the sensor's grid (the CLI's range).
const MAX_FACTOR: usize = 8;
/// Most pixels of the sensor-grid frame (4096 × 4096, the CLI's default image limit): a larger
/// one is extracted on the frame's own pixels rather than allocated.
const MAX_SENSOR_PIXELS: usize = 4096 * 4096;

impl PlaneExtractor {
    /// The whole factor `n` (2–[`MAX_FACTOR`]) by which `camera`'s `w × h` frames are its sensor
    /// decimated (`pixels_per_sensor_pixel` = 1/n within 1 %), when the sensor-grid frame stays
    /// within [`MAX_SENSOR_PIXELS`]; `None` for a camera at its sensor's resolution.
    pub(super) fn sensor_factor(camera: &Camera, w: usize, h: usize) -> Option<usize> {
        let s = camera.pixels_per_sensor_pixel();
        if s >= 1.0 {
            return None;
        }
        let n = (1.0 / s).round();
        if !(2.0..=MAX_FACTOR as f64).contains(&n) || (n * s - 1.0).abs() > 0.01 {
            return None;
        }
        let n = n as usize;
        let pixels = w.checked_mul(h)?.checked_mul(n * n)?;
        (pixels <= MAX_SENSOR_PIXELS).then_some(n)
    }

    /// Runs `extract` (the depth or the disparity path on the frame's own pixels) on the
    /// `w × h` map `data` of `camera`, on the sensor's grid when the camera is its sensor
    /// decimated ([`PlaneExtractor::sensor_factor`]), and returns the frame's segmentation.
    ///
    /// With more than one thread, the extraction runs on a worker of the caller's rayon pool
    /// (called from outside every pool: on a worker of the global pool while the caller waits,
    /// once), so that its parallel final pass splits on the spot instead of queueing for the
    /// pool (see ARCHITECTURE.md, "One parallelism policy"). With one thread it runs on the
    /// calling thread.
    pub(super) fn extract_on_sensor_grid(
        &mut self,
        data: &[f32],
        w: usize,
        h: usize,
        camera: &Camera,
        extract: fn(&mut Self, &[f32], usize, usize, &Camera) -> Result<PlaneSegmentation>,
    ) -> Result<PlaneSegmentation> {
        let here = |this: &mut Self| -> Result<PlaneSegmentation> {
            Self::check(w, h, &camera.intrinsics)?;
            this.sensor_grid = None;
            let Some(n) = Self::sensor_factor(camera, w, h) else {
                return extract(this, data, w, h, camera);
            };
            let mut grid = std::mem::take(&mut this.sensor_grid_input);
            Self::replicate(data, w, h, n, &mut grid);
            this.rows = RowCentres::replicated(n);
            let seg = camera
                .resampled(n as f64)
                .map_err(PlanesError::from)
                .and_then(|sensor| extract(this, &grid, w * n, h * n, &sensor));
            this.rows = RowCentres::default();
            this.sensor_grid_input = grid;
            this.sample_back_to_frame(seg?, n, w, h)
        };
        if rayon::current_num_threads() > 1 {
            return rayon::scope(|_| here(self));
        }
        here(self)
    }

    /// Replicates each value of the `w × h` map `src` over `n × n` pixels into `out`.
    pub(super) fn replicate(src: &[f32], w: usize, h: usize, n: usize, out: &mut Vec<f32>) {
        out.clear();
        out.reserve(w * h * n * n);
        for row in src.chunks_exact(w).take(h) {
            let start = out.len();
            for &v in row {
                out.extend(std::iter::repeat_n(v, n));
            }
            for _ in 1..n {
                out.extend_from_within(start..start + w * n);
            }
        }
    }

    /// The segmentation `seg` of the sensor-grid frame (`n` times the frame's size, intrinsics
    /// `camera.intrinsics.scaled(n)`) as a segmentation of the frame: each frame pixel takes the
    /// label of the centre of its `n × n` block; pixel counts are recounted (planes left with
    /// none are dropped, the rest renumbered by decreasing size); the affine functions are
    /// rewritten in the frame's pixels (`x_sensor = n·x + (n − 1)/2`, the pixel-centre
    /// convention of [`Intrinsics::scaled`]); the 3D planes, centroids and RMS residuals are the
    /// sensor grid's. The sensor-grid labels are kept for
    /// [`PlaneExtractor::explain_unlabelled`].
    pub(super) fn sample_back_to_frame(
        &mut self,
        seg: PlaneSegmentation,
        n: usize,
        w: usize,
        h: usize,
    ) -> Result<PlaneSegmentation> {
        let (ws, _) = seg.labels.dimensions();
        let src = seg.labels.data();
        let mut labels = Vec::with_capacity(w * h);
        for y in 0..h {
            let row = &src[(y * n + n / 2) * ws..];
            labels.extend((0..w).map(|x| row[x * n + n / 2]));
        }
        // Ids are 1..=planes.len() (`finish`); a label beyond them would count as none.
        let mut counts = vec![0usize; seg.planes.len() + 1];
        for &l in &labels {
            if let Some(c) = counts.get_mut(usize::from(l)) {
                *c += 1;
            }
        }
        let count = |id: u16| counts.get(usize::from(id)).copied().unwrap_or(0);
        let mut planes: Vec<PlaneInfo> = seg
            .planes
            .iter()
            .filter(|p| p.id != 0 && count(p.id) > 0)
            .map(|p| {
                let (a, b) = (p.affine.a, p.affine.b);
                let half = (n as f64 - 1.0) / 2.0;
                PlaneInfo {
                    affine: DisparityAffine {
                        a: a * n as f64,
                        b: b * n as f64,
                        c: p.affine.c + (a + b) * half,
                    },
                    pixels: count(p.id),
                    ..*p
                }
            })
            .collect();
        // Stable: equal counts keep the sensor grid's order.
        planes.sort_by_key(|p| std::cmp::Reverse(p.pixels));
        let mut lut = vec![0u16; seg.planes.len() + 1];
        for (i, p) in planes.iter_mut().enumerate() {
            if let Some(slot) = lut.get_mut(usize::from(p.id)) {
                *slot = i as u16 + 1;
            }
            p.id = i as u16 + 1;
        }
        for l in &mut labels {
            *l = lut.get(usize::from(*l)).copied().unwrap_or(0);
        }
        self.sensor_grid = Some((n, seg.labels));
        Ok(PlaneSegmentation {
            labels: Image::from_vec(w, h, labels)?,
            planes,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn replication_copies_each_value_over_its_block() {
        let mut out = Vec::new();
        PlaneExtractor::replicate(&[1.0, 2.0, 3.0, 4.0, 5.0, 6.0], 3, 2, 2, &mut out);
        assert_eq!(
            out,
            [
                1.0, 1.0, 2.0, 2.0, 3.0, 3.0, //
                1.0, 1.0, 2.0, 2.0, 3.0, 3.0, //
                4.0, 4.0, 5.0, 5.0, 6.0, 6.0, //
                4.0, 4.0, 5.0, 5.0, 6.0, 6.0,
            ]
        );
    }

    /// A floor 1 m below a Kinect streaming at 1/2 and 1/4 of its resolution, exact depth:
    /// the plane comes back where it is. Before the rows' centres were used, the sampled rows
    /// (the first of every replicated block) moved the fit by 1/4 and 3/8 of a frame row along
    /// the floor's disparity gradient (0.0375 px at the bottom row at 1/2, 0.2 % of the
    /// disparity), and the 3D plane with it.
    #[test]
    fn a_decimated_frame_gives_the_plane_where_it_is() {
        let height_m = 1.0;
        for n in [2usize, 4] {
            let cam = Camera::kinect_v1().resampled(1.0 / n as f64).unwrap();
            let k = cam.intrinsics;
            let (w, h) = (k.width, k.height);
            let z_at = |y: usize| {
                let t = (y as f64 - k.cy) / k.fy;
                let z = height_m / t;
                if t > 0.0 && z < 4.0 { z as f32 } else { 0.0 }
            };
            let depth: Vec<f32> = (0..h).flat_map(|y| (0..w).map(move |_| z_at(y))).collect();
            let view = DepthView::new(w, h, &depth).unwrap();
            let seg = PlaneExtractor::new(PlaneConfig::default())
                .unwrap()
                .extract_depth(view, &cam)
                .unwrap();
            let p = seg
                .planes
                .first()
                .unwrap_or_else(|| panic!("n = {n}: no plane"));
            // Disparity in the sensor's pixels (the frame's are `n` times larger).
            let fb = cam.sensor.fb();
            for (x, y) in [(w / 2, h - 1), (0, h - 5), (w - 1, h * 7 / 8)] {
                let truth = fb / f64::from(z_at(y));
                let got = p.affine.eval(x as f64, y as f64);
                assert!(
                    (got - truth).abs() < 1e-3,
                    "n = {n}, ({x}, {y}): {got} px, truth {truth}"
                );
            }
            let plane = p.plane.facing_origin();
            assert!(
                (plane.offset_m.abs() - height_m).abs() < 1e-4,
                "n = {n}: {plane:?}"
            );
            assert!(plane.normal.y.abs() > 1.0 - 1e-8, "n = {n}: {plane:?}");
            assert!(
                (p.centroid_m.y - height_m).abs() < 1e-4,
                "n = {n}: {:?}",
                p.centroid_m
            );
        }
    }

    #[test]
    fn only_whole_decimations_of_the_sensor_use_its_grid() {
        let cam = Camera::kinect_v1();
        let k = cam.intrinsics;
        assert_eq!(PlaneExtractor::sensor_factor(&cam, k.width, k.height), None);
        for n in [2usize, 3, 4, 8] {
            let c = cam.resampled(1.0 / n as f64).unwrap();
            let (w, h) = (c.intrinsics.width, c.intrinsics.height);
            assert_eq!(PlaneExtractor::sensor_factor(&c, w, h), Some(n));
        }
        // Not a whole factor, beyond the range, or finer than the sensor: the frame's pixels.
        for f in [0.75, 1.0 / 16.0, 2.0] {
            let c = cam.resampled(f).unwrap();
            let (w, h) = (c.intrinsics.width, c.intrinsics.height);
            assert_eq!(PlaneExtractor::sensor_factor(&c, w, h), None, "{f}");
        }
        // A sensor-grid frame beyond the pixel limit is not allocated.
        let c = cam.resampled(0.5).unwrap();
        assert_eq!(PlaneExtractor::sensor_factor(&c, 4096, 4096), None);
    }
}
