//! The files a command reads and writes (docs/design.md "Safe outputs" and "Bounded reads"):
//! - [`read_text`]: a config or batch file, read bounded and never blocking
//!   (`furbake_formats::input`);
//! - [`toml_overrides`] / [`table_overrides`]: TOML settings as JSON overrides, a non-finite
//!   number refused naming its key (TOML's `nan` and `inf` would otherwise become JSON `null`,
//!   which reads as "automatic");
//! - [`Files`]: the plan of a command's outputs against its inputs — an output must be a regular
//!   file or not exist, must not be one of the command's inputs and no two outputs may be the
//!   same file, all compared as resolved paths (`o/../o/x.fbk`, symlinks) and by inode (hard
//!   links), before anything is read or written;
//! - [`write_output`]: one output written atomically, or to stdout for `-` where a command
//!   allows a stream.

use std::path::{Path, PathBuf};

use anyhow::anyhow;

use crate::failure::Failure;

/// The output path that means stdout.
pub const STDOUT: &str = "-";

/// Whether `path` is `-` (stdout).
pub fn is_stdout(path: &Path) -> bool {
    path.as_os_str() == STDOUT
}

/// Reads the text file `path` (a config or batch file: `what`) whole: only a regular file of at
/// most `furbake_formats::input::MAX_TEXT_BYTES`, never blocking. Exit 1 naming the file.
pub fn read_text(path: &Path, what: &str) -> Result<String, Failure> {
    furbake_formats::input::read_text(path, what)
        .map_err(|e| Failure::Input(anyhow!("{}: cannot read {what}: {e}", path.display())))
}

/// Parses TOML `text` (from `path`) as settings overrides: invalid TOML is bad input (exit 1), a
/// non-finite number a bad setting (exit 2) naming its key and the file.
pub fn toml_overrides(text: &str, path: &Path) -> Result<serde_json::Value, Failure> {
    let table: toml::Table =
        toml::from_str(text).map_err(|e| Failure::Input(anyhow!("{}: invalid TOML: {e}", path.display())))?;
    table_overrides(&table).map_err(|e| Failure::Usage(anyhow!("{e} (in {})", path.display())))
}

/// A TOML table as JSON overrides; `Err` names the first key holding a non-finite number.
pub fn table_overrides(table: &toml::Table) -> Result<serde_json::Value, String> {
    let mut object = serde_json::Map::new();
    for (key, value) in table {
        object.insert(key.clone(), json_of(value, key)?);
    }
    Ok(serde_json::Value::Object(object))
}

fn json_of(value: &toml::Value, key: &str) -> Result<serde_json::Value, String> {
    use serde_json::Value as J;
    Ok(match value {
        toml::Value::Float(f) => match serde_json::Number::from_f64(*f) {
            Some(n) => J::Number(n),
            None => return Err(format!("{key}: {f} is not a finite number")),
        },
        toml::Value::Integer(i) => J::from(*i),
        toml::Value::String(s) => J::String(s.clone()),
        toml::Value::Boolean(b) => J::Bool(*b),
        toml::Value::Datetime(d) => J::String(d.to_string()),
        toml::Value::Array(items) => J::Array(
            items.iter().enumerate().map(|(i, v)| json_of(v, &format!("{key}[{i}]"))).collect::<Result<_, _>>()?,
        ),
        toml::Value::Table(t) => {
            let mut object = serde_json::Map::new();
            for (k, v) in t {
                object.insert(k.clone(), json_of(v, &format!("{key}.{k}"))?);
            }
            J::Object(object)
        }
    })
}

/// Which file a path names: its resolved path (symlinks followed; a file that does not exist yet
/// is its resolved directory joined with its name) and, when it exists, its device and inode.
#[derive(Clone, Debug)]
struct Identity {
    resolved: PathBuf,
    inode: Option<(u64, u64)>,
}

impl Identity {
    fn of(path: &Path) -> Identity {
        let resolved = std::fs::canonicalize(path).unwrap_or_else(|_| resolve_missing(path));
        Identity { resolved, inode: inode(path) }
    }

    fn same(&self, other: &Identity) -> bool {
        self.resolved == other.resolved || (self.inode.is_some() && self.inode == other.inode)
    }
}

#[cfg(unix)]
fn inode(path: &Path) -> Option<(u64, u64)> {
    use std::os::unix::fs::MetadataExt;
    std::fs::metadata(path).ok().map(|m| (m.dev(), m.ino()))
}

#[cfg(not(unix))]
fn inode(_path: &Path) -> Option<(u64, u64)> {
    None
}

/// The resolved form of a path that does not exist (yet): its directory resolved, then its
/// name; `..` and `.` folded lexically where the directory does not exist either.
fn resolve_missing(path: &Path) -> PathBuf {
    let absolute = std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf());
    let (Some(parent), Some(name)) = (absolute.parent(), absolute.file_name()) else { return absolute };
    match std::fs::canonicalize(parent) {
        Ok(dir) => dir.join(name),
        Err(_) => {
            let mut out = PathBuf::new();
            for c in absolute.components() {
                match c {
                    std::path::Component::ParentDir => {
                        out.pop();
                    }
                    std::path::Component::CurDir => {}
                    other => out.push(other),
                }
            }
            out
        }
    }
}

/// A command's inputs and outputs, checked against each other as they are added.
#[derive(Default)]
pub struct Files {
    inputs: Vec<(PathBuf, Identity)>,
    outputs: Vec<(String, PathBuf, Identity)>,
}

impl Files {
    /// A plan with these inputs.
    pub fn with_inputs<'a>(inputs: impl IntoIterator<Item = &'a Path>) -> Files {
        let mut files = Files::default();
        for p in inputs {
            files.input(p);
        }
        files
    }

    /// Adds an input. An input added after an output that is the same file is caught by
    /// [`Files::check_inputs`].
    pub fn input(&mut self, path: &Path) {
        self.inputs.push((path.to_path_buf(), Identity::of(path)));
    }

    /// Adds the output of `flag` (`--output`, `--depfile`, …; the message names it) that may be
    /// `-`, stdout, which is never a file and always passes; otherwise as [`Files::output`].
    pub fn stream_output(&mut self, flag: &str, path: &Path) -> Result<(), Failure> {
        if is_stdout(path) { Ok(()) } else { self.output(flag, path) }
    }

    /// Adds the output of `flag` (`--output`, `--depfile`, …; the message names it): refused
    /// (exit 2) when it is `-` (this output cannot be a stream), when it exists and is not a
    /// regular file, when it is one of the inputs, or when it is the same file as an earlier
    /// output.
    pub fn output(&mut self, flag: &str, path: &Path) -> Result<(), Failure> {
        let refuse = |what: String| Failure::Usage(anyhow!("{flag} {}: {what}", path.display()));
        if let Ok(m) = std::fs::metadata(path) {
            if let Some(kind) = furbake_formats::input::irregular_kind(m.file_type()) {
                return Err(refuse(format!(
                    "is {kind}; an output must be a regular file or not exist yet (furbake never replaces anything else)"
                )));
            }
        }
        if is_stdout(path) {
            return Err(refuse("this output cannot be stdout; name a file".to_owned()));
        }
        let id = Identity::of(path);
        if let Some((input, _)) = self.inputs.iter().find(|(_, i)| i.same(&id)) {
            return Err(refuse(format!("is the input {}; furbake never writes over its inputs", input.display())));
        }
        if let Some((other, other_path, _)) = self.outputs.iter().find(|(_, _, o)| o.same(&id)) {
            return Err(refuse(format!("is the same file as {other} {}", other_path.display())));
        }
        self.outputs.push((flag.to_owned(), path.to_path_buf(), id));
        Ok(())
    }

    /// Refuses (exit 1: the input named it) an input that is the same file as an output: the
    /// files a glTF names (its buffers and images) are known only once it is read, and must not
    /// be written over either (`bake scene.gltf -o scene.bin`).
    pub fn check_inputs<'a>(&self, inputs: impl IntoIterator<Item = &'a Path>) -> Result<(), Failure> {
        for input in inputs {
            let id = Identity::of(input);
            if let Some((flag, out, _)) = self.outputs.iter().find(|(_, _, o)| o.same(&id)) {
                return Err(Failure::Input(anyhow!(
                    "{flag} {}: is the input {}; furbake never writes over its inputs",
                    out.display(),
                    input.display()
                )));
            }
        }
        Ok(())
    }
}

/// Writes `bytes` to `path` atomically (`furbake_formats::write_file_atomic`), or to stdout when
/// `path` is `-`; `what` names the output in errors ("the pack").
pub fn write_output(path: &Path, bytes: &[u8], what: &str) -> Result<(), Failure> {
    if is_stdout(path) {
        use std::io::Write;
        let mut out = std::io::stdout().lock();
        return out.write_all(bytes).and_then(|()| out.flush()).map_err(|e| match e.kind() {
            std::io::ErrorKind::BrokenPipe => Failure::StdoutClosed,
            _ => Failure::Input(anyhow!("cannot write {what} to stdout: {e}")),
        });
    }
    furbake_formats::write_file_atomic(path, bytes)
        .map_err(|e| Failure::Input(anyhow::Error::new(e).context(format!("cannot write {what}"))))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn non_finite_toml_numbers_are_refused_by_key() {
        let table: toml::Table = toml::from_str("[volume]\nlayers = 4\n[shells]\nfur_length_m = nan\n").unwrap();
        assert_eq!(table_overrides(&table).unwrap_err(), "shells.fur_length_m: NaN is not a finite number");
        let table: toml::Table = toml::from_str("a = [1.0, -inf]\n").unwrap();
        assert_eq!(table_overrides(&table).unwrap_err(), "a[1]: -inf is not a finite number");
        let table: toml::Table = toml::from_str("seed = 3\n[x]\ny = 0.5\nz = \"s\"\n").unwrap();
        assert_eq!(table_overrides(&table).unwrap(), serde_json::json!({"seed": 3, "x": {"y": 0.5, "z": "s"}}));
    }

    #[test]
    fn one_file_spelled_two_ways_is_one_file() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        std::fs::create_dir(d.join("o")).unwrap();
        std::fs::write(d.join("in.glb"), b"x").unwrap();
        let mut files = Files::with_inputs([d.join("in.glb").as_path()]);
        files.output("--output", &d.join("o/x.fbk")).unwrap();
        let e = files.output("--depfile", &d.join("o/../o/x.fbk")).unwrap_err();
        assert!(e.message().contains("is the same file as --output"), "{}", e.message());
        assert_eq!(e.code(), 2);
        let e = files.output("--report", &d.join("o/../in.glb")).unwrap_err();
        assert!(e.message().contains("is the input"), "{}", e.message());
        #[cfg(unix)]
        {
            std::os::unix::fs::symlink(d.join("in.glb"), d.join("link.glb")).unwrap();
            assert!(files.output("--report", &d.join("link.glb")).is_err(), "a symlink to the input");
            std::fs::hard_link(d.join("in.glb"), d.join("hard.glb")).unwrap();
            assert!(files.output("--report", &d.join("hard.glb")).is_err(), "a hard link to the input");
            let e = files.output("--report", Path::new("/dev/null")).unwrap_err();
            assert!(e.message().contains("is a character device"), "{}", e.message());
        }
        let e = files.output("--report", d).unwrap_err();
        assert!(e.message().contains("is a directory"), "{}", e.message());
        files.stream_output("--report", Path::new("-")).unwrap();
        assert!(files.output("--depfile", Path::new("-")).is_err());
        files.output("--report", &d.join("o/report.json")).unwrap();
        assert!(files.check_inputs([d.join("o/./report.json").as_path()]).is_err());
        assert!(files.check_inputs([d.join("in.glb").as_path()]).is_ok());
    }
}
