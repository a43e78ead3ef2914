//! Failures of a CLI command and their exit codes: 1 when the input (a mesh, a pack, a config
//! file that cannot be read or is not TOML) is bad or unreadable, 2 when the command line or a
//! setting is wrong (a flag, a `--set`, a config file's key or value). Errors keep this blame
//! through the layers. Messages are one line. A closed stdout is no failure of the command: it
//! ends quietly with exit 0.

/// Exit code for bad input or an invalid file.
pub const EXIT_BAD_INPUT: u8 = 1;
/// Exit code for a usage error (bad flags or settings).
pub const EXIT_USAGE: u8 = 2;

/// A failed command.
#[derive(Debug)]
pub enum Failure {
    /// The input is bad (exit 1).
    Input(anyhow::Error),
    /// The command line or settings are wrong (exit 2).
    Usage(anyhow::Error),
    /// Stdout is a closed pipe (the reader, e.g. `head`, has exited): stop quietly, exit 0.
    StdoutClosed,
}

impl Failure {
    /// The process exit code.
    pub fn code(&self) -> u8 {
        match self {
            Failure::Input(_) => EXIT_BAD_INPUT,
            Failure::Usage(_) => EXIT_USAGE,
            Failure::StdoutClosed => 0,
        }
    }

    /// The whole error chain on one line.
    pub fn message(&self) -> String {
        let e = match self {
            Failure::Input(e) | Failure::Usage(e) => e,
            Failure::StdoutClosed => return String::new(),
        };
        let mut parts: Vec<String> = Vec::new();
        for cause in e.chain() {
            let s = cause.to_string();
            // thiserror's `transparent`/`#[source]` chains often repeat the inner message.
            if !parts.iter().any(|p| p.contains(&s)) {
                parts.push(s);
            }
        }
        parts.join(": ").replace('\n', " ")
    }
}

/// Shorthands to classify any error.
pub trait Classify<T> {
    /// Marks an error as bad input (exit 1).
    fn input(self) -> Result<T, Failure>;
    /// Marks an error as a usage error (exit 2).
    fn usage(self) -> Result<T, Failure>;
}

impl<T, E: Into<anyhow::Error>> Classify<T> for Result<T, E> {
    fn input(self) -> Result<T, Failure> {
        self.map_err(|e| Failure::Input(e.into()))
    }
    fn usage(self) -> Result<T, Failure> {
        self.map_err(|e| Failure::Usage(e.into()))
    }
}

/// A scene in a retired form is a usage error (2); any other bad scene is bad input (1).
pub fn scene(e: furbake_runtime::SceneError) -> Failure {
    match e {
        e @ furbake_runtime::SceneError::Outdated { .. } => Failure::Usage(e.into()),
        e => Failure::Input(e.into()),
    }
}

/// Classifies a runtime error of the scene at `scene_path`.
pub fn runtime(e: furbake_runtime::RuntimeError, scene_path: &std::path::Path) -> Failure {
    match e {
        furbake_runtime::RuntimeError::Scene(e) => scene(e),
        // Every other runtime error blames a file (a pack, a bake without the topology the
        // scene needs) or the simulation of one: bad input.
        e => Failure::Input(anyhow::Error::new(e).context(scene_path.display().to_string())),
    }
}
