//! `sldepth.extract_planes` and `sldepth.motion`: disparity-domain planes and the camera motion
//! they give.

use std::sync::{Mutex, PoisonError};

use numpy::PyArray2;
use pyo3::prelude::*;
use sl_planes::{PlaneConfig, PlaneExtractor, PlaneInfo, RegionExplanation};
use sl_track::DepthMotionConfig;

use crate::arrays::{camera_for_depth, depth_input, depth_input_named, image_array, pose_array};
use crate::camera::{PyCamera, camera_or_default};
use crate::errors::value_error;
use crate::repr::{py_bool, py_opt};
use crate::threads::compute;

/// One plane found in a depth map (camera frame, metres; read-only attributes).
#[pyclass(name = "Plane", module = "sldepth", frozen, get_all)]
#[derive(Debug, Clone)]
pub struct PyPlane {
    /// Label of the plane's pixels in the label image (1, 2, …).
    id: u16,
    /// Unit normal (x, y, z), pointing towards the camera: ``normal·X + offset_m = 0``.
    normal: (f64, f64, f64),
    /// Distance of the plane from the camera centre, metres.
    offset_m: f64,
    /// Disparity as an affine function of the pixel, ``d = a·x + b·y + c`` (pixels).
    disparity_affine: (f64, f64, f64),
    /// Number of pixels with this label.
    pixels: usize,
    /// RMS disparity residual of the pixels the plane was fitted on (a surface's bent pieces
    /// joined to it take its label but not its fit), pixels.
    rms_px: f64,
    /// RMS distance of those pixels' points from the plane, metres.
    rms_m: f64,
    /// Centroid of those pixels' points, metres.
    centroid_m: (f64, f64, f64),
    /// Standard uncertainty of the normal from the sensor's noise model: the RMS angle between
    /// the fitted and the true normal, degrees (``inf`` when undetermined, which includes 61.2°
    /// or more: the RMS angle of a normal guessed on the hemisphere facing the camera). Small,
    /// far or narrow planes are the uncertain ones, and the ones that are not found again in
    /// later frames.
    normal_sigma_deg: f64,
    /// Standard uncertainty of the plane's position along its normal at ``centroid_m``, metres.
    offset_sigma_m: f64,
}

#[pymethods]
impl PyPlane {
    fn __repr__(&self) -> String {
        let n = self.normal;
        format!(
            "Plane(id={}, normal=({:.4}, {:.4}, {:.4}), offset_m={:.4}, pixels={}, rms_px={:.4}, \
             normal_sigma_deg={:.3})",
            self.id, n.0, n.1, n.2, self.offset_m, self.pixels, self.rms_px, self.normal_sigma_deg
        )
    }
}

impl From<&PlaneInfo> for PyPlane {
    fn from(p: &PlaneInfo) -> Self {
        let n = p.plane.normal;
        let c = p.centroid_m;
        Self {
            id: p.id,
            normal: (n.x, n.y, n.z),
            offset_m: p.plane.offset_m,
            disparity_affine: (p.affine.a, p.affine.b, p.affine.c),
            pixels: p.pixels,
            rms_px: p.rms_px,
            rms_m: p.rms_m,
            centroid_m: (c.x, c.y, c.z),
            normal_sigma_deg: p.normal_sigma_deg,
            offset_sigma_m: p.offset_sigma_m,
        }
    }
}

/// Extractors kept between calls, so that their scratch buffers (a few MB for 640×480) are
/// allocated once, as a Rust user keeping a `PlaneExtractor` would. A call takes one out for
/// its whole duration and puts it back: not a thread-local, because an extraction runs on the
/// pool (its final pass in parallel), and a worker waiting for one of its bands may start
/// another Python thread's extraction on the same thread.
static EXTRACTORS: Mutex<Vec<PlaneExtractor>> = Mutex::new(Vec::new());

/// Extractors kept at most (more concurrent calls make theirs and drop them).
const KEPT_EXTRACTORS: usize = 4;

/// Runs `f` with a kept extractor for `config` (made or replaced as needed).
fn with_extractor<T>(
    config: PlaneConfig,
    f: impl FnOnce(&mut PlaneExtractor) -> sl_planes::Result<T>,
) -> sl_planes::Result<T> {
    let kept = EXTRACTORS
        .lock()
        .unwrap_or_else(PoisonError::into_inner)
        .pop();
    let mut extractor = match kept {
        Some(e) if *e.config() == config => e,
        _ => PlaneExtractor::new(config)?,
    };
    let out = f(&mut extractor);
    let mut kept = EXTRACTORS.lock().unwrap_or_else(PoisonError::into_inner);
    if kept.len() < KEPT_EXTRACTORS {
        kept.push(extractor);
    }
    out
}

/// The extractor's parameters a Python caller may set (the others keep their defaults).
#[derive(Debug, Clone, Copy, Default)]
struct PlaneParams {
    threshold_px: Option<f64>,
    min_pixels: Option<usize>,
    log_threshold_px: Option<f64>,
    log_sigma_px: Option<f64>,
    bend_px_per_px2: Option<f64>,
    max_normal_sigma_deg: Option<f64>,
    split_creases: Option<bool>,
    refine_seams: Option<bool>,
    give_back_taken_in: Option<bool>,
    estimate_noise: Option<bool>,
}

impl PlaneParams {
    fn config(&self) -> PyResult<PlaneConfig> {
        let mut c = PlaneConfig::default();
        c.threshold_px = self.threshold_px.unwrap_or(c.threshold_px);
        c.min_pixels = self.min_pixels.unwrap_or(c.min_pixels);
        c.log_threshold_px = self.log_threshold_px.unwrap_or(c.log_threshold_px);
        c.log_sigma_px = self.log_sigma_px.unwrap_or(c.log_sigma_px);
        c.bend_px_per_px2 = self.bend_px_per_px2.unwrap_or(c.bend_px_per_px2);
        c.max_normal_sigma_deg = self.max_normal_sigma_deg.unwrap_or(c.max_normal_sigma_deg);
        c.split_creases = self.split_creases.unwrap_or(c.split_creases);
        c.refine_seams = self.refine_seams.unwrap_or(c.refine_seams);
        c.give_back_taken_in = self.give_back_taken_in.unwrap_or(c.give_back_taken_in);
        c.estimate_noise = self.estimate_noise.unwrap_or(c.estimate_noise);
        c.validate().map_err(value_error)?;
        Ok(c)
    }
}

/// A region of valid depth that no plane took, and the test that turned it down (read-only
/// attributes; ``explain_planes``).
#[pyclass(name = "UnlabelledRegion", module = "sldepth", frozen, get_all)]
#[derive(Debug, Clone)]
pub struct PyUnlabelledRegion {
    /// Valid pixels of the region.
    pixels: usize,
    /// Bounding box ``(x0, y0, x1, y1)``, pixels (inclusive).
    bbox_px: (usize, usize, usize, usize),
    /// The test: ``"NotPlanarLog"``, ``"ResidualNotWhite"``, ``"SeveralSurfaces"``,
    /// ``"Unseeded"``, ``"Uncertain"``, ``"GivenBack"`` or ``"NoiseBeyondThreshold"`` (the
    /// frame's measured disparity noise exceeds ``threshold_px``: no plane was extracted);
    /// the names of ``sldepth planes --explain --json``.
    reason: String,
    /// What the reason means, in words.
    why: String,
    /// Share of its cells that fail the LoG planarity test.
    log_rejected_fraction: f64,
    /// Share of its usable 16×16-pixel patches whose residual exceeds the sensor noise.
    residual_rejected_fraction: f64,
    /// RMS disparity residual of one affine fit of the region, pixels (``None`` without a fit).
    rms_px: Option<f64>,
}

#[pymethods]
impl PyUnlabelledRegion {
    fn __repr__(&self) -> String {
        format!(
            "UnlabelledRegion(pixels={}, bbox_px={:?}, reason={:?})",
            self.pixels, self.bbox_px, self.reason
        )
    }
}

impl From<&RegionExplanation> for PyUnlabelledRegion {
    fn from(r: &RegionExplanation) -> Self {
        let [x0, y0, x1, y1] = r.bbox_px;
        Self {
            pixels: r.pixels,
            bbox_px: (x0, y0, x1, y1),
            reason: format!("{:?}", r.reason),
            why: r.reason.describe().to_string(),
            log_rejected_fraction: r.log_rejected_fraction,
            residual_rejected_fraction: r.residual_rejected_fraction,
            rms_px: r.rms_px.is_finite().then_some(r.rms_px),
        }
    }
}

/// Extracts planes in the disparity domain (one fixed threshold at every depth, the paper's
/// section 3.4). Returns ``(labels, planes)``: a uint16 (H, W) label image (0 = no plane,
/// i = ``planes[i-1]``) and a list of ``Plane``. Frames of a camera resampled from its sensor
/// by a whole factor (``Camera.resampled(0.5)``: a 320×240 stream of a 640×480 Kinect) are
/// extracted on the sensor's grid and give the planes of the full frame; ``min_pixels``
/// (default 1000) counts the sensor's pixels. ``threshold_px`` (0.5) is the residual
/// threshold τ, ``log_threshold_px`` (0.1) and ``log_sigma_px`` (2) the LoG planarity test's
/// threshold and scale, all in disparity pixels; ``bend_px_per_px2`` (7.7e-5) the largest
/// curvature of a surface's disparity the sensor's distortion makes: adjacent planes whose
/// slopes agree at their border and whose fits differ by no more than this bend allows are one
/// surface and take one label (0 = never). ``max_normal_sigma_deg`` (default: none) reports
/// only the planes whose normal the noise model determines within that many degrees
/// (``Plane.normal_sigma_deg``), leaving the others' pixels unlabelled. ``refine_seams``
/// (False) re-decides the pixels along a crease with the two planes' local fits where a
/// plane's whole fit is off there (a surface bent by the sensor's distortion, whose small
/// neighbour would take a strip of it; 0.1–0.3 ms per 640×480 real frame).
/// ``give_back_taken_in`` (False) leaves unlabelled the pieces of a neighbouring surface a
/// plane took in (8×8-pixel blocks off a quadratic fit of the plane by more than the noise
/// model allows, in connected pieces of at least 256 pixels) and refits the plane without
/// them (0.4–0.7 ms per 640×480 real frame). ``estimate_noise``
/// (True) measures the frame's own noise on its 16×16- and 32×32-pixel patches and, where it exceeds the
/// camera's model significantly, runs every noise test with the measured noise (the camera's
/// ``sigma_d_px`` is a floor, never lowered): a sensor noisier than its camera says otherwise
/// comes out in pieces and spurious planes. ``sldepth planes`` has the same options.
#[pyfunction]
#[pyo3(signature = (depth, camera = None, *, threshold_px = None, min_pixels = None, log_threshold_px = None, log_sigma_px = None, bend_px_per_px2 = None, max_normal_sigma_deg = None, split_creases = None, refine_seams = None, give_back_taken_in = None, estimate_noise = None, depth_scale = None))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn extract_planes<'py>(
    py: Python<'py>,
    depth: &Bound<'py, PyAny>,
    camera: Option<&PyCamera>,
    #[pyo3(from_py_with = crate::reals::threshold_px)] threshold_px: Option<f64>,
    #[pyo3(from_py_with = crate::ints::opt_int)] min_pixels: Option<usize>,
    #[pyo3(from_py_with = crate::reals::log_threshold_px)] log_threshold_px: Option<f64>,
    #[pyo3(from_py_with = crate::reals::log_sigma_px)] log_sigma_px: Option<f64>,
    #[pyo3(from_py_with = crate::reals::bend_px_per_px2)] bend_px_per_px2: Option<f64>,
    #[pyo3(from_py_with = crate::reals::max_normal_sigma_deg)] max_normal_sigma_deg: Option<f64>,
    split_creases: Option<bool>,
    refine_seams: Option<bool>,
    give_back_taken_in: Option<bool>,
    estimate_noise: Option<bool>,
    #[pyo3(from_py_with = crate::reals::depth_scale)] depth_scale: Option<f64>,
) -> PyResult<(Bound<'py, PyArray2<u16>>, Vec<PyPlane>)> {
    let params = PlaneParams {
        threshold_px,
        min_pixels,
        log_threshold_px,
        log_sigma_px,
        bend_px_per_px2,
        max_normal_sigma_deg,
        split_creases,
        refine_seams,
        give_back_taken_in,
        estimate_noise,
    };
    let (labels, planes, _) = run_extraction(py, depth, camera, params, depth_scale, None)?;
    Ok((labels, planes))
}

/// ``extract_planes`` that also says why each region of valid depth that no plane took was
/// turned down (``sldepth planes --explain``): returns ``(labels, planes, regions)``, the
/// regions (``UnlabelledRegion``) of at least ``min_region_pixels`` valid pixels (default:
/// ``min_pixels``), largest first. Read from the extraction's own buffers, at no second
/// extraction.
#[pyfunction]
#[pyo3(signature = (depth, camera = None, *, threshold_px = None, min_pixels = None, log_threshold_px = None, log_sigma_px = None, bend_px_per_px2 = None, max_normal_sigma_deg = None, split_creases = None, refine_seams = None, give_back_taken_in = None, estimate_noise = None, min_region_pixels = None, depth_scale = None))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn explain_planes<'py>(
    py: Python<'py>,
    depth: &Bound<'py, PyAny>,
    camera: Option<&PyCamera>,
    #[pyo3(from_py_with = crate::reals::threshold_px)] threshold_px: Option<f64>,
    #[pyo3(from_py_with = crate::ints::opt_int)] min_pixels: Option<usize>,
    #[pyo3(from_py_with = crate::reals::log_threshold_px)] log_threshold_px: Option<f64>,
    #[pyo3(from_py_with = crate::reals::log_sigma_px)] log_sigma_px: Option<f64>,
    #[pyo3(from_py_with = crate::reals::bend_px_per_px2)] bend_px_per_px2: Option<f64>,
    #[pyo3(from_py_with = crate::reals::max_normal_sigma_deg)] max_normal_sigma_deg: Option<f64>,
    split_creases: Option<bool>,
    refine_seams: Option<bool>,
    give_back_taken_in: Option<bool>,
    estimate_noise: Option<bool>,
    #[pyo3(from_py_with = crate::ints::opt_int)] min_region_pixels: Option<usize>,
    #[pyo3(from_py_with = crate::reals::depth_scale)] depth_scale: Option<f64>,
) -> PyResult<Explained<'py>> {
    let params = PlaneParams {
        threshold_px,
        min_pixels,
        log_threshold_px,
        log_sigma_px,
        bend_px_per_px2,
        max_normal_sigma_deg,
        split_creases,
        refine_seams,
        give_back_taken_in,
        estimate_noise,
    };
    run_extraction(
        py,
        depth,
        camera,
        params,
        depth_scale,
        Some(min_region_pixels),
    )
}

/// Labels, planes and unlabelled regions, as `explain_planes` returns them.
type Explained<'py> = (
    Bound<'py, PyArray2<u16>>,
    Vec<PyPlane>,
    Vec<PyUnlabelledRegion>,
);

/// The labels and planes of one extraction and, when `explain` is given, the unlabelled
/// regions of at least that many pixels (`None` inside: the configuration's `min_pixels`).
fn run_extraction<'py>(
    py: Python<'py>,
    depth: &Bound<'py, PyAny>,
    camera: Option<&PyCamera>,
    params: PlaneParams,
    depth_scale: Option<f64>,
    explain: Option<Option<usize>>,
) -> PyResult<Explained<'py>> {
    let camera = camera_or_default(camera);
    let config = params.config()?;
    let explain = explain.map(|min| min.unwrap_or(config.min_pixels));
    let input = depth_input(depth, depth_scale)?;
    let view = input.view()?;
    let camera = camera_for_depth(&view, &camera, "depth")?;
    let (seg, regions) = compute(py, || {
        with_extractor(config, |e| {
            let seg = e.extract_depth(view, &camera)?;
            let regions = match explain {
                Some(min) => e.explain_unlabelled(&seg, min),
                None => Vec::new(),
            };
            Ok((seg, regions))
        })
    })
    .map_err(value_error)?;
    let planes = seg.planes.iter().map(PyPlane::from).collect();
    let regions = regions.iter().map(PyUnlabelledRegion::from).collect();
    Ok((image_array(py, seg.labels)?, planes, regions))
}

/// The camera motion between two depth frames (read-only attributes).
#[pyclass(name = "Motion", module = "sldepth", frozen, get_all)]
#[derive(Debug)]
pub struct PyMotion {
    /// Whether a motion was determined (verified on the depth data unless ``verify=False``).
    determined: bool,
    /// (4, 4) float64 matrix with ``X_a = T·X_b`` (frame B's camera coordinates into frame A's),
    /// or None when undetermined. Its translation is 0 when not determined by the planes.
    matrix: Option<Py<PyArray2<f64>>>,
    /// Rotation angle, degrees (None when undetermined).
    rotation_deg: Option<f64>,
    /// Whether the translation is determined.
    translation_determined: bool,
    /// ``"verified"``, ``"unverified"``, ``"ambiguous"`` … or ``"undetermined"``.
    confidence: String,
    /// Why the motion is undetermined (None when determined).
    reason: Option<String>,
    /// Share of the overlapping points the estimate explains (verified estimates).
    inlier_fraction: Option<f64>,
    /// Whether the ICP refinement was kept (None without ``icp``).
    icp_accepted: Option<bool>,
    /// Planes found in frame A and B.
    planes_a: usize,
    /// Planes found in frame B.
    planes_b: usize,
    /// Matched plane pairs.
    matched_planes: usize,
    /// When the verification could not decide: the (4, 4) float64 alignments ``X_a = T·X_b``
    /// the two frames do not rule out, best first, each more than 15° from those before it (at
    /// most three; more evidence, such as a fused model, can tell them apart). Empty otherwise.
    candidates: Vec<Py<PyArray2<f64>>>,
}

#[pymethods]
impl PyMotion {
    fn __repr__(&self) -> String {
        format!(
            "Motion(determined={}, confidence={:?}, rotation_deg={}, icp_accepted={})",
            py_bool(self.determined),
            self.confidence,
            py_opt(self.rotation_deg),
            py_opt(self.icp_accepted.map(py_bool))
        )
    }
}

/// Camera motion between two depth frames of one camera from matched planes (the paper's
/// section 3.5), verified against both depth maps (``verify``), optionally refined by
/// point-to-plane ICP that is kept only when the depth data confirm it (``icp``). An
/// undetermined motion is returned with ``determined = False`` and the reason, never a guess.
/// Frames whose size is the camera's divided by a whole number up to 8 are its sensor decimated
/// (``camera.resampled(1/n)``), as ``sldepth motion`` reads them.
#[pyfunction]
#[pyo3(signature = (depth_a, depth_b, camera = None, *, icp = true, verify = true, depth_scale = None))]
pub(crate) fn motion(
    py: Python<'_>,
    depth_a: &Bound<'_, PyAny>,
    depth_b: &Bound<'_, PyAny>,
    camera: Option<&PyCamera>,
    icp: bool,
    verify: bool,
    #[pyo3(from_py_with = crate::reals::depth_scale)] depth_scale: Option<f64>,
) -> PyResult<PyMotion> {
    let camera = camera_or_default(camera);
    let a = depth_input_named(depth_a, "depth_a", depth_scale)?;
    let b = depth_input_named(depth_b, "depth_b", depth_scale)?;
    let (va, vb) = (a.view()?, b.view()?);
    let camera = camera_for_depth(&va, &camera, "depth_a")?;
    if (vb.width(), vb.height()) != (va.width(), va.height()) {
        return Err(value_error(format!(
            "depth_b is {}x{} (W x H) but depth_a is {}x{}: both frames come from one camera",
            vb.width(),
            vb.height(),
            va.width(),
            va.height()
        )));
    }
    let (da, db) = (va.to_image(), vb.to_image());
    let mut cfg = DepthMotionConfig::default();
    cfg.icp = icp;
    cfg.verify = verify;
    let r = compute(py, || {
        sl_track::motion_between_depths(&da, &db, &camera, &cfg)
    })
    .map_err(value_error)?;
    let pose = r.pose();
    Ok(PyMotion {
        determined: pose.is_some(),
        matrix: pose
            .as_ref()
            .map(|p| pose_array(py, &p.to_matrix()))
            .transpose()?
            .map(Bound::unbind),
        rotation_deg: pose.map(|p| p.rotation_angle_deg()),
        translation_determined: r.translation_m().is_some(),
        confidence: match &r.motion {
            Ok(m) => m.confidence.as_str().to_string(),
            Err(_) => "undetermined".to_string(),
        },
        reason: r.motion.as_ref().err().map(ToString::to_string),
        inlier_fraction: r
            .motion
            .as_ref()
            .ok()
            .and_then(|m| m.verification.as_ref().map(|v| v.inlier_fraction)),
        icp_accepted: r.icp.as_ref().map(|o| o.accepted),
        planes_a: r.planes_a.len(),
        planes_b: r.planes_b.len(),
        matched_planes: r.motion.as_ref().map_or(0, |m| m.matches.len()),
        candidates: r
            .candidates
            .iter()
            .map(|c| pose_array(py, &c.to_matrix()).map(Bound::unbind))
            .collect::<PyResult<_>>()?,
    })
}
