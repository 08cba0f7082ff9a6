//! Patch rasterisation on the device (`raster.wgsl`) and [`GpuComposer`]: a composition's
//! canvas, its field and the templates uploaded once, then layouts rasterised into the
//! field's parameter buffer, the occupancy grid rebuilt over the columns they touched (the
//! `occupancy_points` and `occupancy_cells` entry points of `render.wgsl`), and rendered
//! back to back, with no round trip through the CPU.

use crate::render::{bytes_of, map, rays_of, scoped, split_views, storage_entry};
use crate::{FieldRenderer, GpuContext, GpuError, RASTER_WGSL};
use assetfield_core::{Camera, GroundTransform};
use assetfield_field::{Field, Occupancy};
use assetfield_scene::{
    Composition, DensityRule, FeaturePatch, InstanceDraw, PlaneGrid, TexelRect,
};
use glam::{Vec2, Vec3};

/// Texels per side of the tiles whose instance lists the host builds.
pub const RASTER_TILE: usize = 16;
/// The shader's `G`: vec4 of channels per group.
const GROUP_VEC4: usize = 4;
/// The shader's workgroup size per side (texels); divides [`RASTER_TILE`].
const WG: usize = 8;
/// Loop iterations one dispatch may spend per invocation: channel groups x entries of a
/// tile's list walked (plus a few), well inside llvmpipe's 65535 per group of invocations.
const LOOP_BUDGET: u32 = 48_000;
/// Entries of a tile's list one dispatch walks at most (fewer with many channel groups).
const MAX_CHUNK: u32 = 16_384;
/// Trip count of the shader's canary loop.
const CANARY: u32 = 2;
const STATUS_BYTES: u64 = 16;
const CHUNK_BYTES: u64 = 16;
/// Bytes of the occupancy pass's uniform (`OccPass` in `render.wgsl`).
const OCC_PASS_BYTES: u64 = 32;
/// Loop iterations one occupancy dispatch may spend per invocation (layers x density
/// evaluations x their loops), well inside llvmpipe's 65535.
const OCC_LOOP_BUDGET: u64 = 48_000;
/// The opacity above which a cell is occupied, as `Composition::refresh_occupancy`.
pub const OCCUPANCY_THRESHOLD: f32 = 1e-4;

/// One instance of a layout: which template (its index in the uploaded templates) and where.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PatchInstance {
    pub patch: usize,
    pub transform: GroundTransform,
}

/// A layout: instances drawn in order (later ones are added after earlier ones, as the CPU
/// composer adds its draws).
pub type Layout = Vec<PatchInstance>;

/// What one rasterisation did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct GpuRasterStats {
    /// Texels written (the dirty rectangle clipped to the grid).
    pub texels: usize,
    /// Instances that reach the rectangle.
    pub instances: usize,
    /// (tile, instance) pairs in the tile lists.
    pub entries: usize,
    /// The longest tile list.
    pub max_list: usize,
    /// Dispatches (more than one when a tile's list is longer than a dispatch may walk).
    pub dispatches: usize,
    /// Occupancy cells re-evaluated (the columns under the rectangle; 0 with the grid off).
    pub occupancy_cells: usize,
}

impl GpuRasterStats {
    fn add(&mut self, s: &GpuRasterStats) {
        self.texels += s.texels;
        self.instances += s.instances;
        self.entries += s.entries;
        self.max_list = self.max_list.max(s.max_list);
        self.dispatches += s.dispatches;
        self.occupancy_cells += s.occupancy_cells;
    }
}

/// 32-bit words of a shader struct, with their member names when asked (for the layout
/// check against `raster.wgsl`).
struct Words {
    bits: Vec<u32>,
    names: Option<Vec<&'static str>>,
}

impl Words {
    fn new(named: bool) -> Self {
        Words { bits: Vec::new(), names: named.then(Vec::new) }
    }
    fn u(&mut self, name: &'static str, v: u32) {
        self.bits.push(v);
        if let Some(n) = &mut self.names {
            n.push(name);
        }
    }
    fn f(&mut self, name: &'static str, v: f32) {
        self.u(name, v.to_bits());
    }
}

/// The shader's `Raster` uniform.
#[derive(Debug, Clone, Copy, Default)]
struct RasterHeader {
    min: [f32; 2],
    step: [f32; 2],
    rows: u32,
    cols: u32,
    nd: u32,
    nc: u32,
    dv: u32,
    cv: u32,
    gd: u32,
    n_groups: u32,
    density_at: u32,
    color_at: u32,
    canvas_color: u32,
    tiles_x: u32,
    n_tiles: u32,
    /// r0, c0, r1, c1
    rect: [u32; 4],
    /// row, column
    base: [u32; 2],
    /// 1: density features add to the canvas outside the patches' cores
    /// (`DensityRule::Add`), 0: replace its share
    density_add: u32,
    canary: u32,
}

impl RasterHeader {
    fn pack(&self, w: &mut Words) {
        w.f("min_x", self.min[0]);
        w.f("min_y", self.min[1]);
        w.f("step_x", self.step[0]);
        w.f("step_y", self.step[1]);
        w.u("rows", self.rows);
        w.u("cols", self.cols);
        w.u("nd", self.nd);
        w.u("nc", self.nc);
        w.u("dv", self.dv);
        w.u("cv", self.cv);
        w.u("gd", self.gd);
        w.u("n_groups", self.n_groups);
        w.u("density_at", self.density_at);
        w.u("color_at", self.color_at);
        w.u("canvas_color", self.canvas_color);
        w.u("tiles_x", self.tiles_x);
        w.u("n_tiles", self.n_tiles);
        w.u("r0", self.rect[0]);
        w.u("c0", self.rect[1]);
        w.u("r1", self.rect[2]);
        w.u("c1", self.rect[3]);
        w.u("r_base", self.base[0]);
        w.u("c_base", self.base[1]);
        w.u("density_add", self.density_add);
        w.u("canary", self.canary);
    }
}

fn pack_chunk(w: &mut Words, entry0: u32, entry1: u32, first: bool, last: bool) {
    w.u("entry0", entry0);
    w.u("entry1", entry1);
    w.u("first", first.into());
    w.u("last", last.into());
}

/// The occupancy pass's `OccPass`: cell columns `i0..i1 x j0..j1`, layers `k0..k1`.
fn pack_occ_pass(w: &mut Words, cols: [u32; 4], k0: u32, k1: u32) {
    for (name, v) in ["i0", "j0", "i1", "j1"].into_iter().zip(cols) {
        w.u(name, v);
    }
    w.u("k0", k0);
    w.u("k1", k1);
    w.u("canary", CANARY);
    w.f("threshold", OCCUPANCY_THRESHOLD);
}

/// The occupancy grid the composer keeps on the device: resolution, placement (as
/// `Occupancy::full` computes them) and layers per dispatch.
#[derive(Debug, Clone, Copy)]
struct OccGrid {
    res: [usize; 3],
    min: Vec2,
    scale: Vec2,
    layers: u32,
}

impl OccGrid {
    /// The cell columns whose footprint meets the world rectangle of texels `rect`, as
    /// `Composition::refresh_occupancy` and `Occupancy::update_region` choose them:
    /// `[i0, j0, i1, j1]`, `None` when empty.
    fn columns(&self, grid: &PlaneGrid, rect: TexelRect) -> Option<[u32; 4]> {
        if rect.is_empty() {
            return None;
        }
        let lo = (grid.world(rect.r0, rect.c0) - self.min) * self.scale;
        let hi = (grid.world(rect.r1.max(1) - 1, rect.c1.max(1) - 1) - self.min) * self.scale;
        let [nx, ny, _] = self.res;
        let i0 = (lo.x.floor().max(0.0) as usize).min(nx);
        let j0 = (lo.y.floor().max(0.0) as usize).min(ny);
        let i1 = ((hi.x.floor() + 1.0).max(0.0) as usize).min(nx);
        let j1 = ((hi.y.floor() + 1.0).max(0.0) as usize).min(ny);
        (i0 < i1 && j0 < j1).then_some([i0 as u32, j0 as u32, i1 as u32, j1 as u32])
    }
}

/// A template on the device: the patch (for its bounds) and where its data lies in `pfeat`.
#[derive(Debug, Clone)]
struct Template {
    patch: FeaturePatch,
    /// vec4 offsets of the density and colour features, f32 offsets of the weights and of
    /// the core weights
    dens: u32,
    colr: u32,
    wt: u32,
    core: u32,
}

/// The shader's `Inst`: the inverse ground transform exactly as
/// `GroundTransform::inverse_transform_point2` computes it (cos and sin of -yaw, then a
/// division by the scale), the instance's texel rectangle and its patch.
fn pack_inst(w: &mut Words, t: &GroundTransform, rect: TexelRect, tpl: &Template) {
    let rot = Vec2::from_angle(-t.yaw_deg.to_radians());
    let p = &tpl.patch;
    w.f("pos_x", t.position.x);
    w.f("pos_y", t.position.y);
    w.f("cos", rot.x);
    w.f("sin", rot.y);
    w.f("scale", t.scale);
    w.u("r0", rect.r0 as u32);
    w.u("c0", rect.c0 as u32);
    w.u("r1", rect.r1 as u32);
    w.u("c1", rect.c1 as u32);
    w.u("rows", p.rows as u32);
    w.u("cols", p.cols as u32);
    w.u("dens", tpl.dens);
    w.u("colr", tpl.colr);
    w.u("wt", tpl.wt);
    w.u("core", tpl.core);
    w.f("texel_x", p.texel.x);
    w.f("texel_y", p.texel.y);
    w.f("half_cols", (p.cols - 1) as f32 * 0.5);
    w.f("half_rows", (p.rows - 1) as f32 * 0.5);
}

/// Member names, in order, of the structs the host packs for `raster.wgsl` (`Raster`,
/// `Chunk`, `Inst`): one 32-bit word each. For the layout check in the tests.
pub fn raster_struct_members() -> Vec<(&'static str, Vec<&'static str>)> {
    let names = |w: Words| w.names.unwrap_or_default();
    let mut h = Words::new(true);
    RasterHeader::default().pack(&mut h);
    let mut c = Words::new(true);
    pack_chunk(&mut c, 0, 0, false, false);
    let mut i = Words::new(true);
    let patch = FeaturePatch::new("x", 1, 1, Vec2::ONE, vec![0.0], vec![0.0], vec![1.0])
        .expect("a one-texel patch");
    let tpl = Template { patch, dens: 0, colr: 0, wt: 0, core: 0 };
    pack_inst(&mut i, &GroundTransform::IDENTITY, TexelRect { r0: 0, c0: 0, r1: 0, c1: 0 }, &tpl);
    vec![("Raster", names(h)), ("Chunk", names(c)), ("Inst", names(i))]
}

/// Member names, in order, of the occupancy pass's uniform (`OccPass` in `render.wgsl`):
/// one 32-bit word each. For the layout check in the tests.
pub fn occupancy_pass_members() -> Vec<&'static str> {
    let mut w = Words::new(true);
    pack_occ_pass(&mut w, [0; 4], 0, 0);
    w.names.unwrap_or_default()
}

/// The most entries of a tile's list a dispatch may walk with `groups` channel groups.
fn max_chunk(groups: usize) -> u32 {
    (LOOP_BUDGET / groups.max(1) as u32).clamp(1, MAX_CHUNK)
}

fn intersect(a: TexelRect, b: TexelRect) -> TexelRect {
    TexelRect { r0: a.r0.max(b.r0), c0: a.c0.max(b.c0), r1: a.r1.min(b.r1), c1: a.c1.min(b.c1) }
}

fn input(msg: impl Into<String>) -> GpuError {
    GpuError::Input(msg.into())
}

/// A layout's per-instance words and tile lists for one dirty rectangle.
struct Binned {
    insts: Vec<u32>,
    /// tile starts (n_tiles + 1), then the lists
    tiles: Vec<u32>,
    stats: GpuRasterStats,
}

/// A composition on the device: the canvas planes and the templates uploaded once, the
/// composed planes living in the renderer's parameter buffer. Rasterise a layout (all of
/// the planes, or dirty rectangles), render it, or do both for a batch of layouts.
///
/// Like the CPU composer (`assetfield_scene::Composer`), it keeps an occupancy grid in step
/// with the planes: every rasterisation re-evaluates, on the device, the grid's cell columns
/// under the rectangle it rewrote (the rule of `Occupancy::update_region`), so renders skip
/// empty space as `Composer::render` does. The grid has the composition's resolution when it
/// has one, else the one `Composition::refresh_occupancy` would build (half the field's,
/// at least 8). [`GpuComposer::set_occupancy`] turns it off (renders then march every
/// sample, as `render_view(&field, None, ..)`).
#[derive(Debug)]
pub struct GpuComposer {
    renderer: FieldRenderer,
    device: wgpu::Device,
    queue: wgpu::Queue,
    pipeline: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
    grid: PlaneGrid,
    header: RasterHeader,
    templates: Vec<Template>,
    canvas: wgpu::Buffer,
    pfeat: wgpu::Buffer,
    raster_uniform: wgpu::Buffer,
    chunk_uniform: wgpu::Buffer,
    chunks: wgpu::Buffer,
    insts: wgpu::Buffer,
    tiles: wgpu::Buffer,
    scratch: wgpu::Buffer,
    status: wgpu::Buffer,
    staging: wgpu::Buffer,
    bind: wgpu::BindGroup,
    chunk_len: u32,
    limit: u64,
    max_groups: u32,
    occ: OccGrid,
    occ_on: bool,
    /// `occupancy_points`, `occupancy_cells`
    occ_pipelines: [wgpu::ComputePipeline; 2],
    occ_bind: wgpu::BindGroup,
    occ_uniform: wgpu::Buffer,
    occ_chunks: wgpu::Buffer,
    // bound in `occ_bind`
    _occ_corners: wgpu::Buffer,
}

/// The occupancy passes of one rectangle: `(columns, dispatches)`, their `OccPass` records
/// already in the chunk table after those of earlier rectangles of the same submission.
#[derive(Debug, Clone, Copy)]
struct OccJob {
    cols: [u32; 4],
    first: u64,
    dispatches: u64,
}

fn uniform_entry(binding: u32) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Uniform,
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    }
}

fn buffer(
    device: &wgpu::Device,
    label: &str,
    size: u64,
    usage: wgpu::BufferUsages,
) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size: size.max(16).next_multiple_of(4),
        usage,
        mapped_at_creation: false,
    })
}

use wgpu::BufferUsages as U;
const STORAGE_IN: U = U::STORAGE.union(U::COPY_DST);

/// Make `buf` hold at least `bytes` (a larger buffer, same label and usage, if not); whether
/// it was replaced (its bind group must then be made again).
fn grow(
    device: &wgpu::Device,
    buf: &mut wgpu::Buffer,
    bytes: u64,
    limit: u64,
    what: &'static str,
) -> Result<bool, GpuError> {
    if buf.size() >= bytes {
        return Ok(false);
    }
    if bytes > limit {
        return Err(GpuError::BufferTooLarge { what, bytes, limit });
    }
    *buf = buffer(device, what, bytes.next_power_of_two().min(limit), buf.usage());
    Ok(true)
}

/// The offsets of the density and colour planes in `field`'s parameters, checked against
/// the grid's texels and the channels.
fn plane_offsets(
    field: &Field,
    grid: &PlaneGrid,
    nd: usize,
    nc: usize,
) -> Result<(u32, u32), GpuError> {
    let n = grid.rows * grid.cols;
    let plane = |name: &str, ch: usize| {
        let s = field
            .params
            .spec(name)
            .ok_or_else(|| input(format!("the composed field has no tensor {name}")))?;
        if s.len != n * ch || ch == 0 {
            return Err(input(format!(
                "{name} holds {} values, not {} x {} texels x {ch} channels",
                s.len, grid.rows, grid.cols
            )));
        }
        u32::try_from(s.offset).map_err(|_| input("plane offset beyond 32 bits"))
    };
    Ok((plane("density.plane", nd)?, plane("color.plane", nc)?))
}

impl OccGrid {
    /// The occupancy grid of `occ_res` cells over `field`'s box, and the layers one
    /// `occupancy_points` dispatch takes with `nd` density channels: its loop runs the
    /// plane's channels once, then per layer the channel blocks, the tail and the layer
    /// loop; the corners take one more layer.
    fn new(field: &Field, occ_res: [usize; 3], nd: usize) -> Self {
        let aabb = field.config.aabb();
        let extent = aabb.extent().max(Vec3::splat(1e-9));
        let ch = nd as u64;
        let per_layer = ch / 8 + ch % 8 + 2;
        let fixed = ch / 4 + 4 + per_layer;
        let layers =
            (OCC_LOOP_BUDGET.saturating_sub(fixed) / per_layer).clamp(1, occ_res[2] as u64) as u32;
        OccGrid {
            res: occ_res,
            min: aabb.min.truncate(),
            scale: Vec2::new(occ_res[0] as f32 / extent.x, occ_res[1] as f32 / extent.y),
            layers,
        }
    }
}

impl RasterHeader {
    /// The uniform of a grid with `(nd, nc)` channels whose planes start at `(density_at,
    /// color_at)` in the field's parameters; no rectangle yet.
    fn new(
        grid: &PlaneGrid,
        (nd, nc): (usize, usize),
        (density_at, color_at): (u32, u32),
        rule: DensityRule,
    ) -> Self {
        let n = grid.rows * grid.cols;
        let (dv, cv) = (nd.div_ceil(4), nc.div_ceil(4));
        let gd = dv.div_ceil(GROUP_VEC4);
        let n_groups = gd + cv.div_ceil(GROUP_VEC4);
        let (tiles_x, tiles_y) = (grid.cols.div_ceil(RASTER_TILE), grid.rows.div_ceil(RASTER_TILE));
        RasterHeader {
            min: grid.min.to_array(),
            step: grid.step.to_array(),
            rows: grid.rows as u32,
            cols: grid.cols as u32,
            nd: nd as u32,
            nc: nc as u32,
            dv: dv as u32,
            cv: cv as u32,
            gd: gd as u32,
            n_groups: n_groups as u32,
            density_at,
            color_at,
            canvas_color: (n * dv) as u32,
            tiles_x: tiles_x as u32,
            n_tiles: (tiles_x * tiles_y) as u32,
            rect: [0; 4],
            base: [0; 2],
            density_add: u32::from(rule == DensityRule::Add),
            canary: CANARY,
        }
    }
}

/// The canvas planes as the shader reads them: density then colour, each texel's channels
/// padded to whole vec4.
fn canvas_planes(field: &Field, h: &RasterHeader) -> Vec<f32> {
    let n = (h.rows * h.cols) as usize;
    let (nd, nc, dv, cv) = (h.nd as usize, h.nc as usize, h.dv as usize, h.cv as usize);
    let mut canvas = vec![0.0f32; n * (dv + cv) * 4];
    let data = &field.params.data;
    let (d_at, c_at) = (h.density_at as usize, h.color_at as usize);
    for k in 0..n {
        canvas[k * dv * 4..][..nd].copy_from_slice(&data[d_at + k * nd..][..nd]);
        canvas[(n * dv + k * cv) * 4..][..nc].copy_from_slice(&data[c_at + k * nc..][..nc]);
    }
    canvas
}

/// The sizes of the buffers that depend on the planes and the occupancy grid, checked
/// against the device's limit and 32-bit indices.
struct BufferSizes {
    /// The weight and core weight sums of every texel.
    scratch_bytes: u64,
    /// One bit per corner of the occupancy grid's cells.
    corner_bytes: u64,
}

impl BufferSizes {
    fn checked(
        canvas: usize,
        texels: usize,
        occ_res: [usize; 3],
        limit: u64,
    ) -> Result<Self, GpuError> {
        let scratch_bytes = (texels * 2 * 4) as u64;
        for (what, bytes) in
            [("the canvas planes", canvas as u64 * 4), ("the raster scratch sums", scratch_bytes)]
        {
            if bytes > limit {
                return Err(GpuError::BufferTooLarge { what, bytes, limit });
            }
        }
        if canvas / 4 >= u32::MAX as usize {
            return Err(input("the planes are too large for 32-bit indices"));
        }
        let corners = (occ_res[0] + 1) * (occ_res[1] + 1) * (occ_res[2] + 1);
        if corners >= u32::MAX as usize {
            return Err(GpuError::Unsupported(format!(
                "an occupancy grid of {occ_res:?} cells is too large for 32-bit indices"
            )));
        }
        let corner_bytes = corners.div_ceil(32) as u64 * 4;
        if corner_bytes > limit {
            let what = "the occupancy grid's corners";
            return Err(GpuError::BufferTooLarge { what, bytes: corner_bytes, limit });
        }
        Ok(BufferSizes { scratch_bytes, corner_bytes })
    }
}

/// The composer's pipelines, bind group layouts and buffers (the canvas uploaded; the
/// others sized for a start and grown on demand).
struct RasterObjects {
    pipeline: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
    occ_pipelines: [wgpu::ComputePipeline; 2],
    occ_layout: wgpu::BindGroupLayout,
    /// canvas, templates, raster header, chunk, chunks, instances, tiles, raster scratch,
    /// raster status, raster readback, occupancy pass, occupancy passes, occupancy corners
    bufs: [wgpu::Buffer; 13],
}

impl RasterObjects {
    fn create(
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        renderer: &FieldRenderer,
        canvas: &[f32],
        sizes: &BufferSizes,
    ) -> Self {
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("raster.wgsl"),
            source: wgpu::ShaderSource::Wgsl(RASTER_WGSL.into()),
        });
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("raster"),
            entries: &[
                uniform_entry(0),
                uniform_entry(1),
                storage_entry(2, true),
                storage_entry(3, true),
                storage_entry(4, true),
                storage_entry(5, true),
                storage_entry(6, false),
                storage_entry(7, false),
                storage_entry(8, false),
            ],
        });
        let pipeline =
            crate::context::compute_pipeline(device, "raster", &layout, &module, "raster");
        let occ_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("occupancy"),
            entries: &[
                storage_entry(0, true),
                storage_entry(1, true),
                storage_entry(7, false),
                storage_entry(8, false),
                uniform_entry(9),
                storage_entry(10, false),
            ],
        });
        let occ_pipelines = ["occupancy_points", "occupancy_cells"].map(|entry| {
            crate::context::compute_pipeline(device, entry, &occ_layout, renderer.module(), entry)
        });
        let canvas_buf = buffer(device, "canvas", canvas.len() as u64 * 4, STORAGE_IN);
        queue.write_buffer(&canvas_buf, 0, bytemuck::cast_slice(canvas));
        let b = |label, size, usage| buffer(device, label, size, usage);
        let bufs = [
            canvas_buf,
            b("templates", 16, STORAGE_IN),
            b("raster header", 4 * 25, U::UNIFORM | U::COPY_DST),
            b("chunk", CHUNK_BYTES, U::UNIFORM | U::COPY_DST),
            b("chunks", CHUNK_BYTES, U::COPY_SRC | U::COPY_DST),
            b("instances", 1 << 12, STORAGE_IN),
            b("tiles", 1 << 12, STORAGE_IN),
            b("raster scratch", sizes.scratch_bytes, U::STORAGE),
            b("raster status", STATUS_BYTES, U::STORAGE | U::COPY_DST | U::COPY_SRC),
            b("raster readback", STATUS_BYTES, U::MAP_READ | U::COPY_DST),
            b("occupancy pass", OCC_PASS_BYTES, U::UNIFORM | U::COPY_DST),
            b("occupancy passes", OCC_PASS_BYTES * 4, U::COPY_SRC | U::COPY_DST),
            b("occupancy corners", sizes.corner_bytes, U::STORAGE),
        ];
        RasterObjects { pipeline, layout, occ_pipelines, occ_layout, bufs }
    }
}

impl GpuComposer {
    /// Upload `composition`'s field and canvas, and `templates` (instances name them by
    /// index). The composition's canvas is what it draws under the patches; the planes it
    /// holds now are not used.
    pub fn new(
        ctx: &GpuContext,
        composition: &Composition,
        templates: &[FeaturePatch],
    ) -> Result<Self, GpuError> {
        // a composition with nothing drawn holds exactly its canvas in its planes
        let mut blank = composition.clone();
        blank.rasterise(blank.full_rect(), &[]);
        let field = &blank.field;
        let grid = blank.grid;
        let (nd, nc) = (blank.nd, blank.nc);
        let n = grid.rows * grid.cols;
        let (density_at, color_at) = plane_offsets(field, &grid, nd, nc)?;
        let res = field.config.res;
        let occ_res = composition
            .occupancy
            .as_ref()
            .map_or([(res[0] / 2).max(8), (res[1] / 2).max(8), (res[2] / 2).max(8)], |o| o.res);
        // every cell occupied until the first occupancy pass below
        let renderer = FieldRenderer::new(ctx, field, Some(&Occupancy::full(field, occ_res)))?;
        let word = |name: &str| {
            renderer.plan().header.iter().find(|f| f.name == name).map_or(u32::MAX, |f| f.bits)
        };
        let axes = ["n_density", "density[0].a0", "density[0].a1", "density[0].a2"].map(word);
        if axes != [1, 0, 1, 2] {
            return Err(GpuError::Unsupported(
                "the composer's occupancy pass needs one density component, a ground plane \
                 times a vertical line (S- and I-fields)"
                    .into(),
            ));
        }
        let occ = OccGrid::new(field, occ_res, nd);
        let limits = ctx.limits();
        let limit = limits.max_storage_buffer_binding_size.min(limits.max_buffer_size);
        let header = RasterHeader::new(&grid, (nd, nc), (density_at, color_at), blank.density_rule);
        let n_groups = header.n_groups as usize;
        if header.n_groups > LOOP_BUDGET / 4 {
            return Err(GpuError::Unsupported(format!("{nd} + {nc} channels are too many")));
        }
        let canvas = canvas_planes(field, &header);
        let sizes = BufferSizes::checked(canvas.len(), n, occ_res, limit)?;
        let device = ctx.device().clone();
        let queue = ctx.queue().clone();
        let gpu = pollster::block_on(scoped(&device, "raster pipeline and upload", || {
            RasterObjects::create(&device, &queue, &renderer, &canvas, &sizes)
        }))?;
        let RasterObjects { pipeline, layout, occ_pipelines, occ_layout, bufs } = gpu;
        let [
            canvas,
            pfeat,
            raster_uniform,
            chunk_uniform,
            chunks,
            insts,
            tiles,
            scratch,
            status,
            staging,
            occ_uniform,
            occ_chunks,
            occ_corners,
        ] = bufs;
        let occ_bind = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("occupancy"),
            layout: &occ_layout,
            entries: &[
                (0, renderer.header_buffer()),
                (1, renderer.params_buffer()),
                (7, &status),
                (8, renderer.occupancy_buffer()),
                (9, &occ_uniform),
                (10, &occ_corners),
            ]
            .map(|(binding, b)| wgpu::BindGroupEntry { binding, resource: b.as_entire_binding() }),
        });
        let bind = Self::bind_group(
            &device,
            &layout,
            [
                &raster_uniform,
                &chunk_uniform,
                &canvas,
                &pfeat,
                &insts,
                &tiles,
                renderer.params_buffer(),
                &scratch,
                &status,
            ],
        );
        let mut composer = GpuComposer {
            renderer,
            device,
            queue,
            pipeline,
            layout,
            grid,
            header,
            templates: Vec::new(),
            canvas,
            pfeat,
            raster_uniform,
            chunk_uniform,
            chunks,
            insts,
            tiles,
            scratch,
            status,
            staging,
            bind,
            chunk_len: max_chunk(n_groups),
            limit,
            max_groups: limits.max_compute_workgroups_per_dimension,
            occ,
            occ_on: true,
            occ_pipelines,
            occ_bind,
            occ_uniform,
            occ_chunks,
            _occ_corners: occ_corners,
        };
        composer.set_templates(templates)?;
        // the grid of the canvas
        composer.refresh_occupancy(None)?;
        Ok(composer)
    }

    fn bind_group(
        device: &wgpu::Device,
        layout: &wgpu::BindGroupLayout,
        buffers: [&wgpu::Buffer; 9],
    ) -> wgpu::BindGroup {
        let entries: Vec<wgpu::BindGroupEntry> = buffers
            .into_iter()
            .enumerate()
            .map(|(k, b)| wgpu::BindGroupEntry {
                binding: k as u32,
                resource: b.as_entire_binding(),
            })
            .collect();
        device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("raster"),
            layout,
            entries: &entries,
        })
    }

    fn rebind(&mut self) {
        self.bind = Self::bind_group(
            &self.device,
            &self.layout,
            [
                &self.raster_uniform,
                &self.chunk_uniform,
                &self.canvas,
                &self.pfeat,
                &self.insts,
                &self.tiles,
                self.renderer.params_buffer(),
                &self.scratch,
                &self.status,
            ],
        );
    }

    /// Replace the templates (instances name them by index). Their channels must be the
    /// composition's.
    pub fn set_templates(&mut self, templates: &[FeaturePatch]) -> Result<(), GpuError> {
        let (nd, nc) = (self.header.nd as usize, self.header.nc as usize);
        let (dv, cv) = (self.header.dv as usize, self.header.cv as usize);
        let mut data: Vec<f32> = Vec::new();
        let mut out = Vec::with_capacity(templates.len());
        for (i, p) in templates.iter().enumerate() {
            if p.nd != nd || p.nc != nc {
                return Err(input(format!(
                    "template {i} ({}) has {} density and {} colour channels; the composition \
                     has {nd} and {nc}",
                    p.name, p.nd, p.nc
                )));
            }
            let texels = p.rows * p.cols;
            let dens = data.len() / 4;
            for k in 0..texels {
                data.extend_from_slice(&p.density[k * nd..][..nd]);
                data.resize(data.len() + dv * 4 - nd, 0.0);
            }
            let colr = data.len() / 4;
            for k in 0..texels {
                data.extend_from_slice(&p.color[k * nc..][..nc]);
                data.resize(data.len() + cv * 4 - nc, 0.0);
            }
            let wt = data.len();
            data.extend_from_slice(&p.weight);
            let core = data.len();
            data.extend_from_slice(&p.core);
            data.resize(data.len().next_multiple_of(4), 0.0);
            if data.len() >= u32::MAX as usize {
                return Err(input("the templates are too large for 32-bit indices"));
            }
            out.push(Template {
                patch: p.clone(),
                dens: dens as u32,
                colr: colr as u32,
                wt: wt as u32,
                core: core as u32,
            });
        }
        let bytes = data.len() as u64 * 4;
        if bytes > self.limit {
            return Err(GpuError::BufferTooLarge {
                what: "the templates",
                bytes,
                limit: self.limit,
            });
        }
        self.pfeat = buffer(&self.device, "templates", bytes, STORAGE_IN);
        self.queue.write_buffer(&self.pfeat, 0, bytemuck::cast_slice(&data));
        self.templates = out;
        self.rebind();
        Ok(())
    }

    /// Walk at most `entries` entries of a tile's instance list per dispatch (at least 1, at
    /// most the default, 16384 or fewer with many channels): more dispatches for the same
    /// planes. For tests of the resumed rasterisation.
    pub fn with_raster_chunk(mut self, entries: u32) -> Self {
        self.chunk_len = entries.clamp(1, max_chunk(self.header.n_groups as usize));
        self
    }

    /// Entries of a tile's list one dispatch walks at most.
    pub fn raster_chunk(&self) -> u32 {
        self.chunk_len
    }

    /// [`GpuComposer::with_raster_chunk`] without the cap: dispatches may then run past
    /// llvmpipe's loop limit. Only for tests of the canary that detects it.
    #[doc(hidden)]
    pub fn with_unbounded_raster_chunk(mut self, entries: u32) -> Self {
        self.chunk_len = entries.max(1);
        self
    }

    /// Evaluate at most `layers` layers of occupancy cells per dispatch (at least 1, at most
    /// the default, which keeps a dispatch inside llvmpipe's loop limit): more dispatches
    /// for the same grid. For tests of the split occupancy passes.
    pub fn with_occupancy_layers(mut self, layers: u32) -> Self {
        self.occ.layers = layers.clamp(1, self.occ.layers);
        self
    }

    /// Layers of occupancy cells one dispatch evaluates at most.
    pub fn occupancy_layers(&self) -> u32 {
        self.occ.layers
    }

    /// [`GpuComposer::with_occupancy_layers`] without the cap: dispatches may then run past
    /// llvmpipe's loop limit. Only for tests of the canary that detects it.
    #[doc(hidden)]
    pub fn with_unbounded_occupancy_layers(mut self, layers: u32) -> Self {
        self.occ.layers = layers.max(1);
        self
    }

    /// The renderer of the composed field.
    pub fn renderer(&self) -> &FieldRenderer {
        &self.renderer
    }

    /// The ground grid of the planes.
    pub fn grid(&self) -> PlaneGrid {
        self.grid
    }

    /// Number of uploaded templates.
    pub fn template_count(&self) -> usize {
        self.templates.len()
    }

    /// Every texel of the planes.
    pub fn full_rect(&self) -> TexelRect {
        TexelRect { r0: 0, c0: 0, r1: self.grid.rows, c1: self.grid.cols }
    }

    /// Instance words and tile lists of `layout` for `rect` (clipped to the grid).
    fn bin(&self, layout: &[PatchInstance], rect: TexelRect) -> Result<Binned, GpuError> {
        let mut words = Words::new(false);
        let mut spans: Vec<TexelRect> = Vec::new();
        for (i, inst) in layout.iter().enumerate() {
            let tpl = self.templates.get(inst.patch).ok_or_else(|| {
                input(format!(
                    "instance {i} draws template {}, but {} are uploaded",
                    inst.patch,
                    self.templates.len()
                ))
            })?;
            let t = &inst.transform;
            let finite = t.position.is_finite() && t.yaw_deg.is_finite();
            if !(finite && t.scale.is_finite() && t.scale > 0.0) {
                return Err(input(format!("instance {i} has a bad transform {t:?}")));
            }
            let draw = InstanceDraw::new(t, &tpl.patch);
            let reach = self.grid.texels_of(draw.world_bounds());
            if !reach.intersects(&rect) {
                continue;
            }
            pack_inst(&mut words, &draw.transform, reach, tpl);
            spans.push(intersect(reach, rect));
        }
        let tiles_x = self.header.tiles_x as usize;
        let n_tiles = self.header.n_tiles as usize;
        let tile_range = |s: &TexelRect| {
            (
                s.r0 / RASTER_TILE..s.r1.div_ceil(RASTER_TILE),
                s.c0 / RASTER_TILE..s.c1.div_ceil(RASTER_TILE),
            )
        };
        // counting sort: instances keep their order within every tile
        let mut start = vec![0u32; n_tiles + 1];
        for s in &spans {
            let (rs, cs) = tile_range(s);
            for tr in rs {
                for tc in cs.clone() {
                    start[tr * tiles_x + tc + 1] += 1;
                }
            }
        }
        let max_list = start.iter().copied().max().unwrap_or(0) as usize;
        for t in 0..n_tiles {
            start[t + 1] += start[t];
        }
        let entries = start[n_tiles] as usize;
        let mut tiles = start.clone();
        tiles.resize(n_tiles + 1 + entries, 0);
        let mut fill = start;
        for (i, s) in spans.iter().enumerate() {
            let (rs, cs) = tile_range(s);
            for tr in rs {
                for tc in cs.clone() {
                    let t = tr * tiles_x + tc;
                    tiles[n_tiles + 1 + fill[t] as usize] = i as u32;
                    fill[t] += 1;
                }
            }
        }
        // (the shader adds a chunk's end to a tile's start)
        if tiles.len() + 2 * MAX_CHUNK as usize >= u32::MAX as usize {
            return Err(input("too many (tile, instance) pairs"));
        }
        Ok(Binned {
            insts: words.bits,
            tiles,
            stats: GpuRasterStats {
                texels: rect.area(),
                instances: spans.len(),
                entries,
                max_list,
                dispatches: 0,
                occupancy_cells: 0,
            },
        })
    }

    /// Upload `layout`'s instances for `rect` and submit its rasterisation; the shader's
    /// status (cleared first when `clear_status`, else added to) is copied to the staging
    /// buffer (see [`GpuComposer::check_status`]).
    async fn submit_raster(
        &mut self,
        layout: &[PatchInstance],
        rect: TexelRect,
        clear_status: bool,
    ) -> Result<GpuRasterStats, GpuError> {
        let rect = intersect(rect, self.full_rect());
        if rect.is_empty() {
            return Ok(GpuRasterStats::default());
        }
        let mut binned = self.bin(layout, rect)?;
        let chunks = (binned.stats.max_list as u64).div_ceil(self.chunk_len as u64).max(1);
        let mut chunk_words = Words::new(false);
        for k in 0..chunks {
            let e0 = k * self.chunk_len as u64;
            let e1 = e0 + self.chunk_len as u64;
            pack_chunk(&mut chunk_words, e0 as u32, e1 as u32, k == 0, k + 1 == chunks);
        }
        let (device, limit) = (&self.device, self.limit);
        let grown = [
            (&mut self.insts, binned.insts.len() as u64 * 4, "the layout's instances"),
            (&mut self.tiles, binned.tiles.len() as u64 * 4, "the tile lists"),
            (&mut self.chunks, chunks * CHUNK_BYTES, "the chunk table"),
        ]
        .into_iter()
        .map(|(buf, bytes, what)| grow(device, buf, bytes, limit, what))
        .collect::<Result<Vec<bool>, GpuError>>()?;
        if grown.contains(&true) {
            self.rebind();
        }
        let base = [rect.r0 / WG * WG, rect.c0 / WG * WG];
        let header = RasterHeader {
            rect: [rect.r0 as u32, rect.c0 as u32, rect.r1 as u32, rect.c1 as u32],
            base: [base[0] as u32, base[1] as u32],
            ..self.header
        };
        let mut hw = Words::new(false);
        header.pack(&mut hw);
        let groups =
            [(rect.c1 - base[1]).div_ceil(WG) as u32, (rect.r1 - base[0]).div_ceil(WG) as u32, 1];
        if groups.iter().any(|g| *g > self.max_groups) {
            return Err(input(format!(
                "a dispatch of {groups:?} workgroups exceeds the device's {} per dimension",
                self.max_groups
            )));
        }
        binned.stats.dispatches = chunks as usize;
        let occ_jobs = self.prepare_occupancy(&[rect])?;
        binned.stats.occupancy_cells = self.occupancy_job_cells(&occ_jobs);
        scoped(&self.device, "rasterise", || {
            let q = &self.queue;
            if !binned.insts.is_empty() {
                q.write_buffer(&self.insts, 0, bytes_of(&binned.insts));
            }
            q.write_buffer(&self.tiles, 0, bytes_of(&binned.tiles));
            q.write_buffer(&self.chunks, 0, bytes_of(&chunk_words.bits));
            q.write_buffer(&self.raster_uniform, 0, bytes_of(&hw.bits));
            let mut enc = self
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("raster") });
            if clear_status {
                enc.clear_buffer(&self.status, 0, None);
            }
            for k in 0..chunks {
                enc.copy_buffer_to_buffer(
                    &self.chunks,
                    k * CHUNK_BYTES,
                    &self.chunk_uniform,
                    0,
                    CHUNK_BYTES,
                );
                let mut cp = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some("raster"),
                    timestamp_writes: None,
                });
                cp.set_pipeline(&self.pipeline);
                cp.set_bind_group(0, &self.bind, &[]);
                cp.dispatch_workgroups(groups[0], groups[1], groups[2]);
            }
            self.encode_occupancy(&mut enc, &occ_jobs);
            enc.copy_buffer_to_buffer(&self.status, 0, &self.staging, 0, STATUS_BYTES);
            q.submit([enc.finish()]);
        })
        .await?;
        Ok(binned.stats)
    }

    /// Write the occupancy passes over the cell columns under each of `rects` (clipped to
    /// the grid) into the pass table: nothing with the grid off. Their layers are split
    /// over dispatches of at most `occ.layers` each.
    fn prepare_occupancy(&mut self, rects: &[TexelRect]) -> Result<Vec<OccJob>, GpuError> {
        if !self.occ_on {
            return Ok(Vec::new());
        }
        let nz = self.occ.res[2] as u32;
        let mut words = Words::new(false);
        let mut jobs = Vec::new();
        let mut at = 0u64;
        for r in rects {
            let Some(cols) = self.occ.columns(&self.grid, intersect(*r, self.full_rect())) else {
                continue;
            };
            let groups = [
                (cols[2] - cols[0] + 1).div_ceil(WG as u32),
                (cols[3] - cols[1] + 1).div_ceil(WG as u32),
            ];
            if groups.iter().any(|g| *g > self.max_groups) {
                return Err(input(format!(
                    "an occupancy dispatch of {groups:?} workgroups exceeds the device's {} per \
                     dimension",
                    self.max_groups
                )));
            }
            let first = at;
            let mut k0 = 0;
            while k0 < nz {
                let k1 = (k0 + self.occ.layers).min(nz);
                pack_occ_pass(&mut words, cols, k0, k1);
                k0 = k1;
                at += 1;
            }
            jobs.push(OccJob { cols, first, dispatches: at - first });
        }
        if !jobs.is_empty() {
            let bytes = at * OCC_PASS_BYTES;
            grow(&self.device, &mut self.occ_chunks, bytes, self.limit, "the occupancy passes")?;
            self.queue.write_buffer(&self.occ_chunks, 0, bytes_of(&words.bits));
        }
        Ok(jobs)
    }

    fn occupancy_job_cells(&self, jobs: &[OccJob]) -> usize {
        jobs.iter()
            .map(|j| {
                let [i0, j0, i1, j1] = j.cols.map(|v| v as usize);
                (i1 - i0) * (j1 - j0) * self.occ.res[2]
            })
            .sum()
    }

    /// Record the occupancy passes of `jobs` (after the raster passes that changed the
    /// planes they read): per layer chunk, the points (corners and centres), then the cells.
    fn encode_occupancy(&self, enc: &mut wgpu::CommandEncoder, jobs: &[OccJob]) {
        let wg = WG as u32;
        for job in jobs {
            let [i0, j0, i1, j1] = job.cols;
            // the corners are one more than the cells along x and y
            let points = [(i1 - i0 + 1).div_ceil(wg), (j1 - j0 + 1).div_ceil(wg), 2];
            let cells = [(i1 - i0).div_ceil(wg), (j1 - j0).div_ceil(wg), 1];
            for d in 0..job.dispatches {
                enc.copy_buffer_to_buffer(
                    &self.occ_chunks,
                    (job.first + d) * OCC_PASS_BYTES,
                    &self.occ_uniform,
                    0,
                    OCC_PASS_BYTES,
                );
                for (pipeline, [x, y, z]) in self.occ_pipelines.iter().zip([points, cells]) {
                    let mut cp = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                        label: Some("occupancy"),
                        timestamp_writes: None,
                    });
                    cp.set_pipeline(pipeline);
                    cp.set_bind_group(0, &self.occ_bind, &[]);
                    cp.dispatch_workgroups(x, y, z);
                }
            }
        }
    }

    /// Re-evaluate the occupancy grid over the cell columns under `rect` (everything for
    /// `None`) from the planes as they are, as `Composition::refresh_occupancy` does; the
    /// number of cells evaluated (0 with the grid off). Waits for the device.
    pub fn refresh_occupancy(&mut self, rect: Option<TexelRect>) -> Result<usize, GpuError> {
        pollster::block_on(async {
            let rect = rect.unwrap_or_else(|| self.full_rect());
            let jobs = self.prepare_occupancy(&[rect])?;
            if jobs.is_empty() {
                return Ok(0);
            }
            scoped(&self.device, "occupancy", || {
                let mut enc = self.device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
                    label: Some("occupancy"),
                });
                enc.clear_buffer(&self.status, 0, None);
                self.encode_occupancy(&mut enc, &jobs);
                enc.copy_buffer_to_buffer(&self.status, 0, &self.staging, 0, STATUS_BYTES);
                self.queue.submit([enc.finish()]);
            })
            .await?;
            self.check_status().await?;
            Ok(self.occupancy_job_cells(&jobs))
        })
    }

    /// Whether the composer keeps an occupancy grid and renders skip the cells it marks
    /// empty (the default).
    pub fn occupancy_enabled(&self) -> bool {
        self.occ_on
    }

    /// Turn the occupancy grid on (rebuilt at once from the planes as they are) or off
    /// (renders march every sample, rasterisations no longer touch the grid).
    pub fn set_occupancy(&mut self, on: bool) -> Result<(), GpuError> {
        if on == self.occ_on {
            return Ok(());
        }
        self.occ_on = on;
        self.renderer.set_occupancy_enabled(on);
        if on {
            self.refresh_occupancy(None)?;
        }
        Ok(())
    }

    /// Cells of the occupancy grid per axis (x, y, z).
    pub fn occupancy_res(&self) -> [usize; 3] {
        self.occ.res
    }

    /// The occupancy grid as it is on the device, one byte per cell (1 = occupied), x
    /// fastest, then y, then z (as `Occupancy::cells_u8`; `Occupancy::from_cells` makes it
    /// a grid again).
    pub fn occupancy_cells(&self) -> Result<Vec<u8>, GpuError> {
        let cells = self.occ.res.iter().product::<usize>();
        let bytes = (cells.div_ceil(32) * 4) as u64;
        pollster::block_on(async {
            let staging = scoped(&self.device, "occupancy readback", || {
                let staging = buffer(&self.device, "occupancy", bytes, U::MAP_READ | U::COPY_DST);
                let mut enc = self.device.create_command_encoder(&Default::default());
                enc.copy_buffer_to_buffer(self.renderer.occupancy_buffer(), 0, &staging, 0, bytes);
                self.queue.submit([enc.finish()]);
                staging
            })
            .await?;
            let view = map(&self.device, self.renderer.device_errors(), &staging, 0..bytes).await?;
            let words: &[u32] = bytemuck::cast_slice(&view);
            let out = (0..cells).map(|k| ((words[k / 32] >> (k % 32)) & 1) as u8).collect();
            drop(view);
            staging.unmap();
            Ok(out)
        })
    }

    /// Wait for the last rasterisation (or occupancy refresh) and refuse it if the driver
    /// cut its loops short.
    async fn check_status(&self) -> Result<(), GpuError> {
        let view = map(&self.device, self.renderer.device_errors(), &self.staging, 0..STATUS_BYTES)
            .await?;
        let word = |k: usize| u32::from_le_bytes([view[k], view[k + 1], view[k + 2], view[k + 3]]);
        let (raster, occupancy) = (word(0), word(8));
        drop(view);
        self.staging.unmap();
        if raster > 0 {
            return Err(GpuError::RasterLoopLimit { invocations: raster });
        }
        if occupancy > 0 {
            return Err(GpuError::OccupancyLoopLimit { invocations: occupancy });
        }
        Ok(())
    }

    /// Redraw the texels of `rect` (the whole grid for `None`) from the canvas and
    /// `layout`'s instances, as `Composition::rasterise` does; texels outside `rect` keep
    /// what they hold. Waits for the device.
    pub fn rasterise(
        &mut self,
        layout: &[PatchInstance],
        rect: Option<TexelRect>,
    ) -> Result<GpuRasterStats, GpuError> {
        pollster::block_on(async {
            let rect = rect.unwrap_or_else(|| self.full_rect());
            let stats = self.submit_raster(layout, rect, true).await?;
            if stats.dispatches > 0 {
                self.check_status().await?;
            }
            Ok(stats)
        })
    }

    /// Redraw the texels of each of `rects` (dirty rectangles, e.g. the old and new
    /// footprints of a moved instance) from the canvas and `layout`'s instances, in one wait
    /// for the device; the stats add up over the rectangles.
    pub fn rasterise_rects(
        &mut self,
        layout: &[PatchInstance],
        rects: &[TexelRect],
    ) -> Result<GpuRasterStats, GpuError> {
        pollster::block_on(async {
            let mut total = GpuRasterStats::default();
            let mut submitted = false;
            for r in rects {
                let s = self.submit_raster(layout, *r, !submitted).await?;
                submitted |= s.dispatches > 0;
                total.add(&s);
            }
            if submitted {
                self.check_status().await?;
            }
            Ok(total)
        })
    }

    /// Rasterise each layout over the whole grid in turn (with the occupancy refresh),
    /// without rendering, waiting for the device once at the end (the planes end as the
    /// last layout's). For timings.
    pub fn rasterise_only<L: AsRef<[PatchInstance]>>(
        &mut self,
        layouts: &[L],
    ) -> Result<GpuRasterStats, GpuError> {
        pollster::block_on(async {
            let full = self.full_rect();
            let mut total = GpuRasterStats::default();
            for (k, l) in layouts.iter().enumerate() {
                let s = self.submit_raster(l.as_ref(), full, k == 0).await?;
                total.add(&s);
            }
            // the counters add up over the layouts
            if !layouts.is_empty() {
                self.check_status().await?;
            }
            Ok(total)
        })
    }

    /// The composed planes as they are on the device: density `[rows][cols][nd]` and colour
    /// `[rows][cols][nc]`.
    pub fn planes(&self) -> Result<(Vec<f32>, Vec<f32>), GpuError> {
        pollster::block_on(async {
            let n = (self.grid.rows * self.grid.cols) as u64;
            let db = n * self.header.nd as u64 * 4;
            let cb = n * self.header.nc as u64 * 4;
            let staging = scoped(&self.device, "plane readback", || {
                let staging = buffer(&self.device, "planes", db + cb, U::MAP_READ | U::COPY_DST);
                let params = self.renderer.params_buffer();
                let mut enc = self.device.create_command_encoder(&Default::default());
                enc.copy_buffer_to_buffer(
                    params,
                    self.header.density_at as u64 * 4,
                    &staging,
                    0,
                    db,
                );
                enc.copy_buffer_to_buffer(
                    params,
                    self.header.color_at as u64 * 4,
                    &staging,
                    db,
                    cb,
                );
                self.queue.submit([enc.finish()]);
                staging
            })
            .await?;
            let view =
                map(&self.device, self.renderer.device_errors(), &staging, 0..db + cb).await?;
            let floats: &[f32] = bytemuck::cast_slice(&view);
            let out = (floats[..(db / 4) as usize].to_vec(), floats[(db / 4) as usize..].to_vec());
            drop(view);
            staging.unmap();
            Ok(out)
        })
    }

    /// Render the planes as they are: one `[height][width][3]` image per camera.
    pub fn render(&self, cameras: &[Camera], background: Vec3) -> Result<Vec<Vec<f32>>, GpuError> {
        self.renderer.render_batch(cameras, background)
    }

    /// For each layout, rasterise it over the whole grid and render every camera:
    /// `[layout][camera]` images of `[height][width][3]`. The rays are made once; each layout
    /// is one raster submission followed by the renderer's passes, and the images are the
    /// only data read back.
    pub fn render_layouts<L: AsRef<[PatchInstance]>>(
        &mut self,
        layouts: &[L],
        cameras: &[Camera],
        background: Vec3,
    ) -> Result<Vec<Vec<Vec<f32>>>, GpuError> {
        pollster::block_on(self.render_layouts_async(layouts, cameras, background))
    }

    /// [`GpuComposer::render_layouts`] as a future.
    pub async fn render_layouts_async<L: AsRef<[PatchInstance]>>(
        &mut self,
        layouts: &[L],
        cameras: &[Camera],
        background: Vec3,
    ) -> Result<Vec<Vec<Vec<f32>>>, GpuError> {
        let rays = rays_of(cameras);
        let full = self.full_rect();
        let mut out = Vec::with_capacity(layouts.len());
        for l in layouts {
            self.submit_raster(l.as_ref(), full, true).await?;
            let rgb = self.renderer.render_rays_async(&rays, background).await?;
            // the render waited for the device: the raster's status is there already
            self.check_status().await?;
            out.push(split_views(&rgb, cameras));
        }
        Ok(out)
    }
}
