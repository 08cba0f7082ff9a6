//! Helpers shared by the criterion benchmarks (run them with `cargo bench -p assetfield-benches`).

use std::path::{Path, PathBuf};

/// A scene of the suite by file stem, e.g. `scene("conference_room")`.
pub fn scene(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes").join(format!("{name}.ron"))
}
