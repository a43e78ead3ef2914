//! furbake-report's integration tests, one binary; `rendering` needs the default `render`
//! feature. Run one subject with `cargo test -p furbake-report --test report <module>::`.

#[cfg(feature = "render")]
mod rendering;
mod tiny_report;
