//! A [`Scene`] of labelled analytic surfaces and its ground-truth [`Render`].

use nalgebra::{Isometry3, Matrix3, Point3, Rotation3, UnitQuaternion, Vector3};
use rayon::prelude::*;
use sl_core::{CameraToWorld, DepthImage, Image, Intrinsics};

use crate::error::{NoiseError, Result};
use crate::sim::primitives::{Hit, Surface, faces_of};

/// Largest image [`Scene::try_render`] accepts, pixels (64 Mpx ≈ 1.2 GB of depth, labels and
/// normals).
pub const MAX_RENDER_PIXELS: usize = 1 << 26;

/// Maximum number of surfaces in a scene (labels are `u16`, 0 is the background).
pub const MAX_SURFACES: usize = u16::MAX as usize;

/// A set of analytic surfaces, each with a label `1..=65535` (0 = background) and an infrared
/// reflectance (1 unless [`Scene::set_reflectance`] says otherwise; the realistic sensor's
/// `RealisticNoise::min_return` drop-out reads it).
#[derive(Default)]
pub struct Scene {
    surfaces: Vec<Box<dyn Surface>>,
    /// Per surface (label − 1): its Lambertian reflectance of the projector's infrared, 0–1.
    reflectance: Vec<f64>,
}

impl std::fmt::Debug for Scene {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Scene")
            .field("surfaces", &self.surfaces.len())
            .finish()
    }
}

/// Ground truth of a scene seen by a camera.
#[derive(Debug, Clone, PartialEq)]
pub struct Render {
    /// Exact depth: `Z` along the optical axis, metres (0 where no surface is hit).
    pub depth: DepthImage,
    /// Label of the visible surface at each pixel (0 = background); the nearest surface wins.
    pub labels: Image<u16>,
    /// Unit surface normal at each pixel in the **camera** frame, facing the camera
    /// (`[0, 0, 0]` for background).
    pub normals: Image<[f32; 3]>,
}

impl Scene {
    /// An empty scene.
    pub fn new() -> Self {
        Self::default()
    }

    /// Number of surfaces (= the largest label).
    pub fn len(&self) -> usize {
        self.surfaces.len()
    }

    /// Whether the scene has no surface.
    pub fn is_empty(&self) -> bool {
        self.surfaces.is_empty()
    }

    /// Adds a surface and returns its label (1-based), or [`NoiseError::SceneFull`] when the
    /// scene already holds [`MAX_SURFACES`].
    pub fn try_add<S: Surface + 'static>(&mut self, surface: S) -> Result<u16> {
        if self.surfaces.len() >= MAX_SURFACES {
            return Err(NoiseError::SceneFull { max: MAX_SURFACES });
        }
        self.surfaces.push(Box::new(surface));
        self.reflectance.push(1.0);
        // Cannot truncate: len ≤ MAX_SURFACES = u16::MAX after the check above.
        Ok(self.surfaces.len() as u16)
    }

    /// Adds a surface and returns its label (1-based).
    ///
    /// # Panics
    /// When the scene already holds [`MAX_SURFACES`] surfaces (a programming error; use
    /// [`Scene::try_add`] to handle it).
    #[allow(clippy::panic)] // Documented capacity limit, like `Vec::push`; `try_add` is the fallible form.
    pub fn add<S: Surface + 'static>(&mut self, surface: S) -> u16 {
        match self.try_add(surface) {
            Ok(label) => label,
            Err(e) => panic!("{e}"),
        }
    }

    /// Adds a box as six labelled faces (order `+x, −x, +y, −y, +z, −z` of the box frame) and
    /// returns their labels. `half_extents` are metres along the box axes (absolute values are
    /// used); `rotation` (a `UnitQuaternion` or `Rotation3`) takes the box frame to the world.
    ///
    /// # Panics
    /// When the scene cannot hold six more surfaces (see [`Scene::add`]).
    pub fn add_cuboid(
        &mut self,
        centre: Point3<f64>,
        half_extents: Vector3<f64>,
        rotation: impl Into<UnitQuaternion<f64>>,
    ) -> [u16; 6] {
        faces_of(&centre, &half_extents, &rotation.into()).map(|face| self.add(face))
    }

    /// Sets the infrared reflectance of surface `label` (Lambertian albedo at the projector's
    /// wavelength, 0–1: about 0.9 for white paint, 0.05–0.1 for black plastic or a dark
    /// worktop). Surfaces added without it reflect 1. Only the realistic sensor's drop-out of
    /// weak returns (`RealisticNoise::min_return`) uses it.
    ///
    /// # Errors
    /// [`NoiseError::InvalidParameter`] for a label the scene does not hold or a reflectance
    /// outside `[0, 1]`.
    pub fn set_reflectance(&mut self, label: u16, reflectance: f64) -> Result<()> {
        if !(0.0..=1.0).contains(&reflectance) {
            return Err(NoiseError::InvalidParameter(format!(
                "reflectance {} of surface {label} must be in [0, 1]",
                crate::error::num(reflectance)
            )));
        }
        let slot = usize::from(label)
            .checked_sub(1)
            .and_then(|i| self.reflectance.get_mut(i))
            .ok_or_else(|| {
                NoiseError::InvalidParameter(format!(
                    "no surface {label} (the scene has labels 1..={})",
                    self.surfaces.len()
                ))
            })?;
        *slot = reflectance;
        Ok(())
    }

    /// The infrared reflectance of surface `label` (1 for the background and unknown labels).
    pub fn reflectance(&self, label: u16) -> f64 {
        usize::from(label)
            .checked_sub(1)
            .and_then(|i| self.reflectance.get(i))
            .copied()
            .unwrap_or(1.0)
    }

    /// The surface with label `label`, if any.
    pub fn surface(&self, label: u16) -> Option<&dyn Surface> {
        let i = usize::from(label).checked_sub(1)?;
        self.surfaces.get(i).map(|b| b.as_ref())
    }

    /// The nearest hit of the ray `origin + t·dir` over all surfaces, with its label.
    pub fn trace(&self, origin: &Point3<f64>, dir: &Vector3<f64>) -> Option<(u16, Hit)> {
        let mut best: Option<(u16, Hit)> = None;
        for (i, s) in self.surfaces.iter().enumerate() {
            if let Some(h) = s.intersect(origin, dir)
                && best.is_none_or(|(_, b)| h.t < b.t)
            {
                // i < MAX_SURFACES, so i + 1 fits in u16.
                best = Some((i as u16 + 1, h));
            }
        }
        best
    }

    /// Unsigned distance from `p` to the nearest surface (`f64::INFINITY` for an empty scene).
    pub fn distance(&self, p: &Point3<f64>) -> f64 {
        self.nearest(p).map_or(f64::INFINITY, |(_, d)| d)
    }

    /// The label of the surface nearest to `p` and its distance.
    pub fn nearest(&self, p: &Point3<f64>) -> Option<(u16, f64)> {
        self.surfaces
            .iter()
            .enumerate()
            .map(|(i, s)| (i as u16 + 1, s.distance(p)))
            .min_by(|a, b| a.1.total_cmp(&b.1))
    }

    /// [`Scene::render`] after checking the image size against [`MAX_RENDER_PIXELS`]: use it
    /// when the intrinsics come from outside (a camera file).
    pub fn try_render(&self, k: &Intrinsics, camera_to_world: &CameraToWorld) -> Result<Render> {
        check_render_size(k)?;
        Ok(self.render(k, camera_to_world))
    }

    /// Renders exact depth, labels and normals through the pinhole `k` from the camera pose
    /// `camera_to_world` (X_w = R·X_c + t). Pixel centres are at integer coordinates; the ray of
    /// pixel `(x, y)` is `R·((x − cx)/fx, (y − cy)/fy, 1)`, so the hit's ray parameter is the
    /// depth `Z` itself. Rows are rendered in parallel. Allocates 18 bytes per pixel without a
    /// size check: see [`Scene::try_render`] for untrusted intrinsics.
    pub fn render(&self, k: &Intrinsics, camera_to_world: &CameraToWorld) -> Render {
        let (w, h) = (k.width, k.height);
        let mut depth = vec![0.0f32; w * h];
        let mut labels = vec![0u16; w * h];
        let mut normals = vec![[0.0f32; 3]; w * h];
        let origin = Point3::from(camera_to_world.translation());
        let rot = camera_to_world.rotation().to_rotation_matrix();
        if w > 0 {
            depth
                .par_chunks_mut(w)
                .zip(labels.par_chunks_mut(w))
                .zip(normals.par_chunks_mut(w))
                .enumerate()
                .for_each(|(y, ((drow, lrow), nrow))| {
                    for x in 0..w {
                        let dir = rot * k.ray(x as f64, y as f64);
                        if let Some((label, hit)) = self.trace(&origin, &dir) {
                            let n = rot.inverse_transform_vector(&hit.normal);
                            drow[x] = hit.t as f32;
                            lrow[x] = label;
                            nrow[x] = [n.x as f32, n.y as f32, n.z as f32];
                        }
                    }
                });
        }
        Render {
            depth: DepthImage::from_image(image_from(w, h, depth)),
            labels: image_from(w, h, labels),
            normals: image_from(w, h, normals),
        }
    }
}

/// Refuses images larger than [`MAX_RENDER_PIXELS`].
pub(crate) fn check_render_size(k: &Intrinsics) -> Result<()> {
    let pixels = k.width.saturating_mul(k.height);
    if pixels > MAX_RENDER_PIXELS {
        return Err(NoiseError::TooLarge {
            what: format!("rendering a {}x{} image", k.width, k.height),
            requested: pixels,
            budget: MAX_RENDER_PIXELS,
        });
    }
    Ok(())
}

/// Wraps a buffer that has exactly `w·h` elements by construction.
fn image_from<T: Clone + Default>(w: usize, h: usize, data: Vec<T>) -> Image<T> {
    Image::from_vec(w, h, data).unwrap_or_else(|_| Image::filled(w, h, T::default()))
}

/// A camera-to-world pose at `eye` looking at `target`, with the image's "up" (−y of the
/// camera) as close as possible to `up`.
///
/// Camera axes follow `sl-core`: x right, y down, z forward. Fails when `eye == target` or the
/// viewing direction is parallel to `up`.
pub fn look_at(eye: Point3<f64>, target: Point3<f64>, up: Vector3<f64>) -> Result<CameraToWorld> {
    let fwd = target - eye;
    let fwd_n = fwd.norm();
    if !(fwd_n.is_finite() && fwd_n > 0.0) {
        return Err(NoiseError::DegenerateGeometry(
            "look_at: eye equals target".into(),
        ));
    }
    let z = fwd / fwd_n;
    let x = z.cross(&up);
    let xn = x.norm();
    if !(xn.is_finite() && xn > 1e-12) {
        return Err(NoiseError::DegenerateGeometry(
            "look_at: view direction parallel to up".into(),
        ));
    }
    let x = x / xn;
    let y = z.cross(&x);
    let r = Rotation3::from_matrix_unchecked(Matrix3::from_columns(&[x, y, z]));
    Ok(CameraToWorld::from_isometry(Isometry3::from_parts(
        eye.coords.into(),
        UnitQuaternion::from_rotation_matrix(&r),
    )))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::primitives::{Plane, Quad, Sphere};

    #[test]
    fn look_at_axes() {
        let pose = look_at(
            Point3::new(0.0, 0.0, 1.0),
            Point3::new(0.0, 5.0, 1.0),
            Vector3::z(),
        )
        .unwrap();
        // Camera forward → world +y, right → world +x, down → world −z.
        assert!((pose.rotation() * Vector3::z() - Vector3::y()).norm() < 1e-12);
        assert!((pose.rotation() * Vector3::x() - Vector3::x()).norm() < 1e-12);
        assert!((pose.rotation() * Vector3::y() + Vector3::z()).norm() < 1e-12);
        assert!(look_at(Point3::origin(), Point3::new(0.0, 0.0, 2.0), Vector3::z()).is_err());
    }

    #[test]
    fn render_wall_depth_is_z_and_labels_nearest() {
        let k = Intrinsics::new(64, 48, 50.0, 50.0, 31.5, 23.5).unwrap();
        let mut scene = Scene::new();
        let wall = scene.add(Plane::new(Point3::new(0.0, 0.0, 2.0), Vector3::z()).unwrap());
        // A small quad in front of the wall, covering the right half of the image.
        let near = scene.add(
            Quad::new(
                Point3::new(0.5, 0.0, 1.0),
                Vector3::new(0.5, 0.0, 0.0),
                Vector3::new(0.0, 1.0, 0.0),
            )
            .unwrap(),
        );
        let r = scene.render(&k, &CameraToWorld::identity());
        assert_eq!((wall, near), (1, 2));
        for y in 0..48 {
            for x in 0..64 {
                let (z, l) = (r.depth.get(x, y).unwrap(), *r.labels.get(x, y).unwrap());
                let n = r.normals.get(x, y).unwrap();
                if (x as f64) > 31.5 {
                    assert_eq!(l, near, "({x},{y})");
                    assert!((z - 1.0).abs() < 1e-6);
                } else {
                    assert_eq!(l, wall, "({x},{y})");
                    assert!((z - 2.0).abs() < 1e-6);
                }
                assert!((n[2] + 1.0).abs() < 1e-6);
            }
        }
    }

    #[test]
    fn render_pose_and_background() {
        let k = Intrinsics::new(40, 30, 40.0, 40.0, 19.5, 14.5).unwrap();
        let mut scene = Scene::new();
        let s = scene.add(Sphere::new(Point3::new(1.0, 2.0, 3.0), 0.3).unwrap());
        let pose = look_at(
            Point3::new(1.0, 2.0, 0.0),
            Point3::new(1.0, 2.0, 3.0),
            Vector3::y(),
        )
        .unwrap();
        let r = scene.render(&k, &pose);
        // Centre pixels see the sphere's front at Z ≈ 2.7; corners see nothing.
        let zc = r.depth.get(20, 15).unwrap();
        assert_eq!(*r.labels.get(20, 15).unwrap(), s);
        let ray = k.ray(20.0, 15.0);
        let expected = {
            let d = pose.rotation() * ray;
            scene.trace(&Point3::new(1.0, 2.0, 0.0), &d).unwrap().1.t
        };
        assert!((f64::from(zc) - expected).abs() < 1e-6);
        assert!(zc > 2.69 && zc < 2.71);
        assert_eq!(*r.labels.get(0, 0).unwrap(), 0);
        assert_eq!(r.depth.get(0, 0).unwrap(), 0.0);
        // Every labelled pixel back-projects onto its surface.
        for y in 0..30 {
            for x in 0..40 {
                let l = *r.labels.get(x, y).unwrap();
                if l != 0 {
                    let z = f64::from(r.depth.get(x, y).unwrap());
                    let p = pose.isometry() * k.back_project(x as f64, y as f64, z);
                    assert!(scene.surface(l).unwrap().distance(&p) < 1e-5);
                }
            }
        }
    }

    #[test]
    fn cuboid_labels_and_scene_distance() {
        let mut scene = Scene::new();
        let labels = scene.add_cuboid(
            Point3::new(0.0, 0.0, 3.0),
            Vector3::new(0.5, 0.5, 0.5),
            UnitQuaternion::identity(),
        );
        assert_eq!(labels, [1, 2, 3, 4, 5, 6]);
        let k = Intrinsics::new(32, 32, 30.0, 30.0, 15.5, 15.5).unwrap();
        let r = scene.render(&k, &CameraToWorld::identity());
        // Seen from the origin along +z: only the −z face (index 5).
        assert_eq!(*r.labels.get(16, 16).unwrap(), labels[5]);
        assert!((r.depth.get(16, 16).unwrap() - 2.5).abs() < 1e-6);
        assert!((scene.distance(&Point3::new(0.0, 0.0, 1.0)) - 1.5).abs() < 1e-12);
        assert_eq!(
            scene.nearest(&Point3::new(0.0, 0.0, 1.0)).unwrap().0,
            labels[5]
        );
        assert!(scene.surface(0).is_none() && scene.surface(7).is_none());
        assert_eq!(Scene::new().distance(&Point3::origin()), f64::INFINITY);
        let huge = Intrinsics::new(65536, 65536, 500.0, 500.0, 0.0, 0.0).unwrap();
        assert!(matches!(
            scene.try_render(&huge, &CameraToWorld::identity()),
            Err(NoiseError::TooLarge { .. })
        ));
        assert_eq!(scene.try_render(&k, &CameraToWorld::identity()).unwrap(), r);
    }
}
