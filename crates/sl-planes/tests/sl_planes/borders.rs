//! Where a plane ends: a straight border along a far crease, a wedge along the image border
//! grown to its end, a plane across a crease split along it, and seams refined on a bent
//! surface.

use super::*;

/// A crease between a floor and a wall 3–4 m away (realistic correlated noise, a 640×480
/// camera rolled and pitched so the crease is diagonal) is a straight border: each pixel goes
/// to the plane that explains it best, not to whichever plane's 16-pixel seed patch reached it
/// first (stair steps). Near the crease the two planes' disparities differ by `s·Δg` at `s` px
/// from it, so noise of `σ` swaps a pixel with probability `Φ(−s·Δg/(σ√2))`; summed over both
/// sides that is `2√2·σ/Δg·∫Φ(−u)du ≈ 1.13·σ/Δg` wrong pixels per column. A border that stays
/// where the patches met is wrong by up to 16 px.
#[test]
fn a_far_crease_is_a_straight_border() {
    let cam = Camera {
        intrinsics: Intrinsics::new(640, 480, 570.0, 570.0, 319.5, 239.5).unwrap(),
        sensor: SensorModel::kinect_v1(),
    };
    let k = cam.intrinsics;
    let rot = sl_core::nalgebra::Rotation3::from_euler_angles(
        15f64.to_radians(),
        0.0,
        10f64.to_radians(),
    );
    let floor = Plane::new(rot * Vector3::new(0.0, 1.0, 0.0), -1.3)
        .unwrap()
        .facing_origin();
    let (s, c) = 25f64.to_radians().sin_cos();
    let wall = Plane::new(rot * Vector3::new(s, 0.0, c), -3.5)
        .unwrap()
        .facing_origin();
    let (truth, gt) = render(&k, &[floor, wall], 8.0);
    let depth = KinectSimulator::with_sensor(cam.sensor).apply(&truth, 5);
    let seg = PlaneExtractor::new(PlaneConfig::default())
        .unwrap()
        .extract_depth(&depth, &cam)
        .unwrap();
    // The extracted plane of each true plane: the one with the most of its pixels.
    let (w, h) = (k.width, k.height);
    let mut count = std::collections::HashMap::<(u16, u16), usize>::new();
    for (&g, &l) in gt.data().iter().zip(seg.labels.data()) {
        if g != 0 && l != 0 {
            *count.entry((g, l)).or_default() += 1;
        }
    }
    let of = |g: u16| {
        count
            .iter()
            .filter(|((gg, _), _)| *gg == g)
            .max_by_key(|(_, n)| **n)
            .map(|((_, l), _)| *l)
            .unwrap()
    };
    let (lf, lw) = (of(1), of(2));
    assert_ne!(lf, lw);
    // Per column with the crease in view: wrong-plane pixels, and the disparity bend Δg.
    let fb = cam.sensor.fb();
    let disp = |p: &Plane, x: usize, y: usize| fb / p.depth_at(&k, x as f64, y as f64).unwrap();
    let (mut wrong, mut cols, mut dg) = (0usize, 0usize, 0.0);
    for x in 0..w {
        let Some(yc) = (1..h).find(|&y| gt.data()[y * w + x] != gt.data()[(y - 1) * w + x]) else {
            continue;
        };
        cols += 1;
        dg += ((disp(&floor, x, yc + 1) - disp(&floor, x, yc))
            - (disp(&wall, x, yc + 1) - disp(&wall, x, yc)))
        .abs();
        for y in 0..h {
            let (g, l) = (gt.data()[y * w + x], seg.labels.data()[y * w + x]);
            wrong += usize::from((g == 1 && l == lw) || (g == 2 && l == lf));
        }
    }
    assert!(cols > 300, "crease in {cols} columns");
    let dg = dg / cols as f64;
    let s = cam.sensor;
    let sigma = (s.sigma_d_px.powi(2) + 1.0 / (12.0 * f64::from(s.subpixel_steps).powi(2))).sqrt();
    let expected = 1.13 * sigma / dg;
    let per_col = wrong as f64 / cols as f64;
    // Half again the expectation: the correlated noise swaps pixels in runs (its 9-pixel
    // window leaves about 70 independent draws along the crease). Borders left where the seed
    // patches met gave 3.1 wrong pixels per column here (twice the expectation).
    assert!(
        per_col <= 1.5 * expected,
        "{per_col:.2} wrong pixels per column, expected {expected:.2} (Δg {dg:.4} px/px)"
    );
}

/// Room 130 of the examined seeds: a box face seen edge-on along the image border, a wedge
/// 4–20 pixels wide and 230 rows tall whose noisy cells mostly fail the LoG. The coarse passes
/// reach one cell further per pass, so the face's plane used to stop about 16 rows above its
/// seed (2,315 of its 3,557 valid pixels, 65 %: neither correct nor missed in SegComp, a
/// spurious plane). The growth over the cells the plane's fit explains within the noise
/// (`PlaneExtractor`'s cell growth) now takes the whole wedge, and no other surface.
#[test]
fn a_wedge_along_the_border_is_grown_to_its_end() {
    let (frame, seg) = extract_room(130);
    // Every surface with at least 2,000 valid pixels is covered at ≥ 95 % by its best plane,
    // which lies at ≥ 95 % on it.
    let valid = |i: usize| frame.depth.data()[i] > 0.0;
    let mut sizes = std::collections::HashMap::<u16, usize>::new();
    for (i, &t) in frame.labels.data().iter().enumerate() {
        if t != 0 && valid(i) {
            *sizes.entry(t).or_default() += 1;
        }
    }
    for (&t, &n) in sizes.iter().filter(|&(_, &n)| n >= 2000) {
        let best = seg
            .planes
            .iter()
            .map(|p| {
                let on = seg
                    .labels
                    .data()
                    .iter()
                    .zip(frame.labels.data())
                    .filter(|&(&l, &g)| l == p.id && g == t)
                    .count();
                (on, p.pixels)
            })
            .max_by_key(|&(on, _)| on)
            .unwrap();
        assert!(
            best.0 * 100 >= n * 95 && best.0 * 100 >= best.1 * 95,
            "surface {t} ({n} px): best plane has {} of its pixels, {} in all",
            best.0,
            best.1
        );
    }
}

/// A plane across a crease is split along it (the `crease` stage): in room 266 of the examined
/// seeds two faces of a box 3.8 m away, meeting at an edge, came out as one 4,525-pixel plane
/// (2,854 px on one face, 1,666 on the other, RMS 0.23 px: a fold, not noise). Its residual is
/// curved beyond what the distortion and the noise allow and two affine pieces meeting along a
/// line fit it better than any quadratic, so it is split where the pieces' fits intersect.
#[test]
fn a_plane_across_a_crease_is_split_along_it() {
    let mut no_split = PlaneConfig::default();
    no_split.split_creases = false;
    let (frame, before) = extract_room_with(266, None, 0.0, &no_split);
    let majority_before = majority_surfaces(&frame, &before);
    assert!(
        majority_before.iter().any(|m| !m.1),
        "without the split a plane spans two surfaces: {majority_before:?}"
    );
    let (frame, after) = extract_room_with(266, None, 0.0, &PlaneConfig::default());
    let majority = majority_surfaces(&frame, &after);
    assert!(
        majority.iter().all(|m| m.1),
        "a plane spans surfaces: {majority:?}"
    );
    assert!(
        !two_planes_on_one_surface(&majority),
        "two planes on one surface: {majority:?}"
    );
    // The pixel counts are exact after the split.
    for p in &after.planes {
        let n = after.labels.data().iter().filter(|&&l| l == p.id).count();
        assert_eq!(n, p.pixels, "plane {}", p.id);
    }
}

/// Share of the pixels of the smallest plane of `seg` that lie on the surface most of them
/// lie on.
fn smallest_plane_purity(
    frame: &sl_noise::sim::SimulatedFrame,
    seg: &sl_planes::PlaneSegmentation,
) -> f64 {
    let p = seg.planes.iter().min_by_key(|p| p.pixels).unwrap();
    let mut counts = std::collections::HashMap::<u16, usize>::new();
    for (&l, &t) in seg.labels.data().iter().zip(frame.labels.data()) {
        if l == p.id {
            *counts.entry(t).or_default() += 1;
        }
    }
    let top = counts.values().copied().max().unwrap_or(0);
    top as f64 / p.pixels as f64
}

/// The seam stage (`PlaneConfig::refine_seams`). Room 270 is a wall filling the view with a
/// sliver of ceiling in the top-left corner. With a 0.5 px radial distortion the wall's whole
/// fit is about 0.3 px off in that corner, the sliver's own fit is not, and the border between
/// them falls about 5 pixels inside the wall: 463 of the sliver's 2,183 pixels are wall (79 %
/// pure, below the benchmark's 80 %, so it counts as spurious). Re-decided with the two
/// planes' fits in strips beside the border, the strip goes back to the wall. Without the
/// distortion the stage finds no whole fit off and changes no pixel.
#[test]
fn refined_seams_give_a_bent_surface_its_border_back() {
    let mut on = PlaneConfig::default();
    on.refine_seams = true;
    let off = PlaneConfig::default();
    let (frame, seg_off) = extract_room_with(270, None, 0.5, &off);
    let (_, seg_on) = extract_room_with(270, None, 0.5, &on);
    assert_eq!(seg_off.planes.len(), 2);
    assert_eq!(seg_on.planes.len(), 2);
    let (p_off, p_on) = (
        smallest_plane_purity(&frame, &seg_off),
        smallest_plane_purity(&frame, &seg_on),
    );
    assert!(
        p_off < 0.8,
        "without the stage the sliver is {p_off:.3} pure"
    );
    assert!(p_on > 0.95, "with the stage the sliver is {p_on:.3} pure");
    // No distortion: identical segmentations.
    let (_, plain_off) = extract_room_with(270, None, 0.0, &off);
    let (_, plain_on) = extract_room_with(270, None, 0.0, &on);
    assert_eq!(plain_off.labels.data(), plain_on.labels.data());
}
