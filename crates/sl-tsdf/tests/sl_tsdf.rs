//! Integration tests of sl-tsdf: analytic TSDFs, weighting, marching cubes topology and
//! accuracy, property tests on planes seen from random poses.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use proptest::prelude::*;
use sl_core::nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use sl_core::{Camera, CameraToWorld, DepthImage, Intrinsics};
use sl_noise::sim::{Plane, Scene, Sphere};
use sl_tsdf::{Axis, Mesh, MeshConfig, SliceSpec, TsdfConfig, TsdfError, TsdfVolume, WeightMode};

/// The mesh's per-vertex confidence (empty when it was not extracted).
fn confidence(mesh: &Mesh) -> &[f32] {
    mesh.scalar_values(sl_tsdf::CONFIDENCE_PROPERTY)
        .unwrap_or_default()
}

fn small_camera() -> Intrinsics {
    Camera::kinect_v1().intrinsics.scaled(0.25).unwrap() // 160x120, f = 145
}

/// A camera at `eye` looking at `target` (y roughly along `up` downwards in the image).
fn look_at(eye: Point3<f64>, target: Point3<f64>) -> CameraToWorld {
    let z = (target - eye).normalize();
    let up = if z.y.abs() > 0.9 {
        Vector3::x()
    } else {
        -Vector3::y()
    };
    let x = (-up).cross(&z).normalize();
    let y = z.cross(&x);
    let r = sl_core::nalgebra::Rotation3::from_matrix_unchecked(
        sl_core::nalgebra::Matrix3::from_columns(&[x, y, z]),
    );
    CameraToWorld::from_isometry(Isometry3::from_parts(
        Translation3::from(eye.coords),
        UnitQuaternion::from_rotation_matrix(&r),
    ))
}

/// A ground-truth scene for `sl-noise`'s ray caster: planes `n·x = d` and spheres (centre,
/// radius).
fn analytic_scene(planes: &[(Vector3<f64>, f64)], spheres: &[(Point3<f64>, f64)]) -> Scene {
    let mut scene = Scene::new();
    for &(n, d) in planes {
        scene.add(Plane::from_normal_offset(n, d).unwrap());
    }
    for &(c, r) in spheres {
        scene.add(Sphere::new(c, r).unwrap());
    }
    scene
}

/// The exact depth of `scene` seen by `k` at camera-to-world `pose`.
fn render(scene: &Scene, k: &Intrinsics, pose: &CameraToWorld) -> DepthImage {
    scene.render(k, pose).depth
}

fn params(voxel_m: f64, trunc_m: f64, weight: WeightMode) -> TsdfConfig {
    let mut config = TsdfConfig::default();
    config.voxel_m = voxel_m;
    config.trunc_m = trunc_m;
    config.weight = weight;
    config
}

#[test]
fn plane_tsdf_is_the_analytic_line_of_sight_distance() {
    let k = small_camera();
    let scene = analytic_scene(&[(Vector3::z(), 1.0)], &[]);
    let pose = CameraToWorld::identity();
    let depth = render(&scene, &k, &pose);
    let (v, trunc) = (0.01, 0.05);
    let mut vol = TsdfVolume::new(params(v, trunc, WeightMode::InvZ4)).unwrap();
    let stats = vol.integrate(&depth, &k, &pose).unwrap();
    assert_eq!(stats.pixels_used, k.pixel_count());
    assert!(stats.blocks_allocated > 0 && stats.blocks_touched == stats.blocks_allocated);
    let mut checked = 0;
    for i in -5i64..=5 {
        for j in -3i64..=3 {
            for kz in 90i64..=110 {
                let Some(vx) = vol.voxel([i, j, kz]) else {
                    continue;
                };
                let p = Point3::new(i as f64 * v, j as f64 * v, kz as f64 * v);
                // Line of sight through p meets z = 1 at range |p|/p.z; f = that − |p|.
                let los = p.coords.norm() / p.z - p.coords.norm();
                if los < -trunc - 1e-6 {
                    assert_eq!(vx.weight, 0.0, "voxel behind the band must stay unobserved");
                    continue;
                }
                assert!(vx.weight > 0.0, "voxel {i},{j},{kz} in the band unobserved");
                let expect = los.min(trunc);
                assert!(
                    (f64::from(vx.tsdf) - expect).abs() < 1e-4,
                    "{} vs {expect}",
                    vx.tsdf
                );
                // One observation at depth 1 m = the reference depth: weight 1.
                assert!((vx.weight - 1.0).abs() < 1e-6);
                checked += 1;
            }
        }
    }
    assert!(checked > 500, "{checked}");
}

/// The fused value is the weighted mean of eq. 12 with the weights of eq. 13.
#[test]
fn weighted_average_of_two_frames() {
    let k = small_camera();
    let near = CameraToWorld::identity();
    let far = CameraToWorld::from_isometry(Isometry3::translation(0.0, 0.0, -1.0));
    // Frame 1 sees a constant-Z wall at world z = 1.00 from 1 m, frame 2 a wall at
    // z = 1.01 from 2.01 m.
    let d1 = DepthImage::from_vec(k.width, k.height, vec![1.0; k.pixel_count()]).unwrap();
    let d2 = DepthImage::from_vec(k.width, k.height, vec![2.01; k.pixel_count()]).unwrap();
    for (mode, w2) in [
        (WeightMode::Uniform, 1.0f64),
        (WeightMode::InvZ4, 1.0 / 2.01f64.powi(4)),
        (WeightMode::InvZ2, 1.0 / 2.01f64.powi(2)),
    ] {
        let mut vol = TsdfVolume::new(params(0.01, 0.04, mode)).unwrap();
        vol.integrate(&d1, &k, &near).unwrap();
        vol.integrate(&d2, &k, &far).unwrap();
        assert_eq!(vol.frame_count(), 2);
        // On the optical axis, f1 = 1 − z, f2 = 1.01 − z.
        for kz in [98i64, 100, 101, 103] {
            let z = kz as f64 * 0.01;
            let vx = vol.voxel([0, 0, kz]).unwrap();
            let expect = (1.0 * (1.0 - z) + w2 * (1.01 - z)) / (1.0 + w2);
            assert!(
                (f64::from(vx.tsdf) - expect).abs() < 2e-6,
                "{mode:?} z {z}: {} vs {expect}",
                vx.tsdf
            );
            assert!((f64::from(vx.weight) - (1.0 + w2)).abs() < 1e-5);
        }
        // The zero crossing moves towards the close frame as its weight grows.
        let s = vol.sample(&Point3::new(0.0, 0.0, 1.005)).unwrap();
        match mode {
            WeightMode::Uniform => assert!(s.abs() < 1e-5),
            _ => assert!(s < 0.0),
        }
    }
}

#[test]
fn weight_cap_turns_into_moving_average() {
    let k = small_camera();
    let mut p = params(0.02, 0.06, WeightMode::Uniform);
    p.max_weight = 4.0;
    let mut vol = TsdfVolume::new(p).unwrap();
    let d = DepthImage::from_vec(k.width, k.height, vec![1.0; k.pixel_count()]).unwrap();
    for _ in 0..10 {
        vol.integrate(&d, &k, &CameraToWorld::identity()).unwrap();
    }
    assert_eq!(vol.voxel([0, 0, 50]).unwrap().weight, 4.0);
    // A new observation now moves the value by w/(W+w) = 1/5 of the difference.
    let d2 = DepthImage::from_vec(k.width, k.height, vec![1.02; k.pixel_count()]).unwrap();
    let before = vol.voxel([0, 0, 50]).unwrap().tsdf;
    vol.integrate(&d2, &k, &CameraToWorld::identity()).unwrap();
    let after = vol.voxel([0, 0, 50]).unwrap().tsdf;
    assert!(
        (after - before - 0.02 / 5.0).abs() < 1e-6,
        "{before} -> {after}"
    );
}

#[test]
fn errors_leave_the_volume_unchanged() {
    let k = small_camera();
    let scene = analytic_scene(&[(Vector3::z(), 1.0)], &[]);
    let depth = render(&scene, &k, &CameraToWorld::identity());
    let mut p = params(0.01, 0.03, WeightMode::InvZ4);
    p.memory_budget_bytes = 10 * sl_tsdf::volume::BYTES_PER_BLOCK;
    let mut vol = TsdfVolume::new(p).unwrap();
    match vol.integrate(&depth, &k, &CameraToWorld::identity()) {
        Err(TsdfError::MemoryBudget { blocks, .. }) => assert!(blocks > 10),
        other => panic!("expected a budget error, got {other:?}"),
    }
    assert_eq!(vol.block_count(), 0);
    assert_eq!(vol.frame_count(), 0);
    let wrong = DepthImage::invalid(10, 10);
    assert!(matches!(
        vol.integrate(&wrong, &k, &CameraToWorld::identity()),
        Err(TsdfError::SizeMismatch { .. })
    ));
    let far_away = CameraToWorld::from_isometry(Isometry3::translation(1e9, 0.0, 0.0));
    let mut vol = TsdfVolume::new(params(0.01, 0.03, WeightMode::InvZ4)).unwrap();
    assert!(matches!(
        vol.integrate(&depth, &k, &far_away),
        Err(TsdfError::OutOfRange(_))
    ));
}

#[test]
fn memory_grows_with_surface_not_bounding_box() {
    // Two walls 3 m apart: the blocks hug the walls, the space between stays empty.
    let k = small_camera();
    let near = DepthImage::from_vec(k.width, k.height, vec![1.0; k.pixel_count()]).unwrap();
    let mut vol = TsdfVolume::new(params(0.01, 0.03, WeightMode::InvZ4)).unwrap();
    vol.integrate(&near, &k, &CameraToWorld::identity())
        .unwrap();
    let one = vol.block_count();
    let far = DepthImage::from_vec(k.width, k.height, vec![3.0; k.pixel_count()]).unwrap();
    vol.integrate(&far, &k, &CameraToWorld::identity()).unwrap();
    // The band is 6 cm thick: at most 2-3 block layers per wall.
    let zs: std::collections::BTreeSet<i32> = vol.block_coords().map(|b| b[2]).collect();
    assert!(
        zs.iter()
            .all(|&z| (11..=14).contains(&z) || (35..=39).contains(&z)),
        "{zs:?}"
    );
    assert!(vol.block_count() > one);
    assert!(vol.memory_bytes() >= vol.block_count() * std::mem::size_of::<sl_tsdf::Block>());
}

fn sphere_volume(voxel: f64, r: f64, centre: Point3<f64>) -> TsdfVolume {
    let lo = [0, 1, 2].map(|a| centre[a] - r - 3.0 * voxel);
    let hi = [0, 1, 2].map(|a| centre[a] + r + 3.0 * voxel);
    TsdfVolume::from_field(
        params(voxel, 4.0 * voxel, WeightMode::Uniform),
        lo,
        hi,
        |p| Some(((p - centre).norm() - r) as f32),
    )
    .unwrap()
}

#[test]
fn sphere_is_closed_manifold_oriented_and_accurate() {
    let (voxel, r) = (0.01, 0.123);
    // Off-grid centre spanning negative coordinates and block borders.
    let c = Point3::new(-0.0137, 0.0412, 0.0051);
    let vol = sphere_volume(voxel, r, c);
    let mesh = vol.extract_mesh(&MeshConfig::default());
    assert!(mesh.triangle_count() > 1000);
    let topo = mesh.topology();
    assert!(topo.is_closed_oriented_manifold(), "{topo:?}");
    assert_eq!(mesh.normals.len(), mesh.vertex_count());
    assert_eq!(confidence(&mesh).len(), mesh.vertex_count());
    // Vertices on the sphere within voxel/10.
    let worst = mesh
        .positions
        .iter()
        .map(|p| ((Point3::new(p[0] as f64, p[1] as f64, p[2] as f64) - c).norm() - r).abs())
        .fold(0.0, f64::max);
    assert!(worst < voxel / 10.0, "worst {worst}");
    // Outward orientation: positive enclosed volume close to 4/3 π r³; normals radial.
    let vol_true = 4.0 / 3.0 * std::f64::consts::PI * r.powi(3);
    let v = mesh.signed_volume();
    assert!((v - vol_true).abs() / vol_true < 0.01, "{v} vs {vol_true}");
    for (p, n) in mesh.positions.iter().zip(&mesh.normals) {
        let radial = (Point3::new(p[0] as f64, p[1] as f64, p[2] as f64) - c).normalize();
        let dot = radial.x * n[0] as f64 + radial.y * n[1] as f64 + radial.z * n[2] as f64;
        assert!(dot > 0.98, "normal {n:?} at {p:?}");
    }
    // No duplicated vertices.
    let mut keys: Vec<[u32; 3]> = mesh
        .positions
        .iter()
        .map(|p| p.coords.map(f32::to_bits).into())
        .collect();
    keys.sort_unstable();
    keys.dedup();
    assert_eq!(keys.len(), mesh.vertex_count());
    // Euler characteristic of a sphere.
    let chi = mesh.vertex_count() as i64 - topo.edges as i64 + mesh.triangle_count() as i64;
    assert_eq!(chi, 2);
}

/// Random fields are full of ambiguous faces (and the interior ambiguities of cases 4, 6,
/// 7, 10, 12, 13): the mesh must still be edge-manifold and consistently oriented, with
/// boundary edges only on the border of the field's box.
#[test]
fn random_fields_give_crack_free_oriented_meshes() {
    use rand::{Rng, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
    let voxel = 0.1;
    for trial in 0..6 {
        let n = 12i64; // voxels -6..6 per axis: spans 2-3 blocks per axis
        let values: Vec<f32> = (0..(n * n * n))
            .map(|_| rng.random_range(-1.0f32..1.0))
            .collect();
        let field = |p: &Point3<f64>| {
            let g = [p.x, p.y, p.z].map(|c| (c / voxel).round() as i64 + n / 2);
            if g.iter().all(|&c| (0..n).contains(&c)) {
                Some(values[(g[0] + n * (g[1] + n * g[2])) as usize])
            } else {
                None
            }
        };
        let half = (n / 2) as f64 * voxel;
        let vol = TsdfVolume::from_field(
            params(voxel, 0.4, WeightMode::Uniform),
            [-half; 3],
            [half; 3],
            field,
        )
        .unwrap();
        let mesh = vol.extract_mesh(&MeshConfig::default());
        let topo = mesh.topology();
        assert_eq!(topo.nonmanifold_edges, 0, "trial {trial}: {topo:?}");
        assert_eq!(topo.inconsistent_edges, 0, "trial {trial}: {topo:?}");
        assert_eq!(topo.degenerate_triangles, 0);
        // Every boundary edge lies on the border faces of the observed box.
        let lo = -half;
        let hi = (n / 2 - 1) as f64 * voxel;
        let mut count = std::collections::HashMap::new();
        for t in &mesh.triangles {
            for i in 0..3 {
                let (a, b) = (t[i].min(t[(i + 1) % 3]), t[i].max(t[(i + 1) % 3]));
                *count.entry((a, b)).or_insert(0) += 1;
            }
        }
        let on_border = |p: &Point3<f32>| {
            p.iter()
                .any(|&c| ((c as f64) - lo).abs() < 1e-5 || ((c as f64) - hi).abs() < 1e-5)
        };
        for ((a, b), c) in count {
            if c == 1 {
                let (pa, pb) = (&mesh.positions[a as usize], &mesh.positions[b as usize]);
                assert!(
                    on_border(pa) && on_border(pb),
                    "interior crack at {pa:?} {pb:?}"
                );
            }
        }
    }
}

/// The parallel extraction gives the same mesh with any number of threads, and every vertex it
/// emits is used by a triangle (also with unobserved voxels and a weight threshold).
#[test]
fn extraction_is_deterministic_and_has_no_unused_vertices() {
    use rand::{Rng, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
    let voxel = 0.1;
    let n = 20i64; // voxels -10..10 per axis: 3-4 blocks per axis
    let values: Vec<Option<f32>> = (0..(n * n * n))
        .map(|_| {
            let f = rng.random_range(-1.0f32..1.0);
            (rng.random_range(0.0f32..1.0) > 0.15).then_some(f)
        })
        .collect();
    let field = |p: &Point3<f64>| {
        let g = [p.x, p.y, p.z].map(|c| (c / voxel).round() as i64 + n / 2);
        if g.iter().all(|&c| (0..n).contains(&c)) {
            values[(g[0] + n * (g[1] + n * g[2])) as usize]
        } else {
            None
        }
    };
    let half = (n / 2) as f64 * voxel;
    let vol = TsdfVolume::from_field(
        params(voxel, 0.4, WeightMode::Uniform),
        [-half; 3],
        [half; 3],
        field,
    )
    .unwrap();
    for min_weight in [0.0, 1.0, 2.0] {
        let mut opts = MeshConfig::default();
        opts.min_weight = min_weight;
        let meshes: Vec<Mesh> = [1, 2, 5]
            .iter()
            .map(|&threads| {
                rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .unwrap()
                    .install(|| vol.extract_mesh(&opts))
            })
            .collect();
        assert_eq!(meshes[0], meshes[1]);
        assert_eq!(meshes[0], meshes[2]);
        let mesh = &meshes[0];
        if min_weight > 1.0 {
            // Every voxel has weight 1: nothing passes.
            assert_eq!(mesh.vertex_count(), 0);
            continue;
        }
        assert!(mesh.triangle_count() > 1000, "{}", mesh.triangle_count());
        let mut used = vec![false; mesh.vertex_count()];
        for t in &mesh.triangles {
            for &i in t {
                used[i as usize] = true;
            }
        }
        assert!(used.iter().all(|&u| u), "unused vertices");
        assert_eq!(mesh.normals.len(), mesh.vertex_count());
        assert_eq!(confidence(mesh).len(), mesh.vertex_count());
    }
}

/// Two cubes sharing an ambiguous face, with each cube's other corners set so that Lorensen's
/// complementary table would resolve the face differently on the two sides.
#[test]
fn ambiguous_shared_face_has_no_crack() {
    // Shared face x = 1: inside at (1,0,0) and (1,1,1), outside at (1,1,0) and (1,0,1).
    // Cube A (x in 0..1) otherwise outside; cube B (x in 1..2) otherwise inside.
    let voxel = 0.1;
    let field = |p: &Point3<f64>| {
        let g = [p.x, p.y, p.z].map(|c| (c / voxel).round() as i64);
        if !(0..=2).contains(&g[0]) || !(0..=1).contains(&g[1]) || !(0..=1).contains(&g[2]) {
            return None;
        }
        let v = match g[0] {
            0 => 1.0,
            2 => -1.0,
            _ => {
                if g[1] == g[2] {
                    -1.0
                } else {
                    1.0
                }
            }
        };
        Some(v)
    };
    let vol = TsdfVolume::from_field(
        params(voxel, 0.4, WeightMode::Uniform),
        [0.0; 3],
        [0.2, 0.1, 0.1],
        field,
    )
    .unwrap();
    let mesh = vol.extract_mesh(&MeshConfig::default());
    let topo = mesh.topology();
    assert_eq!(
        topo.nonmanifold_edges + topo.inconsistent_edges,
        0,
        "{topo:?}"
    );
    // Boundary edges only on the outer faces of the 2x1x1 box (y, z in {0, 0.1}, x in {0, 0.2}).
    let mut count = std::collections::HashMap::new();
    for t in &mesh.triangles {
        for i in 0..3 {
            let (a, b) = (t[i].min(t[(i + 1) % 3]), t[i].max(t[(i + 1) % 3]));
            *count.entry((a, b)).or_insert(0) += 1;
        }
    }
    let outer = |p: &Point3<f32>, q: &Point3<f32>| {
        (0..3).any(|ax| {
            let bounds = if ax == 0 { [0.0, 0.2] } else { [0.0, 0.1] };
            bounds
                .iter()
                .any(|&b| ((p[ax] as f64) - b).abs() < 1e-6 && ((q[ax] as f64) - b).abs() < 1e-6)
        })
    };
    let mut boundary = 0;
    for ((a, b), c) in count {
        if c == 1 {
            boundary += 1;
            assert!(
                outer(&mesh.positions[a as usize], &mesh.positions[b as usize]),
                "crack on the shared face"
            );
        }
    }
    assert!(boundary > 0);
    // The inside corners of the shared face are joined: one connected piece through it.
    assert!(mesh.triangle_count() >= 4);
}

#[test]
fn unobserved_and_light_corners_are_skipped() {
    let (voxel, r) = (0.01, 0.08);
    let c = Point3::new(0.0, 0.0, 0.0);
    let lo = [-0.12; 3];
    let hi = [0.12; 3];
    // Leave the x > 0.03 half unobserved: the mesh is the x < 0.03 part only.
    let vol = TsdfVolume::from_field(params(voxel, 0.04, WeightMode::Uniform), lo, hi, |p| {
        (p.x <= 0.03).then(|| ((p - c).norm() - r) as f32)
    })
    .unwrap();
    let mesh = vol.extract_mesh(&MeshConfig::default());
    assert!(mesh.triangle_count() > 100);
    assert!(mesh.positions.iter().all(|p| p[0] <= 0.03 + 1e-6));
    let topo = mesh.topology();
    assert!(topo.boundary_edges > 0 && topo.nonmanifold_edges == 0 && topo.inconsistent_edges == 0);
    // All voxels weigh 1: a higher threshold removes everything.
    let mut heavy = MeshConfig::default();
    heavy.min_weight = 1.5;
    let none = vol.extract_mesh(&heavy);
    assert_eq!(none.triangle_count(), 0);
    assert_eq!(none.vertex_count(), 0);
}

#[test]
fn fused_sphere_from_views_around_it() {
    let k = small_camera();
    let c = Point3::new(0.0, 0.0, 0.0);
    let r = 0.15;
    let scene = analytic_scene(&[], &[(c, r)]);
    let voxel = 0.01;
    let mut vol = TsdfVolume::new(params(voxel, 0.04, WeightMode::InvZ4)).unwrap();
    let eyes = [
        Point3::new(0.0, 0.0, -0.8),
        Point3::new(0.0, 0.0, 0.8),
        Point3::new(0.8, 0.0, 0.0),
        Point3::new(-0.8, 0.0, 0.0),
        Point3::new(0.0, 0.8, 0.01),
        Point3::new(0.0, -0.8, 0.01),
    ];
    for e in eyes {
        let pose = look_at(e, c);
        vol.integrate(&render(&scene, &k, &pose), &k, &pose)
            .unwrap();
    }
    let mesh = vol.extract_mesh(&MeshConfig::default());
    let topo = mesh.topology();
    assert!(topo.is_closed_oriented_manifold(), "{topo:?}");
    assert!(mesh.signed_volume() > 0.0);
    let d = sl_eval::tsdf::vertex_distances(&mesh, |_| true, |p| scene.distance(p));
    let s = sl_eval::DistanceStats::from_distances(&d).unwrap();
    // Sub-voxel accuracy: RMS under a quarter and p95 under half a voxel. (Single vertices near
    // a view's silhouette can be off by about a pixel footprint, 4.5 mm at 0.65 m, times the
    // tangent of the grazing angle, so the maximum is not bounded this tightly.)
    assert!(s.rms_m < voxel / 4.0 && s.p95_m < voxel / 2.0, "{s:?}");
}

#[test]
fn slice_shows_the_zero_crossing_at_the_wall() {
    let k = small_camera();
    let depth = DepthImage::from_vec(k.width, k.height, vec![1.0; k.pixel_count()]).unwrap();
    let mut vol = TsdfVolume::new(params(0.01, 0.04, WeightMode::InvZ4)).unwrap();
    vol.integrate(&depth, &k, &CameraToWorld::identity())
        .unwrap();
    let spec = SliceSpec {
        axis: Axis::X,
        coord_m: 0.0,
        pixels_per_voxel: 2,
        window_m: Some(([-0.2, 0.2], [0.9, 1.1])),
    };
    let s = vol.slice(&spec).unwrap();
    assert_eq!(s.values.width(), 81);
    assert_eq!(s.values.height(), 41);
    let mask = s.zero_crossing_mask();
    // Row r has v = 1.1 − r·0.005: the crossing is between rows 19 (v = 1.005) and 20 (v = 1.0).
    for x in 0..s.values.width() {
        let rows: Vec<usize> = (0..s.values.height())
            .filter(|&y| *mask.get(x, y).unwrap())
            .collect();
        assert!(rows == vec![19] || rows == vec![20], "column {x}: {rows:?}");
    }
    let rgb = s.to_rgb([0, 0, 0]);
    assert_eq!(*rgb.get(40, 0).unwrap(), sl_tsdf::slice::UNOBSERVED_RGB); // v = 1.1 behind band
    let front = rgb.get(40, 26).unwrap(); // v = 0.97: free space, reddish
    assert!(front[0] > front[2]);
    let image = vol.slice_rgb(&SliceSpec::new(Axis::Y, 0.0)).unwrap();
    assert!(image.width() > 10 && image.height() > 4);
    // A plane that misses the blocks names itself compactly and says where the blocks are.
    for coord in [5.0, 1e300] {
        let e = vol
            .slice(&SliceSpec::new(Axis::Z, coord))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains(&format!(
                "no allocated block crosses the plane z = {} m",
                if coord == 5.0 { "5" } else { "1e300" }
            )) && e.contains("the allocated blocks span z from"),
            "{e}"
        );
        assert!(!e.contains("000000000"), "{e}");
    }
    let empty = TsdfVolume::new(params(0.01, 0.04, WeightMode::InvZ4)).unwrap();
    let e = empty
        .slice(&SliceSpec::new(Axis::X, 0.0))
        .unwrap_err()
        .to_string();
    assert!(e.contains("nothing was fused"), "{e}");
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 24, .. ProptestConfig::default() })]

    /// A plane seen from one or two random poses (distance 0.7-1.6 m, incidence up to 45°):
    /// the fused zero set lies on the plane.
    #[test]
    fn fused_zero_set_lies_on_the_plane(
        nx in -0.4f64..0.4, ny in -0.4f64..0.4, off in -0.2f64..0.2,
        dist1 in 0.7f64..1.6, dist2 in 0.7f64..1.6,
        a1 in -0.5f64..0.5, b1 in -0.5f64..0.5, a2 in -0.5f64..0.5, b2 in -0.5f64..0.5,
        two in proptest::bool::ANY,
    ) {
        let k = small_camera();
        let n = Vector3::new(nx, ny, 1.0).normalize();
        let scene = analytic_scene(&[(n, off)], &[]);
        let foot = Point3::from(n * off);
        let voxel = 0.02;
        let mut vol = TsdfVolume::new(params(voxel, 0.06, WeightMode::InvZ4)).unwrap();
        let mut max_px_m: f64 = 0.0;
        let views: &[(f64, f64, f64)] = if two { &[(dist1, a1, b1), (dist2, a2, b2)] } else { &[(dist1, a1, b1)] };
        for &(d, a, b) in views {
            // Eye on the front side of the plane, tilted by up to ~0.5 rad from the normal.
            let dir = (n + Vector3::new(a, b, 0.0) * 0.9).normalize();
            let eye = foot - dir * d;
            let pose = look_at(eye, foot);
            let depth = render(&scene, &k, &pose);
            vol.integrate(&depth, &k, &pose).unwrap();
            max_px_m = max_px_m.max(d / k.fx);
        }
        let mesh = vol.extract_mesh(&MeshConfig::default());
        prop_assert!(mesh.vertex_count() > 50);
        // Error budget: the nearest-pixel depth lookup shifts the surface by up to half a pixel
        // footprint (range ρ ≤ 1.3·d at the image corners, footprint ρ/f) times tan(incidence)
        // (≤ 1.9 with the tilt plus the half field of view): 0.5·1.3·1.9 ≈ 1.25·d/f; plus a
        // tenth of a voxel for the linear interpolation of the line-of-sight distance.
        let tol = 1.25 * max_px_m + voxel / 10.0;
        for p in &mesh.positions {
            let q = Point3::new(p[0] as f64, p[1] as f64, p[2] as f64);
            let e = (n.dot(&q.coords) - off).abs();
            prop_assert!(e < tol, "vertex {q:?} is {e} m off the plane (tol {tol})");
        }
        let topo = mesh.topology();
        prop_assert_eq!(topo.nonmanifold_edges + topo.inconsistent_edges, 0);
        // Normals face the cameras (towards positive F, the front of the plane).
        let front = mesh.normals.iter().filter(|m| (m[0] as f64 * -n.x + m[1] as f64 * -n.y + m[2] as f64 * -n.z) > 0.9).count();
        prop_assert!(front * 10 >= mesh.vertex_count() * 9);
    }
}

#[test]
fn fused_mesh_survives_a_ply_round_trip() {
    let k = small_camera();
    let scene = analytic_scene(&[(Vector3::z(), 1.4)], &[(Point3::new(0.0, 0.0, 1.0), 0.2)]);
    let mut vol = TsdfVolume::new(params(0.02, 0.06, WeightMode::InvZ4)).unwrap();
    vol.integrate(
        &render(&scene, &k, &CameraToWorld::identity()),
        &k,
        &CameraToWorld::identity(),
    )
    .unwrap();
    let mesh = vol.extract_mesh(&MeshConfig::default());
    assert!(mesh.triangle_count() > 100);
    let dir = tempfile::tempdir().unwrap();
    for (name, format) in [
        ("m.ply", sl_io::PlyFormat::BinaryLittleEndian),
        ("a.ply", sl_io::PlyFormat::Ascii),
    ] {
        let path = dir.path().join(name);
        sl_tsdf::io::write_mesh_ply(&path, &mesh, format).unwrap();
        let back = sl_tsdf::io::read_mesh_ply(&path).unwrap();
        assert_eq!(back.triangles, mesh.triangles);
        assert_eq!(back.positions.len(), mesh.positions.len());
        assert_eq!(confidence(&back).len(), confidence(&mesh).len());
        assert_eq!(back.normals.len(), mesh.normals.len());
        let close = |a: &[f32], b: &[f32]| {
            a.iter()
                .zip(b)
                .all(|(x, y)| (x - y).abs() <= 1e-6 * x.abs().max(1.0))
        };
        for (a, b) in back.positions.iter().zip(&mesh.positions) {
            assert!(
                close(a.coords.as_slice(), b.coords.as_slice()),
                "{a:?} vs {b:?}"
            );
        }
        for (a, b) in back.normals.iter().zip(&mesh.normals) {
            assert!(close(a.as_slice(), b.as_slice()));
        }
        assert!(close(confidence(&back), confidence(&mesh)));
        assert_eq!(back.topology(), mesh.topology());
    }
}

#[test]
fn candidate_blocks_are_counted_against_the_budget_while_they_are_found() {
    // Issue 15: a 0.1 mm voxel with a 1 m band lists billions of candidate blocks; the budget
    // stops the listing long before (the process would otherwise hold gigabytes of keys).
    let k = small_camera();
    let depth = DepthImage::from_vec(k.width, k.height, vec![1.5; k.pixel_count()]).unwrap();
    let mut p = params(0.0001, 1.0, WeightMode::InvZ4);
    p.memory_budget_bytes = 16 << 20;
    let mut vol = TsdfVolume::new(p).unwrap();
    match vol.integrate(&depth, &k, &CameraToWorld::identity()) {
        Err(TsdfError::CandidateBudget {
            candidates,
            max_candidates,
        }) => {
            assert!(
                candidates > max_candidates,
                "{candidates} <= {max_candidates}"
            );
            assert!(max_candidates <= (16 << 20) / 24, "{max_candidates}");
        }
        other => panic!("expected a candidate budget error, got {other:?}"),
    }
    assert_eq!(vol.block_count(), 0);
    assert_eq!(vol.frame_count(), 0);
}

#[test]
fn mesh_extraction_is_counted_against_the_budget() {
    let k = small_camera();
    let scene = analytic_scene(&[(Vector3::z(), 1.0)], &[]);
    let depth = render(&scene, &k, &CameraToWorld::identity());
    let mut vol = TsdfVolume::new(params(0.01, 0.03, WeightMode::InvZ4)).unwrap();
    vol.integrate(&depth, &k, &CameraToWorld::identity())
        .unwrap();
    let opts = MeshConfig::default();
    let mesh = vol.extract_mesh(&opts);
    assert!(mesh.triangle_count() > 0);
    // Enough budget: the same mesh.
    assert_eq!(
        vol.extract_mesh_within(&opts, usize::MAX - 1).unwrap(),
        mesh
    );
    // The volume alone fits, the mesh does not.
    match vol.extract_mesh_within(&opts, vol.memory_bytes() + 1) {
        Err(TsdfError::MeshBudget {
            vertices,
            triangles,
            needed_bytes,
            budget_bytes,
        }) => {
            assert_eq!(vertices, mesh.vertex_count());
            assert_eq!(triangles, mesh.triangle_count());
            assert!(needed_bytes > budget_bytes);
        }
        other => panic!("expected a mesh budget error, got {other:?}"),
    }
}
