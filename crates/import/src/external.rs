//! External files named by buffer and image URIs, read only from inside the asset roots
//! (docs/design.md "Import": a glTF must not read arbitrary files of the machine into a pack).
//!
//! A URI goes through these steps, each refusing with a typed [`UriProblem`]:
//! 1. percent-decode it first (an invalid escape, a decoded NUL or bytes that are not UTF-8 are
//!    refused), so that no check below can be dodged by encoding (`%2Fetc%2Fpasswd`, `%2e%2e/`);
//! 2. refuse, after decoding, any scheme (`file:`, `http:`), absolute paths (`/`, `\`, a drive
//!    letter such as `C:`) and backslash separators;
//! 3. join it with the glTF's directory and resolve `..` lexically: the result must lie inside an
//!    asset root (so escapes are refused whether or not their target exists);
//! 4. canonicalise it (symlinks followed): the real path must lie inside an asset root too (so a
//!    symlink beside the glTF pointing outside is refused, one pointing inside is fine);
//! 5. check the file type, open it without blocking (`O_NONBLOCK`: a FIFO cannot hang the
//!    import) and without following a symlink swapped in since step 4 (`O_NOFOLLOW`), then check
//!    the *opened handle* — not a second path lookup — is a regular file (devices, FIFOs,
//!    directories and sockets are refused), and on Linux that the handle's real path is still
//!    inside an asset root;
//! 6. check its size against what is needed (a buffer's declared `byteLength`, or the import's
//!    size limit for an image) before reading, and read through `take(needed)`.
//!
//! The asset roots are the glTF's own directory, the directory it really lives in when the path
//! given is a symlink to it (build sandboxes link every input: Bazel's `linux-sandbox`), and, when
//! the caller names one (the CLI's `--asset-root DIR`), a wider directory for pipelines that keep
//! textures in shared folders.

use std::fmt;
use std::fs::{File, OpenOptions};

use furbake_formats::input::irregular_kind;
use std::io::Read;
use std::path::{Component, Path, PathBuf};

/// What names an external file: a buffer or an image, by index in the glTF's arrays.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ExternalRef {
    /// `buffers[i].uri`.
    Buffer(usize),
    /// `images[i].uri`.
    Image(usize),
}

impl fmt::Display for ExternalRef {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ExternalRef::Buffer(i) => write!(f, "buffer {i}"),
            ExternalRef::Image(i) => write!(f, "image {i}"),
        }
    }
}

/// Why an external file named by a URI was refused or could not be read. Every variant but
/// [`UriProblem::Io`] and [`UriProblem::NoBaseDirectory`] is a refusal of a hostile or broken
/// reference.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum UriProblem {
    /// A `%` not followed by two hexadecimal digits.
    #[error("has an invalid percent-escape at byte {at} (a '%' must be followed by two hex digits)")]
    InvalidEscape {
        /// Byte offset of the `%` in the URI.
        at: usize,
    },
    /// The decoded path contains a NUL byte.
    #[error("decodes to a path containing a NUL byte")]
    NulByte,
    /// The decoded bytes are not UTF-8.
    #[error("does not decode to UTF-8 text")]
    NotUtf8,
    /// The URI names a scheme (`file:`, `http:`, …): only relative paths (and base64 `data:`
    /// URIs, handled before this) are read.
    #[error("names the URI scheme \"{scheme}\"; only paths relative to the glTF file and base64 data: URIs are read")]
    Scheme {
        /// The scheme, as decoded.
        scheme: String,
    },
    /// The decoded path is absolute (`/…`, `\…`, `C:…`).
    #[error("is an absolute path ({decoded:?} after percent-decoding); only paths relative to the glTF file are read")]
    Absolute {
        /// The percent-decoded path.
        decoded: String,
    },
    /// The decoded path uses a backslash separator.
    #[error("uses a backslash as a path separator ({decoded:?} after percent-decoding); glTF URIs use '/'")]
    Backslash {
        /// The percent-decoded path.
        decoded: String,
    },
    /// The path resolves (lexically, or after following symlinks) outside every asset root.
    #[error("resolves to {}, outside the asset root {}", resolved.display(), DisplayRoots(roots))]
    OutsideRoot {
        /// Where it resolves to.
        resolved: PathBuf,
        /// The canonical asset roots.
        roots: Vec<PathBuf>,
    },
    /// The file is a directory, FIFO, device or socket.
    #[error("is {kind}, not a regular file ({})", path.display())]
    NotRegularFile {
        /// The canonical path.
        path: PathBuf,
        /// What it is instead ("a FIFO", "a directory", …).
        kind: &'static str,
    },
    /// A buffer file shorter than the buffer's declared `byteLength`.
    #[error("holds {len} bytes but the buffer declares byteLength {declared} ({})", path.display())]
    ShorterThanDeclared {
        /// The canonical path.
        path: PathBuf,
        /// Bytes the file holds.
        len: u64,
        /// The buffer's `byteLength`.
        declared: u64,
    },
    /// An image file larger than the import's size limit.
    #[error("is {len} bytes, more than the limit of {limit} ({})", path.display())]
    TooLarge {
        /// The canonical path.
        path: PathBuf,
        /// Bytes the file holds.
        len: u64,
        /// The limit ([`crate::limits::MAX_FILE_BYTES`]).
        limit: u64,
    },
    /// The file (or an asset root) could not be resolved, opened or read.
    #[error("cannot be read ({}): {source}", path.display())]
    Io {
        /// The path that failed.
        path: PathBuf,
        /// The operating-system error.
        source: std::io::Error,
    },
    /// The glTF was given as bytes without a base directory, so no external file can be read.
    #[error("names an external file, but no base directory was given")]
    NoBaseDirectory,
}

impl UriProblem {
    /// Whether this is a refusal (a hostile or broken reference), rather than a file that is
    /// missing or unreadable.
    pub fn is_refusal(&self) -> bool {
        !matches!(self, UriProblem::Io { .. } | UriProblem::NoBaseDirectory)
    }
}

struct DisplayRoots<'a>(&'a [PathBuf]);

impl fmt::Display for DisplayRoots<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (i, root) in self.0.iter().enumerate() {
            if i > 0 {
                f.write_str(" or ")?;
            }
            write!(f, "{}", root.display())?;
        }
        Ok(())
    }
}

/// How much of an external file is wanted.
#[derive(Clone, Copy, Debug)]
pub(crate) enum Need {
    /// A buffer: exactly its declared `byteLength` (already checked against the size limit); a
    /// shorter file is refused, a longer one is read only that far.
    Prefix(u64),
    /// An image: the whole file, refused when larger than the limit.
    Whole { limit: u64 },
}

/// Where external files may be read from: relative URIs resolve against `base_dir` (the glTF's
/// directory), and must land inside `base_dir` or inside `extra_root`.
#[derive(Clone, Copy, Debug)]
pub(crate) struct ExternalFiles<'a> {
    /// The glTF's directory; `None` for in-memory input without one (external files are refused).
    pub base_dir: Option<&'a Path>,
    /// A wider asset root named by the caller (`--asset-root`).
    pub extra_root: Option<&'a Path>,
    /// The directory the glTF really lives in when it was reached through a symlink (a build
    /// system's sandbox or symlink forest links every input into a directory of its own): an
    /// asset root too, so the glTF's own buffers and images, linked beside it the same way, are
    /// read. The file system's layout is the user's; only the glTF's content is untrusted.
    pub real_dir: Option<&'a Path>,
    /// A missing or unreadable image is an error, not a warning ([`crate::ImportSettings::strict_inputs`]).
    pub strict: bool,
}

impl ExternalFiles<'_> {
    /// Reads what `need` asks of the file `uri` names, after every check of the module docs.
    /// Returns the bytes with the file's name relative to the glTF's directory
    /// ([`normalised_name`]).
    pub fn read(&self, uri: &str, need: Need) -> Result<(Vec<u8>, String), UriProblem> {
        let decoded = percent_decode(uri)?;
        let relative = relative_path(&decoded)?;
        let (file, len, real) = self.open(relative)?;
        Ok((read_needed(file, len, need, &real)?, normalised_name(relative)))
    }

    /// Steps 2–5 of the module docs for a path that needs no percent-decoding (a name a pack's
    /// manifest recorded): the opened regular file, its length and its canonical path.
    pub fn open_name(&self, name: &str) -> Result<(File, u64, PathBuf), UriProblem> {
        if name.contains('\0') {
            return Err(UriProblem::NulByte);
        }
        self.open(relative_path(name)?)
    }

    /// Steps 3–5 of the module docs for a relative path already checked by [`relative_path`].
    fn open(&self, relative: &Path) -> Result<(File, u64, PathBuf), UriProblem> {
        let base_dir = self.base_dir.ok_or(UriProblem::NoBaseDirectory)?;
        let canonical = |p: &Path| std::fs::canonicalize(p).map_err(|source| UriProblem::Io { path: p.into(), source });
        let base = canonical(base_dir)?;
        let mut roots = vec![base.clone()];
        if let Some(extra) = self.extra_root {
            roots.push(canonical(extra)?);
        }
        if let Some(real) = self.real_dir {
            roots.push(canonical(real)?);
        }
        let outside = |resolved: PathBuf| UriProblem::OutsideRoot { resolved, roots: roots.clone() };
        let lexical = join_lexically(&base, relative);
        if !inside(&lexical, &roots) {
            return Err(outside(lexical));
        }
        let joined = base.join(relative);
        let real = std::fs::canonicalize(&joined).map_err(|source| UriProblem::Io { path: joined, source })?;
        if !inside(&real, &roots) {
            return Err(outside(real));
        }
        let (file, len) = open_regular_file(&real, &roots)?;
        Ok((file, len, real))
    }
}

/// A relative path as the manifest and depfiles name it: `/`-separated, `.` dropped, `a/../b`
/// folded to `b`, leading `..` kept (a file under `--asset-root` beside the glTF's directory).
/// The same URI spelled two ways gives one name, and no absolute path ever appears.
pub(crate) fn normalised_name(relative: &Path) -> String {
    let mut parts: Vec<String> = Vec::new();
    for c in relative.components() {
        match c {
            Component::CurDir => {}
            Component::ParentDir => {
                if parts.last().is_some_and(|p| p != "..") {
                    parts.pop();
                } else {
                    parts.push("..".to_owned());
                }
            }
            other => parts.push(other.as_os_str().to_string_lossy().into_owned()),
        }
    }
    parts.join("/")
}

/// Decodes `%XX` escapes. Unlike a lenient decoder, an escape that is not two hex digits is an
/// error (it could hide anything), and so are a decoded NUL and bytes that are not UTF-8.
pub(crate) fn percent_decode(uri: &str) -> Result<String, UriProblem> {
    let bytes = uri.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%' {
            let hex = bytes.get(i + 1..i + 3).and_then(|h| std::str::from_utf8(h).ok());
            let byte =
                hex.filter(|h| h.bytes().all(|c| c.is_ascii_hexdigit())).and_then(|h| u8::from_str_radix(h, 16).ok());
            out.push(byte.ok_or(UriProblem::InvalidEscape { at: i })?);
            i += 3;
        } else {
            out.push(bytes[i]);
            i += 1;
        }
    }
    if out.contains(&0) {
        return Err(UriProblem::NulByte);
    }
    String::from_utf8(out).map_err(|_| UriProblem::NotUtf8)
}

/// The scheme of `uri` (`http` in `http://…`), if it has one; a single letter before the colon
/// is a drive letter, not a scheme.
pub(crate) fn scheme(uri: &str) -> Option<&str> {
    let colon = uri.find(':')?;
    let scheme = &uri[..colon];
    let valid = colon > 1
        && scheme.starts_with(|c: char| c.is_ascii_alphabetic())
        && scheme.chars().all(|c| c.is_ascii_alphanumeric() || "+-.".contains(c));
    valid.then_some(scheme)
}

/// The relative path a URI names after the checks of steps 1–2 (module docs), `None` where they
/// refuse it.
pub(crate) fn relative_uri_path(uri: &str) -> Option<PathBuf> {
    let decoded = percent_decode(uri).ok()?;
    relative_path(&decoded).ok().map(Path::to_path_buf)
}

/// Refuses a decoded path that names a scheme, is absolute or uses backslashes.
fn relative_path(decoded: &str) -> Result<&Path, UriProblem> {
    if let Some(scheme) = scheme(decoded) {
        return Err(UriProblem::Scheme { scheme: scheme.to_owned() });
    }
    let b = decoded.as_bytes();
    let drive_letter = b.len() >= 2 && b[0].is_ascii_alphabetic() && b[1] == b':';
    let path = Path::new(decoded);
    if decoded.starts_with(['/', '\\']) || drive_letter || path.has_root() || path.is_absolute() {
        return Err(UriProblem::Absolute { decoded: decoded.to_owned() });
    }
    if decoded.contains('\\') {
        return Err(UriProblem::Backslash { decoded: decoded.to_owned() });
    }
    Ok(path)
}

/// `base` joined with `relative`, with `.` dropped and `..` taken lexically (without asking the
/// file system, so an escape is refused whether or not its target exists).
fn join_lexically(base: &Path, relative: &Path) -> PathBuf {
    let mut out = base.to_path_buf();
    for c in relative.components() {
        match c {
            Component::CurDir => {}
            Component::ParentDir => {
                out.pop();
            }
            // Roots and prefixes were refused by `relative_path`; pushing one replaces `out`,
            // which then fails the root check.
            other => out.push(other),
        }
    }
    out
}

fn inside(path: &Path, roots: &[PathBuf]) -> bool {
    // `starts_with` compares whole components: `/a/bc` is not inside `/a/b`.
    roots.iter().any(|root| path.starts_with(root))
}

/// Opens `path` (canonical, inside a root) for reading and returns it with its length, refusing
/// anything but a regular file. The type is checked before opening (so a device is never even
/// opened) and again on the opened handle (so a file swapped in between cannot slip through);
/// the open itself cannot block on a FIFO and does not follow a symlink.
fn open_regular_file(path: &Path, roots: &[PathBuf]) -> Result<(File, u64), UriProblem> {
    let io = |source| UriProblem::Io { path: path.to_path_buf(), source };
    let not_regular = |kind| UriProblem::NotRegularFile { path: path.to_path_buf(), kind };
    if let Some(kind) = irregular_kind(std::fs::metadata(path).map_err(io)?.file_type()) {
        return Err(not_regular(kind));
    }
    let mut options = OpenOptions::new();
    options.read(true);
    #[cfg(unix)]
    {
        use std::os::unix::fs::OpenOptionsExt;
        // O_NONBLOCK: opening a FIFO returns at once instead of waiting for a writer (regular
        // files ignore the flag when read). O_NOFOLLOW: the last component must not have become
        // a symlink since it was canonicalised.
        options.custom_flags(libc::O_NONBLOCK | libc::O_NOFOLLOW);
    }
    let file = options.open(path).map_err(io)?;
    let metadata = file.metadata().map_err(io)?;
    if let Some(kind) = irregular_kind(metadata.file_type()) {
        return Err(not_regular(kind));
    }
    #[cfg(target_os = "linux")]
    {
        // The handle's own path: a directory on the way swapped for a symlink since the path was
        // canonicalised shows up here. Without /proc the earlier checks stand alone.
        use std::os::fd::AsRawFd;
        if let Ok(real) = std::fs::read_link(format!("/proc/self/fd/{}", file.as_raw_fd())) {
            if real.is_absolute() && !inside(&real, roots) {
                return Err(UriProblem::OutsideRoot { resolved: real, roots: roots.to_vec() });
            }
        }
    }
    #[cfg(not(target_os = "linux"))]
    let _ = roots;
    Ok((file, metadata.len()))
}

/// Checks `len` against `need` before reading, then reads through `take`, so a file that grows
/// meanwhile is still read only as far as was checked.
fn read_needed(file: File, len: u64, need: Need, path: &Path) -> Result<Vec<u8>, UriProblem> {
    let wanted = match need {
        Need::Prefix(declared) if len < declared => {
            return Err(UriProblem::ShorterThanDeclared { path: path.to_path_buf(), len, declared });
        }
        Need::Prefix(declared) => declared,
        Need::Whole { limit } if len > limit => {
            return Err(UriProblem::TooLarge { path: path.to_path_buf(), len, limit });
        }
        Need::Whole { .. } => len,
    };
    // `wanted` is at most the size limit (a buffer's byteLength was checked against it), and
    // the file holds at least that many bytes, so reserving it up front is bounded.
    let mut data = Vec::with_capacity(usize::try_from(wanted).unwrap_or(0));
    file.take(wanted).read_to_end(&mut data).map_err(|source| UriProblem::Io { path: path.to_path_buf(), source })?;
    if let Need::Prefix(declared) = need {
        if (data.len() as u64) < declared {
            // The file shrank after its size was checked.
            return Err(UriProblem::ShorterThanDeclared { path: path.to_path_buf(), len: data.len() as u64, declared });
        }
    }
    Ok(data)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn normalised_names_fold_dots_and_keep_leading_parents() {
        assert_eq!(normalised_name(Path::new("./tex/../tex/fur.png")), "tex/fur.png");
        assert_eq!(normalised_name(Path::new("../common/./body.bin")), "../common/body.bin");
        assert_eq!(normalised_name(Path::new("a/../../b.bin")), "../b.bin");
    }

    #[test]
    fn percent_decoding_is_strict() {
        assert_eq!(percent_decode("a%20b.bin").unwrap(), "a b.bin");
        assert_eq!(percent_decode("%2e%2E/x").unwrap(), "../x");
        assert_eq!(percent_decode("%c3%a9.png").unwrap(), "é.png");
        assert!(matches!(percent_decode("100%"), Err(UriProblem::InvalidEscape { at: 3 })));
        assert!(matches!(percent_decode("x%zz"), Err(UriProblem::InvalidEscape { at: 1 })));
        assert!(matches!(percent_decode("x%+1"), Err(UriProblem::InvalidEscape { at: 1 })));
        assert!(matches!(percent_decode("a%00.bin"), Err(UriProblem::NulByte)));
        assert!(matches!(percent_decode("a\0.bin"), Err(UriProblem::NulByte)));
        assert!(matches!(percent_decode("%ff.bin"), Err(UriProblem::NotUtf8)));
    }

    #[test]
    fn schemes_absolute_paths_and_backslashes_are_refused_after_decoding() {
        assert_eq!(scheme("http://x/y.bin"), Some("http"));
        assert_eq!(scheme("file:///y.bin"), Some("file"));
        assert_eq!(scheme("y.bin"), None);
        assert_eq!(scheme("C:/y.bin"), None, "a drive letter is not a scheme");
        assert_eq!(scheme("dir/a:b.bin"), None);
        let mut checked = 0;
        for (uri, want) in [
            ("file:///etc/passwd", "scheme"),
            ("/etc/passwd", "absolute"),
            ("%2Fetc%2Fpasswd", "absolute"),
            ("\\etc\\passwd", "absolute"),
            ("C:/Windows/win.ini", "absolute"),
            ("c:win.ini", "absolute"),
            ("%2E%2E%5Cpasswd", "backslash"),
            ("tex\\a.png", "backslash"),
        ] {
            let decoded = percent_decode(uri).unwrap();
            let got = match relative_path(&decoded) {
                Err(UriProblem::Scheme { .. }) => "scheme",
                Err(UriProblem::Absolute { .. }) => "absolute",
                Err(UriProblem::Backslash { .. }) => "backslash",
                other => panic!("{uri}: {other:?}"),
            };
            assert_eq!(got, want, "{uri}");
            checked += 1;
        }
        assert_eq!(checked, 8);
        assert_eq!(relative_path("../common/a.png").unwrap(), Path::new("../common/a.png"));
    }

    #[test]
    fn lexical_joins_take_parent_components() {
        let base = Path::new("/r/models");
        assert_eq!(join_lexically(base, Path::new("./a/../b.bin")), Path::new("/r/models/b.bin"));
        assert_eq!(join_lexically(base, Path::new("../../../../etc/passwd")), Path::new("/etc/passwd"));
        assert!(inside(&join_lexically(base, Path::new("../common/t.png")), &[PathBuf::from("/r")]));
        assert!(!inside(Path::new("/r/modelsX/a"), &[PathBuf::from("/r/models")]));
    }
}
