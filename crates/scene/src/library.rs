//! From an asset library on disk (written by `assetfield mine`, see
//! [`assetfield_library`]) to a composed scene: the shared axes and decoders become the
//! composition's field, a container (or an empty canvas) its canvas, and entries become
//! feature patches that the [`Composer`] places.
//!
//! - [`AssetLibrary::open`] reads and checks a library.
//! - [`AssetLibrary::composition`] builds a [`Composition`] on a [`Canvas`].
//! - [`AssetLibrary::patch`] turns an entry into a [`FeaturePatch`]; its weight is the
//!   entry's mask grown by `halo` texels, the same ring the container filled with background
//!   when the objects were removed, so an object placed back where it was mined restores
//!   exactly the texels that were taken out.
//! - [`ScriptAssets`] resolves the assets of a layout script against libraries: names the
//!   script defines with `library: Library(path, entry, size)` (the path relative to the
//!   defining file) and, for names the script does not define, the main library's categories
//!   (their templates) and entries. It is the [`AssetCatalog`] the script is resolved with.

use crate::error::SceneError;
use crate::patch::FeaturePatch;
use crate::raster::{Composition, DensityRule};
use crate::world::Composer;
use assetfield_core::{Rect2, TensorFile};
use assetfield_field::{Field, FieldConfig};
use assetfield_layout::script::LibraryRef;
use assetfield_layout::{AssetCatalog, AssetInfo, LoadedScript, PartsCatalog};
use assetfield_library::{Entry, LibraryIndex, field_with_shared, open_library};
use glam::{Vec2, Vec3};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

pub use assetfield_library::DEFAULT_HALO;

/// Most texels of an empty canvas (rows x cols): 64 million, 16 GiB of the default 16 + 48
/// feature channels.
pub const MAX_CANVAS_TEXELS: usize = 64_000_000;

/// Which entry owns each texel of a container (`u32::MAX`: none).
#[derive(Debug, Clone)]
struct Ownership {
    owner: Vec<u32>,
}

/// What the composed scene is drawn onto.
#[derive(Debug, Clone, PartialEq)]
pub enum Canvas {
    /// A container of the library (a trained scene with its objects removed), by name.
    Container(String),
    /// Nothing: empty space over `extent` (world XY), at the library's texel size.
    Empty { extent: Rect2 },
}

/// A library opened for composing.
#[derive(Debug, Clone)]
pub struct AssetLibrary {
    pub dir: PathBuf,
    pub index: LibraryIndex,
    /// The field configuration the shared tensors belong to.
    pub config: FieldConfig,
    /// The background the source field was trained on (white when not recorded).
    pub background: Vec3,
    /// Metadata of the shared file (ground alignment, dataset), as the field info reads it.
    pub info: assetfield_field::eval::FieldInfo,
    patches: TensorFile,
    shared: TensorFile,
}

fn lib_err(path: &Path, reason: impl Into<String>) -> SceneError {
    SceneError::Library { path: path.to_path_buf(), reason: reason.into() }
}

impl AssetLibrary {
    /// Read and check a library folder, with the one library check there is
    /// ([`assetfield_library::open_library`], which `assetfield library check` runs
    /// too): a library that opens here composes.
    pub fn open(dir: &Path) -> Result<Self, SceneError> {
        let lib = open_library(dir).map_err(|e| SceneError::LibraryCheck {
            dir: dir.to_path_buf(),
            source: Box::new(e),
        })?;
        Ok(AssetLibrary {
            dir: dir.to_path_buf(),
            background: lib.info.background_or_white(),
            config: lib.config,
            info: lib.info,
            index: lib.index,
            patches: lib.patches,
            shared: lib.shared,
        })
    }

    /// Content hash of the shared axes and decoders: libraries with equal hashes can be
    /// composed together.
    pub fn shared_hash(&self) -> &str {
        &self.index.shared.hash
    }

    /// The first container, else an empty canvas over the source field's ground box.
    pub fn default_canvas(&self) -> Canvas {
        match self.index.containers.first() {
            Some(c) => Canvas::Container(c.name.clone()),
            None => {
                let a = self.config.aabb();
                Canvas::Empty { extent: Rect2::new(a.min.truncate(), a.max.truncate()) }
            }
        }
    }

    /// The layout's extent and every instance's box, with a margin of a few texels: what an
    /// empty canvas for `layout` covers.
    pub fn empty_extent(&self, layout: &assetfield_layout::ResolvedLayout) -> Rect2 {
        let mut r = layout.extent;
        for i in layout.objects() {
            r = r.union(&i.bev_aabb);
        }
        let m = self.texel() * 4.0 + Vec2::splat(0.25);
        Rect2::new(r.min - m, r.max + m)
    }

    /// [`Self::default_canvas`], an empty one sized for `layout` ([`Self::empty_extent`])
    /// when the library has no container.
    pub fn canvas_for(&self, layout: &assetfield_layout::ResolvedLayout) -> Canvas {
        match self.default_canvas() {
            Canvas::Empty { .. } => Canvas::Empty { extent: self.empty_extent(layout) },
            c => c,
        }
    }

    /// The world size of one texel.
    pub fn texel(&self) -> Vec2 {
        Vec2::new(self.index.texel_size.0, self.index.texel_size.1)
    }

    /// A field with the library's shared tensors on a plane grid of `cols x rows` texel
    /// nodes starting at `min` (its planes zero).
    fn field_on(&self, min: Vec2, rows: usize, cols: usize) -> Result<Field, SceneError> {
        let config = self.config.on_ground_window(min, cols, rows, self.texel());
        field_with_shared(config, &self.shared).map_err(|e| {
            lib_err(
                &self.dir.join(&self.index.shared.file),
                format!("{e} (the shared tensors do not fit their config)"),
            )
        })
    }

    /// Build the composition for `canvas`.
    pub fn composition(&self, canvas: &Canvas) -> Result<Composition, SceneError> {
        let (nd, nc) = self.index.channels;
        match canvas {
            Canvas::Container(name) => {
                let c =
                    self.index.containers.iter().find(|c| &c.name == name).ok_or_else(|| {
                        let known: Vec<&str> =
                            self.index.containers.iter().map(|c| c.name.as_str()).collect();
                        lib_err(
                            &self.dir,
                            format!(
                                "no container {name:?} (the library has: {})",
                                if known.is_empty() { "none".into() } else { known.join(", ") }
                            ),
                        )
                    })?;
                let (rows, cols) = c.size;
                let texel = self.texel();
                // the container's world box covers whole cells: nodes sit half a texel in
                let min = Vec2::new(c.world[0], c.world[1]) + texel * 0.5;
                let mut field = self.field_on(min, rows, cols)?;
                let ppath = self.dir.join(&self.index.patches);
                let d = self
                    .patches
                    .get_f32(&c.density, &[rows, cols, nd])
                    .map_err(|e| lib_err(&ppath, e.to_string()))?;
                let col = self
                    .patches
                    .get_f32(&c.color, &[rows, cols, nc])
                    .map_err(|e| lib_err(&ppath, e.to_string()))?;
                set_plane(&mut field, "density.plane", d)?;
                set_plane(&mut field, "color.plane", col)?;
                let mut comp = Composition::new(field)?;
                comp.density_rule = DensityRule::Add;
                Ok(comp)
            }
            Canvas::Empty { extent } => {
                if extent.is_empty() || !extent.min.is_finite() || !extent.max.is_finite() {
                    return Err(lib_err(&self.dir, "the empty canvas needs a non-empty extent"));
                }
                let texel = self.texel();
                let n = ((extent.size() / texel).ceil()).max(Vec2::ONE);
                // counted in f64 so that a tiny texel cannot overflow the product
                let texels = (f64::from(n.x) + 1.0) * (f64::from(n.y) + 1.0);
                let (cols, rows) = (n.x as usize + 1, n.y as usize + 1);
                if texels > MAX_CANVAS_TEXELS as f64 {
                    return Err(lib_err(
                        &self.dir,
                        format!(
                            "an empty canvas of {:.1} x {:.1} at {:.3} per texel needs {rows} x {cols} texels: too large",
                            extent.size().x,
                            extent.size().y,
                            texel.x
                        ),
                    ));
                }
                let field = self.field_on(extent.min, rows, cols)?;
                let mut comp = Composition::new(field)?;
                comp.density_rule = DensityRule::Add;
                Ok(comp)
            }
        }
    }

    /// The entry named `name`.
    pub fn entry(&self, name: &str) -> Option<&Entry> {
        self.index.entry(name)
    }

    /// The template entry of category `category`.
    pub fn template_of(&self, category: &str) -> Option<&Entry> {
        let c = self.index.categories.iter().find(|c| c.name == category)?;
        self.index.entry(&c.template)
    }

    /// The halo (texels) the patches of source scene `source` cover when composed: the ring
    /// mining filled in that scene's container ([`assetfield_library::Container::halo`]),
    /// [`DEFAULT_HALO`] for a source without a container.
    pub fn source_halo(&self, source: usize) -> usize {
        self.index.containers.iter().find(|c| c.source == source).map_or(DEFAULT_HALO, |c| c.halo)
    }

    /// An entry as a feature patch: on its mask (its core) its whole density column, on the
    /// rest its density features minus the background (see [`DensityRule::Add`]), its colour
    /// features, its centre at the entry's pivot offset (see
    /// [`FeaturePatch::origin`]), and weight 1 on the texels it owns: its
    /// mask, plus the texels within the halo of it that are nearer to it than to any other
    /// object of its source scene (so that neighbours' patches never cover the same texel,
    /// and every object placed back where it was mined restores its source planes exactly).
    /// The halo is `halo` when given, else its source scene's ([`AssetLibrary::source_halo`]).
    pub fn patch(&self, entry: &str, halo: Option<usize>) -> Result<FeaturePatch, SceneError> {
        let Some(e) = self.entry(entry) else {
            return self.patch_with(entry, halo.unwrap_or(DEFAULT_HALO), None);
        };
        let halo = halo.unwrap_or_else(|| self.source_halo(e.source));
        let owner = self.ownership(e.source, halo)?;
        self.patch_with(entry, halo, owner.as_ref())
    }

    /// Every entry's patch (see [`AssetLibrary::patch`]), by entry name.
    pub fn patches(
        &self,
        halo: Option<usize>,
    ) -> Result<BTreeMap<String, FeaturePatch>, SceneError> {
        let mut owners = BTreeMap::new();
        let mut out = BTreeMap::new();
        for e in &self.index.entries {
            let halo = halo.unwrap_or_else(|| self.source_halo(e.source));
            let owner = match owners.entry(e.source) {
                std::collections::btree_map::Entry::Occupied(o) => o.into_mut(),
                std::collections::btree_map::Entry::Vacant(v) => {
                    v.insert(self.ownership(e.source, halo)?)
                }
            };
            out.insert(e.name.clone(), self.patch_with(&e.name, halo, owner.as_ref())?);
        }
        Ok(out)
    }

    fn patch_with(
        &self,
        entry: &str,
        halo: usize,
        owner: Option<&Ownership>,
    ) -> Result<FeaturePatch, SceneError> {
        let e = self.entry(entry).ok_or_else(|| {
            lib_err(&self.dir, format!("no entry {entry:?} in the library index"))
        })?;
        let (nd, nc) = self.index.channels;
        let (h, w) = e.patch_size;
        let ppath = self.dir.join(&self.index.patches);
        let err = |e: assetfield_core::CoreError| lib_err(&ppath, e.to_string());
        let mut d = self.patches.get_f32(&e.density, &[h, w, nd]).map_err(err)?.to_vec();
        let c = self.patches.get_f32(&e.color, &[h, w, nc]).map_err(err)?.to_vec();
        let m = self.patches.get_u8(&e.mask, &[h, w]).map_err(err)?;
        let mask: Vec<bool> = m.iter().map(|&b| b != 0).collect();
        let grown = grow_mask(m, h, w, halo);
        let mut weight: Vec<f32> = grown.iter().map(|&b| if b { 1.0 } else { 0.0 }).collect();
        if let Some((c, r0, c0)) = self.source_frame(e) {
            let (rows, cols) = c.size;
            let fill = self
                .patches
                .get_f32(&c.density, &[rows, cols, nd])
                .map_err(|err| lib_err(&ppath, err.to_string()))?;
            let me = self.index.entries.iter().position(|x| x.name == e.name).unwrap_or(0) as u32;
            for r in 0..h {
                for col in 0..w {
                    let k = r * w + col;
                    let (rr, cc) = (r0 + r as i64, c0 + col as i64);
                    if rr < 0 || cc < 0 || rr >= rows as i64 || cc >= cols as i64 {
                        continue;
                    }
                    let t = rr as usize * cols + cc as usize;
                    // the ring holds the object minus its background; the core keeps the
                    // whole column
                    if !mask[k] {
                        for (v, f) in d[k * nd..][..nd].iter_mut().zip(&fill[t * nd..][..nd]) {
                            *v -= f;
                        }
                    }
                    if let Some(o) = owner
                        && !mask[k]
                        && o.owner[t] != me
                    {
                        weight[k] = 0.0;
                    }
                }
            }
        }
        let core = mask.iter().map(|&b| if b { 1.0 } else { 0.0 }).collect();
        Ok(FeaturePatch::new(e.name.clone(), h, w, self.texel(), d, c, weight)?
            .with_core(core)?
            .with_origin(-e.pivot_offset()))
    }

    /// The container of an entry's source scene and the texel of it where the entry's patch
    /// starts (row, column; may be negative for patches padded at the plane's border).
    fn source_frame(&self, e: &Entry) -> Option<(&assetfield_library::Container, i64, i64)> {
        let c = self.index.containers.iter().find(|c| c.source == e.source)?;
        let texel = self.texel();
        let min = Vec2::new(c.world[0], c.world[1]) + texel * 0.5;
        let b = e.source_box;
        let centre = Vec2::new(b[0] + b[2], b[1] + b[3]) * 0.5;
        let (h, w) = e.patch_size;
        let corner = centre - Vec2::new((w - 1) as f32, (h - 1) as f32) * texel * 0.5;
        let off = ((corner - min) / texel).round();
        Some((c, off.y as i64, off.x as i64))
    }

    /// Which entry owns each texel of a source scene's container: every entry its own mask
    /// texels, then the texels within `halo` (8-connected steps) go to the nearest mask
    /// (breadth-first, ties to the earlier entry).
    fn ownership(&self, source: usize, halo: usize) -> Result<Option<Ownership>, SceneError> {
        let Some(c) = self.index.containers.iter().find(|c| c.source == source) else {
            return Ok(None);
        };
        let (rows, cols) = c.size;
        let mut owner = vec![u32::MAX; rows * cols];
        let mut frontier = Vec::new();
        let ppath = self.dir.join(&self.index.patches);
        for (i, e) in self.index.entries.iter().enumerate() {
            if e.source != source {
                continue;
            }
            let Some((_, r0, c0)) = self.source_frame(e) else { continue };
            let (h, w) = e.patch_size;
            let m = self
                .patches
                .get_u8(&e.mask, &[h, w])
                .map_err(|err| lib_err(&ppath, err.to_string()))?;
            for r in 0..h {
                for col in 0..w {
                    let (rr, cc) = (r0 + r as i64, c0 + col as i64);
                    if m[r * w + col] == 0
                        || rr < 0
                        || cc < 0
                        || rr >= rows as i64
                        || cc >= cols as i64
                    {
                        continue;
                    }
                    let t = rr as usize * cols + cc as usize;
                    if owner[t] == u32::MAX {
                        owner[t] = i as u32;
                        frontier.push(t);
                    }
                }
            }
        }
        for _ in 0..halo {
            let mut next = Vec::new();
            for &t in &frontier {
                let (r, col) = ((t / cols) as i64, (t % cols) as i64);
                for dr in -1..=1i64 {
                    for dc in -1..=1i64 {
                        let (rr, cc) = (r + dr, col + dc);
                        if rr < 0 || cc < 0 || rr >= rows as i64 || cc >= cols as i64 {
                            continue;
                        }
                        let u = rr as usize * cols + cc as usize;
                        if owner[u] == u32::MAX {
                            owner[u] = owner[t];
                            next.push(u);
                        }
                    }
                }
            }
            frontier = next;
        }
        Ok(Some(Ownership { owner }))
    }

    /// What layout resolution needs to know about an entry: a footprint of the entry's
    /// extent around its patch centre, in the frame of its pivot.
    pub fn entry_info(&self, e: &Entry) -> AssetInfo {
        let half = Vec2::new(e.extent.0, e.extent.1) * 0.5;
        let centre = -e.pivot_offset();
        AssetInfo {
            category: e.category.clone(),
            footprint: Rect2::new(centre - half, centre + half),
            outline: Vec::new(),
            height: e.extent.2,
            yaw_symmetry_deg: 360.0,
            container: false,
            frame_yaw_deg: e.yaw_deg,
        }
    }
}

fn set_plane(field: &mut Field, name: &str, values: &[f32]) -> Result<(), SceneError> {
    let spec = field
        .params
        .spec(name)
        .ok_or_else(|| SceneError::NoGroundPlanes { kind: field.config.kind.name().to_string() })?
        .clone();
    if spec.len != values.len() {
        return Err(SceneError::PatchShape {
            name: name.into(),
            what: "plane",
            expected: spec.len,
            actual: values.len(),
            shape: format!("{:?}", spec.shape),
        });
    }
    field.params.data[spec.offset..spec.offset + spec.len].copy_from_slice(values);
    Ok(())
}

/// One asset of a script, resolved to a patch.
#[derive(Debug, Clone)]
pub struct ResolvedAsset {
    pub category: String,
    pub patch: Arc<FeaturePatch>,
    pub info: AssetInfo,
    /// Where the patch came from (library folder and entry).
    pub source: String,
}

/// The assets a script can use, with their patches: the [`AssetCatalog`] to resolve the
/// script with, and what to install in the [`Composer`].
#[derive(Debug, Clone, Default)]
pub struct ScriptAssets {
    pub assets: BTreeMap<String, ResolvedAsset>,
    /// Container assets of the script (the canvas stands for them; they are not drawn).
    pub containers: BTreeMap<String, AssetInfo>,
}

impl ScriptAssets {
    /// Resolve the assets of `script` against `main` (and the libraries its assets name,
    /// which must share `main`'s axes and decoders). Assets made only of primitives or meshes
    /// cannot be composed and are an error naming their place in the script, as is a library
    /// asset whose entry does not exist. Each patch covers its source scene's halo unless
    /// `halo` overrides it.
    pub fn resolve(
        script: &LoadedScript,
        main: &AssetLibrary,
        halo: Option<usize>,
    ) -> Result<Self, SceneError> {
        let mut out = Self::library_names(main, halo)?;
        // the script's own definitions win over the library's names
        let parts = PartsCatalog::from_script(script);
        let mut opened: BTreeMap<PathBuf, AssetLibrary> = BTreeMap::new();
        let main_dir = canonical(&main.dir);
        for (name, entry) in &script.assets {
            let f = &script.files[entry.file].path;
            let here = format!("{}:{}:{}", f.display(), entry.location.line, entry.location.col);
            let Some(lref) = &entry.def.library else {
                if entry.def.container {
                    // containers are the canvas; they are not drawn
                    let b = entry.def.parts_bounds();
                    let b = if b.is_empty() {
                        assetfield_core::Aabb3::new(Vec3::ZERO, Vec3::ZERO)
                    } else {
                        b
                    };
                    out.containers.insert(
                        name.clone(),
                        assetfield_layout::resolve::asset_info_from_bounds(name, &entry.def, b),
                    );
                    continue;
                }
                return Err(SceneError::Script {
                    location: here,
                    message: format!(
                        "asset \"{name}\" is made of primitives or a mesh; composing needs library assets (`library: Library(path, entry, size)`, or a category or entry name of the library)"
                    ),
                });
            };
            let dir = entry.base_dir(script).join(&lref.path);
            let key = canonical(&dir);
            let lib: &AssetLibrary = if key == main_dir {
                main
            } else {
                if !opened.contains_key(&key) {
                    let lib = AssetLibrary::open(&dir).map_err(|e| SceneError::Script {
                        location: here.clone(),
                        message: format!("asset \"{name}\": {e}"),
                    })?;
                    opened.insert(key.clone(), lib);
                }
                &opened[&key]
            };
            let asset = LibraryAsset { name, lref, dir: &dir, here: &here };
            out.assets.insert(name.clone(), asset.resolve(lib, main, &parts, halo)?);
        }
        Ok(out)
    }

    /// The names `main` offers: its categories (drawn with their templates), then its
    /// entries (each with its own patch).
    fn library_names(main: &AssetLibrary, halo: Option<usize>) -> Result<Self, SceneError> {
        let mut out = ScriptAssets::default();
        let main_patches = main.patches(halo)?;
        let take = |name: &str| -> Result<Arc<FeaturePatch>, SceneError> {
            main_patches.get(name).cloned().map(Arc::new).ok_or_else(|| {
                lib_err(&main.dir, format!("no entry {name:?} in the library index"))
            })
        };
        for c in &main.index.categories {
            if let Some(t) = main.entry(&c.template) {
                let patch = take(&t.name)?;
                let mut info = main.entry_info(t);
                info.category = c.name.clone();
                out.assets.insert(
                    c.name.clone(),
                    ResolvedAsset {
                        category: c.name.clone(),
                        patch,
                        info,
                        source: format!("{} template {}", main.dir.display(), t.name),
                    },
                );
            }
        }
        for e in &main.index.entries {
            if out.assets.contains_key(&e.name) {
                continue;
            }
            out.assets.insert(
                e.name.clone(),
                ResolvedAsset {
                    category: e.category.clone(),
                    patch: take(&e.name)?,
                    info: main.entry_info(e),
                    source: format!("{} entry {}", main.dir.display(), e.name),
                },
            );
        }
        Ok(out)
    }
}

/// A script's asset defined as `library: Library(...)`: its name, the reference, the
/// library's folder and the definition's place in the script (`file:line:col`).
struct LibraryAsset<'a> {
    name: &'a str,
    lref: &'a LibraryRef,
    dir: &'a Path,
    here: &'a str,
}

impl LibraryAsset<'_> {
    fn error(&self, message: String) -> SceneError {
        SceneError::Script { location: self.here.to_string(), message }
    }

    /// The asset drawn from `lib` (which must share `main`'s axes and decoders): the entry's
    /// patch with the script's pivot and `density_from` / `color_from`, and its footprint
    /// from the script's `size` (`parts`) or the entry's.
    fn resolve(
        &self,
        lib: &AssetLibrary,
        main: &AssetLibrary,
        parts: &PartsCatalog,
        halo: Option<usize>,
    ) -> Result<ResolvedAsset, SceneError> {
        let (name, lref, dir) = (self.name, self.lref, self.dir);
        if lib.shared_hash() != main.shared_hash() {
            return Err(self.error(format!(
                "asset \"{name}\" comes from {}, whose axes and decoders ({}) are not those of {} ({}): merge libraries that were trained together (`assetfield library merge`)",
                dir.display(),
                lib.shared_hash(),
                main.dir.display(),
                main.shared_hash()
            )));
        }
        let e = lib.entry(&lref.entry).ok_or_else(|| {
            self.error(format!(
                "asset \"{name}\": the library {} has no entry \"{}\"",
                dir.display(),
                lref.entry
            ))
        })?;
        // the footprint from the script's `size` (around the script's pivot, or around
        // the patch centre without one), else the entry's (around its own pivot)
        let from_parts = parts.asset_info(name);
        let shift_footprint = from_parts.is_some();
        let mut info = from_parts.unwrap_or_else(|| lib.entry_info(e));
        // the patch is the entry's, cut as its object stood, whatever the script's size
        info.frame_yaw_deg = e.yaw_deg;
        let mut patch = lib.patch(&e.name, halo)?;
        // the pivot: the script's, else the entry's
        match lref.pivot {
            Some((x, y)) if !(x.is_finite() && y.is_finite()) => {
                return Err(self.error(format!(
                    "asset \"{name}\": pivot ({x}, {y}) must be finite (metres from the patch centre)"
                )));
            }
            Some((x, y)) => patch = patch.with_origin(-Vec2::new(x, y)),
            None if shift_footprint => {
                let shift = -e.pivot_offset();
                info.footprint = Rect2::new(info.footprint.min + shift, info.footprint.max + shift);
            }
            None => {}
        }
        let mut source = format!("{} entry {}", dir.display(), e.name);
        for (other, what) in
            [(&lref.density_from, "density_from"), (&lref.color_from, "color_from")]
        {
            let Some(other) = other else { continue };
            if lib.entry(other).is_none() {
                return Err(self.error(format!(
                    "asset \"{name}\": {what} names \"{other}\", which is not an entry of {}",
                    dir.display()
                )));
            }
            let src = lib.patch(other, halo)?;
            patch = if what == "density_from" {
                patch.with_density_of(&src)?
            } else {
                patch.with_color_of(&src)?
            };
            source += &format!(", {what} {other}");
        }
        Ok(ResolvedAsset { category: info.category.clone(), patch: Arc::new(patch), info, source })
    }
}

impl ScriptAssets {
    /// Register every asset's patch as a template of the composer.
    pub fn install(&self, composer: &mut Composer) -> Result<(), SceneError> {
        for (name, a) in &self.assets {
            composer.set_template(name, &a.category, a.patch.clone())?;
        }
        Ok(())
    }
}

impl AssetCatalog for ScriptAssets {
    fn asset_info(&self, name: &str) -> Option<AssetInfo> {
        self.assets.get(name).map(|a| a.info.clone()).or_else(|| self.containers.get(name).cloned())
    }
    fn asset_names(&self) -> Vec<String> {
        self.assets.keys().chain(self.containers.keys()).cloned().collect()
    }
}

fn canonical(p: &Path) -> PathBuf {
    std::fs::canonicalize(p).unwrap_or_else(|_| p.to_path_buf())
}

/// A `rows x cols` mask (non-zero: set) grown by `radius` texels in Chebyshev distance (a
/// square of side `2 radius + 1`, clipped to the patch): the ring mining filled with the
/// background around every object it removed (its square dilation, the same radius).
fn grow_mask(mask: &[u8], rows: usize, cols: usize, radius: usize) -> Vec<bool> {
    let set: Vec<bool> = mask.iter().map(|&b| b != 0).collect();
    if radius == 0 || rows == 0 || cols == 0 {
        return set;
    }
    // separable: any set texel within `radius` along the row, then along the column
    let window = |n: usize, i: usize| i.saturating_sub(radius)..(i + radius + 1).min(n);
    let mut along_rows = vec![false; rows * cols];
    for r in 0..rows {
        for c in 0..cols {
            along_rows[r * cols + c] = window(cols, c).any(|k| set[r * cols + k]);
        }
    }
    let mut out = vec![false; rows * cols];
    for r in 0..rows {
        for c in 0..cols {
            out[r * cols + c] = window(rows, r).any(|k| along_rows[k * cols + c]);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::grow_mask;

    #[test]
    fn a_grown_mask_is_a_clipped_square_around_each_set_texel() {
        let (rows, cols) = (5, 7);
        let mut mask = vec![0u8; rows * cols];
        mask[cols + 1] = 1; // (row 1, col 1): its square reaches the top and left borders
        mask[3 * cols + 6] = 1; // (row 3, col 6): the right border
        for radius in 0..4 {
            let grown = grow_mask(&mask, rows, cols, radius);
            for r in 0..rows {
                for c in 0..cols {
                    let near =
                        |(sr, sc): (usize, usize)| r.abs_diff(sr).max(c.abs_diff(sc)) <= radius;
                    let want = near((1, 1)) || near((3, 6));
                    assert_eq!(grown[r * cols + c], want, "radius {radius}, texel ({r}, {c})");
                }
            }
        }
    }
}
