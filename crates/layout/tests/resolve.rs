//! The layout language end to end: generators, supports, edits, ids and located errors.

use assetfield_layout::resolve::{AssetCatalog, AssetInfo, glob_match};
use assetfield_layout::source::{parse_script, write_script};
use assetfield_layout::{GtLayout, LayoutError, PartsCatalog, ResolvedLayout, load_str, resolve};
use std::path::Path;

const ASSETS: &str = r#"
    assets: {
        "chair": Asset(parts: [Box(center: (0, 0, 0.25), size: (0.4, 0.4, 0.5), color: (1, 0, 0))]),
        "stool": Asset(yaw_symmetry_deg: 0, parts: [Cylinder(base: (0, 0, 0), radius: 0.2, height: 0.5, color: (0, 0, 1))]),
        "table": Asset(yaw_symmetry_deg: 180, parts: [Box(center: (0, 0, 0.375), size: (1.6, 0.8, 0.75), color: (0.5, 0.3, 0.1))]),
        "cup": Asset(parts: [Cylinder(base: (0, 0, 0), radius: 0.05, height: 0.1, color: (1, 1, 1))]),
        "floor": Asset(container: true, parts: [Box(center: (0, 0, -0.01), size: (10, 10, 0.02), color: (0.5, 0.5, 0.5))]),
    },"#;

fn scene(body: &str) -> String {
    format!("Scene(\n    name: \"t\",{ASSETS}\n{body}\n)")
}

fn resolve_text(text: &str) -> Result<ResolvedLayout, LayoutError> {
    let loaded = load_str(Path::new("test.ron"), text)?;
    resolve(&loaded, &PartsCatalog::from_script(&loaded))
}

fn ok(body: &str) -> ResolvedLayout {
    resolve_text(&scene(body)).unwrap_or_else(|e| panic!("{e}"))
}

fn err(body: &str) -> String {
    match resolve_text(&scene(body)) {
        Ok(_) => panic!("expected an error"),
        Err(e) => e.to_string(),
    }
}

fn close(a: f32, b: f32) -> bool {
    (a - b).abs() < 1e-4
}

#[test]
fn row_grid_ring_and_along_place_where_asked() {
    let l = ok(r#"layout: [
        Row(asset: "chair", from: (0, 0), to: (3, 0), count: 4, name: "row"),
        Grid(asset: "chair", center: (10, 10), rows: 2, cols: 3, spacing: (1, 2), name: "grid"),
        Ring(asset: "chair", center: (0, 5), radius: 2, count: 4, face: Center, name: "ring"),
        Along(asset: "stool", path: [(0, -5), (4, -5), (4, -1)], spacing: 2.0, face: Path, name: "path"),
    ]"#);
    let row: Vec<_> = l.instances.iter().filter(|i| i.key.starts_with("row[")).collect();
    assert_eq!(row.len(), 4);
    for (k, i) in row.iter().enumerate() {
        assert!(close(i.transform.position.x, k as f32) && close(i.transform.position.y, 0.0));
    }
    let grid: Vec<_> = l.instances.iter().filter(|i| i.key.starts_with("grid[")).collect();
    assert_eq!(grid.len(), 6);
    let mean = grid.iter().map(|i| i.transform.position).sum::<glam::Vec2>() / 6.0;
    assert!(close(mean.x, 10.0) && close(mean.y, 10.0));
    assert!(close(grid[0].transform.position.x, 9.0) && close(grid[0].transform.position.y, 9.0));
    // ring members face the centre: front (+X turned by yaw) points at (0, 5)
    for i in l.instances.iter().filter(|i| i.key.starts_with("ring[")) {
        let p = i.transform.position;
        let front = glam::Vec2::from_angle(i.transform.yaw_deg.to_radians());
        let to_centre = (glam::Vec2::new(0.0, 5.0) - p).normalize();
        assert!(front.dot(to_centre) > 0.999, "{} faces {front:?}", i.key);
        assert!(close(p.distance(glam::Vec2::new(0.0, 5.0)), 2.0));
    }
    // along: 8 m of path, one every 2 m -> 5 instances; the last two go up the second leg
    let path: Vec<_> = l.instances.iter().filter(|i| i.key.starts_with("path[")).collect();
    assert_eq!(path.len(), 5);
    assert!(close(path[4].transform.position.x, 4.0) && close(path[4].transform.position.y, -1.0));
    assert!(close(path[0].transform.yaw_deg, 0.0) && close(path[4].transform.yaw_deg, 90.0));
}

#[test]
fn ids_follow_script_order_and_keys_are_readable() {
    let l = ok(r#"layout: [
        Instance(asset: "table", at: (0, 0), name: "t1"),
        Group(at: (5, 0), yaw: 90, name: "corner", children: [
            Instance(asset: "chair", at: (1, 0)),
            Row(asset: "stool", from: (0, 1), to: (0, 2), count: 2),
        ]),
    ]"#);
    let keys: Vec<(u32, &str)> = l.instances.iter().map(|i| (i.id, i.key.as_str())).collect();
    assert_eq!(
        keys,
        vec![(0, "t1"), (1, "corner/instance0"), (2, "corner/row1[0]"), (3, "corner/row1[1]")]
    );
    // the group turned by 90 degrees: local (1, 0) is world (5, 1)
    let c = l.by_key("corner/instance0").unwrap();
    assert!(close(c.transform.position.x, 5.0) && close(c.transform.position.y, 1.0));
    assert!(close(c.transform.yaw_deg, 90.0));
}

#[test]
fn objects_stand_on_supports_and_follow_them() {
    let l = ok(r#"layout: [
        Instance(asset: "floor", at: (0, 0), name: "floor"),
        Row(asset: "table", from: (0, 0), to: (4, 0), count: 2, name: "tables"),
        Group(on: "tables[*]", children: [Instance(asset: "cup", at: (0.5, 0), name: "cup")]),
        Group(around: "tables[*]", children: [Instance(asset: "chair", at: (0, -0.8), yaw: 90, name: "chair")]),
    ],
    edits: [
        Move(target: "tables[1]", to: (4, 3)),
        Rotate(target: "tables[1]", by: 90),
    ]"#);
    let t1 = l.by_key("tables[1]").unwrap();
    let cup = l.by_key("tables[1]/cup").unwrap();
    assert_eq!(cup.supported_by, Some(t1.id));
    assert!(close(cup.transform.base, 0.75), "cup stands on the table top: {}", cup.transform.base);
    assert!(close(cup.top, 0.85));
    // moved and turned with the table: local (0.5, 0) turned by 90 -> (0, 0.5) from (4, 3)
    assert!(
        close(cup.transform.position.x, 4.0) && close(cup.transform.position.y, 3.5),
        "{:?}",
        cup.transform
    );
    assert!(close(cup.transform.yaw_deg, 90.0));
    // chairs `around` stand on the ground, are not supported, and stay where they were placed
    let chair = l.by_key("tables[1]/chair").unwrap();
    assert_eq!(chair.supported_by, None);
    assert!(close(chair.transform.base, 0.0));
    assert!(close(chair.transform.position.x, 4.0) && close(chair.transform.position.y, -0.8));
    // containers are not objects
    assert_eq!(l.objects().count(), l.instances.len() - 1);
    assert_eq!(l.containers().next().unwrap().key, "floor");
}

#[test]
fn edits_remove_replace_duplicate_and_override() {
    let l = ok(r#"layout: [
        Row(asset: "table", from: (0, 0), to: (6, 0), count: 3, name: "tables"),
        Group(on: "tables[*]", children: [Instance(asset: "cup", at: (0, 0), name: "cup")]),
        Row(asset: "chair", from: (0, 2), to: (6, 2), count: 3, name: "chairs"),
    ],
    edits: [
        Remove("tables[0]"),
        ReplaceAsset(category: "chair", with: "stool"),
        Duplicate(target: "tables[2]", by: (0, 5), name: "extra"),
        Override(target: "chairs[1]", yaw: 45, scale: 1.5),
        Scale(target: "chairs[2]", by: 2),
    ]"#);
    // removing a table removes the cup on it; ids of the rest do not move
    assert!(l.by_key("tables[0]").is_none() && l.by_key("tables[0]/cup").is_none());
    assert_eq!(l.by_key("tables[1]").unwrap().id, 1);
    assert_eq!(l.by_key("chairs[0]").unwrap().id, 6);
    // replaced assets change category too
    assert!(
        l.instances
            .iter()
            .filter(|i| i.key.starts_with("chairs"))
            .all(|i| i.asset == "stool" && i.category == "stool")
    );
    // duplicates carry what stands on them, with new ids after the rest
    let extra = l.by_key("extra").unwrap();
    let extra_cup = l.by_key("extra/cup").unwrap();
    assert_eq!(extra.id, 9);
    assert_eq!(extra_cup.id, 10);
    assert_eq!(extra_cup.supported_by, Some(extra.id));
    assert!(close(extra.transform.position.y, 5.0) && close(extra_cup.transform.position.y, 5.0));
    let c1 = l.by_key("chairs[1]").unwrap();
    assert!(close(c1.transform.yaw_deg, 45.0) && close(c1.transform.scale, 1.5));
    assert!(close(l.by_key("chairs[2]").unwrap().transform.scale, 2.0));
}

#[test]
fn remove_category_and_patterns() {
    let l = ok(r#"layout: [
        Grid(asset: "chair", center: (0, 0), rows: 2, cols: 2, spacing: (1, 1), name: "a"),
        Row(asset: "stool", from: (5, 0), to: (5, 3), count: 4, name: "b"),
    ],
    edits: [RemoveCategory("chair"), Remove("b[?]"), ]"#);
    assert!(l.instances.is_empty());
    assert!(glob_match("x[*]/cup", "x[12]/cup") && !glob_match("x[*]/cup", "x[1]/lamp"));
    assert!(glob_match("#3", "#3") && glob_match("*", "anything"));
}

#[test]
fn scatter_is_seeded_separated_and_clear_of_existing_objects() {
    let body = r#"layout: [
        Instance(asset: "table", at: (0, 0), name: "table"),
        Scatter(asset: "stool", region: Rect(min: (-3, -3), max: (3, 3)), count: 12, min_distance: 0.9, seed: 5,
                vary: (yaw_jitter_deg: 180, seed: 1), name: "s"),
    ]"#;
    let a = ok(body);
    let b = ok(body);
    assert_eq!(a, b, "same seed, same layout");
    let pts: Vec<_> = a.instances.iter().filter(|i| i.key.starts_with("s[")).collect();
    assert_eq!(pts.len(), 12);
    for (k, p) in pts.iter().enumerate() {
        assert!(p.transform.position.abs().max_element() <= 3.0);
        for q in &pts[k + 1..] {
            assert!(p.transform.position.distance(q.transform.position) >= 0.9);
        }
        let table = a.by_key("table").unwrap();
        assert_eq!(
            p.bev_aabb.intersection(&table.bev_aabb).area(),
            0.0,
            "{} overlaps the table",
            p.key
        );
    }
    let c = ok(&body.replace("seed: 5", "seed: 6"));
    assert_ne!(a, c, "another seed, another layout");
}

#[test]
fn gt_layout_has_the_contract_fields() {
    let l = ok(r#"layout: [
        Instance(asset: "floor", at: (0, 0)),
        Instance(asset: "table", at: (1, 2), yaw: 90, name: "t"),
        Group(on: "t", children: [Instance(asset: "cup", at: (0, 0))]),
    ]"#);
    let gt = GtLayout::from_resolved(&l);
    let v: serde_json::Value = serde_json::from_str(&gt.to_json()).unwrap();
    let inst = v["instances"].as_array().unwrap();
    assert_eq!(inst.len(), 2, "containers are not listed as instances");
    let t = &inst[0];
    for key in [
        "id",
        "category",
        "position",
        "yaw_deg",
        "scale",
        "bev_aabb",
        "yaw_symmetry_deg",
        "supported_by",
    ] {
        assert!(t.get(key).is_some(), "missing {key}");
    }
    assert_eq!(t["category"], "table");
    assert_eq!(t["yaw_symmetry_deg"], 180.0);
    assert!(t["supported_by"].is_null());
    // turned by 90: the 1.6 x 0.8 table covers 0.8 in x and 1.6 in y
    let b: Vec<f64> =
        t["bev_aabb"].as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect();
    assert!((b[2] - b[0] - 0.8).abs() < 1e-4 && (b[3] - b[1] - 1.6).abs() < 1e-4, "{b:?}");
    assert_eq!(inst[1]["supported_by"], t["id"]);
    assert!((inst[1]["position"][2].as_f64().unwrap() - 0.75).abs() < 1e-5);
    // readers ignore unknown fields
    let mut extended = v.clone();
    extended["instances"][0]["future_field"] = serde_json::json!(42);
    let back: GtLayout = serde_json::from_value(extended).unwrap();
    assert_eq!(back.instances.len(), 2);
}

#[test]
fn unknown_asset_is_located_with_a_hint() {
    let msg = err(r#"layout: [
        Instance(asset: "table", at: (0, 0)),
        Row(asset: "chiar", from: (0, 0), to: (1, 0), count: 2),
    ]"#);
    // line 10 of the generated text: 1 Scene, 2 name, 3 assets:, 4-8 five assets, 9 `},`... count it
    let line = scene(
        r#"layout: [
        Instance(asset: "table", at: (0, 0)),
        Row(asset: "chiar", from: (0, 0), to: (1, 0), count: 2),
    ]"#,
    )
    .lines()
    .position(|l| l.contains("chiar"))
    .unwrap()
        + 1;
    assert!(msg.starts_with(&format!("test.ron:{line}:")), "{msg}");
    assert!(
        msg.contains("unknown asset \"chiar\"") && msg.contains("did you mean \"chair\""),
        "{msg}"
    );
}

#[test]
fn impossible_scatter_is_located_and_explained() {
    let text = scene(
        r#"layout: [
        Scatter(asset: "table", region: Rect(min: (0, 0), max: (2, 2)), count: 30, min_distance: 1.0),
    ]"#,
    );
    let line = text.lines().position(|l| l.contains("Scatter(")).unwrap() + 1;
    let msg = resolve_text(&text).unwrap_err().to_string();
    assert!(msg.starts_with(&format!("test.ron:{line}:9:")), "{msg}");
    assert!(msg.contains("could place only") && msg.contains("of 30"), "{msg}");
}

#[test]
fn bad_targets_and_values_are_reported() {
    assert!(
        err(r#"layout: [Instance(asset: "chair", at: (0, 0))], edits: [Remove("nope")]"#)
            .contains("\"nope\" matches no instance")
    );
    assert!(
        err(r#"layout: [Group(on: "tbl", children: [])]"#)
            .contains("matches no instance placed before")
    );
    assert!(
        err(r#"layout: [Instance(asset: "chair", at: (0, 0), scale: 0)]"#)
            .contains("scale must be positive")
    );
    assert!(
        err(r#"layout: [Row(asset: "chair", from: (0, 0), to: (1, 0), count: 0)]"#)
            .contains("count must be at least 1")
    );
    assert!(err(r#"layout: [Instance(asset: "chair", at: (0, 0), name: "c")], edits: [Move(target: "c")]"#).contains("exactly one of `to` or `by`"));
    assert!(
        err(r#"layout: [Instance(asset: "chair", at: (0, 0))], edits: [RemoveCategory("sofa")]"#)
            .contains("categories present: chair")
    );
    assert!(
        err(r#"layout: [Along(asset: "chair", path: [(0, 0)], count: 2)]"#)
            .contains("at least 2 points")
    );
}

#[test]
fn syntax_errors_point_at_the_typo() {
    let text = scene(
        r#"layout: [
        Instance(asset: "chair", at: (0, 0) yaw: 3),
    ]"#,
    );
    let line = text.lines().position(|l| l.contains("yaw: 3")).unwrap() + 1;
    let msg = resolve_text(&text).unwrap_err().to_string();
    assert!(msg.starts_with(&format!("test.ron:{line}:")), "{msg}");
    assert!(msg.contains("syntax error"), "{msg}");
}

#[test]
fn base_and_include_compose_files() {
    let dir = std::env::temp_dir().join(format!("assetfield-layout-files-{}", std::process::id()));
    std::fs::create_dir_all(dir.join("lib")).unwrap();
    std::fs::write(dir.join("lib/assets.ron"), format!("Scene({ASSETS})")).unwrap();
    std::fs::write(
        dir.join("room.ron"),
        r#"Scene(name: "room", include: ["lib/assets.ron"], layout: [Row(asset: "chair", from: (0, 0), to: (2, 0), count: 3, name: "c")])"#,
    )
    .unwrap();
    std::fs::write(dir.join("edit.ron"), r#"Scene(base: "room.ron", edits: [Remove("c[1]"), Duplicate(target: "c[0]", at: (9, 9))])"#).unwrap();
    let loaded = assetfield_layout::load(&dir.join("edit.ron")).unwrap();
    assert_eq!(loaded.name, "room");
    let l = resolve(&loaded, &PartsCatalog::from_script(&loaded)).unwrap();
    let keys: Vec<&str> = l.instances.iter().map(|i| i.key.as_str()).collect();
    assert_eq!(keys, vec!["c[0]", "c[2]", "c[0]+copy1"]);
    // an included file with a layout is refused; a cycle is reported
    std::fs::write(dir.join("bad_inc.ron"), r#"Scene(include: ["room.ron"])"#).unwrap();
    let e = assetfield_layout::load(&dir.join("bad_inc.ron")).unwrap_err().to_string();
    assert!(e.contains("may only define assets"), "{e}");
    std::fs::write(dir.join("loop.ron"), r#"Scene(base: "loop.ron")"#).unwrap();
    let e = assetfield_layout::load(&dir.join("loop.ron")).unwrap_err().to_string();
    assert!(e.contains("cycle"), "{e}");
    let e = assetfield_layout::load(&dir.join("missing.ron")).unwrap_err().to_string();
    assert!(e.contains("missing.ron") && e.contains("cannot read"), "{e}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn written_scripts_parse_back_identically() {
    let text = scene(
        r#"layout: [
        Scatter(asset: "stool", region: Polygon([(0, 0), (4, 0), (2, 3)]), count: 3, min_distance: 0.5, seed: 2),
        Group(around: "x", name: "g", children: [Ring(asset: "chair", center: (0, 0), radius: 1, count: 3, face: Outward)]),
    ],
    edits: [Override(target: "g/*", asset: "stool", base: 0.1)]"#,
    );
    let s = parse_script(Path::new("t.ron"), &text).unwrap();
    let again = parse_script(Path::new("t.ron"), &write_script(&s).unwrap()).unwrap();
    assert_eq!(s, again);
}

/// A catalog whose "chair_cut" is a chair cut as it stood, turned 30 degrees from its
/// category's frame (as a mined entry is).
struct TurnedCatalog(PartsCatalog);

impl AssetCatalog for TurnedCatalog {
    fn asset_info(&self, name: &str) -> Option<AssetInfo> {
        let base = if name == "chair_cut" { "chair" } else { name };
        let mut info = self.0.asset_info(base)?;
        if name == "chair_cut" {
            info.frame_yaw_deg = 30.0;
        }
        Some(info)
    }
    fn asset_names(&self) -> Vec<String> {
        let mut names = self.0.asset_names();
        names.push("chair_cut".into());
        names
    }
}

#[test]
fn another_asset_of_the_category_keeps_the_object_s_orientation() {
    let text = scene(
        r#"layout: [
        Instance(asset: "chair_cut", at: (1, 0), yaw: 10, name: "c"),
        Instance(asset: "chair_cut", at: (3, 0), name: "d"),
        Group(on: "d", name: "g", children: [Instance(asset: "cup", at: (0.1, 0), name: "cup")]),
    ],
    edits: [ReplaceAsset(category: "chair", with: "chair"), Override(target: "c", asset: "chair_cut")]"#,
    );
    let loaded = load_str(Path::new("test.ron"), &text).unwrap();
    let catalog = TurnedCatalog(PartsCatalog::from_script(&loaded));
    let all = resolve(&loaded, &catalog).unwrap();
    let get = |l: &ResolvedLayout, k: &str| {
        l.instances.iter().find(|i| i.key.ends_with(k)).unwrap_or_else(|| panic!("{k}")).clone()
    };
    // ReplaceAsset turned both by the 30 degrees the cut carried; Override turned c back
    assert!(close(get(&all, "d").transform.yaw_deg, 30.0), "{}", get(&all, "d").transform.yaw_deg);
    assert_eq!(get(&all, "c").asset, "chair_cut");
    assert!(close(get(&all, "c").transform.yaw_deg, 10.0));
    // what stands on d kept its place and orientation
    let mut before = loaded.clone();
    before.edits.clear();
    let plain = resolve(&before, &catalog).unwrap();
    let (a, b) = (get(&plain, "cup").transform, get(&all, "cup").transform);
    assert!(close(a.position.x, b.position.x) && close(a.position.y, b.position.y), "{a:?} {b:?}");
    assert!(close(a.yaw_deg, b.yaw_deg) && close(a.base, b.base), "{a:?} {b:?}");
}

#[test]
fn categories_take_names_people_read() {
    let l = ok(r#"layout: [Instance(asset: "chair", at: (0, 0), name: "c")],
    edits: [NameCategory(category: "chair", name: "Dining chairs"), NameCategory(category: "chair", name: " Chairs ")]"#);
    assert_eq!(
        l.category_names.get("chair").map(String::as_str),
        Some("Chairs"),
        "the last one, trimmed"
    );
    let e = err(r#"layout: [], edits: [NameCategory(category: "chair", name: "")]"#);
    assert!(e.contains("NameCategory") && e.contains("name"), "{e}");
}
