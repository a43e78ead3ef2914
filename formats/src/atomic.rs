//! Atomic file writes with ordinary permissions, leaving nothing behind when killed
//! ("Hostile inputs", item 6).
//!
//! [`write_file_atomic`] writes the bytes to a file that has no name yet and gives it one only
//! when it is complete, then renames it over the target (rename replaces atomically):
//! - on Linux the file is opened with `O_TMPFILE` in the target's directory (an unnamed inode
//!   that vanishes with the process), written and synced, then linked into the directory under
//!   a temporary name (`linkat` with `AT_EMPTY_PATH`, or through `/proc/self/fd/N`) and renamed
//!   over the target at once: a write killed at any point before the link leaves no file at all;
//! - elsewhere, and where the file system does not support `O_TMPFILE` (`EOPNOTSUPP`, `EISDIR`
//!   from kernels that do not know the flag, `EINVAL`), or the link is not permitted, it falls
//!   back to a named temporary file `.furbake-XXXXXX.tmp` (random name, `O_EXCL`), removed on
//!   any error. Only a process killed mid-write leaves one; the name says it is furbake's and
//!   temporary, so it can safely be removed.
//!
//! Either way the file gets the permissions of an ordinary file write: created with mode
//! `0o666` and the kernel applies the process umask (so `0o644` under umask `022`), without
//! reading or changing the umask ourselves (`umask(2)` set-and-restore would race with other
//! threads).

use std::io::Write;
use std::path::{Path, PathBuf};

use crate::error::{FormatError, Result};

/// Mode requested for every file [`write_file_atomic`] creates on Unix, before the umask: what
/// `open(2)` with `O_CREAT` gets from an ordinary program (`0o666 & !umask`).
#[cfg(unix)]
const ORDINARY_FILE_MODE: u32 = 0o666;

/// Prefix and suffix of the named temporary files (the fallback, and the instant between
/// linking an unnamed file and renaming it into place).
const TEMP_PREFIX: &str = ".furbake-";
const TEMP_SUFFIX: &str = ".tmp";

/// Writes `bytes` to `path` atomically: `path` is either the old file or the complete new one,
/// never half-written, and a failed write leaves no temporary file. See the module docs for how
/// (an unnamed `O_TMPFILE` on Linux, a named temporary file elsewhere) and for the permissions
/// (`0o666` minus the umask).
pub fn write_file_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    write_atomic_with(path, &mut |w| w.write_all(bytes), Method::Best, &mut |_| {}).map(|_| ())
}

/// As [`write_file_atomic`], with the contents streamed: `fill` writes them (through a buffer)
/// into the file that gets the name `path` only once `fill` has returned `Ok` — a long-running
/// producer (a report written step by step) keeps nothing in memory, and an error from `fill`
/// (or a killed process) leaves `path` as it was and no temporary file. `fill` runs exactly once.
pub fn write_file_atomic_from(path: &Path, fill: &mut dyn FnMut(&mut dyn Write) -> std::io::Result<()>) -> Result<()> {
    write_atomic_with(path, fill, Method::Best, &mut |_| {}).map(|_| ())
}

/// The contents of a file being written atomically.
type Fill<'a> = &'a mut dyn FnMut(&mut dyn Write) -> std::io::Result<()>;

/// Runs `fill` into `file` through a buffer, then syncs it.
fn fill_file(file: &mut std::fs::File, fill: Fill) -> std::io::Result<()> {
    let mut buffered = std::io::BufWriter::with_capacity(1 << 16, &mut *file);
    fill(&mut buffered)?;
    buffered.flush()?;
    drop(buffered);
    file.sync_all()
}

/// How a file was (or is to be) written.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Method {
    /// Unnamed where the platform allows, else named (what [`write_file_atomic`] does).
    Best,
    /// An unnamed `O_TMPFILE`, linked into place when complete.
    Unnamed,
    /// A named temporary file, renamed into place.
    Named,
}

/// [`write_file_atomic`], with the method forced (`Best` chooses) and `written` called with the
/// directory after the bytes are written and synced but before the file gets its name there
/// (tests list the directory at that moment). Returns the method used.
pub(crate) fn write_atomic_with(
    path: &Path,
    fill: Fill,
    method: Method,
    written: &mut dyn FnMut(&Path),
) -> Result<Method> {
    let io = |source| FormatError::Io { path: path.to_path_buf(), source };
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    #[cfg(target_os = "linux")]
    if method != Method::Named {
        match unnamed::write(&dir, path, &mut *fill, written) {
            Ok(()) => return Ok(Method::Unnamed),
            Err(unnamed::Error::Unsupported(e)) if method == Method::Unnamed => return Err(io(e)),
            Err(unnamed::Error::Unsupported(_)) => {}
            Err(unnamed::Error::Unlinkable(_, e)) if method == Method::Unnamed => return Err(io(e)),
            // Written but not linkable here: the named fallback copies the unnamed file's
            // contents (`fill` has run and must not run twice).
            Err(unnamed::Error::Unlinkable(mut file, _)) => {
                use std::io::{Seek, SeekFrom};
                let mut copy = |w: &mut dyn Write| {
                    file.seek(SeekFrom::Start(0))?;
                    std::io::copy(&mut file, w).map(|_| ())
                };
                write_named(&dir, path, &mut copy, written).map_err(io)?;
                return Ok(Method::Named);
            }
            Err(unnamed::Error::Failed(e)) => return Err(io(e)),
        }
    }
    #[cfg(not(target_os = "linux"))]
    if method == Method::Unnamed {
        return Err(io(std::io::Error::new(std::io::ErrorKind::Unsupported, "O_TMPFILE is Linux-only")));
    }
    write_named(&dir, path, fill, written).map_err(io)?;
    Ok(Method::Named)
}

/// The fallback: a named temporary file (unpredictable name, `O_EXCL`, mode `0o666` before the
/// umask) renamed into place; dropping it on any error (the `?`s) removes it.
fn write_named(dir: &Path, path: &Path, fill: Fill, written: &mut dyn FnMut(&Path)) -> std::io::Result<()> {
    let mut builder = tempfile::Builder::new();
    builder.prefix(TEMP_PREFIX).suffix(TEMP_SUFFIX);
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        builder.permissions(std::fs::Permissions::from_mode(ORDINARY_FILE_MODE));
    }
    let mut tmp = builder.tempfile_in(dir)?;
    fill_file(tmp.as_file_mut(), fill)?;
    written(dir);
    tmp.persist(path).map_err(|e| e.error)?;
    Ok(())
}

#[cfg(target_os = "linux")]
mod unnamed {
    //! The Linux path: `O_TMPFILE`, then `linkat` to a temporary name and `rename` over the
    //! target.

    use std::ffi::CString;
    use std::fs::{File, OpenOptions};
    use std::os::fd::AsRawFd;
    use std::os::unix::ffi::OsStrExt;
    use std::os::unix::fs::OpenOptionsExt;
    use std::path::Path;

    use super::{Fill, ORDINARY_FILE_MODE, TEMP_PREFIX, TEMP_SUFFIX, fill_file};

    pub(super) enum Error {
        /// This file system or kernel cannot do it: fall back to a named temporary file (nothing
        /// was left behind).
        Unsupported(std::io::Error),
        /// The contents were written, but no link form is permitted here: the caller copies
        /// them from the file into a named temporary file.
        Unlinkable(File, std::io::Error),
        /// A real failure (no space, no permission to write the directory, …).
        Failed(std::io::Error),
    }

    fn unsupported(e: &std::io::Error) -> bool {
        matches!(e.raw_os_error(), Some(libc::EOPNOTSUPP | libc::EISDIR | libc::EINVAL))
    }

    pub(super) fn write(dir: &Path, path: &Path, fill: Fill, written: &mut dyn FnMut(&Path)) -> Result<(), Error> {
        let mut file = OpenOptions::new()
            .write(true)
            .mode(ORDINARY_FILE_MODE)
            .custom_flags(libc::O_TMPFILE)
            .open(dir)
            .map_err(|e| if unsupported(&e) { Error::Unsupported(e) } else { Error::Failed(e) })?;
        fill_file(&mut file, fill).map_err(Error::Failed)?;
        written(dir);
        // The unnamed file gets a temporary name (a link cannot replace an existing file), which
        // the rename then moves over the target at once; on any error dropping `linked` removes
        // the name again. A name clash is retried with another random name.
        let mut refused = None;
        let linked = tempfile::Builder::new().prefix(TEMP_PREFIX).suffix(TEMP_SUFFIX).make_in(dir, |candidate| {
            link(&file, candidate).inspect_err(|e| {
                if e.kind() != std::io::ErrorKind::AlreadyExists {
                    refused = Some(e.raw_os_error());
                }
            })
        });
        let linked = match linked {
            Ok(linked) => linked,
            // Neither link form is permitted here (no CAP_DAC_READ_SEARCH and no /proc): the
            // named fallback copies the contents from the unnamed file.
            Err(e) if matches!(refused, Some(Some(libc::EPERM | libc::ENOENT | libc::EACCES))) => {
                return Err(Error::Unlinkable(file, e));
            }
            Err(e) => return Err(Error::Failed(e)),
        };
        linked.persist(path).map_err(|e| Error::Failed(e.error))?;
        Ok(())
    }

    /// Gives the unnamed `file` the name `target`: `linkat(fd, "", AT_FDCWD, target,
    /// AT_EMPTY_PATH)` (needs `CAP_DAC_READ_SEARCH` before Linux 6.10 for most users), else
    /// through `/proc/self/fd/N` ([`link_through_proc`]).
    fn link(file: &File, target: &Path) -> std::io::Result<()> {
        let c_target = CString::new(target.as_os_str().as_bytes())?;
        // SAFETY: both strings are valid and NUL-terminated, and the descriptor is open for the
        // duration of the call; `linkat` reads them and keeps neither.
        let rc = unsafe {
            libc::linkat(file.as_raw_fd(), c"".as_ptr(), libc::AT_FDCWD, c_target.as_ptr(), libc::AT_EMPTY_PATH)
        };
        if rc == 0 {
            return Ok(());
        }
        let first = std::io::Error::last_os_error();
        if first.kind() == std::io::ErrorKind::AlreadyExists {
            return Err(first);
        }
        link_through_proc(file, target)
    }

    /// `linkat` of `/proc/self/fd/N`, following the magic link to the unnamed file (needs /proc,
    /// no capability).
    pub(super) fn link_through_proc(file: &File, target: &Path) -> std::io::Result<()> {
        let c_target = CString::new(target.as_os_str().as_bytes())?;
        let proc_path = CString::new(format!("/proc/self/fd/{}", file.as_raw_fd()))?;
        // SAFETY: as in `link`.
        let rc = unsafe {
            libc::linkat(libc::AT_FDCWD, proc_path.as_ptr(), libc::AT_FDCWD, c_target.as_ptr(), libc::AT_SYMLINK_FOLLOW)
        };
        if rc == 0 { Ok(()) } else { Err(std::io::Error::last_os_error()) }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn names(dir: &Path) -> Vec<String> {
        let mut names: Vec<String> =
            std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
        names.sort();
        names
    }

    /// Whether this directory's file system supports `O_TMPFILE` (asked directly, not through
    /// the code under test).
    #[cfg(target_os = "linux")]
    fn supports_o_tmpfile(dir: &Path) -> bool {
        use std::os::unix::fs::OpenOptionsExt;
        std::fs::OpenOptions::new().write(true).mode(0o600).custom_flags(libc::O_TMPFILE).open(dir).is_ok()
    }

    #[test]
    fn no_named_temporary_file_exists_while_the_bytes_are_written_where_o_tmpfile_works() {
        // A write killed mid-way left `.furbake-*.tmp` files of up to 121 MB behind: the bytes
        // went into a named temporary file. Written into an unnamed O_TMPFILE, there is
        // nothing to leave: the directory shows no new entry until the file is complete.
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("pack.fbk");
        std::fs::write(&target, b"old").unwrap();
        let mut seen = Vec::new();
        let used =
            write_atomic_with(&target, &mut |w| w.write_all(&[7u8; 1 << 20]), Method::Best, &mut |d| seen = names(d))
                .unwrap();
        #[cfg(target_os = "linux")]
        assert_eq!(used == Method::Unnamed, supports_o_tmpfile(dir.path()), "{used:?}");
        match used {
            Method::Unnamed => assert_eq!(seen, ["pack.fbk"], "only the old file is visible mid-write"),
            _ => {
                assert_eq!(seen.len(), 2, "{seen:?}");
                assert!(seen[0].starts_with(TEMP_PREFIX) && seen[0].ends_with(TEMP_SUFFIX), "{seen:?}");
            }
        }
        assert_eq!(std::fs::read(&target).unwrap(), vec![7u8; 1 << 20]);
        assert_eq!(names(dir.path()), ["pack.fbk"]);
    }

    #[cfg(target_os = "linux")]
    /// A streamed write gets its name only when the producer succeeds; a producer's error
    /// leaves the old file and no temporary one, and the producer runs once.
    #[test]
    fn a_streamed_write_is_named_only_when_the_producer_succeeds() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("report.json");
        std::fs::write(&target, b"old").unwrap();
        let mut runs = 0;
        let err = write_file_atomic_from(&target, &mut |w| {
            runs += 1;
            w.write_all(b"half a report")?;
            Err(std::io::Error::other("the simulation failed"))
        });
        assert!(err.is_err());
        assert_eq!((runs, std::fs::read(&target).unwrap()), (1, b"old".to_vec()));
        assert_eq!(names(dir.path()), ["report.json"]);
        write_file_atomic_from(&target, &mut |w| {
            for k in 0..10_000 {
                writeln!(w, "record {k}")?;
            }
            Ok(())
        })
        .unwrap();
        let text = std::fs::read_to_string(&target).unwrap();
        assert!(text.starts_with("record 0\n") && text.ends_with("record 9999\n"));
        assert_eq!(names(dir.path()), ["report.json"]);
    }

    #[test]
    fn an_unnamed_file_can_be_linked_through_proc() {
        // The form an unprivileged process uses where `AT_EMPTY_PATH` is refused (tests often run
        // as root, where the first form always works).
        use std::os::unix::fs::OpenOptionsExt;
        let dir = tempfile::tempdir().unwrap();
        if !supports_o_tmpfile(dir.path()) || !Path::new("/proc/self/fd").is_dir() {
            eprintln!("skipped: no O_TMPFILE or no /proc here");
            return;
        }
        let mut file =
            std::fs::OpenOptions::new().write(true).mode(0o666).custom_flags(libc::O_TMPFILE).open(dir.path()).unwrap();
        file.write_all(b"unnamed").unwrap();
        let target = dir.path().join("named");
        unnamed::link_through_proc(&file, &target).unwrap();
        assert_eq!(std::fs::read(&target).unwrap(), b"unnamed");
        assert_eq!(names(dir.path()), ["named"]);
    }

    #[test]
    fn the_named_fallback_renames_into_place_and_cleans_up_after_a_failure() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("a.json");
        let mut seen = Vec::new();
        let used =
            write_atomic_with(&target, &mut |w| w.write_all(b"{}"), Method::Named, &mut |d| seen = names(d)).unwrap();
        assert_eq!(used, Method::Named);
        assert_eq!(seen.len(), 1, "the named temporary file is visible mid-write: {seen:?}");
        assert!(seen[0].starts_with(TEMP_PREFIX) && seen[0].ends_with(TEMP_SUFFIX), "{seen:?}");
        assert_eq!(std::fs::read(&target).unwrap(), b"{}");
        // A failed write (the target is a directory) removes its temporary file, by either method.
        let blocker = dir.path().join("blocker");
        std::fs::create_dir(&blocker).unwrap();
        let mut failed = 0;
        for method in [Method::Named, Method::Best] {
            assert!(
                write_atomic_with(&blocker, &mut |w| w.write_all(b"x"), method, &mut |_| {}).is_err(),
                "{method:?}"
            );
            assert_eq!(names(dir.path()), ["a.json", "blocker"], "{method:?}");
            failed += 1;
        }
        assert_eq!(failed, 2);
    }
}
