//! Bounded text input: files, pipes and FIFOs are read in chunks and counted as they arrive,
//! so a limit holds whatever the file's metadata says.

use std::fs::File;
use std::io::Read;
use std::path::Path;

use crate::error::{IoError, Result};
use crate::limits::BUDGET_OPTION;

/// Bytes read per chunk.
const CHUNK_BYTES: usize = 64 << 10;

/// The UTF-8 encoding of U+FEFF, the byte-order mark.
const UTF8_BOM: &[u8] = &[0xef, 0xbb, 0xbf];

/// Reads a whole UTF-8 text input of at most `max_bytes` bytes and `max_lines` lines (a last
/// line without a newline counts), failing with [`IoError::TooLarge`] as soon as either limit
/// is passed — before the excess is held in memory.
pub(crate) fn read_text(path: &Path, max_bytes: u64, max_lines: u64) -> Result<String> {
    let file = File::open(path).map_err(|e| IoError::io(path, e))?;
    read_text_from(path, file, max_bytes, max_lines)
}

/// [`read_text`] from any reader (`path` names it in errors).
pub(crate) fn read_text_from(
    path: &Path,
    mut input: impl Read,
    max_bytes: u64,
    max_lines: u64,
) -> Result<String> {
    let mut buf: Vec<u8> = Vec::new();
    let mut chunk = vec![0u8; CHUNK_BYTES];
    let mut lines: u64 = 0;
    loop {
        let n = match input.read(&mut chunk) {
            Ok(0) => break,
            Ok(n) => n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(e) => return Err(IoError::io(path, e)),
        };
        let got = &chunk[..n];
        if buf.len() as u64 + n as u64 > max_bytes {
            return Err(IoError::too_large(
                path,
                format!(
                    "more than {max_bytes} bytes, over the text limit (raise it with {BUDGET_OPTION})"
                ),
            ));
        }
        lines += got.iter().filter(|&&b| b == b'\n').count() as u64;
        if lines > max_lines {
            return Err(IoError::too_large(
                path,
                format!(
                    "more than {max_lines} lines, over the text limit (raise it with {BUDGET_OPTION})"
                ),
            ));
        }
        buf.extend_from_slice(got);
    }
    if buf.last().is_some_and(|&b| b != b'\n') && lines + 1 > max_lines {
        return Err(IoError::too_large(
            path,
            format!(
                "more than {max_lines} lines, over the text limit (raise it with {BUDGET_OPTION})"
            ),
        ));
    }
    // A UTF-8 byte-order mark (editors on Windows write one) is not part of the text.
    if buf.starts_with(UTF8_BOM) {
        buf.drain(..UTF8_BOM.len());
    }
    String::from_utf8(buf).map_err(|e| {
        IoError::io(
            path,
            std::io::Error::new(
                std::io::ErrorKind::InvalidData,
                format!("not UTF-8 text: {e}"),
            ),
        )
    })
}

/// The lines of `text`: as [`str::lines`] (`\n` or `\r\n` ends a line), and a lone `\r` (old Mac
/// OS line endings) ends one too, so that such a file is not read as one line whose fields past
/// the first few would be ignored (a `depth.txt` of three frames read as one).
pub(crate) fn text_lines(text: &str) -> impl Iterator<Item = &str> {
    text.lines().flat_map(|l| l.split('\r'))
}

/// The whitespace-separated fields of the first line of the file at `path` that is not blank or
/// a `#` comment, looking no further than its first 4 KB (enough for a line of any trajectory or
/// association file); `None` when it is not a regular file (a named pipe would block the
/// opening), cannot be opened or has no such line there. For telling a file's kind by its
/// content, not for reading it.
pub(crate) fn first_data_fields(path: &Path) -> Option<Vec<String>> {
    if !std::fs::metadata(path).is_ok_and(|m| m.is_file()) {
        return None;
    }
    let file = std::fs::File::open(path).ok()?;
    let mut head = Vec::new();
    std::io::Read::read_to_end(&mut std::io::Read::take(file, 4096), &mut head).ok()?;
    let head = String::from_utf8_lossy(&head);
    let line = text_lines(&head)
        .map(str::trim)
        .find(|l| !l.is_empty() && !l.starts_with('#'))?;
    Some(line.split_whitespace().map(str::to_owned).collect())
}

/// Whether `field` is a whole number written with digits only (`12`, not `12.0` or `-1`).
pub(crate) fn is_whole_number(field: &str) -> bool {
    !field.is_empty() && field.bytes().all(|b| b.is_ascii_digit())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The first data line's fields, past comments and blank lines; nothing for a folder or a
    /// missing file.
    #[test]
    fn the_first_data_line_tells_a_files_kind() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.txt");
        std::fs::write(&p, "# head\n\n  0 1 3 \n1 0 0 0\n").unwrap();
        assert_eq!(first_data_fields(&p).unwrap(), ["0", "1", "3"]);
        assert!(first_data_fields(dir.path()).is_none());
        assert!(first_data_fields(&dir.path().join("missing")).is_none());
        std::fs::write(&p, "# only a comment\n").unwrap();
        assert!(first_data_fields(&p).is_none());
        assert!(is_whole_number("12") && !is_whole_number("1.5") && !is_whole_number("-1"));
        assert!(!is_whole_number(""));
    }

    #[test]
    fn counts_bytes_and_lines_while_reading() {
        let p = Path::new("t.txt");
        let ok = read_text_from(p, &b"a\nb\nc"[..], 5, 3).unwrap();
        assert_eq!(ok, "a\nb\nc");
        assert!(matches!(
            read_text_from(p, &b"a\nb\nc"[..], 4, 3),
            Err(IoError::TooLarge { .. })
        ));
        assert!(matches!(
            read_text_from(p, &b"a\nb\nc"[..], 5, 2),
            Err(IoError::TooLarge { .. })
        ));
        assert!(matches!(
            read_text_from(p, &b"\n\n\n"[..], 100, 2),
            Err(IoError::TooLarge { .. })
        ));
        // An endless stream stops at the limit.
        let endless = std::io::repeat(b'x');
        assert!(matches!(
            read_text_from(p, endless, 1 << 20, 10),
            Err(IoError::TooLarge { .. })
        ));
        assert!(read_text_from(p, &[0xffu8, 0xfe][..], 10, 10).is_err());
    }

    #[test]
    fn a_lone_carriage_return_ends_a_line() {
        fn lines(t: &str) -> Vec<&str> {
            text_lines(t).collect()
        }
        assert_eq!(
            lines("1 a.png\r2 b.png\r3 c.png\r"),
            ["1 a.png", "2 b.png", "3 c.png", ""]
        );
        assert_eq!(lines("1 a.png\r\n2 b.png\r\n"), ["1 a.png", "2 b.png"]);
        assert_eq!(lines("1 a.png\n2 b.png"), ["1 a.png", "2 b.png"]);
    }

    #[test]
    fn a_byte_order_mark_is_not_text() {
        let p = Path::new("t.txt");
        let text = read_text_from(p, &b"\xef\xbb\xbf# depth\n1 a.png\n"[..], 100, 10).unwrap();
        assert_eq!(text, "# depth\n1 a.png\n");
    }
}
