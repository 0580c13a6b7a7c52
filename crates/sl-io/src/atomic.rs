//! Atomic, safe file output: a reader never sees a half-written file, and an output name never
//! replaces something that is not a regular file.
//!
//! [`write_atomic`] first checks the destination ([`check_output`]): it must be a new name or an
//! existing **regular file**. A symbolic link is refused (not followed, not replaced: write to
//! the link's target by its own name), and so are directories, character and block devices
//! (`-o /dev/null` never replaces `/dev/null`), FIFOs and sockets. It then writes into a
//! temporary file `.NAME.sldepth-tmp.PID.N` in the destination's directory (so the final
//! `rename` stays on one file system), through a 1 MiB buffer, flushes and `fsync`s it, and
//! renames it over the destination. On any error — or a panic inside the callback — the
//! temporary file is removed and the destination is left untouched.
//!
//! Temporary files are also removed when the process is interrupted: every live temporary path
//! is kept in a registry, and [`remove_live_temps`] (which the `sldepth` binary calls from its
//! SIGINT / SIGTERM handler) deletes them and refuses new ones. A process killed outright
//! (SIGKILL) cannot clean up; its leftovers are recognised by their name, and the next write to
//! the same destination removes every `.NAME.sldepth-tmp.PID.N` whose process `PID` no longer
//! runs (where that cannot be told — no `/proc` — those older than an hour).

use std::collections::HashSet;
use std::ffi::{OsStr, OsString};
use std::fs::{self, File, OpenOptions};
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Mutex, MutexGuard};

use crate::error::{IoError, Result};

/// Buffer size between the callback and the file.
const BUFFER_BYTES: usize = 1 << 20;

/// How many temporary names to try before giving up (names collide only with stale files).
const MAX_TEMP_ATTEMPTS: u32 = 64;

/// The marker between the destination's name and the process id in a temporary name.
pub const TEMP_MARKER: &str = ".sldepth-tmp.";

/// Age after which a temporary file is stale when its process cannot be looked up, seconds.
const STALE_AGE_S: u64 = 3600;

static COUNTER: AtomicU64 = AtomicU64::new(0);

/// The live temporary files of this process, and whether new ones are refused (shutting down).
static LIVE: Mutex<Live> = Mutex::new(Live {
    paths: None,
    closed: false,
});

#[derive(Debug)]
struct Live {
    paths: Option<HashSet<PathBuf>>,
    closed: bool,
}

fn live() -> MutexGuard<'static, Live> {
    // A panic while holding the lock leaves a consistent set: keep using it.
    LIVE.lock().unwrap_or_else(|e| e.into_inner())
}

/// Removes every temporary file this process is writing and refuses new ones (later writes
/// fail with an error). For a signal handler that is about to exit the process; returns the
/// number of files removed.
pub fn remove_live_temps() -> usize {
    let mut live = live();
    live.closed = true;
    let paths = live.paths.take().unwrap_or_default();
    paths.iter().filter(|p| fs::remove_file(p).is_ok()).count()
}

/// Removes the temporary file when dropped, unless it was renamed into place.
struct TempGuard {
    path: PathBuf,
    armed: bool,
}

impl TempGuard {
    fn disarm(&mut self) {
        self.armed = false;
        if let Some(paths) = live().paths.as_mut() {
            paths.remove(&self.path);
        }
    }
}

impl Drop for TempGuard {
    fn drop(&mut self) {
        if self.armed {
            // Best effort: the error that got us here is the one worth reporting.
            let _ = fs::remove_file(&self.path);
            self.disarm();
        }
    }
}

/// Checks that `path` may be written by [`write_atomic`]: it has a file name, and is either
/// absent or a writable regular file (not a read-only file, symbolic link, directory, device,
/// FIFO or socket). Commands
/// call it for every output before doing any work, so that a bad output name fails early.
pub fn check_output(path: &Path) -> Result<()> {
    if path.file_name().is_none() {
        return Err(IoError::invalid_data(
            path,
            "not a file path (no file name)",
        ));
    }
    match fs::symlink_metadata(path) {
        Ok(meta) => {
            let ft = meta.file_type();
            let what = if ft.is_symlink() {
                "a symbolic link (refusing to replace it or write through it; name the target file instead)"
            } else if ft.is_dir() {
                "a directory"
            } else if ft.is_file() && meta.permissions().readonly() {
                // Replacing it by a rename would succeed in a writable directory: refuse, as
                // writing into it would.
                "a read-only file (refusing to replace it; make it writable or name another)"
            } else if ft.is_file() {
                return Ok(());
            } else {
                special_kind(&ft)
            };
            Err(IoError::UnsafeOutput {
                path: path.to_path_buf(),
                message: format!("exists and is {what}; only writable regular files are replaced"),
            })
        }
        Err(e)
            if matches!(
                e.kind(),
                std::io::ErrorKind::NotFound | std::io::ErrorKind::NotADirectory
            ) =>
        {
            check_parent_dir(path)
        }
        Err(e) => Err(IoError::io(path, e)),
    }
}

/// A new output's directory must exist (nothing creates it): said before any work, not when
/// the output is written at the end.
fn check_parent_dir(path: &Path) -> Result<()> {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => return Ok(()),
    };
    match fs::metadata(dir) {
        Ok(meta) if meta.is_dir() => Ok(()),
        Ok(_) => Err(IoError::UnsafeOutput {
            path: path.to_path_buf(),
            message: format!("{} is not a directory", dir.display()),
        }),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Err(IoError::UnsafeOutput {
            path: path.to_path_buf(),
            message: format!("the directory {} does not exist", dir.display()),
        }),
        Err(e) => Err(IoError::io(dir, e)),
    }
}

#[cfg(unix)]
fn special_kind(ft: &fs::FileType) -> &'static str {
    use std::os::unix::fs::FileTypeExt;
    if ft.is_char_device() {
        "a character device"
    } else if ft.is_block_device() {
        "a block device"
    } else if ft.is_fifo() {
        "a FIFO"
    } else if ft.is_socket() {
        "a socket"
    } else {
        "not a regular file"
    }
}

#[cfg(not(unix))]
fn special_kind(_ft: &fs::FileType) -> &'static str {
    "not a regular file"
}

/// Writes `path` atomically: `write` receives a buffered writer on a temporary file in the same
/// directory; when it returns `Ok` the data is flushed, `fsync`ed and renamed onto `path`.
///
/// The destination is checked first ([`check_output`]: [`IoError::UnsafeOutput`] unless it is
/// absent or a regular file), and stale temporary files of killed processes for the same
/// destination are removed. Errors from `write` (use [`std::io::Error::other`] to wrap non-I/O
/// errors) and from the file system are returned as [`IoError::Io`] naming `path`; the
/// temporary file is then removed.
///
/// ```
/// # fn main() -> Result<(), Box<dyn std::error::Error>> {
/// let dir = tempfile::tempdir()?;
/// let path = dir.path().join("hello.txt");
/// sl_io::atomic::write_atomic(&path, |w| w.write_all(b"hello"))?;
/// assert_eq!(std::fs::read(&path)?, b"hello");
/// # Ok(())
/// # }
/// ```
pub fn write_atomic<P, F>(path: P, write: F) -> Result<()>
where
    P: AsRef<Path>,
    F: FnOnce(&mut dyn Write) -> std::io::Result<()>,
{
    let path = path.as_ref();
    check_output(path)?;
    let Some(file_name) = path.file_name() else {
        return Err(IoError::invalid_data(
            path,
            "not a file path (no file name)",
        ));
    };
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    remove_stale_temps(dir, file_name);
    let (mut guard, file) = create_temp(path, dir, file_name)?;

    let finish = |file: File| -> std::io::Result<()> {
        let mut w = BufWriter::with_capacity(BUFFER_BYTES, file);
        write(&mut w)?;
        let file = w.into_inner().map_err(|e| e.into_error())?;
        file.sync_all()
    };
    finish(file).map_err(|e| IoError::io(path, e))?;
    // The destination may have changed while we wrote: check again right before the rename.
    check_output(path)?;
    fs::rename(&guard.path, path).map_err(|e| IoError::io(path, e))?;
    guard.disarm();
    sync_dir(dir);
    Ok(())
}

/// The prefix of the temporary names of `file_name`: `.NAME.sldepth-tmp.`.
fn temp_prefix(file_name: &OsStr) -> OsString {
    let mut name = OsString::from(".");
    name.push(file_name);
    name.push(TEMP_MARKER);
    name
}

/// Creates a fresh temporary file `.NAME.sldepth-tmp.PID.N` in `dir` and registers it.
fn create_temp(path: &Path, dir: &Path, file_name: &OsStr) -> Result<(TempGuard, File)> {
    let pid = std::process::id();
    let mut last_err = None;
    for _ in 0..MAX_TEMP_ATTEMPTS {
        let n = COUNTER.fetch_add(1, Ordering::Relaxed);
        let mut name = temp_prefix(file_name);
        name.push(format!("{pid}.{n}"));
        let tmp = dir.join(name);
        // Registered before it exists, under the lock, so that a signal handler running
        // `remove_live_temps` either sees it or makes us refuse to create it.
        let mut live = live();
        if live.closed {
            return Err(IoError::io(
                path,
                std::io::Error::new(
                    std::io::ErrorKind::Interrupted,
                    "interrupted: no new output files",
                ),
            ));
        }
        match OpenOptions::new().write(true).create_new(true).open(&tmp) {
            Ok(file) => {
                live.paths
                    .get_or_insert_with(HashSet::new)
                    .insert(tmp.clone());
                return Ok((
                    TempGuard {
                        path: tmp,
                        armed: true,
                    },
                    file,
                ));
            }
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => last_err = Some(e),
            Err(e) => return Err(IoError::io(path, e)),
        }
    }
    Err(IoError::io(
        path,
        last_err.unwrap_or_else(|| std::io::Error::other("cannot create a temporary file")),
    ))
}

/// Removes the temporary files of `file_name` in `dir` left by processes that no longer run
/// (best effort: errors are ignored, files of this process are kept).
fn remove_stale_temps(dir: &Path, file_name: &OsStr) {
    let prefix = temp_prefix(file_name);
    let Some(prefix) = prefix.to_str() else {
        return;
    };
    let Ok(entries) = fs::read_dir(dir) else {
        return;
    };
    let me = std::process::id();
    for entry in entries.flatten() {
        let name = entry.file_name();
        let Some(rest) = name.to_str().and_then(|n| n.strip_prefix(prefix)) else {
            continue;
        };
        let Some((pid, n)) = rest.split_once('.') else {
            continue;
        };
        let (Ok(pid), Ok(_)) = (pid.parse::<u32>(), n.parse::<u64>()) else {
            continue;
        };
        let is_file = entry.file_type().is_ok_and(|t| t.is_file());
        if pid == me || !is_file {
            continue;
        }
        if is_stale(pid, &entry) {
            let _ = fs::remove_file(entry.path());
        }
    }
}

/// Whether the temporary file of process `pid` is stale: the process no longer runs (Linux:
/// no `/proc/PID`), or, where that cannot be told, the file is older than an hour.
fn is_stale(pid: u32, entry: &fs::DirEntry) -> bool {
    let proc_root = Path::new("/proc/self");
    if proc_root.exists() {
        return !Path::new("/proc").join(pid.to_string()).exists();
    }
    entry
        .metadata()
        .and_then(|m| m.modified())
        .ok()
        .and_then(|t| t.elapsed().ok())
        .is_some_and(|age| age.as_secs() > STALE_AGE_S)
}

/// Makes the rename durable (best effort: not every platform can `fsync` a directory).
fn sync_dir(dir: &Path) {
    #[cfg(unix)]
    if let Ok(d) = File::open(dir) {
        let _ = d.sync_all();
    }
    #[cfg(not(unix))]
    let _ = dir;
}

#[cfg(test)]
mod tests {
    use super::*;

    fn entries(dir: &Path) -> Vec<String> {
        let mut v: Vec<String> = fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    }

    #[test]
    fn writes_and_replaces() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.bin");
        write_atomic(&p, |w| w.write_all(b"first")).unwrap();
        write_atomic(&p, |w| w.write_all(b"second")).unwrap();
        assert_eq!(fs::read(&p).unwrap(), b"second");
        assert_eq!(entries(dir.path()), vec!["a.bin".to_string()]);
    }

    #[test]
    fn error_leaves_destination_and_no_temp() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.bin");
        write_atomic(&p, |w| w.write_all(b"keep")).unwrap();
        let err = write_atomic(&p, |w| {
            w.write_all(b"partial")?;
            Err(std::io::Error::other("boom"))
        })
        .unwrap_err();
        assert!(
            err.to_string().contains("a.bin") && err.to_string().contains("boom"),
            "{err}"
        );
        assert_eq!(fs::read(&p).unwrap(), b"keep");
        assert_eq!(entries(dir.path()), vec!["a.bin".to_string()]);
    }

    #[test]
    fn panic_in_callback_removes_temp() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("b.bin");
        let r = std::panic::catch_unwind(|| {
            let _ = write_atomic(&p, |_w| -> std::io::Result<()> {
                panic!("callback panicked")
            });
        });
        assert!(r.is_err());
        assert!(entries(dir.path()).is_empty());
    }

    #[cfg(unix)]
    #[test]
    fn refuses_anything_but_a_regular_file() {
        use std::os::unix::fs::FileTypeExt;
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("target.bin");
        fs::write(&target, b"keep").unwrap();
        let link = dir.path().join("link.bin");
        std::os::unix::fs::symlink(&target, &link).unwrap();
        let sub = dir.path().join("sub");
        fs::create_dir(&sub).unwrap();
        for p in [link.as_path(), sub.as_path(), Path::new("/dev/null")] {
            let err = write_atomic(p, |w| w.write_all(b"x")).unwrap_err();
            assert!(matches!(err, IoError::UnsafeOutput { .. }), "{err}");
            assert_eq!(err.path(), p);
        }
        assert!(
            fs::symlink_metadata(&link)
                .unwrap()
                .file_type()
                .is_symlink()
        );
        assert_eq!(fs::read(&target).unwrap(), b"keep");
        assert!(
            fs::metadata("/dev/null")
                .unwrap()
                .file_type()
                .is_char_device()
        );
    }

    #[test]
    fn a_read_only_file_is_not_replaced() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("kept.bin");
        fs::write(&p, b"keep").unwrap();
        let mut perm = fs::metadata(&p).unwrap().permissions();
        perm.set_readonly(true);
        fs::set_permissions(&p, perm).unwrap();
        let err = write_atomic(&p, |w| w.write_all(b"x")).unwrap_err();
        assert!(err.to_string().contains("read-only"), "{err}");
        assert_eq!(fs::read(&p).unwrap(), b"keep");
    }

    #[test]
    fn stale_temps_of_dead_processes_are_removed() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.bin");
        // A PID that cannot run (above the kernel's pid_max of 2^22), and one that runs (ours
        // is kept as live; PID 1 always exists).
        let dead = dir.path().join(".a.bin.sldepth-tmp.4294967295.0");
        let alive = dir.path().join(".a.bin.sldepth-tmp.1.0");
        let other = dir.path().join(".b.bin.sldepth-tmp.4294967295.0");
        for f in [&dead, &alive, &other] {
            fs::write(f, b"stale").unwrap();
        }
        write_atomic(&p, |w| w.write_all(b"new")).unwrap();
        assert!(!dead.exists());
        if Path::new("/proc/self").exists() {
            assert!(alive.exists());
        }
        assert!(other.exists());
        assert_eq!(fs::read(&p).unwrap(), b"new");
    }

    #[test]
    fn missing_directory_is_an_error_naming_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("no/such/dir/c.bin");
        let err = write_atomic(&p, |w| w.write_all(b"x")).unwrap_err();
        assert_eq!(err.path(), p.as_path());
    }

    #[test]
    fn a_new_output_in_a_missing_directory_is_refused_before_any_work() {
        let dir = tempfile::tempdir().unwrap();
        check_output(&dir.path().join("new.bin")).unwrap();
        let missing = dir.path().join("no/such/dir/c.bin");
        let err = check_output(&missing).unwrap_err();
        assert_eq!(err.path(), missing.as_path());
        assert!(err.to_string().contains("does not exist"), "{err}");
        let file = dir.path().join("f");
        fs::write(&file, b"x").unwrap();
        let under_file = file.join("c.bin");
        let err = check_output(&under_file).unwrap_err();
        assert!(err.to_string().contains("is not a directory"), "{err}");
        // A bare file name is in the working directory.
        check_output(Path::new("bare-name-that-does-not-exist.bin")).unwrap();
    }
}
