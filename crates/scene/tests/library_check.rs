//! The library check and the composer's loader are one function: every library it accepts
//! composes (opens, builds both canvases, cuts every patch, places and renders an entry),
//! and every broken library found by fuzzing `compose` is refused by the check, naming the
//! file and the entry, container or tensor.

use assetfield_core::{Camera, Intrinsics, Rect2, TensorFile};
use assetfield_library::{
    INDEX_FILE, LibraryIndex, content_hash, index_from_ron, index_to_ron, open_library,
    write_sample_library,
};
use assetfield_scene::{AssetLibrary, Canvas, Composer, ScriptAssets};
use glam::{Vec2, Vec3};
use std::path::{Path, PathBuf};

fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir()
        .join(format!("assetfield-scene-libcheck-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn read_index(dir: &Path) -> LibraryIndex {
    let p = dir.join(INDEX_FILE);
    index_from_ron(&p, &std::fs::read_to_string(&p).unwrap()).unwrap()
}

fn write_index(dir: &Path, index: &LibraryIndex) {
    std::fs::write(dir.join(INDEX_FILE), index_to_ron(index).unwrap()).unwrap();
}

/// Edit the shared file (and keep the index's hash and tensor list in step, so that only
/// the edit itself is wrong).
fn edit_shared(dir: &Path, edit: impl FnOnce(&mut TensorFile)) {
    let p = dir.join("shared.safetensors");
    let mut f = TensorFile::load(&p).unwrap();
    edit(&mut f);
    f.save(&p).unwrap();
    let mut index = read_index(dir);
    index.shared.hash = content_hash(&f);
    index.shared.tensors = f.names().map(str::to_string).collect();
    write_index(dir, &index);
}

fn edit_patches(dir: &Path, edit: impl FnOnce(&mut TensorFile)) {
    let p = dir.join("patches.safetensors");
    let mut f = TensorFile::load(&p).unwrap();
    edit(&mut f);
    f.save(&p).unwrap();
}

fn edit_config(dir: &Path, edit: impl FnOnce(&mut serde_json_lite::Json)) {
    edit_shared(dir, |f| {
        let mut c = serde_json_lite::Json(f.meta("config").unwrap().to_string());
        edit(&mut c);
        f.set_meta("config", c.0);
    });
}

/// Text edits of the JSON configuration (this crate has no JSON parser).
mod serde_json_lite {
    #[derive(Debug)]
    pub struct Json(pub String);
    impl Json {
        /// Replace the value of `"key":` up to the next `,` or `}` with `value`.
        pub fn set(&mut self, key: &str, value: &str) {
            let pat = format!("\"{key}\":");
            let at = self.0.find(&pat).unwrap_or_else(|| panic!("{key} in {}", self.0)) + pat.len();
            let mut depth = 0;
            let mut end = at;
            for (i, ch) in self.0[at..].char_indices() {
                match ch {
                    '[' | '{' => depth += 1,
                    ']' | '}' if depth > 0 => depth -= 1,
                    ',' | '}' if depth == 0 => {
                        end = at + i;
                        break;
                    }
                    _ => {}
                }
            }
            self.0.replace_range(at..end, value);
        }
    }
}

/// Everything `assetfield compose` does with a library, on the CPU: open it, build the
/// default and an empty canvas, cut every entry's patch, place the template through a
/// layout script and render one view.
fn compose(dir: &Path) -> Result<(), String> {
    let lib = AssetLibrary::open(dir).map_err(|e| e.to_string())?;
    lib.composition(&Canvas::Empty { extent: Rect2::new(Vec2::ZERO, Vec2::splat(0.6)) })
        .map_err(|e| e.to_string())?;
    lib.patches(None).map_err(|e| e.to_string())?;
    let script_path = dir.join("../compose-script.ron");
    let template = lib.index.categories[0].template.clone();
    std::fs::write(
        &script_path,
        format!("Scene(layout: [Instance(asset: \"{template}\", at: (0.2, 0.2), yaw: 30)])\n"),
    )
    .unwrap();
    let script = assetfield_layout::load(&script_path).map_err(|e| e.to_string())?;
    let assets = ScriptAssets::resolve(&script, &lib, None).map_err(|e| e.to_string())?;
    let layout = assetfield_layout::resolve(&script, &assets).map_err(|e| e.to_string())?;
    let comp = lib.composition(&lib.default_canvas()).map_err(|e| e.to_string())?;
    let mut composer = Composer::new(comp);
    assets.install(&mut composer).map_err(|e| e.to_string())?;
    composer.apply_layout(&layout).map_err(|e| e.to_string())?;
    composer.update();
    composer.ensure_occupancy();
    let k = Intrinsics::from_fov_x(8, 8, 0.9);
    let cam = Camera::look_at(k, Vec3::new(0.25, -1.0, 1.0), Vec3::new(0.25, 0.2, 0.0), Vec3::Z);
    let rgb = composer.render(&cam, Vec3::ONE);
    if rgb.iter().any(|v| !v.is_finite()) {
        return Err("the render holds non-finite values".into());
    }
    Ok(())
}

#[test]
fn the_sample_library_checks_and_composes() {
    let root = scratch("ok");
    let dir = root.join("lib");
    write_sample_library(&dir, 0.25).unwrap();
    let lib = open_library(&dir).unwrap();
    assert_eq!(lib.config.density_channels, 2);
    compose(&dir).unwrap();
    std::fs::remove_dir_all(&root).unwrap();
}

/// A broken library: how to break it, which file the error must name, and what else.
type Case = (&'static str, fn(&Path), &'static str, &'static [&'static str]);

fn cases() -> Vec<Case> {
    fn index(dir: &Path, edit: impl FnOnce(&mut LibraryIndex)) {
        let mut ix = read_index(dir);
        edit(&mut ix);
        write_index(dir, &ix);
    }
    vec![
        (
            "texel size (0, 0)",
            |d| index(d, |ix| ix.texel_size = (0.0, 0.0)),
            "index.ron",
            &["\"texel_size\" is (0.0, 0.0)", "positive and finite"],
        ),
        (
            "texel size NaN",
            |d| index(d, |ix| ix.texel_size.1 = f32::NAN),
            "index.ron",
            &["texel_size"],
        ),
        (
            "a listed but missing shared tensor",
            |d| index(d, |ix| ix.shared.tensors.push("decoder.7.weight".into())),
            "shared.safetensors",
            &["missing tensor \"decoder.7.weight\"", "lists"],
        ),
        (
            "a shared config that does not fit its tensors",
            |d| edit_config(d, |c| c.set("basis_dim", "5")),
            "shared.safetensors",
            &["tensor \"color.basis.weight\" has shape [3, 4]", "[5, 4]"],
        ),
        (
            "a shared config out of bounds",
            |d| edit_config(d, |c| c.set("res", "[100000,100000,32]")),
            "shared.safetensors",
            &["metadata \"config\": \"res[0]\" is 100000", "2 to 4096"],
        ),
        (
            "a shared config with a zero step",
            |d| edit_config(d, |c| c.set("step_ratio", "0.0")),
            "shared.safetensors",
            &["\"step_ratio\" is 0.0"],
        ),
        (
            "a VM shared config",
            |d| edit_config(d, |c| c.set("kind", "\"Vm\"")),
            "shared.safetensors",
            &["metadata \"config\": \"kind\" is Vm", "no ground planes"],
        ),
        (
            "no shared config",
            |d| {
                edit_shared(d, |f| {
                    f.metadata.remove("config");
                })
            },
            "shared.safetensors",
            &["config"],
        ),
        (
            "a shared tensor removed",
            |d| {
                edit_shared(d, |f| {
                    f.tensors.remove("decoder.1.bias");
                })
            },
            "shared.safetensors",
            &["missing tensor \"decoder.1.bias\""],
        ),
        (
            "a NaN-filled shared tensor",
            |d| {
                edit_shared(d, |f| {
                    let t = f.get_f32("density.axis", &[32, 2]).unwrap().to_vec();
                    f.insert_f32("density.axis", &[32, 2], t.iter().map(|_| f32::NAN).collect());
                })
            },
            "shared.safetensors",
            &["tensor \"density.axis\" has a non-finite value (NaN) at index 0"],
        ),
        (
            "a shared tensor too large to decode (found by the fuzz harness)",
            |d| {
                edit_shared(d, |f| {
                    let mut t = f.get_f32("density.axis", &[32, 2]).unwrap().to_vec();
                    t[3] = 3.0e38;
                    f.insert_f32("density.axis", &[32, 2], t);
                })
            },
            "shared.safetensors",
            &[
                "tensor \"density.axis\": \"value 3\" is 300000000000000000000000000000000000000, expected within 1e6",
            ],
        ),
        (
            "a shared tensor changed behind the index's back",
            |d| {
                let p = d.join("shared.safetensors");
                let mut f = TensorFile::load(&p).unwrap();
                f.insert_f32("decoder.1.bias", &[3], vec![9.0; 3]);
                f.save(&p).unwrap();
            },
            "shared.safetensors",
            &["content hash"],
        ),
        (
            "no format tag on the shared file",
            |d| {
                edit_shared(d, |f| {
                    f.metadata.remove("format");
                })
            },
            "shared.safetensors",
            &["\"metadata \"format\"\" is None", "assetfield-library-shared/1"],
        ),
        (
            "a missing shared file",
            |d| std::fs::remove_file(d.join("shared.safetensors")).unwrap(),
            "shared.safetensors",
            &[],
        ),
        (
            "NaN extent",
            |d| index(d, |ix| ix.entries[1].extent.0 = f32::NAN),
            "index.ron",
            &["entry \"obj001\": \"extent\" is [NaN, 0.2, 0.5], expected finite numbers"],
        ),
        (
            "negative extent",
            |d| index(d, |ix| ix.entries[0].extent.2 = -1.0),
            "index.ron",
            &["entry \"obj000\": \"extent\"", "non-negative"],
        ),
        (
            "NaN position",
            |d| index(d, |ix| ix.entries[1].position.1 = f32::NAN),
            "index.ron",
            &["entry \"obj001\": \"position\""],
        ),
        (
            "infinite yaw",
            |d| index(d, |ix| ix.entries[1].yaw_deg = f32::INFINITY),
            "index.ron",
            &["entry \"obj001\": \"yaw_deg\" is inf"],
        ),
        (
            "NaN pivot",
            |d| index(d, |ix| ix.entries[0].pivot = Some((f32::NAN, 0.0))),
            "index.ron",
            &["entry \"obj000\": \"pivot\""],
        ),
        (
            "NaN base",
            |d| index(d, |ix| ix.entries[0].base = f32::NAN),
            "index.ron",
            &["entry \"obj000\": \"base\" is NaN"],
        ),
        (
            "an inverted source box",
            |d| index(d, |ix| ix.entries[0].source_box = [0.3, 0.0, 0.0, 0.2]),
            "index.ron",
            &["entry \"obj000\": \"source_box\""],
        ),
        (
            "NaN source box",
            |d| index(d, |ix| ix.entries[0].source_box[2] = f32::NAN),
            "index.ron",
            &["entry \"obj000\": \"source_box\""],
        ),
        (
            "a NaN-filled patch",
            |d| edit_patches(d, |f| f.insert_f32("obj001.color", &[2, 3, 4], vec![f32::NAN; 24])),
            "patches.safetensors",
            &["tensor \"obj001.color\" has a non-finite value (NaN) at index 0"],
        ),
        (
            "a NaN in a container",
            |d| {
                edit_patches(d, |f| {
                    let mut v = vec![0.0; 40];
                    v[17] = f32::NEG_INFINITY;
                    f.insert_f32("container.density", &[4, 5, 2], v);
                })
            },
            "patches.safetensors",
            &["tensor \"container.density\" has a non-finite value (-inf) at index 17"],
        ),
        (
            "a missing patches file",
            |d| std::fs::remove_file(d.join("patches.safetensors")).unwrap(),
            "patches.safetensors",
            &[],
        ),
        (
            "a patch tensor missing",
            |d| {
                edit_patches(d, |f| {
                    f.tensors.remove("obj000.mask");
                })
            },
            "patches.safetensors",
            &["missing tensor \"obj000.mask\"", "entry \"obj000\""],
        ),
        (
            "a patch of another shape than the index says",
            |d| index(d, |ix| ix.entries[1].patch_size = (3, 3)),
            "patches.safetensors",
            &["\"obj001.density\" has shape [2, 3, 2]", "[3, 3, 2]"],
        ),
        (
            "a mask stored as floats",
            |d| edit_patches(d, |f| f.insert_f32("obj000.mask", &[2, 3], vec![1.0; 6])),
            "patches.safetensors",
            &["\"obj000.mask\" has dtype F32, expected U8"],
        ),
        (
            "an empty patch",
            |d| {
                index(d, |ix| ix.entries[0].patch_size = (0, 3));
                edit_patches(d, |f| {
                    f.insert_f32("obj000.density", &[0, 3, 2], vec![]);
                    f.insert_f32("obj000.color", &[0, 3, 4], vec![]);
                    f.insert_u8("obj000.mask", &[0, 3], vec![]);
                });
            },
            "index.ron",
            &["entry \"obj000\": \"patch_size\" is (0, 3)"],
        ),
        (
            "a container of one row",
            |d| {
                index(d, |ix| ix.containers[0].size = (1, 5));
                edit_patches(d, |f| {
                    f.insert_f32("container.density", &[1, 5, 2], vec![0.0; 10]);
                    f.insert_f32("container.color", &[1, 5, 4], vec![0.0; 20]);
                    f.insert_u8("container.mask", &[1, 5], vec![0; 5]);
                });
            },
            "index.ron",
            &["container \"container\": \"size\" is (1, 5)", "2 to 4096"],
        ),
        (
            "a container with an inverted world box",
            |d| index(d, |ix| ix.containers[0].world = [0.5, 0.0, 0.0, 0.4]),
            "index.ron",
            &["container \"container\": \"world\""],
        ),
        (
            "channels that are not the shared config's",
            |d| {
                index(d, |ix| ix.channels = (3, 4));
                edit_patches(d, |f| {
                    for name in ["obj000", "obj001"] {
                        f.insert_f32(format!("{name}.density"), &[2, 3, 3], vec![0.1; 18]);
                    }
                    f.insert_f32("container.density", &[4, 5, 3], vec![0.0; 60]);
                });
            },
            "index.ron",
            &["\"channels\" is (3, 4), expected (2, 4), the channels of the shared configuration"],
        ),
        (
            "no channels",
            |d| index(d, |ix| ix.channels = (0, 4)),
            "index.ron",
            &["\"channels\" is (0, 4)"],
        ),
        (
            "a VM model",
            |d| index(d, |ix| ix.model = "vm".into()),
            "index.ron",
            &["\"model\" is \"vm\""],
        ),
        (
            "a model that is not the shared config's",
            |d| index(d, |ix| ix.model = "i".into()),
            "index.ron",
            &["\"model\" is \"i\", expected \"s\""],
        ),
        (
            "two entries of one name",
            |d| index(d, |ix| ix.entries[1].name = "obj000".into()),
            "index.ron",
            &["unique entry names"],
        ),
        (
            "an entry of an unknown source",
            |d| index(d, |ix| ix.entries[1].source = 4),
            "index.ron",
            &["entry \"obj001\": \"source\" is 4"],
        ),
        (
            "an entry of an unknown category",
            |d| index(d, |ix| ix.entries[1].category = "cat9".into()),
            "index.ron",
            &["entry \"obj001\": \"category\" is \"cat9\""],
        ),
        (
            "an entry on an unknown support",
            |d| index(d, |ix| ix.entries[1].supported_by = Some("obj9".into())),
            "index.ron",
            &["entry \"obj001\": \"supported_by\" is \"obj9\""],
        ),
        (
            "a category naming an unknown entry",
            |d| index(d, |ix| ix.categories[0].members.push("obj5".into())),
            "index.ron",
            &["category \"cat0\" names entry \"obj5\""],
        ),
        (
            "a malformed index",
            |d| std::fs::write(d.join(INDEX_FILE), "Library(format: 3").unwrap(),
            "index.ron",
            &[],
        ),
    ]
}

#[test]
fn every_broken_library_is_refused_by_the_check_naming_file_and_place() {
    let root = scratch("cases");
    for (k, (what, breaks, file, needles)) in cases().into_iter().enumerate() {
        let dir = root.join(format!("lib{k}"));
        write_sample_library(&dir, 0.25).unwrap();
        breaks(&dir);
        // `assetfield library check` runs open_library
        let e = match open_library(&dir) {
            Ok(_) => panic!("{what}: the library check accepted it"),
            Err(e) => e.to_string(),
        };
        let path = dir.join(file).display().to_string();
        assert!(e.contains(&path), "{what}: the error must name {path}: {e}");
        for n in needles {
            assert!(e.contains(n), "{what}: expected {n:?} in: {e}");
        }
        // compose refuses it with the same words
        let c = compose(&dir).unwrap_err();
        assert!(c.contains(&e), "{what}: compose says {c}, the check {e}");
    }
    std::fs::remove_dir_all(&root).unwrap();
}

/// One change to an index.
type IndexEdit = Box<dyn Fn(&mut LibraryIndex)>;

/// Deterministic fuzzing of the index's numbers and sizes: whatever the check accepts,
/// compose must compose (without error or panic).
#[test]
fn whatever_the_check_accepts_composes() {
    let root = scratch("fuzz");
    let base = root.join("base");
    write_sample_library(&base, 0.25).unwrap();
    let good = read_index(&base);
    let floats = [0.0, -0.0, -1.0, 1e-30, 1e30, 3.0e38, f32::NAN, f32::INFINITY, -f32::INFINITY];
    let sizes = [0usize, 1, 2, 3, 7, 100_000, usize::MAX];
    let mut accepted = 0;
    let mut n = 0;
    let mut edits: Vec<IndexEdit> = Vec::new();
    for &v in &floats {
        edits.push(Box::new(move |ix| ix.texel_size.0 = v));
        edits.push(Box::new(move |ix| ix.texel_size = (v, v)));
        edits.push(Box::new(move |ix| ix.entries[0].extent.1 = v));
        edits.push(Box::new(move |ix| ix.entries[0].base = v));
        edits.push(Box::new(move |ix| ix.entries[0].position.0 = v));
        edits.push(Box::new(move |ix| ix.entries[0].pivot = Some((v, 0.0))));
        edits.push(Box::new(move |ix| ix.entries[1].yaw_deg = v));
        edits.push(Box::new(move |ix| ix.entries[1].residual = v));
        edits.push(Box::new(move |ix| ix.entries[1].source_box[0] = v));
        edits.push(Box::new(move |ix| ix.containers[0].world[0] = v));
        edits.push(Box::new(move |ix| ix.containers[0].world[3] = v));
    }
    for &s in &sizes {
        edits.push(Box::new(move |ix| ix.entries[0].patch_size.0 = s));
        edits.push(Box::new(move |ix| ix.containers[0].size.1 = s));
        edits.push(Box::new(move |ix| ix.channels.0 = s));
        edits.push(Box::new(move |ix| ix.entries[1].source = s));
        edits.push(Box::new(move |ix| ix.containers[0].source = s));
    }
    for edit in &edits {
        n += 1;
        let dir = root.join(format!("lib{n}"));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        for f in ["patches.safetensors", "shared.safetensors"] {
            std::fs::copy(base.join(f), dir.join(f)).unwrap();
        }
        let mut ix = good.clone();
        edit(&mut ix);
        write_index(&dir, &ix);
        let checked = open_library(&dir).is_ok();
        let composed = std::panic::catch_unwind(|| compose(&dir));
        match (checked, composed) {
            (true, Ok(Ok(()))) => accepted += 1,
            (true, Ok(Err(e))) => panic!("case {n}: the check accepted it but compose failed: {e}"),
            (_, Err(_)) => panic!("case {n}: compose panicked (check ok: {checked})"),
            (false, Ok(_)) => {}
        }
        let _ = std::fs::remove_dir_all(&dir);
    }
    assert!(accepted > 10, "only {accepted} of {n} variants were accepted");
    std::fs::remove_dir_all(&root).unwrap();
}
