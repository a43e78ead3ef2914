//! `furbake`: the command-line front end. Thin glue: parse flags into a validated plan, call the
//! library crates, print, and map failures to exit codes (0 success, 1 bad input or invalid
//! file, 2 usage error).

mod args;
mod bake_cmd;
mod bake_files;
mod batch_cmd;
mod describe;
mod export_cmd;
mod extract_cmd;
mod failure;
mod files;
mod keyframes_cmd;
mod png;
mod preview_cmd;
mod report_cmd;
mod schema_cmd;
mod shaders_cmd;
mod simulate_cmd;
mod stdout;
mod view_cmd;

use std::process::ExitCode;

use clap::Parser;

use crate::args::{Cli, Command};

/// Most worker threads `--threads` accepts.
const MAX_THREADS: usize = 1024;

fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => {
            // clap prints help/version to stdout (exit 0) and usage errors to stderr (exit 2).
            let _ = e.print();
            return ExitCode::from(if e.use_stderr() { failure::EXIT_USAGE } else { 0 });
        }
    };
    if matches!(cli.command, Command::Preview(_) | Command::View(_)) {
        quiet_wayland_probe();
    }
    if let Some(n) = cli.threads {
        // Part of the plan: checked before any command starts (0 would silently mean "one per
        // core", a huge count exhausts the machine before failing).
        if !(1..=MAX_THREADS).contains(&n) {
            eprintln!("furbake: error: --threads = {n} is out of range (allowed: 1..={MAX_THREADS})");
            return ExitCode::from(failure::EXIT_USAGE);
        }
        if let Err(e) = rayon::ThreadPoolBuilder::new().num_threads(n).build_global() {
            eprintln!("furbake: error: cannot start {n} threads: {e}");
            return ExitCode::from(failure::EXIT_BAD_INPUT);
        }
    }
    let result = match cli.command {
        Command::Bake(a) => bake_cmd::run(a, cli.quiet),
        Command::Batch(a) => batch_cmd::run(a, cli.quiet),
        Command::Inspect(a) => describe::run_inspect(a),
        Command::Verify(a) => describe::run_verify(a, cli.quiet),
        Command::Keyframes(a) => keyframes_cmd::run(a, cli.quiet),
        Command::Preview(a) => preview_cmd::run(a, cli.quiet),
        Command::Simulate(a) => simulate_cmd::run(a, cli.quiet),
        Command::Report(a) => report_cmd::run(a, cli.quiet),
        Command::Extract(a) => extract_cmd::run(a, cli.quiet),
        Command::Export(a) => export_cmd::run(a, cli.quiet),
        Command::Schema(a) => schema_cmd::run(a),
        Command::Shaders(a) => shaders_cmd::run(a, cli.quiet),
        Command::View(a) => view_cmd::run(a, cli.quiet),
    };
    match result {
        Ok(()) | Err(failure::Failure::StdoutClosed) => ExitCode::SUCCESS,
        Err(f) => {
            eprintln!("furbake: error: {}", f.message());
            ExitCode::from(f.code())
        }
    }
}

/// The Vulkan loader probes Wayland, whose client library prints "error: XDG_RUNTIME_DIR is invalid
/// or not set" on headless machines. Give it a private runtime directory so a preview prints only
/// our own messages.
fn quiet_wayland_probe() {
    if std::env::var_os("XDG_RUNTIME_DIR").is_some() {
        return;
    }
    let dir = std::env::temp_dir().join("furbake-xdg-runtime");
    if std::fs::create_dir_all(&dir).is_ok() {
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            let _ = std::fs::set_permissions(&dir, std::fs::Permissions::from_mode(0o700));
        }
        // SAFETY: called from `main` before any thread is started (rayon's pool included), so no
        // other thread can read the environment concurrently.
        unsafe { std::env::set_var("XDG_RUNTIME_DIR", &dir) };
    }
}
