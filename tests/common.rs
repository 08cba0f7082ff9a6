//! Shared helpers of the workspace-level integration tests.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// The repository root.
pub fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("tests/ sits in the repository")
        .to_path_buf()
}

/// Every scene script of the suite (`scenes/*.ron`, not the shared asset files).
pub fn scene_files() -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(repo().join("scenes"))
        .expect("scenes/ exists")
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "ron"))
        .collect();
    v.sort();
    v
}

/// The shared real data folder, or `None` (with a message) when it is absent.
pub fn shared_data(name: &str) -> Option<PathBuf> {
    let p = repo().join("../shared/data").join(name);
    if p.is_dir() {
        Some(p)
    } else {
        eprintln!("skipping: {} not found (real data lives in ../shared/data)", p.display());
        None
    }
}

/// A fresh scratch folder unique to this process and `name`.
pub fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("assetfield-it-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).expect("temp dir is writable");
    d
}

/// The `assetfield` binary next to the test executable, brought up to date once per test
/// process.
pub fn assetfield_bin() -> PathBuf {
    static BUILT: std::sync::OnceLock<PathBuf> = std::sync::OnceLock::new();
    BUILT
        .get_or_init(|| {
            let exe = std::env::current_exe().expect("test executable path");
            let dir = exe.parent().and_then(Path::parent).expect("target/<profile>/deps");
            let bin = dir.join(format!("assetfield{}", std::env::consts::EXE_SUFFIX));
            // always (re)build once per test process: a stale binary from an earlier build
            // would test old code (cheap when it is up to date)
            let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
            let status = Command::new(cargo)
                .args(["build", "-p", "assetfield-cli", "--bin", "assetfield"])
                .current_dir(repo())
                .status()
                .expect("cargo runs");
            assert!(status.success(), "building the assetfield binary failed");
            bin
        })
        .clone()
}

/// Run `assetfield ARGS...` in `cwd`; returns (exit code, stdout, stderr).
pub fn run_cli(cwd: &Path, args: &[&str]) -> (i32, String, String) {
    let Output { status, stdout, stderr } = Command::new(assetfield_bin())
        .args(args)
        .current_dir(cwd)
        .output()
        .expect("assetfield runs");
    (
        status.code().unwrap_or(-1),
        String::from_utf8_lossy(&stdout).into_owned(),
        String::from_utf8_lossy(&stderr).into_owned(),
    )
}
