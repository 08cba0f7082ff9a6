//! A composed scene for benchmarks (`assetfield bench render|reconfigure`, the criterion
//! bench `render_gpu`), the same for the CPU composer and the GPU one: a canvas, templates,
//! random layouts and edits of them, and a camera.
//!
//! [`BenchScene::synthetic`] builds one without any files: a 30 x 30 x 2 m box (ground
//! planes of 301 x 301 texels of 0.1 m, 16 density + 48 colour channels, an MLP decoder,
//! all of it randomly initialised), whose canvas is an opaque floor slab 0.1 m thick and
//! empty space above it (every density feature zero but the floor's), and two templates
//! standing on the floor: a "chair" (a soft disc 0.9 m across, 0.9 m tall, density
//! `softplus(2.5)` so rays cross it in about 20 samples) and a "table" (0.8 x 1.6 m top at
//! 0.65-0.8 m on a pedestal). Colour features are random, scaled so the decoder sees varied
//! inputs; each template has its own. A ray is stopped by the floor (or earlier by
//! furniture), so the march does real work (empty space, furniture, floor) and ends.

use crate::{Layout, PatchInstance};
use assetfield_core::{Aabb3, Camera, GroundTransform, Rect2};
use assetfield_core::{Orbit, fitting_radius};
use assetfield_field::{Field, FieldConfig, ModelKind};
use assetfield_scene::{Composition, FeaturePatch, InstanceDraw, SceneError, TexelRect};
use glam::{Vec2, Vec3};

/// SplitMix64: a tiny seeded generator (the project's choice for reproducible layouts).
#[derive(Debug, Clone)]
pub struct SplitMix(u64);

impl SplitMix {
    pub fn new(seed: u64) -> Self {
        SplitMix(seed)
    }

    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1).
    pub fn f32(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 / (1u64 << 24) as f32
    }

    /// Uniform in [lo, hi).
    pub fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.f32()
    }

    /// Standard normal (Box-Muller).
    pub fn normal(&mut self) -> f32 {
        let u = self.f32().max(1e-7);
        let v = self.f32();
        (-2.0 * u.ln()).sqrt() * (std::f32::consts::TAU * v).cos()
    }
}

/// A canvas, templates and where instances may stand.
#[derive(Debug, Clone)]
pub struct BenchScene {
    /// The canvas and the field (shared axes and decoders) that renders the composition.
    pub composition: Composition,
    /// Templates, by the index [`PatchInstance::patch`] names.
    pub templates: Vec<FeaturePatch>,
    /// Where instance centres are placed (world XY).
    pub region: Rect2,
    pub background: Vec3,
    /// One line saying what the scene is.
    pub description: String,
}

fn smoothstep(x: f32) -> f32 {
    let t = x.clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

impl BenchScene {
    /// A scene from a composition and templates: instances are placed where their patches
    /// stay on the canvas.
    pub fn new(
        composition: Composition,
        templates: Vec<FeaturePatch>,
        background: Vec3,
        description: String,
    ) -> Self {
        let world = composition.grid.world_rect();
        let reach = templates.iter().map(|t| t.half_extent().length()).fold(0.0f32, f32::max);
        let margin = Vec2::splat(reach).min(world.size() * 0.25);
        let region = Rect2::new(world.min + margin, world.max - margin);
        BenchScene { composition, templates, region, background, description }
    }

    /// The synthetic scene described in the module's documentation; `seed` draws the
    /// field's random initialisation and the templates' colours.
    pub fn synthetic(seed: u64) -> Result<Self, SceneError> {
        let aabb = Aabb3::new(Vec3::new(-15.0, -15.0, 0.0), Vec3::new(15.0, 15.0, 2.0));
        let cfg = FieldConfig::new(ModelKind::Standard, aabb, 301);
        let mut field = Field::new(cfg, seed);
        let nz = field.config.res[2];
        let voxel_z = aabb.extent().z / (nz - 1) as f32;
        let spec = |f: &Field, name: &str| f.params.spec(name).expect("a standard field").clone();
        let (dp, da) = (spec(&field, "density.plane"), spec(&field, "density.axis"));
        let nd = dp.shape[2];
        let data = &mut field.params.data;
        // density plane: channel 0 (the floor) everywhere, nothing else on the canvas
        for texel in data[dp.offset..dp.offset + dp.len].chunks_exact_mut(nd) {
            texel.fill(0.0);
            texel[0] = 1.0;
        }
        // density axis: 0 floor (features 16 and 8 on the two lowest samples), 1 chairs
        // (up to 0.9 m), 2 table tops (0.65 to 0.8 m), 3 pedestals (up to 0.8 m)
        for (k, row) in data[da.offset..da.offset + da.len].chunks_exact_mut(nd).enumerate() {
            let z = k as f32 * voxel_z;
            row.fill(0.0);
            row[0] = match k {
                0 => 16.0,
                1 => 8.0,
                _ => 0.0,
            };
            row[1] = f32::from(z <= 0.9);
            row[2] = f32::from((0.65..=0.8).contains(&z));
            row[3] = f32::from(z <= 0.8);
        }
        // colour grids: features of order 1
        for name in ["color.plane", "color.axis"] {
            let s = spec(&field, name);
            for v in &mut field.params.data[s.offset..s.offset + s.len] {
                *v *= 10.0;
            }
        }
        let composition = Composition::new(field)?;
        let (nd, nc) = (composition.nd, composition.nc);
        let texel = composition.grid.step;
        let mut rng = SplitMix::new(seed ^ 0x5EED);
        let mut patch = |name: &str, rows: usize, cols: usize, shape: &dyn Fn(Vec2) -> [f32; 4]| {
            let colour: Vec<f32> = (0..nc).map(|_| rng.normal()).collect();
            let n = rows * cols;
            let (mut d, mut c, mut w) =
                (vec![0.0; n * nd], Vec::with_capacity(n * nc), vec![0.0; n]);
            for r in 0..rows {
                for col in 0..cols {
                    // the texel's position in the patch frame (centre at 0)
                    let q = Vec2::new(
                        (col as f32 - (cols - 1) as f32 * 0.5) * texel.x,
                        (r as f32 - (rows - 1) as f32 * 0.5) * texel.y,
                    );
                    let [weight, d1, d2, d3] = shape(q);
                    let k = r * cols + col;
                    w[k] = weight;
                    d[k * nd..k * nd + 4].copy_from_slice(&[1.0, d1, d2, d3]);
                    c.extend_from_slice(&colour);
                }
            }
            FeaturePatch::new(name, rows, cols, texel, d, c, w)
        };
        let chair = patch("chair", 13, 13, &|q| {
            let r = q.length();
            [smoothstep((0.6 - r) / 0.15), 12.5 * smoothstep((0.45 - r) / 0.08), 0.0, 0.0]
        })?;
        let table = patch("table", 11, 19, &|q| {
            let edge = (0.9 - q.x.abs()).min(0.5 - q.y.abs());
            let top = smoothstep((0.8 - q.x.abs()).min(0.4 - q.y.abs()) / 0.05);
            [smoothstep(edge / 0.1), 0.0, 13.0 * top, 13.0 * smoothstep((0.12 - q.length()) / 0.04)]
        })?;
        let description = format!(
            "synthetic: 30 x 30 x 2 m box, {} x {} texels of 0.1 m, {nd} + {nc} channels, MLP \
             decoder (random); a floor slab; templates chair (0.9 m disc, 0.9 m tall) and table \
             (0.8 x 1.6 m top on a pedestal)",
            composition.grid.cols, composition.grid.rows
        );
        Ok(BenchScene::new(composition, vec![chair, table], Vec3::ONE, description))
    }

    /// The scene's box.
    pub fn aabb(&self) -> Aabb3 {
        self.composition.field.config.aabb()
    }

    /// `views` cameras of `res x res` pixels on an orbit around the box, 35 degrees up,
    /// 40 degree field of view, close enough that the ground fills most of the view; the
    /// first 55 degrees clockwise of +X, the others 360 / `views` degrees apart.
    pub fn cameras(&self, views: usize, res: u32) -> Vec<Camera> {
        let aabb = self.aabb();
        let mut orbit = Orbit::around(&aabb, views, res);
        orbit.elevation_deg = 35.0;
        orbit.start_deg = -55.0;
        orbit.radius = 0.7 * fitting_radius(&aabb, orbit.fov_deg);
        orbit.cameras()
    }

    /// `n` instances at uniform places in the region, uniform yaws, the templates in turn
    /// (two chairs for every table in the synthetic scene).
    pub fn random_layout(&self, n: usize, rng: &mut SplitMix) -> Layout {
        let r = self.region;
        let kinds = self.templates.len().max(1);
        (0..n)
            .map(|i| PatchInstance {
                patch: if kinds == 2 { usize::from(i % 3 == 2) } else { i % kinds },
                transform: GroundTransform::new(
                    Vec2::new(rng.range(r.min.x, r.max.x), rng.range(r.min.y, r.max.y)),
                    rng.range(0.0, 360.0),
                    1.0,
                    0.0,
                ),
            })
            .collect()
    }

    /// An edit of every instance of `layout`: moved by up to 1.5 m (kept in the region),
    /// turned by up to 45 degrees, and one in four swapped between templates 0 and 1.
    pub fn edit(&self, layout: &[PatchInstance], rng: &mut SplitMix) -> Layout {
        let r = self.region;
        layout
            .iter()
            .map(|i| {
                let t = &i.transform;
                let p = Vec2::new(
                    (t.position.x + rng.range(-1.5, 1.5)).clamp(r.min.x, r.max.x),
                    (t.position.y + rng.range(-1.5, 1.5)).clamp(r.min.y, r.max.y),
                );
                let yaw = (t.yaw_deg + rng.range(-45.0, 45.0)).rem_euclid(360.0);
                let swap = self.templates.len() >= 2 && i.patch < 2 && rng.f32() < 0.25;
                PatchInstance {
                    patch: if swap { 1 - i.patch } else { i.patch },
                    transform: GroundTransform::new(p, yaw, t.scale, t.base),
                }
            })
            .collect()
    }

    /// The texels an instance reaches (as the CPU composer tracks its footprint).
    pub fn footprint(&self, i: &PatchInstance) -> TexelRect {
        let draw = InstanceDraw::new(&i.transform, &self.templates[i.patch]);
        self.composition.grid.texels_of(draw.world_bounds())
    }

    /// The texels to redraw when `before` becomes `after` (same length): the old and new
    /// footprints of every changed instance, overlapping ones merged (as the CPU composer
    /// merges its dirty rectangles).
    pub fn dirty_rects(&self, before: &[PatchInstance], after: &[PatchInstance]) -> Vec<TexelRect> {
        TexelRect::merge_overlapping(
            before
                .iter()
                .zip(after)
                .filter(|(a, b)| a != b)
                .flat_map(|(a, b)| [self.footprint(a), self.footprint(b)])
                .collect(),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_synthetic_scene_has_a_floor_and_two_templates() {
        let s = BenchScene::synthetic(1).unwrap();
        assert_eq!(s.templates.len(), 2);
        assert_eq!((s.composition.grid.rows, s.composition.grid.cols), (301, 301));
        let f = &s.composition.field;
        // the floor is dense, the air above it empty
        assert!(f.density(Vec3::new(3.0, -2.0, 0.02)) > 1.0);
        assert!(f.density(Vec3::new(3.0, -2.0, 0.5)) < 1e-3);
        let mut rng = SplitMix::new(3);
        let a = s.random_layout(30, &mut rng);
        assert_eq!(a.iter().filter(|i| i.patch == 1).count(), 10);
        assert!(a.iter().all(|i| s.region.contains(i.transform.position)));
        let b = s.edit(&a, &mut rng);
        assert!(b.iter().all(|i| s.region.contains(i.transform.position)));
        assert!(a.iter().zip(&b).any(|(x, y)| x.patch != y.patch));
        let one: Vec<PatchInstance> =
            a.iter().enumerate().map(|(k, i)| if k == 0 { b[0] } else { *i }).collect();
        let rects = s.dirty_rects(&a, &one);
        assert!(!rects.is_empty() && rects.len() <= 2);
        assert!(s.dirty_rects(&a, &a).is_empty());
        assert_eq!(s.cameras(2, 16).len(), 2);
    }
}
