//! Outputs: links, FIFOs, directories and inputs never replaced; the extension decides the
//! format; nothing written on a failing argument; temporary files removed after kills and
//! signals; a closed or full standard error.

use super::*;

#[cfg(unix)]
#[test]
fn outputs_never_replace_links_fifos_or_directories() {
    let dir = tempfile::tempdir().unwrap();
    let input = testdata("floor-seed1-depth.png");
    let target = dir.path().join("target.png");
    std::fs::write(&target, b"keep").unwrap();
    let link = dir.path().join("link.png");
    std::os::unix::fs::symlink(&target, &link).unwrap();
    let sub = dir.path().join("sub.png");
    std::fs::create_dir(&sub).unwrap();
    let fifo = dir.path().join("fifo.png");
    let have_fifo = Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .is_ok_and(|s| s.success());
    let mut outs = vec![(link.clone(), "symbolic link"), (sub.clone(), "directory")];
    if have_fifo {
        outs.push((fifo.clone(), "FIFO"));
    }
    for (out, what) in &outs {
        let o = run(&["filter", s(&input), s(out)]);
        assert_typed_error(&o, &["refusing to write", what]);
        let o = run(&["planes", s(&input), "-o", s(out)]);
        assert_typed_error(&o, &["refusing to write", what]);
    }
    assert!(
        std::fs::symlink_metadata(&link)
            .unwrap()
            .file_type()
            .is_symlink()
    );
    assert_eq!(std::fs::read(&target).unwrap(), b"keep");
    assert!(sub.is_dir());
    if have_fifo {
        use std::os::unix::fs::FileTypeExt;
        assert!(
            std::fs::symlink_metadata(&fifo)
                .unwrap()
                .file_type()
                .is_fifo()
        );
    }
    // No temporary file is left behind either.
    let left: Vec<String> = entries(dir.path())
        .into_iter()
        .filter(|n| n.contains("sldepth-tmp"))
        .collect();
    assert!(left.is_empty(), "{left:?}");
}

#[test]
fn the_output_extension_decides_the_format_and_an_unknown_one_does_no_work() {
    let dir = tempfile::tempdir().unwrap();
    let input = testdata("floor-seed1-depth.png");
    let tif = dir.path().join("out.tif");
    let o = run(&["filter", s(&input), s(&tif)]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let bytes = std::fs::read(&tif).unwrap();
    assert!(
        bytes.starts_with(b"II*\0") || bytes.starts_with(b"MM\0*"),
        "not a TIFF: {:?}",
        &bytes[..8.min(bytes.len())]
    );
    // It reads back as TIFF with the input's scale, and matches the PNG output.
    let png = dir.path().join("out.png");
    assert!(run(&["filter", s(&input), s(&png)]).status.success());
    let a = sl_io::read_depth(&tif, &sl_io::ReadConfig::default()).unwrap();
    let b = sl_io::read_depth(&png, &sl_io::ReadConfig::default()).unwrap();
    assert_eq!(a.depth, b.depth);
    for (cmd, out) in [
        (vec!["filter", s(&input)], dir.path().join("out.jpg")),
        (vec!["cloud", s(&input), "-o"], dir.path().join("cloud.xyz")),
        (vec!["planes", s(&input), "-o"], dir.path().join("labels")),
        (
            vec!["simulate", "--scene", "floor", "-o"],
            dir.path().join("sim.exr"),
        ),
    ] {
        let mut args = cmd.clone();
        args.push(s(&out));
        let o = run(&args);
        assert_typed_error(&o, &["unknown output format"]);
        assert!(!out.exists());
    }
}

#[test]
fn a_failing_argument_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let (list, cam) = small_sequence(dir.path());
    let mesh = dir.path().join("m.ply");
    for (opt, value) in [
        ("--slice-m", "NaN"),
        ("--min-weight", "NaN"),
        ("--min-weight", "-1"),
        ("--depth-scale", "1e-300"),
    ] {
        let opt_value = format!("{opt}={value}");
        let o = run(&[
            "fuse",
            "--frames",
            s(&list),
            "--camera",
            s(&cam),
            "-o",
            s(&mesh),
            "--slice-png",
            s(&dir.path().join("slice.png")),
            &opt_value,
        ]);
        assert_typed_error(&o, &[opt, "must be"]);
        assert!(!mesh.exists(), "{opt} {value}: the mesh was written");
    }
    // A planes overlay whose colour image is missing: the label image is not written either.
    let labels = dir.path().join("labels.png");
    let o = run(&[
        "planes",
        s(&testdata("floor-seed1-depth.png")),
        "-o",
        s(&labels),
        "--overlay",
        s(&dir.path().join("ov.png")),
        "--color",
        s(&dir.path().join("missing.png")),
    ]);
    assert_typed_error(&o, &["missing.png"]);
    assert!(!labels.exists());
    // Two outputs naming one file (however spelled): refused before anything is written.
    let sub = dir.path().join("sub");
    std::fs::create_dir(&sub).unwrap();
    let depth = sub.join("d.png");
    let same = dir.path().join("sub/../sub/d.png");
    let o = run(&[
        "simulate",
        "--scene",
        "floor",
        "-o",
        s(&depth),
        "--truth",
        s(&same),
    ]);
    assert_typed_error(&o, &["--output and --truth both name"]);
    assert!(!depth.exists());
    let o = run(&[
        "filter",
        s(&testdata("floor-seed1-depth.png")),
        s(&depth),
        "--normals",
        s(&depth),
    ]);
    assert_typed_error(&o, &["OUT and --normals both name"]);
    assert!(!depth.exists());
}

#[test]
fn stale_temporary_files_of_killed_runs_are_removed_by_the_next_write() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("cloud.ply");
    // Left by a process that no longer runs (no PID can be 4294967295).
    let stale = dir.path().join(".cloud.ply.sldepth-tmp.4294967295.3");
    std::fs::write(&stale, vec![0u8; 4096]).unwrap();
    let o = run(&[
        "cloud",
        s(&testdata("floor-seed1-depth.png")),
        "-o",
        s(&out),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(!stale.exists());
    assert_eq!(entries(dir.path()), vec!["cloud.ply"]);
}

#[cfg(unix)]
#[test]
fn sigterm_and_sigint_during_a_write_remove_the_temporary_file() {
    let dir = tempfile::tempdir().unwrap();
    // A 2048x1536 frame: its ASCII cloud takes long enough to write to catch it mid-way.
    let (w, h) = (2048usize, 1536usize);
    let depth = sl_core::DepthImage::from_vec(w, h, vec![1.25; w * h]).unwrap();
    let png = dir.path().join("big.png");
    sl_io::write_depth(&png, &depth, &sl_io::DepthEncoding::default()).unwrap();
    let cam = camera_json(dir.path(), w as u64, h as u64, 1500.0);
    // Any entry beyond these is a temporary file, whatever its naming scheme.
    let before = entries(dir.path());
    let extra = |dir: &Path| -> Vec<String> {
        entries(dir)
            .into_iter()
            .filter(|n| !before.contains(n) && n != "cloud.ply")
            .collect()
    };
    let mut interrupted = 0;
    for signal in ["TERM", "INT"] {
        let out = dir.path().join("cloud.ply");
        let mut child = Command::new(bin())
            .args([
                "cloud",
                s(&png),
                "--camera",
                s(&cam),
                "--ascii",
                "-o",
                s(&out),
            ])
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        // Wait for the temporary file to appear, then interrupt.
        let start = std::time::Instant::now();
        let mut seen = false;
        while start.elapsed().as_secs() < 60 {
            if !extra(dir.path()).is_empty() {
                seen = true;
                break;
            }
            if child.try_wait().unwrap().is_some() {
                break;
            }
            std::thread::sleep(std::time::Duration::from_millis(2));
        }
        if !seen {
            let _ = child.kill();
            let _ = child.wait();
            eprintln!("skipping SIG{signal}: the write finished before it could be interrupted");
            let _ = std::fs::remove_file(&out);
            continue;
        }
        let killed = Command::new("kill")
            .args([format!("-{signal}"), child.id().to_string()])
            .status()
            .unwrap();
        assert!(killed.success());
        let status = child.wait().unwrap();
        let left = extra(dir.path());
        if status.success() {
            // The write won the race; the temp was renamed into place.
            let _ = std::fs::remove_file(&out);
        } else {
            let code = if signal == "TERM" { 143 } else { 130 };
            assert_eq!(status.code(), Some(code), "SIG{signal}: {status:?}");
            assert!(!out.exists(), "SIG{signal}: a partial destination");
        }
        assert!(left.is_empty(), "SIG{signal} left {left:?}");
        interrupted += 1;
    }
    if interrupted == 0 {
        eprintln!("note: no write could be interrupted on this machine; nothing was checked");
    }
}

#[test]
fn a_closed_or_full_stderr_is_not_a_panic() {
    // Closed stderr: the error cannot be told, but the exit code still says it failed.
    let mut child = Command::new(bin())
        .args(["info", "/nonexistent/depth.png"])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stderr.take());
    let status = child.wait().unwrap();
    assert_eq!(status.code(), Some(1), "{status:?}");
    let Ok(full) = std::fs::OpenOptions::new().write(true).open("/dev/full") else {
        eprintln!("skipping the full-stderr case: no /dev/full on this system");
        return;
    };
    // Full stderr, on an error and on a success that reports to stderr.
    let o = Command::new(bin())
        .args(["info", "/nonexistent/depth.png"])
        .stderr(full.try_clone().unwrap())
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(1), "{:?}", o.status);
    let dir = tempfile::tempdir().unwrap();
    let o = Command::new(bin())
        .args([
            "cloud",
            s(&testdata("floor-seed1-depth.png")),
            "-o",
            s(&dir.path().join("c.ply")),
        ])
        .stderr(full)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(0), "{:?}", o.status);
}

/// An output that is the input under its own name or a hard link is refused, and the input
/// stays as it was (written atomically, it was replaced).
#[test]
fn an_output_that_is_an_input_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("in.png");
    std::fs::copy(testdata("floor-seed1-depth.png"), &input).unwrap();
    let before = std::fs::read(&input).unwrap();
    let link = dir.path().join("link.png");
    std::fs::hard_link(&input, &link).unwrap();
    for out in [&input, &link] {
        let o = run(&["filter", s(&input), s(out)]);
        assert_typed_error(&o, &["is an input of this command"]);
    }
    let o = run(&["planes", s(&input), "-o", s(&link)]);
    assert_typed_error(&o, &["is an input of this command"]);
    assert_eq!(std::fs::read(&input).unwrap(), before);
}
