//! The four formats the tools read, each as a fuzz target: where its valid inputs come from,
//! how one case mutates them, and what must hold of anything the loader accepts (the oracle:
//! a loader that says "ok" must hand over only finite, consistent values, and what the next
//! command does with them must work).

use crate::mutate::{Rng, mutate_safetensors, mutate_text};
use assetfield_core::Camera;
use assetfield_data::{Dataset, LoadOptions, Split};
use assetfield_field::eval::load_field;
use assetfield_layout::{AssetCatalog, PartsCatalog};
use assetfield_scene::AssetLibrary;
use glam::{Mat4, Vec3};
use std::path::{Path, PathBuf};

/// A format under test.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    Script,
    Dataset,
    Field,
    Library,
    /// The harness's own check: case 0 panics, 1 aborts, 2 hangs, 3 allocates beyond the
    /// memory limit, 4 breaks the oracle, the rest pass. Not one of [`Format::ALL`].
    Canary,
}

impl Format {
    pub const ALL: [Format; 4] = [Format::Script, Format::Dataset, Format::Field, Format::Library];

    pub fn name(self) -> &'static str {
        match self {
            Format::Script => "script",
            Format::Dataset => "dataset",
            Format::Field => "field",
            Format::Library => "library",
            Format::Canary => "canary",
        }
    }

    pub fn parse(s: &str) -> Option<Format> {
        Format::ALL.into_iter().chain([Format::Canary]).find(|f| f.name() == s)
    }
}

/// The valid inputs every case starts from, made once by the parent process.
#[derive(Debug, Clone)]
pub struct Seeds {
    /// The suite's scene scripts (`scenes/*.ron`).
    pub scripts: Vec<PathBuf>,
    /// A small synthesised dataset folder.
    pub dataset: PathBuf,
    /// A small trained field file.
    pub field: PathBuf,
    /// A library mined from that field.
    pub library: PathBuf,
}

/// One case's outcome: the loader refused the input (with this message), or accepted it and
/// everything that must hold of it held. A broken rule is `Err`.
pub type Outcome = Result<Verdict, String>;

#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Verdict {
    Accepted,
    Refused(String),
}

/// A worker's private copy of the inputs that live in folders (cases rewrite files there).
#[derive(Debug)]
pub struct Workspace {
    pub dir: PathBuf,
}

impl Workspace {
    pub fn new(seeds: &Seeds, dir: PathBuf) -> std::io::Result<Self> {
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir)?;
        copy_dir(&seeds.dataset, &dir.join("dataset"))?;
        copy_dir(&seeds.library, &dir.join("library"))?;
        Ok(Workspace { dir })
    }
}

fn copy_dir(from: &Path, to: &Path) -> std::io::Result<()> {
    std::fs::create_dir_all(to)?;
    for e in std::fs::read_dir(from)? {
        let e = e?;
        let target = to.join(e.file_name());
        if e.file_type()?.is_dir() {
            copy_dir(&e.path(), &target)?;
        } else {
            std::fs::copy(e.path(), target)?;
        }
    }
    Ok(())
}

/// What a case did to its input, for the report.
#[derive(Debug, Clone, Default)]
pub struct Case {
    pub input: String,
    pub mutations: Vec<String>,
    /// The mutated bytes (kept for [`crate::harness::reproduce`]).
    pub mutated: Vec<u8>,
}

/// Run case `number` of `format` (drawing from `rng`, seeded by it): mutate a valid input, load it as the tools do, check the
/// oracle. Files of the workspace that the case changed are restored before it returns.
pub fn run_case(
    format: Format,
    number: u64,
    seeds: &Seeds,
    ws: &Workspace,
    rng: &mut Rng,
    case: &mut Case,
) -> Outcome {
    match format {
        Format::Script => script_case(seeds, rng, case),
        Format::Dataset => dataset_case(ws, rng, case),
        Format::Field => field_case(seeds, ws, rng, case),
        Format::Library => library_case(ws, rng, case),
        Format::Canary => canary_case(number),
    }
}

/// Puts a file of the workspace back as it was when dropped, so that a case that panics
/// leaves the next case the valid input.
struct Restore {
    path: PathBuf,
    bytes: Vec<u8>,
}

impl Restore {
    fn keep(path: &Path) -> Result<Self, String> {
        let bytes = std::fs::read(path).map_err(|e| format!("{}: {e}", path.display()))?;
        Ok(Restore { path: path.to_path_buf(), bytes })
    }
}

impl Drop for Restore {
    fn drop(&mut self) {
        let _ = std::fs::write(&self.path, &self.bytes);
    }
}

/// The canary's cases, by number: each kind of failure the supervisor must catch.
fn canary_case(number: u64) -> Outcome {
    match number {
        0 => panic!("the canary panics"),
        1 => std::process::abort(),
        2 => loop {
            std::thread::sleep(std::time::Duration::from_secs(1));
        },
        3 => {
            // 8 GiB: beyond the workers' address-space limit, within what this machine would
            // hand out without it (no page is touched), so only the limit stops it
            let v: Vec<u8> = Vec::with_capacity(1 << 33);
            Ok(Verdict::Refused(format!("allocated {}", v.capacity())))
        }
        4 => Err("the canary breaks the oracle".into()),
        _ => Ok(Verdict::Accepted),
    }
}

fn refused(e: impl std::fmt::Display) -> Outcome {
    Ok(Verdict::Refused(e.to_string()))
}

fn finite(what: &str, v: &[f32]) -> Result<(), String> {
    match v.iter().position(|x| !x.is_finite()) {
        Some(k) => Err(format!("accepted with a non-finite {what} (value {k}: {})", v[k])),
        None => Ok(()),
    }
}

// --- scripts -----------------------------------------------------------------------------

fn script_case(seeds: &Seeds, rng: &mut Rng, case: &mut Case) -> Outcome {
    let path = rng.pick(&seeds.scripts).clone();
    let mut text = std::fs::read(&path).map_err(|e| format!("{}: {e}", path.display()))?;
    case.input = path.display().to_string();
    case.mutations = mutate_text(rng, &mut text);
    case.mutated = text.clone();
    let Ok(text) = String::from_utf8(text) else {
        return Ok(Verdict::Refused("not UTF-8".into()));
    };
    // the mutated text stands where the original did, so its relative includes resolve
    let script = match assetfield_layout::load_str(&path, &text) {
        Ok(s) => s,
        Err(e) => return refused(e),
    };
    let catalog = PartsCatalog::from_script(&script);
    let layout = match assetfield_layout::resolve(&script, &catalog) {
        Ok(l) => l,
        Err(e) => return refused(e),
    };
    for i in &layout.instances {
        let t = i.transform;
        finite(
            &format!("transform of instance {}", i.key),
            &[t.position.x, t.position.y, t.yaw_deg, t.scale, t.base, i.top],
        )?;
        if t.scale <= 0.0 {
            return Err(format!("accepted instance {} with scale {}", i.key, t.scale));
        }
        let b = i.bev_aabb;
        finite(&format!("box of instance {}", i.key), &[b.min.x, b.min.y, b.max.x, b.max.y])?;
    }
    let e = layout.extent;
    finite("extent", &[e.min.x, e.min.y, e.max.x, e.max.y])?;
    if let Some(v) = &script.views {
        let json = serde_json::to_string(v).map_err(|e| e.to_string())?;
        if json.contains("null") {
            return Err(format!("accepted view settings with a non-finite value: {json}"));
        }
    }
    // every asset the layout uses is one the catalog knows
    for i in &layout.instances {
        if catalog.asset_info(&i.asset).is_none() {
            return Err(format!("instance {} uses unknown asset {:?}", i.key, i.asset));
        }
    }
    Ok(Verdict::Accepted)
}

// --- datasets ----------------------------------------------------------------------------

fn dataset_case(ws: &Workspace, rng: &mut Rng, case: &mut Case) -> Outcome {
    let dir = ws.dir.join("dataset");
    let test_file = rng.chance(0.2);
    let json_path =
        dir.join(if test_file { "transforms_test.json" } else { "transforms_train.json" });
    let json = Restore::keep(&json_path)?;
    let mut text = json.bytes.clone();
    case.input = json_path.display().to_string();
    case.mutations = mutate_text(rng, &mut text);
    // now and then an image is damaged too
    let image = Restore::keep(&dir.join("train/r_0.png"))?;
    if rng.chance(0.1) {
        let cut = rng.below(image.bytes.len());
        std::fs::write(&image.path, &image.bytes[..cut]).map_err(|e| e.to_string())?;
        case.mutations.push(format!("train/r_0.png truncated to {cut} bytes"));
    }
    case.mutated = text.clone();
    std::fs::write(&json_path, &text).map_err(|e| e.to_string())?;
    let split = if rng.chance(0.5) { Split::Train } else { Split::All };
    let result = Dataset::load(&dir, split, &LoadOptions::default());
    drop((json, image));
    let data = match result {
        Ok(d) => d,
        Err(e) => return refused(e),
    };
    if let Some(s) = data.aabb_scale
        && !(s.is_finite() && s > 0.0)
    {
        return Err(format!("accepted aabb_scale {s}"));
    }
    // what the file said, where the loaded cameras cannot show it (an angle of 2 pi + a
    // gives the focal length of a, a translation of 1e30 is finite), if it was read at all
    let read = !test_file || split == Split::All;
    if read && let Ok(v) = serde_json::from_slice::<serde_json::Value>(&case.mutated) {
        check_transforms_json(&v)?;
    }
    for f in &data.frames {
        check_camera(&f.camera).map_err(|e| format!("frame {} ({}): {e}", f.index, f.file_path))?;
        let k = &f.camera.intrinsics;
        if (f.image.width, f.image.height) != (k.width, k.height) {
            return Err(format!(
                "frame {}: image {}x{} but intrinsics {}x{}",
                f.index, f.image.width, f.image.height, k.width, k.height
            ));
        }
        finite(&format!("pixel of frame {}", f.index), &f.image.rgb)?;
    }
    Ok(Verdict::Accepted)
}

/// The largest camera distance from the origin a loader may accept (scene units): a looser
/// bound than any validator's, so that only nonsense trips it.
const FARTHEST_CAMERA: f64 = 1e9;

/// Values of a `transforms_*.json` that an accepted file holds in range: angles of view in
/// (0, pi), positive image sizes and focal lengths, camera positions within reach.
fn check_transforms_json(v: &serde_json::Value) -> Result<(), String> {
    let frames = v.get("frames").and_then(|f| f.as_array()).cloned().unwrap_or_default();
    let mut scopes = vec![("the file".to_string(), v)];
    scopes.extend(frames.iter().enumerate().map(|(k, f)| (format!("frame {k}"), f)));
    for (place, obj) in scopes {
        let num = |key: &str| obj.get(key).and_then(serde_json::Value::as_f64);
        for key in ["camera_angle_x", "camera_angle_y"] {
            if let Some(a) = num(key)
                && !(a > 0.0 && a < std::f64::consts::PI)
            {
                return Err(format!("accepted {key} {a} in {place}"));
            }
        }
        for key in ["w", "h", "fl_x", "fl_y"] {
            if let Some(x) = num(key)
                && x <= 0.0
            {
                return Err(format!("accepted {key} {x} in {place}"));
            }
        }
        if let Some(rows) = obj.get("transform_matrix").and_then(|m| m.as_array()) {
            for row in rows.iter().take(3) {
                if let Some(t) = row.get(3).and_then(serde_json::Value::as_f64)
                    && t.abs() > FARTHEST_CAMERA
                {
                    return Err(format!("accepted a camera at {t} in {place}"));
                }
            }
        }
    }
    Ok(())
}

/// What every accepted camera satisfies: positive image size, positive finite focal lengths,
/// a finite principal point, a rigid camera-to-world transform at a finite place.
fn check_camera(c: &Camera) -> Result<(), String> {
    let k = &c.intrinsics;
    if k.width == 0 || k.height == 0 {
        return Err(format!("accepted image size {}x{}", k.width, k.height));
    }
    finite("intrinsics", &[k.fx, k.fy, k.cx, k.cy])?;
    if k.fx <= 0.0 || k.fy <= 0.0 {
        return Err(format!("accepted focal lengths {} {}", k.fx, k.fy));
    }
    let m = Mat4::from(c.c2w);
    finite("camera matrix", &m.to_cols_array())?;
    assetfield_core::camera::check_rigid(&m).map_err(|e| format!("accepted a camera that {e}"))?;
    // a ray through the image centre is a finite ray
    let r = c.pixel_ray(k.width / 2, k.height / 2);
    finite("centre ray", &[r.origin.x, r.origin.y, r.origin.z, r.dir.x, r.dir.y, r.dir.z])
}

// --- fields ------------------------------------------------------------------------------

fn field_case(seeds: &Seeds, ws: &Workspace, rng: &mut Rng, case: &mut Case) -> Outcome {
    let mut bytes = std::fs::read(&seeds.field).map_err(|e| e.to_string())?;
    case.input = seeds.field.display().to_string();
    case.mutations = mutate_safetensors(rng, &mut bytes);
    let path = ws.dir.join("field.safetensors");
    case.mutated = bytes.clone();
    std::fs::write(&path, &bytes).map_err(|e| e.to_string())?;
    let loaded = match load_field(&path) {
        Ok(l) => l,
        Err(e) => return refused(e),
    };
    let f = &loaded.field;
    let cfg = &f.config;
    finite("parameter", &f.params.data)?;
    let [lo, hi] = cfg.aabb;
    finite("box", &[lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]])?;
    if (0..3).any(|k| lo[k] >= hi[k]) {
        return Err(format!("accepted an empty box {:?}", cfg.aabb));
    }
    if cfg.res.contains(&0) {
        return Err(format!("accepted resolution {:?}", cfg.res));
    }
    if !(cfg.step_ratio.is_finite() && cfg.step_ratio > 0.0) {
        return Err(format!("accepted step ratio {}", cfg.step_ratio));
    }
    // a small view of the field renders to finite colours
    let (lo, hi) = (Vec3::from(lo), Vec3::from(hi));
    let centre = (lo + hi) * 0.5;
    let eye = centre + (hi - lo) * Vec3::new(0.9, -0.7, 0.8);
    let k = assetfield_core::Intrinsics::from_fov_x(6, 6, 0.8);
    let cam = Camera::look_at(k, eye, centre, Vec3::Z);
    let rgb = assetfield_field::train::render_view(f, loaded.occupancy.as_ref(), &cam, Vec3::ONE);
    finite("rendered colour", &rgb)?;
    Ok(Verdict::Accepted)
}

// --- libraries ---------------------------------------------------------------------------

/// The files of a library a case may damage (index text, or one of its tensor files).
const LIBRARY_FILES: [&str; 3] = ["index.ron", "patches.safetensors", "shared.safetensors"];

fn library_case(ws: &Workspace, rng: &mut Rng, case: &mut Case) -> Outcome {
    let dir = ws.dir.join("library");
    let name = *rng.pick(&LIBRARY_FILES);
    let path = dir.join(name);
    let original = Restore::keep(&path)?;
    let mut bytes = original.bytes.clone();
    case.input = path.display().to_string();
    case.mutations = if name.ends_with(".ron") {
        mutate_text(rng, &mut bytes)
    } else {
        mutate_safetensors(rng, &mut bytes)
    };
    case.mutated = bytes.clone();
    std::fs::write(&path, &bytes).map_err(|e| e.to_string())?;
    library_oracle(&dir)
}

/// What `assetfield library check` accepts, `compose` must be able to use: every entry's
/// patch, the library's own canvas, all of it finite.
fn library_oracle(dir: &Path) -> Outcome {
    let lib = match AssetLibrary::open(dir) {
        Ok(l) => l,
        Err(e) => return refused(e),
    };
    for e in &lib.index.entries {
        finite(
            &format!("value of entry {}", e.name),
            &[e.extent.0, e.extent.1, e.extent.2, e.base, e.position.0, e.position.1, e.yaw_deg],
        )?;
        finite(&format!("source box of entry {}", e.name), &e.source_box)?;
    }
    let t = lib.texel();
    if !(t.x > 0.0 && t.y > 0.0 && t.is_finite()) {
        return Err(format!("accepted texel size {t}"));
    }
    let patches = lib.patches(None).map_err(|e| format!("accepted, yet a patch fails: {e}"))?;
    for p in patches.values() {
        finite(&format!("density of patch {}", p.name), &p.density)?;
    }
    lib.composition(&lib.default_canvas())
        .map_err(|e| format!("accepted, yet its canvas fails: {e}"))?;
    Ok(Verdict::Accepted)
}
