//! Resolution: a [`LoadedScript`] becomes a [`ResolvedLayout`], every instance with its world
//! transform, a stable integer id (script order; removed instances leave gaps, duplicates
//! come after) and a human-readable key (`dining/chairs[3]`).

use crate::error::{LayoutError, Location};
use crate::limits::{Limit, Limits};
use crate::rng::Rng;
use crate::script::{AssetDef, Axis, Edit, Facing, Item, Part, Region, V2, Variation};
use crate::source::{ItemNode, LoadedScript};
use crate::spatial::{self, PointGrid, QuadGrid};
use assetfield_core::ground::wrap_degrees;
use assetfield_core::{Aabb3, GroundTransform, Rect2};
use glam::{Vec2, Vec3};
use std::collections::BTreeMap;
use std::ops::Bound;

/// What resolution needs to know about an asset.
#[derive(Debug, Clone, PartialEq)]
pub struct AssetInfo {
    pub category: String,
    /// Footprint in the asset's local frame (unscaled).
    pub footprint: Rect2,
    /// The convex outline of the asset's geometry seen from above, in its local frame
    /// (unscaled), when known (the synthesiser's catalog; empty otherwise). An instance's
    /// bird's-eye box is the box of its turned outline, so a round stool turned by 45 degrees
    /// keeps a box its own size instead of the box of its turned square footprint.
    pub outline: Vec<Vec2>,
    /// Height of the asset's top above its floor (unscaled); things placed `on` it stand there.
    pub height: f32,
    pub yaw_symmetry_deg: f32,
    pub container: bool,
    /// Counter-clockwise turn from the asset's category frame to its own, degrees: a mined
    /// entry is cut as its object stood (the turn taking its category's template onto it);
    /// 0 for templates and for assets made of parts. Giving an instance another asset of
    /// its category turns the instance by the difference, so the object keeps its
    /// orientation in the world.
    pub frame_yaw_deg: f32,
}

/// Where resolution looks up assets: the synthesiser (geometry), the composer (asset library).
pub trait AssetCatalog {
    fn asset_info(&self, name: &str) -> Option<AssetInfo>;
    fn asset_names(&self) -> Vec<String>;
}

/// A catalog computed from the primitive parts of a script's assets. Assets made only of an
/// OBJ mesh are not in it (the synthesiser's catalog loads meshes).
#[derive(Debug, Clone, Default)]
pub struct PartsCatalog {
    infos: BTreeMap<String, AssetInfo>,
}

impl PartsCatalog {
    pub fn from_script(script: &LoadedScript) -> Self {
        let mut infos = BTreeMap::new();
        for (name, entry) in &script.assets {
            let b = entry.def.parts_bounds();
            if !b.is_empty() {
                infos.insert(name.clone(), asset_info_from_bounds(name, &entry.def, b));
            }
        }
        PartsCatalog { infos }
    }
}

impl AssetCatalog for PartsCatalog {
    fn asset_info(&self, name: &str) -> Option<AssetInfo> {
        self.infos.get(name).cloned()
    }
    fn asset_names(&self) -> Vec<String> {
        self.infos.keys().cloned().collect()
    }
}

/// The [`AssetInfo`] of an asset whose local bounds are known.
pub fn asset_info_from_bounds(name: &str, def: &AssetDef, b: Aabb3) -> AssetInfo {
    AssetInfo {
        category: def.category.clone().unwrap_or_else(|| name.to_string()),
        footprint: b.bev(),
        outline: Vec::new(),
        height: b.max.z.max(0.0),
        yaw_symmetry_deg: def.yaw_symmetry_deg,
        container: def.container,
        frame_yaw_deg: 0.0,
    }
}

impl Part {
    /// Local bounding box of the part.
    pub fn bounds(&self) -> Aabb3 {
        let v = |t: (f32, f32, f32)| Vec3::new(t.0, t.1, t.2);
        match self {
            Part::Box { center, size, yaw, .. } => {
                let c = v(*center);
                let h = v(*size) * 0.5;
                let (s, co) = yaw.to_radians().sin_cos();
                let hx = (co * h.x).abs() + (s * h.y).abs();
                let hy = (s * h.x).abs() + (co * h.y).abs();
                let e = Vec3::new(hx, hy, h.z);
                Aabb3::new(c - e, c + e)
            }
            Part::Cylinder { base, radius, height, axis, .. } => {
                let b = v(*base);
                let (along, r) = (axis_vec(*axis) * *height, Vec3::splat(*radius));
                let across = r * (Vec3::ONE - axis_vec(*axis));
                Aabb3::new(b.min(b + along) - across, b.max(b + along) + across)
            }
            Part::Cone { base, radius, top_radius, height, .. } => {
                let b = v(*base);
                let r = radius.max(*top_radius);
                Aabb3::new(b - Vec3::new(r, r, 0.0), b + Vec3::new(r, r, *height))
            }
            Part::Sphere { center, radius, .. } => {
                Aabb3::new(v(*center) - Vec3::splat(*radius), v(*center) + Vec3::splat(*radius))
            }
        }
    }
}

fn axis_vec(a: Axis) -> Vec3 {
    match a {
        Axis::X => Vec3::X,
        Axis::Y => Vec3::Y,
        Axis::Z => Vec3::Z,
    }
}

impl AssetDef {
    /// Union of the parts' bounds (empty for an asset without parts); for a library
    /// asset, its patch's box too (centred on the origin in x and y, or around the given
    /// pivot, from z = 0).
    pub fn parts_bounds(&self) -> Aabb3 {
        let parts = self.parts.iter().fold(Aabb3::EMPTY, |acc, p| acc.union(&p.bounds()));
        match &self.library {
            Some(l) => {
                let h = Vec3::new(l.size.0 * 0.5, l.size.1 * 0.5, 0.0);
                let (px, py) = l.pivot.unwrap_or((0.0, 0.0));
                let c = Vec3::new(-px, -py, 0.0);
                parts.union(&Aabb3::new(c - h, c + h + Vec3::Z * l.size.2))
            }
            None => parts,
        }
    }
}

/// One placed instance.
#[derive(Debug, Clone, PartialEq)]
pub struct ResolvedInstance {
    /// Stable id: script order; removals leave gaps; duplicates get new ids after the rest.
    pub id: u32,
    /// Human-readable key, e.g. `dining/chairs[3]`; edits refer to instances by key.
    pub key: String,
    pub asset: String,
    pub category: String,
    /// World transform.
    pub transform: GroundTransform,
    /// Transform relative to the top of the instance it stands on (equal to `transform` for
    /// instances on the ground).
    pub local: GroundTransform,
    pub supported_by: Option<u32>,
    pub container: bool,
    pub yaw_symmetry_deg: f32,
    /// Footprint rectangle in the asset's own frame (unscaled).
    pub footprint: Rect2,
    /// World bird's-eye-view box of the footprint.
    pub bev_aabb: Rect2,
    /// World height of the top of the instance.
    pub top: f32,
    /// The script item that placed the instance (for a copy, the `Duplicate` edit).
    pub placed_at: Location,
    /// The last edit that changed the instance's transform or asset.
    pub edited_at: Option<Location>,
}

impl ResolvedInstance {
    /// Where in the script the instance got its current state: the last edit that changed
    /// it, else the item that placed it (for error messages about the instance).
    pub fn location(&self) -> &Location {
        self.edited_at.as_ref().unwrap_or(&self.placed_at)
    }
}

/// A resolved layout.
#[derive(Debug, Clone, PartialEq)]
pub struct ResolvedLayout {
    pub name: String,
    /// Instances in id order.
    pub instances: Vec<ResolvedInstance>,
    /// The ground region of interest.
    pub extent: Rect2,
    /// Names people read, by category (`NameCategory` edits; the last one wins).
    pub category_names: BTreeMap<String, String>,
}

impl ResolvedLayout {
    /// Instances that are objects (not containers).
    pub fn objects(&self) -> impl Iterator<Item = &ResolvedInstance> {
        self.instances.iter().filter(|i| !i.container)
    }
    pub fn containers(&self) -> impl Iterator<Item = &ResolvedInstance> {
        self.instances.iter().filter(|i| i.container)
    }
    pub fn get(&self, id: u32) -> Option<&ResolvedInstance> {
        self.instances.binary_search_by_key(&id, |i| i.id).ok().map(|k| &self.instances[k])
    }
    pub fn by_key(&self, key: &str) -> Option<&ResolvedInstance> {
        self.instances.iter().find(|i| i.key == key)
    }
    /// The categories of the layout's objects, in name order: category `k` of this list is
    /// drawn in `palette(k)` in every picture (`layout.png`, the editor), whatever order
    /// edits leave the instances in.
    pub fn categories(&self) -> Vec<String> {
        let set: std::collections::BTreeSet<&str> =
            self.objects().map(|i| i.category.as_str()).collect();
        set.into_iter().map(str::to_string).collect()
    }
}

/// Resolve a loaded script against an asset catalog, under the limits it was loaded with
/// ([`LoadedScript::limits`]).
pub fn resolve(
    script: &LoadedScript,
    catalog: &dyn AssetCatalog,
) -> Result<ResolvedLayout, LayoutError> {
    resolve_with(script, catalog, &script.limits)
}

/// [`resolve()`] under the given limits.
///
/// Resolution takes time about linear in the number of instances: targets and `on` patterns
/// are looked up in an index of keys (by their literal prefix), what stands on what is kept
/// as lists, an edit re-derives only the instances it moves, and scatters test only nearby
/// points and footprints.
pub fn resolve_with(
    script: &LoadedScript,
    catalog: &dyn AssetCatalog,
    limits: &Limits,
) -> Result<ResolvedLayout, LayoutError> {
    let mut r = Resolver::new(script, catalog, limits);
    for (k, node) in script.items.iter().enumerate() {
        r.item(node, GroundTransform::IDENTITY, "", None, k)?;
    }
    for e in &script.edits {
        r.begin_edit();
        r.edit(e)?;
        r.end_edit(&e.location);
    }
    let instances: Vec<ResolvedInstance> =
        r.out.into_iter().zip(r.removed).filter(|(_, gone)| !gone).map(|(i, _)| i).collect();
    for i in &instances {
        check_derived(i)?;
    }
    let extent = match script.extent {
        Some((a, b)) => Rect2::new(Vec2::from(a).min(b.into()), Vec2::from(a).max(b.into())),
        None => {
            let mut e = instances.iter().fold(Rect2::EMPTY, |acc, i| acc.union(&i.bev_aabb));
            if e.is_empty() {
                e = Rect2::new(Vec2::splat(-1.0), Vec2::splat(1.0));
            }
            e
        }
    };
    Ok(ResolvedLayout {
        name: script.name.clone(),
        instances,
        extent,
        category_names: r.category_names,
    })
}

/// The largest coordinate a resolved layout may hold (scene units, either sign): 2^24, where
/// f32 stops telling neighbouring units apart, so that a layout beyond it has no geometry
/// left to draw (and sizes computed from it overflow).
pub const MAX_COORDINATE: f32 = 16_777_216.0;

/// Finite inputs can still give a result out of reach (a row from -3e38 to 3e38 spans an
/// infinite extent, a position of 3e38 moved by 3e38 overflows, a scale of 1e30 makes an
/// infinite box): every resolved instance's position, heights and box must lie within
/// [`MAX_COORDINATE`], or the item (or edit) that made it is named.
fn check_derived(i: &ResolvedInstance) -> Result<(), LayoutError> {
    let t = i.transform;
    let b = i.bev_aabb;
    let values = [
        ("position", t.position.x),
        ("position", t.position.y),
        ("height", t.base),
        ("top", i.top),
        ("box", b.min.x),
        ("box", b.min.y),
        ("box", b.max.x),
        ("box", b.max.y),
    ];
    let yaw_ok = t.yaw_deg.is_finite() && t.scale.is_finite();
    match values.iter().find(|(_, v)| v.is_nan() || v.abs() > MAX_COORDINATE) {
        None if yaw_ok => Ok(()),
        found => {
            let (what, v) = found.copied().unwrap_or(("scale or yaw", t.scale * t.yaw_deg));
            Err(LayoutError::Semantic {
                location: i.location().clone(),
                message: format!(
                    "instance {} gets a {what} of {v}: beyond {MAX_COORDINATE} scene units (the numbers here are too large to compute with)",
                    i.key
                ),
            })
        }
    }
}

/// What the edit being applied changed: each instance's transform and asset before its
/// first change (compared afterwards to set `edited_at`).
#[derive(Debug, Default)]
struct Changes {
    /// Number of the edit being applied (1 for the first; 0 before any).
    serial: u32,
    /// Instances that existed before the edit (later ones are its copies).
    existing: usize,
    /// Per instance, the serial of the last edit that recorded it.
    recorded: Vec<u32>,
    before: Vec<(usize, GroundTransform, String)>,
}

struct Resolver<'a> {
    script: &'a LoadedScript,
    catalog: &'a dyn AssetCatalog,
    limits: &'a Limits,
    /// Every instance made, removed ones included; `out[k].id == k`.
    out: Vec<ResolvedInstance>,
    removed: Vec<bool>,
    /// Indices of the instances by key (keys need not be unique), ordered so that the keys
    /// starting with a pattern's literal prefix form one range.
    keys: BTreeMap<String, Vec<usize>>,
    /// Per instance, the indices of the instances standing directly on it.
    supported: Vec<Vec<usize>>,
    /// Frames of `on`/`around` groups made so far (one per matching instance), bounded like
    /// instances: a group over many hosts does work even when it places nothing.
    host_frames: u64,
    /// Scatter tries the script has left ([`Limits::max_scatter_tries`]).
    tries_left: u64,
    /// Whether every world transform has been re-derived from its local transform (the first
    /// edit that moves something does it for all; later edits only for what they move).
    derived: bool,
    changes: Changes,
    /// `NameCategory` edits so far.
    category_names: BTreeMap<String, String>,
}

fn semantic(location: &Location, message: String) -> LayoutError {
    LayoutError::Semantic { location: location.clone(), message }
}

/// `n` as a `u64` (saturating; counts of this crate fit).
fn wide(n: usize) -> u64 {
    u64::try_from(n).unwrap_or(u64::MAX)
}

/// The characters of a key pattern before its first wildcard.
fn literal_prefix(pattern: &str) -> &str {
    pattern.find(['*', '?']).map_or(pattern, |k| &pattern[..k])
}

/// The instance id a `#ID` pattern names (exactly as ids are written: `#12`, not `#012`).
fn id_pattern(pattern: &str) -> Option<usize> {
    let id: u32 = pattern.strip_prefix('#')?.parse().ok()?;
    (format!("#{id}") == pattern).then_some(id as usize)
}

/// The closest known name (at most 3 edits away), for "did you mean" hints.
pub fn closest<'a>(name: &str, known: &'a [String]) -> Option<&'a String> {
    fn dist(a: &str, b: &str) -> usize {
        let b: Vec<char> = b.chars().collect();
        let mut prev: Vec<usize> = (0..=b.len()).collect();
        for (i, ca) in a.chars().enumerate() {
            let mut cur = vec![i + 1];
            for (j, cb) in b.iter().enumerate() {
                cur.push((prev[j] + usize::from(ca != *cb)).min(prev[j + 1] + 1).min(cur[j] + 1));
            }
            prev = cur;
        }
        prev[b.len()]
    }
    known.iter().map(|k| (dist(name, k), k)).filter(|(d, _)| *d <= 3).min().map(|(_, k)| k)
}

/// `*` matches any run of characters, `?` one character; everything else literally.
pub fn glob_match(pattern: &str, text: &str) -> bool {
    let (p, t): (Vec<char>, Vec<char>) = (pattern.chars().collect(), text.chars().collect());
    let (mut pi, mut ti, mut star, mut mark) = (0, 0, None, 0);
    while ti < t.len() {
        if pi < p.len() && (p[pi] == '?' || p[pi] == t[ti]) {
            pi += 1;
            ti += 1;
        } else if pi < p.len() && p[pi] == '*' {
            star = Some(pi);
            mark = ti;
            pi += 1;
        } else if let Some(s) = star {
            pi = s + 1;
            mark += 1;
            ti = mark;
        } else {
            return false;
        }
    }
    while pi < p.len() && p[pi] == '*' {
        pi += 1;
    }
    pi == p.len()
}

/// Corners of an instance's footprint in world coordinates.
fn footprint_corners(info: &AssetInfo, t: &GroundTransform) -> [Vec2; 4] {
    footprint_corners_of(&info.footprint, t)
}

/// Corners of a footprint rectangle (in the asset's frame) in world coordinates.
fn footprint_corners_of(footprint: &Rect2, t: &GroundTransform) -> [Vec2; 4] {
    let (a, b) = (footprint.min, footprint.max);
    [a, Vec2::new(b.x, a.y), b, Vec2::new(a.x, b.y)].map(|p| t.transform_point2(p))
}

fn bev_of(info: &AssetInfo, t: &GroundTransform) -> Rect2 {
    let grow = |mut r: Rect2, p: Vec2| {
        r.grow(p);
        r
    };
    if info.outline.is_empty() {
        footprint_corners(info, t).into_iter().fold(Rect2::EMPTY, grow)
    } else {
        info.outline.iter().map(|&p| t.transform_point2(p)).fold(Rect2::EMPTY, grow)
    }
}

/// Separating-axis test of two convex quadrilaterals.
fn quads_overlap(a: &[Vec2; 4], b: &[Vec2; 4]) -> bool {
    for quad in [a, b] {
        for k in 0..4 {
            let e = quad[(k + 1) % 4] - quad[k];
            let n = Vec2::new(-e.y, e.x);
            let proj = |q: &[Vec2; 4]| {
                q.iter()
                    .map(|p| p.dot(n))
                    .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), v| (lo.min(v), hi.max(v)))
            };
            let (a0, a1) = proj(a);
            let (b0, b1) = proj(b);
            if a1 <= b0 + 1e-6 || b1 <= a0 + 1e-6 {
                return false;
            }
        }
    }
    true
}

fn region_bounds(r: &Region) -> Rect2 {
    match r {
        Region::Rect { min, max } => {
            Rect2::new(Vec2::from(*min).min((*max).into()), Vec2::from(*min).max((*max).into()))
        }
        Region::Circle { center, radius } => {
            Rect2::new(Vec2::from(*center) - *radius, Vec2::from(*center) + *radius)
        }
        Region::Polygon(pts) => pts.iter().fold(Rect2::EMPTY, |mut r, p| {
            r.grow((*p).into());
            r
        }),
    }
}

fn region_contains(r: &Region, p: Vec2) -> bool {
    match r {
        Region::Rect { .. } => region_bounds(r).contains(p),
        Region::Circle { center, radius } => p.distance(Vec2::from(*center)) <= *radius,
        Region::Polygon(pts) => {
            let mut inside = false;
            let n = pts.len();
            for i in 0..n {
                let (a, b) = (Vec2::from(pts[i]), Vec2::from(pts[(i + n - 1) % n]));
                if (a.y > p.y) != (b.y > p.y) && p.x < (b.x - a.x) * (p.y - a.y) / (b.y - a.y) + a.x
                {
                    inside = !inside;
                }
            }
            inside
        }
    }
}

fn yaw_towards(from: Vec2, to: Vec2) -> f32 {
    let d = to - from;
    if d.length_squared() < 1e-12 { 0.0 } else { d.y.atan2(d.x).to_degrees() }
}

/// A generated placement in the item's frame, before variation: position and facing yaw.
struct Spot {
    pos: Vec2,
    yaw: f32,
}

impl<'a> Resolver<'a> {
    fn new(script: &'a LoadedScript, catalog: &'a dyn AssetCatalog, limits: &'a Limits) -> Self {
        Resolver {
            script,
            catalog,
            limits,
            out: Vec::new(),
            removed: Vec::new(),
            keys: BTreeMap::new(),
            supported: Vec::new(),
            host_frames: 0,
            tries_left: limits.max_scatter_tries,
            derived: false,
            changes: Changes::default(),
            category_names: BTreeMap::new(),
        }
    }

    fn info(&self, asset: &str, node: &ItemNode) -> Result<AssetInfo, LayoutError> {
        self.info_at(asset, &self.script.files[node.file].find_string_after(asset, node.offset))
    }

    fn info_at(&self, asset: &str, location: &Location) -> Result<AssetInfo, LayoutError> {
        if let Some(i) = self.catalog.asset_info(asset) {
            return Ok(i);
        }
        let known = self.catalog.asset_names();
        let hint =
            closest(asset, &known).map(|k| format!("; did you mean \"{k}\"?")).unwrap_or_default();
        Err(semantic(
            location,
            format!("unknown asset \"{asset}\"{hint} (known assets: {})", known.join(", ")),
        ))
    }

    /// Refuse, before making them, `n` more instances than [`Limits::max_instances`]
    /// allows; `what` says what asks for them ("Row(count: 5) would place 5 instances").
    fn reserve(
        &self,
        n: u64,
        location: &Location,
        what: impl FnOnce() -> String,
    ) -> Result<(), LayoutError> {
        let have = wide(self.out.len());
        if have.saturating_add(n) > self.limits.get(Limit::Instances) {
            let what = format!("{} ({have} placed before it)", what());
            return Err(self.limits.exceeded(Limit::Instances, location, what));
        }
        Ok(())
    }

    fn top_frame(&self, supporter: Option<u32>) -> GroundTransform {
        match supporter.and_then(|id| self.out.get(id as usize)) {
            None => GroundTransform::IDENTITY,
            Some(s) => GroundTransform { base: s.top, ..s.transform },
        }
    }

    /// Add an instance (its id becomes its index) to the indexes.
    fn add(&mut self, mut inst: ResolvedInstance) -> usize {
        let k = self.out.len();
        debug_assert!(k < u32::MAX as usize, "the instance limit keeps ids in u32");
        inst.id = k as u32;
        match self.keys.get_mut(&inst.key) {
            Some(v) => v.push(k),
            None => {
                self.keys.insert(inst.key.clone(), vec![k]);
            }
        }
        if let Some(p) = inst.supported_by {
            self.supported[p as usize].push(k);
        }
        self.supported.push(Vec::new());
        self.removed.push(false);
        self.changes.recorded.push(0);
        self.out.push(inst);
        k
    }

    fn push(
        &mut self,
        key: String,
        asset: &str,
        info: &AssetInfo,
        world: GroundTransform,
        supporter: Option<u32>,
        placed_at: &Location,
    ) -> u32 {
        let local = relative_to(&world, &self.top_frame(supporter));
        let k = self.add(ResolvedInstance {
            id: 0,
            key,
            asset: asset.to_string(),
            category: info.category.clone(),
            transform: world,
            local,
            supported_by: supporter,
            container: info.container,
            yaw_symmetry_deg: info.yaw_symmetry_deg,
            footprint: info.footprint,
            bev_aabb: bev_of(info, &world),
            top: world.base + world.scale * info.height,
            placed_at: placed_at.clone(),
            edited_at: None,
        });
        k as u32
    }

    /// Indices of the instances (removed ones too) whose key matches `pattern`, or whose id
    /// it names (`#ID`), ascending. Only keys starting with the pattern's literal prefix are
    /// tested.
    fn candidates(&self, pattern: &str) -> Vec<usize> {
        let prefix = literal_prefix(pattern);
        let mut hits: Vec<usize> = if prefix.len() == pattern.len() {
            self.keys.get(pattern).cloned().unwrap_or_default()
        } else {
            self.keys
                .range::<str, _>((Bound::Included(prefix), Bound::Unbounded))
                .take_while(|(k, _)| k.starts_with(prefix))
                .filter(|(k, _)| glob_match(pattern, k))
                .flat_map(|(_, v)| v.iter().copied())
                .collect()
        };
        if let Some(id) = id_pattern(pattern)
            && id < self.out.len()
        {
            hits.push(id);
        }
        hits.sort_unstable();
        hits.dedup();
        hits
    }

    /// Indices of the instances left that `pattern` matches; none is an error.
    fn matches(&self, pattern: &str, loc: &Location) -> Result<Vec<usize>, LayoutError> {
        let mut hits = self.candidates(pattern);
        hits.retain(|&k| !self.removed[k]);
        if hits.is_empty() {
            let sample: Vec<&str> = self
                .out
                .iter()
                .zip(&self.removed)
                .filter(|(_, gone)| !**gone)
                .take(6)
                .map(|(i, _)| i.key.as_str())
                .collect();
            return Err(semantic(
                loc,
                format!(
                    "\"{pattern}\" matches no instance (keys look like: {}, ...; or use #ID)",
                    sample.join(", ")
                ),
            ));
        }
        Ok(hits)
    }

    /// Indices of `roots` and everything standing on them (transitively), in id order;
    /// `skip_removed` leaves out removed instances (and what stands on them).
    fn family(&self, roots: &[usize], skip_removed: bool) -> Vec<usize> {
        let mut seen = vec![];
        let mut stack: Vec<usize> = roots.to_vec();
        let mut visited = std::collections::HashSet::new();
        while let Some(k) = stack.pop() {
            if !visited.insert(k) {
                continue;
            }
            seen.push(k);
            stack.extend(
                self.supported[k].iter().copied().filter(|&c| !(skip_removed && self.removed[c])),
            );
        }
        seen.sort_unstable();
        seen
    }

    /// Indices of `roots` and everything left standing on them, in id order.
    fn with_dependents(&self, roots: &[usize]) -> Vec<usize> {
        self.family(roots, true)
    }

    /// Remember the state of instance `k` before the current edit first changes it.
    fn record(&mut self, k: usize) {
        let c = &mut self.changes;
        if k < c.existing && c.recorded[k] != c.serial {
            c.recorded[k] = c.serial;
            c.before.push((k, self.out[k].transform, self.out[k].asset.clone()));
        }
    }

    fn begin_edit(&mut self) {
        let c = &mut self.changes;
        c.serial += 1;
        c.existing = self.out.len();
        c.before.clear();
    }

    /// Mark what the edit at `loc` changed (and placed) with its location.
    fn end_edit(&mut self, loc: &Location) {
        let before = std::mem::take(&mut self.changes.before);
        for (k, t, a) in before {
            let inst = &mut self.out[k];
            if inst.transform != t || inst.asset != a {
                inst.edited_at = Some(loc.clone());
            }
        }
        for inst in &mut self.out[self.changes.existing..] {
            inst.placed_at = loc.clone();
            inst.edited_at = Some(loc.clone());
        }
    }

    /// Re-derive the world transform (and boxes) of instance `k` from its local transform
    /// and the top of what it stands on.
    fn rederive(&mut self, k: usize) {
        let frame = self.top_frame(self.out[k].supported_by);
        let world = frame.compose(&self.out[k].local);
        let info = self.catalog.asset_info(&self.out[k].asset);
        self.record(k);
        let inst = &mut self.out[k];
        inst.transform = world;
        if let Some(info) = info {
            inst.footprint = info.footprint;
            inst.bev_aabb = bev_of(&info, &world);
            inst.top = world.base + world.scale * info.height;
        }
    }

    /// Re-derive world transforms of `roots` and everything standing on them, parents first
    /// (a parent's index is below its children's). The first time, every instance is
    /// re-derived, so that every edit sees the same rounding of transforms.
    fn refresh(&mut self, roots: &[usize]) {
        let order = if self.derived {
            self.family(roots, false)
        } else {
            self.derived = true;
            (0..self.out.len()).collect()
        };
        for k in order {
            self.rederive(k);
        }
    }

    fn set_world(&mut self, k: usize, world: GroundTransform) {
        let frame = self.top_frame(self.out[k].supported_by);
        self.out[k].local = relative_to(&world, &frame);
    }

    fn item(
        &mut self,
        node: &ItemNode,
        frame: GroundTransform,
        prefix: &str,
        supporter: Option<u32>,
        index: usize,
    ) -> Result<(), LayoutError> {
        let loc = &node.location;
        let label = node
            .item
            .name()
            .map(str::to_string)
            .unwrap_or_else(|| format!("{}{index}", node.item.variant().to_ascii_lowercase()));
        let full = format!("{prefix}{label}");
        let check_scale = |s: f32| {
            if s.is_finite() && s > 0.0 {
                Ok(())
            } else {
                Err(semantic(loc, format!("scale must be positive, got {s}")))
            }
        };
        let check_count = |n: u32, what: &str| {
            if n == 0 { Err(semantic(loc, format!("{what} must be at least 1"))) } else { Ok(()) }
        };
        match &node.item {
            Item::Instance { asset, at, yaw, scale, base, .. } => {
                check_scale(*scale)?;
                self.reserve(1, loc, || "Instance would place 1 instance".into())?;
                let info = self.info(asset, node)?;
                let local = GroundTransform::new((*at).into(), *yaw, *scale, *base);
                self.push(full, asset, &info, frame.compose(&local), supporter, loc);
            }
            Item::Group { .. } => self.group(node, frame, &full, supporter)?,
            Item::Row { asset, from, to, count, yaw, face, scale, vary, .. } => {
                check_count(*count, "count")?;
                self.reserve(u64::from(*count), loc, || {
                    format!("Row(count: {count}) would place {count} instances")
                })?;
                let (a, b) = (Vec2::from(*from), Vec2::from(*to));
                let mid = (a + b) * 0.5;
                let spots = (0..*count)
                    .map(|i| {
                        let t = if *count == 1 { 0.5 } else { i as f32 / (*count - 1) as f32 };
                        let pos = a.lerp(b, t);
                        Spot { pos, yaw: facing(*face, pos, mid, yaw_towards(a, b)) }
                    })
                    .collect();
                self.place(
                    Target { node, frame, full: &full, supporter },
                    Copies { asset, yaw: *yaw, scale: *scale, vary: vary.as_ref() },
                    spots,
                )?;
            }
            Item::Grid { asset, center, rows, cols, spacing, yaw, scale, vary, .. } => {
                check_count(*rows, "rows")?;
                check_count(*cols, "cols")?;
                let n = u64::from(*rows) * u64::from(*cols);
                self.reserve(n, loc, || {
                    format!("Grid(rows: {rows}, cols: {cols}) would place {n} instances")
                })?;
                let c = Vec2::from(*center);
                let mut spots = Vec::new();
                for r in 0..*rows {
                    for k in 0..*cols {
                        let off = Vec2::new(
                            (k as f32 - (*cols - 1) as f32 * 0.5) * spacing.0,
                            (r as f32 - (*rows - 1) as f32 * 0.5) * spacing.1,
                        );
                        spots.push(Spot { pos: c + off, yaw: 0.0 });
                    }
                }
                self.place(
                    Target { node, frame, full: &full, supporter },
                    Copies { asset, yaw: *yaw, scale: *scale, vary: vary.as_ref() },
                    spots,
                )?;
            }
            Item::Ring {
                asset, center, radius, count, start_deg, face, yaw, scale, vary, ..
            } => {
                check_count(*count, "count")?;
                self.reserve(u64::from(*count), loc, || {
                    format!("Ring(count: {count}) would place {count} instances")
                })?;
                let c = Vec2::from(*center);
                let spots = (0..*count)
                    .map(|i| {
                        let ang = start_deg + 360.0 * i as f32 / *count as f32;
                        let pos = c + Vec2::from_angle(ang.to_radians()) * *radius;
                        Spot { pos, yaw: facing(*face, pos, c, ang + 90.0) }
                    })
                    .collect();
                self.place(
                    Target { node, frame, full: &full, supporter },
                    Copies { asset, yaw: *yaw, scale: *scale, vary: vary.as_ref() },
                    spots,
                )?;
            }
            Item::Along { asset, path, count, spacing, offset, face, yaw, scale, vary, .. } => {
                let plan = along_plan(path, *count, *spacing).map_err(|m| semantic(loc, m))?;
                self.reserve(plan.count, loc, || {
                    format!("Along would place {} instances", plan.count)
                })?;
                let spots = along_spots(path, &plan, *offset, *face);
                self.place(
                    Target { node, frame, full: &full, supporter },
                    Copies { asset, yaw: *yaw, scale: *scale, vary: vary.as_ref() },
                    spots,
                )?;
            }
            Item::Scatter {
                asset,
                region,
                count,
                min_distance,
                seed,
                yaw,
                scale,
                overlap,
                vary,
                ..
            } => {
                check_count(*count, "count")?;
                check_scale(*scale)?;
                self.scatter(
                    Target { node, frame, full: &full, supporter },
                    Copies { asset, yaw: *yaw, scale: *scale, vary: vary.as_ref() },
                    ScatterSpec {
                        region,
                        count: *count,
                        min_distance: *min_distance,
                        seed: *seed,
                        overlap: *overlap,
                    },
                )?;
            }
        }
        Ok(())
    }

    /// A group: its children in its own frame, or once per instance its `on` or `around`
    /// pattern matches.
    fn group(
        &mut self,
        node: &ItemNode,
        frame: GroundTransform,
        full: &str,
        supporter: Option<u32>,
    ) -> Result<(), LayoutError> {
        let loc = &node.location;
        let Item::Group { at, yaw, scale, base, on, around, .. } = &node.item else {
            return Ok(());
        };
        if !(scale.is_finite() && *scale > 0.0) {
            return Err(semantic(loc, format!("scale must be positive, got {scale}")));
        }
        let own = GroundTransform::new((*at).into(), *yaw, *scale, *base);
        let (pattern, stand_on) = match (on, around) {
            (None, None) => {
                let f = frame.compose(&own);
                for (k, c) in node.children.iter().enumerate() {
                    self.item(c, f, &format!("{full}/"), supporter, k)?;
                }
                return Ok(());
            }
            (Some(p), None) => (p, true),
            (None, Some(p)) => (p, false),
            (Some(_), Some(_)) => {
                return Err(semantic(loc, "a Group takes `on` or `around`, not both".into()));
            }
        };
        let field = if stand_on { "on" } else { "around" };
        let hosts = self.candidates(pattern);
        if hosts.is_empty() {
            return Err(semantic(
                loc,
                format!(
                    "`{field}: \"{pattern}\"` matches no instance placed before this group \
                     (instances are matched in script order: place them earlier)"
                ),
            ));
        }
        self.host_frames = self.host_frames.saturating_add(wide(hosts.len()));
        if self.host_frames > self.limits.get(Limit::Instances) {
            let what = format!(
                "Group({field}: \"{pattern}\") would repeat its children on {} instances \
                 ({} such frames in all)",
                hosts.len(),
                self.host_frames
            );
            return Err(self.limits.exceeded(Limit::Instances, loc, what));
        }
        let named = node.item.name().map(|n| format!("{n}/")).unwrap_or_default();
        for host in hosts {
            let h = &self.out[host];
            let (host_key, host_t, host_support) = (h.key.clone(), h.transform, h.supported_by);
            let (f, sup) = if stand_on {
                (self.top_frame(Some(host as u32)).compose(&own), Some(host as u32))
            } else {
                (host_t.compose(&own), host_support)
            };
            for (k, c) in node.children.iter().enumerate() {
                self.item(c, f, &format!("{host_key}/{named}"), sup, k)?;
            }
        }
        Ok(())
    }

    /// Place generated spots (in the item's frame) with variation.
    fn place(
        &mut self,
        to: Target<'_>,
        what: Copies<'_>,
        spots: Vec<Spot>,
    ) -> Result<(), LayoutError> {
        let Target { node, frame, full, supporter } = to;
        let Copies { asset, yaw, scale, vary } = what;
        if !(scale.is_finite() && scale > 0.0) {
            return Err(semantic(&node.location, format!("scale must be positive, got {scale}")));
        }
        let info = self.info(asset, node)?;
        for (i, s) in spots.into_iter().enumerate() {
            let key = format!("{full}[{i}]");
            let local = varied(&key, s.pos, s.yaw + yaw, scale, vary);
            self.push(key, asset, &info, frame.compose(&local), supporter, &node.location);
        }
        Ok(())
    }

    /// Check a scatter against the limits and what its region can hold, before any try.
    fn check_scatter(
        &self,
        loc: &Location,
        asset: &str,
        region: &Region,
        bounds: &Rect2,
        count: u32,
        min_distance: f32,
    ) -> Result<(), LayoutError> {
        if let Region::Polygon(p) = region {
            if p.len() < 3 {
                return Err(semantic(
                    loc,
                    format!("a polygon region needs at least 3 points, got {}", p.len()),
                ));
            }
            if wide(p.len()) > self.limits.get(Limit::RegionPoints) {
                let what = format!("a Scatter region of {} points", p.len());
                return Err(self.limits.exceeded(Limit::RegionPoints, loc, what));
            }
        }
        self.reserve(u64::from(count), loc, || {
            format!("Scatter(count: {count}) would place {count} instances")
        })?;
        if min_distance > 0.0 {
            let fit = spatial::max_points(region, bounds, min_distance).floor();
            if f64::from(count) > fit {
                return Err(semantic(
                    loc,
                    format!(
                        "Scatter could place only {fit} of {count} instances of \"{asset}\" at \
                         most: a region of {:.2} x {:.2} holds no more than {fit} points \
                         min_distance {min_distance} apart (known before any try); enlarge the \
                         region, or lower count or min_distance",
                        bounds.size().x,
                        bounds.size().y,
                    ),
                ));
            }
        }
        Ok(())
    }

    /// The footprints a scatter must keep clear of (those that can meet one of its own),
    /// in a grid with cells about the size of its own footprints.
    fn scatter_obstacles(
        &self,
        info: &AssetInfo,
        frame: &GroundTransform,
        bounds: &Rect2,
        scale: f32,
        vary: Option<&Variation>,
        supporter: Option<u32>,
    ) -> QuadGrid {
        // how far an own footprint reaches from its instance's position, and how far the
        // position can leave the region (position jitter)
        let (scale_jitter, position_jitter) =
            vary.map_or((0.0, 0.0), |v| (v.scale_jitter, v.position_jitter));
        let fp = &info.footprint;
        let corner_reach =
            [fp.min, fp.max, Vec2::new(fp.min.x, fp.max.y), Vec2::new(fp.max.x, fp.min.y)]
                .iter()
                .map(|c| c.length())
                .fold(0.0, f32::max);
        let reach = corner_reach * scale * (1.0 + scale_jitter) * frame.scale;
        let mut area = Rect2::EMPTY;
        for p in [
            bounds.min,
            Vec2::new(bounds.max.x, bounds.min.y),
            bounds.max,
            Vec2::new(bounds.min.x, bounds.max.y),
        ] {
            area.grow(frame.transform_point2(p));
        }
        let margin = Vec2::splat(reach + 2.0 * position_jitter * frame.scale);
        let area = Rect2::new(area.min - margin, area.max + margin);
        let cell = (2.0 * reach).max(area.size().max_element() / 1024.0);
        let mut grid = QuadGrid::new(area.min, cell);
        for i in &self.out {
            if i.container || Some(i.id) == supporter {
                continue;
            }
            let corners = footprint_corners_of(&i.footprint, &i.transform);
            if spatial::boxes_meet(&spatial::quad_box(&corners, 0.0), &area) {
                grid.insert(corners);
            }
        }
        grid
    }

    fn scatter(
        &mut self,
        to: Target<'_>,
        what: Copies<'_>,
        spec: ScatterSpec<'_>,
    ) -> Result<(), LayoutError> {
        let Target { node, frame, full, supporter } = to;
        let Copies { asset, yaw, scale, vary } = what;
        let ScatterSpec { region, count, min_distance, seed, overlap } = spec;
        let loc = &node.location;
        let bounds = region_bounds(region);
        self.check_scatter(loc, asset, region, &bounds, count, min_distance)?;
        let info = self.info(asset, node)?;
        let mut rng = Rng::stream(seed, full);
        let mut points = PointGrid::new(&bounds, min_distance);
        // with `overlap: true` footprints are not tested: no grid to fill
        let mut quads = if overlap {
            QuadGrid::new(bounds.min, 1.0)
        } else {
            self.scatter_obstacles(&info, &frame, &bounds, scale, vary, supporter)
        };
        let own_budget = 500u64.saturating_mul(u64::from(count));
        let budget = own_budget.min(self.tries_left);
        let (mut tries, mut placed) = (0u64, 0u32);
        while placed < count && tries < budget {
            tries += 1;
            let p = Vec2::new(
                rng.range(bounds.min.x, bounds.max.x),
                rng.range(bounds.min.y, bounds.max.y),
            );
            if !region_contains(region, p)
                || (min_distance > 0.0 && points.any_closer(p, min_distance))
            {
                continue;
            }
            let key = format!("{full}[{placed}]");
            let local = varied(&key, p, yaw, scale, vary);
            let world = frame.compose(&local);
            let quad = footprint_corners(&info, &world);
            if !overlap && quads.any_overlap(&quad, quads_overlap) {
                continue;
            }
            placed += 1;
            points.insert(p);
            if !overlap {
                quads.insert(quad);
            }
            self.push(key, asset, &info, world, supporter, loc);
        }
        self.tries_left -= tries;
        if placed == count {
            return Ok(());
        }
        if budget < own_budget {
            let what = format!(
                "Scatter(count: {count}) placed {placed} instances when the script's scatters \
                 had used up their tries"
            );
            return Err(self.limits.exceeded(Limit::ScatterTries, loc, what));
        }
        Err(semantic(
            loc,
            format!(
                "Scatter could place only {placed} of {count} instances of \"{asset}\" in a region of \
                 {:.2} x {:.2} with min_distance {min_distance} after {tries} tries; \
                 enlarge the region, or lower count or min_distance{}",
                bounds.size().x,
                bounds.size().y,
                if overlap { "" } else { " (or allow `overlap: true`)" }
            ),
        ))
    }

    fn edit(&mut self, node: &crate::source::EditNode) -> Result<(), LayoutError> {
        let loc = &node.location;
        let one_of = |to: bool, by: bool| {
            if to == by {
                Err(semantic(
                    loc,
                    format!("{} needs exactly one of `to` or `by`", node.edit.variant()),
                ))
            } else {
                Ok(())
            }
        };
        match &node.edit {
            Edit::Remove(target) => {
                let hits = self.matches(target, loc)?;
                for k in self.with_dependents(&hits) {
                    self.removed[k] = true;
                }
            }
            Edit::RemoveCategory(cat) => {
                let hits = self.of_category(cat, loc)?;
                for k in self.with_dependents(&hits) {
                    self.removed[k] = true;
                }
            }
            Edit::NameCategory { category, name } => {
                self.category_names.insert(category.clone(), name.trim().to_string());
            }
            Edit::ReplaceAsset { category, with } => {
                let src = &self.script.files[node.file];
                let info = self.info_at(with, &src.find_string_after(with, node.offset))?;
                let hits = self.of_category(category, loc)?;
                for &k in &hits {
                    self.retarget(k, with, &info);
                }
                self.refresh(&hits);
            }
            Edit::Move { target, to, by } => {
                one_of(to.is_some(), by.is_some())?;
                self.update_world(target, loc, |w| {
                    w.position = match (to, by) {
                        (Some(t), _) => (*t).into(),
                        _ => w.position + Vec2::from(by.unwrap_or_default()),
                    };
                    Ok(())
                })?;
            }
            Edit::Rotate { target, to, by } => {
                one_of(to.is_some(), by.is_some())?;
                self.update_world(target, loc, |w| {
                    w.yaw_deg = wrap_degrees(to.unwrap_or(w.yaw_deg + by.unwrap_or(0.0)));
                    Ok(())
                })?;
            }
            Edit::Scale { target, to, by } => {
                one_of(to.is_some(), by.is_some())?;
                self.update_world(target, loc, |w| {
                    w.scale = to.unwrap_or(w.scale * by.unwrap_or(1.0));
                    if w.scale.is_finite() && w.scale > 0.0 {
                        Ok(())
                    } else {
                        Err(format!("scale must be positive, got {}", w.scale))
                    }
                })?;
            }
            Edit::Override { target, asset, at, yaw, scale, base } => {
                if let Some(s) = scale
                    && !(s.is_finite() && *s > 0.0)
                {
                    return Err(semantic(loc, format!("scale must be positive, got {s}")));
                }
                let new_info = match asset {
                    Some(a) => Some(self.info_at(
                        a,
                        &self.script.files[node.file].find_string_after(a, node.offset),
                    )?),
                    None => None,
                };
                for k in self.matches(target, loc)? {
                    if let (Some(a), Some(info)) = (asset, &new_info) {
                        self.retarget(k, a, info);
                    }
                    let mut w = self.out[k].transform;
                    if let Some(p) = at {
                        w.position = (*p).into();
                    }
                    if let Some(y) = yaw {
                        w.yaw_deg = wrap_degrees(*y);
                    }
                    if let Some(s) = scale {
                        w.scale = *s;
                    }
                    if let Some(b) = base {
                        w.base = self.top_frame(self.out[k].supported_by).base + b;
                    }
                    self.set_world(k, w);
                    self.refresh(&[k]);
                }
            }
            Edit::Add { asset, at, yaw, scale, name } => {
                let src = &self.script.files[node.file];
                let info = self.info_at(asset, &src.find_string_after(asset, node.offset))?;
                self.reserve(1, loc, || "Add would place 1 instance".into())?;
                let key = match name {
                    Some(k) if self.keys.contains_key(k) => {
                        return Err(semantic(
                            loc,
                            format!(
                                "an instance keyed \"{k}\" exists already; name the new one otherwise"
                            ),
                        ));
                    }
                    Some(k) => k.clone(),
                    None => (1u64..)
                        .map(|n| format!("{asset}+new{n}"))
                        .find(|k| !self.keys.contains_key(k))
                        .unwrap_or_else(|| format!("{asset}+new")),
                };
                let world = GroundTransform::new(
                    (*at).into(),
                    yaw.unwrap_or(0.0),
                    scale.unwrap_or(1.0),
                    0.0,
                );
                self.push(key, asset, &info, world, None, loc);
            }
            Edit::Duplicate { target, at, by, yaw, name } => {
                if at.is_some() && by.is_some() {
                    return Err(semantic(loc, "Duplicate takes `at` or `by`, not both".into()));
                }
                let roots = self.matches(target, loc)?;
                let copies: u64 =
                    roots.iter().map(|&r| wide(self.with_dependents(&[r]).len())).sum();
                self.reserve(copies, loc, || {
                    format!("Duplicate(target: \"{target}\") would copy {copies} instances")
                })?;
                let many = roots.len() > 1;
                for (n, &root) in roots.iter().enumerate() {
                    let new_root_key = match name {
                        Some(nm) if many => format!("{nm}[{n}]"),
                        Some(nm) => nm.clone(),
                        None => self.unique_copy_key(&self.out[root].key),
                    };
                    self.duplicate(root, new_root_key, loc, *at, *by, *yaw)?;
                }
            }
        }
        Ok(())
    }

    /// Copy `root` with everything standing on it; the copy of `root` gets `new_root_key`
    /// and is placed `at`, shifted `by` and turned to `yaw`.
    fn duplicate(
        &mut self,
        root: usize,
        new_root_key: String,
        loc: &Location,
        at: Option<V2>,
        by: Option<V2>,
        yaw: Option<f32>,
    ) -> Result<(), LayoutError> {
        let family = self.with_dependents(&[root]);
        let n = wide(family.len());
        self.reserve(n, loc, || format!("Duplicate would copy {n} instances"))?;
        let root_key = self.out[root].key.clone();
        let mut id_map: BTreeMap<u32, u32> = BTreeMap::new();
        let mut root_copy = None;
        for &k in &family {
            let mut copy = self.out[k].clone();
            let new_id = wide(self.out.len()) as u32;
            id_map.insert(copy.id, new_id);
            copy.supported_by = copy.supported_by.map(|p| *id_map.get(&p).unwrap_or(&p));
            copy.key = if k == root {
                new_root_key.clone()
            } else {
                copy.key.replacen(root_key.as_str(), &new_root_key, 1)
            };
            let c = self.add(copy);
            if k == root {
                root_copy = Some(c);
                let mut w = self.out[c].transform;
                if let Some(p) = at {
                    w.position = p.into();
                }
                if let Some(b) = by {
                    w.position += Vec2::from(b);
                }
                if let Some(y) = yaw {
                    w.yaw_deg = wrap_degrees(y);
                }
                self.set_world(c, w);
            }
        }
        if let Some(c) = root_copy {
            self.refresh(&[c]);
        }
        Ok(())
    }

    /// Indices of the instances left of category `cat`; none is an error.
    fn of_category(&self, cat: &str, loc: &Location) -> Result<Vec<usize>, LayoutError> {
        let hits: Vec<usize> = (0..self.out.len())
            .filter(|&k| !self.removed[k] && self.out[k].category == cat)
            .collect();
        if hits.is_empty() {
            return Err(semantic(
                loc,
                format!("no instance of category \"{cat}\" ({})", self.category_list()),
            ));
        }
        Ok(hits)
    }

    /// Apply `f` to the world transform of every instance matching `target` (what stands on
    /// them follows); `f` may refuse with a message.
    fn update_world(
        &mut self,
        target: &str,
        loc: &Location,
        mut f: impl FnMut(&mut GroundTransform) -> Result<(), String>,
    ) -> Result<(), LayoutError> {
        for k in self.matches(target, loc)? {
            let mut w = self.out[k].transform;
            f(&mut w).map_err(|m| semantic(loc, m))?;
            self.set_world(k, w);
            self.refresh(&[k]);
        }
        Ok(())
    }

    /// Give instance `k` asset `asset` (described by `info`). The instance turns by the
    /// difference of the two assets' frames ([`AssetInfo::frame_yaw_deg`]), so the object
    /// keeps its orientation in the world, and what stands on it keeps its place. Callers
    /// [`Self::refresh`] afterwards.
    fn retarget(&mut self, k: usize, asset: &str, info: &AssetInfo) {
        self.record(k);
        let old = self.catalog.asset_info(&self.out[k].asset).map_or(0.0, |i| i.frame_yaw_deg);
        let turn = wrap_degrees(old - info.frame_yaw_deg);
        let inst = &mut self.out[k];
        inst.asset = asset.to_string();
        inst.category = info.category.clone();
        inst.yaw_symmetry_deg = info.yaw_symmetry_deg;
        inst.container = info.container;
        if turn != 0.0 {
            let children = self.supported[k].clone();
            let worlds: Vec<GroundTransform> =
                children.iter().map(|&c| self.out[c].transform).collect();
            let mut w = self.out[k].transform;
            w.yaw_deg = wrap_degrees(w.yaw_deg + turn);
            self.set_world(k, w);
            // the world transform too (the refresh derives the same from the local one), for
            // an edit that goes on from it (Override sets `at` after the asset)
            self.out[k].transform = w;
            let top = GroundTransform { base: self.out[k].top, ..w };
            for (c, world) in children.into_iter().zip(worlds) {
                self.record(c);
                self.out[c].local = relative_to(&world, &top);
            }
        }
    }

    fn unique_copy_key(&self, key: &str) -> String {
        (1u64..)
            .map(|n| format!("{key}+copy{n}"))
            .find(|k| !self.keys.contains_key(k))
            .unwrap_or_else(|| format!("{key}+copy"))
    }

    fn category_list(&self) -> String {
        let mut cats: Vec<&str> = self
            .out
            .iter()
            .zip(&self.removed)
            .filter(|(_, gone)| !**gone)
            .map(|(i, _)| i.category.as_str())
            .collect();
        cats.sort();
        cats.dedup();
        format!("categories present: {}", cats.join(", "))
    }
}

fn facing(face: Facing, pos: Vec2, centre: Vec2, path_yaw: f32) -> f32 {
    match face {
        Facing::Fixed => 0.0,
        Facing::Center => yaw_towards(pos, centre),
        Facing::Outward => yaw_towards(centre, pos),
        Facing::Path => path_yaw,
        Facing::Toward(x, y) => yaw_towards(pos, Vec2::new(x, y)),
    }
}

/// Apply seeded variation to a placement. The random stream depends on the instance key
/// only, so adding items elsewhere never changes an instance's jitter.
fn varied(key: &str, pos: Vec2, yaw: f32, scale: f32, vary: Option<&Variation>) -> GroundTransform {
    let mut t = GroundTransform::new(pos, wrap_degrees(yaw), scale, 0.0);
    if let Some(v) = vary {
        let mut rng = Rng::stream(v.seed, key);
        let j = rng.range(-v.yaw_jitter_deg, v.yaw_jitter_deg);
        let choice = if v.yaw_choices.is_empty() {
            0.0
        } else {
            v.yaw_choices[rng.below(v.yaw_choices.len())]
        };
        t.yaw_deg = wrap_degrees(t.yaw_deg + j + choice);
        t.scale *= 1.0 + rng.range(-v.scale_jitter, v.scale_jitter);
        t.position += Vec2::new(
            rng.range(-v.position_jitter, v.position_jitter),
            rng.range(-v.position_jitter, v.position_jitter),
        );
    }
    t
}

/// Where an `Along` puts its instances: how many, at which distances along the path.
struct AlongPlan {
    /// Segment lengths of the path, and their sum.
    lens: Vec<f32>,
    total: f32,
    /// Number of instances (checked against the limits before any is made).
    count: u64,
    /// One every `spacing`, else `count` spread over the whole length.
    spacing: Option<f32>,
}

/// Plan an `Along` (without making its instances: a tiny spacing is refused by count).
fn along_plan(path: &[V2], count: Option<u32>, spacing: Option<f32>) -> Result<AlongPlan, String> {
    if path.len() < 2 {
        return Err(format!("Along needs a path of at least 2 points, got {}", path.len()));
    }
    let lens: Vec<f32> =
        path.windows(2).map(|w| Vec2::from(w[0]).distance(Vec2::from(w[1]))).collect();
    let total: f32 = lens.iter().sum();
    if total <= 0.0 {
        return Err("Along path has zero length".into());
    }
    let (count, spacing) = match (count, spacing) {
        (Some(n), None) if n >= 1 => (u64::from(n), None),
        (None, Some(s)) if s > 0.0 => {
            let steps = (total / s + 1e-4).floor();
            let n = if steps.is_finite() { (steps as u64).saturating_add(1) } else { u64::MAX };
            (n, Some(s))
        }
        _ => {
            return Err(
                "Along needs either `count` (at least 1) or a positive `spacing`, not both".into(),
            );
        }
    };
    Ok(AlongPlan { lens, total, count, spacing })
}

/// The spots of a planned `Along`, walking the path once (distances only grow).
fn along_spots(path: &[V2], plan: &AlongPlan, offset: f32, face: Facing) -> Vec<Spot> {
    let pts: Vec<Vec2> = path.iter().map(|p| Vec2::from(*p)).collect();
    let (lens, total) = (&plan.lens, plan.total);
    let n = plan.count;
    let station = |i: u64| match plan.spacing {
        Some(s) => i as f32 * s,
        None if n == 1 => total * 0.5,
        None => total * i as f32 / (n - 1) as f32,
    };
    let centre = pts.iter().copied().sum::<Vec2>() / pts.len() as f32;
    let last = lens.len() - 1;
    let (mut seg, mut acc) = (0, 0.0);
    (0..n)
        .map(|i| {
            let s = station(i);
            while !(s <= acc + lens[seg] || seg == last) {
                acc += lens[seg];
                seg += 1;
            }
            let (a, b) = (pts[seg], pts[seg + 1]);
            let dir = (b - a).normalize_or_zero();
            let t = ((s - acc) / lens[seg].max(1e-12)).clamp(0.0, 1.0);
            let pos = a.lerp(b, t) + Vec2::new(-dir.y, dir.x) * offset;
            Spot { pos, yaw: facing(face, pos, centre, dir.y.atan2(dir.x).to_degrees()) }
        })
        .collect()
}

/// The transform `local` such that `parent.compose(local) == world`.
pub fn relative_to(world: &GroundTransform, parent: &GroundTransform) -> GroundTransform {
    GroundTransform {
        position: parent.inverse_transform_point2(world.position),
        yaw_deg: wrap_degrees(world.yaw_deg - parent.yaw_deg),
        scale: world.scale / parent.scale,
        base: (world.base - parent.base) / parent.scale,
    }
}
/// Where a generator's instances go: the script node that made them, the frame they are
/// placed in, the name their keys start with and the instance they stand on.
#[derive(Clone, Copy)]
struct Target<'a> {
    node: &'a ItemNode,
    frame: GroundTransform,
    full: &'a str,
    supporter: Option<u32>,
}

/// What a generator places at each of its spots: an asset, turned by `yaw` and scaled on
/// top of each spot's own turn, then varied.
#[derive(Clone, Copy)]
struct Copies<'a> {
    asset: &'a str,
    yaw: f32,
    scale: f32,
    vary: Option<&'a Variation>,
}

/// A scatter's own values: where, how many, how far apart, from which seed, and whether
/// footprints may overlap.
#[derive(Clone, Copy)]
struct ScatterSpec<'a> {
    region: &'a Region,
    count: u32,
    min_distance: f32,
    seed: u64,
    overlap: bool,
}
