//! The edit scripts in `scenes/edits/`, one per scene of the suite: the fidelity edit (two
//! moves, a quarter turn, a deletion and a duplication), each naming one object on the ground
//! by its exact key and using `by:` offsets only, because the same edit list is applied to a
//! mined layout whose instance origins differ slightly from the ground truth's. Resolved, an
//! edit keeps the object count, keeps what it moved inside the scene and creates no overlap on
//! the ground. No rendering: these tests only resolve layouts.

use assetfield_core::ground::{wrap_degrees, yaw_difference};
use assetfield_layout::source::parse_script;
use assetfield_layout::{Edit, ResolvedInstance, ResolvedLayout, Script};
use assetfield_synth::load_scene;
use assetfield_tests::{convex_overlap, footprint_polygon, repo, scene_files};
use glam::Vec2;
use std::path::{Path, PathBuf};

/// Smallest gap (metres) a moved or duplicated object keeps to every other object on the
/// ground (the scripts aim for 0.15 m; a little is left for the mined layout's offsets).
const CLEARANCE: f32 = 0.1;

/// Accepted range of a move's length (metres).
const MOVE_RANGE: (f32, f32) = (0.3, 1.5);

fn edit_script_of(scene: &Path) -> PathBuf {
    repo().join("scenes/edits").join(scene.file_name().expect("a scene file"))
}

fn stem(p: &Path) -> String {
    p.file_stem().unwrap().to_string_lossy().into_owned()
}

/// The edit script's own text, parsed (without its base).
fn parsed(scene: &Path) -> Script {
    let path = edit_script_of(scene);
    let text = std::fs::read_to_string(&path)
        .unwrap_or_else(|e| panic!("{}: {e} (every scene needs an edit script)", path.display()));
    parse_script(&path, &text).unwrap_or_else(|e| panic!("{e}"))
}

/// The scene and its edited version, resolved with the synthesiser's catalog.
fn resolved(scene: &Path) -> (ResolvedLayout, ResolvedLayout) {
    let resolve = |p: &Path| load_scene(p).unwrap_or_else(|e| panic!("{}: {e}", p.display())).2;
    (resolve(scene), resolve(&edit_script_of(scene)))
}

/// The edits of one script, sorted by kind.
#[derive(Default)]
struct Edits {
    moves: Vec<(String, Vec2)>,
    rotations: Vec<(String, f32)>,
    removals: Vec<String>,
    duplicates: Vec<(String, Vec2)>,
}

fn edits_of(name: &str, script: &Script) -> Edits {
    let mut e = Edits::default();
    for edit in &script.edits {
        match edit {
            Edit::Move { target, to: None, by: Some(by) } => {
                e.moves.push((target.clone(), (*by).into()))
            }
            Edit::Rotate { target, to: None, by: Some(by) } => {
                e.rotations.push((target.clone(), *by))
            }
            Edit::Remove(target) => e.removals.push(target.clone()),
            Edit::Duplicate { target, at: None, by: Some(by), yaw: None, name: None } => {
                e.duplicates.push((target.clone(), (*by).into()))
            }
            other => panic!("{name}: unexpected {other:?} (Move/Rotate/Duplicate by:, Remove)"),
        }
    }
    e
}

fn is_ground_object(i: &ResolvedInstance) -> bool {
    !i.container && i.supported_by.is_none()
}

fn point_segment_distance(p: Vec2, a: Vec2, b: Vec2) -> f32 {
    let ab = b - a;
    let t = ((p - a).dot(ab) / ab.length_squared().max(1e-12)).clamp(0.0, 1.0);
    p.distance(a + ab * t)
}

/// Gap between two convex polygons (0 when they overlap).
fn gap(p: &[Vec2], q: &[Vec2]) -> f32 {
    if convex_overlap(p, q) {
        return 0.0;
    }
    let one_way = |s: &[Vec2], t: &[Vec2]| {
        s.iter()
            .flat_map(|v| {
                (0..t.len()).map(move |k| point_segment_distance(*v, t[k], t[(k + 1) % t.len()]))
            })
            .fold(f32::MAX, f32::min)
    };
    one_way(p, q).min(one_way(q, p))
}

fn contains(outer: &assetfield_core::Rect2, inner: &assetfield_core::Rect2) -> bool {
    let eps = 1e-4;
    inner.min.x >= outer.min.x - eps
        && inner.min.y >= outer.min.y - eps
        && inner.max.x <= outer.max.x + eps
        && inner.max.y <= outer.max.y + eps
}

#[test]
fn every_scene_has_an_edit_script_of_the_fidelity_form() {
    let scenes = scene_files();
    assert!(scenes.len() >= 10, "found {} scenes", scenes.len());
    for scene in &scenes {
        let name = stem(scene);
        let script = parsed(scene);
        assert_eq!(script.base.as_deref(), Some(format!("../{name}.ron").as_str()), "{name}: base");
        assert!(
            script.layout.is_empty() && script.assets.is_empty() && script.include.is_empty(),
            "{name}: an edit script holds only its base and its edits"
        );
        let e = edits_of(&name, &script);
        assert_eq!(
            (e.moves.len(), e.rotations.len(), e.removals.len(), e.duplicates.len()),
            (2, 1, 1, 1),
            "{name}: two moves, one rotation, one removal, one duplication"
        );
        assert_eq!(e.rotations[0].1, 90.0, "{name}: the rotation is a quarter turn");
        for (target, by) in &e.moves {
            let d = by.length();
            assert!(
                (MOVE_RANGE.0..=MOVE_RANGE.1).contains(&d),
                "{name}: {target} moves {d:.2} m, not within {MOVE_RANGE:?}"
            );
        }
        assert!(e.duplicates[0].1.length() > 0.0, "{name}: a duplicate in place");
        // each edit names one object on the ground, exactly, and each a different one
        let (original, _) = resolved(scene);
        let targets: Vec<&String> = e
            .moves
            .iter()
            .map(|m| &m.0)
            .chain(e.rotations.iter().map(|r| &r.0))
            .chain(&e.removals)
            .chain(e.duplicates.iter().map(|d| &d.0))
            .collect();
        for (k, t) in targets.iter().enumerate() {
            assert!(!t.contains(['*', '?', '#']), "{name}: \"{t}\" is not an exact key");
            let i = original
                .by_key(t)
                .unwrap_or_else(|| panic!("{name}: \"{t}\" is no instance of the scene"));
            assert!(is_ground_object(i), "{name}: \"{t}\" does not stand on the ground");
            assert!(!targets[..k].contains(t), "{name}: \"{t}\" is edited twice");
        }
    }
}

#[test]
fn edited_layouts_keep_their_objects_in_place_and_apart() {
    for scene in scene_files() {
        let name = stem(&scene);
        let e = edits_of(&name, &parsed(&scene));
        let (original, edited) = resolved(&scene);
        assert_eq!(
            edited.objects().count(),
            original.objects().count(),
            "{name}: one object removed and one added (the targets carry nothing)"
        );

        // the edits did what they say
        let removed = &e.removals[0];
        assert!(edited.by_key(removed).is_none(), "{name}: {removed} is still there");
        let mut changed: Vec<(&ResolvedInstance, &str)> = Vec::new();
        for (target, by) in &e.moves {
            let (a, b) = (original.by_key(target).unwrap(), edited.by_key(target).unwrap());
            let moved = b.transform.position - a.transform.position;
            assert!((moved - *by).length() < 1e-4, "{name}: {target} moved by {moved}");
            changed.push((b, "moved"));
        }
        let (target, by) = &e.rotations[0];
        let (a, b) = (original.by_key(target).unwrap(), edited.by_key(target).unwrap());
        let want = wrap_degrees(a.transform.yaw_deg + by);
        assert!(
            wrap_degrees(b.transform.yaw_deg - want).abs() < 1e-3,
            "{name}: {target} turned to {}",
            b.transform.yaw_deg
        );
        assert!(
            yaw_difference(want, a.transform.yaw_deg, a.yaw_symmetry_deg) > 45.0,
            "{name}: {target} looks the same after a quarter turn (symmetry {})",
            a.yaw_symmetry_deg
        );
        changed.push((b, "rotated"));
        let (target, by) = &e.duplicates[0];
        let source = original.by_key(target).unwrap();
        let copies: Vec<_> =
            edited.objects().filter(|i| original.by_key(&i.key).is_none()).collect();
        assert_eq!(copies.len(), 1, "{name}: one new object");
        let copy = copies[0];
        assert_eq!(copy.asset, source.asset, "{name}: {} copies {target}", copy.key);
        let shift = copy.transform.position - source.transform.position;
        assert!((shift - *by).length() < 1e-4, "{name}: {} placed {shift} from {target}", copy.key);
        changed.push((copy, "duplicated"));

        // what the edits touched stays inside the scene
        for (i, what) in &changed {
            assert!(
                contains(&original.extent, &i.bev_aabb),
                "{name}: {what} {} ({:?}) leaves the scene's extent {:?}",
                i.key,
                i.bev_aabb,
                original.extent
            );
        }

        // no new overlaps on the ground
        let ground: Vec<_> = edited.objects().filter(|i| is_ground_object(i)).collect();
        let overlapped_before = |a: &str, b: &str| match (original.by_key(a), original.by_key(b)) {
            (Some(a), Some(b)) => {
                convex_overlap(&footprint_polygon(a, 0.01), &footprint_polygon(b, 0.01))
            }
            _ => false,
        };
        for (k, a) in ground.iter().enumerate() {
            for b in &ground[k + 1..] {
                if convex_overlap(&footprint_polygon(a, 0.01), &footprint_polygon(b, 0.01)) {
                    assert!(
                        overlapped_before(&a.key, &b.key),
                        "{name}: {} and {} overlap after the edit",
                        a.key,
                        b.key
                    );
                }
            }
        }
        // and room around what was moved or added
        for (i, what) in changed.iter().filter(|(_, w)| *w != "rotated") {
            let p = footprint_polygon(i, 0.0);
            let (nearest, g) = ground
                .iter()
                .filter(|o| o.key != i.key)
                .map(|o| (o.key.as_str(), gap(&p, &footprint_polygon(o, 0.0))))
                .fold(("", f32::MAX), |acc, x| if x.1 < acc.1 { x } else { acc });
            eprintln!("{name}: {what} {} is {g:.3} m from {nearest}", i.key);
            assert!(g >= CLEARANCE, "{name}: {what} {} is {g:.3} m from {nearest}", i.key);
        }
    }
}

#[test]
fn the_edit_lists_apply_on_their_own_to_the_scene() {
    // `compose --edits` appends an edit script's edits to another layout of the scene,
    // ignoring its `base`: on the scene itself that is the same as resolving the edit script
    for scene in scene_files() {
        let name = stem(&scene);
        let (_, edited) = resolved(&scene);
        let mut script = assetfield_layout::load(&scene).unwrap();
        let n = assetfield_layout::append_edits(&mut script, &edit_script_of(&scene))
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(n, 5, "{name}");
        let assets = assetfield_synth::AssetSet::from_script(&script).unwrap();
        let again = assetfield_layout::resolve(&script, &assets).unwrap_or_else(|e| panic!("{e}"));
        let summary = |l: &ResolvedLayout| -> Vec<(u32, String, [f32; 3])> {
            l.instances
                .iter()
                .map(|i| {
                    let t = i.transform;
                    (i.id, i.key.clone(), [t.position.x, t.position.y, t.yaw_deg])
                })
                .collect()
        };
        assert_eq!(summary(&again), summary(&edited), "{name}");
    }
}
