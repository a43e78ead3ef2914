//! `furbake`: the command-line front end. Thin glue: parse flags into a validated plan, call the
//! library crates, print, and map failures to exit codes (0 success, 1 bad input or invalid
//! file, 2 usage error).

mod args;
mod bake_cmd;
mod describe;
mod extract_cmd;
mod failure;
mod keyframes_cmd;
mod png;

use std::process::ExitCode;

use clap::Parser;

use crate::args::{Cli, Command};

fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => {
            // clap prints help/version to stdout (exit 0) and usage errors to stderr (exit 2).
            let _ = e.print();
            return ExitCode::from(if e.use_stderr() { failure::EXIT_USAGE } else { 0 });
        }
    };
    if let Some(n) = cli.threads {
        if let Err(e) = rayon::ThreadPoolBuilder::new().num_threads(n).build_global() {
            eprintln!("furbake: error: cannot start {n} threads: {e}");
            return ExitCode::from(failure::EXIT_BAD_INPUT);
        }
    }
    let result = match cli.command {
        Command::Bake(a) => bake_cmd::run(a, cli.quiet),
        Command::Inspect(a) => describe::run_inspect(a),
        Command::Verify(a) => describe::run_verify(a, cli.quiet),
        Command::Keyframes(a) => keyframes_cmd::run(a, cli.quiet),
        Command::Extract(a) => extract_cmd::run(a, cli.quiet),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(f) => {
            eprintln!("furbake: error: {}", f.message());
            ExitCode::from(f.code())
        }
    }
}
