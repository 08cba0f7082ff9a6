//! What the CLI does when its surroundings misbehave: a reader that closes the pipe early, a
//! run killed outright that left its temporaries behind.

use assetfield_tests::{repo, run_cli, scratch};
use std::io::Read;
use std::process::{Command, Stdio};

#[test]
fn a_reader_that_stops_early_is_no_failure() {
    let dir = scratch("robust-pipe");
    // 2500 instances: the table is far more than a pipe holds (64 KiB), so the writer is
    // still writing when the reader leaves
    let script = "Scene(\n  assets: {\n    \"a\": Asset(parts: [Box(center: (0, 0, 0.5), size: (0.5, 0.5, 1), color: (1, 0, 0))]),\n  },\n  layout: [Grid(asset: \"a\", center: (0, 0), rows: 50, cols: 50, spacing: (1, 1))],\n)\n";
    std::fs::write(dir.join("big.ron"), script).unwrap();
    // `assetfield layout big.ron | head -c 1`
    let mut child = Command::new(assetfield_tests::assetfield_bin())
        .args(["layout", "big.ron"])
        .current_dir(&dir)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut stdout = child.stdout.take().unwrap();
    let mut first = [0u8; 1];
    stdout.read_exact(&mut first).unwrap();
    drop(stdout);
    let out = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!err.contains("panicked"), "{err}");
    assert_eq!(out.status.code(), Some(0), "{err}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_killed_synth_s_staging_folder_goes_with_the_next_run() {
    let dir = scratch("robust-stale-synth");
    // what `synth --out d` leaves when killed by SIGKILL half way: a hidden staging folder
    // named after a process that is gone
    let stale = dir.join(".d.tmp-4194305");
    std::fs::create_dir_all(stale.join("train")).unwrap();
    std::fs::write(stale.join("train/r_0.png"), b"half").unwrap();
    let scene = repo().join("scenes/plaza.ron");
    let args = ["synth", scene.to_str().unwrap(), "--out", "d", "--views", "3"];
    let (code, _, err) =
        run_cli(&dir, &[&args[..], &["--test-views", "1", "--res", "16"]].concat());
    assert_eq!(code, 0, "{err}");
    assert!(dir.join("d/transforms_train.json").is_file());
    let names: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert_eq!(names, ["d"], "only the finished output stays");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_limit_is_raised_by_a_flag_as_the_error_says() {
    let dir = scratch("robust-limit");
    let script = "Scene(\n  assets: {\n    \"a\": Asset(parts: [Box(center: (0, 0, 0.5), size: (0.5, 0.5, 1), color: (1, 0, 0))]),\n  },\n  layout: [Row(asset: \"a\", from: (0, 0), to: (10, 0), count: 20)],\n)\n";
    std::fs::write(dir.join("row.ron"), script).unwrap();
    let (code, _, err) = run_cli(&dir, &["layout", "row.ron", "--limit", "instances=10"]);
    assert_eq!(code, 1, "{err}");
    assert!(err.contains("row.ron:5:12"), "{err}");
    assert!(err.contains("--limit instances=N"), "{err}");
    let (code, out, err) = run_cli(&dir, &["layout", "row.ron", "--limit", "instances=20"]);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("20 instances"), "{out}");
    let (code, _, err) = run_cli(&dir, &["layout", "row.ron", "--limit", "instancez=20"]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("unknown limit") && err.contains("scatter-tries"), "{err}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn field_size_bounds_move_with_a_flag() {
    let dir = scratch("robust-plane-res");
    // the default bound, named with the flag that moves it
    let (code, _, err) =
        run_cli(&dir, &["train", "nodata", "--out", "f.safetensors", "--res", "5000"]);
    assert_eq!(code, 1, "{err}");
    assert!(err.contains("at most 4096") && err.contains("--limit plane-res=N"), "{err}");
    // raised, the same --res passes this check (and fails on the missing dataset instead)
    let args = ["--limit", "plane-res=8192", "train", "nodata", "--out", "f.safetensors"];
    let (code, _, err) = run_cli(&dir, &[&args[..], &["--res", "5000"]].concat());
    assert_eq!(code, 1, "{err}");
    assert!(!err.contains("too large") && err.contains("nodata"), "{err}");
    // lowered, a field file larger than the bound is refused on loading, naming the key
    let field = repo().join("tests/data/living_room_s128.safetensors");
    let (code, _, err) =
        run_cli(&dir, &["--limit", "plane-res=64", "eval", field.to_str().unwrap(), "--out", "ev"]);
    assert_eq!(code, 1, "{err}");
    assert!(err.contains("\"res[0]\" is 128, expected 2 to 64"), "{err}");
    std::fs::remove_dir_all(&dir).unwrap();
}
