//! Opening and reading the files furbake is given (docs/design.md "Bounded reads"): every file
//! is opened without blocking (a FIFO named as an input returns at once instead of waiting for a
//! writer), its *opened handle* must be a regular file (a device such as `/dev/zero`, a FIFO, a
//! socket or a directory is refused with its kind named), its size is checked against a limit
//! before anything is read, and the read goes through `take`, so a file that grows meanwhile is
//! still read only as far as was checked.
//!
//! The errors are `std::io::Error`s with a message that says what the file is and what the limit
//! is; every caller wraps them with the path (`FormatError::Io`, `SceneError::Io`, …).

use std::fs::{File, FileType, OpenOptions};
use std::io::Read;
use std::path::Path;

/// Largest text file furbake reads whole: a scene, a bake config, a batch file (16 MiB; the
/// largest bundled scene is 3 KiB).
pub const MAX_TEXT_BYTES: u64 = 16 << 20;

/// Largest pack [`crate::Pack::read`] holds in memory whole (4 GiB). [`crate::Pack::open`] has no
/// such limit: it reads sections on demand, each bounded by the file's real length.
pub const MAX_PACK_BYTES: u64 = 4 << 30;

/// What a file type is when it is not a regular file ("a FIFO", "a character device", …).
pub fn irregular_kind(t: FileType) -> Option<&'static str> {
    if t.is_file() {
        return None;
    }
    if t.is_dir() {
        return Some("a directory");
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if t.is_fifo() {
            return Some("a FIFO");
        }
        if t.is_char_device() {
            return Some("a character device");
        }
        if t.is_block_device() {
            return Some("a block device");
        }
        if t.is_socket() {
            return Some("a socket");
        }
    }
    if t.is_symlink() {
        return Some("a symbolic link");
    }
    Some("a special file")
}

/// The error for a file of kind `kind` where a regular file is needed.
fn not_regular(kind: &str) -> std::io::Error {
    std::io::Error::new(std::io::ErrorKind::InvalidInput, format!("is {kind}, not a regular file"))
}

/// Opens `path` for reading without blocking and returns it with its length, refusing anything
/// but a regular file (checked on the opened handle, so nothing swapped in after a path check
/// slips through). Symlinks are followed: a link to a regular file is that file.
pub fn open_regular(path: &Path) -> std::io::Result<(File, u64)> {
    let mut options = OpenOptions::new();
    options.read(true);
    #[cfg(unix)]
    {
        use std::os::unix::fs::OpenOptionsExt;
        // O_NONBLOCK: opening a FIFO returns at once instead of waiting for a writer; regular
        // files ignore the flag when read.
        options.custom_flags(libc::O_NONBLOCK);
    }
    let file = options.open(path)?;
    let metadata = file.metadata()?;
    if let Some(kind) = irregular_kind(metadata.file_type()) {
        return Err(not_regular(kind));
    }
    Ok((file, metadata.len()))
}

/// Human size: `3.0 GiB`, `16 MiB`, `512 bytes`.
pub fn format_size(bytes: u64) -> String {
    const UNITS: [(u64, &str); 3] = [(1 << 30, "GiB"), (1 << 20, "MiB"), (1 << 10, "KiB")];
    for (unit, name) in UNITS {
        if bytes >= unit {
            let v = bytes as f64 / unit as f64;
            return if bytes.is_multiple_of(unit) {
                format!("{} {name}", bytes / unit)
            } else {
                format!("{v:.1} {name}")
            };
        }
    }
    format!("{bytes} bytes")
}

/// The error for a file of `len` bytes over `limit`; `what` names the kind of file ("a scene").
pub fn too_large(len: u64, limit: u64, what: &str) -> std::io::Error {
    std::io::Error::new(
        std::io::ErrorKind::FileTooLarge,
        format!("is {} ({len} bytes), more than the limit of {} for {what}", format_size(len), format_size(limit)),
    )
}

/// Reads the whole regular file `path` ([`open_regular`]) when it holds at most `limit` bytes
/// (`what` names the kind of file in the error: "a scene", "a batch file").
pub fn read_bounded(path: &Path, limit: u64, what: &str) -> std::io::Result<Vec<u8>> {
    let (file, len) = open_regular(path)?;
    read_open_bounded(file, len, limit, what)
}

/// [`read_bounded`] of an already opened regular file of `len` bytes.
pub fn read_open_bounded(file: File, len: u64, limit: u64, what: &str) -> std::io::Result<Vec<u8>> {
    if len > limit {
        return Err(too_large(len, limit, what));
    }
    // `len` is at most `limit`, so reserving it up front is bounded.
    let mut data = Vec::with_capacity(usize::try_from(len).unwrap_or(0));
    file.take(limit + 1).read_to_end(&mut data)?;
    if data.len() as u64 > limit {
        return Err(too_large(data.len() as u64, limit, what));
    }
    Ok(data)
}

/// [`read_bounded`] as UTF-8 text, at most [`MAX_TEXT_BYTES`].
pub fn read_text(path: &Path, what: &str) -> std::io::Result<String> {
    let bytes = read_bounded(path, MAX_TEXT_BYTES, what)?;
    String::from_utf8(bytes)
        .map_err(|e| std::io::Error::new(std::io::ErrorKind::InvalidData, format!("is not UTF-8 text: {e}")))
}

/// serde's message about a hand-written file (a scene, a bake config) in the words of the file's
/// author: Rust's type names said as what to write (`expected f32` → `expected a number`,
/// `expected a sequence` → `expected an array`), and a three-element array shown by example.
pub fn settings_message_in_words(message: &str) -> String {
    let mut message = message.trim().to_string();
    for (rust, words) in [
        ("expected f32", "expected a number"),
        ("expected f64", "expected a number"),
        ("expected u64", "expected a whole number ≥ 0"),
        ("expected u32", "expected a whole number ≥ 0"),
        ("expected u16", "expected a whole number ≥ 0"),
        ("expected u8", "expected a whole number ≥ 0"),
        ("expected usize", "expected a whole number ≥ 0"),
        ("expected a sequence", "expected an array"),
        ("expected a map", "expected a table"),
        ("invalid type: map,", "invalid type: table,"),
        ("invalid type: sequence,", "invalid type: array,"),
        ("floating point", "number"),
    ] {
        message = message.replace(rust, words);
    }
    if let Some(n) = message.strip_suffix(", expected an array of length 3").map(str::len) {
        message.replace_range(n.., ", expected an array of 3 numbers, e.g. `[0.0, 1.0, 0.0]`");
    }
    // `expected struct VolumeParams`: a table, whatever Rust calls it.
    while let Some(at) = message.find("expected struct ") {
        let name_end =
            message[at + 16..].find(|c: char| !c.is_alphanumeric() && c != '_').map_or(message.len(), |e| at + 16 + e);
        message.replace_range(at..name_end, "expected a table");
    }
    message
}

/// One line locating a settings error in the text of the file it came from: `key: message (line
/// L, column C)`, the dotted key left out when empty (a syntax error, an unknown top-level key),
/// the place left out when the parser gave no byte range.
pub fn located_message(text: &str, key: &str, message: &str, span: Option<std::ops::Range<usize>>) -> String {
    let message = settings_message_in_words(message);
    let at = span.map(|span| {
        let before = &text[..span.start.min(text.len())];
        let line = before.matches('\n').count() + 1;
        let column = before.chars().count() - before.rfind('\n').map_or(0, |i| before[..=i].chars().count()) + 1;
        format!(" (line {line}, column {column})")
    });
    let key = key.trim_start_matches('.');
    match key.is_empty() || key == "?" {
        true => format!("{message}{}", at.unwrap_or_default()),
        false => format!("{key}: {message}{}", at.unwrap_or_default()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_read_as_people_write_them() {
        assert_eq!(format_size(16 << 20), "16 MiB");
        assert_eq!(format_size(3 << 30), "3 GiB");
        assert_eq!(format_size(1536), "1.5 KiB");
        assert_eq!(format_size(12), "12 bytes");
    }

    #[test]
    fn devices_directories_and_oversized_files_are_refused_before_reading() {
        let dir = tempfile::tempdir().unwrap();
        let e = read_bounded(dir.path(), 10, "a scene").unwrap_err();
        assert!(e.to_string().contains("a directory"), "{e}");
        #[cfg(unix)]
        {
            let e = read_bounded(Path::new("/dev/zero"), 10, "a scene").unwrap_err();
            assert!(e.to_string().contains("a character device"), "{e}");
        }
        let big = dir.path().join("big.toml");
        std::fs::write(&big, vec![b'#'; 11]).unwrap();
        let e = read_bounded(&big, 10, "a scene").unwrap_err();
        assert_eq!(e.kind(), std::io::ErrorKind::FileTooLarge);
        assert!(e.to_string().contains("limit of 10 bytes for a scene"), "{e}");
        assert_eq!(read_bounded(&big, 11, "a scene").unwrap().len(), 11);
    }

    #[cfg(unix)]
    #[test]
    fn a_fifo_is_refused_at_once() {
        let dir = tempfile::tempdir().unwrap();
        let fifo = dir.path().join("scene.toml");
        let c = std::ffi::CString::new(fifo.to_str().unwrap()).unwrap();
        // SAFETY: a valid NUL-terminated path; mkfifo keeps nothing.
        assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0);
        let e = read_text(&fifo, "a scene").unwrap_err();
        assert!(e.to_string().contains("a FIFO"), "{e}");
    }
}
