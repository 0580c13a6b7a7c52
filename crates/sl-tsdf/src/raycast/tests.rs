//! Raycast tests: analytic TSDFs of a plane and a sphere (depth and normal errors against the
//! exact intersections), a scene fused from simulated frames, blocks straddling the near plane,
//! buffer reuse, thread-count independence, rays marched together against one at a time, and
//! argument checks.

use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use proptest::prelude::*;
use sl_core::{Camera, CameraToWorld, DepthImage, Intrinsics};

use super::*;
use crate::TsdfConfig;

fn small_camera() -> Intrinsics {
    Camera::kinect_v1().intrinsics.scaled(0.25).unwrap() // 160x120, f = 145
}

fn config(voxel_m: f64, trunc_m: f64) -> TsdfConfig {
    TsdfConfig {
        voxel_m,
        trunc_m,
        ..TsdfConfig::default()
    }
}

/// The exact ray parameter (camera depth) of pixel `(x, y)` hitting a surface, and errors.
struct Errors {
    hits: usize,
    expected: usize,
    max_depth_err_m: f64,
    rms_depth_err_m: f64,
    max_normal_err_deg: f64,
    mean_normal_err_deg: f64,
}

/// Compares a raycast with exact intersections: `exact(origin, dir)` gives the camera depth
/// of the hit and the world unit normal there (None: no hit, or too grazing to judge).
fn compare(
    r: &Raycast,
    k: &Intrinsics,
    pose: &CameraToWorld,
    exact: impl Fn(&Point3<f64>, &Vector3<f64>) -> Option<(f64, Vector3<f64>)>,
) -> Errors {
    let c = pose.centre();
    let mut e = Errors {
        hits: 0,
        expected: 0,
        max_depth_err_m: 0.0,
        rms_depth_err_m: 0.0,
        max_normal_err_deg: 0.0,
        mean_normal_err_deg: 0.0,
    };
    for y in 0..k.height {
        for x in 0..k.width {
            let dir = pose.transform_vector(&k.ray(x as f64, y as f64));
            let Some((z, n)) = exact(&c, &dir) else {
                continue;
            };
            e.expected += 1;
            let i = y * k.width + x;
            let got = f64::from(r.depth.data()[i]);
            if got <= 0.0 {
                continue;
            }
            e.hits += 1;
            let dz = (got - z).abs();
            e.max_depth_err_m = e.max_depth_err_m.max(dz);
            e.rms_depth_err_m += dz * dz;
            let p = r.points[i].cast::<f64>();
            let expect_p = c + dir * z;
            assert!((p - expect_p).norm() < 1e-2, "point {p:?} vs {expect_p:?}");
            let got_n = r.normals[i].cast::<f64>();
            assert!((got_n.norm() - 1.0).abs() < 1e-4);
            let ang = got_n.dot(&n).clamp(-1.0, 1.0).acos().to_degrees();
            e.max_normal_err_deg = e.max_normal_err_deg.max(ang);
            e.mean_normal_err_deg += ang;
            assert!(r.weights[i] > 0.0);
        }
    }
    if e.hits > 0 {
        e.rms_depth_err_m = (e.rms_depth_err_m / e.hits as f64).sqrt();
        e.mean_normal_err_deg /= e.hits as f64;
    }
    e
}

fn tilted_pose() -> CameraToWorld {
    CameraToWorld::from_isometry(Isometry3::from_parts(
        Translation3::new(0.05, -0.03, 0.02),
        UnitQuaternion::from_euler_angles(0.08, -0.12, 0.05),
    ))
}

#[test]
fn plane_field_depth_and_normals_are_exact_to_a_small_fraction_of_a_voxel() {
    let (v, trunc) = (0.01, 0.04);
    let n = Vector3::new(0.3, 0.2, -1.0).normalize(); // faces the camera at the origin
    let p0 = Point3::new(0.0, 0.0, 1.2);
    let vol = TsdfVolume::from_field(config(v, trunc), [-1.0, -1.0, 0.2], [1.0, 1.0, 2.0], |p| {
        let sd = n.dot(&(p - p0));
        (sd >= -trunc).then_some(sd.min(trunc) as f32)
    })
    .unwrap();
    let k = small_camera();
    let pose = tilted_pose();
    let r = vol.raycast(&pose, &k, &RaycastConfig::default()).unwrap();
    let e = compare(&r, &k, &pose, |c, dir| {
        let t = n.dot(&(p0 - c)) / n.dot(dir);
        let hit = c + dir * t;
        // Only where the whole band around the hit is inside the field's box.
        let inside = hit.x.abs() < 0.9 && hit.y.abs() < 0.9 && hit.z > 0.3 && hit.z < 1.9;
        (t > 0.0 && inside).then_some((t, n))
    });
    eprintln!(
        "plane: {}/{} hits, depth error max {:.2e} m rms {:.2e} m, normal error max {:.4}°",
        e.hits, e.expected, e.max_depth_err_m, e.rms_depth_err_m, e.max_normal_err_deg
    );
    assert_eq!(e.hits, e.expected);
    assert!(e.expected > k.pixel_count() * 9 / 10);
    // The trilinear interpolant of an affine field is exact: only f32 rounding remains.
    assert!(e.max_depth_err_m < 0.01 * v, "{}", e.max_depth_err_m);
    assert!(e.max_normal_err_deg < 0.1, "{}", e.max_normal_err_deg);
}

#[test]
fn sphere_field_depth_and_normals_are_accurate() {
    let (v, trunc) = (0.01, 0.04);
    let (c0, rad) = (Point3::new(0.05, -0.02, 1.3), 0.35);
    let vol = TsdfVolume::from_field(config(v, trunc), [-0.5, -0.5, 0.8], [0.5, 0.5, 1.8], |p| {
        let sd = (p - c0).norm() - rad;
        (sd >= -trunc).then_some(sd.min(trunc) as f32)
    })
    .unwrap();
    let k = small_camera();
    let pose = tilted_pose();
    let r = vol.raycast(&pose, &k, &RaycastConfig::default()).unwrap();
    let e = compare(&r, &k, &pose, |c, dir| {
        // Ray-sphere: |c + dir·t − c0|² = r².
        let oc = c - c0;
        let (a, b, cc) = (dir.dot(dir), 2.0 * dir.dot(&oc), oc.dot(&oc) - rad * rad);
        let disc = b * b - 4.0 * a * cc;
        if disc <= 0.0 {
            return None;
        }
        let t = (-b - disc.sqrt()) / (2.0 * a);
        let nrm = (c + dir * t - c0) / rad;
        // Judge only where the ray meets the sphere at least 30° from grazing.
        (-nrm.dot(&dir.normalize()) > 0.5).then_some((t, nrm))
    });
    eprintln!(
        "sphere: {}/{} hits, depth error max {:.2e} m rms {:.2e} m, normal error max {:.3}° mean {:.3}°",
        e.hits,
        e.expected,
        e.max_depth_err_m,
        e.rms_depth_err_m,
        e.max_normal_err_deg,
        e.mean_normal_err_deg
    );
    assert_eq!(e.hits, e.expected);
    assert!(e.expected > 1000);
    assert!(e.max_depth_err_m < 0.1 * v, "{}", e.max_depth_err_m);
    assert!(e.rms_depth_err_m < 0.03 * v, "{}", e.rms_depth_err_m);
    // The gradient of a trilinear cell is first-order accurate on a curved field: its error is
    // of the order of the angle a voxel subtends from the centre of curvature, h/(2r) rad
    // (0.82° here) on average, at most twice that.
    let bound_deg = (v / (2.0 * rad)).to_degrees();
    assert!(
        e.mean_normal_err_deg < bound_deg,
        "{}",
        e.mean_normal_err_deg
    );
    assert!(
        e.max_normal_err_deg < 2.0 * bound_deg,
        "{}",
        e.max_normal_err_deg
    );
}

#[test]
fn only_front_faces_are_hit_and_empty_space_gives_nothing() {
    let (v, trunc) = (0.01, 0.04);
    // A wall at z = 1 whose positive side faces away from the camera (+z): seen from the
    // origin the ray meets − then +, a back face.
    let vol = TsdfVolume::from_field(config(v, trunc), [-1.0, -1.0, 0.8], [1.0, 1.0, 1.2], |p| {
        let sd = p.z - 1.0;
        (sd >= -trunc).then_some(sd.min(trunc) as f32)
    })
    .unwrap();
    let k = small_camera();
    let r = vol
        .raycast(&CameraToWorld::identity(), &k, &RaycastConfig::default())
        .unwrap();
    assert_eq!(r.hit_count(), 0);
    assert!(r.depth.data().iter().all(|&d| d == 0.0));
    assert!(r.points.iter().all(|p| p.x.is_nan()));
    // An empty volume: no hits.
    let empty = TsdfVolume::new(config(v, trunc)).unwrap();
    let r = empty
        .raycast(&CameraToWorld::identity(), &k, &RaycastConfig::default())
        .unwrap();
    assert_eq!((r.width, r.height, r.hit_count()), (k.width, k.height, 0));
}

/// A room with a sphere, fused from exact simulated frames.
fn fused_room(k: &Intrinsics, v: f64, trunc: f64) -> (TsdfVolume, sl_noise::sim::Scene) {
    use sl_noise::sim::{Plane, Scene, Sphere};
    let mut scene = Scene::new();
    for (n, d) in [
        (Vector3::x(), 1.5),
        (-Vector3::x(), 1.5),
        (Vector3::z(), 2.5),
        (Vector3::y(), 1.0),
        (-Vector3::y(), 1.2),
    ] {
        scene.add(Plane::from_normal_offset(n, d).unwrap());
    }
    scene.add(Sphere::new(Point3::new(0.2, 0.3, 1.6), 0.3).unwrap());
    let mut vol = TsdfVolume::new(config(v, trunc)).unwrap();
    for i in 0..5 {
        let pose = Isometry3::new(
            Vector3::new(-0.2 + 0.1 * i as f64, 0.0, 0.0),
            Vector3::new(0.0, 0.06 * i as f64 - 0.12, 0.0),
        );
        let depth = scene.render(k, &CameraToWorld::from_isometry(pose)).depth;
        vol.integrate(&depth, k, &CameraToWorld::from_isometry(pose))
            .unwrap();
    }
    (vol, scene)
}

#[test]
fn fused_scene_raycast_matches_the_exact_depth_from_a_new_pose() {
    let k = small_camera();
    let v = 0.01;
    let (vol, scene) = fused_room(&k, v, 0.04);
    // A pose between the fused ones.
    let iso = Isometry3::new(Vector3::new(0.05, 0.02, 0.0), Vector3::new(0.01, 0.03, 0.0));
    let pose = CameraToWorld::from_isometry(iso);
    let r = vol.raycast(&pose, &k, &RaycastConfig::default()).unwrap();
    let truth = scene.render(&k, &pose).depth;
    let mut errs = Vec::new();
    let mut valid = 0;
    for (&t, &d) in truth.data().iter().zip(r.depth.data()) {
        if t > 0.0 && t < 4.0 {
            valid += 1;
            if d > 0.0 {
                errs.push((f64::from(d) - f64::from(t)).abs());
            }
        }
    }
    errs.sort_by(f64::total_cmp);
    let med = errs[errs.len() / 2];
    let p95 = errs[errs.len() * 95 / 100];
    eprintln!(
        "fused room: {}/{valid} hits, |depth error| median {med:.2e} m, p95 {p95:.2e} m",
        errs.len()
    );
    assert!(errs.len() * 100 >= valid * 97, "{} of {valid}", errs.len());
    assert!(med < 0.1 * v, "{med}");
    assert!(p95 < 0.5 * v, "{p95}");
    // Normals face the camera (but in the room's corners and at the sphere's silhouette,
    // where the fused fields of two surfaces meet).
    let c = pose.centre().coords.cast::<f32>();
    let away = r
        .points
        .iter()
        .zip(&r.normals)
        .filter(|(p, n)| p.x.is_finite() && n.dot(&(c - p.coords)) <= 0.0)
        .count();
    eprintln!("fused room: {away} normals facing away");
    assert!(away * 1000 < r.hit_count(), "{away}");
}

/// The raycast normals of a wall seen at a grazing angle (70–80° from the line of sight over
/// most of the image), fused from one exact frame, with both depth lookups: (mean error, mean
/// lean towards the camera beyond the true normal's), degrees.
fn grazing_wall_normals(lookup: crate::DepthLookup) -> (f64, f64) {
    use sl_noise::sim::{Plane, Scene};
    let k = Camera::kinect_v1().intrinsics.scaled(0.5).unwrap(); // 320x240, f = 290
    // A wall 0.4 m to the side, off the voxel grid's axes, facing the camera at the origin.
    let n = Vector3::new(-1.0, 0.15, 0.05).normalize();
    let mut scene = Scene::new();
    scene.add(Plane::from_normal_offset(n, -0.4).unwrap());
    let pose = CameraToWorld::from_isometry(Isometry3::identity());
    let depth = scene.render(&k, &pose).depth;
    let mut cfg = config(0.004, 0.02);
    cfg.depth_lookup = lookup;
    let mut vol = TsdfVolume::new(cfg).unwrap();
    vol.integrate(&depth, &k, &pose).unwrap();
    let r = vol.raycast(&pose, &k, &RaycastConfig::default()).unwrap();
    let (mut sum, mut lean, mut count) = (0.0, 0.0, 0);
    for (i, (p, got)) in r.points.iter().zip(&r.normals).enumerate() {
        // Away from the wall's far edge (the depth range) and the image border.
        let (x, y) = (i % k.width, i / k.width);
        if !p.x.is_finite() || p.z > 3.0 || x < 4 || y < 4 || x + 4 >= k.width || y + 4 >= k.height
        {
            continue;
        }
        let got = got.cast::<f64>();
        sum += got.dot(&n).clamp(-1.0, 1.0).acos().to_degrees();
        lean += ((-got.z).asin() - (-n.z).asin()).to_degrees();
        count += 1;
    }
    assert!(count > 5_000, "{count}");
    (sum / f64::from(count), lean / f64::from(count))
}

#[test]
fn a_grazing_wall_fused_with_bilinear_depth_keeps_its_normals() {
    // With the nearest pixel every voxel within one pixel's footprint reads one depth: the
    // wall is fused as steps one pixel wide and its normals lean towards the camera.
    let (near_err, near_lean) = grazing_wall_normals(crate::DepthLookup::Nearest);
    let (bil_err, bil_lean) = grazing_wall_normals(crate::DepthLookup::Bilinear);
    eprintln!(
        "grazing wall normals: nearest {near_err:.2}° (lean {near_lean:.2}°), bilinear {bil_err:.3}° (lean {bil_lean:.3}°)"
    );
    assert!(near_lean > 1.0, "{near_lean}");
    assert!(
        bil_err < 0.5 && bil_lean.abs() < 0.1,
        "{bil_err} {bil_lean}"
    );
}

/// A hint at the surface (the depth the fused frames saw), half a band behind it (a noisy
/// frame) or far in front of it: the hinted raycast finds the same surfaces as the plain one,
/// to a small fraction of a voxel, but for a few pixels in 1,000 at silhouettes, where the
/// hinted ray mostly finds the surface nearer the truth.
#[test]
fn a_hinted_raycast_finds_the_same_surface() {
    let k = small_camera();
    let v = 0.01;
    let (vol, scene) = fused_room(&k, v, 0.04);
    let pose = CameraToWorld::from_isometry(Isometry3::new(
        Vector3::new(0.0, 0.0, 0.0),
        Vector3::new(0.0, 0.0, 0.0),
    ));
    let plain = vol.raycast(&pose, &k, &RaycastConfig::default()).unwrap();
    let truth = scene.render(&k, &pose).depth;
    for offset_m in [0.0f32, 0.02, -0.5] {
        let mut hint = truth.clone();
        for z in hint.data_mut() {
            if *z > 0.0 {
                *z = (*z + offset_m).max(0.05);
            }
        }
        let mut hinted = Raycast::default();
        vol.raycast_hinted_into(
            &pose,
            &k,
            &RaycastConfig::default(),
            Some(&hint),
            &mut hinted,
        )
        .unwrap();
        // Pixels where one raycast hits and the other does not, and where both hit but
        // different surfaces; for those, which one is nearer to the exact depth.
        let (mut both, mut one, mut moved, mut plain_nearer) = (0usize, 0usize, 0usize, 0usize);
        let mut same = Vec::new();
        for ((a, b), t) in plain
            .depth
            .data()
            .iter()
            .zip(hinted.depth.data())
            .zip(truth.data())
        {
            match (*a > 0.0, *b > 0.0) {
                (true, true) => {
                    both += 1;
                    let d = (a - b).abs();
                    if d < v as f32 {
                        same.push(d);
                    } else {
                        moved += 1;
                        plain_nearer += usize::from((a - t).abs() < (b - t).abs());
                    }
                }
                (false, false) => {}
                _ => one += 1,
            }
        }
        same.sort_by(f32::total_cmp);
        let p99 = same[same.len() * 99 / 100];
        let over = same.iter().filter(|d| **d > 0.1 * v as f32).count();
        eprintln!(
            "hint offset {offset_m} m: {both} hits in both, {moved} on another surface \
             (plain nearer the truth: {plain_nearer}), {one} in one only, same surface: p99 \
             {p99:.2e} m, {over} over a tenth of a voxel"
        );
        assert!(
            (one + moved) * 500 <= plain.hit_count(),
            "{one} + {moved} of {}",
            plain.hit_count()
        );
        assert!(p99 < 0.1 * v as f32, "{p99}");
    }
    let wrong = DepthImage::invalid(k.width + 1, k.height);
    let mut out = Raycast::default();
    assert!(
        vol.raycast_hinted_into(&pose, &k, &RaycastConfig::default(), Some(&wrong), &mut out)
            .is_err()
    );
}

/// A wall 1 m in front of the identity camera, fused from that camera.
fn wall_volume(k: &Intrinsics, v: f64) -> TsdfVolume {
    let mut vol = TsdfVolume::new(config(v, 4.0 * v)).unwrap();
    let wall =
        sl_core::DepthImage::from_vec(k.width, k.height, vec![1.0; k.pixel_count()]).unwrap();
    vol.integrate(&wall, k, &CameraToWorld::identity()).unwrap();
    vol
}

#[test]
fn a_block_straddling_the_near_plane_beside_the_view_does_not_widen_the_rays() {
    // A small patch 0.1 m in front of the camera's plane but 0.2 m to its side (seen by
    // another camera): its blocks straddle the near plane z = 0.1 m and project outside the
    // image. They must not make every ray march from the near plane (the cost that made
    // raycasts of real recordings 3-4x slower), nor change the rendering.
    let k = small_camera();
    let v = 0.01;
    let wall_only = wall_volume(&k, v);
    let mut vol = TsdfVolume::new(config(v, 4.0 * v)).unwrap();
    let mut patch = sl_core::DepthImage::invalid(k.width, k.height);
    let (cx, cy) = (k.cx as usize, k.cy as usize);
    for y in cy - 5..cy + 5 {
        for x in cx - 5..cx + 5 {
            patch.data_mut()[y * k.width + x] = 0.6;
        }
    }
    let side = CameraToWorld::from_isometry(Isometry3::translation(0.2, 0.0, -0.5));
    vol.integrate(&patch, &k, &side).unwrap();
    let wall =
        sl_core::DepthImage::from_vec(k.width, k.height, vec![1.0; k.pixel_count()]).unwrap();
    vol.integrate(&wall, &k, &CameraToWorld::identity())
        .unwrap();
    let block_m = crate::volume::BLOCK_SIDE as f64 * v;
    let straddling = vol
        .block_coords()
        .filter(|b| {
            let (z0, z1) = (f64::from(b[2]) * block_m, f64::from(b[2] + 1) * block_m);
            z0 < 0.1 && z1 > 0.1
        })
        .count();
    assert!(straddling > 0, "the patch allocated no straddling block");
    let pose = CameraToWorld::identity();
    let cfg = RaycastConfig::default();
    let frame = march::RayFrame::new(&vol, pose.isometry(), &k, &cfg).unwrap();
    let mut tiles = range::Tiles::default();
    range::tile_ranges(&vol, &frame, &k, &mut tiles).unwrap();
    for y in 0..k.height {
        for x in 0..k.width {
            let (lo, _) = range::pixel_range(&tiles, k.width, x, y);
            assert!(lo > 0.5, "pixel ({x}, {y}) marches from {lo} m");
        }
    }
    // The pieces' grids merge into the ranges of one piece, whatever their size (one block a
    // piece, uneven pieces, more pieces than blocks), reusing the same scratch.
    let ranges = |t: &range::Tiles| {
        let mut v = Vec::new();
        for y in (0..k.height).step_by(range::TILE) {
            for x in (0..k.width).step_by(range::TILE) {
                let (lo, hi) = range::pixel_range(t, k.width, x, y);
                v.push((lo.to_bits(), hi.to_bits()));
            }
        }
        v
    };
    let whole = ranges(&tiles);
    assert!(vol.block_count() > 7, "{}", vol.block_count());
    for piece_blocks in [usize::MAX, 1, 7, vol.block_count() - 1] {
        range::tile_ranges_in_pieces(&vol, &frame, &k, &mut tiles, piece_blocks).unwrap();
        assert_eq!(ranges(&tiles), whole, "pieces of {piece_blocks} blocks");
    }
    let a = vol.raycast(&pose, &k, &cfg).unwrap();
    let b = wall_only.raycast(&pose, &k, &cfg).unwrap();
    assert!(
        a.hit_count() * 10 > k.pixel_count() * 9,
        "{}",
        a.hit_count()
    );
    assert_eq!(a.depth.data(), b.depth.data());
}

proptest! {
    /// Every point of a block in front of the near plane projects inside the block's clipped
    /// bounds, for blocks in any orientation straddling the plane or not.
    #[test]
    fn clipped_bounds_contain_every_visible_point_of_the_block(
        angles in prop::array::uniform3(-3.2f64..3.2),
        centre in prop::array::uniform3(-0.3f64..0.3),
        side in 0.01f64..0.2,
        samples in prop::collection::vec(prop::array::uniform3(0.0f64..1.0), 32),
    ) {
        let min_z = 0.1f32;
        let rot = UnitQuaternion::from_euler_angles(angles[0], angles[1], angles[2]);
        let c = Vector3::new(centre[0], centre[1], 0.1 + centre[2]);
        let at = |t: [f64; 3]| -> Vector3<f64> {
            c + rot * (Vector3::new(t[0], t[1], t[2]).add_scalar(-0.5) * side)
        };
        let corners: [Vector3<f32>; 8] = std::array::from_fn(|i| {
            at([(i & 1) as f64, ((i >> 1) & 1) as f64, (i >> 2) as f64]).cast::<f32>()
        });
        prop_assume!(corners.iter().any(|p| p.z >= min_z));
        let (f, cxy) = (500.0f32, 320.0f32);
        let (ulo, uhi, vlo, vhi) = range::clipped_bounds(&corners, min_z, f, f, cxy, cxy);
        for t in samples {
            let p = at(t).cast::<f32>();
            if p.z < min_z {
                continue;
            }
            let (u, v) = (f * p.x / p.z + cxy, f * p.y / p.z + cxy);
            // Round-off of the corners and of the edge intersections: a relative 1e-4.
            let tol = |a: f32| 1e-4 * (1.0 + a.abs());
            prop_assert!(u >= ulo - tol(ulo) && u <= uhi + tol(uhi), "u {u} not in [{ulo}, {uhi}]");
            prop_assert!(v >= vlo - tol(vlo) && v <= vhi + tol(vhi), "v {v} not in [{vlo}, {vhi}]");
        }
    }
}

proptest! {
    /// The frustum cull in front of the tile ranges rejects only blocks the exact footprint
    /// (eight projected corners, clipped at the near plane) rejects too, for any camera pose
    /// and block, with the camera inside, beside or far from the block; and it rejects a large
    /// share of the blocks around a camera (it is not vacuous).
    #[test]
    fn the_frustum_cull_rejects_only_unseen_blocks(
        angles in prop::array::uniform3(-3.2f64..3.2),
        centre in prop::array::uniform3(-1.0f64..1.0),
        blocks in prop::collection::vec(prop::array::uniform3(-150i32..150), 400),
        voxel_m in 0.002f64..0.02,
    ) {
        let k = small_camera();
        let vol = TsdfVolume::new(config(voxel_m, 4.0 * voxel_m)).unwrap();
        let pose = Isometry3::from_parts(
            Translation3::new(centre[0], centre[1], centre[2]),
            UnitQuaternion::from_euler_angles(angles[0], angles[1], angles[2]),
        );
        let cfg = RaycastConfig::default();
        let frame = march::RayFrame::new(&vol, &pose, &k, &cfg).unwrap();
        let view = range::BlockView::new(&frame, &k);
        let mut culled = 0;
        for b in blocks {
            // Also the blocks next to the camera (within a few blocks of it).
            for b in [b, [b[0] / 40, b[1] / 40, b[2] / 40]] {
                if view.cull.outside(&view.centre(b)) {
                    culled += 1;
                    prop_assert!(view.footprint(b).is_none(), "block {b:?} culled but seen");
                }
            }
        }
        prop_assert!(culled > 200, "only {culled} of 800 blocks culled");
    }
}

#[test]
fn the_occupancy_map_has_no_false_empty_super_block() {
    // Every super-block holding an allocated block must read "maybe occupied" (a false
    // "empty" would let rays jump over surfaces); most empty ones read "empty".
    let k = small_camera();
    let (vol, _) = fused_room(&k, 0.01, 0.04);
    let mut occ = occupancy::Occupancy::default();
    occ.fill(&vol).unwrap();
    let shift = occupancy::SUPER_SHIFT;
    let mut occupied = std::collections::HashSet::new();
    for b in vol.block_coords() {
        let sb = b.map(|c| c >> shift);
        assert!(occ.maybe_occupied(sb), "block {b:?}");
        occupied.insert(sb);
    }
    let mut empty = 0;
    let mut clear = 0;
    for x in -40..40 {
        for y in -40..40 {
            for z in -40..40 {
                if !occupied.contains(&[x, y, z]) {
                    empty += 1;
                    clear += usize::from(!occ.maybe_occupied([x, y, z]));
                }
            }
        }
    }
    assert!(
        clear * 10 > empty * 9,
        "{clear} of {empty} empty super-blocks read empty"
    );
}

#[test]
fn raycast_into_reuses_buffers_and_threads_do_not_change_the_result() {
    let k = small_camera();
    let (vol, _) = fused_room(&k, 0.02, 0.08);
    let pose = CameraToWorld::identity();
    let cfg = RaycastConfig::default();
    let a = vol.raycast(&pose, &k, &cfg).unwrap();
    let mut out = Raycast::default();
    vol.raycast_into(&pose, &k, &cfg, &mut out).unwrap();
    let ptr = out.points.as_ptr();
    vol.raycast_into(&pose, &k, &cfg, &mut out).unwrap();
    assert_eq!(ptr, out.points.as_ptr(), "buffers reallocated");
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap()
        .install(|| vol.raycast(&pose, &k, &cfg).unwrap());
    for r in [&out, &one] {
        assert_eq!(a.depth.data(), r.depth.data());
        assert_eq!(a.weights, r.weights);
        let bits = |v: &[Vector3<f32>]| v.iter().map(|n| n.map(f32::to_bits)).collect::<Vec<_>>();
        assert_eq!(bits(&a.normals), bits(&r.normals));
    }
    assert!(a.hit_count() > k.pixel_count() / 2);
}

#[test]
fn bad_arguments_are_errors() {
    let k = small_camera();
    let vol = TsdfVolume::new(config(0.01, 0.04)).unwrap();
    let pose = CameraToWorld::identity();
    let cfg = RaycastConfig {
        min_depth_m: 5.0,
        ..RaycastConfig::default()
    };
    assert!(vol.raycast(&pose, &k, &cfg).is_err());
    let cfg = RaycastConfig {
        step_fraction: f64::NAN,
        ..RaycastConfig::default()
    };
    assert!(vol.raycast(&pose, &k, &cfg).is_err());
    let cfg = RaycastConfig {
        min_step_voxels: 0.0,
        ..RaycastConfig::default()
    };
    assert!(cfg.validate().is_err());
    let far = CameraToWorld::from_isometry(Isometry3::translation(1e12, 0.0, 0.0));
    assert!(vol.raycast(&far, &k, &RaycastConfig::default()).is_err());
    let nan = CameraToWorld::from_isometry(Isometry3::translation(f64::NAN, 0.0, 0.0));
    assert!(vol.raycast(&nan, &k, &RaycastConfig::default()).is_err());
}

#[test]
fn rays_marched_together_give_what_each_gives_alone() {
    // The row loop marches `LANES` rays a step each in turn; every pixel must get exactly what
    // one march (`RayFrame::cast`: the hinted start, then the near end when it fails) gives.
    let k = small_camera();
    let v = 0.01;
    let (vol, scene) = fused_room(&k, v, 0.04);
    let pose = CameraToWorld::from_isometry(Isometry3::new(
        Vector3::new(0.05, -0.03, 0.1),
        Vector3::new(0.02, -0.04, 0.01),
    ));
    let truth = scene.render(&k, &pose).depth;
    let config = RaycastConfig::default();
    let band = crate::params::BandFn::new(vol.params());
    let margin = |z: f32| band.band(z) + 2.0 * v as f32;
    // Hints on the surface, behind it (rays that give up and march again) and none at all.
    for offset_m in [Some(0.0f32), Some(0.3), None] {
        let hint = offset_m.map(|o| {
            let mut h = truth.clone();
            for (i, z) in h.data_mut().iter_mut().enumerate() {
                if *z > 0.0 && i % 7 != 0 {
                    *z += o;
                } else {
                    *z = 0.0;
                }
            }
            h
        });
        let mut out = Raycast::default();
        vol.raycast_hinted_into(&pose, &k, &config, hint.as_ref(), &mut out)
            .unwrap();
        let frame = march::RayFrame::new(&vol, pose.isometry(), &k, &config).unwrap();
        let mut sampler = sampler::Sampler::new(&vol);
        let (mut hits, mut gave_up) = (0usize, 0usize);
        for y in 0..k.height {
            for x in 0..k.width {
                let (lo, hi) = range::pixel_range(&out.tiles, k.width, x, y);
                let start = hint
                    .as_ref()
                    .and_then(|h| h.data().get(y * k.width + x))
                    .filter(|z| **z > 0.0)
                    .map(|&z| (z, z - margin(z)))
                    .filter(|(_, s)| *s > lo);
                let occ = &out.occupancy;
                let alone = match start {
                    Some((z, s)) => frame
                        .cast_ray(&mut sampler, occ, frame.hinted_ray(x, y, z, s, hi))
                        .or_else(|| {
                            gave_up += 1;
                            frame.cast(&mut sampler, occ, x, y, lo, hi, false)
                        }),
                    None => frame.cast(&mut sampler, occ, x, y, lo, hi, false),
                };
                let i = y * k.width + x;
                let got = out.depth.data()[i];
                match alone {
                    Some(h) => {
                        hits += 1;
                        assert_eq!(got.to_bits(), h.z_m.to_bits(), "({x}, {y})");
                        assert_eq!(out.points[i], h.point, "({x}, {y})");
                        assert_eq!(out.normals[i], h.normal, "({x}, {y})");
                        assert_eq!(out.weights[i].to_bits(), h.weight.to_bits());
                    }
                    None => assert_eq!(got, 0.0, "({x}, {y})"),
                }
            }
        }
        assert!(hits * 2 > k.width * k.height, "{hits} hits");
        if offset_m == Some(0.3) {
            assert!(gave_up > 100, "{gave_up} hinted rays marched again");
        }
    }
}

/// The base voxel is `⌊g⌋` on both sides of the magic-number range (2^22 voxels), and `None`
/// for coordinates beyond the grid or not finite.
#[test]
fn base_voxels_are_the_floor_near_and_far_from_the_origin() {
    let mut coords = vec![0.0f32, -0.0, 0.5, -0.5, 1.0, -1.0, 1e-30, -1e-30];
    for e in [
        1.0f32,
        100.0,
        4_194_303.0,
        4_194_304.0,
        4_194_305.0,
        3.0e7,
        9.9e8,
    ] {
        for v in [e, -e, e + 0.25 * e.min(1.0), -e - 0.25 * e.min(1.0)] {
            coords.extend([
                v,
                f32::from_bits(v.to_bits() + 1),
                f32::from_bits(v.to_bits() - 1),
            ]);
        }
    }
    for &x in &coords {
        for &y in &coords[..8] {
            let g = [x, y, -x];
            let want = g.map(|c| c.floor() as i32);
            assert_eq!(sampler::base_voxel(g), Some(want), "{g:?}");
        }
    }
    for bad in [1.0e9f32, -2.0e9, f32::INFINITY, f32::NAN] {
        assert_eq!(sampler::base_voxel([0.0, bad, 0.0]), None, "{bad}");
    }
}
