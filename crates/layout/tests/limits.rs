//! Scripts that ask for unbounded work or give nonsense numbers: each is refused quickly,
//! with the script's file:line:col, the limit and how to raise it. One test per reproducer
//! of the reliability issue.

use assetfield_layout::{
    LayoutError, Limit, Limits, LoadedScript, PartsCatalog, ResolvedLayout, load_str_with,
    load_with, resolve,
};
use std::fmt::Write;
use std::path::{Path, PathBuf};
use std::sync::mpsc;
use std::time::Duration;

const ASSETS: &str = r#"    assets: {
        "a": Asset(parts: [Box(center: (0, 0, 0.25), size: (0.2, 0.2, 0.5), color: (1, 0, 0))]),
    },"#;

/// A scene (`test.ron`) with the `layout` and `edits` bodies given.
fn scene(layout: &str, edits: &str) -> String {
    format!("Scene(\n{ASSETS}\n    layout: [\n{layout}\n    ],\n    edits: [\n{edits}\n    ],\n)\n")
}

fn resolve_text(text: &str, limits: &Limits) -> Result<ResolvedLayout, LayoutError> {
    let loaded = load_str_with(Path::new("test.ron"), text, limits)?;
    resolve(&loaded, &PartsCatalog::from_script(&loaded))
}

/// The error of resolving `text`, with the 1-based line of the first line containing `at`.
fn error_at(text: &str, limits: &Limits, at: &str) -> (LayoutError, usize) {
    let line = text.lines().position(|l| l.contains(at)).expect("marker in text") + 1;
    match resolve_text(text, limits) {
        Ok(l) => panic!("expected an error, got {} instances", l.instances.len()),
        Err(e) => (e, line),
    }
}

/// Assert `e` is the instance limit, at `test.ron:line:col`.
fn assert_instance_limit(e: &LayoutError, line: usize, col: usize) {
    let msg = e.to_string();
    assert!(msg.starts_with(&format!("test.ron:{line}:{col}: ")), "{msg}");
    assert!(matches!(e, LayoutError::Limit { limit: Limit::Instances, .. }), "{msg}");
    assert!(msg.contains("limit of 1000000 instances per script"), "{msg}");
    assert!(msg.contains("ASSETFIELD_MAX_INSTANCES=N"), "{msg}");
}

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("af-limits-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Run `f` on a thread; fail (instead of hanging the suite) if it takes over `secs`.
fn within<T: Send + 'static>(secs: u64, f: impl FnOnce() -> T + Send + 'static) -> T {
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        let _ = tx.send(f());
    });
    rx.recv_timeout(Duration::from_secs(secs))
        .unwrap_or_else(|_| panic!("did not return within {secs} s"))
}

#[test]
fn scatter_of_a_billion_in_a_small_region_is_refused_before_trying() {
    let limits = Limits::default();
    let text = scene(
        r#"        Scatter(asset: "a", region: Rect(min: (0, 0), max: (10, 10)), count: 1000000000, min_distance: 1.0),"#,
        "",
    );
    let (e, line) = within(10, move || error_at(&text, &limits, "Scatter("));
    assert_instance_limit(&e, line, 9);
    // under the instance limit, the region's capacity refuses it: 10 x 10 holds ~150 points
    // 1 apart, so 1000 cannot fit (and no try is made)
    let text = scene(
        r#"        Scatter(asset: "a", region: Rect(min: (0, 0), max: (10, 10)), count: 1000, min_distance: 1.0),"#,
        "",
    );
    let (e, line) = error_at(&text, &limits, "Scatter(");
    let msg = e.to_string();
    assert!(msg.starts_with(&format!("test.ron:{line}:9: ")), "{msg}");
    assert!(msg.contains("could place only 153 of 1000"), "{msg}");
    assert!(msg.contains("known before any try"), "{msg}");
}

#[test]
fn scatter_tries_are_bounded_per_script() {
    // 100 instances at most 0.05 apart need few tries each; 2 scatters of 60 with a budget
    // of 100 tries run out in the second one
    let limits = Limits { max_scatter_tries: 100, ..Limits::default() };
    let text = scene(
        r#"        Scatter(asset: "a", region: Rect(min: (0, 0), max: (50, 50)), count: 60, min_distance: 0.05, seed: 1, name: "s1"),
        Scatter(asset: "a", region: Rect(min: (60, 0), max: (110, 50)), count: 60, min_distance: 0.05, seed: 2, name: "s2"),"#,
        "",
    );
    let (e, line) = error_at(&text, &limits, "name: \"s2\"");
    let msg = e.to_string();
    assert!(
        matches!(e, LayoutError::Limit { limit: Limit::ScatterTries, value: 100, .. }),
        "{msg}"
    );
    assert!(msg.starts_with(&format!("test.ron:{line}:9: ")), "{msg}");
    assert!(msg.contains("ASSETFIELD_MAX_SCATTER_TRIES=N"), "{msg}");
    // with the default budget the same script resolves
    assert_eq!(resolve_text(&text, &Limits::default()).unwrap().instances.len(), 120);
}

#[test]
fn row_of_four_billion_is_refused_before_allocating() {
    let text =
        scene(r#"        Row(asset: "a", from: (0, 0), to: (10, 0), count: 4294967295),"#, "");
    let (e, line) = within(10, move || error_at(&text, &Limits::default(), "Row("));
    assert_instance_limit(&e, line, 9);
    assert!(e.to_string().contains("Row(count: 4294967295) would place 4294967295"), "{e}");
}

#[test]
fn every_generator_counts_against_the_instance_limit() {
    let limits = Limits { max_instances: 1000, ..Limits::default() };
    let cases = [
        r#"        Grid(asset: "a", center: (0, 0), rows: 4294967295, cols: 4294967295, spacing: (1, 1)),"#,
        r#"        Ring(asset: "a", center: (0, 0), radius: 5, count: 3000000000),"#,
        r#"        Along(asset: "a", path: [(0, 0), (1000, 0)], spacing: 0.0000001),"#,
        r#"        Along(asset: "a", path: [(0, 0), (3e38, 0)], spacing: 1e-30),"#,
        r#"        Row(asset: "a", from: (0, 0), to: (10, 0), count: 600), Row(asset: "a", from: (0, 1), to: (10, 1), count: 600),"#,
    ];
    for layout in cases {
        let text = scene(layout, "");
        let marker = layout.trim().split('(').next().unwrap();
        let (e, line) = within(10, move || error_at(&text, &limits, marker));
        let msg = e.to_string();
        assert!(msg.starts_with(&format!("test.ron:{line}:")), "{msg}");
        assert!(
            matches!(e, LayoutError::Limit { limit: Limit::Instances, value: 1000, .. }),
            "{msg}"
        );
    }
    // groups standing on many hosts: 30 x 30 hosts, 30 children each, would be 27,900
    let text = scene(
        r#"        Grid(asset: "a", center: (0, 0), rows: 30, cols: 30, spacing: (1, 1), name: "g"),
        Group(on: "g[*]", children: [
            Row(asset: "a", from: (0, 0), to: (0.1, 0), count: 30, name: "r"),
        ]),"#,
        "",
    );
    let (e, line) = within(10, move || error_at(&text, &limits, "name: \"r\""));
    let msg = e.to_string();
    assert!(msg.starts_with(&format!("test.ron:{line}:13: ")), "{msg}");
    assert!(matches!(e, LayoutError::Limit { limit: Limit::Instances, .. }), "{msg}");
    // a group that places nothing still counts its frames: nested over every instance
    let text = scene(
        r#"        Grid(asset: "a", center: (0, 0), rows: 30, cols: 30, spacing: (1, 1), name: "g"),
        Group(on: "*", children: [Group(on: "*", children: [])]),"#,
        "",
    );
    let (e, _) = within(10, move || error_at(&text, &limits, "Group("));
    assert!(e.to_string().contains("would repeat its children on 900 instances"), "{e}");
}

#[test]
fn doubling_duplicates_stop_at_the_instance_limit_with_the_edit_located() {
    let edits: String = (0..40).map(|_| "        Duplicate(target: \"*\"),\n").collect();
    let text = scene(r#"        Instance(asset: "a", at: (0, 0), name: "x"),"#, &edits);
    let first_edit = text.lines().position(|l| l.contains("Duplicate(")).unwrap() + 1;
    let e = within(20, move || resolve_text(&text, &Limits::default()).unwrap_err());
    // 2^19 = 524,288 instances after 19 duplicates; the 20th would make 1,048,576
    assert_instance_limit(&e, first_edit + 19, 9);
    assert!(e.to_string().contains("would copy 524288 instances (524288 placed before it)"), "{e}");
}

#[test]
fn include_chains_are_bounded_in_depth_and_in_loads() {
    // each file includes the next twice: 2^26 loads without a bound
    let dir = temp_dir("doubling");
    for k in 0..26 {
        let next = format!("f{}.ron", k + 1);
        std::fs::write(
            dir.join(format!("f{k}.ron")),
            format!(
                "Scene(\n    include: [\n        \"{next}\",\n        \"{next}\",\n    ],\n)\n"
            ),
        )
        .unwrap();
    }
    std::fs::write(dir.join("f26.ron"), format!("Scene(\n{ASSETS}\n)\n")).unwrap();
    let main = dir.join("f0.ron");
    let e = within(20, move || load_with(&main, &Limits::default()).unwrap_err());
    let msg = e.to_string();
    assert!(matches!(e, LayoutError::Limit { limit: Limit::FileLoads, value: 1024, .. }), "{msg}");
    // located at an include of some file of the chain (line 3 or 4, column 9)
    assert!(msg.contains(".ron:3:9: ") || msg.contains(".ron:4:9: "), "{msg}");
    assert!(msg.contains("ASSETFIELD_MAX_FILE_LOADS=N"), "{msg}");
    // a chain of single includes deeper than the depth limit
    for k in 0..40 {
        let body = format!("Scene(\n    include: [\"g{}.ron\"],\n)\n", k + 1);
        std::fs::write(dir.join(format!("g{k}.ron")), body).unwrap();
    }
    std::fs::write(dir.join("g40.ron"), format!("Scene(\n{ASSETS}\n)\n")).unwrap();
    let e = load_with(&dir.join("g0.ron"), &Limits::default()).unwrap_err();
    let msg = e.to_string();
    assert!(matches!(e, LayoutError::Limit { limit: Limit::IncludeDepth, value: 32, .. }), "{msg}");
    assert!(msg.contains("g31.ron:2:15: ") && msg.contains("g32.ron"), "{msg}");
    // within the limits, repeated includes load (each file parsed once) and resolve
    let shallow = Limits { max_include_depth: 64, ..Limits::default() };
    let loaded: LoadedScript = load_with(&dir.join("g0.ron"), &shallow).unwrap();
    assert!(loaded.assets.contains_key("a"));
    let ok = dir.join("f20.ron");
    let loaded = load_with(&ok, &Limits::default()).unwrap(); // 2^7 - 1 = 127 loads
    assert_eq!(loaded.files.len(), 7, "every file read once");
    let _ = std::fs::remove_dir_all(&dir);
}

/// A scene file whose `base` is `base`, and its error on loading.
fn base_error(dir: &Path, base: &str, limits: Limits) -> LayoutError {
    let main = dir.join("edit.ron");
    std::fs::write(&main, format!("Scene(\n    base: \"{base}\",\n)\n")).unwrap();
    within(10, move || load_with(&main, &limits).unwrap_err())
}

#[cfg(target_os = "linux")]
#[test]
fn base_naming_a_device_is_refused_without_reading_it() {
    let dir = temp_dir("device");
    let e = base_error(&dir, "/dev/zero", Limits::default());
    let msg = e.to_string();
    assert!(matches!(e, LayoutError::NotAFile { kind: "a character device", .. }), "{msg}");
    assert!(
        msg.starts_with(&format!(
            "{}:2:11: /dev/zero: not a regular file",
            dir.join("edit.ron").display()
        )),
        "{msg}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[cfg(unix)]
#[test]
fn base_naming_a_fifo_is_refused_without_blocking() {
    let dir = temp_dir("fifo");
    let fifo = dir.join("pipe.ron");
    match std::process::Command::new("mkfifo").arg(&fifo).status() {
        Ok(s) if s.success() => {}
        other => {
            eprintln!(
                "SKIPPED base_naming_a_fifo_is_refused_without_blocking: mkfifo failed ({other:?})"
            );
            return;
        }
    }
    let e = base_error(&dir, "pipe.ron", Limits::default());
    assert!(matches!(e, LayoutError::NotAFile { kind: "a FIFO", .. }), "{e}");
    assert!(e.to_string().contains(":2:11: "), "{e}");
    // the main script and an appended edit list are checked the same way
    let e = within(10, {
        let fifo = fifo.clone();
        move || load_with(&fifo, &Limits::default()).unwrap_err()
    });
    assert!(matches!(e, LayoutError::NotAFile { .. }), "{e}");
    std::fs::write(dir.join("s.ron"), format!("Scene(\n{ASSETS}\n)\n")).unwrap();
    let mut script = load_with(&dir.join("s.ron"), &Limits::default()).unwrap();
    let e = within(10, move || assetfield_layout::append_edits(&mut script, &fifo).unwrap_err());
    assert!(matches!(e, LayoutError::NotAFile { .. }), "{e}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn folders_and_large_files_are_refused() {
    let dir = temp_dir("large");
    std::fs::create_dir_all(dir.join("folder.ron")).unwrap();
    let e = base_error(&dir, "folder.ron", Limits::default());
    assert!(matches!(e, LayoutError::NotAFile { kind: "a folder", .. }), "{e}");
    let mut big = format!("Scene(\n{ASSETS}\n)\n");
    big.push_str(&" ".repeat(200));
    std::fs::write(dir.join("big.ron"), &big).unwrap();
    let small = Limits { max_file_bytes: 200, ..Limits::default() };
    let e = base_error(&dir, "big.ron", small);
    let msg = e.to_string();
    assert!(matches!(e, LayoutError::TooLarge { limit: 200, .. }), "{msg}");
    assert!(msg.contains(":2:11: ") && msg.contains("ASSETFIELD_MAX_SCRIPT_BYTES=N"), "{msg}");
    // a text given directly is held to the same size
    let e = load_str_with(Path::new("t.ron"), &big, &small).unwrap_err();
    assert!(matches!(e, LayoutError::TooLarge { .. }), "{e}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// A scene of `n` single instances, one per line, and `edits` moves of distinct instances.
fn many_instances(n: usize, edits: usize) -> String {
    let mut layout = String::new();
    for k in 0..n {
        let _ = writeln!(layout, "        Instance(asset: \"a\", at: ({}, {})),", k % 100, k / 100);
    }
    let mut e = String::new();
    for k in 0..edits {
        let _ = writeln!(e, "        Move(target: \"instance{}\", by: (0.1, 0)),", k * 3);
    }
    scene(&layout, &e)
}

#[test]
fn sixteen_thousand_instances_resolve() {
    // resolving was quadratic (16,000 lines took 16 s); the criterion bench `layout`
    // measures it, this only checks that it completes and is right
    let text = many_instances(16_000, 4_000);
    let move_line = text.lines().position(|l| l.contains("\"instance3\"")).unwrap() + 1;
    let l = within(120, move || resolve_text(&text, &Limits::default()).unwrap());
    assert_eq!(l.instances.len(), 16_000);
    let moved = l.by_key("instance3").unwrap();
    assert!((moved.transform.position.x - 3.1).abs() < 1e-5);
    assert_eq!(moved.location().line, move_line, "located at its Move");
    assert!(l.by_key("instance4").unwrap().edited_at.is_none());
}

/// Resolve a scene and return the message of its error (which must be `Invalid`).
fn invalid(layout: &str, edits: &str) -> (String, usize) {
    let text = scene(layout, edits);
    let marker = if edits.is_empty() { layout } else { edits }.trim();
    let line = text.lines().position(|l| l.trim() == marker).unwrap() + 1;
    let e = resolve_text(&text, &Limits::default()).unwrap_err();
    assert!(matches!(e, LayoutError::Invalid(_)), "{e}");
    (e.to_string(), line)
}

#[test]
fn non_finite_and_nonsense_numbers_are_refused_with_their_place() {
    let (msg, line) = invalid(r#"        Instance(asset: "a", at: (NaN, 0)),"#, "");
    assert_eq!(
        msg,
        format!("test.ron:{line}:9: Instance: at must be a point of finite numbers, got (NaN, 0)")
    );
    let cases: &[(&str, &str, &str)] = &[
        (
            r#"        Instance(asset: "a", at: (0, 0), yaw: inf),"#,
            "",
            "yaw must be a finite number, got inf",
        ),
        (
            r#"        Instance(asset: "a", at: (0, 0), scale: -1),"#,
            "",
            "scale must be positive, got -1",
        ),
        (r#"        Row(asset: "a", from: (0, 0), to: (inf, 0), count: 3),"#, "", "to must be"),
        (
            r#"        Grid(asset: "a", center: (0, 0), rows: 2, cols: 2, spacing: (NaN, 1)),"#,
            "",
            "spacing must be",
        ),
        (
            r#"        Ring(asset: "a", center: (0, 0), radius: NaN, count: 3),"#,
            "",
            "radius must be at least 0, got NaN",
        ),
        (
            r#"        Scatter(asset: "a", region: Circle(center: (0, 0), radius: -2), count: 1, min_distance: 0),"#,
            "",
            "region: Circle radius must be at least 0",
        ),
        (
            r#"        Scatter(asset: "a", region: Rect(min: (0, 0), max: (1, 1)), count: 1, min_distance: NaN),"#,
            "",
            "min_distance must be at least 0, got NaN",
        ),
        (
            r#"        Along(asset: "a", path: [(0, 0), (1, inf)], count: 2),"#,
            "",
            "path[1] must be",
        ),
        (
            r#"        Row(asset: "a", from: (0, 0), to: (1, 0), count: 2, vary: (scale_jitter: 1.5)),"#,
            "",
            "vary.scale_jitter must be at least 0 and below 1, got 1.5",
        ),
        (
            r#"        Row(asset: "a", from: (0, 0), to: (1, 0), count: 2, face: Toward(NaN, 0)),"#,
            "",
            "face: Toward must be",
        ),
        (
            r#"        Group(at: (0, 0), scale: inf, children: []),"#,
            "",
            "Group: scale must be positive, got inf",
        ),
    ];
    for (layout, edits, expected) in cases {
        let (msg, line) = invalid(layout, edits);
        assert!(msg.starts_with(&format!("test.ron:{line}:9: ")), "{msg}");
        assert!(msg.contains(expected), "{msg} (expected {expected})");
    }
    let placed = r#"        Instance(asset: "a", at: (0, 0), name: "x"),"#;
    for (edit, expected) in [
        (r#"        Move(target: "x", by: (inf, 0)),"#, "Move: by must be"),
        (r#"        Rotate(target: "x", to: NaN),"#, "Rotate: to must be a finite number, got NaN"),
        (r#"        Scale(target: "x", by: 0),"#, "Scale: scale factor must be positive, got 0"),
        (r#"        Duplicate(target: "x", at: (0, NaN)),"#, "Duplicate: at must be"),
        (
            r#"        Override(target: "x", base: -inf),"#,
            "Override: base must be a finite number, got -inf",
        ),
    ] {
        let (msg, line) = invalid(placed, edit);
        assert!(msg.starts_with(&format!("test.ron:{line}:9: ")), "{msg}");
        assert!(msg.contains(expected), "{msg} (expected {expected})");
    }
}

#[test]
fn bad_assets_and_settings_are_refused_with_their_place() {
    let check = |text: String, marker: &str, expected: &str| {
        let line = text.lines().position(|l| l.contains(marker)).unwrap() + 1;
        let e = resolve_text(&text, &Limits::default()).unwrap_err();
        let msg = e.to_string();
        assert!(matches!(e, LayoutError::Invalid(_)), "{msg}");
        assert!(msg.starts_with(&format!("test.ron:{line}:")), "{msg} (expected line {line})");
        assert!(msg.contains(expected), "{msg} (expected {expected})");
    };
    let with = |settings: &str| {
        format!(
            "Scene(\n{ASSETS}\n{settings}\n    layout: [Instance(asset: \"a\", at: (0, 0))],\n)\n"
        )
    };
    check(
        with("    views: (resolution: 0),"),
        "views:",
        "views: resolution must be 8..=8192 pixels, got 0",
    );
    check(
        with("    views: (count: 10, test: 10),"),
        "views:",
        "views: test must be between 1 and 9",
    );
    check(
        with("    views: (fov_deg: NaN),"),
        "views:",
        "views: fov_deg must be between 5 and 150, got NaN",
    );
    check(
        with("    views: (count: 4000000000),"),
        "views:",
        "views: count must be between 2 and 10000",
    );
    check(with("    views: (elevation_deg: (60, 30)),"), "views:", "elevation_deg must be");
    check(
        with("    units_per_metre: -1,"),
        "units_per_metre",
        "units_per_metre must be positive, got -1",
    );
    check(with("    extent: ((0, 0), (inf, 1)),"), "extent", "extent max must be");
    check(
        with("    lighting: (ambient: NaN),"),
        "lighting",
        "lighting: ambient must be between 0 and 1",
    );
    let part = |def: &str| {
        format!(
            "Scene(\n    assets: {{\n        \"b\": Asset({def}),\n    }},\n    layout: [Instance(asset: \"b\", at: (0, 0))],\n)\n"
        )
    };
    check(
        part("parts: [Box(center: (0, 0, 0), size: (1, 0, 1), color: (1, 0, 0))]"),
        "\"b\"",
        "asset \"b\", part 1: Box size must be three positive sizes, got (1, 0, 1)",
    );
    check(
        part("parts: [Sphere(center: (0, 0, 0), radius: 1, color: (2, 0, 0))]"),
        "\"b\"",
        "Sphere color must be a colour",
    );
    check(
        part(
            "yaw_symmetry_deg: NaN, parts: [Sphere(center: (0, 0, 0), radius: 1, color: (1, 0, 0))]",
        ),
        "\"b\"",
        "yaw_symmetry_deg must be between 0 and 360",
    );
}

#[test]
fn deeply_nested_groups_are_refused_by_the_parser_not_the_stack() {
    let depth = 2000;
    let open = "Group(children: [".repeat(depth);
    let close = "])".repeat(depth);
    let text = scene(&format!("        {open}Instance(asset: \"a\", at: (0, 0)){close},"), "");
    let e = within(20, move || resolve_text(&text, &Limits::default()).unwrap_err());
    assert!(matches!(e, LayoutError::Syntax { .. }), "{e}");
    assert!(e.to_string().starts_with("test.ron:6:"), "{e}");
}

#[test]
fn finite_numbers_whose_results_overflow_are_refused_with_their_place() {
    // found by the fuzz harness: each number is finite, what the item computes from them is
    // not (the row's spacing is infinite; the move overflows the position)
    let cases = [
        (r#"        Row(asset: "a", from: (-3e38, 0), to: (3e38, 0), count: 3),"#, ""),
        (
            r#"        Instance(asset: "a", at: (3e38, 0), name: "x"),"#,
            r#"        Move(target: "x", by: (3e38, 0)),"#,
        ),
    ];
    for (layout, edits) in cases {
        let text = scene(layout, edits);
        let marker = if edits.is_empty() { layout } else { edits }.trim();
        let line = text.lines().position(|l| l.trim() == marker).unwrap() + 1;
        let msg = resolve_text(&text, &Limits::default()).unwrap_err().to_string();
        assert!(msg.starts_with(&format!("test.ron:{line}:9: instance ")), "{msg}");
        assert!(msg.contains("too large to compute with"), "{msg}");
    }
}
