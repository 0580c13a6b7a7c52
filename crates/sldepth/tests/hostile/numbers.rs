//! Numbers: meaningless values refused with their range, absurd ones printed compactly.

use super::*;

#[test]
fn meaningless_numbers_are_refused_with_their_range() {
    let input = testdata("floor-seed1-depth.png");
    // Outputs in a directory that exists (one that does not is refused first), never written:
    // every command below stops at its meaningless number.
    let dir = tempfile::tempdir().unwrap();
    let out = |name: &str| dir.path().join(name).to_string_lossy().into_owned();
    let (l_png, x_png, f_png) = (out("l.png"), out("x.png"), out("f.png"));
    for (args, needles) in [
        (
            vec!["info", s(&input), "--depth-scale", "1e-300"],
            vec!["--depth-scale", "must be between 1 and 1e6"],
        ),
        (
            vec!["info", s(&input), "--depth-scale", "inf"],
            vec!["--depth-scale"],
        ),
        (
            vec!["planes", s(&input), "-o", &l_png, "--threshold-px", "NaN"],
            vec!["--threshold-px", "must be a number from"],
        ),
        (
            vec!["motion", s(&input), s(&input), "--threshold-px=-3"],
            vec!["--threshold-px"],
        ),
        (
            vec![
                "simulate",
                "--scene",
                "floor",
                "-o",
                &x_png,
                "--depth-scale",
                "NaN",
            ],
            vec!["--depth-scale"],
        ),
        (
            vec!["filter", s(&input), &f_png, "--repeat", "1000000000"],
            vec!["--repeat"],
        ),
        (
            vec!["--max-memory", "lots", "cameras"],
            vec!["--max-memory"],
        ),
    ] {
        let o = run(&args);
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert!(!stderr.contains("panicked"), "{stderr}");
        assert!(
            std::fs::read_dir(dir.path()).unwrap().next().is_none(),
            "{args:?} wrote an output"
        );
        assert!(
            matches!(o.status.code(), Some(1) | Some(2)),
            "{args:?}: {:?} {stderr}",
            o.status
        );
        for n in needles {
            assert!(stderr.contains(n), "{args:?}: expected {n:?} in {stderr}");
        }
    }
}

/// A number far out of range is printed as it was meant, `1e300` (or `-1e300`, `1e-300`), not as
/// a 301-digit decimal, in every range error of the command line; the valid range alike.
#[test]
fn absurd_numbers_are_printed_compactly_in_range_errors() {
    let input = testdata("floor-seed1-depth.png");
    let dir = tempfile::tempdir().unwrap();
    let out = |name: &str| dir.path().join(name).to_string_lossy().into_owned();
    let (l_png, x_png, m_ply) = (out("l.png"), out("x.png"), out("m.ply"));
    let missing = dir.path().join("no-such-sequence");
    let simulate = |extra: &[&'static str]| {
        let mut v = vec!["simulate", "--scene", "floor", "-o", x_png.as_str()];
        v.extend_from_slice(extra);
        v
    };
    for (args, needles) in [
        (
            vec!["info", s(&input), "--depth-scale", "1e300"],
            vec!["--depth-scale 1e300: must be between 1 and 1e6"],
        ),
        (
            vec!["planes", s(&input), "-o", &l_png, "--threshold-px", "1e300"],
            vec!["--threshold-px 1e300: must be a number from 1e-6 to 1000"],
        ),
        (
            vec!["motion", s(&input), s(&input), "--threshold-px", "1e-300"],
            vec!["--threshold-px 1e-300: must be a number from 1e-6 to 1000"],
        ),
        (
            vec![
                "fuse",
                "--7scenes",
                s(&missing),
                "-o",
                &m_ply,
                "--slice-m=-1e300",
            ],
            vec!["--slice-m -1e300: must be a number from -1e6 to 1e6"],
        ),
        (
            vec![
                "fuse",
                "--7scenes",
                s(&missing),
                "-o",
                &m_ply,
                "--voxel-m",
                "1e300",
            ],
            vec!["--voxel-m 1e300: must be a number from 0.0001 to 1"],
        ),
        (
            vec![
                "fuse",
                "--7scenes",
                s(&missing),
                "-o",
                &m_ply,
                "--trunc-m",
                "1e300",
            ],
            vec!["--trunc-m 1e300: must be a number from 0.0001 to 10"],
        ),
        (
            vec!["track", "--7scenes", s(&missing), "--model-scale", "1e300"],
            vec!["--model-scale 1e300: must be a number from 0.001 to 1"],
        ),
        (
            vec!["track", "--7scenes", s(&missing), "--voxel-m", "1e-300"],
            vec!["--voxel-m 1e-300: must be a number from 0.0001 to 1"],
        ),
        (
            simulate(&["--sigma-d-px", "1e300"]),
            vec!["--sigma-d-px 1e300: must be a number from 0 to 100"],
        ),
        (
            simulate(&["--min-return=-1e300"]),
            vec!["--min-return -1e300: must be a finite number >= 0"],
        ),
        (
            simulate(&["--min-return", "0.04", "--reflectance", "1=1e300"]),
            vec![
                "--reflectance 1=1e300",
                "reflectance 1e300 of surface 1 must be in [0, 1]",
            ],
        ),
    ] {
        let o = run(&args);
        assert_typed_error(&o, &needles);
        let stderr = String::from_utf8_lossy(&o.stderr);
        let longest_digits = stderr
            .split(|c: char| !c.is_ascii_digit())
            .map(str::len)
            .max()
            .unwrap_or(0);
        assert!(longest_digits < 20, "{args:?}: {stderr}");
        assert!(
            std::fs::read_dir(dir.path()).unwrap().next().is_none(),
            "{args:?} wrote an output"
        );
    }
}
