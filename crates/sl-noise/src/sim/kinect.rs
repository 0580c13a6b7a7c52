//! The seeded Kinect sensor: ground-truth depth in, realistic quantised depth out.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use rayon::prelude::*;
use sl_core::{CameraToWorld, DepthImage, Image, Intrinsics, SensorModel};

use crate::sim::realistic::{self, RealisticNoise};
use crate::sim::scene::Scene;

/// Which disparity error the simulator draws.
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub enum NoiseModel {
    /// The paper's idealised model: independent Gaussian disparity noise per pixel, no
    /// occlusion bands (Algorithm 1 and the paper's experiments).
    White,
    /// A real Kinect: block-matching-correlated disparity error, occlusion bands, drop-outs
    /// (see [`crate::sim::realistic`]).
    Realistic(RealisticNoise),
}

impl Default for NoiseModel {
    fn default() -> Self {
        Self::Realistic(RealisticNoise::default())
    }
}

/// A structured-light depth sensor applied to exact depth.
///
/// **Noise models.** [`KinectSimulator::noise`] selects the realistic sensor
/// ([`NoiseModel::Realistic`], the default since issue 11: correlated block-matching error,
/// occlusion bands, drop-outs; see [`crate::sim::realistic`]) or the paper's idealised white
/// model ([`NoiseModel::White`], which everything that reproduces the paper asks for
/// explicitly). The rest of this description is the white model; the realistic one replaces
/// the per-pixel deviate `n` by a correlated field and adds invalid pixels.
///
/// Per valid pixel of true depth `Z₀`: disparity `D₀ = f·B/Z₀`, plus Gaussian noise
/// `σ_D·n` (n ~ N(0, 1)), quantised to `1/q` px (`D = round(q·(D₀ + σ_D·n))/q`), converted back
/// `Z = f·B/D`, rounded to `depth_step_m` (1 mm), set invalid (0) outside
/// `[min_depth_m, max_depth_m]` or for `D ≤ 0`, and dropped (0) with probability `dropout`.
///
/// Every output depth therefore lies on the representable set
/// `{round(f·B/(k/q) / step)·step : k = 1, 2, …}` (see [`KinectSimulator::representable_depths`]).
///
/// **Seeding.** Row `y` draws from `ChaCha8Rng::seed_from_u64(seed)` on stream `y`, two draws per
/// pixel (the normal deviate, then the dropout uniform) for every pixel, valid or not. The output
/// depends only on `(seed, truth)`: not on the number of threads, nor on which pixels are valid
/// elsewhere in the image.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct KinectSimulator {
    /// The disparity-domain sensor (f, B, q, σ_D).
    pub sensor: SensorModel,
    /// Nearest reported depth, metres (closer → 0).
    pub min_depth_m: f64,
    /// Farthest reported depth, metres (farther → 0).
    pub max_depth_m: f64,
    /// Fraction of valid pixels set invalid at random, in `[0, 1]`.
    pub dropout: f64,
    /// Rounding step of the output depth, metres (0 disables rounding).
    pub depth_step_m: f64,
    /// The disparity error model (realistic by default).
    pub noise: NoiseModel,
}

/// Nearest depth a Kinect v1 reports in default mode, metres.
pub const KINECT_MIN_DEPTH_M: f64 = 0.5;
/// Farthest depth the simulator reports by default, metres.
///
/// The Kinect v1 hardware returns disparities out to ~8–10 m, but beyond about 5 m the depth
/// step exceeds 7 cm and σ_Z several cm, and drivers commonly clip there; 5 m also keeps every
/// named scene (the `corridor` reaches 4.5 m) fully inside the range.
pub const KINECT_MAX_DEPTH_M: f64 = 5.0;

impl KinectSimulator {
    /// The `kinect-v1` sensor (f = 580 px, B = 0.075 m, q = 8, σ_D = 0.07 px), range
    /// 0.5–5 m, 1 mm output steps, **no random dropout** (`dropout = 0`), and the realistic
    /// noise model ([`NoiseModel::Realistic`] with [`RealisticNoise::default`]: the raw IR view
    /// with projector shadows, grazing-angle drop-outs and correlated error). Call
    /// [`KinectSimulator::white`] for the paper's model, whose invalid pixels come only from the
    /// range limits and the background.
    pub fn kinect_v1() -> Self {
        Self::with_sensor(SensorModel::kinect_v1())
    }

    /// The paper's Kinect (f = 587 px), otherwise as [`KinectSimulator::kinect_v1`].
    pub fn paper_kinect() -> Self {
        Self::with_sensor(SensorModel::paper_kinect())
    }

    /// Defaults of [`KinectSimulator::kinect_v1`] around another sensor model.
    pub fn with_sensor(sensor: SensorModel) -> Self {
        Self {
            sensor,
            min_depth_m: KINECT_MIN_DEPTH_M,
            max_depth_m: KINECT_MAX_DEPTH_M,
            dropout: 0.0,
            depth_step_m: 0.001,
            noise: NoiseModel::default(),
        }
    }

    /// The same simulator with another noise model.
    pub fn with_noise(self, noise: NoiseModel) -> Self {
        Self { noise, ..self }
    }

    /// The same simulator with the paper's white noise ([`NoiseModel::White`]).
    pub fn white(self) -> Self {
        self.with_noise(NoiseModel::White)
    }

    /// The measured depth (metres, 0 = invalid) for a true depth and a standard-normal deviate
    /// `n` (the deterministic part of [`KinectSimulator::apply`], without dropout).
    pub fn measure(&self, z_true_m: f64, n: f64) -> f64 {
        if !(z_true_m > 0.0 && z_true_m.is_finite()) {
            return 0.0;
        }
        let fb = self.sensor.fb();
        let q = f64::from(self.sensor.subpixel_steps.max(1));
        let d = fb / z_true_m + self.sensor.sigma_d_px * n;
        let dq = (d * q).round() / q;
        if !(dq > 0.0 && fb.is_finite() && fb > 0.0) {
            return 0.0;
        }
        let z = self.round_depth(fb / dq);
        if z < self.min_depth_m || z > self.max_depth_m || !z.is_finite() {
            0.0
        } else {
            z
        }
    }

    /// Rounds a depth to the output step (no-op when the step is not positive).
    pub fn round_depth(&self, z_m: f64) -> f64 {
        let s = self.depth_step_m;
        if s > 0.0 && s.is_finite() {
            (z_m / s).round() * s
        } else {
            z_m
        }
    }

    /// Every depth the sensor can report inside its range, ascending (`k/q` disparities mapped
    /// through `Z = f·B/D` and the depth rounding; duplicates after rounding removed).
    pub fn representable_depths(&self) -> Vec<f64> {
        let fb = self.sensor.fb();
        let q = f64::from(self.sensor.subpixel_steps.max(1));
        if !(fb > 0.0
            && fb.is_finite()
            && self.min_depth_m > 0.0
            && self.max_depth_m >= self.min_depth_m)
        {
            return Vec::new();
        }
        // Disparity indices k with Z in range (one extra on each side, the rounding decides).
        let k_lo = ((fb * q / (self.max_depth_m * 1.01)).floor() as u64).max(1);
        let k_hi = (fb * q / (self.min_depth_m * 0.99)).ceil() as u64;
        let mut out: Vec<f64> = (k_lo..=k_hi)
            .map(|k| self.round_depth(fb * q / k as f64))
            .filter(|z| *z >= self.min_depth_m && *z <= self.max_depth_m)
            .collect();
        out.sort_by(f64::total_cmp);
        out.dedup();
        out
    }

    /// Applies the sensor to exact depth `truth` (0 = nothing seen) with the given seed.
    ///
    /// With the realistic model this draws the correlated disparity error and invalidates the
    /// pixels at depth discontinuities; occlusion bands and grazing-angle drop-outs need the
    /// scene and its normals, which only [`KinectSimulator::simulate`] has.
    ///
    /// Every pixel of `truth` is taken as one of the sensor's: σ_D, the disparity step and the
    /// realistic model's correlation window are laid on `truth`'s own pixels. A stream of the
    /// sensor decimated by `n` (`sl_core::Camera::resampled`, a 320×240 Kinect) is simulated
    /// faithfully at the sensor's resolution and then averaged over `n × n` blocks; simulated
    /// on the decimated image itself, its error is correlated over `n` times the sensor's window
    /// in each direction and never averaged (docs/bench/track.md, session 56: a tracker's steps
    /// 2–4 σ off on such frames, within their σ on averaged ones).
    pub fn apply(&self, truth: &DepthImage, seed: u64) -> DepthImage {
        match self.noise {
            NoiseModel::White => self.apply_white(truth, seed),
            NoiseModel::Realistic(cfg) => self.apply_realistic(truth, seed, &cfg),
        }
    }

    fn apply_realistic(&self, truth: &DepthImage, seed: u64, cfg: &RealisticNoise) -> DepthImage {
        let (w, h) = (truth.width(), truth.height());
        let field =
            realistic::correlated_field(w, h, cfg.window_x, cfg.window_y, cfg.speckle_px, seed);
        let fb = self.sensor.fb();
        let edges = realistic::edge_mask(truth, fb, cfg.edge_px, cfg.edge_jump_px);
        let (cx, cy) = ((w as f64 - 1.0) / 2.0, (h as f64 - 1.0) / 2.0);
        let r2_corner = (cx * cx + cy * cy).max(1.0);
        let mut out = vec![0.0f32; w * h];
        if w > 0 {
            out.par_chunks_mut(w)
                .zip(truth.data().par_chunks(w))
                .enumerate()
                .for_each(|(y, (orow, trow))| {
                    let mut rng = ChaCha8Rng::seed_from_u64(seed);
                    rng.set_stream((2u64 << 32) + y as u64);
                    for (x, (o, &z)) in orow.iter_mut().zip(trow).enumerate() {
                        let i = y * w + x;
                        let u: f64 = if self.dropout > 0.0 {
                            rng.random()
                        } else {
                            1.0
                        };
                        if edges[i] || u < self.dropout {
                            continue;
                        }
                        let dx = x as f64 - cx;
                        let dy = y as f64 - cy;
                        let bias = cfg.distortion_px * (dx * dx + dy * dy) / r2_corner;
                        let n = f64::from(field[i]) + bias / self.sensor.sigma_d_px.max(1e-12);
                        let n = if self.sensor.sigma_d_px > 0.0 { n } else { 0.0 };
                        let m = if self.sensor.sigma_d_px > 0.0 {
                            self.measure(f64::from(z), n)
                        } else {
                            self.measure_biased(f64::from(z), bias)
                        };
                        *o = m as f32;
                    }
                });
        }
        DepthImage::from_vec(w, h, out).unwrap_or_else(|_| DepthImage::invalid(w, h))
    }

    /// [`KinectSimulator::measure`] with a disparity bias instead of noise.
    fn measure_biased(&self, z_true_m: f64, bias_px: f64) -> f64 {
        if !(z_true_m > 0.0 && z_true_m.is_finite()) {
            return 0.0;
        }
        let fb = self.sensor.fb();
        if !(fb > 0.0 && fb.is_finite()) {
            return 0.0;
        }
        let z_biased = fb / (fb / z_true_m + bias_px);
        Self {
            sensor: SensorModel {
                sigma_d_px: 0.0,
                ..self.sensor
            },
            ..*self
        }
        .measure(if z_biased > 0.0 { z_biased } else { 0.0 }, 0.0)
    }

    fn apply_white(&self, truth: &DepthImage, seed: u64) -> DepthImage {
        let w = truth.width();
        let h = truth.height();
        let mut out = vec![0.0f32; w * h];
        if w > 0 {
            out.par_chunks_mut(w)
                .zip(truth.data().par_chunks(w))
                .enumerate()
                .for_each(|(y, (orow, trow))| {
                    let mut rng = ChaCha8Rng::seed_from_u64(seed);
                    rng.set_stream(y as u64);
                    for (o, &z) in orow.iter_mut().zip(trow) {
                        let n: f64 = rng.sample(StandardNormal);
                        let u: f64 = rng.random();
                        let m = self.measure(f64::from(z), n);
                        *o = if u < self.dropout { 0.0 } else { m as f32 };
                    }
                });
        }
        // The buffer has exactly w·h values, so from_vec cannot fail.
        DepthImage::from_vec(w, h, out).unwrap_or_else(|_| DepthImage::invalid(w, h))
    }

    /// [`KinectSimulator::simulate`] after checking the image size against
    /// [`crate::sim::MAX_RENDER_PIXELS`]: use it when the intrinsics come from outside.
    pub fn try_simulate(
        &self,
        scene: &Scene,
        k: &Intrinsics,
        camera_to_world: &CameraToWorld,
        seed: u64,
    ) -> crate::Result<SimulatedFrame> {
        crate::sim::scene::check_render_size(k)?;
        Ok(self.simulate(scene, k, camera_to_world, seed))
    }

    /// Renders `scene` through `k` from `camera_to_world` and applies the sensor (no size
    /// check: see [`KinectSimulator::try_simulate`]). `k` is taken as the sensor's own pixels
    /// (see [`KinectSimulator::apply`] for a decimated stream).
    pub fn simulate(
        &self,
        scene: &Scene,
        k: &Intrinsics,
        camera_to_world: &CameraToWorld,
        seed: u64,
    ) -> SimulatedFrame {
        let render = scene.render(k, camera_to_world);
        let mut depth = self.apply(&render.depth, seed);
        if let NoiseModel::Realistic(cfg) = self.noise {
            self.invalidate_unmeasurable(scene, k, camera_to_world, &render, &cfg, &mut depth);
        }
        SimulatedFrame {
            truth: render.depth,
            depth,
            labels: render.labels,
            normals: render.normals,
        }
    }
}

impl KinectSimulator {
    /// The realistic model's occlusion bands and drop-outs: points the projector cannot
    /// light, points the IR camera cannot see (registered frames), surfaces seen at grazing
    /// angles and, when `min_return` is set, surfaces that return too little of the pattern
    /// (dark or far) are set invalid. Candidates are found by marching along the rows of the
    /// exact depth (the epipolar lines, O(pixels)); only they get an exact scene ray test, as in
    /// [`KinectSimulator::projector_shadows`].
    fn invalidate_unmeasurable(
        &self,
        scene: &Scene,
        k: &Intrinsics,
        camera_to_world: &CameraToWorld,
        render: &crate::sim::Render,
        cfg: &RealisticNoise,
        depth: &mut DepthImage,
    ) {
        let b_rgb = cfg.registration_baseline_m;
        let mut masks: Vec<Vec<bool>> = Vec::new();
        if cfg.projector_shadows {
            let mut shadow = realistic::hidden_from(
                scene,
                k,
                camera_to_world,
                &render.depth,
                self.sensor.baseline_m - b_rgb,
            );
            realistic::fill_shadow_edges(&mut shadow, depth, &render.depth, cfg.shadow_fill_px);
            masks.push(shadow);
        }
        if b_rgb != 0.0 {
            masks.push(realistic::hidden_from(
                scene,
                k,
                camera_to_world,
                &render.depth,
                -b_rgb,
            ));
        }
        masks.push(realistic::grazing_mask(
            k,
            &render.normals,
            cfg.max_incidence_deg,
        ));
        if cfg.min_return > 0.0 {
            masks.push(realistic::weak_return_mask(
                k,
                render,
                scene,
                cfg.min_return,
            ));
        }
        for m in &masks {
            for (z, hidden) in depth.data_mut().iter_mut().zip(m) {
                if *hidden {
                    *z = 0.0;
                }
            }
        }
    }

    /// The projector shadow mask: `true` where the scene point seen at a pixel (from the exact
    /// depth `truth`, rendered through `k` from `camera_to_world`) is hidden from the projector.
    /// A structured-light camera cannot measure such points — they are the invalid bands a
    /// Kinect shows beside foreground objects.
    ///
    /// The projector sits `B` (the sensor's baseline) along the camera's +x axis (image right,
    /// as on the Kinect v1, whose shadows fall on the left of objects). Rows run in parallel.
    pub fn projector_shadows(
        &self,
        scene: &Scene,
        k: &Intrinsics,
        camera_to_world: &CameraToWorld,
        truth: &DepthImage,
    ) -> Image<bool> {
        let (w, h) = (truth.width(), truth.height());
        let mut mask = vec![false; w * h];
        let projector =
            camera_to_world.isometry() * nalgebra::Point3::new(self.sensor.baseline_m, 0.0, 0.0);
        if w > 0 {
            mask.par_chunks_mut(w)
                .zip(truth.data().par_chunks(w))
                .enumerate()
                .for_each(|(y, (mrow, trow))| {
                    for (x, (m, &z)) in mrow.iter_mut().zip(trow).enumerate() {
                        if !(z > 0.0 && z.is_finite()) {
                            continue;
                        }
                        let p = camera_to_world.isometry()
                            * k.back_project(x as f64, y as f64, f64::from(z));
                        let dir = p - projector;
                        // Hidden when something lies between the projector and the point (the
                        // tolerance ignores the point's own surface).
                        let tol = 1e-6 + 1e-4 / dir.norm().max(1e-9);
                        *m = scene
                            .trace(&projector, &dir)
                            .is_some_and(|(_, hit)| hit.t < 1.0 - tol);
                    }
                });
        }
        Image::from_vec(w, h, mask).unwrap_or_else(|_| Image::filled(w, h, false))
    }

    /// [`KinectSimulator::simulate`] plus projector shadows: shadowed pixels are invalid (0) in
    /// `depth` (the truth and labels are unchanged).
    pub fn simulate_with_shadows(
        &self,
        scene: &Scene,
        k: &Intrinsics,
        camera_to_world: &CameraToWorld,
        seed: u64,
    ) -> SimulatedFrame {
        let mut frame = self.simulate(scene, k, camera_to_world, seed);
        let mask = self.projector_shadows(scene, k, camera_to_world, &frame.truth);
        for (z, shadow) in frame.depth.data_mut().iter_mut().zip(mask.data()) {
            if *shadow {
                *z = 0.0;
            }
        }
        frame
    }
}

impl Default for KinectSimulator {
    fn default() -> Self {
        Self::kinect_v1()
    }
}

/// One simulated frame: the exact depth, what the sensor reports, and the ground-truth labels.
#[derive(Debug, Clone, PartialEq)]
pub struct SimulatedFrame {
    /// Exact depth `Z` (metres, 0 = background).
    pub truth: DepthImage,
    /// The simulated sensor output (metres, 0 = invalid).
    pub depth: DepthImage,
    /// Surface label per pixel (0 = background), from the exact render.
    pub labels: Image<u16>,
    /// Exact unit normals in the camera frame, facing the camera (`[0, 0, 0]` = background).
    pub normals: Image<[f32; 3]>,
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::primitives::Plane;
    use nalgebra::{Point3, Vector3};

    fn ramp(w: usize, h: usize) -> DepthImage {
        let data = (0..w * h)
            .map(|i| 0.45 + 4.7 * i as f32 / (w * h) as f32)
            .collect();
        DepthImage::from_vec(w, h, data).unwrap()
    }

    #[test]
    fn output_is_on_the_representable_set() {
        let sim = KinectSimulator::kinect_v1().white();
        let out = sim.apply(&ramp(200, 100), 7);
        let fb = sim.sensor.fb();
        let mut valid = 0;
        for &z in out.data() {
            if z == 0.0 {
                continue;
            }
            valid += 1;
            let z = f64::from(z);
            assert!((0.5..=5.0).contains(&z));
            let k0 = (fb * 8.0 / z).round() as i64;
            let on_set = (k0 - 2..=k0 + 2).any(|k| {
                let zk = ((fb / (k as f64 / 8.0)) / 0.001).round() * 0.001;
                (zk - z).abs() < 1e-6
            });
            assert!(on_set, "{z} is not representable");
        }
        assert!(valid > 18_000);
        // And the set helper agrees with itself.
        let set = sim.representable_depths();
        assert!(set.windows(2).all(|w| w[0] < w[1]));
        for &z in out.data().iter().filter(|z| **z > 0.0) {
            let z = f64::from(z);
            let i = set.partition_point(|s| *s < z - 1e-6);
            assert!((set[i] - z).abs() < 1e-6);
        }
    }

    #[test]
    fn seed_reproducibility_and_independence() {
        let sim = KinectSimulator {
            dropout: 0.02,
            ..KinectSimulator::kinect_v1().white()
        };
        let truth = ramp(64, 48);
        let a = sim.apply(&truth, 42);
        let b = sim.apply(&truth, 42);
        assert_eq!(a, b);
        let c = sim.apply(&truth, 43);
        assert_ne!(a, c);
        // Row independence: a single-row image reproduces row 0 of the full one.
        let row0 = DepthImage::from_vec(64, 1, truth.data()[..64].to_vec()).unwrap();
        assert_eq!(sim.apply(&row0, 42).data(), &a.data()[..64]);
        // Same result on a one-thread pool.
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap();
        let d = pool.install(|| sim.apply(&truth, 42));
        assert_eq!(a, d);
    }

    #[test]
    fn range_limits_dropout_and_noise_level() {
        let sim = KinectSimulator {
            dropout: 0.1,
            ..KinectSimulator::kinect_v1().white()
        };
        let truth = DepthImage::from_vec(100, 100, vec![2.0; 10_000]).unwrap();
        let out = sim.apply(&truth, 1);
        let invalid = out.data().iter().filter(|z| **z == 0.0).count();
        assert!((800..1200).contains(&invalid), "{invalid} dropped of 10000");
        // σ_Z = Z²σ_D/(fB) ≈ 6.4 mm at 2 m (plus quantisation).
        let v: Vec<f64> = out
            .data()
            .iter()
            .filter(|z| **z > 0.0)
            .map(|z| f64::from(*z))
            .collect();
        let mean = v.iter().sum::<f64>() / v.len() as f64;
        let sd = (v.iter().map(|z| (z - mean).powi(2)).sum::<f64>() / v.len() as f64).sqrt();
        let expected =
            (sim.sensor.sigma_z(2.0).powi(2) + sim.sensor.depth_step_m(2.0).powi(2) / 12.0).sqrt();
        assert!(
            (sd / expected - 1.0).abs() < 0.1,
            "sd {sd} expected {expected}"
        );
        assert!((mean - 2.0).abs() < 0.002);
        // Out of range.
        let near_far = DepthImage::from_vec(3, 1, vec![0.3, 7.0, 0.0]).unwrap();
        assert!(
            KinectSimulator::kinect_v1()
                .white()
                .apply(&near_far, 3)
                .data()
                .iter()
                .all(|z| *z == 0.0)
        );
    }

    #[test]
    fn projector_shadow_band_left_of_an_object() {
        // A board at 1 m covering the right half, a wall at 2 m: the wall pixels hidden from the
        // projector (B to the right) form a band left of the board, as wide as the disparity
        // difference f·B/1 − f·B/2 = 21.75 px at f = 580.
        let k = Intrinsics::kinect_v1();
        let mut scene = Scene::new();
        scene.add(Plane::new(Point3::new(0.0, 0.0, 2.0), Vector3::z()).unwrap());
        let board = crate::sim::Quad::new(
            Point3::new(1.0, 0.0, 1.0),
            Vector3::new(1.0, 0.0, 0.0),
            Vector3::new(0.0, 2.0, 0.0),
        )
        .unwrap();
        scene.add(board);
        let sim = KinectSimulator::kinect_v1().white();
        let f = sim.simulate_with_shadows(&scene, &k, &CameraToWorld::identity(), 3);
        let mask = sim.projector_shadows(&scene, &k, &CameraToWorld::identity(), &f.truth);
        for y in [0, 100, 240, 479] {
            let row: Vec<usize> = (0..640).filter(|x| *mask.get(*x, y).unwrap()).collect();
            assert!(
                (21..=22).contains(&row.len()),
                "row {y}: {} shadowed",
                row.len()
            );
            // The band ends where the board starts (x > cx).
            assert_eq!(*row.last().unwrap(), 319);
            assert!(row.iter().all(|x| f.depth.get(*x, y) == Some(0.0)));
        }
        // Nothing else is invalid.
        assert_eq!(
            f.depth.valid_count(),
            640 * 480 - mask.data().iter().filter(|m| **m).count()
        );
    }

    #[test]
    fn simulate_keeps_truth_and_labels() {
        let k = Intrinsics::new(40, 30, 35.0, 35.0, 19.5, 14.5).unwrap();
        let mut scene = Scene::new();
        scene.add(Plane::new(Point3::new(0.0, 0.0, 1.5), Vector3::z()).unwrap());
        let sim = KinectSimulator::kinect_v1().white();
        let f = sim.simulate(&scene, &k, &CameraToWorld::identity(), 5);
        assert!(f.truth.data().iter().all(|z| (*z - 1.5).abs() < 1e-6));
        assert!(f.labels.data().iter().all(|l| *l == 1));
        assert_eq!(f.depth, sim.apply(&f.truth, 5));
        // Noise-free sensor: depth is the truth quantised, within half a disparity step.
        let exact = KinectSimulator {
            sensor: SensorModel {
                sigma_d_px: 0.0,
                ..sim.sensor
            },
            ..sim
        };
        let g = exact.simulate(&scene, &k, &CameraToWorld::identity(), 5);
        let half_step = sim.sensor.depth_step_m(1.5) / 2.0 + 0.0005;
        assert!(
            g.depth
                .data()
                .iter()
                .all(|z| (f64::from(*z) - 1.5).abs() <= half_step)
        );
    }

    fn realistic_sim() -> KinectSimulator {
        KinectSimulator::kinect_v1()
    }

    fn board_before_wall(zf: f64, zb: f64) -> Scene {
        let mut scene = Scene::new();
        scene.add(Plane::new(Point3::new(0.0, 0.0, zb), Vector3::z()).unwrap());
        scene.add(
            crate::sim::Quad::new(
                Point3::new(0.0, 0.0, zf),
                Vector3::new(0.15, 0.0, 0.0),
                Vector3::new(0.0, 2.0, 0.0),
            )
            .unwrap(),
        );
        scene
    }

    #[test]
    fn realistic_is_the_default_and_deterministic_for_any_thread_count() {
        assert!(matches!(
            KinectSimulator::default().noise,
            NoiseModel::Realistic(_)
        ));
        let ns = crate::sim::named_scene("figure-walls").unwrap();
        let k = ns.intrinsics.scaled(0.5).unwrap();
        let sim = realistic_sim();
        let a = sim.simulate(&ns.scene, &k, &ns.pose, 9);
        let one = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap()
            .install(|| sim.simulate(&ns.scene, &k, &ns.pose, 9));
        assert_eq!(a, one);
        assert_ne!(a.depth, sim.simulate(&ns.scene, &k, &ns.pose, 10).depth);
        // Valid realistic output stays on the sensor's representable set.
        let set = sim.representable_depths();
        for &z in a.depth.data().iter().filter(|z| **z > 0.0) {
            let z = f64::from(z);
            let i = set.partition_point(|s| *s < z - 1e-6);
            assert!((set[i] - z).abs() < 1e-6, "{z}");
        }
    }

    #[test]
    fn realistic_error_is_correlated_and_white_is_not() {
        // A floor: the residual of the realistic model is shared by neighbours, the white
        // model's is not; both have σ_D near the sensor's (plus quantisation).
        let ns = crate::sim::named_scene("floor").unwrap();
        let (k, pose) = (ns.intrinsics, ns.pose);
        let opts = crate::stats::NoiseStatsConfig::default();
        let stats = |sim: &KinectSimulator| {
            let f = sim.simulate(&ns.scene, &k, &pose, 4);
            crate::stats::noise_stats(&f.depth, sim.sensor.fb(), &f.labels, &opts).unwrap()
        };
        let real = stats(&realistic_sim());
        let white = stats(&KinectSimulator::kinect_v1().white());
        let (rx, ry) = real.acf_at(1).unwrap();
        let (wx, wy) = white.acf_at(1).unwrap();
        assert!(rx > 0.5 && ry > 0.5, "realistic ρ(1) = {rx}, {ry}");
        assert!(wx.abs() < 0.2 && wy.abs() < 0.2, "white ρ(1) = {wx}, {wy}");
        for s in [&real, &white] {
            assert!((0.06..0.1).contains(&s.sigma_d_px), "σ_D {}", s.sigma_d_px);
        }
        // Terraces: wider with the correlated error.
        assert!(real.terraces.widths.mean_px > white.terraces.widths.mean_px);
    }

    #[test]
    fn occlusion_bands_follow_the_geometry() {
        // Board at 1 m before a wall at 2 m: the projector shadow is f·B·(1/1 − 1/2) = 21.75 px
        // on the left of the board, minus the filled pixels; no band on the right of a raw IR
        // frame; a registered frame (colour camera 2.5 cm right) has f·b·0.5 = 7.25 px on the
        // right and f·(B − b)·0.5 = 14.5 px of shadow on the left.
        let k = Intrinsics::kinect_v1();
        let scene = board_before_wall(1.0, 2.0);
        let raw = realistic_sim();
        let cfg = RealisticNoise::default();
        let f = raw.simulate(&scene, &k, &CameraToWorld::identity(), 2);
        let b = crate::stats::occlusion_bands(&f.depth, raw.sensor.fb(), 0.15, 64);
        let fill = cfg.shadow_fill_px as f64;
        assert!(
            (b.left.widths.median_px - (21.75 - fill)).abs() <= 1.0,
            "{b:?}"
        );
        assert_eq!(b.right.widths.count, 0);
        assert!(b.right.direct_edges > 400);
        let reg = raw.with_noise(NoiseModel::Realistic(RealisticNoise::for_camera("tum-fr1")));
        let f = reg.simulate(&scene, &k, &CameraToWorld::identity(), 2);
        let b = crate::stats::occlusion_bands(&f.depth, reg.sensor.fb(), 0.15, 64);
        assert!(
            (b.left.widths.median_px - (14.5 - fill)).abs() <= 1.0,
            "{b:?}"
        );
        assert!((b.right.widths.median_px - 7.25).abs() <= 1.0, "{b:?}");
    }

    #[test]
    fn grazing_surfaces_and_edges_drop_out() {
        // A floor seen nearly edge-on: the far rows exceed 80° of incidence and are invalid.
        let k = Intrinsics::kinect_v1().scaled(0.25).unwrap();
        let mut scene = Scene::new();
        scene.add(Plane::new(Point3::new(0.0, 0.3, 0.0), Vector3::y()).unwrap());
        let sim = realistic_sim();
        let f = sim.simulate(&scene, &k, &CameraToWorld::identity(), 1);
        let valid_truth = f.truth.valid_count();
        assert!(valid_truth > 0);
        assert!(f.depth.valid_count() < valid_truth);
        let no_graze = RealisticNoise {
            max_incidence_deg: 90.0,
            ..RealisticNoise::default()
        };
        let g = sim.with_noise(NoiseModel::Realistic(no_graze)).simulate(
            &scene,
            &k,
            &CameraToWorld::identity(),
            1,
        );
        assert!(g.depth.valid_count() > f.depth.valid_count());
        // Edge invalidation: `edge_px` pixels on each side of the board's edges.
        let mut edges = RealisticNoise {
            edge_px: 2,
            projector_shadows: false,
            ..RealisticNoise::default()
        };
        let scene = board_before_wall(1.0, 2.0);
        let k = Intrinsics::kinect_v1();
        let e = sim.with_noise(NoiseModel::Realistic(edges)).simulate(
            &scene,
            &k,
            &CameraToWorld::identity(),
            1,
        );
        let b = crate::stats::occlusion_bands(&e.depth, sim.sensor.fb(), 0.15, 64);
        assert_eq!(b.left.widths.median_px, 4.0);
        assert_eq!(b.right.widths.median_px, 4.0);
        assert!(edges.validate().is_ok());
        edges.window_x = 0;
        assert!(edges.validate().is_err());
    }

    #[test]
    fn row_marching_with_ray_tests_equals_scene_ray_tests() {
        // The candidates of the row march, checked by scene ray tests, are exactly the pixels
        // the ray test of every pixel (`projector_shadows`) finds; the row march alone also
        // shadows the wall behind the thin arms, which the projector's light passes behind.
        let ns = crate::sim::named_scene("figure-walls").unwrap();
        let k = ns.intrinsics.scaled(0.5).unwrap();
        let sim = realistic_sim();
        let truth = ns.scene.render(&k, &ns.pose).depth;
        let exact = sim.projector_shadows(&ns.scene, &k, &ns.pose, &truth);
        let fast = realistic::hidden_from(&ns.scene, &k, &ns.pose, &truth, sim.sensor.baseline_m);
        assert!(exact.data().iter().filter(|m| **m).count() > 500);
        assert_eq!(exact.data(), &fast[..]);
        let marched = realistic::hidden_along_rows(&truth, k.fx, sim.sensor.baseline_m);
        let extra = marched
            .iter()
            .zip(exact.data())
            .filter(|(m, e)| **m && !**e)
            .count();
        assert!(extra > 0);
    }
}
