//! The mined layout as a script of the layout language (`layout.ron`): one library asset per
//! category (its template's patch, `Library(path: ".", entry: TEMPLATE, size: (x, y,
//! height))`), one `Instance` per object on the ground at its template-aligned position and
//! yaw (relative to the template), and the objects standing on others in `Group(on:
//! PARENT)` items, placed in their parent's frame so that they move with it. An instance that
//! keeps its own patch (every one by default, see [`OWN_PATCH_RESIDUAL`]) gets an asset of
//! its own (its entry's patch, same category, at its own pivot, yaw 0). Every asset is
//! placed and turned about its entry's pivot (the centre of its ground contact, see
//! [`crate::pivot`]), written as `pivot` where it is off the patch centre.

use assetfield_core::GroundTransform;
use assetfield_core::ground::wrap_degrees;
use assetfield_layout::{AssetDef, Item, LibraryRef, PartsCatalog, Script, resolve};
use glam::Vec2;
use std::collections::BTreeMap;
use std::path::Path;

use crate::error::{MiningError, Result};
use assetfield_library::{Entry, EntryKind, LibraryIndex};

/// Default of `mine --own-patch-residual`: 0, every instance keeps its own patch, so the
/// mined layout reproduces the trained scene exactly and edits of it stay faithful (the
/// templates still define the categories and serve new compositions and category edits).
/// A positive R gives an instance its category's template when its template-matching residual
/// is at most R times the median of the residuals measured on the same kind of patch (a
/// compact layout, as in the paper's reconfiguration; rotating a template resamples it, which
/// costs detail on thin parts).
pub const OWN_PATCH_RESIDUAL: f32 = 0.0; // fixed: a choice (own patches everywhere)

/// Residuals of one kind needed for a median that can judge an instance's fit (the fewest
/// with a median that is not one of two extremes).
const MIN_RESIDUALS: usize = 3; // fixed: the smallest sample with a median

/// A layout script shows lengths to the decimal place where a texel's this-many-th part
/// shows: finer than anything a field resolves, and in the capture's own unit (millimetres
/// for the suite's 2.4-7.7 cm texels, whatever unit COLMAP solved a capture in).
/// Presentation, not a tuned value.
const TEXEL_PARTS_SHOWN: f32 = 20.0; // fixed: printed precision

/// Degrees are shown to the thousandth.
fn round_deg(v: f32) -> f32 {
    (v * 1000.0).round() / 1000.0 // fixed: printed precision
}

/// How lengths are rounded in a layout script (see [`TEXEL_PARTS_SHOWN`]).
#[derive(Debug, Clone, Copy)]
struct Lengths {
    /// The finer side of the library's texels (world units).
    texel: f32,
    /// `10^places`.
    scale: f32,
}

impl Lengths {
    fn of(index: &LibraryIndex) -> Self {
        let texel = index.texel_size.0.min(index.texel_size.1);
        let places = if texel.is_finite() && texel > 0.0 {
            // fixed: decimal places f32 holds
            (TEXEL_PARTS_SHOWN / texel).log10().ceil().clamp(0.0, 9.0) as i32
        } else {
            3 // fixed: millimetres when the texel is unknown
        };
        Lengths { texel, scale: 10f32.powi(places) } // fixed: decimal
    }

    fn round(self, v: f32) -> f32 {
        (v * self.scale).round() / self.scale
    }
}

/// The layout asset of a library entry in `category` (its patch at the entry's extent, its
/// pivot where it is off the patch centre, lengths rounded by `len`), with its height.
fn library_asset(e: &Entry, category: &str, library_path: &str, len: Lengths) -> (AssetDef, f32) {
    let size =
        (len.round(e.extent.0), len.round(e.extent.1), len.round(e.extent.2).max(1.0 / len.scale));
    let pivot = e.pivot_offset();
    let pivot = (len.round(pivot.x), len.round(pivot.y));
    let def = AssetDef {
        parts: Vec::new(),
        obj: None,
        category: Some(category.to_string()),
        yaw_symmetry_deg: 360.0, // fixed: a full turn (no symmetry known)
        container: false,
        library: Some(LibraryRef {
            path: library_path.to_string(),
            entry: e.name.clone(),
            size,
            pivot: (pivot != (0.0, 0.0)).then_some(pivot),
            density_from: None,
            color_from: None,
        }),
    };
    (def, size.2)
}

/// Build the layout script of a library index (see the module docs). `extent` is the ground
/// region `[xmin, ymin, xmax, ymax]`; `library_path` the library folder relative to the
/// script (`"."` when the script lives in it). Instances are named after their entries,
/// or after `names[entry]` where given (e.g. the ground-truth keys they matched; a name is
/// used for an object standing on another only when it starts with its host's name and a
/// `/`, the rest becoming its name inside the host's group, so that keys stay equal).
pub fn layout_script(
    index: &LibraryIndex,
    name: &str,
    extent: [f32; 4],
    library_path: &str,
    names: &BTreeMap<String, String>,
    own_patch_residual: f32,
) -> Result<Script> {
    let display = |entry: &str| names.get(entry).cloned().unwrap_or_else(|| entry.to_string());
    let len = Lengths::of(index);
    let mut assets = BTreeMap::new();
    let mut heights = BTreeMap::new();
    for c in &index.categories {
        let t = index.entry(&c.template).ok_or_else(|| MiningError::Format {
            path: "library index".into(),
            message: format!(
                "category {:?} names template {:?}, which is not an entry",
                c.name, c.template
            ),
        })?;
        let (def, height) = library_asset(t, &c.name, library_path, len);
        heights.insert(c.name.clone(), height);
        assets.insert(c.name.clone(), def);
    }
    // where each entry is placed, and with which asset: its category's template at the
    // template-aligned pose, or, for an instance the template cannot reproduce (matching
    // residual above `own_patch_residual` times the median of the library's residuals
    // measured on the same kind of patch, or unmatched), its own patch at its own centre
    // (0: every instance; infinity: none). Fewer than `MIN_RESIDUALS` residuals of a kind
    // give no median to judge by (with two, the "median" is the larger one): those
    // instances keep their own patches unless templates are asked for everywhere.
    fn on(e: &Entry) -> &str {
        e.matched_on.as_deref().unwrap_or("unrecorded")
    }
    let mut residuals: BTreeMap<&str, Vec<f32>> = BTreeMap::new();
    for e in index.entries.iter().filter(|e| e.kind == EntryKind::Instance && e.residual >= 0.0) {
        residuals.entry(on(e)).or_default().push(e.residual);
    }
    let cuts: BTreeMap<&str, f32> = residuals
        .into_iter()
        .map(|(kind, mut r)| {
            r.sort_by(f32::total_cmp);
            let cut = if own_patch_residual.is_infinite() {
                f32::INFINITY
            } else if r.len() < MIN_RESIDUALS {
                f32::NEG_INFINITY
            } else {
                r[r.len() / 2] * own_patch_residual
            };
            (kind, cut)
        })
        .collect();
    let cut = |e: &Entry| cuts.get(on(e)).copied().unwrap_or(f32::INFINITY);
    let mut placed: BTreeMap<&str, (String, GroundTransform)> = BTreeMap::new();
    for e in &index.entries {
        let own = e.kind == EntryKind::Instance && (e.residual < 0.0 || e.residual > cut(e));
        let (asset, t) = if own {
            let (def, height) = library_asset(e, &e.category, library_path, len);
            assets.insert(e.name.clone(), def);
            heights.insert(e.name.clone(), height);
            (e.name.clone(), GroundTransform::new(e.pivot_world(), 0.0, 1.0, 0.0))
        } else {
            let yaw = if e.kind == EntryKind::Template { 0.0 } else { wrap_degrees(e.yaw_deg) };
            (
                e.category.clone(),
                GroundTransform::new(Vec2::new(e.position.0, e.position.1), yaw, 1.0, 0.0),
            )
        };
        placed.insert(e.name.as_str(), (asset, t));
    }
    let mut layout = Vec::new();
    let mut children: BTreeMap<&str, Vec<Item>> = BTreeMap::new();
    for e in &index.entries {
        let (asset, t) = placed[e.name.as_str()].clone();
        match e.supported_by.as_deref() {
            None => layout.push(Item::Instance {
                asset,
                at: (len.round(t.position.x), len.round(t.position.y)),
                yaw: round_deg(t.yaw_deg),
                scale: 1.0,
                base: 0.0,
                name: Some(display(&e.name)),
            }),
            Some(parent) => {
                let (passet, pt) =
                    placed.get(parent).cloned().ok_or_else(|| MiningError::Format {
                        path: "library index".into(),
                        message: format!(
                            "entry {:?} stands on {parent:?}, which is not an entry",
                            e.name
                        ),
                    })?;
                let local = pt.inverse_transform_point2(t.position);
                let top = heights.get(&passet).copied().unwrap_or(0.0);
                let base = len.round(e.base - top);
                children.entry(parent).or_default().push(Item::Instance {
                    asset,
                    at: (len.round(local.x), len.round(local.y)),
                    yaw: round_deg(wrap_degrees(t.yaw_deg - pt.yaw_deg)),
                    scale: 1.0,
                    // within half a level of its host's top (the voxels are cubic: half a
                    // texel), it stands on it: the field resolves no finer
                    base: if base.abs() < 0.5 * len.texel { 0.0 } else { base },
                    name: Some(
                        display(&e.name)
                            .strip_prefix(&format!("{}/", display(parent)))
                            .filter(|rest| !rest.is_empty())
                            .map_or_else(|| e.name.clone(), str::to_string),
                    ),
                });
            }
        }
    }
    for (parent, kids) in children {
        layout.push(Item::standing_on(display(parent), kids));
    }
    Ok(Script {
        name: Some(name.to_string()),
        assets,
        extent: Some(((extent[0], extent[1]), (extent[2], extent[3]))),
        layout,
        ..Script::default()
    })
}

/// Serialise a script and check that it loads and resolves (library assets take their
/// footprint from `size`); `path` names the file the text will be written to.
pub fn script_text_checked(script: &Script, path: &Path) -> Result<(String, usize)> {
    let text = assetfield_layout::source::write_script(script)
        .map_err(|e| MiningError::io("cannot write the layout script", e))?;
    let loaded = assetfield_layout::load_str(path, &text).map_err(|e| MiningError::Format {
        path: path.display().to_string(),
        message: format!("the mined layout does not load back: {e}"),
    })?;
    let resolved =
        resolve(&loaded, &PartsCatalog::from_script(&loaded)).map_err(|e| MiningError::Format {
            path: path.display().to_string(),
            message: format!("the mined layout does not resolve: {e}"),
        })?;
    Ok((text, resolved.instances.len()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use assetfield_library::{Category, Entry, LibraryIndex, SharedRef};

    fn entry(name: &str, cat: &str, kind: EntryKind, pos: (f32, f32), yaw: f32) -> Entry {
        Entry {
            kind,
            patch_size: (10, 10),
            extent: (1.0, 0.6, 0.75),
            position: pos,
            yaw_deg: yaw,
            ..Entry::named(name, cat)
        }
    }

    /// A library index of `entries` in `categories` at `texel` metres (no tensors).
    fn index_of(texel: f32, categories: Vec<Category>, entries: Vec<Entry>) -> LibraryIndex {
        LibraryIndex {
            format: assetfield_library::FORMAT.into(),
            sources: vec![],
            model: "s".into(),
            texel_size: (texel, texel),
            channels: (16, 48),
            patches: "patches.safetensors".into(),
            shared: SharedRef {
                file: "shared.safetensors".into(),
                hash: String::new(),
                tensors: vec![],
            },
            categories,
            entries,
            containers: vec![],
        }
    }

    #[test]
    fn lengths_are_shown_to_a_twentieth_of_a_texel_in_any_unit() {
        let at = |texel: f32, v: f32| Lengths::of(&index_of(texel, vec![], vec![])).round(v);
        // the suite's texels (metres): millimetres
        assert_eq!(at(0.028, 1.234_567), 1.235);
        assert_eq!(at(0.077, 1.234_567), 1.235);
        // the same scene in centimetres: tenths of a centimetre, the same length
        assert_eq!(at(2.8, 123.456_7), 123.5);
        // a capture solved in tiny units keeps its detail
        assert!((at(0.000_28, 0.012_345_67) - 0.012_35).abs() < 1e-7);
        assert!(at(0.000_28, 0.000_9) > 0.0);
        // a degenerate texel falls back to thousandths
        assert_eq!(at(0.0, 1.234_567), 1.235);
    }

    #[test]
    fn layout_round_trips_and_supported_objects_land_on_their_parent() {
        let mut laptop = entry("obj002", "cat1", EntryKind::Template, (2.3, 1.1), 0.0);
        laptop.extent = (0.3, 0.2, 0.25);
        laptop.base = 0.75;
        laptop.supported_by = Some("obj001".into());
        let mut laptop2 = entry("obj003", "cat1", EntryKind::Instance, (2.0, 0.9), 200.0);
        laptop2.base = 0.8;
        laptop2.supported_by = Some("obj001".into());
        let index = index_of(
            0.025,
            vec![
                Category {
                    name: "cat0".into(),
                    template: "obj000".into(),
                    members: vec!["obj000".into(), "obj001".into()],
                },
                Category {
                    name: "cat1".into(),
                    template: "obj002".into(),
                    members: vec!["obj002".into(), "obj003".into()],
                },
            ],
            vec![
                entry("obj000", "cat0", EntryKind::Template, (-1.0, 0.0), 0.0),
                entry("obj001", "cat0", EntryKind::Instance, (2.0, 1.0), 90.0),
                laptop,
                laptop2,
            ],
        );
        let script = layout_script(
            &index,
            "mined",
            [-3.0, -2.0, 3.0, 2.0],
            ".",
            &BTreeMap::new(),
            f32::INFINITY,
        )
        .unwrap();
        let path = std::env::temp_dir().join("assetfield-mining-layout-test.ron");
        let (text, n) = script_text_checked(&script, &path).unwrap();
        assert_eq!(n, 4, "{text}");
        assert!(text.contains("Library(") && text.contains("on: \"obj001\""), "{text}");
        let loaded = assetfield_layout::load_str(&path, &text).unwrap();
        let r = resolve(&loaded, &PartsCatalog::from_script(&loaded)).unwrap();
        let get = |k: &str| r.by_key(k).unwrap_or_else(|| panic!("{k} in {text}"));
        let table = get("obj001");
        assert!((table.transform.position - Vec2::new(2.0, 1.0)).length() < 1e-3);
        assert!((table.transform.yaw_deg - 90.0).abs() < 1e-3);
        assert!((table.top - 0.75).abs() < 1e-3);
        assert!((table.bev_aabb.size() - Vec2::new(0.6, 1.0)).length() < 1e-3);
        // the supported objects are back at their world poses, standing on the table
        let l = get("obj001/obj002");
        assert_eq!(l.supported_by, Some(table.id));
        assert!((l.transform.position - Vec2::new(2.3, 1.1)).length() < 1e-3, "{:?}", l.transform);
        assert!(wrap_degrees(l.transform.yaw_deg).abs() < 1e-3);
        assert!((l.transform.base - 0.75).abs() < 1e-3);
        let l2 = get("obj001/obj003");
        assert!((l2.transform.position - Vec2::new(2.0, 0.9)).length() < 1e-3);
        assert!((wrap_degrees(l2.transform.yaw_deg) - wrap_degrees(200.0)).abs() < 1e-2);
        assert!((l2.transform.base - 0.8).abs() < 1e-3);
        // and the text is stable under a second round trip
        let again = assetfield_layout::source::parse_script(&path, &text).unwrap();
        assert_eq!(again, script);
    }

    #[test]
    fn own_patches_compare_residuals_measured_on_the_same_plane() {
        // density-plane residuals near 1, semantic-plane residuals near 0.01 (libraries
        // mined with different --yaw-on planes, merged): each plane has its own median; the
        // colour plane has only two residuals, too few for a median
        let mut entries = Vec::new();
        let mut categories = Vec::new();
        let kinds: [(&str, &[f32]); 3] = [
            ("density", &[1.0, 1.2, 3.0]),
            ("semantic", &[0.01, 0.012, 0.03]),
            ("color", &[0.5, 0.6]),
        ];
        for (c, (on, rs)) in kinds.into_iter().enumerate() {
            let cat = format!("cat{c}");
            let names: Vec<String> = (0..=rs.len()).map(|i| format!("obj{}", 4 * c + i)).collect();
            for (i, name) in names.iter().enumerate() {
                let kind = if i == 0 { EntryKind::Template } else { EntryKind::Instance };
                let mut e = entry(name, &cat, kind, (i as f32, c as f32 * 2.0), 0.0);
                e.residual = if i == 0 { 0.0 } else { rs[i - 1] };
                e.matched_on = Some(on.to_string());
                entries.push(e);
            }
            categories.push(Category { name: cat, template: names[0].clone(), members: names });
        }
        let own = |entries: &[Entry], r: f32| -> Vec<String> {
            let index = index_of(0.025, categories.clone(), entries.to_vec());
            let script =
                layout_script(&index, "m", [-3.0, -3.0, 9.0, 9.0], ".", &BTreeMap::new(), r)
                    .unwrap();
            let path = std::env::temp_dir().join("assetfield-own-patch-test.ron");
            let (text, _) = script_text_checked(&script, &path).unwrap();
            (0..12)
                .map(|i| format!("obj{i}"))
                .filter(|n| text.contains(&format!("asset: \"{n}\"")))
                .collect()
        };
        // twice its kind's median: obj3 (3.0 > 2.4) and obj7 (0.03 > 0.024); the colour
        // instances cannot be judged and keep their own patches
        assert_eq!(own(&entries, 2.0), ["obj3", "obj7", "obj9", "obj10"]);
        assert!(own(&entries, f32::INFINITY).is_empty());
        assert_eq!(own(&entries, 0.0).len(), 8);
        // older libraries (no `matched_on`) are judged together, against one median (0.6):
        // obj7, 3 times its own kind's median, would get the template
        for e in &mut entries {
            e.matched_on = None;
        }
        assert_eq!(own(&entries, 2.0), ["obj3"]);
    }

    #[test]
    fn assets_are_placed_and_turned_about_their_pivots() {
        // two street lamps whose poles stand 0.5 m behind their box centres; the second is
        // the first turned a quarter, its pole at (4, 1)
        let mut a = entry("obj000", "cat0", EntryKind::Template, (0.0, 0.0), 0.0);
        a.extent = (1.3, 0.3, 4.0);
        a.source_box = [-0.15, -0.15, 1.15, 0.15];
        a.pivot = Some((0.0, 0.0));
        let mut b = entry("obj001", "cat0", EntryKind::Instance, (4.0, 1.0), 90.0);
        b.extent = (0.3, 1.3, 4.0);
        b.source_box = [3.85, 0.85, 4.15, 2.15];
        b.pivot = Some((4.0, 1.0));
        let index = index_of(
            0.05,
            vec![Category {
                name: "cat0".into(),
                template: "obj000".into(),
                members: vec!["obj000".into(), "obj001".into()],
            }],
            vec![a, b],
        );
        let path = std::env::temp_dir().join("assetfield-mining-pivot-test.ron");
        // with the template (both placed by their poles) and with own patches: the same boxes
        for own in [f32::INFINITY, 0.0] {
            let script =
                layout_script(&index, "lamps", [-3.0, -3.0, 6.0, 4.0], ".", &BTreeMap::new(), own)
                    .unwrap();
            let (text, _) = script_text_checked(&script, &path).unwrap();
            assert!(text.contains("pivot: (-0.5, 0.0)"), "{text}");
            let loaded = assetfield_layout::load_str(&path, &text).unwrap();
            let r = resolve(&loaded, &PartsCatalog::from_script(&loaded)).unwrap();
            let lamp = r.by_key("obj001").unwrap();
            assert!((lamp.transform.position - Vec2::new(4.0, 1.0)).length() < 1e-3);
            let expected = Vec2::new(4.0, 1.5);
            let got = (lamp.bev_aabb.min + lamp.bev_aabb.max) * 0.5;
            assert!((got - expected).length() < 1e-3, "own {own}: box centre {got}\n{text}");
            assert!((lamp.bev_aabb.size() - Vec2::new(0.3, 1.3)).length() < 1e-3);
            let first = r.by_key("obj000").unwrap();
            assert!((first.transform.position - Vec2::ZERO).length() < 1e-3);
        }
    }
}
