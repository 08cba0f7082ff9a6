//! The ECS world: components, resources, the systems that keep the composed planes in step
//! with the entities, and [`Composer`], the Rust-side API over them.
//!
//! | system | set | reads | writes |
//! |---|---|---|---|
//! | `track_container` | `ComposeSet::Track` | changed or removed `ContainerPlanes` | `Composition` canvas, `Footprints` (the whole grid dirty) |
//! | `track_instances` | `ComposeSet::Track` | changed `Placement`, `InstanceOf`, `PatchOverride`, changed `Template`s, removed instances, `Composition` (grid) | `Footprints` (rect per instance, pending dirty rects) |
//! | `rasterise_dirty` | `ComposeSet::Rasterise` | `Footprints`, every instance's `Placement` + patch | `Composition` planes in the dirty rects, `RasterStats` |
//! | `refresh_occupancy` | `ComposeSet::Occupancy` | `Footprints` (last dirty rects), `Composition` | `Composition` occupancy grid |

use crate::SceneError;
use crate::grid::TexelRect;
use crate::patch::FeaturePatch;
use crate::raster::{Composition, InstanceDraw};
use assetfield_core::{Camera, GroundTransform};
use assetfield_layout::ResolvedLayout;
use bevy_ecs::prelude::*;
use std::collections::{BTreeMap, HashMap, HashSet};
use std::sync::Arc;

/// Where an instance stands on the ground.
#[derive(Component, Debug, Clone, Copy, PartialEq)]
pub struct Placement(pub GroundTransform);

/// An asset of the library: its template patch and category. Replacing the patch (a
/// category-level edit) redraws every instance of it.
#[derive(Component, Debug, Clone)]
pub struct Template {
    pub name: String,
    pub category: String,
    pub patch: Arc<FeaturePatch>,
}

/// The template an instance draws.
#[derive(Component, Debug, Clone, Copy, PartialEq, Eq)]
pub struct InstanceOf(pub Entity);

/// An instance's stable key (from the layout script), used to diff layouts.
#[derive(Component, Debug, Clone, PartialEq, Eq, Hash)]
pub struct InstanceKey(pub String);

/// A per-instance patch that replaces the template's (density warping, a one-off
/// recolour).
#[derive(Component, Debug, Clone)]
pub struct PatchOverride(pub Arc<FeaturePatch>);

/// A container entity: canvas planes (a trained scene with its objects removed, a room, a
/// street) that the instances are drawn onto, `[rows][cols][nd]` and `[rows][cols][nc]` on
/// the composition's grid. Inserting, changing or removing it (then the canvas is empty
/// space) redraws every texel. Without one, the canvas the composition was built with stays.
#[derive(Component, Debug, Clone)]
pub struct ContainerPlanes {
    pub name: String,
    pub density: Arc<Vec<f32>>,
    pub color: Arc<Vec<f32>>,
}

/// The composed planes and the field that renders them.
#[derive(Resource, Debug)]
pub struct ComposedPlanes(pub Composition);

/// The texel rectangle each instance was last drawn in, and the rectangles waiting to be
/// redrawn.
#[derive(Resource, Debug, Default)]
pub struct Footprints {
    pub rects: HashMap<Entity, TexelRect>,
    pub pending: Vec<TexelRect>,
    /// The rectangles redrawn by the last frame (for the occupancy refresh).
    pub last_dirty: Vec<TexelRect>,
}

/// What the last frames cost.
#[derive(Resource, Debug, Default, Clone, Copy, PartialEq)]
pub struct RasterStats {
    /// Texels written in the last frame.
    pub texels: usize,
    /// Dirty rectangles redrawn in the last frame.
    pub rects: usize,
    /// Frames run.
    pub frames: u64,
}

/// The composer's system sets, run in this order every frame.
#[derive(SystemSet, Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ComposeSet {
    /// Work out which texels edits touched.
    Track,
    /// Redraw them.
    Rasterise,
    /// Keep the occupancy grid in step.
    Occupancy,
}

fn patch_of<'a>(
    inst: (&InstanceOf, Option<&'a PatchOverride>),
    templates: &'a Query<&Template>,
) -> Option<&'a Arc<FeaturePatch>> {
    match inst.1 {
        Some(o) => Some(&o.0),
        None => templates.get(inst.0.0).ok().map(|t| &t.patch),
    }
}

type Changed3 = Or<(Changed<Placement>, Changed<InstanceOf>, Changed<PatchOverride>)>;

/// What was taken off instances since the last run: their placements (despawned or
/// unplaced) and their patch overrides (back to their template's patch).
#[derive(bevy_ecs::system::SystemParam)]
struct Removals<'w, 's> {
    placements: RemovedComponents<'w, 's, Placement>,
    overrides: RemovedComponents<'w, 's, PatchOverride>,
}

fn track_instances(
    comp: Res<ComposedPlanes>,
    mut fp: ResMut<Footprints>,
    changed: Query<(), Changed3>,
    changed_templates: Query<Entity, Changed<Template>>,
    instances: Query<(Entity, &Placement, &InstanceOf, Option<&PatchOverride>)>,
    templates: Query<&Template>,
    mut removed: Removals,
) {
    let fp = &mut *fp;
    for e in removed.placements.read() {
        if let Some(r) = fp.rects.remove(&e) {
            fp.pending.push(r);
        }
    }
    let reverted: HashSet<Entity> = removed.overrides.read().collect();
    let retemplated: HashSet<Entity> = changed_templates.iter().collect();
    let grid = comp.0.grid;
    for (e, place, of, ov) in &instances {
        if !(changed.contains(e) || retemplated.contains(&of.0) || reverted.contains(&e)) {
            continue;
        }
        let Some(patch) = patch_of((of, ov), &templates) else { continue };
        let rect = grid.texels_of(InstanceDraw::new(&place.0, patch).world_bounds());
        if let Some(old) = fp.rects.insert(e, rect) {
            fp.pending.push(old);
        }
        fp.pending.push(rect);
    }
}

fn track_container(
    mut comp: ResMut<ComposedPlanes>,
    mut fp: ResMut<Footprints>,
    changed: Query<&ContainerPlanes, Changed<ContainerPlanes>>,
    mut removed: RemovedComponents<ContainerPlanes>,
    remaining: Query<(), With<ContainerPlanes>>,
) {
    let mut redraw = false;
    if let Some(c) = changed.iter().last() {
        // sizes were checked by Composer::set_container
        if comp.0.set_canvas(c.density.to_vec(), c.color.to_vec()).is_ok() {
            redraw = true;
        }
    } else if removed.read().count() > 0 && remaining.is_empty() {
        let n = comp.0.grid.rows * comp.0.grid.cols;
        let (nd, nc) = (comp.0.nd, comp.0.nc);
        if comp.0.set_canvas(vec![0.0; n * nd], vec![0.0; n * nc]).is_ok() {
            redraw = true;
        }
    }
    if redraw {
        let full = comp.0.full_rect();
        fp.pending.push(full);
    }
}

/// The order instances are drawn in: by key (instances without one last, by entity), so
/// that the composed planes depend only on which instances there are, not on the order the
/// ECS happens to store them in (a despawned and respawned instance moves in storage, and
/// sums of overlapping patches in another order differ in the last bits: undo would not
/// restore the planes exactly).
fn draw_order<T>(mut items: Vec<(Option<&InstanceKey>, Entity, T)>) -> Vec<T> {
    fn order(key: Option<&InstanceKey>, e: Entity) -> (bool, Option<&str>, Entity) {
        (key.is_none(), key.map(|k| k.0.as_str()), e)
    }
    items.sort_by(|a, b| order(a.0, a.1).cmp(&order(b.0, b.1)));
    items.into_iter().map(|(_, _, t)| t).collect()
}

/// What rasterisation reads of an instance.
type DrawnInstance = (
    Entity,
    Option<&'static InstanceKey>,
    &'static Placement,
    &'static InstanceOf,
    Option<&'static PatchOverride>,
);

fn rasterise_dirty(
    mut comp: ResMut<ComposedPlanes>,
    mut fp: ResMut<Footprints>,
    instances: Query<DrawnInstance>,
    templates: Query<&Template>,
    mut stats: ResMut<RasterStats>,
) {
    stats.frames += 1;
    let dirty = TexelRect::merge_overlapping(std::mem::take(&mut fp.pending));
    stats.rects = dirty.len();
    stats.texels = 0;
    if !dirty.is_empty() {
        let draws: Vec<InstanceDraw> = draw_order(
            instances
                .iter()
                .filter_map(|(e, key, p, of, ov)| {
                    patch_of((of, ov), &templates)
                        .map(|patch| (key, e, InstanceDraw::new(&p.0, patch.as_ref())))
                })
                .collect(),
        );
        for r in &dirty {
            stats.texels += comp.0.rasterise(*r, &draws);
        }
    }
    fp.last_dirty = dirty;
}

fn refresh_occupancy(mut comp: ResMut<ComposedPlanes>, fp: Res<Footprints>) {
    if comp.0.occupancy.is_none() {
        return; // built on the first render
    }
    for r in &fp.last_dirty {
        comp.0.refresh_occupancy(Some(*r));
    }
}

/// The frame schedule: track -> rasterise -> occupancy.
pub fn compose_schedule() -> Schedule {
    let mut s = Schedule::default();
    s.configure_sets((ComposeSet::Track, ComposeSet::Rasterise, ComposeSet::Occupancy).chain());
    s.add_systems((
        (track_container, track_instances).in_set(ComposeSet::Track),
        rasterise_dirty.in_set(ComposeSet::Rasterise),
        refresh_occupancy.in_set(ComposeSet::Occupancy),
    ));
    s
}

/// A composed scene: the ECS world with its schedule, and a Rust API for edits.
pub struct Composer {
    pub world: World,
    schedule: Schedule,
    templates: BTreeMap<String, Entity>,
}

impl std::fmt::Debug for Composer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Composer").field("templates", &self.templates).finish_non_exhaustive()
    }
}

fn check_transform(key: &str, t: &GroundTransform) -> Result<(), SceneError> {
    let bad = |reason: String| Err(SceneError::BadTransform { key: key.to_string(), reason });
    if !(t.scale.is_finite() && t.scale > 0.0) {
        return bad(format!("scale {} must be a positive number", t.scale));
    }
    if !(t.position.is_finite() && t.yaw_deg.is_finite() && t.base.is_finite()) {
        return bad("position and yaw must be finite".into());
    }
    Ok(())
}

impl Composer {
    /// A composer drawing onto `composition`'s canvas. Nothing is drawn until [`update`].
    ///
    /// [`update`]: Composer::update
    pub fn new(composition: Composition) -> Self {
        let mut world = World::new();
        world.insert_resource(ComposedPlanes(composition));
        world.init_resource::<Footprints>();
        world.init_resource::<RasterStats>();
        Composer { world, schedule: compose_schedule(), templates: BTreeMap::new() }
    }

    /// Run one frame: redraw what changed since the last one.
    pub fn update(&mut self) {
        self.schedule.run(&mut self.world);
    }

    pub fn composition(&self) -> &Composition {
        &self.world.resource::<ComposedPlanes>().0
    }

    /// The texel rectangles the last frame redrew (the whole grid when the canvas changed).
    pub fn last_dirty(&self) -> &[TexelRect] {
        &self.world.resource::<Footprints>().last_dirty
    }

    pub fn stats(&self) -> RasterStats {
        *self.world.resource::<RasterStats>()
    }

    /// Add (or replace: a category-level edit) the template of asset `name`.
    pub fn set_template(
        &mut self,
        name: &str,
        category: &str,
        patch: Arc<FeaturePatch>,
    ) -> Result<Entity, SceneError> {
        self.composition().check_patch(&patch)?;
        let t = Template { name: name.to_string(), category: category.to_string(), patch };
        Ok(match self.templates.get(name) {
            Some(&e) => {
                self.world.entity_mut(e).insert(t);
                e
            }
            None => {
                let e = self.world.spawn(t).id();
                self.templates.insert(name.to_string(), e);
                e
            }
        })
    }

    /// Put the instances into a container (scene-level edit): its planes become the canvas
    /// and everything is redrawn on the next frame. Replaces the current container entity if
    /// there is one.
    pub fn set_container(
        &mut self,
        name: &str,
        density: Vec<f32>,
        color: Vec<f32>,
    ) -> Result<Entity, SceneError> {
        let comp = self.composition();
        let n = comp.grid.rows * comp.grid.cols;
        for (what, len, ch) in
            [("density", density.len(), comp.nd), ("color", color.len(), comp.nc)]
        {
            if len != n * ch {
                return Err(SceneError::PatchShape {
                    name: name.to_string(),
                    what,
                    expected: n * ch,
                    actual: len,
                    shape: format!("{} x {} texels x {ch}", comp.grid.rows, comp.grid.cols),
                });
            }
        }
        let c = ContainerPlanes {
            name: name.to_string(),
            density: Arc::new(density),
            color: Arc::new(color),
        };
        let mut q = self.world.query_filtered::<Entity, With<ContainerPlanes>>();
        Ok(match q.iter(&self.world).next() {
            Some(e) => {
                self.world.entity_mut(e).insert(c);
                e
            }
            None => self.world.spawn(c).id(),
        })
    }

    /// Take the instances out of their container: the canvas becomes empty space.
    pub fn remove_container(&mut self) {
        let mut q = self.world.query_filtered::<Entity, With<ContainerPlanes>>();
        let all: Vec<Entity> = q.iter(&self.world).collect();
        for e in all {
            self.world.despawn(e);
        }
    }

    pub fn template(&self, name: &str) -> Option<Entity> {
        self.templates.get(name).copied()
    }

    /// Asset names with templates.
    pub fn asset_names(&self) -> Vec<String> {
        self.templates.keys().cloned().collect()
    }

    /// Place a new instance of asset `asset`.
    pub fn spawn(
        &mut self,
        key: &str,
        asset: &str,
        t: GroundTransform,
    ) -> Result<Entity, SceneError> {
        check_transform(key, &t)?;
        let template = self.template(asset).ok_or_else(|| SceneError::UnknownAsset {
            key: key.to_string(),
            asset: asset.to_string(),
        })?;
        self.check_inside(key, template, &t)?;
        Ok(self
            .world
            .spawn((Placement(t), InstanceOf(template), InstanceKey(key.to_string())))
            .id())
    }

    fn check_inside(
        &self,
        key: &str,
        template: Entity,
        t: &GroundTransform,
    ) -> Result<(), SceneError> {
        let patch = &self.world.get::<Template>(template).expect("template entity").patch;
        let b = InstanceDraw::new(t, patch).world_bounds();
        let canvas = self.composition().grid.world_rect();
        let inside = b.min.x < canvas.max.x
            && b.max.x > canvas.min.x
            && b.min.y < canvas.max.y
            && b.max.y > canvas.min.y;
        if inside {
            Ok(())
        } else {
            Err(SceneError::BadTransform {
                key: key.to_string(),
                reason: format!(
                    "at ({:.2}, {:.2}) it lies outside the canvas [{:.2}, {:.2}] x [{:.2}, {:.2}]",
                    t.position.x,
                    t.position.y,
                    canvas.min.x,
                    canvas.max.x,
                    canvas.min.y,
                    canvas.max.y
                ),
            })
        }
    }

    /// Move, turn or scale an instance.
    pub fn set_placement(&mut self, e: Entity, t: GroundTransform) -> Result<(), SceneError> {
        let key = self.world.get::<InstanceKey>(e).map(|k| k.0.clone()).unwrap_or_default();
        check_transform(&key, &t)?;
        let of = self.world.get::<InstanceOf>(e).map(|o| o.0);
        if let Some(of) = of {
            self.check_inside(&key, of, &t)?;
        }
        if let Some(mut p) = self.world.get_mut::<Placement>(e)
            && p.0 != t
        {
            p.0 = t;
        }
        Ok(())
    }

    /// The instance with `key`.
    pub fn find(&mut self, key: &str) -> Option<Entity> {
        let mut q = self.world.query::<(Entity, &InstanceKey)>();
        q.iter(&self.world).find(|(_, k)| k.0 == key).map(|(e, _)| e)
    }

    /// Delete an instance.
    pub fn despawn(&mut self, e: Entity) {
        self.world.despawn(e);
    }

    /// Give one instance its own patch (density warping), or take it away (`None`).
    pub fn set_override(
        &mut self,
        e: Entity,
        patch: Option<Arc<FeaturePatch>>,
    ) -> Result<(), SceneError> {
        match patch {
            Some(p) => {
                self.composition().check_patch(&p)?;
                self.world.entity_mut(e).insert(PatchOverride(p));
            }
            None => {
                self.world.entity_mut(e).remove::<PatchOverride>();
            }
        }
        Ok(())
    }

    /// Make the world match a resolved layout: instances are matched by key; new keys are
    /// spawned, missing ones despawned, changed placements or assets updated (unchanged
    /// instances are not touched, so they are not redrawn). Containers are the canvas and
    /// are skipped.
    pub fn apply_layout(&mut self, layout: &ResolvedLayout) -> Result<(), SceneError> {
        // validate everything first, so that a bad layout changes nothing
        for inst in layout.objects() {
            let at = |e: SceneError| SceneError::At {
                location: inst.location().to_string(),
                inner: Box::new(e),
            };
            check_transform(&inst.key, &inst.transform).map_err(at)?;
            let t = self
                .template(&inst.asset)
                .ok_or_else(|| SceneError::UnknownAsset {
                    key: inst.key.clone(),
                    asset: inst.asset.clone(),
                })
                .map_err(at)?;
            self.check_inside(&inst.key, t, &inst.transform).map_err(at)?;
        }
        let mut q = self.world.query::<(Entity, &InstanceKey)>();
        let existing: HashMap<String, Entity> =
            q.iter(&self.world).map(|(e, k)| (k.0.clone(), e)).collect();
        let mut seen = HashSet::new();
        for inst in layout.objects() {
            seen.insert(inst.key.clone());
            let template = self.templates[&inst.asset];
            match existing.get(&inst.key) {
                Some(&e) => {
                    let mut em = self.world.entity_mut(e);
                    if em.get::<Placement>().is_none_or(|p| p.0 != inst.transform) {
                        em.insert(Placement(inst.transform));
                    }
                    if em.get::<InstanceOf>().is_none_or(|o| o.0 != template) {
                        em.insert(InstanceOf(template));
                    }
                }
                None => {
                    self.world.spawn((
                        Placement(inst.transform),
                        InstanceOf(template),
                        InstanceKey(inst.key.clone()),
                    ));
                }
            }
        }
        for (key, e) in existing {
            if !seen.contains(&key) {
                self.world.despawn(e);
            }
        }
        Ok(())
    }

    /// Redraw everything from scratch (for checks and benchmarks): the planes a fresh
    /// composer would produce for the current entities.
    pub fn rasterise_everything(&mut self) -> usize {
        let mut q = self.world.query::<DrawnInstance>();
        let items: Vec<(GroundTransform, Arc<FeaturePatch>)> = draw_order(
            q.iter(&self.world)
                .filter_map(|(e, key, p, of, ov)| {
                    let patch = match ov {
                        Some(o) => o.0.clone(),
                        None => self.world.get::<Template>(of.0)?.patch.clone(),
                    };
                    Some((key, e, (p.0, patch)))
                })
                .collect(),
        );
        let draws: Vec<InstanceDraw> = items.iter().map(|(t, p)| InstanceDraw::new(t, p)).collect();
        let mut comp = self.world.resource_mut::<ComposedPlanes>();
        let full = comp.0.full_rect();
        comp.0.rasterise(full, &draws)
    }

    /// Build the occupancy grid of the composed field if there is none yet (later frames keep
    /// it up to date over the dirty rectangles).
    pub fn ensure_occupancy(&mut self) {
        let mut comp = self.world.resource_mut::<ComposedPlanes>();
        if comp.0.occupancy.is_none() {
            comp.0.refresh_occupancy(None);
        }
    }

    /// Render a view of the composed scene (builds the occupancy grid on first use).
    pub fn render(&mut self, camera: &Camera, background: glam::Vec3) -> Vec<f32> {
        self.ensure_occupancy();
        self.composition().render(camera, background)
    }

    /// [`Composer::render`] that gives up (`None`) when `stop` says so.
    pub fn render_unless(
        &mut self,
        camera: &Camera,
        background: glam::Vec3,
        stop: &(dyn Fn() -> bool + Sync),
    ) -> Option<Vec<f32>> {
        self.ensure_occupancy();
        self.composition().render_unless(camera, background, stop)
    }
}
