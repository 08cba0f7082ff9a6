//! The ground-truth renderer: a two-level BVH (instances, then each asset's shapes), a fixed
//! directional light with Lambert shading plus ambient light, optional hard shadows,
//! stratified anti-aliasing and a transparent background (or, for photographs, a background
//! colour per direction); rows in parallel with rayon.

use crate::assets::AssetSet;
use crate::bvh::Bvh;
use crate::geometry::AssetGeometry;
use assetfield_core::{Aabb3, Camera};
use assetfield_layout::{Lighting, ResolvedLayout};
use glam::{Affine3A, Mat3A, Vec3};
use rayon::prelude::*;
use std::sync::Arc;

/// Light settings of the ground-truth renderer.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Light {
    /// Unit direction towards the light.
    pub direction: Vec3,
    /// Fraction of light that reaches every surface regardless of orientation.
    pub ambient: f32,
    /// Hard shadows. Off by default: a neural field bakes shadows into the surfaces they fall
    /// on, so a moved object would leave its shadow behind in composed renders, and ground
    /// truth of edited layouts could not be matched.
    pub shadows: bool,
}

impl Default for Light {
    fn default() -> Self {
        Light { direction: Vec3::new(0.35, 0.25, 1.0).normalize(), ambient: 0.35, shadows: false }
    }
}

impl Light {
    pub fn from_script(l: Option<&Lighting>) -> Self {
        let mut out = Light::default();
        if let Some(l) = l {
            if let Some(d) = l.direction {
                out.direction = Vec3::new(d.0, d.1, d.2).normalize_or(out.direction);
            }
            if let Some(a) = l.ambient {
                out.ambient = a.clamp(0.0, 1.0);
            }
            if let Some(s) = l.shadows {
                out.shadows = s;
            }
        }
        out
    }
}

#[derive(Debug, Clone)]
struct Placed {
    geometry: Arc<AssetGeometry>,
    to_local: Affine3A,
    rotation: Mat3A,
}

/// A surface hit in world space.
#[derive(Debug, Clone, Copy)]
pub struct Hit {
    pub t: f32,
    /// Unit world normal facing the incoming ray.
    pub normal: Vec3,
    pub color: Vec3,
}

/// A renderable scene: placed asset geometry under an instance BVH.
#[derive(Debug, Clone)]
pub struct Scene {
    placed: Vec<Placed>,
    top: Bvh,
    pub light: Light,
}

impl Scene {
    /// Place every instance of a resolved layout (containers included).
    pub fn new(layout: &ResolvedLayout, assets: &AssetSet, light: Light) -> Self {
        let mut placed = Vec::new();
        let mut boxes = Vec::new();
        for inst in &layout.instances {
            let Some(g) = assets.geometry.get(&inst.asset) else { continue };
            let world = inst.transform.to_affine();
            let local_b = g.bounds();
            let wb = local_b.corners().iter().fold(Aabb3::EMPTY, |mut b, c| {
                b.grow(world.transform_point3(*c));
                b
            });
            boxes.push(wb);
            placed.push(Placed {
                geometry: g.clone(),
                to_local: world.inverse(),
                rotation: Mat3A::from_rotation_z(inst.transform.yaw_deg.to_radians()),
            });
        }
        Scene { top: Bvh::build(&boxes), placed, light }
    }

    /// World bounds of everything in the scene.
    pub fn bounds(&self) -> Aabb3 {
        self.top.bounds()
    }

    /// Nearest hit along a ray (unit direction).
    pub fn trace(&self, o: Vec3, d: Vec3, t_max: f32) -> Option<Hit> {
        let mut best = None;
        self.top.traverse(o, d, t_max, |i, tm| {
            let p = &self.placed[i as usize];
            let h = p.geometry.intersect(
                p.to_local.transform_point3(o),
                p.to_local.transform_vector3(d),
                tm,
            )?;
            best = Some((h, i));
            Some(h.t)
        })?;
        let (h, i) = best?;
        let mut n = (self.placed[i as usize].rotation * glam::Vec3A::from(h.normal)).normalize();
        if n.dot(d.into()) > 0.0 {
            n = -n;
        }
        Some(Hit { t: h.t, normal: n.into(), color: h.color })
    }

    /// Shaded colour along a ray, `None` for the background.
    pub fn shade(&self, o: Vec3, d: Vec3) -> Option<Vec3> {
        let h = self.trace(o, d, f32::INFINITY)?;
        let l = &self.light;
        let mut diffuse = h.normal.dot(l.direction).max(0.0);
        if l.shadows && diffuse > 0.0 {
            let p = o + d * h.t + h.normal * 1e-3;
            if self.trace(p, l.direction, f32::INFINITY).is_some() {
                diffuse = 0.0;
            }
        }
        Some(h.color * (l.ambient + (1.0 - l.ambient) * diffuse))
    }

    /// Render a view over a background: linear colour per pixel (row-major, not clamped),
    /// the mean of `samples_per_side^2` stratified samples, where a sample that hits nothing
    /// takes `background(direction)`. What a photograph sees: no alpha.
    pub fn render_over(
        &self,
        camera: &Camera,
        samples_per_side: u32,
        background: &(dyn Fn(Vec3) -> Vec3 + Sync),
    ) -> Vec<Vec3> {
        let (w, h) = (camera.intrinsics.width as usize, camera.intrinsics.height as usize);
        let n = samples_per_side.max(1);
        let mut out = vec![Vec3::ZERO; w * h];
        out.par_chunks_mut(w.max(1)).enumerate().for_each(|(j, row)| {
            for (i, px) in row.iter_mut().enumerate() {
                let mut sum = Vec3::ZERO;
                for a in 0..n {
                    for b in 0..n {
                        let u = i as f32 + (b as f32 + 0.5) / n as f32;
                        let v = j as f32 + (a as f32 + 0.5) / n as f32;
                        let ray = camera.ray(u, v);
                        sum +=
                            self.shade(ray.origin, ray.dir).unwrap_or_else(|| background(ray.dir));
                    }
                }
                *px = sum / (n * n) as f32;
            }
        });
        out
    }

    /// Render a view as straight-alpha RGBA8: `samples_per_side^2` stratified samples per
    /// pixel; alpha is the covered fraction, colour the mean over covering samples.
    pub fn render(&self, camera: &Camera, samples_per_side: u32) -> image::RgbaImage {
        let (w, h) = (camera.intrinsics.width, camera.intrinsics.height);
        let n = samples_per_side.max(1);
        let mut buf = vec![0u8; (w * h * 4) as usize];
        buf.par_chunks_mut((w * 4) as usize).enumerate().for_each(|(j, row)| {
            for i in 0..w {
                let mut sum = Vec3::ZERO;
                let mut hits = 0u32;
                for a in 0..n {
                    for b in 0..n {
                        let u = i as f32 + (b as f32 + 0.5) / n as f32;
                        let v = j as f32 + (a as f32 + 0.5) / n as f32;
                        let ray = camera.ray(u, v);
                        if let Some(c) = self.shade(ray.origin, ray.dir) {
                            sum += c;
                            hits += 1;
                        }
                    }
                }
                let px = &mut row[(i * 4) as usize..(i * 4 + 4) as usize];
                if hits > 0 {
                    let c = (sum / hits as f32).clamp(Vec3::ZERO, Vec3::ONE) * 255.0;
                    px[0] = c.x.round() as u8;
                    px[1] = c.y.round() as u8;
                    px[2] = c.z.round() as u8;
                    px[3] = ((hits as f32 / (n * n) as f32) * 255.0).round() as u8;
                }
            }
        });
        image::RgbaImage::from_raw(w, h, buf).expect("buffer matches the image size")
    }
}
