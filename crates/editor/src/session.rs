//! An editing session: a library, the layout being edited (a base script plus edit batches),
//! the composer that keeps the composed planes up to date, undo and redo, renders and save.
//!
//! Every change goes through [`EditSession::apply`] (one batch of edits in the layout
//! language), [`EditSession::undo`] or [`EditSession::redo`]; each resolves the whole
//! script again (milliseconds for a room) and hands the resolved layout to the composer,
//! which redraws only the instances whose placement or asset changed. A batch that does not
//! parse or resolve, or that the composer refuses, changes nothing.

use std::path::{Path, PathBuf};

use assetfield_core::{Aabb3, Camera};
use assetfield_core::{Orbit, fitting_radius};
use assetfield_gpu::{GpuContext, GpuView, GpuViews};
use assetfield_layout::source::{EditNode, SourceFile};
use assetfield_layout::{
    AssetDef, Edit, LibraryRef, LoadedScript, ResolvedLayout, Script, resolve,
};
use assetfield_scene::{AssetLibrary, Composer, ScriptAssets};
use glam::{Vec2, Vec3};
use serde::Serialize;

use crate::bev::{BevColumns, BevMapping, bev_picture};
use crate::error::{EditorError, Result};

/// Largest render side the session accepts, pixels.
pub const MAX_RENDER_SIDE: u32 = 2048;

/// Instances a session's layout may come to hold (everything its script and edits make,
/// removed ones included, as [`assetfield_layout::Limits::max_instances`] counts them),
/// unless `ASSETFIELD_MAX_INSTANCES` or `--limit instances=N` sets that limit; twice the
/// starting layout's count when that is more. A room or a hall has hundreds to a few
/// thousand; composing 20,000 takes a few seconds here, where the scripts' own default
/// (1,000,000) would hold the session for minutes on one request.
pub const EDITOR_MAX_INSTANCES: usize = 20_000;

/// Default time a CPU render may take before it is cancelled (the GPU renders the largest
/// view in well under a second): a 512 x 512 view of a room takes about a second on two
/// cores, a 2048 x 2048 one over a minute.
pub const DEFAULT_RENDER_BUDGET: std::time::Duration = std::time::Duration::from_secs(10);

/// How the session was asked to start.
#[derive(Debug, Clone, Default)]
pub struct SessionOptions {
    /// The file Save writes (default `LIB/edited.ron`). When it exists, the session starts
    /// from it: an edit script (`Scene(base: ..., edits: [...])`) continues its edits; a
    /// whole layout script is edited in place (Save appends the session's edits to it).
    pub layout: Option<PathBuf>,
    /// Texels around each entry's mask that its patch covers (default: its source scene's,
    /// [`AssetLibrary::source_halo`]).
    pub halo: Option<usize>,
    /// Time a CPU render may take before it is cancelled (default [`DEFAULT_RENDER_BUDGET`]).
    pub render_budget: Option<std::time::Duration>,
}

/// What Save writes.
#[derive(Debug, Clone)]
enum SaveAs {
    /// `Scene(base: "<relative path>", edits: [...])`: the edits of the start file (if it
    /// was an edit script) and the session's.
    EditScript { base: String, earlier: Vec<Edit> },
    /// The start file itself with the session's edits appended to its own.
    Whole { script: Box<Script> },
}

/// One applied batch of edits: where its edits (and the request text they came from, when
/// it has one) start in the session's script, and its edits (for the log and Save). Undo
/// cuts the script back there; the memory a session holds is the text of its requests once,
/// however long the history.
#[derive(Debug, Clone)]
struct Batch {
    edits_at: usize,
    files_at: usize,
    edits: Vec<Edit>,
}

/// A batch taken back: its place, and what undo cut from the script (put back by redo,
/// without parsing anything again).
#[derive(Debug, Clone)]
struct Undone {
    batch: Batch,
    nodes: Vec<EditNode>,
    files: Vec<SourceFile>,
}

/// A view of the composed scene to render.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ViewRequest {
    pub width: u32,
    pub height: u32,
    /// Degrees counter-clockwise from +X, seen from above.
    pub azimuth_deg: f32,
    /// Degrees above the ground.
    pub elevation_deg: f32,
    /// Distance from the scene's centre (default: where the scene's box fits the view).
    pub radius: Option<f32>,
}

/// Horizontal field of view of [`ViewRequest`] renders, degrees.
pub const VIEW_FOV_DEG: f32 = 40.0;

/// An instance as the page and the API describe it.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct InstanceView {
    pub key: String,
    pub category: String,
    pub asset: String,
    pub x: f32,
    pub y: f32,
    pub yaw_deg: f32,
    pub scale: f32,
    /// Footprint corners in world (x, y), counter-clockwise.
    pub footprint: Vec<[f32; 2]>,
    /// Key of the instance it stands on.
    pub on: Option<String>,
}

/// A category of the library.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct CategoryView {
    pub name: String,
    /// The name people read (a `NameCategory` edit's), else `name`.
    pub label: String,
    pub template: String,
    pub members: Vec<String>,
}

/// An asset a layout can name: a category (drawn with its template) or an entry (its own
/// patch).
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct AssetView {
    pub name: String,
    pub category: String,
    /// `"category"` or `"entry"`.
    pub kind: &'static str,
    /// Footprint size (x, y) and height, world units.
    pub size: [f32; 3],
}

/// The layout as `GET /api/layout` answers it.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct LayoutView {
    /// Bumped by every change (edits, undo, redo).
    pub version: u64,
    pub instances: Vec<InstanceView>,
    pub categories: Vec<CategoryView>,
    pub assets: Vec<AssetView>,
    /// The composed planes' world rectangle `[xmin, ymin, xmax, ymax]`.
    pub extent: [f32; 4],
    /// How `GET /api/bev` pixels map to the world.
    pub bev: BevMapping,
    pub can_undo: bool,
    pub can_redo: bool,
    /// The session's edits as RON (the language `compose --edits` reads).
    pub edits: String,
    /// Where Save writes.
    pub save_path: String,
    /// Whether the layout changed since it was opened or last saved.
    pub unsaved: bool,
    /// Each category's colour (`#rrggbb`) in the bird's-eye view and the panels: the
    /// layout's categories in name order take `palette(0, 1, ...)`, as in `compose`'s
    /// `layout.png`; the library's other categories follow.
    pub category_colours: std::collections::BTreeMap<String, String>,
}

/// An editing session over one library.
pub struct EditSession {
    lib: AssetLibrary,
    assets: ScriptAssets,
    /// The script as it stands: the start file as loaded, then every applied batch.
    script: LoadedScript,
    save_path: PathBuf,
    save_as: SaveAs,
    batches: Vec<Batch>,
    redo: Vec<Undone>,
    layout: ResolvedLayout,
    composer: Composer,
    version: u64,
    /// Whether anything changed since the session opened or last saved.
    unsaved: bool,
    requests: u64,
    bev_cache: Option<(u64, bool, Vec<u8>)>,
    bev_columns: BevColumns,
    /// Category thumbnails (PNG), by category.
    thumbnails: std::collections::BTreeMap<String, Vec<u8>>,
    /// The device and the composed field's renderer as of the version it last rendered.
    gpu: Option<GpuViews>,
    /// Texels around each entry's mask that its patch covers (`None`: its source scene's).
    halo: Option<usize>,
    render_budget: std::time::Duration,
    /// Assets the session defined (recoloured categories), by name: Save writes them into
    /// the script's `assets`, with the library path relative to the saved file.
    defined: std::collections::BTreeMap<String, AssetDef>,
}

impl std::fmt::Debug for EditSession {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("EditSession")
            .field("library", &self.lib.dir)
            .field("save_path", &self.save_path)
            .field("batches", &self.batches.len())
            .field("version", &self.version)
            .finish_non_exhaustive()
    }
}

fn scene_err(
    context: impl Into<String>,
) -> impl FnOnce(assetfield_scene::SceneError) -> EditorError {
    let context = context.into();
    move |source| EditorError::Scene { context, source }
}

/// `target` written relative to the folder `from` (`..` where needed); absolute when the
/// two share no root.
fn relative_path(target: &Path, from: &Path) -> PathBuf {
    let (t, f) = (canonical(target), canonical(from));
    let tc: Vec<_> = t.components().collect();
    let fc: Vec<_> = f.components().collect();
    let common = tc.iter().zip(&fc).take_while(|(a, b)| a == b).count();
    if common == 0 {
        return t;
    }
    let mut out = PathBuf::new();
    for _ in common..fc.len() {
        out.push("..");
    }
    for c in &tc[common..] {
        out.push(c);
    }
    if out.as_os_str().is_empty() { PathBuf::from(".") } else { out }
}

/// The absolute, symlink-free form of `p` (its parent's when `p` does not exist yet).
fn canonical(p: &Path) -> PathBuf {
    if let Ok(c) = std::fs::canonicalize(p) {
        return c;
    }
    match (p.parent(), p.file_name()) {
        (Some(dir), Some(name)) => {
            let dir = if dir.as_os_str().is_empty() { Path::new(".") } else { dir };
            std::fs::canonicalize(dir).map(|d| d.join(name)).unwrap_or_else(|_| p.to_path_buf())
        }
        _ => p.to_path_buf(),
    }
}

impl EditSession {
    /// Open `library` and the layout to edit (see [`SessionOptions::layout`]); `gpu` renders
    /// when given (`fallback`: move to the CPU if the device fails).
    pub fn open(
        library: &Path,
        opts: &SessionOptions,
        gpu: Option<(GpuContext, bool)>,
    ) -> Result<Self> {
        let lib = AssetLibrary::open(library)
            .map_err(scene_err(format!("opening the asset library {}", library.display())))?;
        let save_path = opts.layout.clone().unwrap_or_else(|| library.join("edited.ron"));
        let mined = library.join("layout.ron");
        let (start_path, save_as) = if save_path.is_file() {
            let text = assetfield_layout::read_script_file(
                &save_path,
                &assetfield_layout::Limits::from_env()?,
                None,
            )?;
            let parsed = assetfield_layout::source::parse_script(&save_path, &text)?;
            let edit_only =
                parsed.layout.is_empty() && parsed.assets.is_empty() && parsed.include.is_empty();
            match (&parsed.base, edit_only) {
                (Some(base), true) => (
                    save_path.clone(),
                    SaveAs::EditScript { base: base.clone(), earlier: parsed.edits.clone() },
                ),
                _ => (save_path.clone(), SaveAs::Whole { script: Box::new(parsed) }),
            }
        } else {
            if !mined.is_file() {
                return Err(EditorError::LayoutFile {
                    path: mined,
                    reason: "the library has no layout.ron (written by `assetfield mine`); name the layout to edit with --layout".into(),
                });
            }
            let dir = save_path.parent().filter(|d| !d.as_os_str().is_empty());
            let base = relative_path(&mined, dir.unwrap_or(Path::new(".")));
            (
                mined,
                SaveAs::EditScript { base: base.to_string_lossy().into_owned(), earlier: vec![] },
            )
        };
        let mut start = assetfield_layout::load(&start_path)?;
        // the start file's own edits become the session's first batches, one per edit, so
        // a reopened session lists them and can undo them
        let own: &[Edit] = match &save_as {
            SaveAs::EditScript { earlier, .. } => earlier,
            SaveAs::Whole { script } => &script.edits,
        };
        let first = start.edits.len().checked_sub(own.len()).filter(|&f| {
            !own.is_empty() && start.edits[f..].iter().map(|n| &n.edit).eq(own.iter())
        });
        let (save_as, batches) = match first {
            None => (save_as, Vec::new()),
            Some(first) => {
                let files_at = start.files.len();
                let batches = own
                    .iter()
                    .enumerate()
                    .map(|(k, e)| Batch { edits_at: first + k, files_at, edits: vec![e.clone()] })
                    .collect();
                let save_as = match save_as {
                    SaveAs::EditScript { base, .. } => SaveAs::EditScript { base, earlier: vec![] },
                    SaveAs::Whole { mut script } => {
                        script.edits.clear();
                        SaveAs::Whole { script }
                    }
                };
                (save_as, batches)
            }
        };
        let halo = opts.halo;
        let assets = ScriptAssets::resolve(&start, &lib, halo)
            .map_err(scene_err(format!("resolving the assets of {}", start_path.display())))?;
        let layout = resolve(&start, &assets)?;
        if !assetfield_layout::Limits::explicitly_set(assetfield_layout::Limit::Instances) {
            let cap = EDITOR_MAX_INSTANCES.max(2 * layout.instances.len());
            start.limits.max_instances = start.limits.max_instances.min(cap);
        }
        let canvas = lib.canvas_for(&layout);
        let composition = lib.composition(&canvas).map_err(scene_err("building the canvas"))?;
        let mut composer = Composer::new(composition);
        assets.install(&mut composer).map_err(scene_err("installing the library's assets"))?;
        composer
            .apply_layout(&layout)
            .map_err(scene_err(format!("composing {}", start_path.display())))?;
        composer.update();
        composer.ensure_occupancy();
        let gpu = gpu.map(|(ctx, fallback)| GpuViews::new(ctx, fallback));
        Ok(EditSession {
            lib,
            assets,
            script: start,
            save_path,
            save_as,
            batches,
            redo: Vec::new(),
            layout,
            composer,
            version: 0,
            unsaved: false,
            requests: 0,
            bev_cache: None,
            bev_columns: BevColumns::default(),
            thumbnails: Default::default(),
            gpu,
            halo,
            render_budget: opts.render_budget.unwrap_or(DEFAULT_RENDER_BUDGET),
            defined: Default::default(),
        })
    }

    /// The library being edited.
    pub fn library(&self) -> &AssetLibrary {
        &self.lib
    }

    /// The resolved layout as it stands.
    pub fn layout(&self) -> &ResolvedLayout {
        &self.layout
    }

    /// The composer (its composed planes are up to date after every call).
    pub fn composer(&self) -> &Composer {
        &self.composer
    }

    /// Bumped by every change.
    pub fn version(&self) -> u64 {
        self.version
    }

    /// Where Save writes.
    pub fn save_path(&self) -> &Path {
        &self.save_path
    }

    /// Make the composer match `layout` (nothing changes when it refuses).
    fn show(&mut self, layout: ResolvedLayout) -> Result<()> {
        self.composer.apply_layout(&layout).map_err(scene_err("composing the edited layout"))?;
        self.composer.update();
        self.bev_columns.invalidate(self.composer.last_dirty());
        self.layout = layout;
        self.version += 1;
        self.unsaved = true;
        Ok(())
    }

    /// Apply a batch of edits given as RON text (`[Move(target: "obj3", by: (0.5, 0.0))]` or
    /// `Scene(edits: [...])`). Errors name the place in the text as `edit request N:line:col`
    /// and change nothing. Clears the redo stack.
    pub fn apply(&mut self, text: &str) -> Result<()> {
        self.requests += 1;
        let name = PathBuf::from(format!("edit request {}", self.requests));
        let (edits_at, files_at) = (self.script.edits.len(), self.script.files.len());
        assetfield_layout::append_edits_str(&mut self.script, &name, text)?;
        let edits: Vec<Edit> =
            self.script.edits[edits_at..].iter().map(|n| n.edit.clone()).collect();
        let shown = if edits.is_empty() {
            Err(EditorError::BadRequest(format!("{}: no edits", name.display())))
        } else {
            resolve(&self.script, &self.assets).map_err(Into::into).and_then(|l| self.show(l))
        };
        if let Err(e) = shown {
            self.script.edits.truncate(edits_at);
            self.script.files.truncate(files_at);
            return Err(e);
        }
        self.batches.push(Batch { edits_at, files_at, edits });
        self.redo.clear();
        Ok(())
    }

    /// Recolour a category (the paper's Fig. 9): every instance of `category` drawn with its
    /// template's geometry and the colour features of entry `from`, stretched onto the
    /// template's extent. Defines the asset `CATEGORY~FROM` (a library asset with
    /// `color_from`, which Save writes into the script) and applies
    /// `ReplaceAsset(category: CATEGORY, with: "CATEGORY~FROM")` as one batch.
    pub fn recolour(&mut self, category: &str, from: &str) -> Result<()> {
        let bad = |m: String| Err(EditorError::BadRequest(m));
        let Some(cat) = self.lib.index.categories.iter().find(|c| c.name == category) else {
            let names: Vec<&str> =
                self.lib.index.categories.iter().map(|c| c.name.as_str()).collect();
            return bad(format!("no category \"{category}\" (categories: {})", names.join(", ")));
        };
        if self.lib.entry(from).is_none() {
            return bad(format!("no entry \"{from}\" in the library"));
        }
        let Some(template) = self.lib.entry(&cat.template) else {
            return bad(format!("category \"{category}\" has no template entry"));
        };
        let name = format!("{category}~{from}");
        if !self.defined.contains_key(&name) {
            let (ex, ey, ez) = template.extent;
            let symmetry =
                self.assets.assets.get(category).map_or(360.0, |a| a.info.yaw_symmetry_deg);
            let def = AssetDef {
                parts: Vec::new(),
                obj: None,
                yaw_symmetry_deg: symmetry,
                container: false,
                category: Some(category.to_string()),
                library: Some(LibraryRef {
                    path: canonical(&self.lib.dir).to_string_lossy().into_owned(),
                    entry: template.name.clone(),
                    size: (ex, ey, ez),
                    pivot: None,
                    density_from: None,
                    color_from: Some(from.to_string()),
                }),
            };
            let script = Script {
                assets: [(name.clone(), def.clone())].into_iter().collect(),
                ..Default::default()
            };
            let text = assetfield_layout::source::write_script(&script)?;
            let probe = assetfield_layout::load_str(&self.lib.dir.join("(recolour)"), &text)?;
            let mut resolved = ScriptAssets::resolve(&probe, &self.lib, self.halo)
                .map_err(scene_err(format!("recolouring {category} from {from}")))?;
            let asset = resolved.assets.remove(&name).ok_or_else(|| {
                EditorError::BadRequest(format!("the asset {name} did not resolve"))
            })?;
            self.composer
                .set_template(&name, &asset.category, asset.patch.clone())
                .map_err(scene_err(format!("installing {name}")))?;
            self.assets.assets.insert(name.clone(), asset);
            self.defined.insert(name.clone(), def);
            let applied =
                self.apply(&format!("[ReplaceAsset(category: {category:?}, with: {name:?})]"));
            if applied.is_err() {
                // nothing refers to the new asset: forget it (its template entity stays
                // unused in the composer)
                self.assets.assets.remove(&name);
                self.defined.remove(&name);
            }
            return applied;
        }
        self.apply(&format!("[ReplaceAsset(category: {category:?}, with: {name:?})]"))
    }

    /// Take back the last batch; `false` when there is none.
    pub fn undo(&mut self) -> Result<bool> {
        let Some(batch) = self.batches.last() else { return Ok(false) };
        let nodes = self.script.edits.split_off(batch.edits_at);
        let files = self.script.files.split_off(batch.files_at);
        let shown =
            resolve(&self.script, &self.assets).map_err(Into::into).and_then(|l| self.show(l));
        if let Err(e) = shown {
            self.script.edits.extend(nodes);
            self.script.files.extend(files);
            return Err(e);
        }
        let batch = self.batches.pop().expect("checked above");
        self.redo.push(Undone { batch, nodes, files });
        Ok(true)
    }

    /// Apply the last batch taken back again; `false` when there is none.
    pub fn redo(&mut self) -> Result<bool> {
        let Some(undone) = self.redo.pop() else { return Ok(false) };
        let (edits_at, files_at) = (self.script.edits.len(), self.script.files.len());
        debug_assert_eq!((edits_at, files_at), (undone.batch.edits_at, undone.batch.files_at));
        self.script.edits.extend(undone.nodes.iter().cloned());
        self.script.files.extend(undone.files.iter().cloned());
        let shown =
            resolve(&self.script, &self.assets).map_err(Into::into).and_then(|l| self.show(l));
        if let Err(e) = shown {
            self.script.edits.truncate(edits_at);
            self.script.files.truncate(files_at);
            self.redo.push(undone);
            return Err(e);
        }
        self.batches.push(undone.batch);
        Ok(true)
    }

    /// Every edit of the session, in order.
    pub fn edits(&self) -> Vec<Edit> {
        self.batches.iter().flat_map(|b| b.edits.iter().cloned()).collect()
    }

    /// The session's edits as a RON list (what `POST /api/edits` takes, and `compose --edits`
    /// reads inside `Scene(edits: ...)`); empty without edits.
    pub fn edits_ron(&self) -> String {
        let edits = self.edits();
        if edits.is_empty() {
            return String::new();
        }
        let cfg = ron::ser::PrettyConfig::new().struct_names(true).depth_limit(2).indentor("    ");
        // optional values as a script writes them (`to: (1.0, 2.0)`, not `Some((1.0, 2.0))`):
        // every reader of edits parses with implicit `Some`
        ron::Options::default()
            .with_default_extension(ron::extensions::Extensions::IMPLICIT_SOME)
            .to_string_pretty(&edits, cfg)
            .unwrap_or_default()
    }

    /// The text Save writes.
    pub fn saved_text(&self) -> Result<String> {
        let mut script = match &self.save_as {
            SaveAs::EditScript { base, earlier } => {
                let mut edits = earlier.clone();
                edits.extend(self.edits());
                Script { base: Some(base.clone()), edits, ..Default::default() }
            }
            SaveAs::Whole { script } => {
                let mut s = Script::clone(script);
                s.edits.extend(self.edits());
                s
            }
        };
        let dir = self.save_path.parent().filter(|d| !d.as_os_str().is_empty());
        let lib_path = relative_path(&self.lib.dir, dir.unwrap_or(Path::new(".")));
        for (name, def) in &self.defined {
            let mut def = def.clone();
            if let Some(l) = &mut def.library {
                l.path = lib_path.to_string_lossy().into_owned();
            }
            script.assets.insert(name.clone(), def);
        }
        Ok(assetfield_layout::source::write_script(&script)?)
    }

    /// Write the layout (start file plus edits) to [`Self::save_path`], atomically and
    /// durably (synced before it returns; see [`assetfield_core::fsx::write_durable`]).
    pub fn save(&mut self) -> Result<PathBuf> {
        let text = self.saved_text()?;
        assetfield_core::fsx::write_durable(&self.save_path, text.as_bytes()).map_err(
            |source| EditorError::Io {
                context: format!("saving {}", self.save_path.display()),
                source,
            },
        )?;
        self.unsaved = false;
        Ok(self.save_path.clone())
    }

    /// The box cameras look at: the composed planes' ground rectangle and the field's height.
    pub fn scene_box(&self) -> Aabb3 {
        let r = self.composer.composition().grid.world_rect();
        let z = self.lib.config.aabb();
        Aabb3::new(r.min.extend(z.min.z.max(0.0)), r.max.extend(z.max.z.max(0.5)))
    }

    /// The camera of a view request (checked).
    pub fn camera(&self, v: &ViewRequest) -> Result<Camera> {
        let bad = |m: String| Err(EditorError::BadRequest(m));
        if !(1..=MAX_RENDER_SIDE).contains(&v.width) || !(1..=MAX_RENDER_SIDE).contains(&v.height) {
            return bad(format!(
                "width and height must be 1..{MAX_RENDER_SIDE} pixels, got {} x {}",
                v.width, v.height
            ));
        }
        if !v.azimuth_deg.is_finite() || !(-89.0..=89.0).contains(&v.elevation_deg) {
            return bad(format!(
                "azimuth must be finite and elevation within -89..89 degrees, got {} and {}",
                v.azimuth_deg, v.elevation_deg
            ));
        }
        let aabb = self.scene_box();
        let fit = fitting_radius(&aabb, VIEW_FOV_DEG);
        let radius = match v.radius {
            None => fit,
            Some(r) if r.is_finite() && r > 0.0 && r <= 100.0 * fit => r,
            Some(r) => return bad(format!("radius must be in (0, {}], got {r}", 100.0 * fit)),
        };
        let mut orbit = Orbit::around(&aabb, 1, v.width);
        orbit.height = v.height;
        orbit.radius = radius;
        orbit.elevation_deg = v.elevation_deg;
        orbit.start_deg = v.azimuth_deg;
        orbit.fov_deg = VIEW_FOV_DEG;
        orbit
            .cameras()
            .into_iter()
            .next()
            .ok_or_else(|| EditorError::BadRequest("no camera".into()))
    }

    /// Render a view of the composed scene: linear RGB in `[0, 1]`, row-major.
    pub fn render(&mut self, v: &ViewRequest) -> Result<Vec<f32>> {
        let cam = self.camera(v)?;
        let bg = self.lib.background;
        if let Some(gpu) = &mut self.gpu {
            let comp = self.composer.composition();
            match gpu.render(&comp.field, comp.occupancy.as_ref(), self.version, &cam, bg) {
                Ok(GpuView::Done(rgb)) => return Ok(rgb),
                Ok(GpuView::FellBack { note }) => {
                    tracing::warn!("{note}");
                    self.gpu = None;
                }
                Err(source) => return Err(EditorError::Gpu { source }),
            }
        }
        let started = std::time::Instant::now();
        let budget = self.render_budget;
        self.composer.render_unless(&cam, bg, &|| started.elapsed() > budget).ok_or_else(|| {
            EditorError::BadRequest(format!(
                "the {} x {} render was cancelled after {:.0} s (the session's render budget on the CPU); ask for a smaller view",
                v.width,
                v.height,
                budget.as_secs_f64()
            ))
        })
    }

    /// Which backend renders: `"gpu"` or `"cpu"`.
    pub fn backend(&self) -> &'static str {
        if self.gpu.is_some() { "gpu" } else { "cpu" }
    }

    /// The bird's-eye view as PNG bytes: the composed scene's column opacity, with every
    /// instance's footprint outlined in its category's colour when `footprints`.
    pub fn bev_png(&mut self, footprints: bool) -> Result<Vec<u8>> {
        if let Some((v, f, png)) = &self.bev_cache
            && *v == self.version
            && *f == footprints
        {
            return Ok(png.clone());
        }
        let mut columns = std::mem::take(&mut self.bev_columns);
        let (pic, _) =
            bev_picture(self, columns.update(&self.composer.composition().field), footprints);
        self.bev_columns = columns;
        let png = crate::png::encode_rgb8(pic.width, pic.height, &pic.pixels)?;
        self.bev_cache = Some((self.version, footprints, png.clone()));
        Ok(png)
    }

    /// Each category's index into [`assetfield_core::canvas::palette`] (see
    /// [`LayoutView::category_colours`]).
    pub fn category_colour_indices(&self) -> std::collections::BTreeMap<String, usize> {
        let mut order = self.layout.categories();
        for c in &self.lib.index.categories {
            if !order.contains(&c.name) {
                order.push(c.name.clone());
            }
        }
        order.into_iter().enumerate().map(|(k, name)| (name, k)).collect()
    }

    /// A category's thumbnail as PNG bytes (see [`crate::bev::thumbnail`]), made once.
    pub fn thumbnail_png(&mut self, category: &str) -> Result<Vec<u8>> {
        if let Some(png) = self.thumbnails.get(category) {
            return Ok(png.clone());
        }
        let Some(asset) = self
            .assets
            .assets
            .get(category)
            .filter(|_| self.lib.index.categories.iter().any(|c| c.name == category))
        else {
            let names: Vec<&str> =
                self.lib.index.categories.iter().map(|c| c.name.as_str()).collect();
            return Err(EditorError::BadRequest(format!(
                "no category \"{category}\" (categories: {})",
                names.join(", ")
            )));
        };
        let pic = crate::bev::thumbnail(&self.lib, &asset.patch)
            .map_err(scene_err(format!("drawing the thumbnail of {category}")))?;
        let png = crate::png::encode_rgb8(pic.width, pic.height, &pic.pixels)?;
        self.thumbnails.insert(category.to_string(), png.clone());
        Ok(png)
    }

    /// The layout as the API describes it.
    pub fn view(&self) -> LayoutView {
        let keys: std::collections::HashMap<u32, &str> =
            self.layout.instances.iter().map(|i| (i.id, i.key.as_str())).collect();
        let instances = self
            .layout
            .objects()
            .map(|i| InstanceView {
                key: i.key.clone(),
                category: i.category.clone(),
                asset: i.asset.clone(),
                x: i.transform.position.x,
                y: i.transform.position.y,
                yaw_deg: i.transform.yaw_deg,
                scale: i.transform.scale,
                footprint: footprint_corners(i).iter().map(|p| p.to_array()).collect(),
                on: i.supported_by.and_then(|id| keys.get(&id)).map(|k| k.to_string()),
            })
            .collect();
        let categories = self
            .lib
            .index
            .categories
            .iter()
            .map(|c| CategoryView {
                name: c.name.clone(),
                label: self.layout.category_names.get(&c.name).unwrap_or(&c.name).clone(),
                template: c.template.clone(),
                members: c.members.clone(),
            })
            .collect();
        let assets = self
            .assets
            .assets
            .iter()
            .map(|(name, a)| AssetView {
                name: name.clone(),
                category: a.category.clone(),
                kind: if self.lib.index.categories.iter().any(|c| &c.name == name) {
                    "category"
                } else {
                    "entry"
                },
                size: {
                    let e = a.info.footprint.max - a.info.footprint.min;
                    [e.x, e.y, a.info.height]
                },
            })
            .collect();
        let r = self.composer.composition().grid.world_rect();
        LayoutView {
            version: self.version,
            instances,
            categories,
            assets,
            extent: [r.min.x, r.min.y, r.max.x, r.max.y],
            bev: BevMapping::of(self),
            can_undo: !self.batches.is_empty(),
            can_redo: !self.redo.is_empty(),
            edits: self.edits_ron(),
            save_path: self.save_path.display().to_string(),
            unsaved: self.unsaved,
            category_colours: self
                .category_colour_indices()
                .into_iter()
                .map(|(name, k)| {
                    let [r, g, b, _] = assetfield_core::canvas::palette(k);
                    (name, format!("#{r:02x}{g:02x}{b:02x}"))
                })
                .collect(),
        }
    }

    /// The background colour renders are composited on.
    pub fn background(&self) -> Vec3 {
        self.lib.background
    }
}

/// An instance's footprint corners in world (x, y), counter-clockwise.
pub fn footprint_corners(i: &assetfield_layout::ResolvedInstance) -> [Vec2; 4] {
    let (a, b) = (i.footprint.min, i.footprint.max);
    [a, Vec2::new(b.x, a.y), b, Vec2::new(a.x, b.y)].map(|p| i.transform.transform_point2(p))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn relative_paths_climb_out_of_the_save_folder() {
        let root = std::env::temp_dir().join(format!("af-editor-rel-{}", std::process::id()));
        std::fs::create_dir_all(root.join("lib")).unwrap();
        std::fs::create_dir_all(root.join("work/rooms")).unwrap();
        std::fs::write(root.join("lib/layout.ron"), "Scene()").unwrap();
        let lib = root.join("lib/layout.ron");
        assert_eq!(relative_path(&lib, &root.join("lib")), PathBuf::from("layout.ron"));
        assert_eq!(relative_path(&root.join("lib"), &root.join("lib")), PathBuf::from("."));
        assert_eq!(
            relative_path(&lib, &root.join("work/rooms")),
            PathBuf::from("../../lib/layout.ron")
        );
        let _ = std::fs::remove_dir_all(&root);
    }
}
