//! The fast paths of [`TsdfVolume::integrate`] against straightforward f64 references: block
//! discovery (the band of blocks) against a segment/box test of every valid pixel's segment,
//! the voxel update (every weight mode, both depth lookups, both pixel-table gathers, blocks
//! with and without voxels behind the camera) against a per-voxel projective update, and the
//! budget-capped block arena.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::collections::{BTreeSet, HashMap, HashSet};

use nalgebra::Point3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use sl_core::{CameraToWorld, SensorModel};

use super::*;
use crate::params::{DepthLookup, SAME_SURFACE_MAX_INCIDENCE_DEG, WeightMode};
use sl_noise::sim::{Plane, Scene, Sphere};

/// Allowance for the f32 arithmetic of the fast path, in block units (1/1000 of a block): a
/// block whose box the segment misses or meets by less than this may go either way.
const EPS_BLOCKS: f64 = 1e-3;

/// Pixels whose projection falls this close (pixels) to the boundary between two pixels may
/// pick either in f32.
const EPS_PX: f64 = 2e-3;

/// Voxels whose signed distance is this close (metres) to `−trunc` may be in or out.
const EPS_SDF_M: f64 = 1e-5;

fn valid_depth(p: &TsdfConfig, d: f32) -> bool {
    d > p.min_depth_m as f32 && d <= p.max_depth_m as f32
}

fn small_camera() -> Intrinsics {
    Intrinsics::new(160, 120, 150.0, 147.0, 77.3, 61.9).unwrap()
}

fn random_pose(rng: &mut ChaCha8Rng, t_m: f64, angle: f64) -> Isometry3<f64> {
    let axis = Vector3::new(
        rng.random_range(-1.0..1.0),
        rng.random_range(-1.0..1.0),
        rng.random_range(-1.0..1.0),
    );
    Isometry3::new(
        Vector3::new(
            rng.random_range(-t_m..t_m),
            rng.random_range(-t_m..t_m),
            rng.random_range(-t_m..t_m),
        ),
        axis.normalize() * rng.random_range(0.0..angle),
    )
}

/// Tilted random patches of depth in `range` with holes: 5 % random invalid pixels, a
/// rectangular hole, and a few NaN / infinite / negative values (invalid too). The image
/// borders keep their (mostly valid) patches.
fn patch_frame(rng: &mut ChaCha8Rng, w: usize, h: usize, range: (f32, f32)) -> Vec<f32> {
    let patch = 6;
    let cw = w.div_ceil(patch);
    let cells: Vec<f32> = (0..cw * h.div_ceil(patch))
        .map(|_| rng.random_range(range.0..range.1))
        .collect();
    let hole = (rng.random_range(0..w / 2), rng.random_range(0..h / 2));
    (0..w * h)
        .map(|i| {
            let (x, y) = (i % w, i / w);
            let r: f32 = rng.random_range(0.0..1.0);
            if r < 0.05 || (x >= hole.0 && x < hole.0 + w / 5 && y >= hole.1 && y < hole.1 + h / 5)
            {
                return 0.0;
            }
            if r > 0.998 {
                return [f32::NAN, f32::INFINITY, -1.0][i % 3];
            }
            let c = cells[x / patch + cw * (y / patch)];
            c + 0.003 * (x % patch) as f32 - 0.002 * (y % patch) as f32
        })
        .collect()
}

/// Keeps only the pixels on the image border (rows 0 and h − 1, columns 0 and w − 1).
fn border_only(depth: &mut [f32], w: usize, h: usize) {
    for (i, d) in depth.iter_mut().enumerate() {
        let (x, y) = (i % w, i / w);
        if x != 0 && x != w - 1 && y != 0 && y != h - 1 {
            *d = 0.0;
        }
    }
}

/// Whether the segment `a → b` meets the unit box of cell `c` grown by `grow` on every side.
fn segment_meets_box(a: &Vector3<f64>, b: &Vector3<f64>, c: [i32; 3], grow: f64) -> bool {
    let (mut t0, mut t1) = (0.0f64, 1.0f64);
    for ax in 0..3 {
        let lo = f64::from(c[ax]) - grow;
        let hi = f64::from(c[ax]) + 1.0 + grow;
        let d = b[ax] - a[ax];
        if d == 0.0 {
            if a[ax] < lo || a[ax] > hi {
                return false;
            }
        } else {
            let (ta, tb) = ((lo - a[ax]) / d, (hi - a[ax]) / d);
            t0 = t0.max(ta.min(tb));
            t1 = t1.min(ta.max(tb));
        }
    }
    t0 <= t1
}

/// The band by brute force, in f64: every valid pixel's segment along its pixel-centre ray,
/// from depth `max(d − dt, 0)` to `d + dt` with `dt = trunc/‖ray‖` (±trunc in range), tested
/// against the box of every block near it. A point belongs to the block of its nearest voxel,
/// so block `c` is the box `[8c − 1/2, 8c + 15/2]` in voxel units. `grow` (block units) grows
/// the boxes (negative: shrinks them).
fn reference_band(
    p: &TsdfConfig,
    k: &Intrinsics,
    pose: &Isometry3<f64>,
    depth: &[f32],
    grow: f64,
) -> BTreeSet<[i32; 3]> {
    let bs = p.voxel_m * BLOCK_SIDE as f64;
    let shift = Vector3::repeat(0.5 / BLOCK_SIDE as f64);
    let mut out = BTreeSet::new();
    for (i, &d) in depth.iter().enumerate() {
        if !valid_depth(p, d) {
            continue;
        }
        let (x, y) = (i % k.width, i / k.width);
        let ray = Vector3::new((x as f64 - k.cx) / k.fx, (y as f64 - k.cy) / k.fy, 1.0);
        let d = f64::from(d);
        let dt = p.band_at(d) / ray.norm();
        let at = |z: f64| (pose * Point3::from(ray * z)).coords / bs + shift;
        let (a, b) = (at((d - dt).max(0.0)), at(d + dt));
        let lo = a.inf(&b).map(|c| c.floor() as i32 - 1);
        let hi = a.sup(&b).map(|c| c.floor() as i32 + 1);
        for cz in lo.z..=hi.z {
            for cy in lo.y..=hi.y {
                for cx in lo.x..=hi.x {
                    if segment_meets_box(&a, &b, [cx, cy, cz], grow) {
                        out.insert([cx, cy, cz]);
                    }
                }
            }
        }
    }
    out
}

/// The bands with shrunk and grown boxes: the fast path must find every block of the first
/// and no block outside the second.
fn reference_bands(
    p: &TsdfConfig,
    k: &Intrinsics,
    pose: &Isometry3<f64>,
    depth: &[f32],
) -> (BTreeSet<[i32; 3]>, BTreeSet<[i32; 3]>) {
    let inner = reference_band(p, k, pose, depth, -EPS_BLOCKS);
    let outer = reference_band(p, k, pose, depth, EPS_BLOCKS);
    // The allowance must stay an allowance for rounding, not hide a different band.
    assert!(
        (outer.len() - inner.len()) * 50 <= inner.len(),
        "{} of {} blocks ambiguous",
        outer.len() - inner.len(),
        inner.len()
    );
    (inner, outer)
}

fn image(k: &Intrinsics, depth: &[f32]) -> DepthImage {
    DepthImage::from_vec(k.width, k.height, depth.to_vec()).unwrap()
}

/// Checks `inner ⊆ got ⊆ outer`, naming the offending blocks.
fn assert_band(got: &BTreeSet<[i32; 3]>, inner: &BTreeSet<[i32; 3]>, outer: &BTreeSet<[i32; 3]>) {
    let missed: Vec<_> = inner.difference(got).take(5).collect();
    assert!(missed.is_empty(), "band blocks not found: {missed:?}");
    let extra: Vec<_> = got.difference(outer).take(5).collect();
    assert!(extra.is_empty(), "blocks outside the band: {extra:?}");
}

#[test]
fn integrate_allocates_exactly_the_band_of_the_valid_pixels() {
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let k = small_camera();
    let (w, h) = (k.width, k.height);
    // Voxel sizes from blocks longer than the band (one or two blocks per segment) to much
    // shorter ones (long segments, the DDA path); depth ranges that cut off both ends of the
    // frame's depths, and a zero minimum where segments start at the camera centre.
    let cases = [
        (0.004, 0.02, 0.1, 3.0),
        (0.01, 0.03, 0.0, 2.0),
        (0.002, 0.012, 0.5, 1.5),
        (0.02, 0.08, 0.1, 4.0),
        (0.001, 0.03, 0.3, 2.5),
    ];
    for (case, &(voxel_m, trunc_m, min_depth_m, max_depth_m)) in cases.iter().enumerate() {
        let p = TsdfConfig {
            voxel_m,
            trunc_m,
            min_depth_m,
            max_depth_m,
            ..TsdfConfig::default()
        };
        let pose = random_pose(&mut rng, 1.5, 3.0);
        let depth = patch_frame(&mut rng, w, h, (0.02, 5.0));
        let mut vol = TsdfVolume::new(p).unwrap();
        let stats = vol
            .integrate(&image(&k, &depth), &k, &CameraToWorld::from_isometry(pose))
            .unwrap();
        let got: BTreeSet<[i32; 3]> = vol.block_coords().collect();
        let (inner, outer) = reference_bands(&p, &k, &pose, &depth);
        assert!(inner.len() > 100, "case {case}: {}", inner.len());
        assert_band(&got, &inner, &outer);
        assert_eq!(got.len(), vol.block_count(), "case {case}: duplicate keys");
        assert_eq!(stats.blocks_allocated, got.len());
        assert_eq!(stats.blocks_touched, got.len());
        let used = depth.iter().filter(|&&d| valid_depth(&p, d)).count();
        assert_eq!(stats.pixels_used, used, "case {case}");
        // The depth range matters here: the pixels outside it would add blocks.
        let all = TsdfConfig {
            min_depth_m: 0.0,
            max_depth_m: 100.0,
            ..p
        };
        let uncut = reference_band(&all, &k, &pose, &depth, -EPS_BLOCKS);
        assert!(
            uncut.difference(&outer).count() > 10,
            "case {case}: the depth range cuts nothing"
        );

        // A second frame from a nearby pose with only the border pixels of the first frame
        // valid: the blocks it touches are the existing ones in its band plus the new ones.
        let pose2 = pose * random_pose(&mut rng, 0.5 * voxel_m, 0.002);
        let mut depth2 = depth.clone();
        border_only(&mut depth2, w, h);
        let stats2 = vol
            .integrate(
                &image(&k, &depth2),
                &k,
                &CameraToWorld::from_isometry(pose2),
            )
            .unwrap();
        let got2: BTreeSet<[i32; 3]> = vol.block_coords().collect();
        let (inner2, outer2) = reference_bands(&p, &k, &pose2, &depth2);
        assert!(inner2.len() > 20, "case {case}: {}", inner2.len());
        let new: BTreeSet<[i32; 3]> = got2.difference(&got).copied().collect();
        assert_eq!(stats2.blocks_allocated, new.len(), "case {case}");
        assert!(got.is_subset(&got2));
        assert_band(
            &new,
            &inner2.difference(&got).copied().collect(),
            &outer2.difference(&got).copied().collect(),
        );
        assert!(
            (inner2.len()..=outer2.len()).contains(&stats2.blocks_touched),
            "case {case}: touched {} not in {}..={}",
            stats2.blocks_touched,
            inner2.len(),
            outer2.len()
        );
        assert!(
            stats2.blocks_touched > stats2.blocks_allocated,
            "case {case}: the second frame should touch existing blocks"
        );
    }
}

/// The weight of an observation at depth `d`, straight from the definitions (normalised at
/// `z_ref`).
fn reference_weight(p: &TsdfConfig, d: f64) -> f64 {
    match p.weight {
        WeightMode::Uniform => 1.0,
        WeightMode::InvZ2 => (p.z_ref_m / d).powi(2),
        WeightMode::InvZ4 => (p.z_ref_m / d).powi(4),
        WeightMode::SensorVariance { sensor, floor_m } => {
            let var = |z: f64| sensor.sigma_z(z).powi(2) + floor_m * floor_m;
            var(p.z_ref_m) / var(d)
        }
    }
}

/// A dense f64 TSDF updated voxel by voxel; voxels whose fast-path result may legitimately
/// differ (f32 rounding at a decision boundary) are marked ambiguous and not compared.
#[derive(Default)]
struct ReferenceVolume {
    voxels: HashMap<[i64; 3], (f64, f64)>,
    ambiguous: HashSet<[i64; 3]>,
}

impl ReferenceVolume {
    /// Integrates a frame into the blocks of its band: the blocks of `inner` are updated,
    /// those of `outer` but not `inner` may or may not be (their voxels become ambiguous).
    fn integrate(
        &mut self,
        p: &TsdfConfig,
        k: &Intrinsics,
        pose: &Isometry3<f64>,
        depth: &[f32],
        (inner, outer): &(BTreeSet<[i32; 3]>, BTreeSet<[i32; 3]>),
    ) {
        let inv = pose.inverse();
        let s = BLOCK_SIDE as i64;
        for b in outer {
            for l in 0..BLOCK_VOXELS as i64 {
                let g = [
                    i64::from(b[0]) * s + l % s,
                    i64::from(b[1]) * s + (l / s) % s,
                    i64::from(b[2]) * s + l / (s * s),
                ];
                if inner.contains(b) {
                    self.update(p, k, &inv, depth, g);
                } else {
                    self.ambiguous.insert(g);
                }
            }
        }
    }

    fn update(
        &mut self,
        p: &TsdfConfig,
        k: &Intrinsics,
        inv: &Isometry3<f64>,
        depth: &[f32],
        g: [i64; 3],
    ) {
        let pw = Point3::new(g[0] as f64, g[1] as f64, g[2] as f64) * p.voxel_m;
        let pc = inv * pw;
        if pc.z <= 0.0 {
            return;
        }
        let u = k.fx * pc.x / pc.z + k.cx;
        let v = k.fy * pc.y / pc.z + k.cy;
        let near_half = |c: f64| ((c - c.floor()) - 0.5).abs() < EPS_PX;
        let inside = |c: f64, n: usize| c > -1.0 && c < n as f64;
        if inside(u, k.width) && inside(v, k.height) && (near_half(u) || near_half(v)) {
            self.ambiguous.insert(g);
            return;
        }
        let (px, py) = (u.round(), v.round());
        if px < 0.0 || py < 0.0 || px >= k.width as f64 || py >= k.height as f64 {
            return;
        }
        let d = depth[py as usize * k.width + px as usize];
        if !valid_depth(p, d) {
            return;
        }
        // The weight is the nearest pixel's; the depth may be interpolated.
        let w = reference_weight(p, f64::from(d));
        let mut d = f64::from(d);
        if p.depth_lookup == DepthLookup::Bilinear {
            // The four pixels around (u, v); outside the image they are invalid.
            let near_int = |c: f64| (c - c.round()).abs() < EPS_PX;
            if near_int(u) || near_int(v) {
                self.ambiguous.insert(g);
                return;
            }
            let (u0, v0) = (u.floor(), v.floor());
            let at = |x: f64, y: f64| -> f64 {
                if x < 0.0 || y < 0.0 || x >= k.width as f64 || y >= k.height as f64 {
                    return 0.0;
                }
                let z = depth[y as usize * k.width + x as usize];
                if valid_depth(p, z) { f64::from(z) } else { 0.0 }
            };
            let c = [
                at(u0, v0),
                at(u0 + 1.0, v0),
                at(u0, v0 + 1.0),
                at(u0 + 1.0, v0 + 1.0),
            ];
            let lo = c.iter().copied().fold(f64::INFINITY, f64::min);
            let hi = c.iter().copied().fold(0.0, f64::max);
            if lo > 0.0 {
                let slope = std::f64::consts::SQRT_2
                    * SAME_SURFACE_MAX_INCIDENCE_DEG.to_radians().tan()
                    / k.fx.min(k.fy);
                let margin = lo * slope + p.band_at(lo) - (hi - lo);
                if margin.abs() < 1e-5 * lo {
                    self.ambiguous.insert(g);
                    return;
                }
                if margin > 0.0 {
                    let (fu, fv) = (u - u0, v - v0);
                    let inv = (1.0 - fv) * ((1.0 - fu) / c[0] + fu / c[1])
                        + fv * ((1.0 - fu) / c[2] + fu / c[3]);
                    d = 1.0 / inv;
                }
            }
        }
        let sdf = (d - pc.z) * pc.coords.norm() / pc.z;
        let band = p.band_at(d);
        if (sdf + band).abs() < EPS_SDF_M {
            self.ambiguous.insert(g);
            return;
        }
        if sdf < -band {
            return;
        }
        let f = sdf.min(band);
        let (tsdf, weight) = self.voxels.entry(g).or_insert((0.0, 0.0));
        let wn = *weight + w;
        *tsdf += (f - *tsdf) * w / wn;
        *weight = wn.min(f64::from(p.max_weight));
    }

    /// Compares every voxel of `vol` with the reference; returns (compared, observed).
    fn compare(&self, vol: &TsdfVolume, what: &str) -> (usize, usize) {
        let s = BLOCK_SIDE as i64;
        let (mut compared, mut observed, mut skipped) = (0, 0, 0);
        for b in vol.block_coords() {
            let blk = vol.block(b).unwrap();
            for l in 0..BLOCK_VOXELS {
                let li = l as i64;
                let g = [
                    i64::from(b[0]) * s + li % s,
                    i64::from(b[1]) * s + (li / s) % s,
                    i64::from(b[2]) * s + li / (s * s),
                ];
                if self.ambiguous.contains(&g) {
                    skipped += 1;
                    continue;
                }
                let (t, w) = self.voxels.get(&g).copied().unwrap_or((0.0, 0.0));
                let got = blk.voxel(l);
                assert!(
                    (f64::from(got.weight) - w).abs() <= 1e-5 * w.max(1e-3),
                    "{what}: voxel {g:?} weight {} vs reference {w}",
                    got.weight
                );
                assert!(
                    (f64::from(got.tsdf) - t).abs() <= 1e-5,
                    "{what}: voxel {g:?} F {} vs reference {t} (weight {w})",
                    got.tsdf
                );
                compared += 1;
                observed += usize::from(w > 0.0);
            }
        }
        // The ambiguous voxels stay a small minority.
        assert!(
            skipped * 10 < compared,
            "{what}: {skipped} ambiguous voxels, {compared} compared"
        );
        (compared, observed)
    }
}

/// A room-like scene (walls, floor, two spheres) rendered from `pose`, with holes and a few
/// non-finite pixels.
fn scene_frame(
    rng: &mut ChaCha8Rng,
    k: &Intrinsics,
    pose: &Isometry3<f64>,
    scene: &Scene,
) -> Vec<f32> {
    let mut depth = scene
        .render(k, &CameraToWorld::from_isometry(*pose))
        .depth
        .data()
        .to_vec();
    for d in depth.iter_mut() {
        let r: f32 = rng.random_range(0.0..1.0);
        if r < 0.04 {
            *d = 0.0;
        } else if r > 0.999 {
            *d = f32::NAN;
        }
    }
    depth
}

/// Walls and a floor `n·x = d` and two spheres, ray-cast by `sl-noise`'s simulator.
fn room() -> Scene {
    let mut scene = Scene::new();
    for (n, d) in [
        (Vector3::z(), 1.6),
        (Vector3::x(), 0.9),
        (-Vector3::y(), 0.7),
    ] {
        scene.add(Plane::from_normal_offset(n, d).unwrap());
    }
    for (c, r) in [
        (Point3::new(0.1, 0.05, 1.1), 0.2),
        (Point3::new(-0.4, -0.2, 1.3), 0.15),
    ] {
        scene.add(Sphere::new(c, r).unwrap());
    }
    scene
}

/// Fuses `frames` into a fresh volume and into the reference, comparing after each frame.
/// Returns the number of observed voxels compared after the last frame.
fn fuse_and_compare(
    p: &TsdfConfig,
    k: &Intrinsics,
    frames: &[(Vec<f32>, Isometry3<f64>)],
    what: &str,
) -> usize {
    let mut vol = TsdfVolume::new(*p).unwrap();
    let mut reference = ReferenceVolume::default();
    let mut observed = 0;
    let mut bands_union = BTreeSet::new();
    for (i, (depth, pose)) in frames.iter().enumerate() {
        vol.integrate(&image(k, depth), k, &CameraToWorld::from_isometry(*pose))
            .unwrap();
        let bands = reference_bands(p, k, pose, depth);
        // Every block allocated so far is in some frame's (grown) band.
        bands_union.extend(bands.1.iter().copied());
        assert_band(
            &vol.block_coords().collect(),
            &BTreeSet::new(),
            &bands_union,
        );
        reference.integrate(p, k, pose, depth, &bands);
        observed = reference.compare(&vol, &format!("{what}, frame {i}")).1;
    }
    observed
}

#[test]
fn integration_matches_the_scalar_reference_for_every_weight_mode() {
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let k = small_camera();
    let scene = room();
    let modes = [
        WeightMode::Uniform,
        WeightMode::InvZ2,
        WeightMode::InvZ4,
        WeightMode::sensor_variance(SensorModel::kinect_v1()),
    ];
    let lookups = [DepthLookup::Bilinear, DepthLookup::Nearest];
    for ((m, &weight), depth_lookup) in modes.iter().enumerate().zip(lookups.iter().cycle()) {
        let p = TsdfConfig {
            voxel_m: 0.02,
            trunc_m: 0.06,
            weight,
            // The cap in the uniform case turns the second observation into a moving average.
            max_weight: if m == 0 { 1.5 } else { 1e6 },
            depth_lookup: *depth_lookup,
            ..TsdfConfig::default()
        };
        let frames: Vec<(Vec<f32>, Isometry3<f64>)> = (0..2)
            .map(|_| {
                let pose = random_pose(&mut rng, 0.1, 0.3);
                (scene_frame(&mut rng, &k, &pose, &scene), pose)
            })
            .collect();
        let observed = fuse_and_compare(&p, &k, &frames, weight.name());
        assert!(observed > 20_000, "{}: {observed}", weight.name());
    }
}

#[test]
fn integration_matches_the_scalar_reference_with_the_large_pixel_table() {
    // Above about 720×720 pixels the per-pixel table no longer fits the masked small table:
    // the bounds-checked gather runs. Only the bottom-right corner (including the last row and
    // column) is valid, to keep the test small.
    let k = Intrinsics::new(740, 720, 600.0, 600.0, 369.5, 359.5).unwrap();
    assert!((k.width + 2) * (k.height + 2) > SMALL_TABLE);
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    let scene = room();
    let p = TsdfConfig {
        voxel_m: 0.01,
        trunc_m: 0.04,
        depth_lookup: DepthLookup::Bilinear,
        ..TsdfConfig::default()
    };
    let frames: Vec<(Vec<f32>, Isometry3<f64>)> = (0..2)
        .map(|_| {
            let pose = random_pose(&mut rng, 0.05, 0.1);
            let mut depth = scene_frame(&mut rng, &k, &pose, &scene);
            for (i, d) in depth.iter_mut().enumerate() {
                if i % k.width < 600 || i / k.width < 580 {
                    *d = 0.0;
                }
            }
            (depth, pose)
        })
        .collect();
    let observed = fuse_and_compare(&p, &k, &frames, "large table");
    assert!(observed > 10_000, "{observed}");
}

#[test]
fn integration_matches_the_scalar_reference_next_to_the_camera() {
    // Surfaces a few centimetres in front of the camera with a zero minimum depth: band blocks
    // contain the camera centre, so some have voxels behind the camera (the per-voxel z test)
    // and others do not.
    let k = small_camera();
    let mut rng = ChaCha8Rng::seed_from_u64(13);
    let p = TsdfConfig {
        voxel_m: 0.005,
        trunc_m: 0.04,
        min_depth_m: 0.0,
        weight: WeightMode::InvZ2,
        depth_lookup: DepthLookup::Bilinear,
        ..TsdfConfig::default()
    };
    let frames: Vec<(Vec<f32>, Isometry3<f64>)> = (0..2)
        .map(|_| {
            let pose = random_pose(&mut rng, 0.02, 0.2);
            (patch_frame(&mut rng, k.width, k.height, (0.02, 0.3)), pose)
        })
        .collect();
    let observed = fuse_and_compare(&p, &k, &frames, "near camera");
    assert!(observed > 5_000, "{observed}");
    // Both kinds of blocks occurred in the last frame's band.
    let (depth, pose) = &frames[1];
    let inv = pose.inverse();
    let bs = p.voxel_m * BLOCK_SIDE as f64;
    let (mut behind, mut front) = (0, 0);
    for b in reference_band(&p, &k, pose, depth, -EPS_BLOCKS) {
        let z_min = (0..8)
            .map(|c| {
                let corner = Point3::new(
                    (f64::from(b[0]) + f64::from(c & 1) * 7.0 / 8.0) * bs,
                    (f64::from(b[1]) + f64::from((c >> 1) & 1) * 7.0 / 8.0) * bs,
                    (f64::from(b[2]) + f64::from((c >> 2) & 1) * 7.0 / 8.0) * bs,
                );
                (inv * corner).z
            })
            .fold(f64::INFINITY, f64::min);
        if z_min <= 0.0 {
            behind += 1;
        } else {
            front += 1;
        }
    }
    assert!(behind > 0 && front > 0, "behind {behind}, in front {front}");
}

/// Voxel data and bookkeeping of a volume, for checking that it did not change.
fn snapshot(vol: &TsdfVolume) -> (usize, usize, usize, Vec<[i32; 3]>, Vec<u32>) {
    let bits = vol
        .blocks()
        .iter()
        .flat_map(|b| b.tsdf.iter().chain(b.weight.iter()).map(|x| x.to_bits()))
        .collect();
    (
        vol.block_count(),
        vol.frame_count(),
        vol.memory_bytes(),
        vol.block_coords().collect(),
        bits,
    )
}

#[test]
fn budget_refuses_one_block_too_many_and_the_volume_stays_usable() {
    let k = small_camera();
    let scene = room();
    let mut rng = ChaCha8Rng::seed_from_u64(17);
    let p = TsdfConfig {
        voxel_m: 0.008,
        trunc_m: 0.03,
        ..TsdfConfig::default()
    };
    let pose_a = Isometry3::identity();
    let pose_b = Isometry3::new(Vector3::new(0.3, 0.0, 0.0), Vector3::new(0.0, 0.3, 0.0));
    let a = image(&k, &scene_frame(&mut rng, &k, &pose_a, &scene));
    let b = image(&k, &scene_frame(&mut rng, &k, &pose_b, &scene));
    let mut free = TsdfVolume::new(p).unwrap();
    free.integrate(&a, &k, &CameraToWorld::from_isometry(pose_a))
        .unwrap();
    let n_a = free.block_count();
    free.integrate(&b, &k, &CameraToWorld::from_isometry(pose_b))
        .unwrap();
    let n = free.block_count();
    assert!(n > n_a + 10, "{n_a} -> {n}");

    // A budget of exactly n blocks takes both frames, and the memory held stays within it.
    let exact = TsdfConfig {
        memory_budget_bytes: n * BYTES_PER_BLOCK,
        ..p
    };
    let mut vol = TsdfVolume::new(exact).unwrap();
    vol.integrate(&a, &k, &CameraToWorld::from_isometry(pose_a))
        .unwrap();
    vol.integrate(&b, &k, &CameraToWorld::from_isometry(pose_b))
        .unwrap();
    assert_eq!(vol.block_count(), n);
    assert!(vol.memory_bytes() <= exact.memory_budget_bytes);

    // One block less: the second frame (n blocks) is refused with the sizes in the error.
    let budget = (n - 1) * BYTES_PER_BLOCK;
    let tight = TsdfConfig {
        memory_budget_bytes: budget,
        ..p
    };
    let mut vol = TsdfVolume::new(tight).unwrap();
    vol.integrate(&a, &k, &CameraToWorld::from_isometry(pose_a))
        .unwrap();
    let before = snapshot(&vol);
    let err = vol
        .integrate(&b, &k, &CameraToWorld::from_isometry(pose_b))
        .unwrap_err();
    match err {
        TsdfError::MemoryBudget {
            blocks,
            needed_bytes,
            budget_bytes,
        } => {
            assert_eq!(blocks, n);
            assert_eq!(needed_bytes, n * BYTES_PER_BLOCK);
            assert_eq!(budget_bytes, budget);
        }
        ref other => panic!("expected a budget error, got {other:?}"),
    }
    let msg = err.to_string();
    for number in [n, n * BYTES_PER_BLOCK, budget] {
        assert!(msg.contains(&number.to_string()), "{msg}");
    }
    // Nothing changed: blocks, voxels, frame count, memory.
    assert!(before == snapshot(&vol));
    assert!(vol.memory_bytes() <= budget);

    // Still usable: a frame within the budget integrates, and the result is that of a volume
    // that never saw the refused frame.
    let pose_c = Isometry3::new(Vector3::new(0.01, 0.0, 0.0), Vector3::zeros());
    let c = image(&k, &scene_frame(&mut rng, &k, &pose_c, &scene));
    let stats = vol
        .integrate(&c, &k, &CameraToWorld::from_isometry(pose_c))
        .unwrap();
    let mut fresh = TsdfVolume::new(p).unwrap();
    fresh
        .integrate(&a, &k, &CameraToWorld::from_isometry(pose_a))
        .unwrap();
    assert_eq!(
        fresh
            .integrate(&c, &k, &CameraToWorld::from_isometry(pose_c))
            .unwrap(),
        stats
    );
    assert!(vol.block_count() < n);
    assert_eq!(vol.frame_count(), 2);
    assert!(snapshot(&vol).3 == snapshot(&fresh).3);
    assert!(snapshot(&vol).4 == snapshot(&fresh).4);
    assert!(vol.memory_bytes() <= budget);
    let min_bytes = vol.block_count() * (std::mem::size_of::<Block>() + 8 + 17);
    assert!(vol.memory_bytes() >= min_bytes);
}

#[test]
fn memory_bytes_stays_within_an_exactly_fitting_budget() {
    // Volumes of exactly n blocks under a budget of n blocks, built by `from_field` and by
    // integration: the capacities (blocks, keys, hash index) stay within the budget; one byte
    // less is refused.
    let p = TsdfConfig {
        voxel_m: 0.01,
        trunc_m: 0.03,
        ..TsdfConfig::default()
    };
    let bs = p.voxel_m * BLOCK_SIDE as f64;
    for n in 1..=70usize {
        let hi = [0.5 * bs, 0.5 * bs, (n as f64 - 0.5) * bs];
        let budget = n * BYTES_PER_BLOCK;
        let fits = TsdfConfig {
            memory_budget_bytes: budget,
            ..p
        };
        let vol = TsdfVolume::from_field(fits, [0.0; 3], hi, |_| None).unwrap();
        assert_eq!(vol.block_count(), n);
        assert!(
            vol.memory_bytes() <= budget,
            "{n} blocks: {} > {budget}",
            vol.memory_bytes()
        );
        let short = TsdfConfig {
            memory_budget_bytes: budget - 1,
            ..p
        };
        assert!(matches!(
            TsdfVolume::from_field(short, [0.0; 3], hi, |_| None),
            Err(TsdfError::MemoryBudget { blocks, .. }) if blocks == n
        ));
    }
    // Integration, frame by frame, under a budget that the last frame fills exactly.
    let k = small_camera();
    let scene = room();
    let poses: Vec<Isometry3<f64>> = (0..8)
        .map(|i| Isometry3::new(Vector3::new(0.03 * i as f64, 0.0, 0.0), Vector3::zeros()))
        .collect();
    let frames: Vec<DepthImage> = poses
        .iter()
        .map(|q| scene.render(&k, &CameraToWorld::from_isometry(*q)).depth)
        .collect();
    let mut free = TsdfVolume::new(p).unwrap();
    for (d, q) in frames.iter().zip(&poses) {
        free.integrate(d, &k, &CameraToWorld::from_isometry(*q))
            .unwrap();
    }
    let budget = free.block_count() * BYTES_PER_BLOCK;
    let mut vol = TsdfVolume::new(TsdfConfig {
        memory_budget_bytes: budget,
        ..p
    })
    .unwrap();
    for (d, q) in frames.iter().zip(&poses) {
        vol.integrate(d, &k, &CameraToWorld::from_isometry(*q))
            .unwrap();
        assert!(
            vol.memory_bytes() <= budget,
            "{} > {budget}",
            vol.memory_bytes()
        );
    }
    assert_eq!(vol.block_count(), free.block_count());
}

#[test]
fn non_finite_pose_is_refused() {
    let k = small_camera();
    let depth = DepthImage::from_vec(k.width, k.height, vec![1.0; k.pixel_count()]).unwrap();
    let mut vol = TsdfVolume::new(TsdfConfig::default()).unwrap();
    for pose in [
        Isometry3::new(Vector3::new(f64::NAN, 0.0, 0.0), Vector3::zeros()),
        Isometry3::new(Vector3::zeros(), Vector3::new(f64::NAN, 0.0, 0.0)),
    ] {
        assert!(matches!(
            vol.integrate(&depth, &k, &CameraToWorld::from_isometry(pose)),
            Err(TsdfError::OutOfRange(_))
        ));
    }
    assert_eq!(vol.block_count(), 0);
    assert_eq!(vol.frame_count(), 0);
}
