//! Writing to stdout. `println!` panics when stdout is a closed pipe (`furbake inspect PACK |
//! head -1` once `head` has exited); every command prints through [`write`](fn@write) instead, which turns
//! `BrokenPipe` into [`Failure::StdoutClosed`]: `main` ends the command quietly with exit 0, as
//! other Unix tools do (ripgrep does the same). Any other write error is a failure (exit 1).

use std::io::{ErrorKind, Write};

use anyhow::anyhow;

use crate::failure::Failure;

/// Writes `text` to stdout and flushes it.
pub fn write(text: &str) -> Result<(), Failure> {
    let mut out = std::io::stdout().lock();
    out.write_all(text.as_bytes()).and_then(|()| out.flush()).map_err(|e| match e.kind() {
        ErrorKind::BrokenPipe => Failure::StdoutClosed,
        _ => Failure::Input(anyhow!("cannot write to stdout: {e}")),
    })
}

/// Writes `line` and a newline to stdout.
pub fn line(line: impl std::fmt::Display) -> Result<(), Failure> {
    write(&format!("{line}\n"))
}
