//! Atomic file writes with ordinary permissions, leaving nothing behind when killed
//! (docs/design.md "Safe outputs").
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
//! The target must be a regular file or not exist: a device (`/dev/null` run as root), a FIFO, a
//! socket or a directory is refused before anything is written and checked again just before the
//! rename ([`refuse_special_target`]), so an output never replaces one.
//!
//! The temporary name (`.furbake-<pid>-XXXXXX.tmp`) carries the writer's process id. Where the
//! target does not exist yet, the unnamed file is linked straight to its name and never has a
//! temporary one. Each write first removes the temporary files in its directory whose writer is
//! no longer running and which have not changed for a minute ([`remove_stale_temporaries`]): what
//! a killed write left, never another live writer's file.
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
/// linking an unnamed file and renaming it into place): `.furbake-<pid>-XXXXXX.tmp`.
const TEMP_PREFIX: &str = ".furbake-";
const TEMP_SUFFIX: &str = ".tmp";

/// How long a temporary file of a writer that is no longer running must have been unchanged
/// before another write removes it.
const STALE_AFTER: std::time::Duration = std::time::Duration::from_secs(60);

/// The prefix of this process's temporary names.
fn temp_prefix() -> String {
    format!("{TEMP_PREFIX}{}-", std::process::id())
}

/// Refuses a target that exists and is not a regular file (followed through symlinks: a link to
/// `/dev/null` is `/dev/null`). A missing target, or one whose type cannot be read, is left to
/// the write itself.
pub(crate) fn refuse_special_target(path: &Path) -> std::io::Result<()> {
    match std::fs::metadata(path) {
        Ok(m) => match crate::input::irregular_kind(m.file_type()) {
            Some(kind) => Err(std::io::Error::new(
                std::io::ErrorKind::InvalidInput,
                format!("is {kind}; furbake writes only regular files and never replaces anything else"),
            )),
            None => Ok(()),
        },
        Err(_) => Ok(()),
    }
}

/// Removes the temporary files in `dir` that a killed write left: named as ours, a regular file
/// owned by this user, unchanged for [`STALE_AFTER`], and whose writer's process id is not a
/// running process. Errors are ignored (the file stays, and the write goes on).
#[cfg(unix)]
fn remove_stale_temporaries(dir: &Path) {
    use std::os::unix::fs::MetadataExt;
    let Ok(entries) = std::fs::read_dir(dir) else { return };
    // SAFETY: geteuid has no preconditions and cannot fail.
    let uid = unsafe { libc::geteuid() };
    for entry in entries.flatten() {
        let name = entry.file_name();
        let Some(pid) = name.to_str().and_then(stale_name_pid) else { continue };
        let Ok(m) = entry.path().symlink_metadata() else { continue };
        let old = m.modified().ok().and_then(|t| t.elapsed().ok()).is_some_and(|age| age >= STALE_AFTER);
        if !m.file_type().is_file() || m.uid() != uid || !old || process_is_running(pid) {
            continue;
        }
        let _ = std::fs::remove_file(entry.path());
    }
}

#[cfg(not(unix))]
fn remove_stale_temporaries(_dir: &Path) {}

/// The writer's process id in a temporary name `.furbake-<pid>-XXXXXX.tmp`.
fn stale_name_pid(name: &str) -> Option<u32> {
    let rest = name.strip_prefix(TEMP_PREFIX)?.strip_suffix(TEMP_SUFFIX)?;
    let (pid, random) = rest.split_once('-')?;
    if random.is_empty() || pid.is_empty() || !pid.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    pid.parse().ok().filter(|&p| p > 0)
}

/// Whether `pid` names a running process (a process of another user counts as running).
#[cfg(unix)]
fn process_is_running(pid: u32) -> bool {
    let Ok(pid) = libc::pid_t::try_from(pid) else { return true };
    // SAFETY: signal 0 only checks that the process exists; nothing is sent.
    let rc = unsafe { libc::kill(pid, 0) };
    rc == 0 || std::io::Error::last_os_error().raw_os_error() != Some(libc::ESRCH)
}

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
    refuse_special_target(path).map_err(io)?;
    remove_stale_temporaries(&dir);
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
    let prefix = temp_prefix();
    builder.prefix(&prefix).suffix(TEMP_SUFFIX);
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        builder.permissions(std::fs::Permissions::from_mode(ORDINARY_FILE_MODE));
    }
    let mut tmp = builder.tempfile_in(dir)?;
    fill_file(tmp.as_file_mut(), fill)?;
    written(dir);
    refuse_special_target(path)?;
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

    use super::{Fill, ORDINARY_FILE_MODE, TEMP_SUFFIX, fill_file, refuse_special_target, temp_prefix};

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
        // A target that does not exist gets the file's first and only name at once: no
        // temporary name ever appears. (A link cannot replace an existing file: EEXIST.)
        if link(&file, path).is_ok() {
            return Ok(());
        }
        // The unnamed file gets a temporary name (a link cannot replace an existing file), which
        // the rename then moves over the target at once; on any error dropping `linked` removes
        // the name again. A name clash is retried with another random name.
        let mut refused = None;
        let prefix = temp_prefix();
        let linked = tempfile::Builder::new().prefix(&prefix).suffix(TEMP_SUFFIX).make_in(dir, |candidate| {
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
        refuse_special_target(path).map_err(Error::Failed)?;
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

    #[cfg(unix)]
    fn mkfifo(path: &Path) {
        use std::os::unix::ffi::OsStrExt;
        let c = std::ffi::CString::new(path.as_os_str().as_bytes()).unwrap();
        // SAFETY: a valid NUL-terminated path; mkfifo keeps nothing.
        assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0);
    }

    #[cfg(unix)]
    #[test]
    fn a_fifo_a_directory_or_a_link_to_a_device_is_never_replaced() {
        use std::os::unix::fs::FileTypeExt;
        let dir = tempfile::tempdir().unwrap();
        let fifo = dir.path().join("out.fbk");
        mkfifo(&fifo);
        let link = dir.path().join("null.fbk");
        std::os::unix::fs::symlink("/dev/null", &link).unwrap();
        let sub = dir.path().join("sub");
        std::fs::create_dir(&sub).unwrap();
        for (target, kind) in [(&fifo, "a FIFO"), (&link, "a character device"), (&sub, "a directory")] {
            for method in [Method::Best, Method::Named] {
                let e = write_atomic_with(target, &mut |w| w.write_all(b"pack"), method, &mut |_| {}).unwrap_err();
                assert!(e.to_string().contains(kind), "{target:?} {method:?}: {e}");
            }
        }
        assert!(std::fs::symlink_metadata(&fifo).unwrap().file_type().is_fifo());
        assert!(std::fs::symlink_metadata(&link).unwrap().file_type().is_symlink());
        assert!(std::fs::metadata("/dev/null").unwrap().file_type().is_char_device());
        assert_eq!(names(dir.path()), ["null.fbk", "out.fbk", "sub"], "no temporary file left");
    }

    #[test]
    fn temporary_names_carry_the_writer_and_parse_back() {
        let name = format!("{}abc123{TEMP_SUFFIX}", temp_prefix());
        assert_eq!(stale_name_pid(&name), Some(std::process::id()));
        for other in
            [".furbake-abc123.tmp", ".furbake--x.tmp", ".furbake-12-.tmp", "furbake-12-x.tmp", ".furbake-0-x.tmp"]
        {
            assert_eq!(stale_name_pid(other), None, "{other}");
        }
    }

    #[cfg(unix)]
    #[test]
    fn a_write_removes_what_killed_writes_left_and_nothing_of_live_ones() {
        let dir = tempfile::tempdir().unwrap();
        // A process that has exited: its id names no running process (until reused, which the
        // kernel does only after cycling through the id space).
        let mut child = std::process::Command::new("true").spawn().unwrap();
        let dead = child.id();
        child.wait().unwrap();
        let old = std::time::SystemTime::now() - 2 * STALE_AFTER;
        let make = |name: &str, modified: std::time::SystemTime| {
            let path = dir.path().join(name);
            std::fs::write(&path, b"half a pack").unwrap();
            std::fs::File::options().append(true).open(&path).unwrap().set_modified(modified).unwrap();
        };
        make(&format!(".furbake-{dead}-killed{TEMP_SUFFIX}"), old);
        make(&format!(".furbake-{dead}-fresh{TEMP_SUFFIX}"), std::time::SystemTime::now());
        make(&format!("{}live{TEMP_SUFFIX}", temp_prefix()), old);
        make(&format!(".furbake-{dead}-x.json"), old);
        write_file_atomic(&dir.path().join("pack.fbk"), b"pack").unwrap();
        let mut want = vec![
            format!(".furbake-{dead}-fresh{TEMP_SUFFIX}"),
            format!(".furbake-{dead}-x.json"),
            format!("{}live{TEMP_SUFFIX}", temp_prefix()),
            "pack.fbk".to_owned(),
        ];
        want.sort();
        assert_eq!(names(dir.path()), want);
    }
}
