//! Timings of the GPU composer next to the CPU one, on the composer benchmark's scene (a
//! 301 x 301 ground plane, 30 x 30 m at 0.1 m texels, 16 density + 48 colour channels, 1.2 m
//! patches at random places and yaws):
//! - full rasterisation of 100 and 1000 instances;
//! - 20 layouts of 50 instances, each rasterised and rendered at 64 x 64 (layouts per second;
//!   the random field is nearly empty, so every ray marches through the whole box).
//! - the occupancy grid (150 x 150 x 16 cells) rebuilt on the device and on the CPU.
//!
//! The GPU composer's occupancy grid is turned off for the first two, so both sides do the
//! same work (`render_view(.., None, ..)` on the CPU); `assetfield bench` times the composers
//! with their grids.
//!
//! Each figure is the median wall time of several runs, with the CPU time the process used
//! (all threads) per run: on a shared machine the latter says what the work costs.
//!
//! `cargo run --release -p assetfield-gpu --example compose_timing`

use assetfield_core::{Aabb3, Camera, GroundTransform, Intrinsics};
use assetfield_field::{Field, FieldConfig, ModelKind, render_view};
use assetfield_gpu::{GpuComposer, GpuContext, Layout, PatchInstance};
use assetfield_scene::{Composition, FeaturePatch, InstanceDraw, TexelRect};
use glam::{Vec2, Vec3};
use std::time::Instant;

struct Rng(u64);
impl Rng {
    fn f(&mut self) -> f32 {
        self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (self.0 >> 40) as f32 / (1u64 << 24) as f32
    }
}

fn layout(rng: &mut Rng, n: usize) -> Layout {
    (0..n)
        .map(|_| PatchInstance {
            patch: 0,
            transform: GroundTransform::new(
                Vec2::new(rng.f() * 28.0 - 14.0, rng.f() * 28.0 - 14.0),
                rng.f() * 360.0,
                1.0,
                0.0,
            ),
        })
        .collect()
}

/// CPU seconds this process has used (all threads), from /proc (Linux; 0 elsewhere).
fn cpu_seconds() -> f64 {
    let stat = std::fs::read_to_string("/proc/self/stat").unwrap_or_default();
    // the fields after the command name (in parentheses): utime and stime are 14 and 15
    let rest = stat.rsplit_once(')').map_or("", |(_, r)| r);
    let f: Vec<f64> = rest.split_whitespace().map(|v| v.parse().unwrap_or(0.0)).collect();
    if f.len() < 13 { 0.0 } else { (f[11] + f[12]) / 100.0 }
}

/// Median wall time of `runs` calls of `f`, and the mean CPU time (all threads) per call,
/// in seconds: the machine is shared, CPU time says what the work costs under contention.
fn median(runs: usize, mut f: impl FnMut()) -> (f64, f64) {
    let c0 = cpu_seconds();
    let mut t: Vec<f64> = (0..runs)
        .map(|_| {
            let t0 = Instant::now();
            f();
            t0.elapsed().as_secs_f64()
        })
        .collect();
    let cpu = (cpu_seconds() - c0) / runs as f64;
    t.sort_by(f64::total_cmp);
    (t[runs / 2], cpu)
}

fn ms((wall, cpu): (f64, f64)) -> String {
    format!("{:.1} ms (cpu time {:.1} ms)", wall * 1e3, cpu * 1e3)
}

fn main() {
    let ctx = match GpuContext::new() {
        Ok(c) => c,
        Err(e) => {
            eprintln!("SKIPPED: {e}");
            return;
        }
    };
    println!("adapter: {}", ctx.describe());
    let aabb = Aabb3::new(Vec3::new(-15.0, -15.0, 0.0), Vec3::new(15.0, 15.0, 2.0));
    let field = Field::new(FieldConfig::new(ModelKind::Standard, aabb, 301), 1);
    let mut comp = Composition::new(field).unwrap();
    let grid = comp.grid;
    let tensor = |name: &str| comp.field.params.tensor(name).unwrap();
    let rect = TexelRect { r0: 100, c0: 100, r1: 112, c1: 112 };
    let (patch, _) = FeaturePatch::cut(
        "chair",
        &grid,
        tensor("density.plane"),
        tensor("color.plane"),
        rect,
        |_, _| 1.0,
    )
    .unwrap();
    let templates = vec![patch];
    println!(
        "plane {} x {}, {} + {} channels, patch {} x {} texels",
        grid.rows, grid.cols, comp.nd, comp.nc, templates[0].rows, templates[0].cols
    );
    let t0 = Instant::now();
    let mut gpu = GpuComposer::new(&ctx, &comp, &templates).unwrap();
    println!("upload and pipelines: {:.2} s", t0.elapsed().as_secs_f64());
    let t_occ = median(5, || {
        gpu.refresh_occupancy(None).unwrap();
    });
    let t_cpu_occ = median(5, || {
        comp.refresh_occupancy(None);
    });
    println!(
        "occupancy grid {:?} rebuilt: gpu {}, cpu {}",
        gpu.occupancy_res(),
        ms(t_occ),
        ms(t_cpu_occ)
    );
    gpu.set_occupancy(false).unwrap();
    let mut rng = Rng(7);
    let one = TexelRect { r0: 0, c0: 0, r1: 1, c1: 1 };
    gpu.rasterise(&[], Some(one)).unwrap();
    let t_one = median(15, || {
        gpu.rasterise(&[], Some(one)).unwrap();
    });
    let t_empty = median(15, || {
        gpu.rasterise(&[], None).unwrap();
    });
    println!("gpu, one texel (a submission and its wait): {}", ms(t_one));
    println!("gpu, empty layout over the full plane (the canvas copied): {}", ms(t_empty));
    for n in [100usize, 1000] {
        let l = layout(&mut rng, n);
        let stats = gpu.rasterise(&l, None).unwrap(); // warm-up
        let t_gpu = median(15, || {
            gpu.rasterise(&l, None).unwrap();
        });
        let draws: Vec<InstanceDraw> =
            l.iter().map(|i| InstanceDraw::new(&i.transform, &templates[i.patch])).collect();
        let full = comp.full_rect();
        let t_cpu = median(15, || {
            comp.rasterise(full, &draws);
        });
        println!(
            "rasterise {n} instances (full plane; {} tile entries, longest list {}): gpu {}, \
             cpu {}",
            stats.entries,
            stats.max_list,
            ms(t_gpu),
            ms(t_cpu)
        );
    }
    let layouts: Vec<Layout> = (0..20).map(|_| layout(&mut rng, 50)).collect();
    let cam = Camera::look_at(
        Intrinsics::from_fov_x(64, 64, 0.9),
        Vec3::new(18.0, -14.0, 16.0),
        Vec3::new(0.0, 0.0, 0.5),
        Vec3::Z,
    );
    let cams = [cam];
    let bg = Vec3::ONE;
    gpu.render_layouts(&layouts[..1], &cams, bg).unwrap(); // warm-up
    let t_raster = median(3, || {
        gpu.rasterise_only(&layouts).unwrap();
    });
    let t_gpu = median(3, || {
        gpu.render_layouts(&layouts, &cams, bg).unwrap();
    });
    let t_render = median(3, || {
        for _ in &layouts {
            gpu.render(&cams, bg).unwrap();
        }
    });
    let t_cpu = median(3, || {
        for l in &layouts {
            let draws: Vec<InstanceDraw> =
                l.iter().map(|i| InstanceDraw::new(&i.transform, &templates[i.patch])).collect();
            comp.rasterise(comp.full_rect(), &draws);
            let _ = render_view(&comp.field, None, &cam, bg);
        }
    });
    let per = |(w, c): (f64, f64)| (w / 20.0, c / 20.0);
    println!("20 layouts x 50 instances, per layout:");
    println!("  gpu rasterise only: {}", ms(per(t_raster)));
    println!("  gpu render only (64x64, no occupancy grid): {}", ms(per(t_render)));
    println!("  gpu rasterise + render: {} = {:.2} layouts/s", ms(per(t_gpu)), 20.0 / t_gpu.0);
    println!("  cpu rasterise + render_view: {} = {:.2} layouts/s", ms(per(t_cpu)), 20.0 / t_cpu.0);
}
