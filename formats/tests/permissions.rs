//! Files written by [`write_file_atomic`] get the permissions of an ordinary file write
//! (`0o666` minus the umask), not the `0o600` of a private temporary file.
//!
//! Regression: the temporary file was created with `tempfile`'s default mode `0o600` and renamed
//! into place, so every baked pack, PNG and JSON was unreadable to other users (a web server, a
//! second account in an asset pipeline). This test is its own binary because the umask it sets
//! is process-wide: no other test runs beside it.

#![cfg(unix)]

use std::os::unix::fs::PermissionsExt;

use furbake_formats::{PackWriter, write_file_atomic};

#[test]
fn atomic_writes_get_0644_under_umask_022_and_leave_no_temporary_file() {
    // SAFETY: `umask` only swaps the process's file-mode creation mask; it cannot fail.
    let previous = unsafe { libc::umask(0o022) };
    let dir = tempfile::tempdir().unwrap();
    let plain = dir.path().join("plain.json");
    write_file_atomic(&plain, b"{}\n").unwrap();
    let pack = dir.path().join("empty.fbk");
    PackWriter::new().write_atomic(&pack).unwrap();
    // Overwriting an existing file keeps the rule (the rename replaces it with the new file).
    write_file_atomic(&plain, b"{\"again\":1}\n").unwrap();
    let mut checked = 0;
    for path in [&plain, &pack] {
        let mode = std::fs::metadata(path).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode, 0o644, "{}: mode {mode:o}", path.display());
        checked += 1;
    }
    assert_eq!(checked, 2);
    // A failed write (the target is a directory) removes its temporary file.
    let blocker = dir.path().join("a-directory");
    std::fs::create_dir(&blocker).unwrap();
    assert!(write_file_atomic(&blocker, b"x").is_err());
    let names: Vec<String> =
        std::fs::read_dir(dir.path()).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
    assert!(names.iter().all(|n| !n.ends_with(".tmp")), "temporary file left behind: {names:?}");
    assert_eq!(names.len(), 3, "{names:?}");
    // SAFETY: as above; restores the mask this process started with.
    unsafe { libc::umask(previous) };
}
