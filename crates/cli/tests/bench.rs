//! `assetfield bench render|reconfigure` end to end at tiny sizes: the JSON has its keys, the
//! table its rows, `--backend auto` without an adapter falls back to the CPU with one line on
//! stderr, `--backend gpu` without one is a clear error (never a panic), and on a GPU (or
//! lavapipe) the GPU path runs.

use serde_json::Value;
use std::process::Command;

/// Run `assetfield ARGS` with extra environment; (exit code, stdout, stderr).
fn run(args: &[&str], env: &[(&str, &str)]) -> (i32, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_assetfield"))
        .args(args)
        .envs(env.iter().copied())
        .env("XDG_RUNTIME_DIR", std::env::var("XDG_RUNTIME_DIR").unwrap_or("/tmp".into()))
        .output()
        .expect("assetfield runs");
    let text = |b: Vec<u8>| String::from_utf8_lossy(&b).into_owned();
    (out.status.code().unwrap_or(-1), text(out.stdout), text(out.stderr))
}

fn json(stdout: &str) -> Value {
    serde_json::from_str(stdout).unwrap_or_else(|e| panic!("not JSON ({e}):\n{stdout}"))
}

fn num(v: &Value, key: &str) -> f64 {
    v[key].as_f64().unwrap_or_else(|| panic!("{key} missing or not a number in {v}"))
}

/// No wgpu adapter can be found: only the GL backend, which this build does not have.
const NO_ADAPTER: [(&str, &str); 1] = [("WGPU_BACKEND", "gl")];

#[test]
fn reconfigure_on_the_cpu_reports_every_count() {
    let args = [
        "bench",
        "reconfigure",
        "--instances",
        "10",
        "--layouts",
        "2",
        "--res",
        "16",
        "--backend",
        "cpu",
        "--json",
    ];
    let (code, out, err) = run(&args, &[]);
    assert_eq!(code, 0, "{err}");
    assert!(!err.contains("adapter"), "cpu looks for no device: {err}");
    let v = json(&out);
    assert_eq!(v["command"], "bench reconfigure");
    assert_eq!(v["backend"], "cpu");
    assert!(v["adapter"].is_null() && v["scene"].as_str().unwrap().starts_with("synthetic"));
    assert_eq!((v["res"].as_u64(), v["layouts"].as_u64()), (Some(16), Some(2)));
    let rows = v["rows"].as_array().unwrap();
    assert_eq!(rows.len(), 1);
    let r = &rows[0];
    assert_eq!(r["instances"].as_u64(), Some(10));
    for key in
        ["layouts_per_s", "ms_per_layout", "move_one_ms", "full_raster_ms", "full_with_grid_ms"]
    {
        assert!(num(r, key) > 0.0, "{key} in {r}");
    }
    // a move redraws a small part of what a full redraw does
    assert!(num(r, "move_one_texels") > 0.0);
    assert!(num(r, "move_one_texels") * 10.0 < num(r, "full_raster_texels"), "{r}");
}

#[test]
fn reconfigure_prints_a_table_row_per_count() {
    let args = [
        "bench",
        "reconfigure",
        "--instances",
        "3,6",
        "--layouts",
        "1",
        "--res",
        "8",
        "--moves",
        "2",
        "--backend",
        "cpu",
    ];
    let (code, out, err) = run(&args, &[]);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("layouts/s") && out.contains("move one (ms)"), "{out}");
    let rows: Vec<&str> = out
        .lines()
        .filter(|l| l.split_whitespace().next().is_some_and(|w| w == "3" || w == "6"))
        .collect();
    assert_eq!(rows.len(), 2, "{out}");
}

#[test]
fn render_on_the_cpu_reports_frames_and_the_batch() {
    let args = [
        "bench",
        "render",
        "--res",
        "16",
        "--instances",
        "5",
        "--frames",
        "2",
        "--batch",
        "2",
        "--views",
        "1",
        "--backend",
        "cpu",
        "--json",
    ];
    let (code, out, err) = run(&args, &[]);
    assert_eq!(code, 0, "{err}");
    let v = json(&out);
    assert_eq!((v["command"].as_str(), v["backend"].as_str()), (Some("bench render"), Some("cpu")));
    assert_eq!((v["res"].as_u64(), v["instances"].as_u64()), (Some(16), Some(5)));
    for key in ["ms_per_frame", "min_ms_per_frame", "rays_per_s", "first_frame_ms", "setup_ms"] {
        assert!(num(&v, key) > 0.0, "{key} in {v}");
    }
    let b = &v["batch"];
    assert_eq!((b["layouts"].as_u64(), b["views"].as_u64()), (Some(2), Some(1)));
    assert!(num(b, "layouts_per_s") > 0.0 && num(b, "rays_per_s") > 0.0, "{b}");
    // no batch
    let (code, out, _) = run(
        &[
            "bench",
            "render",
            "--res",
            "8",
            "--instances",
            "2",
            "--frames",
            "1",
            "--batch",
            "0",
            "--backend",
            "cpu",
            "--json",
        ],
        &[],
    );
    assert_eq!(code, 0);
    assert!(json(&out)["batch"].is_null());
}

#[test]
fn auto_without_an_adapter_says_so_once_and_uses_the_cpu() {
    let args = [
        "bench",
        "render",
        "--res",
        "8",
        "--instances",
        "2",
        "--frames",
        "1",
        "--batch",
        "0",
        "--json",
    ];
    let (code, out, err) = run(&args, &NO_ADAPTER);
    assert_eq!(code, 0, "{err}");
    assert_eq!(json(&out)["backend"], "cpu");
    let notes: Vec<&str> = err.lines().filter(|l| !l.trim().is_empty()).collect();
    assert_eq!(notes.len(), 1, "one line on stderr, got:\n{err}");
    assert!(notes[0].contains("no wgpu adapter") && notes[0].contains("CPU"), "{err}");
}

#[test]
fn gpu_without_an_adapter_is_a_clear_error() {
    let args = [
        "bench",
        "reconfigure",
        "--instances",
        "2",
        "--layouts",
        "1",
        "--res",
        "8",
        "--backend",
        "gpu",
    ];
    let (code, out, err) = run(&args, &NO_ADAPTER);
    assert_eq!(code, 1, "stdout:\n{out}\nstderr:\n{err}");
    assert!(err.contains("no wgpu adapter") && err.contains("--backend cpu"), "{err}");
    assert!(!err.contains("panicked"), "{err}");
}

#[test]
fn bad_counts_are_refused() {
    let (code, _, err) =
        run(&["bench", "reconfigure", "--instances", "0", "--backend", "cpu"], &[]);
    assert_eq!(code, 1);
    assert!(err.contains("--instances"), "{err}");
    let (code, _, err) = run(&["bench", "render", "--frames", "0", "--backend", "cpu"], &[]);
    assert_eq!(code, 1);
    assert!(err.contains("--frames"), "{err}");
}

/// The GPU path at tiny sizes, on whatever adapter exists (lavapipe without a GPU).
#[test]
fn reconfigure_and_render_on_the_gpu() {
    let args = [
        "bench",
        "reconfigure",
        "--instances",
        "10",
        "--layouts",
        "2",
        "--res",
        "16",
        "--moves",
        "2",
        "--backend",
        "gpu",
        "--json",
    ];
    let (code, out, err) = run(&args, &[]);
    if code != 0 && err.contains("no wgpu adapter") {
        eprintln!("SKIPPED: no wgpu adapter ({}); the GPU bench did not run", err.trim());
        return;
    }
    assert_eq!(code, 0, "{err}");
    let v = json(&out);
    assert_eq!(v["backend"], "gpu");
    assert!(v["adapter"].as_str().is_some_and(|a| !a.is_empty()));
    let r = &v["rows"][0];
    assert!(num(r, "layouts_per_s") > 0.0 && num(r, "full_with_grid_ms") > 0.0, "{r}");
    assert!(num(r, "move_one_texels") * 10.0 < num(r, "full_raster_texels"), "{r}");
    let args = [
        "bench",
        "render",
        "--res",
        "16",
        "--instances",
        "5",
        "--frames",
        "1",
        "--batch",
        "2",
        "--views",
        "2",
        "--backend",
        "gpu",
        "--json",
    ];
    let (code, out, err) = run(&args, &[]);
    assert_eq!(code, 0, "{err}");
    let v = json(&out);
    assert_eq!(v["backend"], "gpu");
    assert!(num(&v, "rays_per_s") > 0.0 && num(&v["batch"], "layouts_per_s") > 0.0, "{v}");
}
