//! Analytic surfaces: the [`Surface`] trait and its primitives.
//!
//! All primitives work in the world frame, in metres. A ray is `origin + t·dir` with `dir` any
//! non-zero vector (not necessarily unit length): [`Hit::t`] is that ray parameter, so a renderer
//! that uses the camera ray with unit Z component gets the depth `Z` directly as `t`.

use nalgebra::{Point3, Unit, UnitQuaternion, Vector3};

use crate::error::{NoiseError, Result};

/// Smallest accepted ray parameter: hits at `t ≤ T_MIN` (behind or at the origin) are ignored.
pub const T_MIN: f64 = 1e-9;

/// A ray–surface intersection.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hit {
    /// Ray parameter of the hit: the point is `origin + t·dir` (`t > 0`).
    pub t: f64,
    /// Unit surface normal at the hit, world frame, oriented towards the ray origin
    /// (`normal · dir ≤ 0`).
    pub normal: Vector3<f64>,
}

/// An analytic surface that can be ray-traced and measured.
///
/// Implement it for your own shapes and add them with [`crate::sim::Scene::add`].
pub trait Surface: Send + Sync {
    /// The nearest intersection with `t > T_MIN` of the ray `origin + t·dir`, if any.
    fn intersect(&self, origin: &Point3<f64>, dir: &Vector3<f64>) -> Option<Hit>;
    /// Unsigned Euclidean distance from `p` to the surface, metres.
    fn distance(&self, p: &Point3<f64>) -> f64;
}

impl<S: Surface + ?Sized> Surface for Box<S> {
    fn intersect(&self, origin: &Point3<f64>, dir: &Vector3<f64>) -> Option<Hit> {
        (**self).intersect(origin, dir)
    }
    fn distance(&self, p: &Point3<f64>) -> f64 {
        (**self).distance(p)
    }
}

/// Flips `n` so that it faces the ray (`n · dir ≤ 0`).
pub(super) fn facing(n: Vector3<f64>, dir: &Vector3<f64>) -> Vector3<f64> {
    if n.dot(dir) > 0.0 { -n } else { n }
}

fn unit(v: Vector3<f64>, what: &str) -> Result<Unit<Vector3<f64>>> {
    let norm = v.norm();
    if !(norm.is_finite() && norm > 0.0) {
        return Err(NoiseError::DegenerateGeometry(format!(
            "{what} {v:?} has no direction"
        )));
    }
    Ok(Unit::new_unchecked(v / norm))
}

pub(super) fn finite_point(p: &Point3<f64>, what: &str) -> Result<()> {
    if p.iter().all(|c| c.is_finite()) {
        Ok(())
    } else {
        Err(NoiseError::DegenerateGeometry(format!(
            "{what} {p:?} is not finite"
        )))
    }
}

pub(super) fn positive(v: f64, what: &str) -> Result<()> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(NoiseError::DegenerateGeometry(format!(
            "{what} = {} must be positive and finite",
            sl_core::Compact(v)
        )))
    }
}

/// Two orthogonal half-extent axes → (unit u, unit v, unit normal u×v, |u|, |v|).
type Frame = (
    Unit<Vector3<f64>>,
    Unit<Vector3<f64>>,
    Unit<Vector3<f64>>,
    f64,
    f64,
);

pub(super) fn rectangle_frame(half_u: Vector3<f64>, half_v: Vector3<f64>) -> Result<Frame> {
    let u = unit(half_u, "half-extent axis u")?;
    let v = unit(half_v, "half-extent axis v")?;
    if u.dot(&v).abs() > 1e-9 {
        return Err(NoiseError::DegenerateGeometry(format!(
            "rectangle axes {half_u:?} and {half_v:?} are not orthogonal"
        )));
    }
    let n = Unit::new_normalize(u.cross(&v));
    Ok((u, v, n, half_u.norm(), half_v.norm()))
}

// ---------------------------------------------------------------------------------------------

/// An infinite plane through a point with a normal: the ray-traced surface of an
/// [`sl_core::Plane`] (see [`Plane::from_core`] and [`Plane::to_core`]).
///
/// It keeps its anchor point because the ray intersection is computed from it (changing that
/// would change simulated depths at round-off level). Note the sign convention of
/// [`Plane::offset`]: `n · x = offset`, whereas `sl_core::Plane` is `n·x + offset_m = 0`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Plane {
    point: Point3<f64>,
    normal: Unit<Vector3<f64>>,
}

impl Plane {
    /// The plane through `point` with normal `normal` (any non-zero length).
    pub fn new(point: Point3<f64>, normal: Vector3<f64>) -> Result<Self> {
        finite_point(&point, "plane point")?;
        Ok(Self {
            point,
            normal: unit(normal, "plane normal")?,
        })
    }

    /// The plane `n · x = offset`, with `n` normalised first (the offset is scaled with it).
    pub fn from_normal_offset(normal: Vector3<f64>, offset: f64) -> Result<Self> {
        let len = normal.norm();
        let n = unit(normal, "plane normal")?;
        if !offset.is_finite() {
            return Err(NoiseError::DegenerateGeometry(format!(
                "plane offset {offset}"
            )));
        }
        Ok(Self {
            point: Point3::from(n.into_inner() * (offset / len)),
            normal: n,
        })
    }

    /// The surface of an `sl-core` plane `n·x + offset_m = 0` (same normal orientation; the
    /// anchor point is `−offset_m·n`).
    pub fn from_core(plane: &sl_core::Plane) -> Result<Self> {
        Self::from_normal_offset(plane.normal, -plane.offset_m)
    }

    /// The plane in the workspace's convention, `n·x + offset_m = 0` with this plane's normal.
    pub fn to_core(&self) -> sl_core::Plane {
        sl_core::Plane {
            normal: self.normal(),
            offset_m: -self.offset(),
        }
    }

    /// A point on the plane.
    pub fn point(&self) -> Point3<f64> {
        self.point
    }

    /// The unit normal.
    pub fn normal(&self) -> Vector3<f64> {
        self.normal.into_inner()
    }

    /// The offset `d` of `n · x = d` with the unit normal.
    pub fn offset(&self) -> f64 {
        self.normal.dot(&self.point.coords)
    }

    /// Signed distance `n · (p − point)`.
    pub fn signed_distance(&self, p: &Point3<f64>) -> f64 {
        self.normal.dot(&(p - self.point))
    }
}

/// Ray parameter of the intersection with the plane `(point, n)`, if in front of the origin.
fn plane_t(
    point: &Point3<f64>,
    n: &Vector3<f64>,
    origin: &Point3<f64>,
    dir: &Vector3<f64>,
) -> Option<f64> {
    let denom = n.dot(dir);
    if denom.abs() <= 1e-15 * dir.norm() {
        return None;
    }
    let t = n.dot(&(point - origin)) / denom;
    (t > T_MIN && t.is_finite()).then_some(t)
}

impl Surface for Plane {
    fn intersect(&self, origin: &Point3<f64>, dir: &Vector3<f64>) -> Option<Hit> {
        let t = plane_t(&self.point, &self.normal, origin, dir)?;
        Some(Hit {
            t,
            normal: facing(self.normal.into_inner(), dir),
        })
    }

    fn distance(&self, p: &Point3<f64>) -> f64 {
        self.signed_distance(p).abs()
    }
}

// ---------------------------------------------------------------------------------------------

/// A finite rectangle: a centre and two orthogonal half-extent axes.
///
/// The rectangle is `{centre + a·half_u + b·half_v : |a| ≤ 1, |b| ≤ 1}`; its normal is
/// `half_u × half_v` normalised.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Quad {
    centre: Point3<f64>,
    u: Unit<Vector3<f64>>,
    v: Unit<Vector3<f64>>,
    normal: Unit<Vector3<f64>>,
    half_u: f64,
    half_v: f64,
}

impl Quad {
    /// The rectangle with the given centre and orthogonal, non-zero half-extent axes.
    pub fn new(centre: Point3<f64>, half_u: Vector3<f64>, half_v: Vector3<f64>) -> Result<Self> {
        finite_point(&centre, "quad centre")?;
        let (u, v, normal, hu, hv) = rectangle_frame(half_u, half_v)?;
        Ok(Self {
            centre,
            u,
            v,
            normal,
            half_u: hu,
            half_v: hv,
        })
    }

    /// The centre.
    pub fn centre(&self) -> Point3<f64> {
        self.centre
    }

    /// The unit normal `u × v`.
    pub fn normal(&self) -> Vector3<f64> {
        self.normal.into_inner()
    }

    /// The two half-extent axes (with their lengths).
    pub fn half_axes(&self) -> (Vector3<f64>, Vector3<f64>) {
        (
            self.u.into_inner() * self.half_u,
            self.v.into_inner() * self.half_v,
        )
    }

    /// The infinite plane that holds the rectangle.
    pub fn plane(&self) -> Plane {
        Plane {
            point: self.centre,
            normal: self.normal,
        }
    }

    /// Whether the in-plane coordinates `(a, b)` (metres from the centre along u and v) fall
    /// inside the rectangle.
    fn contains_uv(&self, a: f64, b: f64) -> bool {
        a.abs() <= self.half_u * (1.0 + 1e-12) && b.abs() <= self.half_v * (1.0 + 1e-12)
    }
}

impl Surface for Quad {
    fn intersect(&self, origin: &Point3<f64>, dir: &Vector3<f64>) -> Option<Hit> {
        let t = plane_t(&self.centre, &self.normal, origin, dir)?;
        let d = origin + dir * t - self.centre;
        if !self.contains_uv(d.dot(&self.u), d.dot(&self.v)) {
            return None;
        }
        Some(Hit {
            t,
            normal: facing(self.normal.into_inner(), dir),
        })
    }

    fn distance(&self, p: &Point3<f64>) -> f64 {
        let d = p - self.centre;
        let a = d.dot(&self.u).clamp(-self.half_u, self.half_u);
        let b = d.dot(&self.v).clamp(-self.half_v, self.half_v);
        let q = self.centre + self.u.into_inner() * a + self.v.into_inner() * b;
        (p - q).norm()
    }
}

// ---------------------------------------------------------------------------------------------

/// A sphere (its surface).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sphere {
    centre: Point3<f64>,
    radius: f64,
}

impl Sphere {
    /// A sphere with a positive radius, metres.
    pub fn new(centre: Point3<f64>, radius: f64) -> Result<Self> {
        finite_point(&centre, "sphere centre")?;
        positive(radius, "sphere radius")?;
        Ok(Self { centre, radius })
    }

    /// The centre.
    pub fn centre(&self) -> Point3<f64> {
        self.centre
    }

    /// The radius, metres.
    pub fn radius(&self) -> f64 {
        self.radius
    }
}

/// Roots of `a·t² + b·t + c = 0` in ascending order (numerically stable form), if real.
fn quadratic_roots(a: f64, b: f64, c: f64) -> Option<(f64, f64)> {
    if a == 0.0 {
        return None;
    }
    let disc = b * b - 4.0 * a * c;
    if disc < 0.0 || !disc.is_finite() {
        return None;
    }
    let s = disc.sqrt();
    let q = -0.5 * (b + b.signum() * s);
    let (r0, r1) = if q == 0.0 { (0.0, 0.0) } else { (q / a, c / q) };
    Some(if r0 <= r1 { (r0, r1) } else { (r1, r0) })
}

impl Surface for Sphere {
    fn intersect(&self, origin: &Point3<f64>, dir: &Vector3<f64>) -> Option<Hit> {
        let oc = origin - self.centre;
        let (t0, t1) = quadratic_roots(
            dir.dot(dir),
            2.0 * dir.dot(&oc),
            oc.dot(&oc) - self.radius * self.radius,
        )?;
        let t = if t0 > T_MIN {
            t0
        } else if t1 > T_MIN {
            t1
        } else {
            return None;
        };
        let n = (origin + dir * t - self.centre) / self.radius;
        Some(Hit {
            t,
            normal: facing(n, dir),
        })
    }

    fn distance(&self, p: &Point3<f64>) -> f64 {
        ((p - self.centre).norm() - self.radius).abs()
    }
}

// ---------------------------------------------------------------------------------------------

/// A rotated box (its six faces).
///
/// As a single [`Surface`] it reports one label for the whole box; use
/// [`crate::sim::Scene::add_cuboid`] for one label per face. Face order of [`Cuboid::faces`]:
/// `+x, −x, +y, −y, +z, −z` of the box's own frame (rotated by `rotation`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cuboid {
    centre: Point3<f64>,
    half_extents: Vector3<f64>,
    rotation: UnitQuaternion<f64>,
}

impl Cuboid {
    /// A box with positive half extents (metres) along its own axes, rotated by `rotation`
    /// (a `UnitQuaternion` or `Rotation3`).
    pub fn new(
        centre: Point3<f64>,
        half_extents: Vector3<f64>,
        rotation: impl Into<UnitQuaternion<f64>>,
    ) -> Result<Self> {
        finite_point(&centre, "cuboid centre")?;
        for h in half_extents.iter() {
            positive(*h, "cuboid half extent")?;
        }
        Ok(Self {
            centre,
            half_extents,
            rotation: rotation.into(),
        })
    }

    /// The centre.
    pub fn centre(&self) -> Point3<f64> {
        self.centre
    }

    /// Half extents along the box's own axes, metres.
    pub fn half_extents(&self) -> Vector3<f64> {
        self.half_extents
    }

    /// The rotation from the box frame to the world frame.
    pub fn rotation(&self) -> UnitQuaternion<f64> {
        self.rotation
    }

    /// The six faces in the order `+x, −x, +y, −y, +z, −z`; each face's normal points out of
    /// the box.
    pub fn faces(&self) -> [Quad; 6] {
        faces_of(&self.centre, &self.half_extents, &self.rotation)
    }
}

/// The six outward-facing faces of a box (half extents taken in absolute value).
pub(crate) fn faces_of(
    centre: &Point3<f64>,
    half: &Vector3<f64>,
    rot: &UnitQuaternion<f64>,
) -> [Quad; 6] {
    let axes = [Vector3::x_axis(), Vector3::y_axis(), Vector3::z_axis()];
    let world: [Unit<Vector3<f64>>; 3] = axes.map(|a| rot * a);
    let h = half.abs();
    let face = |i: usize, sign: f64| {
        // (j, k) chosen so that sign·(e_j × e_k) = outward normal.
        let (j, k) = if sign > 0.0 {
            ((i + 1) % 3, (i + 2) % 3)
        } else {
            ((i + 2) % 3, (i + 1) % 3)
        };
        Quad {
            centre: centre + world[i].into_inner() * (sign * h[i]),
            u: world[j],
            v: world[k],
            normal: if sign > 0.0 { world[i] } else { -world[i] },
            half_u: h[j],
            half_v: h[k],
        }
    };
    [
        face(0, 1.0),
        face(0, -1.0),
        face(1, 1.0),
        face(1, -1.0),
        face(2, 1.0),
        face(2, -1.0),
    ]
}

impl Surface for Cuboid {
    fn intersect(&self, origin: &Point3<f64>, dir: &Vector3<f64>) -> Option<Hit> {
        self.faces()
            .iter()
            .filter_map(|f| f.intersect(origin, dir))
            .min_by(|a, b| a.t.total_cmp(&b.t))
    }

    fn distance(&self, p: &Point3<f64>) -> f64 {
        let local = self.rotation.inverse_transform_vector(&(p - self.centre));
        let q = local.abs() - self.half_extents;
        let outside = q.map(|c| c.max(0.0)).norm();
        if outside > 0.0 {
            outside
        } else {
            // Inside: distance to the nearest face.
            -q.max()
        }
    }
}

// ---------------------------------------------------------------------------------------------

/// A finite cylinder around an axis: its lateral surface, optionally closed by two disc caps.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cylinder {
    centre: Point3<f64>,
    axis: Unit<Vector3<f64>>,
    radius: f64,
    half_length: f64,
    capped: bool,
}

impl Cylinder {
    /// A cylinder centred at `centre` along `axis` (any non-zero length), with positive radius
    /// and half length (metres); `capped` adds the two end discs.
    pub fn new(
        centre: Point3<f64>,
        axis: Vector3<f64>,
        radius: f64,
        half_length: f64,
        capped: bool,
    ) -> Result<Self> {
        finite_point(&centre, "cylinder centre")?;
        positive(radius, "cylinder radius")?;
        positive(half_length, "cylinder half length")?;
        Ok(Self {
            centre,
            axis: unit(axis, "cylinder axis")?,
            radius,
            half_length,
            capped,
        })
    }
}

impl Surface for Cylinder {
    fn intersect(&self, origin: &Point3<f64>, dir: &Vector3<f64>) -> Option<Hit> {
        let a = self.axis.into_inner();
        let o = origin - self.centre;
        let (oa, da) = (o.dot(&a), dir.dot(&a));
        let op = o - a * oa;
        let dp = dir - a * da;
        let mut best: Option<Hit> = None;
        let mut consider = |t: f64, n: Vector3<f64>| {
            if t > T_MIN && best.is_none_or(|b| t < b.t) {
                best = Some(Hit {
                    t,
                    normal: facing(n, dir),
                });
            }
        };
        if let Some((t0, t1)) = quadratic_roots(
            dp.dot(&dp),
            2.0 * dp.dot(&op),
            op.dot(&op) - self.radius * self.radius,
        ) {
            for t in [t0, t1] {
                if (oa + t * da).abs() <= self.half_length {
                    consider(t, (op + dp * t) / self.radius);
                }
            }
        }
        if self.capped && da != 0.0 {
            for s in [1.0, -1.0] {
                let t = (s * self.half_length - oa) / da;
                if (op + dp * t).norm() <= self.radius {
                    consider(t, a * s);
                }
            }
        }
        best
    }

    fn distance(&self, p: &Point3<f64>) -> f64 {
        let a = self.axis.into_inner();
        let d = p - self.centre;
        let axial = d.dot(&a);
        let radial = (d - a * axial).norm();
        let over = (axial.abs() - self.half_length).max(0.0);
        let lateral = (radial - self.radius).hypot(over);
        if !self.capped {
            return lateral;
        }
        let to_cap_plane = (axial.abs() - self.half_length).abs();
        let cap = to_cap_plane.hypot((radial - self.radius).max(0.0));
        lateral.min(cap)
    }
}

// ---------------------------------------------------------------------------------------------

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Rotation3;

    fn close(a: f64, b: f64, tol: f64) -> bool {
        (a - b).abs() <= tol
    }

    #[test]
    fn plane_intersection_and_distance() {
        let p = Plane::new(Point3::new(0.0, 0.0, 2.0), Vector3::new(0.0, 0.0, -3.0)).unwrap();
        let h = p
            .intersect(&Point3::origin(), &Vector3::new(0.1, -0.2, 1.0))
            .unwrap();
        assert!(close(h.t, 2.0, 1e-12));
        assert!(close(h.normal.z, -1.0, 1e-12));
        // From behind: normal flips to face the ray.
        let h = p
            .intersect(&Point3::new(0.0, 0.0, 5.0), &Vector3::new(0.0, 0.0, -1.0))
            .unwrap();
        assert!(close(h.t, 3.0, 1e-12) && close(h.normal.z, 1.0, 1e-12));
        assert!(
            p.intersect(&Point3::origin(), &Vector3::new(0.0, 0.0, -1.0))
                .is_none()
        );
        assert!(
            p.intersect(&Point3::origin(), &Vector3::new(1.0, 0.0, 0.0))
                .is_none()
        );
        assert!(close(p.distance(&Point3::new(3.0, 4.0, 0.5)), 1.5, 1e-12));
        let q = Plane::from_normal_offset(Vector3::new(0.0, 2.0, 0.0), 3.0).unwrap();
        assert!(close(q.offset(), 1.5, 1e-12));
        assert!(close(q.distance(&Point3::new(7.0, 1.0, -2.0)), 0.5, 1e-12));
        assert!(Plane::new(Point3::origin(), Vector3::zeros()).is_err());
    }

    #[test]
    fn core_plane_conversion() {
        // The wall Z = 2 with its normal towards the camera: n = −z, offset_m = 2.
        let core = sl_core::Plane::new(Vector3::new(0.0, 0.0, -2.0), 4.0).unwrap();
        let p = Plane::from_core(&core).unwrap();
        assert_eq!(p.point(), Point3::new(0.0, 0.0, 2.0));
        assert_eq!(p.to_core(), core);
        let h = p.intersect(&Point3::origin(), &Vector3::z()).unwrap();
        assert_eq!(h.t, 2.0);
        let q = Plane::new(Point3::new(1.0, 2.0, 3.0), Vector3::new(0.3, -0.4, 1.0)).unwrap();
        let x = Point3::new(-0.5, 0.25, 4.0);
        assert!(close(
            q.to_core().signed_distance_m(&x),
            q.signed_distance(&x),
            1e-12
        ));
        assert!(
            p.intersect(&Point3::origin(), &Vector3::new(0.0, 0.0, -1.0))
                .is_none()
        );
    }

    #[test]
    fn quad_intersection_and_distance() {
        let q = Quad::new(
            Point3::new(0.0, 0.0, 1.0),
            Vector3::new(0.5, 0.0, 0.0),
            Vector3::new(0.0, 0.25, 0.0),
        )
        .unwrap();
        assert!(
            q.intersect(&Point3::origin(), &Vector3::new(0.49, 0.24, 1.0))
                .is_some()
        );
        assert!(
            q.intersect(&Point3::origin(), &Vector3::new(0.51, 0.0, 1.0))
                .is_none()
        );
        assert!(
            q.intersect(&Point3::origin(), &Vector3::new(0.0, 0.26, 1.0))
                .is_none()
        );
        let h = q
            .intersect(&Point3::new(0.1, 0.1, 3.0), &Vector3::new(0.0, 0.0, -2.0))
            .unwrap();
        assert!(close(h.t, 1.0, 1e-12) && close(h.normal.z, 1.0, 1e-12));
        // Distances: above the face, beside an edge, off a corner.
        assert!(close(q.distance(&Point3::new(0.2, -0.1, 1.3)), 0.3, 1e-12));
        assert!(close(q.distance(&Point3::new(0.9, 0.0, 1.3)), 0.5, 1e-12));
        assert!(close(
            q.distance(&Point3::new(0.5 + 0.3, 0.25 + 0.4, 1.0)),
            0.5,
            1e-12
        ));
        assert!(Quad::new(Point3::origin(), Vector3::x(), Vector3::new(1.0, 1.0, 0.0)).is_err());
    }

    #[test]
    fn sphere_intersection_and_distance() {
        let s = Sphere::new(Point3::new(0.0, 0.0, 3.0), 1.0).unwrap();
        let h = s
            .intersect(&Point3::origin(), &Vector3::new(0.0, 0.0, 2.0))
            .unwrap();
        assert!(close(h.t, 1.0, 1e-12) && close(h.normal.z, -1.0, 1e-12));
        // From inside: the far wall, normal facing the origin (inwards).
        let h = s
            .intersect(&Point3::new(0.0, 0.0, 3.0), &Vector3::new(1.0, 0.0, 0.0))
            .unwrap();
        assert!(close(h.t, 1.0, 1e-12) && close(h.normal.x, -1.0, 1e-12));
        assert!(
            s.intersect(&Point3::origin(), &Vector3::new(1.0, 0.0, 1.0))
                .is_none()
        );
        assert!(close(s.distance(&Point3::new(0.0, 2.0, 3.0)), 1.0, 1e-12));
        assert!(close(s.distance(&Point3::new(0.0, 0.0, 3.25)), 0.75, 1e-12));
        assert!(Sphere::new(Point3::origin(), 0.0).is_err());
    }

    #[test]
    fn cuboid_faces_and_distance() {
        let rot = Rotation3::from_axis_angle(&Vector3::z_axis(), 0.3);
        let c = Cuboid::new(
            Point3::new(0.2, -0.1, 4.0),
            Vector3::new(0.5, 0.3, 0.2),
            rot,
        )
        .unwrap();
        for (i, f) in c.faces().iter().enumerate() {
            // Outward normals, alternating along the box axes.
            let axis = rot * [Vector3::x(), Vector3::y(), Vector3::z()][i / 2];
            let sign = if i % 2 == 0 { 1.0 } else { -1.0 };
            assert!(close(f.normal().dot(&axis), sign, 1e-12), "face {i}");
            assert!(close(c.distance(&f.centre()), 0.0, 1e-12));
            assert!((f.centre() - c.centre()).dot(&f.normal()) > 0.0);
        }
        // Ray along the camera axis hits the −z face at z = 3.8.
        let h = c
            .intersect(&Point3::new(0.2, -0.1, 0.0), &Vector3::z())
            .unwrap();
        assert!(close(h.t, 3.8, 1e-12) && close(h.normal.z, -1.0, 1e-12));
        // Inside: nearest face; outside, beyond a face.
        assert!(close(c.distance(&c.centre()), 0.2, 1e-12));
        assert!(close(c.distance(&Point3::new(0.2, -0.1, 4.5)), 0.3, 1e-12));
        // Off a corner (box frame): distance is the Euclidean norm of the overshoot.
        let corner = c.centre() + rot * Vector3::new(0.5 + 0.3, 0.3 + 0.4, 0.2);
        assert!(close(c.distance(&corner), 0.5, 1e-12));
        assert!(
            Cuboid::new(
                Point3::origin(),
                Vector3::new(1.0, 0.0, 1.0),
                UnitQuaternion::identity()
            )
            .is_err()
        );
    }

    #[test]
    fn cylinder_intersection_and_distance() {
        let c = Cylinder::new(Point3::new(0.0, 0.0, 3.0), Vector3::y(), 0.5, 1.0, true).unwrap();
        let h = c.intersect(&Point3::origin(), &Vector3::z()).unwrap();
        assert!(close(h.t, 2.5, 1e-12) && close(h.normal.z, -1.0, 1e-12));
        // Along the axis from outside: the cap.
        let h = c
            .intersect(&Point3::new(0.0, -3.0, 3.0), &Vector3::y())
            .unwrap();
        assert!(close(h.t, 2.0, 1e-12) && close(h.normal.y, -1.0, 1e-12));
        let open =
            Cylinder::new(Point3::new(0.0, 0.0, 3.0), Vector3::y(), 0.5, 1.0, false).unwrap();
        // Without caps the axial ray passes through.
        assert!(
            open.intersect(&Point3::new(0.0, -3.0, 3.0), &Vector3::y())
                .is_none()
        );
        // Beyond the end (open): distance to the rim.
        assert!(close(
            open.distance(&Point3::new(0.0, 1.3, 3.0)),
            0.3f64.hypot(0.5),
            1e-12
        ));
        assert!(close(c.distance(&Point3::new(0.0, 1.3, 3.0)), 0.3, 1e-12));
        assert!(close(c.distance(&Point3::new(1.0, 0.2, 3.0)), 0.5, 1e-12));
        assert!(close(c.distance(&Point3::new(0.1, 0.9, 3.0)), 0.1, 1e-12));
    }
}
