//! `sldepth.RosBag`: a robot recording's depth topic and camera, and its depth frames one by
//! one.

use std::path::PathBuf;
use std::sync::Mutex;

use numpy::PyArray2;
use pyo3::prelude::*;
use sl_core::Camera;
use sl_io::Limits;
use sl_io::rosbag::{
    BagMessage, CAMERA_INFO_TYPE, DepthEncodingKind, RosBag, TfLookupError, TfTree,
};

use crate::arrays::depth_array;
use crate::camera::PyCamera;
use crate::errors::{io_error, value_error};
use crate::threads::compute;

/// A robot recording, as ``sldepth track REC`` reads it: a ROS 1 bag (``.bag``, format 2.0;
/// chunks uncompressed, ``bz2`` or ``lz4``), a ROS 2 bag in MCAP (``.mcap``; chunks
/// uncompressed, ``zstd`` or ``lz4``) or in SQLite (``.db3``), or a ROS 2 bag's folder with
/// ``metadata.yaml`` (all its files, when the recording was split into several); a RealSense recording (librealsense's ``.bag``, or ``.db3`` since 2.56)
/// is one of these. ``RosBag(path)`` reads its index (nothing is decompressed); ``topics``
/// lists ``(topic, type, messages)``; ``depth_topic()`` finds the one image topic holding depth
/// (``16UC1`` millimetres or ``32FC1`` metres, or ``mono16`` on a topic named for depth, or
/// ``image_transport``'s ``compressedDepth``, PNG or RVL); ``camera()`` reads the
/// ``camera_info`` beside it (its ``plumb_bob`` lens as ``Camera.lens``, which ``Tracker``
/// undoes; a RealSense recording's device and baseline choose the noise model);
/// ``depth_frames()`` iterates ``(stamp_s, depth)`` pairs, depth a float32 (H, W) array of
/// metres (0 = none), stamped with the image header's stamp (a RealSense recording's: the
/// frame's sensor timestamp). A file that is not a bag, a bag without an index (``rosbag
/// reindex`` writes one) or a malformed one raises ``OSError``.
#[pyclass(name = "RosBag", module = "sldepth", frozen)]
#[derive(Debug)]
pub struct PyRosBag {
    path: PathBuf,
    bag: Mutex<BagState>,
}

/// The open recording and, once asked for, its trees of transforms by namespace.
#[derive(Debug)]
struct BagState {
    bag: RosBag,
    transforms: std::collections::HashMap<String, TfTree>,
}

impl BagState {
    /// The recording's transforms under `namespace` (`""`: `/tf`, `/tf_static`), read on
    /// first use.
    fn transforms(&mut self, namespace: &str) -> sl_io::Result<&TfTree> {
        let key = namespace.trim_matches('/').to_string();
        if !self.transforms.contains_key(&key) {
            let tree = self.bag.transforms_in(&key)?;
            self.transforms.insert(key.clone(), tree);
        }
        Ok(&self.transforms[&key])
    }
}

impl PyRosBag {
    fn with_bag<T: Send>(
        &self,
        py: Python<'_>,
        f: impl FnOnce(&mut RosBag) -> sl_io::Result<T> + Send,
    ) -> PyResult<T> {
        self.with_state(py, |s| f(&mut s.bag))
    }

    fn with_state<T: Send>(
        &self,
        py: Python<'_>,
        f: impl FnOnce(&mut BagState) -> sl_io::Result<T> + Send,
    ) -> PyResult<T> {
        crate::threads::compute_locked(py, &self.bag, f)
            .map_err(|_| value_error("the bag's lock was poisoned by a panic"))?
            .map_err(io_error)
    }
}

#[pymethods]
impl PyRosBag {
    #[new]
    fn new(py: Python<'_>, path: PathBuf) -> PyResult<Self> {
        let bag = compute(py, || RosBag::open(&path, &Limits::default())).map_err(io_error)?;
        Ok(Self {
            path,
            bag: Mutex::new(BagState {
                bag,
                transforms: std::collections::HashMap::new(),
            }),
        })
    }

    /// Whether ``path`` names a recording ``RosBag`` opens: a ``.bag``, ``.mcap`` or ``.db3``
    /// file, a ROS 2 bag's folder (``metadata.yaml`` beside its files), or a folder of one ROS 1
    /// recording split by ``rosbag record --split`` (``NAME_0.bag``, ``NAME_1.bag``, ...). The rule
    /// ``sldepth track`` and ``track_sequence`` tell a recording from a folder of frames by.
    #[staticmethod]
    fn is_recording(path: PathBuf) -> bool {
        sl_io::rosbag::is_bag_file(&path)
    }

    /// The bag's file.
    #[getter]
    fn path(&self) -> PathBuf {
        self.path.clone()
    }

    /// What holds the recording: ``"ROS 1 bag"``, ``"MCAP (ROS 2 bag)"`` or
    /// ``"SQLite (ROS 2 bag)"``.
    #[getter]
    fn container(&self, py: Python<'_>) -> PyResult<&'static str> {
        self.with_bag(py, |b| Ok(b.container()))
    }

    /// How many files hold the recording (a ROS 2 bag split by size or duration: several).
    #[getter]
    fn files(&self, py: Python<'_>) -> PyResult<usize> {
        self.with_bag(py, |b| Ok(b.files()))
    }

    /// ``(topic, message type, messages)`` of every topic, by name.
    #[getter]
    fn topics(&self, py: Python<'_>) -> PyResult<Vec<(String, String, u64)>> {
        self.with_bag(py, |b| {
            Ok(b.topics()
                .into_iter()
                .map(|t| (t.topic, t.message_type, t.messages))
                .collect())
        })
    }

    /// The depth topic: ``topic`` when given (an image topic of the bag), else the one image
    /// topic whose images hold depth; several raise ``OSError`` naming them.
    #[pyo3(signature = (topic = None))]
    fn depth_topic(&self, py: Python<'_>, topic: Option<String>) -> PyResult<String> {
        self.with_bag(py, move |b| b.depth_topic(topic.as_deref()))
    }

    /// The camera of the ``sensor_msgs/CameraInfo`` beside the depth topic (``topic``, or the
    /// one ``depth_topic()`` finds; ``/camera/depth/image`` → ``/camera/depth/camera_info``;
    /// a RealSense recording's ``.../Depth_0/image/data`` → ``.../Depth_0/info/camera_info``),
    /// or of the camera info topic ``topic`` itself: its intrinsics, its ``plumb_bob`` lens as
    /// ``lens``, and the noise model of the sensor — in a RealSense recording its device's
    /// preset (``d415``, ``d435``, ``d455``) at the recorded stereo baseline; else the baseline
    /// a ROS driver states beside the topic (``P[3] = -f*B`` of ``realsense2_camera``'s
    /// ``infra2/camera_info``: the D400 model; of ``openni_camera``'s
    /// ``projector/camera_info``: the Kinect's); else the Kinect's. No such topic (give the camera yourself: ``Camera.preset``,
    /// ``Camera.from_file``), binning, a region of interest or another distortion model raise
    /// ``OSError``.
    #[pyo3(signature = (topic = None))]
    fn camera(&self, py: Python<'_>, topic: Option<String>) -> PyResult<PyCamera> {
        let (camera, k, lens) = self.with_bag(py, move |b| match topic {
            Some(t) if b.message_type(&t) == Some(CAMERA_INFO_TYPE) => {
                let ros = b.camera(&t)?;
                Ok((None, ros.intrinsics, ros.lens))
            }
            t => {
                let depth = b.depth_topic(t.as_deref())?;
                let c = b.depth_camera(&depth)?;
                Ok((Some(c.camera), c.camera.intrinsics, c.lens))
            }
        })?;
        let camera = match camera {
            Some(c) => c,
            None => Camera::from_intrinsics(k, None, None).map_err(value_error)?,
        };
        Ok(PyCamera {
            inner: camera,
            lens,
            preset_name: None,
        })
    }

    /// What a RealSense recording (librealsense's ``.bag``, or ``.db3`` since 2.56) says of the
    /// sensor behind the depth topic (``topic``, or ``depth_topic()``): a dict with
    /// ``device`` (its name), ``depth_units_m`` (metres per 16-bit unit) and
    /// ``stereo_baseline_m``, each None when not recorded; None for a recording that is not
    /// librealsense's.
    #[pyo3(signature = (topic = None))]
    fn realsense<'py>(
        &self,
        py: Python<'py>,
        topic: Option<String>,
    ) -> PyResult<Option<Bound<'py, pyo3::types::PyDict>>> {
        let info = self.with_bag(py, move |b| {
            let depth = b.depth_topic(topic.as_deref())?;
            b.realsense(&depth)
        })?;
        let Some(r) = info else {
            return Ok(None);
        };
        let d = pyo3::types::PyDict::new(py);
        d.set_item("device", r.device_name)?;
        d.set_item("depth_units_m", r.depth_units_m)?;
        d.set_item("stereo_baseline_m", r.stereo_baseline_m)?;
        Ok(Some(d))
    }

    /// The depth frames of ``topic`` (None: ``depth_topic()``), in the order they were
    /// recorded: an iterator of ``(stamp_s, depth)`` with ``len()``. 16-bit images are divided by
    /// ``depth_scale`` (None: 1000, ROS's millimetres, or a RealSense recording's own depth
    /// units), float images by it (None: 1, metres).
    #[pyo3(signature = (topic = None, depth_scale = None))]
    fn depth_frames(
        &self,
        py: Python<'_>,
        topic: Option<String>,
        #[pyo3(from_py_with = crate::reals::depth_scale)] depth_scale: Option<f64>,
    ) -> PyResult<PyBagFrames> {
        let path = self.path.clone();
        let (bag, messages, units, times) = compute(py, move || {
            let mut bag = RosBag::open(&path, &Limits::default())?;
            let topic = bag.depth_topic(topic.as_deref())?;
            let messages = bag.messages(&topic)?;
            let kind = match messages.first() {
                Some(m) => bag.depth_kind(m)?,
                None => None,
            };
            let units = match kind {
                Some(DepthEncodingKind::F32) => sl_io::depth::FLOAT_UNITS_PER_M,
                _ => bag.depth_units_per_m(&topic)?,
            };
            let times = bag.realsense_frame_times(&topic, &messages)?;
            Ok::<_, sl_io::IoError>((bag, messages, units, times))
        })
        .map_err(io_error)?;
        let units_per_m = depth_scale.unwrap_or(units);
        Ok(PyBagFrames {
            len: messages.len(),
            state: Mutex::new(FramesState {
                bag,
                messages,
                times,
                next: 0,
                units_per_m,
            }),
        })
    }

    /// The frame the depth topic's images (``topic``, or ``depth_topic()``) name in their
    /// headers: the camera driver's optical frame (``camera_depth_optical_frame``; z forward,
    /// x right, y down), the frame ``tf_lookup`` poses; ``""`` when the driver set none.
    #[pyo3(signature = (topic = None))]
    fn image_frame(&self, py: Python<'_>, topic: Option<String>) -> PyResult<String> {
        self.with_bag(py, move |b| {
            let depth = b.depth_topic(topic.as_deref())?;
            match b.messages(&depth)?.first() {
                Some(m) => b.image_frame_id(m),
                None => Ok(String::new()),
            }
        })
    }

    /// The namespaces that hold a tree of transforms, sorted: ``""`` for ``/tf`` and
    /// ``/tf_static``, ``"/robot1"`` for ``/robot1/tf`` (a multi-robot recording's remapping).
    fn tf_namespaces(&self, py: Python<'_>) -> PyResult<Vec<String>> {
        self.with_bag(py, |b| Ok(b.tf_namespaces()))
    }

    /// The frames of the recording's transforms (``/tf``, ``/tf_static``:
    /// ``tf2_msgs/TFMessage``), one dict each, by name: ``frame``, ``parent``, ``static``,
    /// ``republished_constant`` (sampled on ``/tf`` and never changed, as ROS 1 ``tf``'s static
    /// publisher republished), ``samples``, ``first_s``, ``last_s``. Empty when the recording has none. Read on first
    /// use and kept; a malformed message, or a frame with two parents, raises ``OSError``.
    /// ``namespace``: another tree, in a recording that remapped its transforms (``"/robot1"``:
    /// ``/robot1/tf`` and ``/robot1/tf_static``; ``tf_namespaces()`` lists them).
    #[pyo3(signature = (namespace = ""))]
    fn transforms<'py>(
        &self,
        py: Python<'py>,
        namespace: &str,
    ) -> PyResult<Vec<Bound<'py, pyo3::types::PyDict>>> {
        let ns = namespace.to_string();
        let frames = self.with_state(py, move |s| Ok(s.transforms(&ns)?.frames()))?;
        frames
            .into_iter()
            .map(|f| {
                let d = pyo3::types::PyDict::new(py);
                d.set_item("frame", f.frame)?;
                d.set_item("parent", f.parent)?;
                d.set_item("static", f.is_static)?;
                d.set_item("republished_constant", f.republished_constant)?;
                d.set_item("samples", f.samples)?;
                d.set_item("first_s", f.first_s)?;
                d.set_item("last_s", f.last_s)?;
                Ok(d)
            })
            .collect()
    }

    /// The pose of ``frame`` in ``target_frame`` at each of ``stamps_s`` (seconds, as the
    /// frames' ``stamp_s``): a float64 (N, 4, 4) array of matrices mapping ``frame``'s points
    /// into ``target_frame`` — for a camera's optical frame (``image_frame()``) in a world frame
    /// (``map``, ``odom``, ``world``), the camera-to-world pose ``TsdfVolume.integrate`` takes,
    /// as ``sldepth fuse REC --tf`` poses its frames. Each transform of the chain is
    /// interpolated between samples no more than twice its median interval apart (a static one
    /// holds at any time); where a transform has no sample within ``max_gap_s`` of a time
    /// (beyond its first or last, or in a gap of its samples), at a NaN stamp, or where the
    /// pose is not finite, that matrix is all NaN. ``stamps_s`` is one 1-D sequence or array of
    /// seconds, ``max_gap_s`` from 0 to 3600 s; ``namespace`` the tree (as ``transforms``). A frame no transform names, two frames no chain
    /// joins, or other stamps or gaps raise ``ValueError``.
    #[pyo3(signature = (target_frame, frame, stamps_s, *, max_gap_s = 0.02, namespace = ""))]
    fn tf_lookup<'py>(
        &self,
        py: Python<'py>,
        target_frame: String,
        frame: String,
        stamps_s: &Bound<'py, PyAny>,
        max_gap_s: f64,
        namespace: &str,
    ) -> PyResult<Bound<'py, numpy::PyArray3<f64>>> {
        let ns = namespace.to_string();
        if !(0.0..=sl_io::trajectory::MAX_GAP_S).contains(&max_gap_s) {
            return Err(value_error(format!(
                "max_gap_s must be from 0 to {} seconds, got {max_gap_s}",
                sl_io::trajectory::MAX_GAP_S
            )));
        }
        let stamps_s = stamps_vector(stamps_s)?;
        let looked = self.with_state(py, move |s| {
            let tree = s.transforms(&ns)?;
            // A missing pose becomes NaN at once (its error, naming both frames, is not kept);
            // any other error ends the call.
            let mut matrices = Vec::with_capacity(stamps_s.len());
            for &t in &stamps_s {
                matrices.push(match tree.lookup(&target_frame, &frame, t, max_gap_s) {
                    Ok(p) => p.to_homogeneous(),
                    Err(
                        TfLookupError::NoSample { .. }
                        | TfLookupError::NotFinite { .. }
                        | TfLookupError::TimeNotFinite(_),
                    ) => sl_core::nalgebra::Matrix4::from_element(f64::NAN),
                    Err(e) => return Ok(Err(e)),
                });
            }
            Ok(Ok(matrices))
        })?;
        let matrices = looked.map_err(value_error)?;
        Ok(crate::arrays::poses_array(py, &matrices))
    }

    fn __repr__(&self) -> String {
        format!("RosBag({:?})", self.path.display().to_string())
    }
}

/// The times of `obj` as seconds: a 1-D sequence or array of real numbers (a scalar, a 2-D
/// array or text raise `ValueError` saying so).
fn stamps_vector(obj: &Bound<'_, PyAny>) -> PyResult<Vec<f64>> {
    let py = obj.py();
    let bad = |got: String| {
        value_error(format!(
            "stamps_s must be a 1-D sequence of times in seconds (for one time, [t]), got {got}"
        ))
    };
    let arr = py
        .import("numpy")?
        .call_method1("asarray", (obj,))
        .map_err(|_| bad("an object NumPy cannot read as an array".into()))?;
    let shape: Vec<usize> = arr.getattr("shape")?.extract()?;
    let kind: String = arr.getattr("dtype")?.getattr("kind")?.extract()?;
    if shape.len() != 1 {
        return Err(bad(format!("an array of shape {shape:?}")));
    }
    if !matches!(kind.as_str(), "f" | "i" | "u") {
        return Err(bad(format!("an array of dtype kind {kind:?}")));
    }
    arr.call_method1("astype", ("float64",))?
        .call_method0("tolist")?
        .extract()
}

/// The depth frames of a bag's topic (``RosBag.depth_frames``): an iterator of
/// ``(stamp_s, depth)``, with ``len()``.
#[pyclass(name = "BagFrames", module = "sldepth", frozen)]
#[derive(Debug)]
pub struct PyBagFrames {
    len: usize,
    state: Mutex<FramesState>,
}

#[derive(Debug)]
struct FramesState {
    bag: RosBag,
    messages: Vec<BagMessage>,
    /// A RealSense recording's sensor timestamps, where recorded.
    times: Vec<Option<f64>>,
    next: usize,
    units_per_m: f64,
}

#[pymethods]
impl PyBagFrames {
    fn __len__(&self) -> usize {
        self.len
    }

    fn __iter__(slf: PyRef<'_, Self>) -> PyRef<'_, Self> {
        slf
    }

    fn __next__<'py>(&self, py: Python<'py>) -> PyResult<Option<(f64, Bound<'py, PyArray2<f32>>)>> {
        let frame = crate::threads::compute_locked(py, &self.state, |s| {
            let Some(m) = s.messages.get(s.next).copied() else {
                return Ok(None);
            };
            let time = s.times.get(s.next).copied().flatten();
            s.next += 1;
            let mut d = s.bag.read_depth(&m, s.units_per_m, s.units_per_m)?;
            d.stamp_s = time.unwrap_or(d.stamp_s);
            Ok(Some(d))
        })
        .map_err(|_| value_error("the bag's lock was poisoned by a panic"))?
        .map_err(io_error)?;
        match frame {
            None => Ok(None),
            Some(d) => Ok(Some((d.stamp_s, depth_array(py, d.depth)?))),
        }
    }
}
