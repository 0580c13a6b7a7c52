//! Whether a frame's geometry pins the pose down at all: the standard deviation of the pose
//! along its least-constrained direction that point-to-plane alignment of the frame could
//! reach, from the sensor model — with the normals of the frame's planes where it has them.
//!
//! **Why planes.** The normal equations of the alignment itself cannot tell a single wall from
//! a room: the noise of per-pixel normals (several degrees at 2 m, central differences over a
//! few pixels) spreads them over all directions and fills the null space of a wall or a floor
//! with fake constraints (session 10 measured the conditioning of a wall at 1.7·10⁻², within
//! the range of well-constrained real frames). A plane's normal comes from thousands of pixels,
//! so on a wall every sample gets the same normal and the directions along the wall get no
//! information, as the geometry says. Pixels on no plane (objects, curved surfaces) keep
//! their own normal, under the rules of [`super::normal_noise`]: none by the image border, an
//! invalid pixel, a depth edge or a crease, and `n nᵀ` estimated without its noise bias from
//! the normal one correlation window away.
//!
//! **The rule.** Each sample (every [`STEP`]-th pixel in both directions) contributes the
//! point-to-plane Jacobian `[p × n; n]` with the information of its `STEP²` pixels: one
//! independent measurement per correlation window of the sensor's error
//! ([`TrackerConfig::correlated_pixels`]) of variance `σ_Z²` at its depth. Rotations are
//! expressed as displacements at the mean depth of the samples. The result is
//! `1/√λ_min` of that information matrix, metres. [`super::Tracker`] reports a frame lost when
//! this exceeds the σ of its own motion prior (`max_acceleration_m_s2 · frame_interval_s²`):
//! along such a direction the data say less than the constant-velocity guess, so the pose
//! there would be the guess, not a measurement.
//!
//! **Twice.** Before any alignment on the whole frame (a single wall; also the first frame,
//! which must pin the pose to anchor a model), and after each alignment that passed its other
//! checks on the samples that are inliers of the reference at the aligned pose, with the
//! reference surface's variance added to the sample's (`solve::on_reference_at`): a frame can be
//! well constrained while the part of it the reference also holds is not (a model of one wall
//! and the floor so far, surfaces beyond the fused range). Simulated rooms and corridors
//! (`docs/bench/track.md`, session 13): tracked steps off by more than 2 cm fell from 19 to 11.
//!
//! **Against a reference, along what the reference measures.** The residual of a sample
//! against the reference runs along the reference surface's normal, so a plane's sample pins
//! its plane's normal only by the squared cosine between the two, where the reference's
//! normal is a plane's (the last frame's) or the fused model's; a pixel's own normal there is
//! too noisy to say (it only gates the association). A wall's samples by a corner land on the
//! reference's floor; in a corridor whose model is fused up to 4 m, the end wall's samples
//! beyond it land where the model's floor and walls end, and credited along the end wall's
//! normal they pinned the corridor's axis: steps 13–22 mm off reported tracked at σ 7–10 mm
//! (session 52). The squared cosine's shortfall from the model normals' own noise is measured
//! and given back ([`super::reference_normal_noise`]).

use nalgebra::{Matrix6, Point3, SymmetricEigen, Vector3, Vector6};
use rayon::prelude::*;
use sl_core::{Camera, DepthView, Intrinsics, SensorModel};
use sl_planes::{PlaneConfig, PlaneExtractor};

use super::TrackerConfig;
use super::agreement::{agreeing_information, disputed_direction, positive_part};
use super::frame_planes::FramePlanes;
use super::normal_noise::{NormalNoise, modelled_variance, window_is_one_surface};
use super::pyramid::{Level, normal_radius};
use super::reference_normal_noise::ReferenceNormalNoise;
use super::solve::{OnReference, rotations_at_depth};
use crate::error::Result;

/// Pixels between samples, in both directions.
pub(crate) const STEP: usize = 4;

/// What [`StructureCheck::weakest_sigma_m`] finds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Weakest {
    /// The pose's standard deviation along its least-constrained direction, metres
    /// (`f64::INFINITY` when a direction gets no information at all).
    pub(crate) sigma_m: f64,
    /// When the samples that land on the reference beyond the gates pin some direction better
    /// than those that agree with the pose, and within the motion prior's σ: that σ from them
    /// alone, metres. The pose is then disputed by the data, not determined by it.
    pub(crate) disputed_sigma_m: Option<f64>,
    /// The information the view gives the pose, rotations as displacements at `scale_m`
    /// (`solve::rotations_at_depth`); zero when it gives none.
    pub(crate) info: Matrix6<f64>,
    /// The depth the rotations of `info` are scaled at, metres.
    pub(crate) scale_m: f64,
}

impl Weakest {
    const UNDETERMINED: Self = Self {
        sigma_m: f64::INFINITY,
        disputed_sigma_m: None,
        info: Matrix6::new(
            0.0, 0.0, 0.0, 0.0, 0.0, 0.0, //
            0.0, 0.0, 0.0, 0.0, 0.0, 0.0, //
            0.0, 0.0, 0.0, 0.0, 0.0, 0.0, //
            0.0, 0.0, 0.0, 0.0, 0.0, 0.0, //
            0.0, 0.0, 0.0, 0.0, 0.0, 0.0, //
            0.0, 0.0, 0.0, 0.0, 0.0, 0.0,
        ),
        scale_m: 1.0,
    };
}

/// Which of the check's samples vouch only for what they agree with (see
/// [`StructureCheck::weakest_sigma_m`]): those on each plane (`planes`), and those on no plane
/// together (`samples`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub(crate) struct MustAgree {
    pub(crate) planes: bool,
    pub(crate) samples: bool,
}

/// The plane extractor kept between frames (its buffers are reused) and the last frame's
/// segmentation: its label image and its planes.
#[derive(Debug, Default)]
pub(crate) struct StructureCheck {
    extractor: Option<PlaneExtractor>,
    /// The segmentation of the last [`StructureCheck::segment`].
    planes: FramePlanes,
    /// The noise of the segmented level's own normals.
    normal_noise: NormalNoise,
}

impl StructureCheck {
    /// Extracts the planes of pyramid level `index` of the frame (level 1, half resolution, is
    /// where [`super::Tracker`] runs it: a plane's normal needs no more, and the extraction
    /// costs a quarter), for [`StructureCheck::weakest_sigma_m`]; `camera` is the frame's.
    pub(crate) fn segment(
        &mut self,
        level: &Level,
        index: usize,
        camera: &Camera,
        cfg: &TrackerConfig,
    ) -> Result<()> {
        self.planes.clear();
        let Some(k) = level.k else {
            self.normal_noise = NormalNoise::default();
            return Ok(());
        };
        let scale = f64::from(1u32 << index.min(16));
        let extractor = match &mut self.extractor {
            Some(e) => e,
            None => {
                // The correlation window of the sensor's error in sensor pixels at this level's
                // scale (the extractor converts it to the level's pixels with the camera below).
                let mut pc = PlaneConfig::default();
                // With the tracker's `estimate_noise` off the planes keep the camera's model
                // too; on, the level's camera below carries the frame's measured noise.
                pc.estimate_noise = cfg.estimate_noise;
                pc.noise_window_x_px = (cfg.noise_window_x_px / scale).max(1.0);
                pc.noise_window_y_px = (cfg.noise_window_y_px / scale).max(1.0);
                self.extractor.insert(PlaneExtractor::new(pc)?)
            }
        };
        // The level's disparity in the level's pixels: the sensor's focal length scaled as the
        // level's (equal to the level's focal length at the sensor's own resolution).
        let level_camera = Camera {
            intrinsics: k,
            sensor: SensorModel {
                focal_px: k.fx / camera.pixels_per_sensor_pixel(),
                ..camera.sensor
            },
        };
        // The extraction and the normals' noise read the level only: side by side.
        let (hx, hy) = half_window(index, camera, cfg);
        let normal_noise = &mut self.normal_noise;
        let (seg, ()) = rayon::join(
            || {
                extractor.extract_depth(
                    DepthView::new(k.width, k.height, &level.depth)?,
                    &level_camera,
                )
            },
            || {
                normal_noise.measure(
                    level,
                    &k,
                    &camera.sensor,
                    (sample_step(index), normal_radius(index)),
                    (2 * hx + 1, 2 * hy + 1),
                );
            },
        );
        let seg = seg?;
        self.planes.labels.extend_from_slice(seg.labels.data());
        self.planes
            .planes
            .extend(seg.planes.iter().map(|p| p.plane));
        (self.planes.width, self.planes.height, self.planes.level) = (k.width, k.height, index);
        Ok(())
    }

    /// Swaps the last segmentation into `into` (the frame it segmented becomes the last good
    /// frame); this check's own is then stale until the next [`StructureCheck::segment`].
    pub(crate) fn hand_over(&mut self, into: &mut FramePlanes) {
        std::mem::swap(&mut self.planes, into);
        self.planes.clear();
    }

    /// The pose's standard deviation along its least-constrained direction, metres
    /// (`f64::INFINITY` when a direction gets no information at all: a single plane), and
    /// whether the samples beyond the gates dispute the pose ([`Weakest`]), from the
    /// samples of pyramid level `index` (point and normal) for which `on_reference` is
    /// `Some` (the whole frame, or where it lands on the reference at the aligned pose), with the
    /// planes of the last [`StructureCheck::segment`] of that level. A sample's residual
    /// variance is its own `σ_Z²` plus the reference surface's variance, as in the alignment
    /// ([`OnReference::NONE`] for the frame alone). `camera` is the frame's.
    ///
    /// **`must_agree.planes`: a plane vouches only for what it agrees with** — against the
    /// fused model always, against the last frame when the start is a guess (a relocalising
    /// frame, or the first step after the sequence's first frame). At the right pose a
    /// plane's samples lie on the reference around zero; at a pose slid along a crease, a plane
    /// whose normal has a small component along the slide still passes the inlier gate, but
    /// all of its samples sit off the reference by the same amount. That shared offset is an
    /// error the plane's samples do not average away, so the plane's information becomes that
    /// of a mean with it added: `W / (1 + W·b²)` for the plane's summed weight `W` and `b²` the
    /// unbiased estimate `m² − 1/W` of the squared offset from the weighted mean residual `m`
    /// (0 when the mean is within its noise). A wrong relocalisation in the `boxes` scene,
    /// 13 cm along the floor–wall crease, was vouched for (σ 8.4 mm) by the back wall and a box
    /// face 6° off it, whose samples sat 5.1 and −5.7 mm off the reference on average (2.2 and
    /// 3.2 standard errors of those means); with their offsets σ is 19 mm and the alignment is
    /// rejected (docs/bench/track.md, session 25). On the simulated rooms the second frame of a
    /// sequence slid 44–51 mm along the crease its overlap with the one-frame model leaves
    /// weakest, vouched for at σ 6–9 mm; with the planes' offsets it is lost (session 38).
    /// A start from the constant-velocity prediction is no safer when the camera shakes: on
    /// the rooms with a hand-held jitter of up to 1 cm and 1° per axis and frame, steps from the
    /// prediction slid 30–49 mm with planes vouching at σ 3–10 mm (session 39).
    ///
    /// **`must_agree.samples`: the samples on no plane together, likewise** (session 40): a box
    /// too small to be a plane at this level vouched with its faces' samples, the right face's
    /// 57 samples 28 mm off the model on average and the left face's 54 samples −10 mm, each
    /// within its gate (room 3006, frame 15, 31 mm along the wall at σ 3.2 mm). One offset per
    /// plane does not describe them, a pose error does: their score `Σ w r J` is tested as a χ²
    /// and their information discounted along the pose change it asks for, given what the
    /// rest of the frame pins ([`super::agreement::agreeing_information`]).
    /// [`super::Tracker`] asks for it where the planes' rule applies and, in addition,
    /// against the last frame when that is the
    /// fallback after the model's alignment was rejected (room 3006's slides moved there
    /// otherwise: 45 mm at σ 6 mm). Not against the last frame from a prediction otherwise:
    /// tracking TUM fr1/rpy-200 frame to frame with it lost 1 of 200 frames (none without).
    ///
    /// **Disputed poses.** Agreement is measured on the samples the gate lets through, so it
    /// can be self-fulfilling: at a pose slid along the direction the view pins least, the
    /// samples that would object sit beyond the gate and count for nothing. Samples that land
    /// on the reference with a compatible normal beyond the gate, by at most the largest
    /// plausible correction ([`TrackerConfig::max_correction_m`]), are therefore summed apart
    /// ([`OnReference::inlier`]); where they pin some direction better than all the samples
    /// that agree with the pose (the largest generalised eigenvalue of the two information
    /// matrices exceeds 1), and within the motion prior's σ, the pose is
    /// [`Weakest::disputed_sigma_m`]: the data contradict it rather than confirm it. Room
    /// 3021 with a shaking camera: a step slid 48 mm up the walls was vouched for at σ 10.4 mm
    /// by what the gate let through, while a horizontal surface's samples and the box edges'
    /// sat 50 mm off the model beyond it, pinning the height to 1.5 mm; disputed, the frame is
    /// aligned to the last frame instead, within 1 mm (docs/bench/track.md, session 41). Asked
    /// for where the agreement rules are.
    ///
    /// Not against the last frame from a prediction: one frame's plane carries a low-frequency
    /// error of its own as a whole (the sensor's distortion and correlated noise, which the
    /// samples' variances do not hold), so a well-aligned next frame's planes sit off it beyond
    /// the noise of thousands of samples — tracking TUM fr1/rpy-200 frame to frame with the
    /// rule lost 10 of 200 frames (none without). The fused model averages that error over
    /// many views: with the rule, frame to model loses no frame of TUM fr1/rpy-200 or
    /// 7-Scenes, and 7 TUM frames whose planes sit off the model are aligned to the last frame
    /// instead (ATE 2.94 → 2.85 cm; docs/bench/track.md, session 39). Not with the
    /// rolling-shutter model either ([`TrackerConfig::rolling_shutter_readout_s`]): the offsets
    /// are measured at the frame's one pose while its rows are aligned each from its own, so
    /// they hold the readout's skew (with the rule, the simulated constant-velocity
    /// rolling-shutter sequence that `a_rolling_shutter_is_modelled_row_by_row` used until
    /// session 45 was recovered within 2.32 mm instead of 1.51 mm).
    pub(crate) fn weakest_sigma_m(
        &self,
        level: &Level,
        index: usize,
        camera: &Camera,
        cfg: &TrackerConfig,
        on_reference: impl Fn(&Point3<f32>, &Vector3<f32>) -> Option<OnReference> + Sync,
        must_agree: MustAgree,
    ) -> Weakest {
        let MustAgree {
            planes: planes_must_agree,
            samples: samples_must_agree,
        } = must_agree;
        let Some(k) = level.k else {
            return Weakest::UNDETERMINED;
        };
        // Samples beyond the gates count only for a dispute, asked where the agreement rules
        // are: elsewhere they are dropped before the partner search.
        let dispute = planes_must_agree || samples_must_agree;
        let on_reference = |p: &Point3<f32>, n: &Vector3<f32>| {
            on_reference(p, n).filter(|on_ref| dispute || on_ref.inlier)
        };
        let step = sample_step(index);
        let sampling = Sampling {
            k,
            step,
            r: normal_radius(index),
            half_window: half_window(index, camera, cfg),
            share: (step * step) as f64
                / cfg.correlated_pixels(index, camera.pixels_per_sensor_pixel()),
        };
        // Fixed bands of sample rows, each summed in row order, and the bands' sums added in
        // order: the same result for any thread count and on every run (as `solve::pass`).
        let sample_rows = (step / 2..k.height).step_by(step).len();
        let planes = self.planes.planes.len();
        let reference_noise = self.reference_normal_noise(level, &sampling, &on_reference);
        let bands: Vec<Information> = (0..sample_rows.div_ceil(ROWS_PER_BAND))
            .into_par_iter()
            .map(|band| {
                let rows = band * ROWS_PER_BAND..((band + 1) * ROWS_PER_BAND).min(sample_rows);
                self.band_information(
                    level,
                    camera,
                    (&sampling, &reference_noise),
                    &on_reference,
                    rows,
                )
            })
            .collect();
        let mut total = Information::new(planes);
        for band in &bands {
            total.add(band);
        }
        let Information {
            mut info,
            on_planes,
            info_off_planes,
            info_off_planes_own,
            score_off_planes,
            mut info_beyond_gates,
            z_sum,
            count,
        } = total;
        if count < 6.0 {
            return Weakest::UNDETERMINED;
        }
        for (plane_info, weight, weighted_residual) in &on_planes {
            if *weight > 0.0 {
                // W·b² = W·m² − 1 with m = Σwr / W.
                let excess = if planes_must_agree {
                    (weighted_residual * weighted_residual / weight - 1.0).max(0.0)
                } else {
                    0.0
                };
                info += plane_info / (1.0 + excess);
            }
        }
        // An unbiased estimate of a positive semi-definite matrix whose noise makes it
        // indefinite: its negative eigenvalues are noise, not information taken away.
        let off_psd = positive_part(info_off_planes);
        info += if samples_must_agree {
            agreeing_information(&off_psd, &info, &info_off_planes_own, &score_off_planes)
        } else {
            off_psd
        };
        // Rotations as displacements at the mean depth.
        let scale_m = z_sum / count;
        rotations_at_depth(&mut info, scale_m);
        let eigen = SymmetricEigen::new(info);
        let min = eigen
            .eigenvalues
            .iter()
            .copied()
            .fold(f64::INFINITY, f64::min);
        let largest = info.diagonal().max();
        // Round-off of a rank-deficient sum leaves |λ_min| ~ 1e-12 of the largest.
        let determined = min > largest * 1e-9;
        if !determined {
            return Weakest {
                info,
                scale_m,
                ..Weakest::UNDETERMINED
            };
        }
        let disputed_sigma_m = if dispute {
            rotations_at_depth(&mut info_beyond_gates, z_sum / count);
            disputed_direction(&eigen, &positive_part(info_beyond_gates))
                .filter(|&s| s <= cfg.motion_prior_sigma_m())
        } else {
            None
        };
        Weakest {
            sigma_m: 1.0 / min.sqrt(),
            disputed_sigma_m,
            info,
            scale_m,
        }
    }

    /// The noise of the reference's normals where the planes' samples land on them as
    /// inliers, every other sample in each direction ([`ReferenceNormalNoise`]); nothing for
    /// a frame checked on its own or without planes.
    fn reference_normal_noise(
        &self,
        level: &Level,
        sampling: &Sampling,
        on_reference: &(impl Fn(&Point3<f32>, &Vector3<f32>) -> Option<OnReference> + Sync),
    ) -> ReferenceNormalNoise {
        if self.planes.planes.is_empty() {
            return ReferenceNormalNoise::NONE;
        }
        let (k, step) = (sampling.k, 2 * sampling.step);
        let rows: Vec<usize> = (step / 2..k.height).step_by(step).collect();
        let pairs: Vec<Vec<(f64, f32)>> = rows
            .par_chunks(ROWS_PER_BAND)
            .map(|band| {
                let mut out = Vec::new();
                for &v in band {
                    for u in (step / 2..k.width).step_by(step) {
                        let i = v * k.width + u;
                        let plane = self
                            .planes
                            .labels
                            .get(i)
                            .and_then(|&l| usize::from(l).checked_sub(1))
                            .and_then(|l| self.planes.planes.get(l));
                        let (Some(plane), Some(p), Some(n_own)) =
                            (plane, level.points.get(i), level.normals.get(i))
                        else {
                            continue;
                        };
                        if !(p.z > 0.0 && n_own.x.is_finite()) {
                            continue;
                        }
                        let Some(n_ref) = on_reference(p, n_own)
                            .filter(|on_ref| on_ref.inlier)
                            .and_then(|on_ref| on_ref.normal)
                        else {
                            continue;
                        };
                        let c = plane.normal.dot(&n_ref);
                        out.push((f64::from(p.z), (1.0 - c * c) as f32));
                    }
                }
                out
            })
            .collect();
        ReferenceNormalNoise::measure(pairs.into_iter().flatten())
    }

    /// The information of the sample rows `rows` (indices of [`Sampling::step`]-spaced rows)
    /// for [`StructureCheck::weakest_sigma_m`], summed in row order.
    fn band_information(
        &self,
        level: &Level,
        camera: &Camera,
        (sampling, reference_noise): (&Sampling, &ReferenceNormalNoise),
        on_reference: &impl Fn(&Point3<f32>, &Vector3<f32>) -> Option<OnReference>,
        rows: std::ops::Range<usize>,
    ) -> Information {
        let Sampling {
            k,
            step,
            r,
            half_window,
            share,
        } = *sampling;
        let mut acc = Information::new(self.planes.planes.len());
        let Information {
            info,
            on_planes,
            info_off_planes,
            info_off_planes_own,
            score_off_planes,
            info_beyond_gates,
            z_sum,
            count,
        } = &mut acc;
        for row in rows {
            let v = step / 2 + row * step;
            for u in (step / 2..k.width).step_by(step) {
                let i = v * k.width + u;
                let (Some(p32), Some(n_own)) = (level.points.get(i), level.normals.get(i)) else {
                    continue;
                };
                if p32.z.is_nan() || p32.z <= 0.0 || !n_own.x.is_finite() {
                    continue;
                }
                let Some(on_ref) = on_reference(p32, n_own) else {
                    continue;
                };
                let p = p32.cast::<f64>().coords;
                let label = self.planes.labels.get(i).map_or(0, |&l| l as usize);
                let plane = label
                    .checked_sub(1)
                    .and_then(|l| self.planes.planes.get(l))
                    .map(|p| &p.normal);
                // On no plane: the own normal, if it describes one surface across the
                // correlation window, and a partner's one window away (`normal_noise`).
                let (n, partner) = match plane {
                    Some(n) if n.dot(&p) > 0.0 => (-n, None),
                    Some(n) => (*n, None),
                    None => {
                        let modelled = modelled_variance(&camera.sensor, p.z, k.fx, r);
                        let noise = self.normal_noise.variance(p.z, modelled);
                        // The cheap tests first: four normals, up to four partners, then the
                        // window's depths.
                        let partner =
                            NormalNoise::holds_across_window(level, k.width, i, half_window, noise)
                                .then(|| {
                                    NormalNoise::partner(
                                        level,
                                        &k,
                                        &camera.sensor,
                                        (u, v),
                                        half_window,
                                    )
                                })
                                .flatten()
                                .filter(|_| {
                                    window_is_one_surface(
                                        level,
                                        &k,
                                        &camera.sensor,
                                        (u, v),
                                        half_window,
                                    )
                                });
                        let Some(partner) = partner else {
                            continue;
                        };
                        (n_own.cast::<f64>(), Some(partner.cast::<f64>()))
                    }
                };
                let sigma_z = camera.sensor.sigma_z(p.z);
                let var = sigma_z * sigma_z + on_ref.variance_m2;
                if !(var > 0.0 && var.is_finite()) {
                    continue;
                }
                // J = A n with A = [[p]×; I]; on no plane n nᵀ is estimated without the noise's
                // bias by the symmetric product of two normals with independent errors, so
                // J Jᵀ becomes ½(A n̂ (A m̂)ᵀ + A m̂ (A n̂)ᵀ).
                let jacobian = |n: &Vector3<f64>| {
                    let pxn = p.cross(n);
                    Vector6::new(pxn.x, pxn.y, pxn.z, n.x, n.y, n.z)
                };
                let j = jacobian(&n);
                // A plane's sample is credited along its plane's normal, but its residual
                // measures along the reference surface's normal: a motion along the plane's
                // normal moves it by their cosine, so it pins that direction by the cosine
                // squared — next to nothing where a wall's sample by a corner lands on the
                // reference's floor, or on the rim where a model fused up to its depth limit
                // ends (its own pixel normal, mixed at the corner, let it through). The squared
                // cosine to a noisy reference normal is short by that noise on average; it is
                // given back as measured ([`ReferenceNormalNoise`]), so the sum is unbiased.
                let along = match (plane, on_ref.normal) {
                    (Some(_), Some(n_ref)) => {
                        n.dot(&n_ref).powi(2) + reference_noise.mean_square_error(p.z)
                    }
                    _ => 1.0,
                };
                let w = share / var;
                let own = j * j.transpose() * (w * along);
                let sample_info = match partner {
                    Some(m) => {
                        let jm = j * jacobian(&m).transpose();
                        (jm + jm.transpose()) * (0.5 * w)
                    }
                    None => own,
                };
                if !on_ref.inlier {
                    *info_beyond_gates += sample_info;
                    continue;
                }
                match (partner, on_planes.get_mut(label.wrapping_sub(1))) {
                    (Some(_), _) => {
                        *info_off_planes += sample_info;
                        *info_off_planes_own += own;
                        *score_off_planes += j * (w * on_ref.residual_m);
                    }
                    (None, Some((plane_info, weight, weighted_residual))) => {
                        *plane_info += sample_info;
                        *weight += w;
                        *weighted_residual += w * on_ref.residual_m;
                    }
                    (None, None) => *info += sample_info,
                }
                *z_sum += p.z;
                *count += 1.0;
            }
        }
        acc
    }
}

/// Level pixels between samples at pyramid level `index`, in both directions.
fn sample_step(index: usize) -> usize {
    let scale = f64::from(1u32 << index.min(16));
    (STEP as f64 / scale).max(1.0) as usize
}

/// Half the sensor's correlation window ([`TrackerConfig::noise_window_x_px`], `…_y_px`) in
/// pixels of pyramid level `index`, x and y, at least 1.
fn half_window(index: usize, camera: &Camera, cfg: &TrackerConfig) -> (usize, usize) {
    let pixels = camera.pixels_per_sensor_pixel() / f64::from(1u32 << index.min(16));
    let half = |side: f64| (side * pixels / 2.0).round().max(1.0) as usize;
    (half(cfg.noise_window_x_px), half(cfg.noise_window_y_px))
}

/// Where [`StructureCheck::weakest_sigma_m`] samples a level and what a sample counts for.
#[derive(Debug, Clone, Copy)]
struct Sampling {
    /// The level's intrinsics.
    k: Intrinsics,
    /// Every `step`-th pixel of every `step`-th row, from `step / 2`.
    step: usize,
    /// The normals' baseline, pixels.
    r: usize,
    /// Half the correlation window, pixels (x, y).
    half_window: (usize, usize),
    /// One sample's share of an independent measurement.
    share: f64,
}

/// Sample rows per band of [`StructureCheck::weakest_sigma_m`]'s parallel sums.
const ROWS_PER_BAND: usize = 16;

/// The information of a band of samples (see [`StructureCheck::weakest_sigma_m`]).
struct Information {
    /// Samples attributed neither to a plane nor to a partner normal.
    info: Matrix6<f64>,
    /// Per plane: information, summed weight and weighted residual.
    on_planes: Vec<(Matrix6<f64>, f64, f64)>,
    /// Samples on no plane with a partner normal (unbiased, not positive semi-definite).
    info_off_planes: Matrix6<f64>,
    /// The same samples with their own normal only (`Σ w J Jᵀ`, noise bias included): the
    /// covariance of [`Information::score_off_planes`] at the right pose.
    info_off_planes_own: Matrix6<f64>,
    /// The same samples' score `Σ w r J` (their residuals on the reference).
    score_off_planes: Vector6<f64>,
    /// Samples that land on the reference beyond the gate (`OnReference::inlier` false), on a
    /// plane or on no plane alike (unbiased on no plane, as `info_off_planes`).
    info_beyond_gates: Matrix6<f64>,
    z_sum: f64,
    count: f64,
}

impl Information {
    fn new(planes: usize) -> Self {
        Self {
            info: Matrix6::zeros(),
            on_planes: vec![(Matrix6::zeros(), 0.0, 0.0); planes],
            info_off_planes: Matrix6::zeros(),
            info_off_planes_own: Matrix6::zeros(),
            score_off_planes: Vector6::zeros(),
            info_beyond_gates: Matrix6::zeros(),
            z_sum: 0.0,
            count: 0.0,
        }
    }

    fn add(&mut self, other: &Self) {
        self.info += other.info;
        for (a, b) in self.on_planes.iter_mut().zip(&other.on_planes) {
            a.0 += b.0;
            a.1 += b.1;
            a.2 += b.2;
        }
        self.info_off_planes += other.info_off_planes;
        self.info_off_planes_own += other.info_off_planes_own;
        self.score_off_planes += other.score_off_planes;
        self.info_beyond_gates += other.info_beyond_gates;
        self.z_sum += other.z_sum;
        self.count += other.count;
    }
}
