//! `sldepth.TsdfVolume` and `sldepth.Mesh`: 1/Z⁴-weighted TSDF fusion and marching cubes.

use std::path::PathBuf;
use std::sync::RwLock;

use numpy::ndarray::{Array1, Array2, Array3};
use numpy::{IntoPyArray, PyArray1, PyArray2, PyArray3, PyArrayMethods, PyReadonlyArray2};
use pyo3::prelude::*;
use sl_core::{Mesh, VertexScalar};
use sl_io::PlyFormat;
use sl_tsdf::{
    Axis, DepthLookup, MeshConfig, RaycastConfig, SliceSpec, Truncation, TsdfConfig, TsdfVolume,
    WeightMode,
};

use crate::arrays::{
    camera_for_depth, depth_array, depth_input, image_array, pose_input, rows3_array,
};
use crate::camera::PyCamera;
use crate::errors::{SlDepthIOError, value_error};
use crate::threads::{compute, compute_read, compute_write};

/// A sparse TSDF volume (8³-voxel blocks allocated near observed surfaces) that merges depth
/// frames with noise weights and extracts a mesh by marching cubes.
///
/// ``weight``: ``"inv-z4"`` (the paper's 1/Z⁴ = 1/σ_Z² weights, default), ``"inv-z2"``,
/// ``"uniform"``, or ``"sensor"`` (inverse σ_Z² of the camera of the first ``integrate``; a
/// later frame of a camera with another noise model raises ``ValueError``).
/// ``depth_lookup``: ``"nearest"`` (each voxel reads the pixel nearest its projection, default)
/// or ``"bilinear"`` (inverse depth interpolated between the four pixels around it when they lie
/// on one surface: no staircase on surfaces seen at grazing angles, 1.6–2× the integration time).
/// ``truncation``: ``"sensor"`` (default) — the band of an observation at depth Z is
/// ``max(trunc_m, trunc_sigmas·σ_Z(Z))`` up to 0.12 m, with σ_Z from the noise model of the camera
/// of the first ``integrate`` (a D435's band is 2.3× a Kinect's at the same depth) — or
/// ``"fixed"`` (``trunc_m`` everywhere, as Open3D's ``sdf_trunc``). With ``estimate_noise``
/// (default) the first frame's own disparity noise is measured against that camera's model (on
/// its 16×16- and 32×32-pixel patches, as ``extract_planes`` and ``Tracker`` do) and a sensor significantly
/// noisier than its model gets the band of its measured σ_D; ``noise_scale`` says by how much.
/// A later frame of another camera keeps the first frame's band.
/// ``memory_budget_bytes`` caps the blocks; integration past it raises ``ValueError`` and leaves
/// the volume unchanged. One volume may be used from several Python threads: reads (meshes,
/// raycasts, slices) run side by side, an ``integrate`` waits for them and they for it.
#[pyclass(name = "TsdfVolume", module = "sldepth", frozen)]
#[derive(Debug)]
pub struct PyTsdfVolume {
    state: RwLock<VolumeState>,
}

/// What a [`PyTsdfVolume`] guards.
#[derive(Debug)]
struct VolumeState {
    volume: TsdfVolume,
    sensor_weight: bool,
    /// Whether a sensor-adaptive band follows the first frame's measured noise.
    estimate_noise: bool,
    /// The first frame's pixel variance over its camera's model (1 until measured).
    noise_scale: f64,
}

/// The message of a volume whose lock holder panicked (no call of this crate should).
const POISONED: &str = "the volume is unusable: a call on it failed midway";

impl PyTsdfVolume {
    /// Runs `f` on the fused volume (shared with other readers), with the GIL released.
    pub(crate) fn read<T: Send>(
        &self,
        py: Python<'_>,
        f: impl FnOnce(&TsdfVolume) -> T + Send,
    ) -> PyResult<T> {
        compute_read(py, &self.state, |s| f(&s.volume)).map_err(|_| value_error(POISONED))
    }
}

#[pymethods]
impl PyTsdfVolume {
    #[new]
    #[pyo3(signature = (voxel_m = 0.004, trunc_m = 0.02, weight = "inv-z4", *, max_depth_m = 4.0, min_depth_m = 0.1, memory_budget_bytes = 4usize << 30, depth_lookup = "nearest", truncation = "sensor", trunc_sigmas = 3.0, estimate_noise = true))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        #[pyo3(from_py_with = crate::reals::voxel_m)] voxel_m: f64,
        #[pyo3(from_py_with = crate::reals::trunc_m)] trunc_m: f64,
        weight: &str,
        #[pyo3(from_py_with = crate::reals::max_depth_m)] max_depth_m: f64,
        #[pyo3(from_py_with = crate::reals::min_depth_m)] min_depth_m: f64,
        #[pyo3(from_py_with = crate::ints::int)] memory_budget_bytes: usize,
        depth_lookup: &str,
        truncation: &str,
        #[pyo3(from_py_with = crate::reals::trunc_sigmas)] trunc_sigmas: f64,
        estimate_noise: bool,
    ) -> PyResult<Self> {
        let sensor_weight = weight == "sensor";
        let weight = if sensor_weight {
            // Replaced by the camera's model at the first integration.
            WeightMode::sensor_variance(sl_core::SensorModel::kinect_v1())
        } else {
            WeightMode::parse(weight).map_err(value_error)?
        };
        let mut params = TsdfConfig::default();
        params.voxel_m = voxel_m;
        params.trunc_m = trunc_m;
        params.weight = weight;
        params.max_depth_m = max_depth_m;
        params.min_depth_m = min_depth_m;
        params.memory_budget_bytes = memory_budget_bytes;
        params.depth_lookup = depth_lookup.parse::<DepthLookup>().map_err(value_error)?;
        match (truncation, &mut params.truncation) {
            // The default's sensor-adaptive band; its sensor is replaced by the first frame's
            // camera (and its measured noise) at its integration.
            ("sensor", Truncation::SensorAdaptive { sigmas, .. }) => *sigmas = trunc_sigmas,
            ("fixed", t) => *t = Truncation::Fixed,
            (other, _) => {
                return Err(value_error(format!(
                    "truncation {other:?}: expected \"sensor\" or \"fixed\""
                )));
            }
        }
        Ok(Self {
            state: RwLock::new(VolumeState {
                volume: TsdfVolume::new(params).map_err(value_error)?,
                sensor_weight,
                estimate_noise,
                noise_scale: 1.0,
            }),
        })
    }

    /// Integrates one depth frame (metres, (H, W)) seen by ``camera`` at ``pose``, a (4, 4)
    /// camera-to-world matrix. Returns the number of blocks allocated by this frame. A frame
    /// whose size is the camera's divided by a whole number up to 8 is the camera's sensor
    /// decimated (``camera.resampled(1/n)``), as ``sldepth fuse`` reads it.
    #[pyo3(signature = (depth, camera, pose, *, depth_scale = None))]
    fn integrate(
        &self,
        py: Python<'_>,
        depth: &Bound<'_, PyAny>,
        camera: &PyCamera,
        pose: &Bound<'_, PyAny>,
        #[pyo3(from_py_with = crate::reals::depth_scale)] depth_scale: Option<f64>,
    ) -> PyResult<usize> {
        let pose = pose_input(pose)?;
        let input = depth_input(depth, depth_scale)?;
        let view = input.view()?;
        let camera = camera_for_depth(&view, &camera.inner, "depth")?;
        let stats = compute_write(py, &self.state, |state| -> Result<_, String> {
            if state.volume.frame_count() == 0 {
                first_frame(state, &view, &camera)?;
            } else if state.sensor_weight
                && let WeightMode::SensorVariance { sensor, .. } = state.volume.params().weight
                && sensor != camera.sensor
            {
                return Err(format!(
                    "a TsdfVolume(weight=\"sensor\") weighs every frame by the noise model of the camera of its first frame (f = {} px, B = {} m, sigma_d_px = {}); this camera's differs (f = {} px, B = {} m, sigma_d_px = {}): fuse each sensor in its own volume, or use weight=\"inv-z4\"",
                    sensor.focal_px,
                    sensor.baseline_m,
                    sensor.sigma_d_px,
                    camera.sensor.focal_px,
                    camera.sensor.baseline_m,
                    camera.sensor.sigma_d_px
                ));
            }
            state
                .volume
                .integrate(view, &camera.intrinsics, &pose)
                .map_err(|e| e.to_string())
        })
        .map_err(|_| value_error(POISONED))?
        .map_err(value_error)?;
        Ok(stats.blocks_allocated)
    }

    /// Extracts the zero crossing as a triangle mesh (marching cubes over the observed voxels;
    /// cubes with a corner weight below ``min_weight`` are skipped).
    #[pyo3(signature = (min_weight = 0.0))]
    fn extract_mesh(
        &self,
        py: Python<'_>,
        #[pyo3(from_py_with = crate::reals::min_weight)] min_weight: f32,
    ) -> PyResult<PyMesh> {
        let opts = mesh_config(min_weight)?;
        let mesh = self.read(py, |volume| volume.extract_mesh(&opts))?;
        PyMesh::from_mesh(py, mesh)
    }

    /// Extracts the mesh and writes it as PLY (binary unless ``ascii``), atomically.
    #[pyo3(signature = (path, min_weight = 0.0, ascii = false))]
    fn write_ply(
        &self,
        py: Python<'_>,
        path: PathBuf,
        #[pyo3(from_py_with = crate::reals::min_weight)] min_weight: f32,
        ascii: bool,
    ) -> PyResult<()> {
        let opts = mesh_config(min_weight)?;
        self.read(py, |volume| {
            let mesh = volume.extract_mesh(&opts);
            sl_tsdf::io::write_mesh_ply(&path, &mesh, ply_format(ascii))
        })?
        .map_err(|e| SlDepthIOError::new_err(e.to_string()))
    }

    /// Renders the fused surface seen by ``camera`` at ``pose`` ((4, 4) camera-to-world): for
    /// every pixel the first zero crossing of F along its ray between ``min_depth_m`` and
    /// ``max_depth_m``. Returns ``(depth, points, normals, weights)``: depth (H, W) float32
    /// camera-frame metres (0 = no hit), points and normals (H, W, 3) float32 in world
    /// coordinates (NaN where no hit; normals are unit and face the camera), weights (H, W)
    /// float32 fused weights (0 = no hit).
    #[pyo3(signature = (camera, pose, *, min_depth_m = 0.1, max_depth_m = 4.0))]
    #[allow(clippy::type_complexity)]
    fn raycast<'py>(
        &self,
        py: Python<'py>,
        camera: &PyCamera,
        pose: &Bound<'_, PyAny>,
        #[pyo3(from_py_with = crate::reals::min_depth_m)] min_depth_m: f64,
        #[pyo3(from_py_with = crate::reals::max_depth_m)] max_depth_m: f64,
    ) -> PyResult<(
        Bound<'py, PyArray2<f32>>,
        Bound<'py, PyArray3<f32>>,
        Bound<'py, PyArray3<f32>>,
        Bound<'py, PyArray2<f32>>,
    )> {
        let camera = camera.inner;
        let pose = pose_input(pose)?;
        let mut config = RaycastConfig::default();
        config.min_depth_m = min_depth_m;
        config.max_depth_m = max_depth_m;
        let r = self
            .read(py, |volume| {
                volume.raycast(&pose, &camera.intrinsics, &config)
            })?
            .map_err(value_error)?;
        let (w, h) = (r.width, r.height);
        let grid3 = |rows: Vec<[f32; 3]>| -> PyResult<Bound<'py, PyArray3<f32>>> {
            let flat: Vec<f32> = rows.into_iter().flatten().collect();
            Ok(Array3::from_shape_vec((h, w, 3), flat)
                .map_err(value_error)?
                .into_pyarray(py))
        };
        let points = grid3(r.points.iter().map(|p| [p.x, p.y, p.z]).collect())?;
        let normals = grid3(r.normals.iter().map(|n| [n.x, n.y, n.z]).collect())?;
        let weights = Array2::from_shape_vec((h, w), r.weights)
            .map_err(value_error)?
            .into_pyarray(py);
        Ok((depth_array(py, r.depth)?, points, normals, weights))
    }

    /// The signed distance F (metres, NaN where unobserved) on the axis-aligned plane
    /// ``axis = coord_m`` (``axis`` is ``"x"``, ``"y"`` or ``"z"``), as a float32 image with row 0
    /// at the largest in-plane coordinate.
    #[pyo3(signature = (axis, coord_m, pixels_per_voxel = 2))]
    fn slice<'py>(
        &self,
        py: Python<'py>,
        axis: &str,
        #[pyo3(from_py_with = crate::reals::coord_m)] coord_m: f64,
        #[pyo3(from_py_with = crate::ints::int)] pixels_per_voxel: usize,
    ) -> PyResult<Bound<'py, PyArray2<f32>>> {
        let spec = SliceSpec {
            pixels_per_voxel,
            ..SliceSpec::new(Axis::parse(axis).map_err(value_error)?, coord_m)
        };
        let slice = self
            .read(py, |volume| volume.slice(&spec))?
            .map_err(value_error)?;
        image_array(py, slice.values)
    }

    /// The first frame's disparity-error variance over its camera's noise model, as measured
    /// for the truncation band (1.0 before the first frame, with ``estimate_noise=False``, with a
    /// fixed band, or when the frame is within its model).
    #[getter]
    fn noise_scale(&self, py: Python<'_>) -> PyResult<f64> {
        // Waited for with the GIL released, as every other call on the volume: an integration
        // holds the lock for its whole frame.
        compute_read(py, &self.state, |s| s.noise_scale).map_err(|_| value_error(POISONED))
    }

    /// The truncation band (metres) of an observation at depth ``z_m`` metres: ``trunc_m`` with
    /// ``truncation="fixed"``; with ``"sensor"`` the band of the first frame's camera (before
    /// the first frame: a Kinect v1's).
    fn band_m(&self, py: Python<'_>, z_m: f64) -> PyResult<f64> {
        if !(z_m.is_finite() && z_m > 0.0) {
            return Err(value_error(format!(
                "z_m {}: a depth must be finite and positive",
                sl_core::Compact(z_m)
            )));
        }
        self.read(py, |v| v.params().band_at(z_m))
    }

    /// Number of allocated voxel blocks.
    #[getter]
    fn block_count(&self, py: Python<'_>) -> PyResult<usize> {
        self.read(py, TsdfVolume::block_count)
    }

    /// Number of integrated frames.
    #[getter]
    fn frame_count(&self, py: Python<'_>) -> PyResult<usize> {
        self.read(py, TsdfVolume::frame_count)
    }

    /// Memory used by the blocks and their index, bytes.
    #[getter]
    fn memory_bytes(&self, py: Python<'_>) -> PyResult<usize> {
        self.read(py, TsdfVolume::memory_bytes)
    }

    fn __repr__(&self, py: Python<'_>) -> PyResult<String> {
        self.read(py, |v| {
            let p = v.params();
            format!(
                "TsdfVolume(voxel_m={}, trunc_m={}, weight={:?}, truncation={:?}, frames={}, blocks={})",
                p.voxel_m,
                p.trunc_m,
                p.weight.name(),
                match p.truncation {
                    Truncation::Fixed => "fixed",
                    Truncation::SensorAdaptive { .. } => "sensor",
                },
                v.frame_count(),
                v.block_count()
            )
        })
    }
}

/// Before the first frame: the `"sensor"` weight and the sensor-adaptive band take the frame's
/// camera, the band the frame's measured noise when asked.
fn first_frame(
    state: &mut VolumeState,
    view: &sl_core::DepthView<'_>,
    camera: &sl_core::Camera,
) -> Result<(), String> {
    let mut params = *state.volume.params();
    if state.sensor_weight {
        params.weight = WeightMode::sensor_variance(camera.sensor);
    }
    if let Truncation::SensorAdaptive { sensor, .. } = &mut params.truncation {
        if state.estimate_noise {
            state.noise_scale =
                sl_planes::frame_noise_scale(*view, camera, &sl_planes::PlaneConfig::default())
                    .map_err(|e| format!("measuring the frame's noise: {e}"))?;
        }
        *sensor = camera.sensor.with_variance_scale(state.noise_scale);
    }
    state.volume = TsdfVolume::new(params).map_err(|e| e.to_string())?;
    Ok(())
}

fn mesh_config(min_weight: f32) -> PyResult<MeshConfig> {
    let mut config = MeshConfig::default();
    config.min_weight = min_weight;
    config.validate().map_err(value_error)?;
    Ok(config)
}

fn ply_format(ascii: bool) -> PlyFormat {
    if ascii {
        PlyFormat::Ascii
    } else {
        PlyFormat::BinaryLittleEndian
    }
}

/// A triangle mesh (world frame, metres) as NumPy arrays: ``vertices`` (N, 3) float32,
/// ``triangles`` (M, 3) uint32 (counter-clockwise seen from outside), ``normals`` (N, 3)
/// float32, ``confidence`` (N,) float32 (accumulated fusion weight). Hand them to Open3D with
/// ``o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(m.vertices), …)`` or to trimesh.
#[pyclass(name = "Mesh", module = "sldepth", frozen)]
#[derive(Debug)]
pub struct PyMesh {
    vertices: Py<PyArray2<f32>>,
    triangles: Py<PyArray2<u32>>,
    normals: Py<PyArray2<f32>>,
    confidence: Py<PyArray1<f32>>,
}

impl PyMesh {
    pub(crate) fn from_mesh(py: Python<'_>, mesh: Mesh) -> PyResult<Self> {
        Ok(Self {
            vertices: rows3_array(py, mesh.positions.iter().map(|p| p.coords.into()))?.unbind(),
            triangles: rows3_array(py, mesh.triangles.iter().copied())?.unbind(),
            normals: rows3_array(py, mesh.normals.iter().map(|&n| n.into()))?.unbind(),
            confidence: Array1::from_vec(
                mesh.scalar_values(sl_tsdf::CONFIDENCE_PROPERTY)
                    .map(<[f32]>::to_vec)
                    .unwrap_or_default(),
            )
            .into_pyarray(py)
            .unbind(),
        })
    }
}

/// The rows of an (N, 3) array, each as `R` (`[T; 3]`, a point or a vector).
fn rows<T: numpy::Element + Copy, R: From<[T; 3]>>(
    a: &PyReadonlyArray2<'_, T>,
) -> PyResult<Vec<R>> {
    let v = a.as_array();
    if v.ncols() != 3 {
        return Err(value_error("expected an (N, 3) array"));
    }
    Ok(v.rows()
        .into_iter()
        .map(|r| R::from([r[0], r[1], r[2]]))
        .collect())
}

#[pymethods]
impl PyMesh {
    /// Vertex positions, (N, 3) float32, metres.
    #[getter]
    fn vertices<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f32>> {
        self.vertices.bind(py).clone()
    }
    /// Triangles as vertex indices, (M, 3) uint32.
    #[getter]
    fn triangles<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<u32>> {
        self.triangles.bind(py).clone()
    }
    /// Unit vertex normals, (N, 3) float32.
    #[getter]
    fn normals<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f32>> {
        self.normals.bind(py).clone()
    }
    /// Per-vertex fusion confidence (accumulated weight), (N,) float32.
    #[getter]
    fn confidence<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f32>> {
        self.confidence.bind(py).clone()
    }

    /// Writes the mesh as PLY (binary unless ``ascii``), atomically.
    #[pyo3(signature = (path, ascii = false))]
    fn write_ply(&self, py: Python<'_>, path: PathBuf, ascii: bool) -> PyResult<()> {
        let confidence = self.confidence.bind(py).readonly().as_array().to_vec();
        let mesh = Mesh {
            positions: rows(&self.vertices.bind(py).readonly())?,
            normals: rows(&self.normals.bind(py).readonly())?,
            triangles: rows(&self.triangles.bind(py).readonly())?,
            scalar: (!confidence.is_empty()).then(|| VertexScalar {
                name: sl_tsdf::CONFIDENCE_PROPERTY.to_owned(),
                values: confidence,
            }),
        };
        compute(py, || {
            sl_tsdf::io::write_mesh_ply(&path, &mesh, ply_format(ascii))
        })
        .map_err(|e| SlDepthIOError::new_err(e.to_string()))
    }

    fn __len__(&self, py: Python<'_>) -> usize {
        self.vertices.bind(py).readonly().as_array().nrows()
    }

    fn __repr__(&self, py: Python<'_>) -> String {
        format!(
            "Mesh(vertices={}, triangles={})",
            self.vertices.bind(py).readonly().as_array().nrows(),
            self.triangles.bind(py).readonly().as_array().nrows()
        )
    }
}
