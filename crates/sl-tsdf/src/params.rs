//! Fusion parameters: voxel size, truncation band, weighting scheme and memory budget.

use sl_core::{Isa, SensorModel};

use crate::error::{Result, TsdfError};

/// How much one observation counts in the running average `F = Σ wᵢ fᵢ / Σ wᵢ`.
///
/// All weights are *normalised* so that they are of order one: an observation at the reference
/// depth `z_ref` (1 m by default) weighs 1 in every mode. The normalisation does not change the
/// average (the paper notes that a constant factor cancels in eq. 12) but keeps the f32
/// arithmetic away from the range where `1/Z⁴` of millimetre units would under- or overflow and
/// makes the weight cap and the `min_weight` threshold of the mesher meaningful for every mode.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum WeightMode {
    /// The paper (eq. 13): `w = (z_ref / Z)⁴`, the inverse variance of a structured-light depth
    /// whose noise grows as `Z²`. Default.
    #[default]
    InvZ4,
    /// The classic unweighted average of Curless & Levoy / KinectFusion: `w = 1`.
    Uniform,
    /// `w = (z_ref / Z)²`, as used by voxblox and nvblox.
    InvZ2,
    /// The inverse variance of the sensor model plus a floor:
    /// `w = (σ_Z(z_ref)² + σ_floor²) / (σ_Z(Z)² + σ_floor²)` with `σ_Z(Z) = Z²·σ_D/(f·B)` from
    /// [`SensorModel::sigma_z`]. The floor (e.g. the 1 mm depth-storage step over √12) keeps
    /// close observations from being weighted beyond what the file format can resolve; with a
    /// zero floor this is exactly [`WeightMode::InvZ4`].
    SensorVariance {
        /// The sensor model giving `σ_Z(Z)`.
        sensor: SensorModel,
        /// Standard deviation that does not shrink with depth, metres.
        floor_m: f64,
    },
}

impl WeightMode {
    /// Parses `inv-z4`, `uniform`, `inv-z2` (the CLI names). `sensor` is not parsed here since
    /// it needs a sensor model: use [`WeightMode::sensor_variance`].
    pub fn parse(name: &str) -> Result<Self> {
        match name {
            "inv-z4" | "invz4" => Ok(Self::InvZ4),
            "uniform" => Ok(Self::Uniform),
            "inv-z2" | "invz2" => Ok(Self::InvZ2),
            other => Err(TsdfError::InvalidParameter(format!(
                "unknown weight '{other}' (expected inv-z4, uniform, inv-z2 or sensor)"
            ))),
        }
    }

    /// The sensor-variance weight with the depth-storage floor of a 1 mm depth step
    /// (`0.001/√12` m).
    pub fn sensor_variance(sensor: SensorModel) -> Self {
        Self::SensorVariance {
            sensor,
            floor_m: 0.001 / 12f64.sqrt(),
        }
    }

    /// The CLI name of the mode.
    pub fn name(&self) -> &'static str {
        match self {
            Self::InvZ4 => "inv-z4",
            Self::Uniform => "uniform",
            Self::InvZ2 => "inv-z2",
            Self::SensorVariance { .. } => "sensor",
        }
    }
}

/// How wide the truncation band of one observation is.
///
/// The band must hold the spread of the zero crossing: a surface seen at depth `Z` by a
/// structured-light sensor lands at `Z ± σ_Z(Z)` with `σ_Z = Z²·σ_D/(f·B)`, Gaussian to a
/// good approximation (the disparity error is), so `±3σ_Z` holds 99.7 % of the observations
/// and a band of `3σ_Z` keeps every one of them on the correct side of its voxels. A fixed
/// band is either wider than needed close to the camera (thin structures blur) or narrower
/// than the noise far away: with 2 cm, beyond about 2.1 m for a Kinect v1 (`3σ_Z(2.1 m)` =
/// 2 cm), observations scatter past the band, far voxels are overwritten with
/// inconsistent clamped values, and marching cubes finds spurious crossings (the "foam" of
/// issue 13).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Truncation {
    /// Every observation uses [`TsdfConfig::trunc_m`].
    Fixed,
    /// The band of an observation at depth `Z` is
    /// `min(max(trunc_m, sigmas·σ_Z(Z)), max(max_m, trunc_m))`: [`TsdfConfig::trunc_m`] is the
    /// floor (a few voxels, so that marching cubes sees both sides of the surface),
    /// `sigmas·σ_Z(Z)` follows the sensor noise, `max_m` bounds the memory far away (a
    /// `trunc_m` above it wins: the band is then `trunc_m` everywhere). Default, with the `kinect-v1`
    /// sensor, 3σ and a 0.12 m cap (3σ_Z at 4.9 m).
    SensorAdaptive {
        /// The sensor model giving `σ_Z(Z)`.
        sensor: SensorModel,
        /// Multiple of `σ_Z` (3: 99.7 % of the zero crossings).
        sigmas: f64,
        /// Widest band, metres.
        max_m: f64,
    },
}

impl Truncation {
    /// The sensor-adaptive band with 3σ and a 0.12 m cap.
    pub fn sensor_adaptive(sensor: SensorModel) -> Self {
        Self::SensorAdaptive {
            sensor,
            sigmas: 3.0,
            max_m: 0.12,
        }
    }

    /// The CLI name of the mode.
    pub fn name(&self) -> &'static str {
        match self {
            Self::Fixed => "fixed",
            Self::SensorAdaptive { .. } => "sensor-adaptive",
        }
    }
}

/// The band as a function of the observed depth: `min(max(floor, c·Z²), max)`, with `c = 0`
/// and `max = floor` for a fixed band (so one branch-free formula serves both modes).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct BandFn {
    pub(crate) floor: f32,
    pub(crate) c: f32,
    pub(crate) max: f32,
}

impl BandFn {
    pub(crate) fn new(p: &TsdfConfig) -> Self {
        let floor = p.trunc_m as f32;
        match p.truncation {
            Truncation::Fixed => Self {
                floor,
                c: 0.0,
                max: floor,
            },
            Truncation::SensorAdaptive {
                sensor,
                sigmas,
                max_m,
            } => Self {
                floor,
                c: (sigmas * sensor.sigma_d_px / sensor.fb()) as f32,
                max: (max_m as f32).max(floor),
            },
        }
    }

    /// The band of an observation at depth `z`, metres (plain compares: vectorises).
    #[inline(always)]
    pub(crate) fn band(&self, z: f32) -> f32 {
        let b = self.c * z * z;
        let b = if b > self.floor { b } else { self.floor };
        if b < self.max { b } else { self.max }
    }
}

/// Where a voxel reads the depth of the frame it is updated from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[non_exhaustive]
pub enum DepthLookup {
    /// The pixel whose centre is nearest to the voxel's projection (KinectFusion's and
    /// Open3D's projective update). Within one pixel's footprint every voxel reads the same
    /// depth, so a surface seen at a grazing angle is fused as a staircase of steps one pixel
    /// wide: on a simulated corridor's walls (exact depth, 4 mm voxels) the model's normals
    /// lean 4° towards the camera on average (10° RMS). Default: the faster (see `Bilinear`).
    #[default]
    Nearest,
    /// Inverse depth interpolated bilinearly between the four pixels around the projection, when
    /// they are valid and lie on one surface (their depths differ by no more than a surface
    /// at 80° to the line of sight across the cell's diagonal, plus the observation's band);
    /// otherwise the nearest pixel. Inverse depth is affine in the image for a plane (the
    /// paper's disparity), so a plane is fused exactly, and the four pixels' noise is averaged.
    Bilinear,
}

impl DepthLookup {
    /// The names the CLI and Python accept, in the order of [`DepthLookup::ALL`].
    pub const NAMES: [&'static str; 2] = ["nearest", "bilinear"];
    /// Both lookups.
    pub const ALL: [DepthLookup; 2] = [DepthLookup::Nearest, DepthLookup::Bilinear];

    /// The CLI name of the mode.
    pub fn name(&self) -> &'static str {
        match self {
            Self::Nearest => "nearest",
            Self::Bilinear => "bilinear",
        }
    }
}

impl std::str::FromStr for DepthLookup {
    type Err = TsdfError;
    fn from_str(s: &str) -> Result<Self> {
        Self::ALL
            .into_iter()
            .find(|m| m.name() == s)
            .ok_or_else(|| {
                TsdfError::InvalidParameter(format!(
                    "unknown depth_lookup {s:?} (expected nearest or bilinear)"
                ))
            })
    }
}

/// The steepest surface, relative to the line of sight, whose neighbouring pixels
/// [`DepthLookup::Bilinear`] interpolates between: 80°.
pub(crate) const SAME_SURFACE_MAX_INCIDENCE_DEG: f64 = 80.0;

/// A per-frame weight function, precomputed from a [`WeightMode`] and the reference depth so
/// that the inner loop costs a few multiplications.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum WeightFn {
    Uniform,
    /// `(z_ref/Z)²` computed as `(z_ref · 1/Z)²`.
    InvZ2 {
        z_ref: f32,
    },
    InvZ4 {
        z_ref: f32,
    },
    /// `num / (c·Z⁴ + floor²)` with `c = (σ_D/(f·B))²`.
    Variance {
        c: f32,
        floor2: f32,
        num: f32,
    },
}

impl WeightFn {
    pub(crate) fn new(mode: WeightMode, z_ref_m: f64) -> Self {
        match mode {
            WeightMode::Uniform => Self::Uniform,
            WeightMode::InvZ2 => Self::InvZ2 {
                z_ref: z_ref_m as f32,
            },
            WeightMode::InvZ4 => Self::InvZ4 {
                z_ref: z_ref_m as f32,
            },
            WeightMode::SensorVariance { sensor, floor_m } => {
                // Work in units of the reference variance so that everything is O(1).
                let s_ref = sensor.sigma_z(z_ref_m);
                if !(s_ref > 0.0 && s_ref.is_finite()) {
                    // A noise-free sensor (σ_D = 0): every observation has the floor's
                    // variance, the same at every depth.
                    return Self::Uniform;
                }
                let c = (sensor.sigma_d_px / sensor.fb()).powi(2) / (s_ref * s_ref);
                let floor2 = (floor_m / s_ref).powi(2);
                Self::Variance {
                    c: c as f32,
                    floor2: floor2 as f32,
                    num: (1.0 + floor2) as f32,
                }
            }
        }
    }

    /// The weight of an observation whose pixel has depth `z` (metres, > 0).
    #[inline(always)]
    pub(crate) fn weight(&self, z: f32) -> f32 {
        match *self {
            Self::Uniform => 1.0,
            Self::InvZ2 { z_ref } => {
                let r = z_ref / z;
                r * r
            }
            Self::InvZ4 { z_ref } => {
                let r = z_ref / z;
                let r2 = r * r;
                r2 * r2
            }
            Self::Variance { c, floor2, num } => {
                let z2 = z * z;
                num / (c * z2 * z2 + floor2)
            }
        }
    }
}

/// Parameters of a [`crate::TsdfVolume`].
///
/// Defaults (see [`TsdfConfig::default`]): 4 mm voxels, a sensor-adaptive truncation band of
/// `max(2 cm, 3σ_Z(Z))` up to 12 cm (the `kinect-v1` sensor), `inv-z4` weights normalised at
/// 1 m, 4 m maximum depth, weight cap 10⁶ and a 4 GiB memory budget.
///
/// **Truncation.** The band must cover the sensor noise and a few voxels: a surface seen
/// with noise `σ_Z` spreads its zero crossing over ±3σ_Z (99.7 % of a Gaussian), and marching
/// cubes needs the voxels on both sides of the surface to be observed. For a Kinect v1 `σ_Z`
/// is 1.6 mm at 1 m, 6.4 mm at 2 m and 14 mm at 3 m, so a fixed 2 cm (5 voxels of 4 mm)
/// covers ±3σ up to about 2 m and only ±1.4σ at 3 m. The default
/// [`Truncation::SensorAdaptive`] therefore gives each observation its own band,
/// `max(trunc_m, 3·σ_Z(Z))` capped at 12 cm: 2 cm up to 2.1 m, 4.3 cm at 3 m, 7.7 cm at 4 m;
/// [`Truncation::Fixed`] keeps `trunc_m` for every depth.
/// [`TsdfConfig::suggested_trunc_m`] computes `max(4·voxel, 3·σ_Z(z))` for one depth. A wider
/// band blurs thin structures (the two sides of a 1 cm board interfere) and costs memory.
///
/// **Mixing bands.** A voxel stores `F` in metres (not normalised by the band), so
/// observations with different bands average consistently: each contributes its line-of-sight
/// distance clipped to its own band, `min(sdf, band_i)`, and only while the voxel is less than
/// `band_i` behind its surface. Within the narrowest band of the observations (where the zero
/// crossing is) every observation contributes its unclipped distance and `F` is the plain
/// weighted mean; farther out `F` mixes clips of different widths, which keeps its sign
/// (positive in front of the surface) and keeps `|F|` at most the line-of-sight distance, the
/// two properties marching cubes and the raycaster's step rely on. The weights are untouched
/// by the band (`inv-z4` already weighs a far, wide-band observation by its noise).
///
/// `#[non_exhaustive]`: start from [`TsdfConfig::default`] and assign the fields you need.
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub struct TsdfConfig {
    /// Edge of a voxel, metres.
    pub voxel_m: f64,
    /// Truncation `f_max = −f_min`, metres: signed distances are clipped to
    /// `[−band, band]`; voxels more than `band` behind the observed surface are not updated
    /// (they are occluded: Curless & Levoy's "unseen" region). `band = trunc_m` with
    /// [`Truncation::Fixed`]; with [`Truncation::SensorAdaptive`] `trunc_m` is the narrowest
    /// band.
    pub trunc_m: f64,
    /// How the band follows the depth of each observation (default
    /// [`Truncation::SensorAdaptive`] with the `kinect-v1` sensor: for another camera start from
    /// [`TsdfConfig::for_sensor`], or a D435's frames get a band less than half as wide as their
    /// noise).
    pub truncation: Truncation,
    /// The weighting scheme.
    pub weight: WeightMode,
    /// Reference depth at which every weight mode gives 1, metres.
    pub z_ref_m: f64,
    /// Depths above this are ignored, metres.
    pub max_depth_m: f64,
    /// Depths below this are ignored, metres.
    pub min_depth_m: f64,
    /// Cap of the accumulated weight of a voxel (in normalised units). Past the cap the running
    /// average becomes an exponential moving average; it also keeps `w/(W+w)` above the f32
    /// resolution for any observation weighing more than 10⁻⁶ of the cap.
    pub max_weight: f32,
    /// Memory the voxel blocks and their index may use, bytes. Integration that would exceed it
    /// fails with [`TsdfError::MemoryBudget`] and leaves the volume unchanged.
    pub memory_budget_bytes: usize,
    /// Where a voxel reads the frame's depth (default [`DepthLookup::Nearest`]).
    pub depth_lookup: DepthLookup,
    /// The instruction set of block discovery and the voxel update: by default the widest this
    /// CPU supports ([`Isa::detect`]); a set this CPU lacks runs as the widest narrower one.
    /// Every choice gives bit-identical volumes (the update is elementwise). Compiled for AVX2,
    /// they were no faster than the portable code until the update prefetched its next block
    /// (session 23 of docs/bench/track.md; before, the update waited on the blocks' memory).
    pub isa: Isa,
}

/// The former name of [`TsdfConfig`].
#[deprecated(
    since = "0.1.0",
    note = "renamed `TsdfConfig` (every configuration is a `…Config`)"
)]
pub type TsdfParams = TsdfConfig;

impl Default for TsdfConfig {
    fn default() -> Self {
        Self {
            voxel_m: 0.004,
            trunc_m: 0.02,
            truncation: Truncation::sensor_adaptive(SensorModel::kinect_v1()),
            weight: WeightMode::InvZ4,
            z_ref_m: 1.0,
            max_depth_m: 4.0,
            min_depth_m: 0.1,
            max_weight: 1.0e6,
            memory_budget_bytes: 4 << 30,
            depth_lookup: DepthLookup::Nearest,
            isa: Isa::detect(),
        }
    }
}

impl TsdfConfig {
    /// The defaults with the sensor-adaptive band of `sensor` (3σ_Z of its noise model, 0.12 m
    /// cap) instead of the `kinect-v1` model's.
    pub fn for_sensor(sensor: SensorModel) -> Self {
        Self {
            truncation: Truncation::sensor_adaptive(sensor),
            ..Self::default()
        }
    }

    /// The instruction set block discovery and the voxel update are compiled for, when not
    /// portable: [`TsdfConfig::isa`], or the widest narrower set this CPU has.
    pub(crate) fn fusion_isa(&self) -> Option<Isa> {
        Some(self.isa.effective()).filter(|&isa| isa != Isa::Portable)
    }

    /// Checks the parameters.
    pub fn validate(&self) -> Result<()> {
        let pos = |name: &str, v: f64| {
            if v.is_finite() && v > 0.0 {
                Ok(())
            } else {
                Err(TsdfError::InvalidParameter(format!(
                    "{name} = {} must be positive and finite",
                    sl_core::Compact(v)
                )))
            }
        };
        pos("voxel_m", self.voxel_m)?;
        pos("trunc_m", self.trunc_m)?;
        pos("z_ref_m", self.z_ref_m)?;
        pos("max_depth_m", self.max_depth_m)?;
        pos("max_weight", f64::from(self.max_weight))?;
        if !(self.min_depth_m.is_finite()
            && self.min_depth_m >= 0.0
            && self.min_depth_m < self.max_depth_m)
        {
            return Err(TsdfError::InvalidParameter(format!(
                "min_depth_m = {} must be in [0, max_depth_m = {})",
                sl_core::Compact(self.min_depth_m),
                sl_core::Compact(self.max_depth_m)
            )));
        }
        // The block keys address ±(MAX_BLOCK_COORD − 2) blocks about the origin (the margin
        // of the integration's range check): a surface at `max_depth_m` seen from the origin
        // must fit.
        let reach_m = f64::from(crate::hash::MAX_BLOCK_COORD - 2)
            * crate::volume::BLOCK_SIDE as f64
            * self.voxel_m;
        if reach_m < self.max_depth_m {
            return Err(TsdfError::InvalidParameter(format!(
                "voxel_m = {:e} addresses only ±{reach_m:.3e} m about the origin, less than \
                 max_depth_m = {} m: a larger voxel_m",
                self.voxel_m,
                sl_core::Compact(self.max_depth_m)
            )));
        }
        if self.trunc_m < self.voxel_m {
            return Err(TsdfError::InvalidParameter(format!(
                "trunc_m = {} must be at least one voxel ({} m)",
                sl_core::Compact(self.trunc_m),
                sl_core::Compact(self.voxel_m)
            )));
        }
        if let Truncation::SensorAdaptive {
            sensor,
            sigmas,
            max_m,
        } = self.truncation
        {
            sensor.validate()?;
            if !(sigmas.is_finite() && sigmas > 0.0 && sigmas <= 100.0) {
                return Err(TsdfError::InvalidParameter(format!(
                    "truncation sigmas = {} must be in (0, 100]",
                    sl_core::Compact(sigmas)
                )));
            }
            if !(max_m.is_finite() && max_m > 0.0) {
                return Err(TsdfError::InvalidParameter(format!(
                    "truncation max_m = {} must be positive and finite",
                    sl_core::Compact(max_m)
                )));
            }
        }
        if let WeightMode::SensorVariance { sensor, floor_m } = self.weight {
            sensor.validate()?;
            if !(floor_m.is_finite() && floor_m >= 0.0) {
                return Err(TsdfError::InvalidParameter(format!(
                    "floor_m = {} must be >= 0",
                    sl_core::Compact(floor_m)
                )));
            }
        }
        Ok(())
    }

    /// A truncation suited to `voxel_m` and a sensor at typical depth `z_m`:
    /// `max(4·voxel, 3·σ_Z(z))`.
    pub fn suggested_trunc_m(voxel_m: f64, sensor: &SensorModel, z_m: f64) -> f64 {
        (4.0 * voxel_m).max(3.0 * sensor.sigma_z(z_m))
    }

    /// The truncation band of one observation at depth `z_m` under these parameters, metres.
    pub fn band_at(&self, z_m: f64) -> f64 {
        f64::from(BandFn::new(self).band(z_m as f32))
    }

    /// The normalised weight of one observation at depth `z_m` under these parameters.
    pub fn weight_at(&self, z_m: f64) -> f32 {
        WeightFn::new(self.weight, self.z_ref_m).weight(z_m as f32)
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
mod tests {
    use super::*;

    #[test]
    fn weights_are_normalised_at_reference() {
        let s = SensorModel::kinect_v1();
        for mode in [
            WeightMode::InvZ4,
            WeightMode::Uniform,
            WeightMode::InvZ2,
            WeightMode::sensor_variance(s),
        ] {
            let p = TsdfConfig {
                weight: mode,
                ..TsdfConfig::default()
            };
            assert!((p.weight_at(1.0) - 1.0).abs() < 1e-6, "{mode:?}");
        }
    }

    #[test]
    fn a_noise_free_sensor_weighs_every_depth_alike() {
        let mut s = SensorModel::kinect_v1();
        s.sigma_d_px = 0.0;
        let p = TsdfConfig {
            weight: WeightMode::sensor_variance(s),
            ..TsdfConfig::default()
        };
        for z in [0.5, 1.0, 3.0] {
            assert_eq!(p.weight_at(z), 1.0);
        }
    }

    #[test]
    fn inv_z4_ratio_matches_paper() {
        let p = TsdfConfig::default();
        // The paper's two scans: 0.75 m and 1.5 m -> the close one weighs 2^4 = 16 times more.
        let r = p.weight_at(0.75) / p.weight_at(1.5);
        assert!((r - 16.0).abs() < 1e-4, "{r}");
        // Far and near weights stay in a comfortable f32 range.
        assert!(p.weight_at(8.0) > 1e-4 && p.weight_at(0.2) < 1e4);
        let p2 = TsdfConfig {
            weight: WeightMode::InvZ2,
            ..p
        };
        assert!((p2.weight_at(0.5) - 4.0).abs() < 1e-5);
    }

    #[test]
    fn sensor_variance_is_inv_z4_without_floor() {
        let s = SensorModel::kinect_v1();
        let p = TsdfConfig {
            weight: WeightMode::SensorVariance {
                sensor: s,
                floor_m: 0.0,
            },
            ..TsdfConfig::default()
        };
        let q = TsdfConfig::default();
        for z in [0.5, 1.3, 3.0] {
            assert!((p.weight_at(z) / q.weight_at(z) - 1.0).abs() < 1e-4);
        }
        // With the floor, close observations gain less than 1/Z^4.
        let f = TsdfConfig {
            weight: WeightMode::sensor_variance(s),
            ..TsdfConfig::default()
        };
        assert!(f.weight_at(0.5) < q.weight_at(0.5));
    }

    #[test]
    fn a_sensors_config_has_the_band_of_its_noise() {
        // A D435-like stereo camera (f 426 px, B 5 cm, σ_D 0.08 px) is 2.3× noisier in depth
        // than the default's Kinect at the same distance, and so is its band.
        let d435 = SensorModel {
            focal_px: 426.0,
            baseline_m: 0.05,
            sigma_d_px: 0.08,
            ..SensorModel::kinect_v1()
        };
        let p = TsdfConfig::for_sensor(d435);
        // (The band is computed in f32.)
        assert!((p.band_at(2.0) / (3.0 * d435.sigma_z(2.0)) - 1.0).abs() < 1e-6);
        let kinect = TsdfConfig::default().band_at(3.0);
        assert!(
            (p.band_at(3.0) / kinect - d435.sigma_z(3.0) / SensorModel::kinect_v1().sigma_z(3.0))
                .abs()
                < 1e-5
        );
        assert_eq!(p.voxel_m, TsdfConfig::default().voxel_m);
    }

    #[test]
    fn adaptive_band_follows_three_sigma_between_floor_and_cap() {
        let s = SensorModel::kinect_v1();
        let p = TsdfConfig::default();
        // Below 2.1 m the floor, beyond it 3σ_Z, the cap far away.
        assert!((p.band_at(1.0) - 0.02).abs() < 1e-7);
        for z in [3.0, 4.0] {
            let want = 3.0 * s.sigma_z(z);
            assert!(
                want > 0.02 && (p.band_at(z) - want).abs() < 1e-6 * want.max(1.0),
                "{z}"
            );
        }
        assert!((p.band_at(8.0) - 0.12).abs() < 1e-7);
        let fixed = TsdfConfig {
            truncation: Truncation::Fixed,
            ..p
        };
        for z in [0.5, 3.0, 8.0] {
            assert!((fixed.band_at(z) - 0.02).abs() < 1e-7);
        }
        // A cap below the floor: the floor everywhere.
        let capped = TsdfConfig {
            truncation: Truncation::SensorAdaptive {
                sensor: s,
                sigmas: 3.0,
                max_m: 0.01,
            },
            ..p
        };
        assert!((capped.band_at(4.0) - 0.02).abs() < 1e-7);
        let bad = TsdfConfig {
            truncation: Truncation::SensorAdaptive {
                sensor: s,
                sigmas: f64::NAN,
                max_m: 0.1,
            },
            ..p
        };
        assert!(bad.validate().is_err());
    }

    #[test]
    fn validation() {
        assert!(TsdfConfig::default().validate().is_ok());
        let bad = TsdfConfig {
            voxel_m: 0.0,
            ..TsdfConfig::default()
        };
        assert!(bad.validate().is_err());
        let bad = TsdfConfig {
            trunc_m: 0.001,
            ..TsdfConfig::default()
        };
        assert!(bad.validate().is_err());
        assert!(WeightMode::parse("inv-z4").is_ok());
        assert!(WeightMode::parse("foo").is_err());
        let t = TsdfConfig::suggested_trunc_m(0.004, &SensorModel::kinect_v1(), 2.0);
        assert!(t > 0.016 && t < 0.03, "{t}");
    }
}
