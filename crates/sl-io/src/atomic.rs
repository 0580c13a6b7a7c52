//! Atomic file output: a reader never sees a half-written file.
//!
//! [`write_atomic`] writes into a temporary file in the destination's directory (so the final
//! `rename` stays on one file system), through a 1 MiB buffer, flushes and `fsync`s it, then
//! renames it over the destination. On any error — or a panic inside the callback — the temporary
//! file is removed and the destination is left untouched. Every writer of `sl-io` uses it.

use std::ffi::OsString;
use std::fs::{self, File, OpenOptions};
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use crate::error::{IoError, Result};

/// Buffer size between the callback and the file.
const BUFFER_BYTES: usize = 1 << 20;

/// How many temporary names to try before giving up (names collide only with stale files).
const MAX_TEMP_ATTEMPTS: u32 = 64;

static COUNTER: AtomicU64 = AtomicU64::new(0);

/// Removes the temporary file when dropped, unless it was renamed into place.
struct TempGuard {
    path: PathBuf,
    armed: bool,
}

impl Drop for TempGuard {
    fn drop(&mut self) {
        if self.armed {
            // Best effort: the error that got us here is the one worth reporting.
            let _ = fs::remove_file(&self.path);
        }
    }
}

/// Writes `path` atomically: `write` receives a buffered writer on a temporary file in the same
/// directory; when it returns `Ok` the data is flushed, `fsync`ed and renamed onto `path`.
///
/// Errors from `write` (use [`std::io::Error::other`] to wrap non-I/O errors) and from the file
/// system are returned as [`IoError::Io`] naming `path`; the temporary file is then removed.
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
    let (guard, file) = create_temp(path, dir, file_name)?;
    let mut guard = guard;

    let finish = |file: File| -> std::io::Result<()> {
        let mut w = BufWriter::with_capacity(BUFFER_BYTES, file);
        write(&mut w)?;
        let file = w.into_inner().map_err(|e| e.into_error())?;
        file.sync_all()
    };
    finish(file).map_err(|e| IoError::io(path, e))?;
    fs::rename(&guard.path, path).map_err(|e| IoError::io(path, e))?;
    guard.armed = false;
    sync_dir(dir);
    Ok(())
}

/// Creates a fresh temporary file `.<name>.<pid>.<n>.tmp` in `dir`.
fn create_temp(path: &Path, dir: &Path, file_name: &std::ffi::OsStr) -> Result<(TempGuard, File)> {
    let pid = std::process::id();
    let mut last_err = None;
    for _ in 0..MAX_TEMP_ATTEMPTS {
        let n = COUNTER.fetch_add(1, Ordering::Relaxed);
        let mut name = OsString::from(".");
        name.push(file_name);
        name.push(format!(".{pid}.{n}.tmp"));
        let tmp = dir.join(name);
        match OpenOptions::new().write(true).create_new(true).open(&tmp) {
            Ok(file) => {
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

    #[test]
    fn missing_directory_is_an_error_naming_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("no/such/dir/c.bin");
        let err = write_atomic(&p, |w| w.write_all(b"x")).unwrap_err();
        assert_eq!(err.path(), p.as_path());
    }
}
