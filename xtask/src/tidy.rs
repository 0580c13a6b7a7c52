//! The architecture invariants of `docs/ARCHITECTURE.md`, checked over the source tree by
//! `cargo test` (the `tidy` tests below) and by `cargo xtask tidy`.
//!
//! Each rule is a function from a tree (the workspace root, or a temporary tree in the tests)
//! to the list of its violations, each naming the file and line:
//! 1. [`fs_or_print_in_libraries`]: a library crate other than `sl-io` uses `std::fs` or prints;
//! 2. [`unsafe_outside_dispatch`]: `unsafe` outside sl-filter's runtime ISA dispatch
//!    (`crates/sl-filter/src/kernel.rs`);
//! 3. [`missing_module_docs`]: a Rust source file that does not open with a `//!` line;
//! 4. [`missing_readmes`]: a crate without a `README.md`;
//! 5. [`stale_doc_names`]: `docs/ARCHITECTURE.md`, a crate README or a crate's `lib.rs` docs
//!    name (in backticks) a type or function that appears nowhere in the workspace's Rust
//!    sources, or a Markdown file that does not exist;
//! 6. [`generator_markers`]: a leftover generator marker comment (`// @name-list …`);
//! 7. [`thread_locals`]: a `thread_local!` outside the files listed in `THREAD_LOCAL_FILES`;
//! 8. [`python_lock_sites`]: a lock taken (`.lock()`, `.read()`, `.write()`, their `try_`
//!    forms) in sl-py outside the files listed in `PY_LOCK_FILES`;
//! 9. [`long_source_files`]: a Rust source file whose code (the lines before an inline test
//!    module) runs past `MAX_CODE_LINES`.
//!
//! The tests also plant one violation of each rule in a temporary tree and check that the rule
//! reports it.

use std::collections::HashSet;
use std::fs;
use std::path::{Path, PathBuf};

/// Library crates that may use `std::fs` and print: sl-io (all file I/O goes through it), the
/// dev-only sl-testkit (finds the shared data, says why a test skips) and the unpublished
/// evaluation support sl-eval (for xtask and the CLI, like the binaries). Binaries (`sldepth`,
/// `xtask`) are not library crates.
const IO_CRATES: &[&str] = &["sl-io", "sl-testkit", "sl-eval", "sl-fuzz"];
/// Binary crates: exempt from the library rules.
const BINARY_CRATES: &[&str] = &["sldepth"];
/// Files allowed to declare a `thread_local!`, each with why no borrow of it spans rayon work:
/// sl-filter's kernel borrows its scratch for one block of rows, which calls no parallel code;
/// sl-filter's multi-scale filter moves its buffers out of the cell before its parallel passes
/// and back after them (a call nested on the same worker meanwhile finds the cell empty);
/// sl-fuzz keeps a per-thread scratch directory, borrowed only to read or set its path; sl-py
/// keeps each Python thread's one-thread pool, borrowed only to build it or clone its handle.
const THREAD_LOCAL_FILES: &[&str] = &[
    "crates/sl-filter/src/kernel.rs",
    "crates/sl-filter/src/multiscale.rs",
    "crates/sl-fuzz/src/lib.rs",
    "crates/sl-py/src/threads.rs",
];
/// sl-py files allowed to take a lock, each reviewed for where it takes it: `threads.rs` holds
/// the helpers that take a `TsdfVolume`'s or `Tracker`'s lock on the calling thread before the
/// call enters a pool (`compute_locked`, `compute_read`, `compute_write`) and the lock of the
/// chosen thread count; `planes.rs` holds its extractor cache's lock only to take an extractor
/// out and put it back, never across an extraction; `track.rs` reads a tracker's state on the
/// calling thread, outside any pool. A lock taken inside a pool can deadlock: a worker that
/// waits for its parallel pieces runs other queued jobs meanwhile, and one of another Python
/// thread's calls would wait for a lock the worker's own thread holds (session 69).
const PY_LOCK_FILES: &[&str] = &[
    "crates/sl-py/src/threads.rs",
    "crates/sl-py/src/planes.rs",
    "crates/sl-py/src/track.rs",
];
/// The lock calls [`python_lock_sites`] looks for.
const LOCK_CALLS: &[&str] = &[
    ".lock()",
    ".read()",
    ".write()",
    ".try_lock()",
    ".try_read()",
    ".try_write()",
];
/// The most lines of code a source file may hold before its inline test module (rule 9): a
/// file longer than this has more than one job, and is split by role into a folder module
/// (as sl-noise's `stats`, sl-io's `trajectory`, sl-track's `track`). Test files count too:
/// a long test file is split by what it tests.
const MAX_CODE_LINES: usize = 1000;
/// The one file allowed to contain `unsafe`: sl-filter's ISA dispatch.
const UNSAFE_FILE: &str = "crates/sl-filter/src/kernel.rs";

/// Names from outside the workspace that the docs may mention in backticks.
const EXTERNAL_NAMES: &[&str] = &[
    "Isometry3",
    "Point3",
    "Vector3",
    "Matrix3",
    "Matrix4",
    "UnitQuaternion",
    "Rotation3",
    "ThreadPool",
    "PinholeCameraIntrinsic",
    "ScalableTSDFVolume",
    "VoxelBlockGrid",
    "Result",
    "Option",
    "Vec",
    "String",
    "Default",
    "FromStr",
    "Display",
    "ValueEnum",
    "PathBuf",
    "Limits",
    "BufRead",
    "Read",
    "Write",
    "NaN",
    "README",
    "PyO3",
    "NumPy",
    "GIL",
    "ValueError",
    "OSError",
];

/// One finding: where and what.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Violation {
    /// The file, relative to the tree's root.
    pub file: PathBuf,
    /// 1-based line (0 when the finding is about the file as a whole).
    pub line: usize,
    /// What is wrong.
    pub message: String,
}

impl std::fmt::Display for Violation {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}:{}: {}", self.file.display(), self.line, self.message)
    }
}

/// Every rule over the tree at `root`.
pub fn check_all(root: &Path) -> Vec<Violation> {
    let mut v = fs_or_print_in_libraries(root);
    v.extend(unsafe_outside_dispatch(root));
    v.extend(missing_module_docs(root));
    v.extend(missing_readmes(root));
    v.extend(stale_doc_names(root));
    v.extend(generator_markers(root));
    v.extend(thread_locals(root));
    v.extend(python_lock_sites(root));
    v.extend(long_source_files(root));
    v
}

/// Rule 9: no Rust source file of the crates or xtask (their `src`, `tests`, `benches` and
/// `examples`) holds more than [`MAX_CODE_LINES`] lines before its first top-level
/// `#[cfg(test)]`.
pub fn long_source_files(root: &Path) -> Vec<Violation> {
    let mut files = Vec::new();
    for dir in crate_dirs(root) {
        rust_files(&dir, &mut files);
    }
    rust_files(&root.join("xtask"), &mut files);
    files
        .into_iter()
        .filter_map(|f| {
            let text = fs::read_to_string(&f).unwrap_or_default();
            let n = code_lines(&text).len();
            (n > MAX_CODE_LINES).then(|| Violation {
                file: rel(root, &f),
                line: MAX_CODE_LINES + 1,
                message: format!(
                    "{n} lines of code before any test module, more than {MAX_CODE_LINES}: split \
                     the file by role (see tidy rule 9)"
                ),
            })
        })
        .collect()
}

/// Rule 8: sl-py takes locks only in the files of [`PY_LOCK_FILES`]. A binding that needs an
/// object's lock goes through `threads::compute_locked` (or `compute_read` / `compute_write`),
/// which take it outside the pool; the Python suite's
/// `test_threads_sharing_one_volume_and_tracker_never_deadlock` checks the behaviour, this rule
/// keeps new lock sites from appearing unreviewed. Lines of `//` comments and test modules are
/// skipped as in the other rules.
pub fn python_lock_sites(root: &Path) -> Vec<Violation> {
    let mut files = Vec::new();
    rust_files(&root.join("crates/sl-py/src"), &mut files);
    lines_outside_reviewed_files(
        root,
        files,
        PY_LOCK_FILES,
        LOCK_CALLS,
        "a lock taken in sl-py outside the reviewed files: take an object's lock through \
         threads::compute_locked / compute_read / compute_write, outside the pool (see tidy \
         rule 8)",
    )
}

/// Rule 7: no `thread_local!` in the crates outside [`THREAD_LOCAL_FILES`]. Code on a rayon
/// worker that waits for a parallel part of its own work runs other jobs meanwhile, on the same
/// thread: a per-thread cache borrowed across a call that may run parallel work is borrowed
/// again by the job that re-enters (sl-py's plane-extractor cache panicked with "already
/// borrowed" once the extractor's final pass ran on the pool).
pub fn thread_locals(root: &Path) -> Vec<Violation> {
    let mut files = Vec::new();
    for dir in crate_dirs(root) {
        rust_files(&dir, &mut files);
    }
    lines_outside_reviewed_files(
        root,
        files,
        THREAD_LOCAL_FILES,
        &["thread_local!"],
        "`thread_local!` outside the reviewed files (a borrow spanning rayon work is re-entered \
         by work-stealing; see tidy rule 7)",
    )
}

/// Every code line of `files` (outside the `reviewed` ones) that contains one of `patterns`,
/// reported with `message` (rules 7 and 8).
fn lines_outside_reviewed_files(
    root: &Path,
    files: Vec<PathBuf>,
    reviewed: &[&str],
    patterns: &[&str],
    message: &str,
) -> Vec<Violation> {
    let mut out = Vec::new();
    for f in files {
        let path = rel(root, &f);
        if reviewed.iter().any(|a| path == Path::new(a)) {
            continue;
        }
        let text = fs::read_to_string(&f).unwrap_or_default();
        for (line, code) in code_lines(&text) {
            if patterns.iter().any(|p| code.contains(p)) {
                out.push(Violation {
                    file: path.clone(),
                    line,
                    message: message.into(),
                });
            }
        }
    }
    out
}

/// `cargo xtask tidy`: prints every violation and fails if there is one.
pub fn run(root: &Path) -> anyhow::Result<()> {
    let v = check_all(root);
    for x in &v {
        println!("{x}");
    }
    anyhow::ensure!(v.is_empty(), "{} tidy violation(s)", v.len());
    println!("tidy: all rules hold");
    Ok(())
}

fn crate_dirs(root: &Path) -> Vec<PathBuf> {
    let mut dirs: Vec<PathBuf> = fs::read_dir(root.join("crates"))
        .map(|rd| {
            rd.filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| p.join("Cargo.toml").is_file())
                .collect()
        })
        .unwrap_or_default();
    dirs.sort();
    dirs
}

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(rd) = fs::read_dir(dir) else {
        return;
    };
    let mut entries: Vec<PathBuf> = rd.filter_map(|e| e.ok().map(|e| e.path())).collect();
    entries.sort();
    for p in entries {
        if p.is_dir() {
            rust_files(&p, out);
        } else if p.extension().is_some_and(|e| e == "rs") {
            out.push(p);
        }
    }
}

fn rel(root: &Path, p: &Path) -> PathBuf {
    p.strip_prefix(root).unwrap_or(p).to_path_buf()
}

/// Lines of a source file before its first top-level `#[cfg(test)]` (tests may use files and
/// print), with `//` comments removed; paired with their 1-based numbers.
fn code_lines(text: &str) -> Vec<(usize, String)> {
    text.lines()
        .enumerate()
        .take_while(|(_, l)| !l.starts_with("#[cfg(test)]"))
        .map(|(i, l)| (i + 1, l.split("//").next().unwrap_or("").to_string()))
        .collect()
}

fn has_word(line: &str, word: &str) -> bool {
    line.match_indices(word).any(|(i, _)| {
        let before = line[..i].chars().next_back();
        let after = line[i + word.len()..].chars().next();
        let ident = |c: Option<char>| c.is_some_and(|c| c.is_alphanumeric() || c == '_');
        !ident(before) && !ident(after)
    })
}

/// Rule 1: library crates (all but sl-io and the binaries) neither touch the file system nor
/// print, outside their test modules.
pub fn fs_or_print_in_libraries(root: &Path) -> Vec<Violation> {
    let mut out = Vec::new();
    for dir in crate_dirs(root) {
        let name = dir.file_name().and_then(|n| n.to_str()).unwrap_or("");
        if IO_CRATES.contains(&name) || BINARY_CRATES.contains(&name) {
            continue;
        }
        let mut files = Vec::new();
        rust_files(&dir.join("src"), &mut files);
        for f in files {
            if f.file_name()
                .is_some_and(|n| n.to_string_lossy().ends_with("tests.rs"))
            {
                continue;
            }
            let text = fs::read_to_string(&f).unwrap_or_default();
            for (n, line) in code_lines(&text) {
                let found = [
                    "std::fs",
                    "println!",
                    "eprintln!",
                    "print!",
                    "eprint!",
                    "dbg!",
                ]
                .into_iter()
                .find(|m| has_word(&line, m.trim_end_matches('!')) && line.contains(m));
                if let Some(m) = found {
                    out.push(Violation {
                        file: rel(root, &f),
                        line: n,
                        message: format!(
                            "library crate {name} uses `{m}`: only sl-io does I/O, libraries never print"
                        ),
                    });
                }
            }
        }
    }
    out
}

/// Rule 2: `unsafe` only in sl-filter's runtime ISA dispatch.
pub fn unsafe_outside_dispatch(root: &Path) -> Vec<Violation> {
    let mut files = Vec::new();
    for dir in crate_dirs(root) {
        rust_files(&dir, &mut files);
    }
    rust_files(&root.join("xtask"), &mut files);
    let mut out = Vec::new();
    for f in files {
        if rel(root, &f) == Path::new(UNSAFE_FILE) {
            continue;
        }
        let text = fs::read_to_string(&f).unwrap_or_default();
        for (i, l) in text.lines().enumerate() {
            let code = l.split("//").next().unwrap_or("");
            if has_word(code, "unsafe") && !code.contains('"') {
                out.push(Violation {
                    file: rel(root, &f),
                    line: i + 1,
                    message: format!("`unsafe` outside the documented dispatch ({UNSAFE_FILE})"),
                });
            }
        }
    }
    out
}

/// Rule 3: every source file of a crate and of xtask opens with a `//!` line.
pub fn missing_module_docs(root: &Path) -> Vec<Violation> {
    let mut files = Vec::new();
    for dir in crate_dirs(root) {
        rust_files(&dir.join("src"), &mut files);
    }
    rust_files(&root.join("xtask/src"), &mut files);
    files
        .into_iter()
        .filter(|f| {
            let text = fs::read_to_string(f).unwrap_or_default();
            !text.trim_start().starts_with("//!")
        })
        .map(|f| Violation {
            file: rel(root, &f),
            line: 1,
            message: "source file does not open with a `//!` line saying what it is for".into(),
        })
        .collect()
}

/// Rule 4: every crate has a README.md.
pub fn missing_readmes(root: &Path) -> Vec<Violation> {
    crate_dirs(root)
        .into_iter()
        .filter(|d| !d.join("README.md").is_file())
        .map(|d| Violation {
            file: rel(root, &d),
            line: 0,
            message: "crate has no README.md (what it does, an example, where it sits)".into(),
        })
        .collect()
}

/// Every identifier that appears in the code (comments and docs excluded) of the workspace's
/// Rust sources, and in the Python package and its stubs.
fn known_names(root: &Path) -> HashSet<String> {
    let mut files = Vec::new();
    for dir in crate_dirs(root) {
        rust_files(&dir, &mut files);
    }
    rust_files(&root.join("xtask"), &mut files);
    let mut names = HashSet::new();
    let mut add = |text: &str| {
        for w in text.split(|c: char| !(c.is_alphanumeric() || c == '_')) {
            if !w.is_empty() {
                names.insert(w.to_string());
            }
        }
    };
    // This file's tests plant stale names; they must not count as existing.
    files.retain(|f| !f.ends_with("xtask/src/tidy.rs"));
    for f in files {
        let text = fs::read_to_string(f).unwrap_or_default();
        for line in text.lines() {
            add(line.split("//").next().unwrap_or(""));
        }
    }
    for dir in crate_dirs(root) {
        for stub in ["python/sldepth/__init__.pyi", "python/sldepth/__init__.py"] {
            add(&fs::read_to_string(dir.join(stub)).unwrap_or_default());
        }
    }
    names.extend(EXTERNAL_NAMES.iter().map(|s| s.to_string()));
    names
}

/// The documents rule 5 reads: ARCHITECTURE.md, every crate README, and the `//!` docs of every
/// crate's lib.rs; each as (path, lines).
fn documents(root: &Path) -> Vec<(PathBuf, Vec<String>)> {
    let mut docs = Vec::new();
    let mut add = |p: PathBuf, only_doc_comments: bool| {
        if let Ok(text) = fs::read_to_string(&p) {
            let lines = text
                .lines()
                .map(|l| {
                    if only_doc_comments && !l.trim_start().starts_with("//") {
                        String::new()
                    } else {
                        l.to_string()
                    }
                })
                .collect();
            docs.push((p, lines));
        }
    };
    add(root.join("docs/ARCHITECTURE.md"), false);
    for dir in crate_dirs(root) {
        add(dir.join("README.md"), false);
        add(dir.join("src/lib.rs"), true);
    }
    docs
}

/// The name a backticked span refers to, if it looks like a Rust item: `CamelCase`,
/// `snake_case()`, or the last segment of `a::b::c` / `Type::method`.
fn item_name(span: &str) -> Option<&str> {
    let s = span.trim().trim_end_matches("()");
    if s.is_empty() || s.contains(' ') || s.contains('=') || s.contains('/') || s.contains('.') {
        return None;
    }
    let last = s.rsplit("::").next()?;
    let is_ident = last.chars().all(|c| c.is_alphanumeric() || c == '_')
        && last.chars().next().is_some_and(|c| c.is_alphabetic());
    if !is_ident {
        return None;
    }
    let camel = last.chars().next().is_some_and(char::is_uppercase)
        && last.chars().any(char::is_lowercase)
        && !last.contains('_');
    let call = span.trim().ends_with("()") || s.contains("::");
    (camel || call).then_some(last)
}

/// Rule 5: names in the docs exist in the code; Markdown files the docs cite exist.
pub fn stale_doc_names(root: &Path) -> Vec<Violation> {
    let names = known_names(root);
    let mut out = Vec::new();
    for (path, lines) in documents(root) {
        let dir = path.parent().unwrap_or(root).to_path_buf();
        let mut in_code_block = false;
        for (i, line) in lines.iter().enumerate() {
            if line
                .trim_start()
                .trim_start_matches("//!")
                .trim_start()
                .starts_with("```")
            {
                in_code_block = !in_code_block;
                continue;
            }
            if in_code_block {
                continue;
            }
            for (k, span) in line.split('`').enumerate() {
                if k % 2 == 1
                    && let Some(name) = item_name(span)
                    && !names.contains(name)
                {
                    out.push(Violation {
                        file: rel(root, &path),
                        line: i + 1,
                        message: format!("names `{span}`, which does not exist in the code"),
                    });
                }
            }
            for word in line.split(|c: char| c.is_whitespace() || "()[]`'\",;".contains(c)) {
                let word = word.trim_end_matches(['.', ':']);
                // Files under target/ are outputs the docs describe, not sources.
                if word.ends_with(".md")
                    && !word.starts_with("http")
                    && !word.starts_with("target/")
                {
                    let exists = [
                        root.join(word),
                        dir.join(word),
                        root.join("docs").join(word),
                    ]
                    .iter()
                    .any(|p| p.is_file());
                    if !exists {
                        out.push(Violation {
                            file: rel(root, &path),
                            line: i + 1,
                            message: format!("cites {word}, which does not exist"),
                        });
                    }
                }
            }
        }
    }
    out
}

/// Rule 6: no generator marker comments (`// @commands-variants …`, `# @deps …`) remain.
pub fn generator_markers(root: &Path) -> Vec<Violation> {
    let mut files = Vec::new();
    for dir in crate_dirs(root) {
        rust_files(&dir, &mut files);
        files.push(dir.join("Cargo.toml"));
    }
    rust_files(&root.join("xtask"), &mut files);
    files.push(root.join("xtask/Cargo.toml"));
    files.push(root.join("Cargo.toml"));
    let mut out = Vec::new();
    for f in files {
        let text = fs::read_to_string(&f).unwrap_or_default();
        for (i, l) in text.lines().enumerate() {
            let t = l.trim_start();
            let rest = t
                .strip_prefix("//")
                .or_else(|| t.strip_prefix('#'))
                .map(str::trim_start);
            if let Some(r) = rest
                && let Some(tag) = r.strip_prefix('@')
                && tag.chars().next().is_some_and(|c| c.is_ascii_lowercase())
                && tag
                    .split_whitespace()
                    .next()
                    .is_some_and(|w| w.chars().all(|c| c.is_ascii_lowercase() || c == '-'))
            {
                out.push(Violation {
                    file: rel(root, &f),
                    line: i + 1,
                    message: format!("generator marker left in the code: {t}"),
                });
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write(root: &Path, path: &str, text: &str) {
        let p = root.join(path);
        if let Some(d) = p.parent() {
            fs::create_dir_all(d).unwrap();
        }
        fs::write(p, text).unwrap();
    }

    /// A minimal tree that satisfies every rule.
    fn clean_tree() -> tempfile::TempDir {
        let t = tempfile::tempdir().unwrap();
        let r = t.path();
        write(r, "Cargo.toml", "[workspace]\n");
        write(r, "xtask/Cargo.toml", "[package]\nname = \"xtask\"\n");
        write(
            r,
            "xtask/src/main.rs",
            "//! Automation.\nfn main() { println!(\"ok\"); }\n",
        );
        write(
            r,
            "docs/ARCHITECTURE.md",
            "`Widget` lives in `make_widget()`; see README.md.\n",
        );
        write(r, "README.md", "# demo\n");
        for c in ["sl-demo", "sl-io", "sldepth", "sl-filter"] {
            write(r, &format!("crates/{c}/Cargo.toml"), "[package]\n");
            write(r, &format!("crates/{c}/README.md"), "# demo\n");
        }
        write(
            r,
            "crates/sl-demo/src/lib.rs",
            "//! Demo: `Widget`.\npub struct Widget;\npub fn make_widget() -> Widget { Widget }\n\
             #[cfg(test)]\nmod tests { fn t() { println!(\"tests may print\"); } }\n",
        );
        write(
            r,
            "crates/sl-io/src/lib.rs",
            "//! I/O.\npub fn r() { let _ = std::fs::read(\"x\"); }\n",
        );
        write(
            r,
            "crates/sldepth/src/main.rs",
            "//! CLI.\nfn main() { println!(\"hi\"); }\n",
        );
        write(
            r,
            "crates/sl-filter/src/kernel.rs",
            "//! Kernels.\nfn dispatch() { unsafe { f() } }\nunsafe fn f() {}\n",
        );
        write(
            r,
            "crates/sl-filter/src/lib.rs",
            "//! Filters.\nmod kernel;\n",
        );
        t
    }

    #[test]
    fn the_clean_tree_passes_every_rule() {
        let t = clean_tree();
        assert_eq!(check_all(t.path()), Vec::new());
    }

    #[test]
    fn planted_fs_and_print_in_a_library_fail() {
        let t = clean_tree();
        write(
            t.path(),
            "crates/sl-demo/src/io.rs",
            "//! Bad.\nfn f() { let _ = std::fs::read(\"x\"); }\n",
        );
        write(
            t.path(),
            "crates/sl-demo/src/log.rs",
            "//! Bad.\nfn g() { eprintln!(\"x\"); }\n",
        );
        let v = fs_or_print_in_libraries(t.path());
        assert_eq!(v.len(), 2, "{v:?}");
        assert!(v.iter().any(|x| x.file.ends_with("io.rs") && x.line == 2));
        assert!(v.iter().any(|x| x.message.contains("eprintln!")));
    }

    #[test]
    fn planted_unsafe_fails() {
        let t = clean_tree();
        write(
            t.path(),
            "crates/sl-demo/src/fast.rs",
            "//! Bad.\nfn f() { unsafe { g() } }\n",
        );
        let v = unsafe_outside_dispatch(t.path());
        assert_eq!(v.len(), 1, "{v:?}");
        assert!(v[0].file.ends_with("fast.rs"));
    }

    #[test]
    fn planted_thread_local_fails() {
        let t = clean_tree();
        write(
            t.path(),
            "crates/sl-demo/src/cache.rs",
            "//! Bad.\nthread_local! { static C: std::cell::Cell<u8> = const { std::cell::Cell::new(0) }; }\n",
        );
        let v = thread_locals(t.path());
        assert_eq!(v.len(), 1, "{v:?}");
        assert!(v[0].file.ends_with("cache.rs") && v[0].line == 2);
    }

    #[test]
    fn planted_python_lock_site_fails() {
        let t = clean_tree();
        write(
            t.path(),
            "crates/sl-py/src/volume.rs",
            "//! Bad.\nfn f(m: &std::sync::Mutex<u8>) -> u8 {\n    *m.lock().unwrap()\n}\n",
        );
        // The reviewed files may.
        write(
            t.path(),
            "crates/sl-py/src/threads.rs",
            "//! Fine.\nfn g(m: &std::sync::RwLock<u8>) -> u8 {\n    *m.read().unwrap()\n}\n",
        );
        let v = python_lock_sites(t.path());
        assert_eq!(v.len(), 1, "{v:?}");
        assert!(v[0].file.ends_with("volume.rs") && v[0].line == 3);
    }

    #[test]
    fn planted_long_source_file_fails() {
        let t = clean_tree();
        let lines = |n: usize| "fn f() {}\n".repeat(n);
        // The module doc and `MAX_CODE_LINES` more: one line too many.
        let long = format!("//! Long.\n{}", lines(MAX_CODE_LINES));
        write(t.path(), "crates/sl-demo/src/long.rs", &long);
        // At the limit, with an inline test module beyond it.
        let tested = format!(
            "//! Fine.\n{}#[cfg(test)]\nmod tests {{\n{}}}\n",
            lines(MAX_CODE_LINES - 1),
            lines(10)
        );
        write(t.path(), "crates/sl-demo/src/tested.rs", &tested);
        let v = long_source_files(t.path());
        assert_eq!(v.len(), 1, "{v:?}");
        assert!(v[0].file.ends_with("long.rs"), "{v:?}");
    }

    #[test]
    fn planted_missing_module_doc_fails() {
        let t = clean_tree();
        write(t.path(), "crates/sl-demo/src/nodoc.rs", "pub fn f() {}\n");
        let v = missing_module_docs(t.path());
        assert_eq!(v.len(), 1, "{v:?}");
        assert!(v[0].file.ends_with("nodoc.rs"));
    }

    #[test]
    fn planted_missing_readme_fails() {
        let t = clean_tree();
        fs::remove_file(t.path().join("crates/sl-demo/README.md")).unwrap();
        let v = missing_readmes(t.path());
        assert_eq!(v.len(), 1, "{v:?}");
        assert!(v[0].file.ends_with("sl-demo"));
    }

    #[test]
    fn planted_stale_names_and_files_fail() {
        let t = clean_tree();
        write(
            t.path(),
            "docs/ARCHITECTURE.md",
            "`Widget` via `filter_depth()` and `Weighting`; rules in CONVENTIONS.md.\n",
        );
        let v = stale_doc_names(t.path());
        let msgs: Vec<_> = v.iter().map(|x| x.message.as_str()).collect();
        assert_eq!(v.len(), 3, "{msgs:?}");
        assert!(msgs.iter().any(|m| m.contains("filter_depth")));
        assert!(msgs.iter().any(|m| m.contains("Weighting")));
        assert!(msgs.iter().any(|m| m.contains("CONVENTIONS.md")));
    }

    #[test]
    fn planted_generator_marker_fails() {
        let t = clean_tree();
        write(
            t.path(),
            "crates/sldepth/src/main.rs",
            "//! CLI.\nfn main() {}\n// @commands-variants (add lines above)\n",
        );
        write(
            t.path(),
            "xtask/Cargo.toml",
            "[package]\n# @deps (other crates add here)\n",
        );
        let v = generator_markers(t.path());
        assert_eq!(v.len(), 2, "{v:?}");
    }

    /// The real tree: every rule holds for the workspace itself.
    #[test]
    fn tidy() {
        let v = check_all(&crate::workspace_root());
        let report: Vec<String> = v.iter().map(ToString::to_string).collect();
        assert!(v.is_empty(), "tidy violations:\n{}", report.join("\n"));
    }
}
