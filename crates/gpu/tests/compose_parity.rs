//! The GPU composer against the CPU one (`assetfield_scene::Composition` and the ECS
//! `Composer`): the same canvas, templates and layouts rasterised by both (planes equal to
//! 1e-5), occupancy grids rebuilt by both after every edit (cells equal but for a few at the
//! threshold), composed scenes rendered by both with and without the grid (PSNR above
//! 45 dB), and a batch of layouts rendered like one layout at a time.

mod common;

use assetfield_core::{Aabb3, Camera, GroundTransform, Intrinsics, Rect2};
use assetfield_field::{DecoderKind, Field, FieldConfig, ModelKind, Occupancy, render_view};
use assetfield_gpu::{GpuComposer, GpuError, Layout, OCCUPANCY_THRESHOLD, PatchInstance};
use assetfield_scene::{
    Composer, Composition, DensityRule, FeaturePatch, InstanceDraw, InstanceOf, TexelRect,
};
use common::{compare, context_or_skip, spread, structured_field};
use glam::{Vec2, Vec3};
use std::sync::Arc;
use std::time::Instant;

const MAX_PLANE_DIFF: f32 = 1e-5;
const MIN_PSNR: f64 = 45.0;
/// Occupancy cells on which the device and the CPU may disagree (density within rounding
/// of the threshold), as a fraction of the grid.
const MAX_OCC_MISMATCH: f64 = 1e-3;

/// Who composes.
enum Backend<'a> {
    /// The CPU reference, `Composition::rasterise` and `render_view`.
    Cpu(Box<Composition>),
    Gpu(&'a mut GpuComposer),
}

impl Backend<'_> {
    /// Redraw `rect` (everything for `None`) with `layout`'s instances of `templates`.
    fn rasterise(&mut self, templates: &[FeaturePatch], layout: &Layout, rect: Option<TexelRect>) {
        match self {
            Backend::Cpu(comp) => {
                let draws: Vec<InstanceDraw> = layout
                    .iter()
                    .map(|i| InstanceDraw::new(&i.transform, &templates[i.patch]))
                    .collect();
                let rect = rect.unwrap_or_else(|| comp.full_rect());
                comp.rasterise(rect, &draws);
            }
            Backend::Gpu(g) => {
                g.rasterise(layout, rect).expect("GPU rasterise");
            }
        }
    }

    /// Density and colour planes.
    fn planes(&self) -> (Vec<f32>, Vec<f32>) {
        match self {
            Backend::Cpu(comp) => {
                let p = &comp.field.params;
                (
                    p.tensor("density.plane").unwrap().to_vec(),
                    p.tensor("color.plane").unwrap().to_vec(),
                )
            }
            Backend::Gpu(g) => g.planes().expect("plane readback"),
        }
    }

    /// `[layout][camera]` images of every layout drawn over the whole grid.
    fn render_layouts(
        &mut self,
        templates: &[FeaturePatch],
        layouts: &[Layout],
        cams: &[Camera],
        bg: Vec3,
    ) -> Vec<Vec<Vec<f32>>> {
        match self {
            Backend::Cpu(_) => layouts
                .iter()
                .map(|l| {
                    self.rasterise(templates, l, None);
                    let Backend::Cpu(comp) = &*self else { unreachable!() };
                    cams.iter().map(|c| render_view(&comp.field, None, c, bg)).collect()
                })
                .collect(),
            Backend::Gpu(g) => g.render_layouts(layouts, cams, bg).expect("GPU render"),
        }
    }
}

struct Rng(u64);

impl Rng {
    /// Uniform in [0, 1).
    fn f(&mut self) -> f32 {
        self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (self.0 >> 40) as f32 / (1u64 << 24) as f32
    }
}

fn plane<'a>(field: &'a Field, name: &str) -> &'a [f32] {
    field.params.tensor(name).unwrap()
}

fn smooth(x: f32) -> f32 {
    let t = x.clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// A random field (planes scaled up to ~N(0, 0.5^2)) and four templates with soft weights:
/// two cut from its planes (one not square, one with a core), one made by hand with its own
/// texel size and a pivot off its centre, one density-warped (taking the core along).
fn random_scene(nd: usize, nc: usize, res: usize) -> (Composition, Vec<FeaturePatch>) {
    let aabb = Aabb3::new(Vec3::new(-1.0, -1.0, 0.0), Vec3::new(1.0, 1.0, 0.8));
    let mut cfg = FieldConfig::new(ModelKind::Standard, aabb, res);
    cfg.density_channels = nd;
    cfg.color_channels = nc;
    let mut field = Field::new(cfg, 5);
    for name in ["density.plane", "color.plane"] {
        let s = field.params.spec(name).unwrap().clone();
        for v in &mut field.params.data[s.offset..s.offset + s.len] {
            *v *= 5.0;
        }
    }
    let comp = Composition::new(field).unwrap();
    let grid = comp.grid;
    let (d, c) = (plane(&comp.field, "density.plane"), plane(&comp.field, "color.plane"));
    let rect_a = TexelRect { r0: 10, c0: 6, r1: 22, c1: 22 };
    let (a, _) = FeaturePatch::cut("a", &grid, d, c, rect_a, |r, col| {
        let u = (col as f32 - 13.5) / 8.0;
        let v = (r as f32 - 15.5) / 6.0;
        smooth((1.0 - (u * u + v * v).sqrt()) * 3.0)
    })
    .unwrap();
    // a core (where its features are the whole column under the additive rule): the inner
    // part of its weight, soft at the edge
    let core = a.weight.iter().map(|w| ((w - 0.4) * 2.0).clamp(0.0, 1.0)).collect();
    let a = a.with_core(core).unwrap();
    let rect_b = TexelRect { r0: 25, c0: 25, r1: 34, c1: 34 };
    let (b, _) =
        FeaturePatch::cut(
            "b",
            &grid,
            d,
            c,
            rect_b,
            |r, col| {
                if (r + col) % 3 == 0 { 0.5 } else { 1.0 }
            },
        )
        .unwrap();
    let mut rng = Rng(3);
    let (rows, cols) = (7, 11);
    let mut rand = |n: usize, s: f32| (0..n).map(|_| (rng.f() - 0.5) * s).collect::<Vec<_>>();
    let density = rand(rows * cols * nd, 4.0);
    let color = rand(rows * cols * nc, 4.0);
    let weight = rand(rows * cols, 1.0).into_iter().map(|w| (w + 0.5).clamp(0.0, 1.0)).collect();
    let texel = grid.step * Vec2::new(0.7, 1.2);
    // its pivot off the patch centre: placed and turned about a point beside it
    let hand = FeaturePatch::new("hand", rows, cols, texel, density, color, weight)
        .unwrap()
        .with_origin(Vec2::new(0.12, -0.05));
    let warped = b.with_density_of(&a).unwrap();
    (comp, vec![a, b, hand, warped])
}

fn at(patch: usize, x: f32, y: f32, yaw: f32, scale: f32) -> PatchInstance {
    PatchInstance { patch, transform: GroundTransform::new(Vec2::new(x, y), yaw, scale, 0.0) }
}

/// Rotations (0, 37, 90, -120, 200 degrees), scales (0.7, 1.3), overlaps, instances partly
/// outside the canvas, every template.
fn layout_a() -> Layout {
    vec![
        at(0, -0.3, 0.2, 0.0, 1.0),
        at(1, -0.25, 0.3, 37.0, 1.3),
        at(2, -0.2, 0.1, 90.0, 0.7),
        at(3, 0.4, -0.4, -120.0, 1.0),
        at(0, 0.95, 0.5, 200.0, 1.3),
        at(1, -1.02, -0.9, 37.0, 0.7),
        at(2, 0.45, -0.35, 12.5, 1.0),
        at(0, -0.3, 0.2, 90.0, 1.0),
        at(3, 0.0, 0.98, 63.0, 1.3),
    ]
}

/// `layout_a` edited: two instances moved and turned, one removed, one added.
fn layout_b() -> Layout {
    let mut l = layout_a();
    l[2] = at(2, 0.1, -0.2, 37.0, 1.3);
    l[6] = at(1, 0.5, 0.55, 90.0, 0.7);
    l.remove(4);
    l.push(at(3, -0.6, -0.5, 300.0, 1.0));
    l
}

fn max_diff(a: &[f32], b: &[f32]) -> f32 {
    assert_eq!(a.len(), b.len());
    a.iter().zip(b).map(|(x, y)| (x - y).abs()).fold(0.0, f32::max)
}

fn planes_match(test: &str, nd: usize, nc: usize, res: usize, rule: DensityRule) {
    let Some(ctx) = context_or_skip(test) else { return };
    let (mut comp, templates) = random_scene(nd, nc, res);
    comp.density_rule = rule;
    let mut gpu = GpuComposer::new(ctx, &comp, &templates).expect("upload");
    let mut resumed =
        GpuComposer::new(ctx, &comp, &templates).expect("upload").with_raster_chunk(1);
    let canvas =
        (plane(&comp.field, "density.plane").to_vec(), plane(&comp.field, "color.plane").to_vec());
    let mut cpu = Backend::Cpu(Box::new(comp));
    let (a, b) = (layout_a(), layout_b());
    // the dirty rectangle of the edit: the old and new footprints of what changed
    let grid = gpu.grid();
    let footprint = |i: &PatchInstance| {
        grid.texels_of(InstanceDraw::new(&i.transform, &templates[i.patch]).world_bounds())
    };
    let dirty = [&a[2], &a[4], &a[6], &b[5], &b[8]]
        .into_iter()
        .map(footprint)
        .fold(TexelRect { r0: 0, c0: 0, r1: 0, c1: 0 }, |u, r| u.union(&r));
    let some = TexelRect { r0: 3, c0: 9, r1: 29, c1: 27 };
    let mut last: Option<(Vec<f32>, Vec<f32>)> = None;
    for (step, layout, rect) in
        [("full", &a, None), ("dirty", &b, Some(dirty)), ("rectangle", &a, Some(some))]
    {
        cpu.rasterise(&templates, layout, rect);
        let t0 = Instant::now();
        let stats = gpu.rasterise(layout, rect).expect("rasterise");
        let t_gpu = t0.elapsed().as_secs_f64();
        let rs = resumed.rasterise(layout, rect).expect("resumed rasterise");
        assert!(rs.dispatches > 1 && rs.dispatches == stats.max_list, "{rs:?} {stats:?}");
        let (cd, cc) = cpu.planes();
        let (gd, gc) = Backend::Gpu(&mut gpu).planes();
        let (dd, dc) = (max_diff(&cd, &gd), max_diff(&cc, &gc));
        eprintln!(
            "{test} {step}: max |cpu - gpu| density {dd:.2e} colour {dc:.2e}; {stats:?}, \
             gpu {t_gpu:.3} s"
        );
        assert!(dd < MAX_PLANE_DIFF && dc < MAX_PLANE_DIFF, "{test} {step}: {dd:.2e} {dc:.2e}");
        assert!(stats.instances >= 4 && stats.max_list >= 3, "{stats:?}");
        let (rd, rc) = resumed.planes().unwrap();
        assert_eq!((&rd, &rc), (&gd, &gc), "{test} {step}: resumed rasterisation");
        // the edit changed something
        let (pd, pc) = last.as_ref().unwrap_or(&canvas);
        assert!(max_diff(pd, &gd) > 0.01 && max_diff(pc, &gc) > 0.01, "{test} {step}: no change");
        last = Some((gd, gc));
    }
}

#[test]
fn planes_match_cpu() {
    planes_match("planes 10 + 12 channels", 10, 12, 48, DensityRule::Replace);
}

#[test]
fn planes_match_cpu_default_channels() {
    planes_match("planes 16 + 48 channels", 16, 48, 40, DensityRule::Replace);
}

/// Density features added to the canvas (as library compositions combine them).
#[test]
fn planes_match_cpu_additive_density() {
    planes_match("planes 10 + 12 channels, added", 10, 12, 40, DensityRule::Add);
}

/// The structured field of the GPU tests with its objects cut out as templates (soft
/// weights from their density) and removed from the canvas.
fn object_scene() -> (Composition, Vec<FeaturePatch>) {
    let field = structured_field(ModelKind::Standard, DecoderKind::Sh { degree: 1 });
    let comp = Composition::new(field.clone()).unwrap();
    let grid = comp.grid;
    let (d, c) = (plane(&field, "density.plane"), plane(&field, "color.plane"));
    let nd = comp.nd;
    let cut = |name: &str, lo: Vec2, hi: Vec2, ch: usize| {
        let rect = grid.texels_of(Rect2::new(lo, hi));
        let weight = |r: usize, col: usize| smooth(d[(r * grid.cols + col) * nd + ch] / 6.0);
        FeaturePatch::cut(name, &grid, d, c, rect, weight).unwrap().0
    };
    let templates = vec![
        cut("tall disc", Vec2::new(-0.8, 0.0), Vec2::new(-0.1, 0.7), 0),
        cut("glass", Vec2::new(0.0, 0.15), Vec2::new(0.6, 0.75), 1),
        cut("block", Vec2::new(0.1, -0.75), Vec2::new(0.8, -0.05), 0),
    ];
    // the canvas: the scene without its objects
    let mut empty = field;
    let spec = empty.params.spec("density.plane").unwrap().clone();
    for texel in empty.params.data[spec.offset..spec.offset + spec.len].chunks_exact_mut(nd) {
        texel[..3].fill(0.0);
    }
    (Composition::new(empty).unwrap(), templates)
}

fn object_layouts() -> Vec<Layout> {
    vec![
        vec![at(0, -0.45, 0.35, 0.0, 1.0), at(1, 0.3, 0.45, 0.0, 1.0), at(2, 0.45, -0.4, 0.0, 1.0)],
        vec![
            at(0, 0.4, 0.3, 37.0, 1.3),
            at(2, -0.4, -0.3, 90.0, 0.7),
            at(1, -0.2, -0.2, 200.0, 1.0),
            at(1, 0.0, 0.0, 20.0, 0.7),
        ],
        vec![at(2, 0.0, 0.1, 45.0, 1.0), at(0, 0.85, -0.85, 0.0, 1.3), at(2, 0.1, 0.2, 30.0, 0.7)],
    ]
}

fn object_cameras(res: u32) -> Vec<Camera> {
    let k = Intrinsics::from_fov_x(res, res, 0.9);
    let target = Vec3::new(0.0, 0.0, 0.3);
    [Vec3::new(2.2, 0.6, 1.6), Vec3::new(-0.6, -2.0, 1.9)]
        .into_iter()
        .map(|eye| Camera::look_at(k, eye, target, Vec3::Z))
        .collect()
}

#[test]
fn composed_renders_match_cpu() {
    let test = "composed renders";
    let Some(ctx) = context_or_skip(test) else { return };
    let (comp, templates) = object_scene();
    let mut gpu = GpuComposer::new(ctx, &comp, &templates).expect("upload");
    // every sample marched, as render_view(field, None, ..)
    gpu.set_occupancy(false).unwrap();
    assert!(!gpu.occupancy_enabled());
    let layouts = object_layouts();
    let cams = object_cameras(40);
    let bg = Vec3::new(1.0, 0.9, 0.8);
    let t0 = Instant::now();
    let cpu_views = Backend::Cpu(Box::new(comp)).render_layouts(&templates, &layouts, &cams, bg);
    let t_cpu = t0.elapsed().as_secs_f64();
    let t0 = Instant::now();
    let gpu_views = Backend::Gpu(&mut gpu).render_layouts(&templates, &layouts, &cams, bg);
    let t_gpu = t0.elapsed().as_secs_f64();
    for (l, (cv, gv)) in cpu_views.iter().zip(&gpu_views).enumerate() {
        let (psnr, max) = compare(&cv.concat(), &gv.concat());
        eprintln!(
            "{test}: layout {l}: PSNR {psnr:.1} dB, max |cpu - gpu| {:.2e} {:.2e} {:.2e}",
            max[0], max[1], max[2]
        );
        assert!(spread(&cv.concat()) > 0.05, "layout {l}: the reference images are flat");
        for (k, (c, g)) in cv.iter().zip(gv).enumerate() {
            let (p, _) = compare(c, g);
            assert!(p > MIN_PSNR, "layout {l} view {k}: PSNR {p:.1} dB");
        }
    }
    // the layouts differ from each other
    let (p01, _) = compare(&gpu_views[0].concat(), &gpu_views[1].concat());
    assert!(p01 < 30.0, "layouts 0 and 1 render alike ({p01:.1} dB)");
    eprintln!(
        "{test}: {} layouts x {} views 40x40: cpu {t_cpu:.2} s, gpu {t_gpu:.2} s",
        layouts.len(),
        cams.len()
    );
}

#[test]
fn a_batch_of_layouts_renders_like_one_at_a_time() {
    let Some(ctx) = context_or_skip("a_batch_of_layouts_renders_like_one_at_a_time") else {
        return;
    };
    let (comp, templates) = object_scene();
    let mut gpu = GpuComposer::new(ctx, &comp, &templates).expect("upload");
    let layouts = object_layouts();
    let cams = object_cameras(24);
    let batch = gpu.render_layouts(&layouts, &cams, Vec3::ONE).unwrap();
    assert_eq!(batch.len(), layouts.len());
    // one by one, in another order, and with the planes rasterised then rendered
    for l in [2, 0, 1] {
        let one = gpu.render_layouts(&layouts[l..=l], &cams, Vec3::ONE).unwrap();
        assert_eq!(one[0], batch[l], "layout {l}");
        gpu.rasterise(&layouts[l], None).unwrap();
        assert_eq!(gpu.render(&cams, Vec3::ONE).unwrap(), batch[l], "layout {l}");
    }
    let none: [Layout; 0] = [];
    assert!(gpu.render_layouts(&none, &cams, Vec3::ONE).unwrap().is_empty());
    // an empty layout is the canvas
    let empty = gpu.render_layouts(&[Layout::new()], &cams, Vec3::ONE).unwrap();
    let canvas = comp.clone();
    let mut blank = canvas;
    blank.rasterise(blank.full_rect(), &[]);
    let cpu: Vec<Vec<f32>> =
        cams.iter().map(|c| render_view(&blank.field, None, c, Vec3::ONE)).collect();
    let (psnr, _) = compare(&cpu.concat(), &empty[0].concat());
    assert!(psnr > MIN_PSNR, "{psnr}");
}

#[test]
fn bad_inputs_are_refused() {
    let Some(ctx) = context_or_skip("bad_inputs_are_refused") else { return };
    let (comp, templates) = random_scene(10, 12, 40);
    let mut gpu = GpuComposer::new(ctx, &comp, &templates).unwrap();
    let err = gpu.rasterise(&[at(7, 0.0, 0.0, 0.0, 1.0)], None).unwrap_err();
    assert!(matches!(err, GpuError::Input(_)), "{err}");
    let err = gpu.rasterise(&[at(0, 0.0, 0.0, 0.0, 0.0)], None).unwrap_err();
    assert!(matches!(err, GpuError::Input(_)), "{err}");
    let (_, other) = random_scene(16, 12, 40);
    let err = GpuComposer::new(ctx, &comp, &other).unwrap_err();
    assert!(matches!(err, GpuError::Input(_)), "{err}");
    eprintln!("{err}");
    // an empty rectangle writes nothing
    let s = gpu.rasterise(&layout_a(), Some(TexelRect { r0: 5, c0: 5, r1: 5, c1: 9 })).unwrap();
    assert_eq!(s.texels, 0);
}

/// A tile list longer than llvmpipe lets a dispatch walk: by default split over several
/// dispatches, right; forced into one dispatch, either the driver runs it all (hardware
/// GPUs) and the planes are right, or it cuts the loops short and the canary refuses the
/// planes; never wrong planes.
#[test]
fn loops_cut_short_are_detected() {
    let Some(ctx) = context_or_skip("loops_cut_short_are_detected") else { return };
    let (comp, templates) = random_scene(10, 12, 40);
    let n = 70_000;
    let layout: Layout = (0..n)
        .map(|i| at(i % 4, -0.3 + (i % 7) as f32 * 0.01, 0.2, (i % 360) as f32, 0.7))
        .collect();
    let rect = Some(TexelRect { r0: 16, c0: 16, r1: 24, c1: 24 });
    let mut gpu =
        GpuComposer::new(ctx, &comp, &templates).unwrap().with_unbounded_raster_chunk(1 << 20);
    let mut bounded = GpuComposer::new(ctx, &comp, &templates).unwrap();
    let mut cpu = Backend::Cpu(Box::new(comp));
    cpu.rasterise(&templates, &layout, rect);
    let (cd, cc) = cpu.planes();
    // close to the CPU's planes: sums of 70000 terms, in the same order
    let close = |(gd, gc): (Vec<f32>, Vec<f32>)| {
        let scale = cd.iter().chain(&cc).fold(1.0f32, |m, v| m.max(v.abs()));
        let d = max_diff(&cd, &gd).max(max_diff(&cc, &gc));
        eprintln!("max |cpu - gpu| {d:.2e} (largest value {scale:.1})");
        assert!(d < 1e-5 * scale, "{d} vs {scale}");
    };
    // bounded dispatches: the sums resumed over several of them
    let t0 = Instant::now();
    let stats = bounded.rasterise(&layout, rect).unwrap();
    eprintln!(
        "{n} instances, {} dispatches: {:.2} s",
        stats.dispatches,
        t0.elapsed().as_secs_f64()
    );
    let chunk = bounded.raster_chunk() as usize;
    assert_eq!((stats.dispatches, stats.max_list), (n.div_ceil(chunk), n));
    close(bounded.planes().unwrap());
    let t0 = Instant::now();
    let result = gpu.rasterise(&layout, rect);
    eprintln!("{n} instances in one dispatch: {:.2} s", t0.elapsed().as_secs_f64());
    match result {
        Ok(stats) => {
            assert_eq!((stats.dispatches, stats.max_list), (1, n));
            eprintln!("the driver ran every loop");
            close(gpu.planes().unwrap());
        }
        Err(e) => {
            eprintln!("{e}");
            assert!(matches!(e, GpuError::RasterLoopLimit { .. }), "{e}");
        }
    }
}

/// The footprint (texel rectangle) of an instance, as the CPU composer tracks it.
fn footprint(gpu: &GpuComposer, templates: &[FeaturePatch], i: &PatchInstance) -> TexelRect {
    gpu.grid().texels_of(InstanceDraw::new(&i.transform, &templates[i.patch]).world_bounds())
}

/// Cells on which two grids (bytes, 1 = occupied) disagree, and the fill of the first.
fn occ_mismatch(a: &[u8], b: &[u8]) -> (usize, f64) {
    assert_eq!(a.len(), b.len());
    let differ = a.iter().zip(b).filter(|(x, y)| x != y).count();
    let fill = a.iter().filter(|x| **x != 0).count() as f64 / a.len() as f64;
    (differ, fill)
}

/// The CPU composer (ECS) on `comp`'s canvas with templates `t0, t1, ..` and `layout`'s
/// instances keyed `i0, i1, ..`, one frame run.
fn cpu_composer(comp: &Composition, templates: &[FeaturePatch], layout: &Layout) -> Composer {
    let mut c = Composer::new(comp.clone());
    for (k, t) in templates.iter().enumerate() {
        c.set_template(&format!("t{k}"), "object", Arc::new(t.clone())).unwrap();
    }
    for (k, i) in layout.iter().enumerate() {
        c.spawn(&format!("i{k}"), &format!("t{}", i.patch), i.transform).unwrap();
    }
    c.update();
    c
}

/// Make the CPU composer's instances `i0, i1, ..` match `layout` (same length): moves,
/// turns and template swaps, then one frame (dirty rectangles and occupancy columns).
fn cpu_edit(c: &mut Composer, layout: &Layout) {
    for (k, i) in layout.iter().enumerate() {
        let e = c.find(&format!("i{k}")).unwrap();
        c.set_placement(e, i.transform).unwrap();
        let t = c.template(&format!("t{}", i.patch)).unwrap();
        if c.world.get::<InstanceOf>(e) != Some(&InstanceOf(t)) {
            c.world.entity_mut(e).insert(InstanceOf(t));
        }
    }
    c.update();
}

/// The CPU composer's occupancy grid as bytes.
fn cpu_grid(c: &Composer) -> Vec<u8> {
    c.composition().occupancy.as_ref().expect("a grid after the first render").cells_u8()
}

/// The composed scene edited in steps (a full layout, then moves, a turn, a template swap),
/// on the CPU composer (ECS: dirty rectangles, `Occupancy::update_region`) and on the GPU
/// (`rasterise_rects` over the old and new footprints, the occupancy pass over their
/// columns): after every step, the occupancy grids agree but for a few cells at the
/// threshold, and the renders (both skipping empty cells) agree above 45 dB.
#[test]
fn composed_renders_with_occupancy_match_the_cpu_composer() {
    let test = "composed renders with occupancy";
    let Some(ctx) = context_or_skip(test) else { return };
    let (comp, templates) = object_scene();
    let mut gpu = GpuComposer::new(ctx, &comp, &templates).expect("upload");
    assert!(gpu.occupancy_enabled());
    let res = gpu.occupancy_res();
    assert_eq!(res, [20, 20, 16], "half the field's resolution, as the CPU composer");
    let cams = object_cameras(40);
    let bg = Vec3::new(1.0, 0.9, 0.8);
    let base = object_layouts()[0].clone();
    // the same instances edited: moves, a turn, a template swap, a scale
    let mut steps = vec![base.clone()];
    let mut l = base.clone();
    l[0] = at(0, -0.2, 0.5, 30.0, 1.0);
    steps.push(l.clone());
    l[2] = at(1, 0.5, -0.45, 120.0, 1.0);
    steps.push(l.clone());
    l[1] = at(2, -0.5, -0.5, 200.0, 1.3);
    steps.push(l);
    let mut cpu = cpu_composer(&comp, &templates, &steps[0]);
    gpu.rasterise(&steps[0], None).unwrap();
    let mut prev: Option<(Layout, Vec<Vec<f32>>)> = None;
    for (k, layout) in steps.iter().enumerate() {
        let mut gstats = None;
        if let Some((before, _)) = &prev {
            cpu_edit(&mut cpu, layout);
            let rects: Vec<TexelRect> = before
                .iter()
                .zip(layout)
                .filter(|(a, b)| a != b)
                .flat_map(|(a, b)| [footprint(&gpu, &templates, a), footprint(&gpu, &templates, b)])
                .collect();
            gstats = Some(gpu.rasterise_rects(layout, &rects).unwrap());
        }
        let t0 = Instant::now();
        let cv: Vec<Vec<f32>> = cams.iter().map(|c| cpu.render(c, bg)).collect();
        let t_cpu = t0.elapsed().as_secs_f64();
        let t0 = Instant::now();
        let gv = gpu.render(&cams, bg).unwrap();
        let t_gpu = t0.elapsed().as_secs_f64();
        let (gc, cc) = (gpu.occupancy_cells().unwrap(), cpu_grid(&cpu));
        let (differ, fill) = occ_mismatch(&cc, &gc);
        let (psnr, max) = compare(&cv.concat(), &gv.concat());
        eprintln!(
            "{test}: step {k}: grid {res:?} fill {fill:.3}, {differ} cells differ; PSNR {psnr:.1} \
             dB, max |cpu - gpu| {:.2e}; cpu {t_cpu:.3} s, gpu {t_gpu:.3} s; {gstats:?}",
            max.iter().fold(0.0f32, |a, b| a.max(*b)),
        );
        assert!(fill > 0.02 && fill < 0.6, "step {k}: the grid should skip space ({fill})");
        assert!(
            (differ as f64) <= MAX_OCC_MISMATCH * cc.len() as f64,
            "step {k}: {differ} of {} cells differ",
            cc.len()
        );
        assert!(spread(&cv.concat()) > 0.05, "step {k}: the reference images are flat");
        for (v, (c, g)) in cv.iter().zip(&gv).enumerate() {
            let (p, _) = compare(c, g);
            assert!(p > MIN_PSNR, "step {k} view {v}: PSNR {p:.1} dB");
        }
        if let Some((_, before)) = &prev {
            let (p, _) = compare(&before.concat(), &gv.concat());
            assert!(p < 40.0, "step {k}: the edit changed nothing ({p:.1} dB)");
        }
        prev = Some((layout.clone(), gv));
    }
    // the whole layout rasterised and rendered in one batch: the same as the edits
    let (last, edited) = prev.unwrap();
    let batch = gpu.render_layouts(&[last], &cams, bg).unwrap();
    let (psnr, _) = compare(&edited.concat(), &batch[0].concat());
    assert!(psnr > 80.0, "batch vs edited: {psnr:.1} dB");
}

/// The grid on the device against `Occupancy::from_field` on the CPU's planes, for a full
/// rasterisation, after which the grid is turned off (renders then equal those without a
/// grid) and on again (rebuilt); its passes split over many dispatches give the same grid.
#[test]
fn the_device_grid_matches_a_full_cpu_rebuild() {
    let test = "device occupancy grid";
    let Some(ctx) = context_or_skip(test) else { return };
    let (comp, templates) = object_scene();
    let layout = object_layouts()[1].clone();
    let mut gpu = GpuComposer::new(ctx, &comp, &templates).expect("upload");
    let res = gpu.occupancy_res();
    // the empty canvas: the composer builds its grid on upload
    let mut blank = comp.clone();
    blank.rasterise(blank.full_rect(), &[]);
    let cpu_blank = Occupancy::from_field(&blank.field, res, OCCUPANCY_THRESHOLD).cells_u8();
    let (differ, fill) = occ_mismatch(&cpu_blank, &gpu.occupancy_cells().unwrap());
    eprintln!("{test}: canvas: fill {fill:.3}, {differ} cells differ");
    assert!((differ as f64) <= MAX_OCC_MISMATCH * cpu_blank.len() as f64);
    let stats = gpu.rasterise(&layout, None).unwrap();
    assert_eq!(stats.occupancy_cells, res.iter().product::<usize>());
    let mut cpu = comp.clone();
    let draws: Vec<InstanceDraw> =
        layout.iter().map(|i| InstanceDraw::new(&i.transform, &templates[i.patch])).collect();
    cpu.rasterise(cpu.full_rect(), &draws);
    let cpu_occ = Occupancy::from_field(&cpu.field, res, OCCUPANCY_THRESHOLD);
    let gpu_cells = gpu.occupancy_cells().unwrap();
    let (differ, fill) = occ_mismatch(&cpu_occ.cells_u8(), &gpu_cells);
    eprintln!("{test}: layout: fill {fill:.3}, {differ} cells differ");
    assert!((differ as f64) <= MAX_OCC_MISMATCH * gpu_cells.len() as f64);
    assert!(fill < 0.6 && fill > cpu_blank.iter().filter(|c| **c != 0).count() as f64 / 6400.0);
    let cams = object_cameras(24);
    let with_grid = gpu.render(&cams, Vec3::ONE).unwrap();
    // off: every sample marched; the render matches the CPU without a grid
    gpu.set_occupancy(false).unwrap();
    let without = gpu.render(&cams, Vec3::ONE).unwrap();
    let cpu_none: Vec<Vec<f32>> =
        cams.iter().map(|c| render_view(&cpu.field, None, c, Vec3::ONE)).collect();
    let (p_none, _) = compare(&cpu_none.concat(), &without.concat());
    let cpu_grid: Vec<Vec<f32>> =
        cams.iter().map(|c| render_view(&cpu.field, Some(&cpu_occ), c, Vec3::ONE)).collect();
    let (p_grid, _) = compare(&cpu_grid.concat(), &with_grid.concat());
    eprintln!("{test}: PSNR without a grid {p_none:.1} dB, with {p_grid:.1} dB");
    assert!(p_none > MIN_PSNR && p_grid > MIN_PSNR);
    // edits while off leave the grid alone; turning it on rebuilds it
    let s = gpu.rasterise(&object_layouts()[2], None).unwrap();
    assert_eq!(s.occupancy_cells, 0);
    gpu.set_occupancy(true).unwrap();
    gpu.rasterise(&layout, None).unwrap();
    assert_eq!(gpu.occupancy_cells().unwrap(), gpu_cells);
    assert_eq!(gpu.render(&cams, Vec3::ONE).unwrap(), with_grid);
    // an explicit refresh over a rectangle changes nothing when the planes did not change
    let n = gpu.refresh_occupancy(Some(TexelRect { r0: 3, c0: 5, r1: 17, c1: 30 })).unwrap();
    assert!(n > 0 && n < gpu_cells.len());
    assert_eq!(gpu.occupancy_cells().unwrap(), gpu_cells);
}

/// Occupancy passes split over many dispatches give the same grid; a field so tall that a
/// column's cells take more loop iterations than llvmpipe allows is split by default (right
/// grid) and, forced into one dispatch, either runs (hardware GPUs: the same grid) or is
/// refused by the canary; never a wrong grid.
#[test]
fn occupancy_passes_split_and_loops_cut_short_are_detected() {
    let test = "occupancy passes";
    let Some(ctx) = context_or_skip(test) else { return };
    let (comp, templates) = object_scene();
    let layout = object_layouts()[0].clone();
    let mut whole = GpuComposer::new(ctx, &comp, &templates).unwrap();
    let mut split = GpuComposer::new(ctx, &comp, &templates).unwrap().with_occupancy_layers(3);
    assert_eq!(split.occupancy_layers(), 3);
    assert!(whole.occupancy_layers() >= 16, "{}", whole.occupancy_layers());
    whole.rasterise(&layout, None).unwrap();
    split.rasterise(&layout, None).unwrap();
    assert_eq!(whole.occupancy_cells().unwrap(), split.occupancy_cells().unwrap());
    // a tall thin field: 8 x 8 texels, 16000 samples along z, 23 density channels (a
    // layer of points costs the occupancy pass 11 loop iterations)
    let aabb = Aabb3::new(Vec3::new(-1.0, -1.0, 0.0), Vec3::new(1.0, 1.0, 3.0));
    let mut cfg = FieldConfig::new(ModelKind::Standard, aabb, 8);
    let nd = 23;
    cfg.density_channels = nd;
    cfg.color_channels = 8;
    cfg.res = [8, 8, 16000];
    let mut field = Field::new(cfg, 3);
    let s = field.params.spec("density.plane").unwrap().clone();
    for v in &mut field.params.data[s.offset..s.offset + s.len] {
        *v = 1.0;
    }
    let s = field.params.spec("density.axis").unwrap().clone();
    for (k, v) in field.params.data[s.offset..s.offset + s.len].iter_mut().enumerate() {
        // slabs of density here and there along z
        *v = if (k / nd) % 97 < 10 { 0.9 } else { -0.5 };
    }
    let tall = Composition::new(field).unwrap();
    let bounded = GpuComposer::new(ctx, &tall, &[]).unwrap();
    assert_eq!(bounded.occupancy_res(), [8, 8, 8000]);
    let layers = bounded.occupancy_layers();
    assert!(layers < 8000, "{layers} layers per dispatch");
    let mut blank = tall.clone();
    blank.rasterise(blank.full_rect(), &[]);
    let cpu = Occupancy::from_field(&blank.field, [8, 8, 8000], OCCUPANCY_THRESHOLD).cells_u8();
    let cells = bounded.occupancy_cells().unwrap();
    let (differ, fill) = occ_mismatch(&cpu, &cells);
    eprintln!("{test}: tall field, {layers} layers per dispatch: fill {fill:.3}, {differ} differ");
    assert!(fill > 0.05 && fill < 0.5, "{fill}");
    assert!((differ as f64) <= MAX_OCC_MISMATCH * cpu.len() as f64);
    let mut forced =
        GpuComposer::new(ctx, &tall, &[]).unwrap().with_unbounded_occupancy_layers(8000);
    match forced.refresh_occupancy(None) {
        Ok(n) => {
            assert_eq!(n, 8 * 8 * 8000);
            eprintln!("{test}: the driver ran every loop");
            assert_eq!(forced.occupancy_cells().unwrap(), cells);
        }
        Err(e) => {
            eprintln!("{test}: {e}");
            assert!(matches!(e, GpuError::OccupancyLoopLimit { .. }), "{e}");
        }
    }
}
