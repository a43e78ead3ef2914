//! The checked-in `include/furbake.h` is what cbindgen makes of the crate today.

use std::path::Path;

/// Fails when `include/furbake.h` is stale; `FURBAKE_BLESS=1` (what `make capi-header` sets)
/// rewrites it instead.
#[test]
fn the_checked_in_header_is_cbindgens_output() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"));
    let config = cbindgen::Config::from_file(dir.join("cbindgen.toml")).unwrap();
    let bindings = cbindgen::Builder::new().with_crate(dir).with_config(config).generate().unwrap();
    let mut made = Vec::new();
    bindings.write(&mut made);
    let path = dir.join("include/furbake.h");
    if std::env::var_os("FURBAKE_BLESS").is_some() {
        std::fs::write(&path, &made).unwrap();
        return;
    }
    let checked_in = std::fs::read(&path).unwrap_or_default();
    assert!(checked_in == made, "{} is stale: run `make capi-header` and commit it", path.display());
}
