//! Unit tests of the volume: storage, integration, budget and discovery.

use super::*;
use rand::{Rng, SeedableRng};
use sl_core::CameraToWorld;

/// A depth frame of random patches (steps between them), some invalid pixels.
fn random_frame(
    rng: &mut rand_chacha::ChaCha8Rng,
    w: usize,
    h: usize,
    range: (f32, f32),
) -> Vec<f32> {
    let patch = 5;
    let cells: Vec<f32> = (0..w.div_ceil(patch) * h.div_ceil(patch))
        .map(|_| rng.random_range(range.0..range.1))
        .collect();
    (0..w * h)
        .map(|i| {
            let (x, y) = (i % w, i / w);
            if rng.random_range(0.0f32..1.0) < 0.05 {
                return 0.0;
            }
            // A tilted patch: depth varies across it, so that segments cross cells
            // at different places.
            let c = cells[x / patch + w.div_ceil(patch) * (y / patch)];
            c + 0.002 * (x % patch) as f32 - 0.0015 * (y % patch) as f32
        })
        .collect()
}

/// The band's blocks by brute force: every valid pixel's segment traversed cell by cell.
fn band_reference(f: &BandFrame<'_>, depth: &[f32]) -> Vec<u64> {
    let k = f.k;
    let mut keys = Vec::new();
    for (i, &d) in depth.iter().enumerate() {
        if d <= 0.0 {
            continue;
        }
        let (x, y) = (i % k.width, i / k.width);
        let ry = ((y as f64 - k.cy) / k.fy) as f32;
        let r = f.rx[x];
        let dt = f.band.band(d) / (r * r + (ry * ry + 1.0)).sqrt();
        // The ray's direction rounded as in `band_rows`.
        let dir = f.rot * Vector3::new(0.0, ry, 1.0) + f.rot.column(0) * r;
        let a = f.t + dir * (d - dt).max(0.0);
        let b = f.t + dir * (d + dt);
        traverse(&a, &b, |c| keys.push(pack_unchecked(c)));
    }
    keys.sort_unstable();
    keys.dedup();
    keys
}

#[test]
fn band_rows_matches_brute_force_traversal() {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
    let k = Intrinsics::new(64, 48, 60.0, 62.0, 31.3, 23.8).unwrap();
    let pixels = PixelFn {
        min_d: 0.0,
        max_d: 100.0,
    };
    // Voxel sizes from blocks longer than the band (one or two cells per segment) to
    // much shorter (long segments: the DDA path).
    for (case, &voxel_m) in [0.004, 0.01, 0.001, 0.0005].iter().enumerate() {
        for _ in 0..4 {
            let p = TsdfConfig {
                voxel_m,
                trunc_m: 0.02,
                ..TsdfConfig::default()
            };
            let axis = Vector3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            );
            let pose = Isometry3::new(
                Vector3::new(
                    rng.random_range(-2.0..2.0),
                    rng.random_range(-2.0..2.0),
                    rng.random_range(-2.0..2.0),
                ),
                axis * rng.random_range(0.0..3.0),
            );
            let depth = random_frame(&mut rng, k.width, k.height, (0.3, 3.0));
            let rx: Vec<f32> = (0..k.width)
                .map(|x| ((x as f64 - k.cx) / k.fx) as f32)
                .collect();
            let band = BandFrame::new(&p, &k, &pose, &rx).unwrap();
            let tw = k.width + 2;
            let mut table = vec![0.0f32; tw * (k.height + 2)];
            let mut keys = Vec::new();
            for (ci, (trows, drows)) in table[tw..tw * (k.height + 1)]
                .chunks_mut(tw * BAND_ROWS)
                .zip(depth.chunks(k.width * BAND_ROWS))
                .enumerate()
            {
                pixels.fill(trows, drows, k.width);
                keys.extend(band_rows(&band, trows, ci * BAND_ROWS).unwrap());
            }
            keys.sort_unstable();
            keys.dedup();
            let reference = band_reference(&band, &depth);
            assert!(reference.len() > 50, "case {case}: {}", reference.len());
            assert_eq!(keys, reference, "case {case}");
        }
    }
    // A depth too far for the block index is refused.
    let p = TsdfConfig {
        voxel_m: 0.001,
        max_depth_m: 1e9,
        ..TsdfConfig::default()
    };
    let rx: Vec<f32> = (0..k.width)
        .map(|x| ((x as f64 - k.cx) / k.fx) as f32)
        .collect();
    let band = BandFrame::new(&p, &k, &Isometry3::identity(), &rx).unwrap();
    let tw = k.width + 2;
    let mut trows = vec![0.0f32; tw * BAND_ROWS];
    trows[tw * 3 + 10] = 1e8;
    assert!(matches!(
        band_rows(&band, &trows, 0),
        Err(TsdfError::OutOfRange(_))
    ));
}

#[test]
fn voxel_update_variants_agree() {
    // The masked small-table gather and the bounds-checked one, with and without the
    // per-voxel z test, give bit-identical voxels.
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
    let k = Intrinsics::new(640, 480, 525.0, 525.0, 319.5, 239.5).unwrap();
    let tw = k.width + 2;
    let mut table = vec![0.0f32; SMALL_TABLE];
    for y in 0..k.height {
        for x in 0..k.width {
            if rng.random_range(0.0f32..1.0) < 0.9 {
                let d = rng.random_range(0.5f32..3.0);
                table[(y + 1) * tw + x + 1] = d;
            }
        }
    }
    let small: &[f32; SMALL_TABLE] = table.first_chunk().unwrap();
    let p = TsdfConfig::default();
    let pose = Isometry3::new(Vector3::new(0.1, -0.2, 0.05), Vector3::new(0.1, 0.2, -0.1));
    let fc = FrameConsts::new(&p, &k, &pose);
    let mut n_updated = 0;
    for _ in 0..200 {
        // Blocks in front of the camera (within 0.5..3 m along its axis).
        let pc = Vector3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-0.8..0.8),
            rng.random_range(0.5..3.0),
        );
        let pw = pose.transform_point(&pc.into());
        let b = [pw.x, pw.y, pw.z].map(|c| (c / (8.0 * p.voxel_m)).floor() as i32);
        let mut blk = Block::default();
        for (i, (t, w)) in blk.tsdf.iter_mut().zip(blk.weight.iter_mut()).enumerate() {
            *t = (i as f32 * 0.37).sin() * 0.02;
            *w = (i % 3) as f32;
        }
        let o = [0, 1, 2].map(|a| (b[a] * BLOCK_SIDE as i32) as f32 * fc.v);
        let origin = fc.rt * Vector3::new(o[0], o[1], o[2]) + fc.tt;
        let mut a = blk.clone();
        let mut c = blk.clone();
        let mut d = blk.clone();
        integrate_block_with::<_, false>(&mut a, None, &origin, &fc, small);
        integrate_block_with::<_, true>(&mut c, None, &origin, &fc, small);
        integrate_block_with::<_, false>(&mut d, None, &origin, &fc, table.as_slice());
        let mut e = blk.clone();
        integrate_block(&mut e, b, &fc, table.as_slice());
        for other in [&c, &d, &e] {
            assert!(
                a.tsdf
                    .iter()
                    .zip(&other.tsdf)
                    .all(|(x, y)| x.to_bits() == y.to_bits())
            );
            assert!(
                a.weight
                    .iter()
                    .zip(&other.weight)
                    .all(|(x, y)| x.to_bits() == y.to_bits())
            );
        }
        n_updated += a
            .weight
            .iter()
            .zip(&blk.weight)
            .filter(|(x, y)| x != y)
            .count();
    }
    assert!(n_updated > 10_000, "{n_updated}");
}

#[test]
fn block_arena_stays_within_the_budget() {
    let k = Intrinsics::new(160, 120, 145.0, 145.0, 79.5, 59.5).unwrap();
    let depth = DepthImage::from_vec(k.width, k.height, vec![1.2; k.pixel_count()]).unwrap();
    let poses: Vec<Isometry3<f64>> = (0..6)
        .map(|i| Isometry3::new(Vector3::new(0.05 * i as f64, 0.0, 0.0), Vector3::zeros()))
        .collect();
    let mut free = TsdfVolume::new(TsdfConfig::default()).unwrap();
    for pose in &poses {
        free.integrate(&depth, &k, &CameraToWorld::from_isometry(*pose))
            .unwrap();
    }
    let budget = free.block_count() * BYTES_PER_BLOCK;
    let mut tight = TsdfVolume::new(TsdfConfig {
        memory_budget_bytes: budget,
        ..TsdfConfig::default()
    })
    .unwrap();
    for pose in &poses {
        tight
            .integrate(&depth, &k, &CameraToWorld::from_isometry(*pose))
            .unwrap();
        let arena = tight.blocks.capacity() * (std::mem::size_of::<Block>() + 8);
        assert!(arena <= budget, "{arena} > {budget}");
        assert!(tight.keys.capacity() <= tight.blocks.capacity());
    }
    assert_eq!(tight.block_count(), free.block_count());
    // One more block than the budget allows is refused, the volume unchanged.
    let mut over = TsdfVolume::new(TsdfConfig {
        memory_budget_bytes: budget - 1,
        ..TsdfConfig::default()
    })
    .unwrap();
    let mut refused = false;
    for pose in &poses {
        match over.integrate(&depth, &k, &CameraToWorld::from_isometry(*pose)) {
            Ok(_) => {}
            Err(TsdfError::MemoryBudget { .. }) => {
                refused = true;
                break;
            }
            Err(e) => panic!("{e}"),
        }
    }
    assert!(refused);
    assert!(over.block_count() < free.block_count());
}

#[test]
fn traversal_is_connected_and_reaches_end() {
    let a = Vector3::new(0.2f32, 0.3, -0.7);
    let b = Vector3::new(3.9f32, -2.2, 1.4);
    let mut cells = Vec::new();
    traverse(&a, &b, |c| cells.push(c));
    assert_eq!(pack_unchecked([-3, 4, 5]), pack([-3, 4, 5]).unwrap());
    assert_eq!(cells[0], [0, 0, -1]);
    assert_eq!(*cells.last().unwrap(), [3, -3, 1]);
    for w in cells.windows(2) {
        let d: i32 = (0..3).map(|i| (w[0][i] - w[1][i]).abs()).sum();
        assert_eq!(d, 1);
    }
    // Crosses 3 + 3 + 2 boundaries.
    assert_eq!(cells.len(), 9);
}

#[test]
fn voxel_addressing() {
    assert_eq!(local_index(7, 7, 7), BLOCK_VOXELS - 1);
    let vol = TsdfVolume::new(TsdfConfig::default()).unwrap();
    assert_eq!(vol.voxel([-1, 0, 0]), None);
    assert_eq!(vol.block_count(), 0);
}

/// Discovery and the voxel update run with every instruction set this CPU has
/// (`TsdfConfig::isa`) and give the same blocks and voxels, bit for bit, on frames of random
/// patches from moving poses (voxels behind the camera and off the image included).
#[test]
fn every_instruction_set_fuses_bit_identically() {
    let k = Intrinsics::new(160, 120, 145.0, 145.0, 79.5, 59.5).unwrap();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
    let frames: Vec<(DepthImage, CameraToWorld)> = (0..4)
        .map(|i| {
            let d = random_frame(&mut rng, k.width, k.height, (0.4, 3.5));
            let pose = Isometry3::new(
                Vector3::new(0.04 * i as f64, -0.01 * i as f64, 0.02),
                Vector3::new(0.02 * i as f64, 0.05 * i as f64, 0.0),
            );
            (
                DepthImage::from_vec(k.width, k.height, d).unwrap(),
                CameraToWorld::from_isometry(pose),
            )
        })
        .collect();
    let fuse = |isa: sl_core::Isa| {
        let mut vol = TsdfVolume::new(TsdfConfig {
            voxel_m: 0.01,
            isa,
            ..TsdfConfig::default()
        })
        .unwrap();
        for (d, pose) in &frames {
            vol.integrate(d, &k, pose).unwrap();
        }
        let mut out: Vec<(u64, Vec<u32>)> = vol
            .keys
            .iter()
            .zip(&vol.blocks)
            .map(|(&key, b)| {
                let bits = b
                    .tsdf
                    .iter()
                    .chain(&b.weight)
                    .map(|v| v.to_bits())
                    .collect();
                (key, bits)
            })
            .collect();
        out.sort();
        out
    };
    let base = fuse(sl_core::Isa::Portable);
    assert!(base.len() > 500, "{} blocks", base.len());
    for isa in sl_core::Isa::ALL.into_iter().filter(|i| i.is_supported()) {
        assert!(fuse(isa) == base, "{isa}: the volume differs");
    }
}

#[test]
fn the_band_sensor_changes_only_before_the_first_frame() {
    // A sensor twice as noisy widens the sensor-adaptive band by two at a depth where the
    // band is neither the floor nor the cap; a fixed band stays; after a frame it is an error.
    let mut vol = TsdfVolume::new(TsdfConfig::default()).unwrap();
    let before = vol.params().band_at(3.0);
    let mut noisier = SensorModel::kinect_v1();
    noisier.sigma_d_px *= 2.0;
    vol.set_band_sensor(noisier).unwrap();
    let after = vol.params().band_at(3.0);
    assert!((after / before - 2.0).abs() < 1e-6, "{before} {after}");
    let mut fixed = TsdfVolume::new(TsdfConfig {
        truncation: Truncation::Fixed,
        ..TsdfConfig::default()
    })
    .unwrap();
    fixed.set_band_sensor(noisier).unwrap();
    assert_eq!(fixed.params().truncation, Truncation::Fixed);
    let k = Intrinsics::new(160, 120, 145.0, 145.0, 79.5, 59.5).unwrap();
    let depth = DepthImage::from_vec(k.width, k.height, vec![1.2; k.pixel_count()]).unwrap();
    vol.integrate(&depth, &k, &CameraToWorld::identity())
        .unwrap();
    assert!(matches!(
        vol.set_band_sensor(SensorModel::kinect_v1()),
        Err(TsdfError::InvalidParameter(_))
    ));
    assert_eq!(vol.params().band_at(3.0), after);
}
