//! Sensor presets as data: one table of the cameras and datasets the noise model covers, each
//! with its intrinsics, baseline, disparity sub-pixel steps, disparity noise, valid depth range,
//! the depth units its files use, and where the numbers come from.
//!
//! | name | camera | size | f (px) | B (m) | 1/q px | range (m) | file units/m | source |
//! |---|---|---|---|---|---|---|---|---|
//! | `kinect-v1` | Kinect v1 / PrimeSense (default) | 640×480 | 580 | 0.075 | 1/8 | 0.5–5 | 1000 | nominal Kinect v1 (ROS `kinect_calibration` model) |
//! | `paper-kinect` | the paper's Kinect | 640×480 | 587 | 0.075 | 1/8 | 0.5–5 | 1000 | the paper, §2 |
//! | `primesense` | PrimeSense Carmine / Asus Xtion | 640×480 | 570 | 0.075 | 1/8 | 0.5–5 | 1000 | OpenNI default focal length (570.3 px) |
//! | `tum-fr1` / `tum-fr2` / `tum-fr3` | TUM RGB-D (Kinect v1) | 640×480 | 517.3 / 520.9 / 535.4 | 0.075 | 1/8 | 0.5–5 | 5000 | TUM RGB-D benchmark, "Camera calibration" (depth = ROS default for fr3) |
//! | `7-scenes` | Microsoft 7-Scenes (Kinect v1) | 640×480 | 585 | 0.075 | 1/8 | 0.5–5 | 1000 | 7-Scenes `camera-intrinsics.txt` (nominal) |
//! | `nyu-v2` | NYU Depth v2 raw (Kinect v1) | 640×480 | 582.6 | 0.07537 | 1/8 | 0.5–5 | raw disparity | NYU toolbox `camera_params.m`; f·B = 43.9125 px·m from its depth conversion |
//! | `ros-default` | ROS/OpenNI default Kinect intrinsics | 640×480 | 525 | 0.075 | 1/8 | 0.5–5 | 1000 | ROS `openni_camera` default; Open3D `PrimeSenseDefault` |
//! | `pcl-openni` | PCL's OpenNI grabber default | 640×480 | 525 | 0.075 | 1/8 | 0.5–5 | 1000 | PCL OpenNI grabber, c = (320, 240) |
//! | `icl-nuim` | ICL-NUIM (synthetic, Kinect-like noise) | 640×480 | 525 | 0.075 | 1/8 | 0.5–5 | 1000 | ICL-NUIM `camera.json` |
//! | `icl-nuim-tum` | ICL-NUIM's own TUM-format archives | 640×480 | 481.2 / 480 | 0.075 | 1/8 | 0.5–5 | 5000 | ICL-NUIM web page (fx 481.20, fy −480.00: its y axis points up, see below) |
//! | `d415` | Intel RealSense D415 | 1280×720 | 912 | 0.055 | 1/32 | 0.3–10 | 1000 | D400 datasheet (baseline, 1/32 px sub-pixel); typical factory fx — calibrate your unit |
//! | `d435` | Intel RealSense D435 / D435i | 848×480 | 426 | 0.050 | 1/32 | 0.3–10 | 1000 | D400 datasheet; typical fx at 848×480 — calibrate your unit |
//! | `d455` | Intel RealSense D455 | 1280×720 | 640 | 0.095 | 1/32 | 0.6–10 | 1000 | D400 datasheet; typical fx — calibrate your unit |
//! | `oak-d` | Luxonis OAK-D (OV9282 stereo pair) | 1280×800 | 800 | 0.075 | 1/8 | 0.7–15 | 1000 | Luxonis docs: 7.5 cm baseline, 3-bit sub-pixel mode; typical fx — calibrate your unit |
//!
//! `tum-fr1` and `tum-fr2` also carry the lens distortion TUM publishes (their depth is
//! registered to the distorted colour image; [`SensorPreset::lens`], used by `sldepth track
//! --lens auto`, see [`crate::lens`]).
//!
//! The Kinect-class presets also carry the IR camera's rolling-shutter readout
//! ([`KINECT_READOUT_S`], [`SensorPreset::rolling_shutter_readout_s`]), which `sldepth track`
//! and Python's `Tracker` model when tracking against the fused model; `icl-nuim` (rendered
//! images) and the active-stereo presets have none (global shutters; the D415's rolling-shutter
//! readout is not published).
//!
//! `icl-nuim-tum` is the camera of ICL-NUIM's own TUM-format archives (`living_room_trajN_frei_png`,
//! `traj0_frei_png`, ...), whose published fy is −480: POV-Ray renders in a left-handed frame,
//! image y up. The preset keeps the focal length's size; the mirror belongs to the data set's
//! trajectories, which sldepth reads and writes through [`crate::CameraToWorld::y_reflected`]
//! (`sl_io::sequence::icl_nuim_tum_folder`). Open3D's copy of ICL-NUIM (`icl-nuim`) is
//! re-rendered at 525 px in the usual frame.
//!
//! σ_D is the paper's 0.07 px for the structured-light cameras. For the active-stereo cameras it
//! is the 0.08 px "subpixel RMS" Intel quotes for a well-textured target (D400 tuning guide);
//! OAK-D uses the same. Active-stereo depth follows the same `σ_Z = Z²·σ_D/(f·B)` law.
//!
//! ```
//! use sl_core::{Camera, preset};
//!
//! let d435 = Camera::preset("d435")?;
//! assert_eq!(d435.intrinsics.width, 848);
//! assert_eq!(d435.sensor.subpixel_steps, 32);
//! assert!(preset::find("no-such-camera").is_err());
//! # Ok::<(), sl_core::CoreError>(())
//! ```

use crate::camera::Camera;
use crate::error::{CoreError, Result};
use crate::intrinsics::Intrinsics;
use crate::lens::LensDistortion;
use crate::sensor::{DEFAULT_SIGMA_D_PX, SensorModel};

/// Disparity noise of the active-stereo presets (D400 "subpixel RMS" of a textured target).
pub const ACTIVE_STEREO_SIGMA_D_PX: f64 = 0.08;

/// How a dataset's depth files store depth.
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub enum DepthUnits {
    /// 16-bit depth with this many units per metre (1000 = millimetres, 5000 = TUM).
    UnitsPerMetre(f64),
    /// Raw Kinect disparity (NYU Depth v2 raw PGM).
    RawDisparity,
}

/// One camera or dataset: everything the noise model needs to know about it.
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub struct SensorPreset {
    /// The name `--camera NAME` and [`Camera::preset`] accept.
    pub name: &'static str,
    /// What camera or dataset this is.
    pub description: &'static str,
    /// Image width, pixels.
    pub width: usize,
    /// Image height, pixels.
    pub height: usize,
    /// Focal length x, pixels.
    pub fx: f64,
    /// Focal length y, pixels.
    pub fy: f64,
    /// Principal point x, pixels.
    pub cx: f64,
    /// Principal point y, pixels.
    pub cy: f64,
    /// Projector–camera (or stereo) baseline, metres.
    pub baseline_m: f64,
    /// Disparity sub-pixel steps per pixel (`q`: 8 for the Kinect, 32 for RealSense D400).
    pub subpixel_steps: u32,
    /// Disparity noise σ_D, pixels.
    pub sigma_d_px: f64,
    /// Nearest depth the camera reports, metres.
    pub min_depth_m: f64,
    /// Farthest depth worth using, metres.
    pub max_depth_m: f64,
    /// How the dataset's files store depth.
    pub depth_units: DepthUnits,
    /// The lens distortion of the images the depth is stored in (`None`: pinhole, or not
    /// published): TUM fr1/fr2 depth is registered to the distorted colour image.
    pub lens: Option<LensDistortion>,
    /// The depth sensor's rolling-shutter readout time, first image row to last, seconds (0: a
    /// global shutter, or a readout not known). See [`KINECT_READOUT_S`].
    pub rolling_shutter_readout_s: f64,
    /// Where the numbers come from.
    pub source: &'static str,
}

/// Nearest depth a Kinect v1 reports in default mode, metres.
pub const KINECT_MIN_DEPTH_M: f64 = 0.5;
/// Farthest Kinect v1 depth worth using, metres: beyond about 5 m the depth step exceeds 7 cm.
pub const KINECT_MAX_DEPTH_M: f64 = 5.0;

/// Rolling-shutter readout of the Kinect v1 / PrimeSense-class IR camera, first depth row to
/// last, seconds: 30 ms, an estimate (not published). The IR camera is a rolling-shutter CMOS
/// sensor (Aptina MT9M001, 1280×1024) read out at 30 frames/s, so its full readout takes most of
/// the 33.3 ms frame period, and the 480 depth rows span nearly all of its rows. On TUM fr1/rpy-200
/// (motion-capture reference) the tracker's relative pose error falls as the modelled readout
/// grows to 30–33 ms (docs/bench/track.md, session 44).
pub const KINECT_READOUT_S: f64 = 0.030;

const fn kinect(
    name: &'static str,
    description: &'static str,
    (fx, fy, cx, cy): (f64, f64, f64, f64),
    depth_units: DepthUnits,
    source: &'static str,
) -> SensorPreset {
    SensorPreset {
        name,
        description,
        width: 640,
        height: 480,
        fx,
        fy,
        cx,
        cy,
        baseline_m: 0.075,
        subpixel_steps: 8,
        sigma_d_px: DEFAULT_SIGMA_D_PX,
        min_depth_m: KINECT_MIN_DEPTH_M,
        max_depth_m: KINECT_MAX_DEPTH_M,
        depth_units,
        lens: None,
        rolling_shutter_readout_s: KINECT_READOUT_S,
        source,
    }
}

/// NYU Depth v2 depth camera focal length x, pixels (toolbox `camera_params.m`).
const NYU_FX: f64 = 582.624_481_677_379_6;
/// `f·B` implied by the NYU toolbox's raw-disparity conversion `Z = 351.3 / (1092.5 − raw)`
/// with raw in 1/8 px: `f·B = 351.3 / 8 = 43.9125` px·m.
pub const NYU_FB_PX_M: f64 = 351.3 / 8.0;

const MM: DepthUnits = DepthUnits::UnitsPerMetre(1000.0);

/// The default camera: a nominal Kinect v1.
pub const KINECT_V1: SensorPreset = kinect(
    "kinect-v1",
    "Kinect v1 / PrimeSense-class structured light (the default)",
    (580.0, 580.0, 319.5, 239.5),
    MM,
    "nominal Kinect v1: f = 580 px, B = 7.5 cm, 1/8 px disparity (ROS kinect_calibration model)",
);

/// The Kinect of the seed paper.
pub const PAPER_KINECT: SensorPreset = kinect(
    "paper-kinect",
    "the Kinect of the seed paper",
    (587.0, 587.0, 319.5, 239.5),
    MM,
    "the paper, section 2: f = 587 px, B = 75 mm, 1/8 px",
);

/// Every preset, in the order `sldepth cameras` lists them.
pub const PRESETS: &[SensorPreset] = &[
    KINECT_V1,
    PAPER_KINECT,
    kinect(
        "primesense",
        "PrimeSense Carmine / Asus Xtion PRO (also `xtion`)",
        (570.3, 570.3, 319.5, 239.5),
        MM,
        "OpenNI default depth focal length 570.3 px; PrimeSense reference design baseline 7.5 cm",
    ),
    kinect(
        "xtion",
        "Asus Xtion PRO Live (same optics as `primesense`)",
        (570.3, 570.3, 319.5, 239.5),
        MM,
        "OpenNI default depth focal length 570.3 px",
    ),
    SensorPreset {
        lens: Some(LensDistortion {
            k1: 0.2624,
            k2: -0.9531,
            p1: -0.0054,
            p2: 0.0026,
            k3: 1.1633,
        }),
        ..kinect(
            "tum-fr1",
            "TUM RGB-D freiburg1 sequences (Kinect v1; depth registered to the distorted colour image)",
            (517.3, 516.5, 318.6, 255.3),
            DepthUnits::UnitsPerMetre(5000.0),
            "TUM RGB-D benchmark, file formats / camera calibration page (fr1 intrinsics and distortion d0–d4)",
        )
    },
    SensorPreset {
        lens: Some(LensDistortion {
            k1: 0.2312,
            k2: -0.7849,
            p1: -0.0033,
            p2: -0.0001,
            k3: 0.9172,
        }),
        ..kinect(
            "tum-fr2",
            "TUM RGB-D freiburg2 sequences (Kinect v1; depth registered to the distorted colour image)",
            (520.9, 521.0, 325.1, 249.7),
            DepthUnits::UnitsPerMetre(5000.0),
            "TUM RGB-D benchmark, camera calibration page (fr2 intrinsics and distortion d0–d4)",
        )
    },
    kinect(
        "tum-fr3",
        "TUM RGB-D freiburg3 sequences (Asus Xtion, registered depth)",
        (535.4, 539.2, 320.1, 247.6),
        DepthUnits::UnitsPerMetre(5000.0),
        "TUM RGB-D benchmark, camera calibration page (fr3 intrinsics)",
    ),
    kinect(
        "7-scenes",
        "Microsoft 7-Scenes (Kinect v1, depth not registered to colour)",
        (585.0, 585.0, 320.0, 240.0),
        MM,
        "7-Scenes camera-intrinsics.txt (nominal values shipped with the dataset)",
    ),
    SensorPreset {
        baseline_m: NYU_FB_PX_M / NYU_FX,
        depth_units: DepthUnits::RawDisparity,
        ..kinect(
            "nyu-v2",
            "NYU Depth v2 raw Kinect disparity",
            (
                NYU_FX,
                582.691_032_709_886_4,
                313.044_758_708_047_3,
                238.443_896_266_203_9,
            ),
            DepthUnits::RawDisparity,
            "NYU Depth v2 toolbox camera_params.m (depth camera); f·B from its depth conversion 351.3/(1092.5 − raw)",
        )
    },
    kinect(
        "ros-default",
        "the default Kinect intrinsics of ROS/OpenNI (Open3D's PrimeSenseDefault, TUM's ROS default)",
        (525.0, 525.0, 319.5, 239.5),
        MM,
        "ROS openni_camera default calibration; Open3D PinholeCameraIntrinsicParameters.PrimeSenseDefault",
    ),
    kinect(
        "pcl-openni",
        "PCL's OpenNI grabber default (PrimeSense/Kinect via OpenNI)",
        (525.0, 525.0, 320.0, 240.0),
        MM,
        "PCL OpenNI grabber default intrinsics (fx = fy = 525, c = (320, 240))",
    ),
    SensorPreset {
        // Rendered images: every row from the frame's one pose.
        rolling_shutter_readout_s: 0.0,
        ..kinect(
            "icl-nuim",
            "ICL-NUIM synthetic living room / office (Kinect-like noise)",
            (525.0, 525.0, 319.5, 239.5),
            MM,
            "ICL-NUIM camera.json as shipped with Open3D's test data",
        )
    },
    SensorPreset {
        // Rendered images: every row from the frame's one pose.
        rolling_shutter_readout_s: 0.0,
        ..kinect(
            "icl-nuim-tum",
            "ICL-NUIM's TUM-format archives (synthetic, Kinect-like noise; fy published as -480: y up)",
            (481.2, 480.0, 319.5, 239.5),
            DepthUnits::UnitsPerMetre(5000.0),
            "ICL-NUIM web page (VaFRIC codes): fx 481.20, fy -480.00, c = (319.5, 239.5); depth / 5000 as in TUM",
        )
    },
    SensorPreset {
        name: "d415",
        description: "Intel RealSense D415 active stereo (1280x720)",
        width: 1280,
        height: 720,
        fx: 912.0,
        fy: 912.0,
        cx: 640.0,
        cy: 360.0,
        baseline_m: 0.055,
        subpixel_steps: 32,
        sigma_d_px: ACTIVE_STEREO_SIGMA_D_PX,
        min_depth_m: 0.3,
        max_depth_m: 10.0,
        depth_units: MM,
        lens: None,
        // Its OV2740 imagers have a rolling shutter, but no readout time is published: pass
        // one (`--rolling-shutter-ms`) if you know it.
        rolling_shutter_readout_s: 0.0,
        source: "Intel RealSense D400 datasheet (55 mm baseline, 1/32 px sub-pixel); typical factory fx at 1280x720 - calibrate your unit",
    },
    SensorPreset {
        name: "d435",
        description: "Intel RealSense D435 / D435i active stereo (848x480, its best-accuracy mode)",
        width: 848,
        height: 480,
        fx: 426.0,
        fy: 426.0,
        cx: 424.0,
        cy: 240.0,
        baseline_m: 0.050,
        subpixel_steps: 32,
        sigma_d_px: ACTIVE_STEREO_SIGMA_D_PX,
        min_depth_m: 0.3,
        max_depth_m: 10.0,
        depth_units: MM,
        lens: None,
        // Global-shutter imagers.
        rolling_shutter_readout_s: 0.0,
        source: "Intel RealSense D400 datasheet (50 mm baseline, 1/32 px sub-pixel); typical factory fx at 848x480 - calibrate your unit",
    },
    SensorPreset {
        name: "d455",
        description: "Intel RealSense D455 active stereo (1280x720)",
        width: 1280,
        height: 720,
        fx: 640.0,
        fy: 640.0,
        cx: 640.0,
        cy: 360.0,
        baseline_m: 0.095,
        subpixel_steps: 32,
        sigma_d_px: ACTIVE_STEREO_SIGMA_D_PX,
        min_depth_m: 0.6,
        max_depth_m: 10.0,
        depth_units: MM,
        lens: None,
        // Global-shutter imagers.
        rolling_shutter_readout_s: 0.0,
        source: "Intel RealSense D400 datasheet (95 mm baseline, 1/32 px sub-pixel); typical factory fx at 1280x720 - calibrate your unit",
    },
    SensorPreset {
        name: "oak-d",
        description: "Luxonis OAK-D stereo depth (OV9282 pair, 1280x800)",
        width: 1280,
        height: 800,
        fx: 800.0,
        fy: 800.0,
        cx: 640.0,
        cy: 400.0,
        baseline_m: 0.075,
        subpixel_steps: 8,
        sigma_d_px: ACTIVE_STEREO_SIGMA_D_PX,
        min_depth_m: 0.7,
        max_depth_m: 15.0,
        depth_units: MM,
        lens: None,
        // OV9282: global shutter.
        rolling_shutter_readout_s: 0.0,
        source: "Luxonis OAK-D docs (7.5 cm baseline, 3 fractional bits in sub-pixel mode); typical fx at 1280x800 - calibrate your unit",
    },
];

/// The preset called `name` (case-insensitive), or an error that lists every name.
pub fn find(name: &str) -> Result<&'static SensorPreset> {
    PRESETS
        .iter()
        .find(|p| p.name.eq_ignore_ascii_case(name.trim()))
        .ok_or_else(|| {
            CoreError::UnknownPreset(format!(
                "{name:?}; known cameras: {}",
                PRESETS
                    .iter()
                    .map(|p| p.name)
                    .collect::<Vec<_>>()
                    .join(", ")
            ))
        })
}

/// Which preset models a device by the name its driver reports: a word of the name (letters
/// and digits) starting with the model, so that a model's variants share its preset (a
/// `D435i` or `D435if` is a D435; a `D456` has the D455's 95 mm baseline).
const DEVICE_MODELS: &[(&str, &str)] = &[
    ("D415", "d415"),
    ("D435", "d435"),
    ("D455", "d455"),
    ("D456", "d455"),
];

/// The preset of the device called `name` as its driver reports it (`Intel RealSense D435I`
/// → `d435`; librealsense records the name in every recording), if one models it.
pub fn for_device_name(name: &str) -> Option<&'static SensorPreset> {
    let upper = name.to_ascii_uppercase();
    let words: Vec<&str> = upper.split(|c: char| !c.is_ascii_alphanumeric()).collect();
    DEVICE_MODELS
        .iter()
        .find(|(model, _)| {
            words.iter().any(|w| {
                w.strip_prefix(model)
                    .is_some_and(|rest| rest.chars().all(|c| c.is_ascii_alphabetic()))
            })
        })
        .and_then(|(_, preset)| find(preset).ok())
}

/// The names of every preset.
pub fn names() -> impl Iterator<Item = &'static str> {
    PRESETS.iter().map(|p| p.name)
}

impl SensorPreset {
    /// The pinhole intrinsics.
    pub fn intrinsics(&self) -> Intrinsics {
        Intrinsics {
            width: self.width,
            height: self.height,
            fx: self.fx,
            fy: self.fy,
            cx: self.cx,
            cy: self.cy,
        }
    }

    /// The disparity sensor model.
    pub fn sensor(&self) -> SensorModel {
        SensorModel {
            focal_px: self.fx,
            baseline_m: self.baseline_m,
            subpixel_steps: self.subpixel_steps,
            sigma_d_px: self.sigma_d_px,
        }
    }

    /// Intrinsics and sensor model together.
    pub fn camera(&self) -> Camera {
        Camera {
            intrinsics: self.intrinsics(),
            sensor: self.sensor(),
        }
    }
}

impl Camera {
    /// The camera of the preset called `name` (see [`PRESETS`]); an unknown name is an error
    /// that lists the known ones.
    pub fn preset(name: &str) -> Result<Self> {
        Ok(find(name)?.camera())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_preset_is_a_valid_camera_with_a_unique_name() {
        for (i, p) in PRESETS.iter().enumerate() {
            let cam = p.camera();
            cam.intrinsics.validate().unwrap();
            cam.sensor.validate().unwrap();
            assert!(
                p.min_depth_m > 0.0 && p.max_depth_m > p.min_depth_m,
                "{}",
                p.name
            );
            assert!(!p.source.is_empty() && !p.description.is_empty());
            assert!(PRESETS[..i].iter().all(|q| q.name != p.name), "{}", p.name);
        }
    }

    #[test]
    fn kinect_presets_match_the_constructors() {
        assert_eq!(Camera::preset("kinect-v1").unwrap(), Camera::kinect_v1());
        assert_eq!(
            Camera::preset("paper-kinect").unwrap(),
            Camera::paper_kinect()
        );
        assert_eq!(Camera::preset("KINECT-V1").unwrap(), Camera::kinect_v1());
    }

    #[test]
    fn rolling_shutter_readouts_fit_in_a_frame_interval() {
        for p in PRESETS {
            assert!(
                (0.0..1.0 / 30.0).contains(&p.rolling_shutter_readout_s),
                "{}: {}",
                p.name,
                p.rolling_shutter_readout_s
            );
        }
        for name in ["kinect-v1", "tum-fr1", "7-scenes", "nyu-v2", "primesense"] {
            assert_eq!(
                find(name).unwrap().rolling_shutter_readout_s,
                KINECT_READOUT_S,
                "{name}"
            );
        }
        for name in ["icl-nuim", "icl-nuim-tum", "d435", "d455", "oak-d", "d415"] {
            assert_eq!(find(name).unwrap().rolling_shutter_readout_s, 0.0, "{name}");
        }
    }

    #[test]
    fn device_names_find_their_presets() {
        let of = |n: &str| for_device_name(n).map(|p| p.name);
        assert_eq!(of("Intel RealSense D435"), Some("d435"));
        assert_eq!(of("Intel RealSense D435I"), Some("d435"));
        assert_eq!(of("Intel RealSense D435IF"), Some("d435"));
        assert_eq!(of("Intel RealSense D415"), Some("d415"));
        assert_eq!(of("Intel RealSense D456"), Some("d455"));
        // Another model, or a longer number, is not one of them.
        assert_eq!(of("Intel RealSense D405"), None);
        assert_eq!(of("Intel RealSense L515"), None);
        assert_eq!(of("Intel RealSense D4350"), None);
        assert_eq!(of("Stereo Module"), None);
    }

    #[test]
    fn unknown_name_lists_the_known_ones() {
        let e = Camera::preset("kinect-v3").unwrap_err().to_string();
        for n in names() {
            assert!(e.contains(n), "{e}");
        }
    }

    #[test]
    fn nyu_preset_has_the_toolbox_fb() {
        let s = find("nyu-v2").unwrap().sensor();
        assert!((s.fb() - 43.9125).abs() < 1e-9, "{}", s.fb());
    }
}
