//! The transforms a recording holds on `/tf` and `/tf_static` (`tf2_msgs/TFMessage`, ROS 1's
//! `tf/tfMessage`): the tree of coordinate frames a robot publishes — a motion-capture
//! system's, a robot's odometry, a SLAM system's map — and the pose of one frame in another at
//! a time, which is where the camera was when it took a frame.
//!
//! Looked up as `tf2` does it, with its gaps made explicit:
//!
//! - every frame has one parent, and a frame's pose in another goes through their nearest
//!   common ancestor; loops, a second parent, and a frame on both `/tf_static` and `/tf` are
//!   refused;
//! - a transform of `/tf_static` holds at every time (its newest sample);
//! - a transform recorded over time is interpolated between the two samples around the time
//!   asked for (the translation linearly, the rotation along the shorter arc) when they are no
//!   more than twice its median interval apart — a transform published regularly; `tf2`
//!   interpolates across any gap, which would bridge a motion capture's dropout;
//! - there is no extrapolation: before a transform's first sample, after its last, or inside
//!   a gap of its samples, the nearest sample is taken only within `max_gap_s` of the time
//!   (`tf2` takes none beyond the ends); further away there is no pose. A transform
//!   republished on `/tf` without ever changing (ROS 1 `tf`'s `static_transform_publisher`, as
//!   bags recorded before `/tf_static` existed hold a camera's own frames) reaches twice its
//!   interval beyond its samples.
//!
//! Frame names are compared without a leading `/` (ROS 1's `tf` wrote `/world`, `tf2` writes
//! `world`). Samples that make no rigid transform (numbers not finite, a zero quaternion, a
//! translation beyond [`MAX_TRANSLATION_M`]) or name no proper frame (empty, longer than
//! [`MAX_FRAME_NAME_BYTES`], its own parent) are left out and counted ([`TfTree::skipped`]).

use std::collections::{BTreeMap, HashMap, HashSet};
use std::fmt;
use std::sync::OnceLock;

use sl_core::nalgebra::{Isometry3, Translation3, UnitQuaternion};

/// A rigid transform between two frames of the tree (the pose of a child frame in its parent).
type Rigid = Isometry3<f64>;

use super::messages::TransformEntry;

/// One frame of a [`TfTree`]: its parent and the samples of its pose there.
#[derive(Debug, Clone, PartialEq)]
pub struct TfFrame {
    /// The frame (`camera_depth_optical_frame`).
    pub frame: String,
    /// The frame its pose is given in (`camera_link`, `odom`, `map`).
    pub parent: String,
    /// Whether its transform is static (`/tf_static`): it holds at any time.
    pub is_static: bool,
    /// Whether it was sampled on `/tf` more than once and never changed (ROS 1 `tf`'s
    /// republished static transforms): it holds within twice its interval of its samples.
    pub republished_constant: bool,
    /// Samples of its pose (one for most static transforms).
    pub samples: usize,
    /// The first sample's stamp, seconds.
    pub first_s: f64,
    /// The last sample's stamp, seconds.
    pub last_s: f64,
}

/// Why a pose could not be looked up.
#[derive(Debug, Clone, PartialEq)]
pub enum TfLookupError {
    /// The frame is in no transform of the recording.
    UnknownFrame(String),
    /// The two frames are in different trees: no chain of transforms joins them.
    NotConnected {
        /// The frame whose pose was asked for.
        frame: String,
        /// The frame it was asked in.
        target: String,
    },
    /// The chain from the frame to its root is longer than [`MAX_CHAIN_FRAMES`].
    ChainTooLong(String),
    /// The time asked for is not a finite number (no pose is at it, not even a frame's in
    /// itself).
    TimeNotFinite(f64),
    /// The chain's transforms compose into a pose that is not finite.
    NotFinite {
        /// The frame whose pose was asked for.
        frame: String,
        /// The frame it was asked in.
        target: String,
        /// The time asked for, seconds.
        time_s: f64,
    },
    /// A transform of the chain has no sample near enough to the time.
    NoSample {
        /// The transform's child frame.
        frame: String,
        /// The transform's parent frame.
        parent: String,
        /// The time asked for, seconds.
        time_s: f64,
        /// The transform's first sample, seconds.
        first_s: f64,
        /// The transform's last sample, seconds.
        last_s: f64,
    },
}

impl fmt::Display for TfLookupError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::UnknownFrame(name) => write!(f, "no transform names the frame {name:?}"),
            Self::NotConnected { frame, target } => write!(
                f,
                "no chain of transforms joins {frame:?} to {target:?} (they are in different \
                 trees)"
            ),
            Self::ChainTooLong(frame) => write!(
                f,
                "the chain of frames above {frame:?} is longer than {MAX_CHAIN_FRAMES}"
            ),
            Self::TimeNotFinite(t) => write!(f, "the time {t} s is not a finite number"),
            Self::NotFinite {
                frame,
                target,
                time_s,
            } => write!(
                f,
                "the pose of {frame:?} in {target:?} at {time_s:.6} s is not finite"
            ),
            Self::NoSample {
                frame,
                parent,
                time_s,
                first_s,
                last_s,
            } => write!(
                f,
                "the transform {parent} → {frame} has no sample near {time_s:.6} s (its samples \
                 span {first_s:.6}–{last_s:.6} s)"
            ),
        }
    }
}

impl std::error::Error for TfLookupError {}

/// The longest frame name kept, bytes (ROS frame names are a few dozen; a longer one is left
/// out, so that a small recording cannot make the tree hold gigabytes of names).
pub const MAX_FRAME_NAME_BYTES: usize = 1024;
/// The farthest a transform may move a frame, metres: a sample beyond it is left out (no robot
/// or camera is 10,000 km from its parent frame), so that chains of transforms stay finite.
pub const MAX_TRANSLATION_M: f64 = 1e7;
/// The longest chain of frames looked through (a robot's tree is a few dozen deep).
pub const MAX_CHAIN_FRAMES: usize = 1024;

/// The pose of a frame in its parent, sampled over time.
#[derive(Debug, Clone)]
struct Edge {
    parent: String,
    /// Published on `/tf_static`.
    is_static: bool,
    /// `(stamp, pose)` by stamp ([`time_key`]), one per stamp (the last recorded kept).
    samples: BTreeMap<u64, (f64, Rigid)>,
    /// The first sample recorded, and whether any other differs from it.
    first: Rigid,
    varies: bool,
    /// The median interval between consecutive samples, seconds (computed on first use).
    interval_s: OnceLock<f64>,
}

impl Edge {
    /// Whether it was sampled more than once on `/tf` without ever changing: ROS 1 `tf`'s
    /// `static_transform_publisher` republished its transform so, with fresh stamps, before
    /// `/tf_static` existed).
    fn is_republished_constant(&self) -> bool {
        !self.is_static && self.samples.len() > 1 && !self.varies
    }

    /// The median interval between consecutive samples, seconds (0 with fewer than two).
    fn interval_s(&self) -> f64 {
        *self.interval_s.get_or_init(|| {
            let t: Vec<f64> = self.samples.values().map(|(t, _)| *t).collect();
            let mut d: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
            if d.is_empty() {
                return 0.0;
            }
            let mid = d.len() / 2;
            *d.select_nth_unstable_by(mid, f64::total_cmp).1
        })
    }
}

/// An order-preserving key of a finite stamp (`f64::total_cmp`'s order as an integer).
fn time_key(t: f64) -> u64 {
    let b = t.to_bits();
    if b >> 63 == 1 { !b } else { b | (1 << 63) }
}

/// The tree of frames of a recording's transforms (see the module docs), built by
/// [`super::RosBag::transforms`] or from transforms given by hand ([`TfTree::insert`]).
#[derive(Debug, Clone)]
pub struct TfTree {
    /// Each frame's edge to its parent, by the frame's name.
    edges: HashMap<String, Edge>,
    /// Every frame that is some frame's parent.
    parents: HashSet<String>,
    /// Samples left out (see [`TfTree::skipped`]).
    skipped: usize,
    /// Samples kept.
    samples: usize,
}

/// A frame name as compared: without ROS 1's leading `/`.
fn normalised(name: &str) -> &str {
    name.trim_start_matches('/')
}

impl Default for TfTree {
    fn default() -> Self {
        Self::new()
    }
}

impl TfTree {
    /// An empty tree.
    pub fn new() -> Self {
        Self {
            edges: HashMap::new(),
            parents: HashSet::new(),
            skipped: 0,
            samples: 0,
        }
    }

    /// Adds one sample: the pose of `child` in `parent` at `stamp_s` (`t` in metres, the
    /// quaternion `x, y, z, w`), from `/tf_static` (`is_static`) or `/tf`. A sample left out
    /// ([`TfTree::skipped`]: numbers that make no rigid transform, a translation beyond
    /// [`MAX_TRANSLATION_M`], a frame name empty, longer than [`MAX_FRAME_NAME_BYTES`] or its
    /// own parent) is counted and is no error.
    ///
    /// # Errors
    /// Transforms that make no tree, named in the message: a frame given a second parent, a
    /// frame on both `/tf_static` and `/tf`, a loop of frames, or a chain of more than
    /// [`MAX_CHAIN_FRAMES`].
    pub fn insert(
        &mut self,
        parent: &str,
        child: &str,
        stamp_s: f64,
        t: [f64; 3],
        q_xyzw: [f64; 4],
        is_static: bool,
    ) -> Result<(), String> {
        let (parent, child) = (normalised(parent), normalised(child));
        let names_ok = |n: &str| !n.is_empty() && n.len() <= MAX_FRAME_NAME_BYTES;
        let pose = match sl_core::pose::pose_from_translation_quaternion(t, q_xyzw) {
            Ok(p)
                if stamp_s.is_finite()
                    && names_ok(parent)
                    && names_ok(child)
                    && parent != child
                    && p.translation.vector.norm() <= MAX_TRANSLATION_M =>
            {
                p
            }
            _ => {
                self.skipped += 1;
                return Ok(());
            }
        };
        if !self.edges.contains_key(child) {
            self.check_new_edge(parent, child)?;
            self.parents.insert(parent.to_owned());
        }
        let edge = self.edges.entry(child.to_owned()).or_insert_with(|| Edge {
            parent: parent.to_owned(),
            is_static,
            samples: BTreeMap::new(),
            first: pose,
            varies: false,
            interval_s: OnceLock::new(),
        });
        if edge.parent != parent {
            return Err(format!(
                "the frame {child:?} has two parents, {:?} and {parent:?} (a frame of a \
                 transform tree has one)",
                edge.parent
            ));
        }
        if edge.is_static != is_static {
            return Err(format!(
                "the frame {child:?} is published both on /tf_static and on /tf (a transform \
                 is static or moving, not both)"
            ));
        }
        edge.varies |= edge.first != pose;
        edge.interval_s = OnceLock::new();
        if edge
            .samples
            .insert(time_key(stamp_s), (stamp_s, pose))
            .is_none()
        {
            self.samples += 1;
        }
        Ok(())
    }

    /// Refuses an edge `child → parent` that would close a loop, or hang `child` below a
    /// chain longer than [`MAX_CHAIN_FRAMES`].
    fn check_new_edge(&self, parent: &str, child: &str) -> Result<(), String> {
        let mut at = parent;
        for _ in 0..MAX_CHAIN_FRAMES {
            if at == child {
                return Err(format!(
                    "the transform {parent:?} → {child:?} closes a loop of frames (a transform \
                     tree has none)"
                ));
            }
            match self.edges.get(at) {
                Some(e) => at = e.parent.as_str(),
                None => return Ok(()),
            }
        }
        Err(format!(
            "the frame {child:?} hangs below a chain of more than {MAX_CHAIN_FRAMES} frames"
        ))
    }

    /// Adds the transforms of one message.
    pub(super) fn insert_entries(
        &mut self,
        entries: &[TransformEntry],
        is_static: bool,
    ) -> Result<(), String> {
        for e in entries {
            self.insert(
                &e.parent,
                &e.child,
                e.stamp_s,
                e.translation,
                e.rotation_xyzw,
                is_static,
            )?;
        }
        Ok(())
    }

    /// Samples kept.
    pub fn samples(&self) -> usize {
        self.samples
    }

    /// Samples left out: numbers that make no rigid transform (not finite, a zero
    /// quaternion), a translation beyond [`MAX_TRANSLATION_M`], or a frame name that is
    /// empty, longer than [`MAX_FRAME_NAME_BYTES`] or its own parent.
    pub fn skipped(&self) -> usize {
        self.skipped
    }

    /// Whether any transform names `frame` (as child or parent).
    pub fn has_frame(&self, frame: &str) -> bool {
        let frame = normalised(frame);
        self.edges.contains_key(frame) || self.parents.contains(frame)
    }

    /// Every frame that has a parent, sorted by name.
    pub fn frames(&self) -> Vec<TfFrame> {
        let mut out: Vec<TfFrame> = self
            .edges
            .iter()
            .map(|(frame, e)| TfFrame {
                frame: frame.clone(),
                parent: e.parent.clone(),
                is_static: e.is_static,
                republished_constant: e.is_republished_constant(),
                samples: e.samples.len(),
                first_s: e.samples.values().next().map_or(f64::NAN, |s| s.0),
                last_s: e.samples.values().next_back().map_or(f64::NAN, |s| s.0),
            })
            .collect();
        out.sort_by(|a, b| a.frame.cmp(&b.frame));
        out
    }

    /// The frames from `frame` up to its root, `frame` first.
    ///
    /// # Errors
    /// A chain longer than [`MAX_CHAIN_FRAMES`].
    fn chain<'a>(&'a self, frame: &'a str) -> Result<Vec<&'a str>, TfLookupError> {
        let mut out = vec![frame];
        let mut at = frame;
        while let Some(e) = self.edges.get(at) {
            if out.len() > MAX_CHAIN_FRAMES {
                return Err(TfLookupError::ChainTooLong(frame.to_owned()));
            }
            at = e.parent.as_str();
            out.push(at);
        }
        Ok(out)
    }

    /// The pose of `frame` in `target` at `time_s`: `T_target_frame`, which maps points of
    /// `frame` into `target` (for a camera's optical frame in a world frame, the camera-to-world
    /// pose). Each transform of the chain at `time_s`:
    ///
    /// - a static one: its newest sample;
    /// - between two samples no more than twice its median interval apart (a transform
    ///   published regularly; or no more than `2·max_gap_s` apart): interpolated;
    /// - otherwise (before its first sample, after its last, or in a gap of its samples, a
    ///   motion capture's dropout): its nearest sample within `max_gap_s` of `time_s`, or
    ///   within twice its interval for a transform republished unchanged; else no pose.
    ///
    /// # Errors
    /// An unknown frame, frames in different trees, a transform without a sample near
    /// enough, or a pose that is not finite ([`TfLookupError`]).
    pub fn lookup(
        &self,
        target: &str,
        frame: &str,
        time_s: f64,
        max_gap_s: f64,
    ) -> Result<Isometry3<f64>, TfLookupError> {
        let (target, frame) = (normalised(target), normalised(frame));
        for f in [frame, target] {
            if !self.has_frame(f) {
                return Err(TfLookupError::UnknownFrame(f.to_owned()));
            }
        }
        if !time_s.is_finite() {
            return Err(TfLookupError::TimeNotFinite(time_s));
        }
        let up = self.chain(frame)?;
        let down = self.chain(target)?;
        // The nearest common ancestor: the first frame of `frame`'s chain on `target`'s.
        let on_down: HashMap<&str, usize> = down.iter().enumerate().map(|(j, f)| (*f, j)).collect();
        let Some((i, j)) = up
            .iter()
            .enumerate()
            .find_map(|(i, f)| on_down.get(f).map(|&j| (i, j)))
        else {
            return Err(TfLookupError::NotConnected {
                frame: frame.to_owned(),
                target: target.to_owned(),
            });
        };
        let in_ancestor = |chain: &[&str]| -> Result<Rigid, TfLookupError> {
            // `chain[0]`'s pose in `chain[last]`: the edges composed from the ancestor down.
            let mut pose = Rigid::identity();
            for f in chain[..chain.len() - 1].iter().rev() {
                pose *= self.edge_at(f, time_s, max_gap_s)?;
            }
            Ok(pose)
        };
        let frame_in_ancestor = in_ancestor(&up[..=i])?;
        let target_in_ancestor = in_ancestor(&down[..=j])?;
        let pose = target_in_ancestor.inverse() * frame_in_ancestor;
        let finite = pose.translation.vector.iter().all(|v| v.is_finite())
            && pose.rotation.coords.iter().all(|v| v.is_finite());
        if !finite {
            return Err(TfLookupError::NotFinite {
                frame: frame.to_owned(),
                target: target.to_owned(),
                time_s,
            });
        }
        Ok(pose)
    }

    /// The pose of `frame` in its parent at `time_s` (see [`TfTree::lookup`]).
    fn edge_at(&self, frame: &str, time_s: f64, max_gap_s: f64) -> Result<Rigid, TfLookupError> {
        let Some(e) = self.edges.get(frame) else {
            return Err(TfLookupError::UnknownFrame(frame.to_owned()));
        };
        let first = e.samples.values().next();
        let last = e.samples.values().next_back();
        let no_sample = || TfLookupError::NoSample {
            frame: frame.to_owned(),
            parent: e.parent.clone(),
            time_s,
            first_s: first.map_or(f64::NAN, |s| s.0),
            last_s: last.map_or(f64::NAN, |s| s.0),
        };
        let Some(&(_, newest)) = last else {
            return Err(no_sample());
        };
        if e.is_static {
            return Ok(newest);
        }
        if !time_s.is_finite() {
            return Err(no_sample());
        }
        let key = time_key(time_s);
        let before = e.samples.range(..=key).next_back().map(|(_, s)| *s);
        let after = e.samples.range(key..).next().map(|(_, s)| *s);
        let interval = e.interval_s();
        // How far from a sample a time may be and still take it.
        let reach = if e.is_republished_constant() {
            max_gap_s.max(2.0 * interval)
        } else {
            max_gap_s
        };
        match (before, after) {
            (Some((t0, a)), Some((t1, b))) => {
                if t0 == t1 {
                    return Ok(a);
                }
                if t1 - t0 <= (2.0 * interval).max(2.0 * max_gap_s) {
                    return Ok(interpolate(&a, &b, (time_s - t0) / (t1 - t0)));
                }
                let (d, p) = if time_s - t0 <= t1 - time_s {
                    (time_s - t0, a)
                } else {
                    (t1 - time_s, b)
                };
                if d <= reach { Ok(p) } else { Err(no_sample()) }
            }
            (Some((t, p)), None) | (None, Some((t, p))) if (time_s - t).abs() <= reach => Ok(p),
            _ => Err(no_sample()),
        }
    }
}

/// The pose a fraction `s` (0–1) of the way from `a` to `b`: the translation linearly, the
/// rotation along the shorter arc (slerp; normalised linear interpolation where the two
/// rotations are too close for slerp's formula).
fn interpolate(a: &Rigid, b: &Rigid, s: f64) -> Rigid {
    let ta = a.translation.vector;
    let tb = b.translation.vector;
    let t = ta + (tb - ta) * s;
    let qa = a.rotation;
    // The shorter arc: `q` and `−q` are the same rotation.
    let qb = if qa.coords.dot(&b.rotation.coords) < 0.0 {
        UnitQuaternion::new_unchecked(-b.rotation.into_inner())
    } else {
        b.rotation
    };
    let q = qa.try_slerp(&qb, s, 1e-12).unwrap_or_else(|| {
        UnitQuaternion::new_normalize(qa.into_inner() * (1.0 - s) + qb.into_inner() * s)
    });
    Rigid::from_parts(Translation3::from(t), q)
}

#[cfg(test)]
mod tests {
    use super::*;
    use sl_core::nalgebra::{Point3, Vector3};

    fn q_of(axis: Vector3<f64>, deg: f64) -> [f64; 4] {
        let q = UnitQuaternion::from_scaled_axis(axis * deg.to_radians());
        [q.i, q.j, q.k, q.w]
    }

    /// `map → odom` static, `odom → base` moving along x and turning about z,
    /// `base → camera_link` static, `camera_link → optical` static (the optical frame's axes).
    fn robot() -> TfTree {
        let mut t = TfTree::new();
        t.insert(
            "map",
            "odom",
            0.0,
            [1.0, 2.0, 0.0],
            q_of(Vector3::z(), 90.0),
            true,
        )
        .unwrap();
        for i in 0..=10 {
            let s = f64::from(i);
            t.insert(
                "/odom",
                "base",
                10.0 + s,
                [s, 0.0, 0.0],
                q_of(Vector3::z(), 3.0 * s),
                false,
            )
            .unwrap();
        }
        t.insert(
            "base",
            "camera_link",
            0.0,
            [0.1, 0.0, 0.5],
            [0.0, 0.0, 0.0, 1.0],
            true,
        )
        .unwrap();
        // ROS's optical frame: z forward (the link's x), x right (−y), y down (−z).
        let r = UnitQuaternion::from_basis_unchecked(&[
            Vector3::new(0.0, -1.0, 0.0),
            Vector3::new(0.0, 0.0, -1.0),
            Vector3::new(1.0, 0.0, 0.0),
        ]);
        t.insert(
            "camera_link",
            "optical",
            0.0,
            [0.0; 3],
            [r.i, r.j, r.k, r.w],
            true,
        )
        .unwrap();
        t
    }

    #[test]
    fn a_chain_composes_its_transforms_and_interpolates_between_samples() {
        let t = robot();
        // At 12.5 s the base is at x = 2.5 in odom, turned 7.5° about z.
        let p = t.lookup("map", "optical", 12.5, 0.02).unwrap();
        let base = Rigid::from_parts(
            Translation3::new(2.5, 0.0, 0.0),
            UnitQuaternion::from_scaled_axis(Vector3::z() * 7.5f64.to_radians()),
        );
        let odom = Rigid::from_parts(
            Translation3::new(1.0, 2.0, 0.0),
            UnitQuaternion::from_scaled_axis(Vector3::z() * 90f64.to_radians()),
        );
        // The camera's origin is 0.1 m ahead of the base and 0.5 m up; its z axis looks ahead.
        let origin = odom * base * Point3::new(0.1, 0.0, 0.5);
        let ahead = (odom * base).rotation * Vector3::x();
        assert!((p * Point3::origin() - origin).norm() < 1e-12);
        assert!((p.rotation * Vector3::z() - ahead).norm() < 1e-12);
        // The camera's y axis (image down) points down in the world.
        assert!((p.rotation * Vector3::y() - Vector3::new(0.0, 0.0, -1.0)).norm() < 1e-12);
        // Asked the other way round: the inverse.
        let back = t.lookup("optical", "map", 12.5, 0.02).unwrap();
        assert!(((back * p).to_homogeneous() - Rigid::identity().to_homogeneous()).norm() < 1e-12);
        // Frames that share an ancestor below the root: camera_link in odom.
        let q = t.lookup("odom", "camera_link", 10.0, 0.02).unwrap();
        assert!((q.translation.vector - Vector3::new(0.1, 0.0, 0.5)).norm() < 1e-12);
    }

    #[test]
    fn there_is_no_extrapolation_beyond_the_gap() {
        let t = robot();
        // The moving transform spans 10–20 s.
        assert!(t.lookup("map", "optical", 20.01, 0.02).is_ok());
        assert!(t.lookup("map", "optical", 9.99, 0.02).is_ok());
        let e = t.lookup("map", "optical", 20.5, 0.02).unwrap_err();
        assert!(
            matches!(&e, TfLookupError::NoSample { frame, parent, .. } if frame == "base" && parent == "odom"),
            "{e}"
        );
        assert!(e.to_string().contains("10.000000–20.000000 s"), "{e}");
        // Static transforms hold at any time, even long before the moving ones.
        assert!(t.lookup("map", "odom", -1e6, 0.02).is_ok());
        // A time that is no number: no pose, not even through static transforms only.
        for bad in [f64::NAN, f64::INFINITY] {
            for (target, frame) in [("map", "optical"), ("map", "odom"), ("map", "map")] {
                let e = t.lookup(target, frame, bad, 0.02);
                assert!(
                    matches!(e, Err(TfLookupError::TimeNotFinite(x)) if x.to_bits() == bad.to_bits()),
                    "{e:?}"
                );
            }
        }
        assert!(t.lookup("map", "optical", 12.0, f64::NAN).is_ok());
        assert_eq!(
            t.lookup("map", "nowhere", 12.0, 0.02),
            Err(TfLookupError::UnknownFrame("nowhere".into()))
        );
    }

    #[test]
    fn separate_trees_two_parents_and_bad_numbers_are_said() {
        let mut t = robot();
        t.insert(
            "elsewhere",
            "marker",
            0.0,
            [0.0; 3],
            [0.0, 0.0, 0.0, 1.0],
            true,
        )
        .unwrap();
        assert!(matches!(
            t.lookup("map", "marker", 12.0, 0.02),
            Err(TfLookupError::NotConnected { .. })
        ));
        let e = t
            .insert("map", "base", 11.0, [0.0; 3], [0.0, 0.0, 0.0, 1.0], false)
            .unwrap_err();
        assert!(e.contains("two parents"), "{e}");
        let before = t.samples();
        // A frame its own parent is left out, as bad numbers are.
        t.insert("a", "/a", 0.0, [0.0; 3], [0.0, 0.0, 0.0, 1.0], false)
            .unwrap();
        t.insert(
            "odom",
            "base",
            30.0,
            [f64::NAN, 0.0, 0.0],
            [0.0, 0.0, 0.0, 1.0],
            false,
        )
        .unwrap();
        t.insert("odom", "base", 31.0, [0.0; 3], [0.0; 4], false)
            .unwrap();
        assert_eq!((t.samples(), t.skipped()), (before, 3));
    }

    #[test]
    fn samples_out_of_order_are_sorted_and_the_last_of_a_stamp_kept() {
        let mut t = TfTree::new();
        for (s, x) in [(2.0, 2.0), (0.0, 0.0), (1.0, 5.0), (1.0, 1.0)] {
            t.insert("w", "c", s, [x, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0], false)
                .unwrap();
        }
        assert_eq!(t.samples(), 3);
        let p = t.lookup("w", "c", 1.5, 0.0).unwrap();
        assert!((p.translation.x - 1.5).abs() < 1e-12);
        let f = &t.frames()[0];
        assert_eq!((f.first_s, f.last_s, f.samples), (0.0, 2.0, 3));
    }

    #[test]
    fn a_transform_republished_unchanged_reaches_twice_its_interval() {
        let mut t = TfTree::new();
        // ROS 1 `tf`'s static publisher: the same transform on /tf every 0.1 s.
        for i in 0..3 {
            let s = 10.0 + 0.1 * f64::from(i);
            t.insert(
                "kinect",
                "optical",
                s,
                [0.0, 0.02, 0.0],
                [0.0, 0.0, 0.0, 1.0],
                false,
            )
            .unwrap();
        }
        // One sample alone says nothing of other times.
        t.insert(
            "world",
            "kinect",
            10.0,
            [1.0, 0.0, 0.0],
            [0.0, 0.0, 0.0, 1.0],
            false,
        )
        .unwrap();
        assert!(t.lookup("kinect", "optical", 9.85, 0.02).is_ok());
        assert!(t.lookup("kinect", "optical", 10.39, 0.02).is_ok());
        assert!(t.lookup("kinect", "optical", 9.7, 0.02).is_err());
        assert!(t.lookup("world", "kinect", 10.1, 0.02).is_err());
        let frames = t.frames();
        assert!(!frames[0].republished_constant && frames[1].republished_constant);
        assert!(!frames[1].is_static);
        // A change makes it a moving transform again.
        t.insert(
            "kinect",
            "optical",
            10.3,
            [0.0, 0.03, 0.0],
            [0.0, 0.0, 0.0, 1.0],
            false,
        )
        .unwrap();
        assert!(t.lookup("kinect", "optical", 9.85, 0.02).is_err());
        let p = t.lookup("kinect", "optical", 10.25, 0.02).unwrap();
        assert!((p.translation.y - 0.025).abs() < 1e-12);
    }

    #[test]
    fn a_gap_in_the_samples_is_not_bridged() {
        let mut t = TfTree::new();
        // 100 Hz, with a dropout from 10.1 to 10.5 s.
        let stamps = (0..=10).chain(50..=60).map(|i| 10.0 + 0.01 * f64::from(i));
        for s in stamps {
            t.insert("w", "c", s, [s, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0], false)
                .unwrap();
        }
        assert!(t.lookup("w", "c", 10.055, 0.02).is_ok());
        // Within 20 ms of the dropout's ends: the nearest sample; in its middle: nothing.
        let near = t.lookup("w", "c", 10.115, 0.02).unwrap();
        assert!((near.translation.x - 10.1).abs() < 1e-12);
        assert!(t.lookup("w", "c", 10.3, 0.02).is_err());
        // A wider gap asked for bridges it.
        let wide = t.lookup("w", "c", 10.3, 0.25).unwrap();
        assert!((wide.translation.x - 10.3).abs() < 1e-9);
    }

    #[test]
    fn loops_and_static_moving_mixtures_are_refused_long_names_left_out() {
        let q = [0.0, 0.0, 0.0, 1.0];
        let mut t = TfTree::new();
        t.insert("a", "b", 0.0, [0.0; 3], q, false).unwrap();
        t.insert("b", "c", 0.0, [0.0; 3], q, false).unwrap();
        let e = t.insert("c", "a", 0.0, [0.0; 3], q, false).unwrap_err();
        assert!(e.contains("closes a loop"), "{e}");
        let e = t.insert("a", "b", 1.0, [0.0; 3], q, true).unwrap_err();
        assert!(e.contains("both on /tf_static and on /tf"), "{e}");
        let long = "x".repeat(MAX_FRAME_NAME_BYTES + 1);
        t.insert("a", &long, 0.0, [0.0; 3], q, false).unwrap();
        t.insert("a", "far", 0.0, [2e7, 0.0, 0.0], q, false)
            .unwrap();
        t.insert("a", "/a", 0.0, [0.0; 3], q, false).unwrap();
        assert_eq!((t.samples(), t.skipped()), (2, 3));
        assert!(!t.has_frame(&long) && !t.has_frame("far"));
    }

    #[test]
    fn long_chains_are_bounded_and_reversed_samples_are_cheap() {
        let q = [0.0, 0.0, 0.0, 1.0];
        // Each frame's parent given before the frame's own parent is known: the chain above a
        // new edge is short when it is added, and grows past the bound; a lookup says so.
        let mut deep = TfTree::new();
        for i in 0..MAX_CHAIN_FRAMES + 2 {
            deep.insert(
                &format!("f{}", i + 1),
                &format!("f{i}"),
                0.0,
                [0.0; 3],
                q,
                true,
            )
            .unwrap();
        }
        assert!(matches!(
            deep.lookup("f5", "f0", 0.0, 0.02),
            Err(TfLookupError::ChainTooLong(_))
        ));
        // A frame hung below that chain is refused when it is added.
        let e = deep.insert("f0", "g", 0.0, [0.0; 3], q, true).unwrap_err();
        assert!(e.contains("chain of more than"), "{e}");
        // 200,000 samples newest first: each inserted in its place without moving the rest.
        let mut r = TfTree::new();
        for i in (0..200_000).rev() {
            r.insert("w", "c", f64::from(i) * 0.01, [0.0; 3], q, false)
                .unwrap();
        }
        assert_eq!(r.samples(), 200_000);
        assert!(r.lookup("w", "c", 1000.005, 0.0).is_ok());
    }

    #[test]
    fn rotations_interpolate_along_the_shorter_arc() {
        let a = Rigid::from_parts(
            Translation3::new(0.0, 0.0, 0.0),
            UnitQuaternion::from_scaled_axis(Vector3::z() * 170f64.to_radians()),
        );
        // −q of a rotation of −170° (= 190°): the shorter arc passes through 180°.
        let r = UnitQuaternion::from_scaled_axis(Vector3::z() * (-170f64).to_radians());
        let b = Rigid::from_parts(
            Translation3::new(2.0, 0.0, 0.0),
            UnitQuaternion::new_unchecked(-r.into_inner()),
        );
        let m = interpolate(&a, &b, 0.5);
        assert!((m.rotation.angle() - std::f64::consts::PI).abs() < 1e-9);
        assert!((m.translation.x - 1.0).abs() < 1e-12);
        // Equal rotations: no division by a zero angle.
        let same = interpolate(&a, &a, 0.3);
        assert!((same.rotation.angle_to(&a.rotation)).abs() < 1e-12);
    }
}
