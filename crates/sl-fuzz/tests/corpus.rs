//! Replays the committed seed corpus and every libFuzzer finding kept in `fuzz/corpus/<target>/`
//! through the target bodies, on the stable toolchain: a regression there fails `cargo test`.

use std::path::PathBuf;

fn corpus_root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../fuzz/corpus")
}

#[test]
fn every_target_has_a_corpus_and_replays_it_without_panicking() {
    let root = corpus_root();
    let mut total = 0;
    for (name, target) in sl_fuzz::TARGETS {
        let dir = root.join(name);
        let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
            .unwrap_or_else(|e| {
                panic!(
                    "{}: {e} (run `cargo run -p sl-fuzz --example gen_corpus`)",
                    dir.display()
                )
            })
            .map(|e| e.map(|e| e.path()))
            .collect::<Result<_, _>>()
            .unwrap_or_else(|e| panic!("{}: {e}", dir.display()));
        files.sort();
        assert!(!files.is_empty(), "{}: empty corpus", dir.display());
        for f in &files {
            let data = std::fs::read(f).unwrap_or_else(|e| panic!("{}: {e}", f.display()));
            target(&data);
        }
        total += files.len();
    }
    assert!(total >= sl_fuzz::TARGETS.len());
}

#[test]
fn fuzz_crate_has_one_target_file_per_target() {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../fuzz/fuzz_targets");
    for (name, _) in sl_fuzz::TARGETS {
        let f = dir.join(format!("{name}.rs"));
        let text = std::fs::read_to_string(&f).unwrap_or_else(|e| panic!("{}: {e}", f.display()));
        assert!(
            text.contains(&format!("sl_fuzz::{name}(")),
            "{} does not call sl_fuzz::{name}",
            f.display()
        );
    }
}

#[test]
fn the_tracking_seeds_reach_the_tracker() {
    use sl_track::TrackStatus;
    let read = |name: &str| std::fs::read(corpus_root().join("track").join(name)).unwrap();
    // Three faces in a corner, enlarged 8 times: the first frame starts the map, the next are
    // tracked (against the model or, within the fuzz target's small volume budget, the frame).
    for name in ["still-corner", "moving-corner", "moving-corner-f2f-rs"] {
        let steps = sl_fuzz::track_steps(&read(name));
        assert!(steps.len() >= 3, "{name}: {steps:?}");
        assert_eq!(
            steps[0],
            Some(TrackStatus::Initialised),
            "{name}: {steps:?}"
        );
        assert!(
            steps[1..].iter().all(|s| matches!(
                s,
                Some(TrackStatus::Tracked | TrackStatus::TrackedAgainstFrame)
            )),
            "{name}: {steps:?}"
        );
    }
    // A single plane cannot start a map.
    let steps = sl_fuzz::track_steps(&read("still-floor"));
    assert!(
        steps.iter().all(|s| *s == Some(TrackStatus::Lost)),
        "{steps:?}"
    );
}
