//! furbake-capi's tests: the checked-in header against cbindgen's output, the C interface
//! called from Rust (every path a host takes, and the ways it can be misused), and C programs
//! built with the system compiler against the static library.

mod api;
mod c_programs;
mod common;
mod gl_host;
mod header;
