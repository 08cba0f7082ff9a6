//! Asset geometry in the asset's local frame: analytic primitives (box, cylinder, cone or
//! frustum, sphere) and triangles from OBJ meshes, each with a material, under a BVH.

use crate::bvh::Bvh;
use assetfield_core::Aabb3;
use assetfield_layout::script::{Axis, Part};
use glam::{Vec2, Vec3};

/// A diffuse material: a colour, optionally modulated by a texture.
#[derive(Debug, Clone)]
pub struct Material {
    pub color: Vec3,
    pub texture: Option<usize>,
}

/// An RGB texture with bilinear, wrapping lookups (OBJ convention: v = 0 at the bottom).
#[derive(Debug, Clone)]
pub struct Texture {
    pub width: u32,
    pub height: u32,
    pub rgb: Vec<Vec3>,
}

impl Texture {
    pub fn sample(&self, uv: Vec2) -> Vec3 {
        let (w, h) = (self.width as i64, self.height as i64);
        let x = uv.x.rem_euclid(1.0) * w as f32 - 0.5;
        let y = (1.0 - uv.y.rem_euclid(1.0)) * h as f32 - 0.5;
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let at = |i: i64, j: i64| self.rgb[(j.rem_euclid(h) * w + i.rem_euclid(w)) as usize];
        let (i, j) = (x0 as i64, y0 as i64);
        let top = at(i, j).lerp(at(i + 1, j), fx);
        let bottom = at(i, j + 1).lerp(at(i + 1, j + 1), fx);
        top.lerp(bottom, fy)
    }
}

/// One piece of geometry.
#[derive(Debug, Clone)]
pub enum Shape {
    /// Box with centre, half size, turned by (cos, sin) of its yaw about z.
    Box {
        center: Vec3,
        half: Vec3,
        cos: f32,
        sin: f32,
    },
    /// Cylinder or frustum around an axis through `base`: radius `r0` at the base, `r1` at
    /// `base + height * axis`. `perm` maps the axis to local z.
    Frustum {
        base: Vec3,
        axis: Axis,
        r0: f32,
        r1: f32,
        height: f32,
    },
    Sphere {
        center: Vec3,
        radius: f32,
    },
    Triangle {
        v0: Vec3,
        e1: Vec3,
        e2: Vec3,
        n: [Vec3; 3],
        uv: [Vec2; 3],
        smooth: bool,
    },
}

/// Where a ray hits a shape.
#[derive(Debug, Clone, Copy)]
pub struct ShapeHit {
    pub t: f32,
    /// Unit normal in the asset's local frame (not yet facing the ray).
    pub normal: Vec3,
    pub uv: Vec2,
}

fn to_axis_frame(axis: Axis, v: Vec3) -> Vec3 {
    match axis {
        Axis::Z => v,
        Axis::X => Vec3::new(v.y, v.z, v.x),
        Axis::Y => Vec3::new(v.z, v.x, v.y),
    }
}

pub(crate) fn from_axis_frame(axis: Axis, v: Vec3) -> Vec3 {
    match axis {
        Axis::Z => v,
        Axis::X => Vec3::new(v.z, v.x, v.y),
        Axis::Y => Vec3::new(v.y, v.z, v.x),
    }
}

/// Smallest root of `a t^2 + b t + c` in `(t_min, t_max)` that passes `accept`.
fn quadratic_hits(a: f32, b: f32, c: f32) -> Option<(f32, f32)> {
    if a.abs() < 1e-12 {
        if b.abs() < 1e-12 {
            return None;
        }
        let t = -c / b;
        return Some((t, t));
    }
    let disc = b * b - 4.0 * a * c;
    if disc < 0.0 {
        return None;
    }
    let s = disc.sqrt();
    let q = -0.5 * (b + b.signum() * s);
    let (t0, t1) = (q / a, if q != 0.0 { c / q } else { q / a });
    Some((t0.min(t1), t0.max(t1)))
}

impl Shape {
    pub fn bounds(&self) -> Aabb3 {
        match self {
            Shape::Box { center, half, cos, sin } => {
                let hx = (cos * half.x).abs() + (sin * half.y).abs();
                let hy = (sin * half.x).abs() + (cos * half.y).abs();
                let e = Vec3::new(hx, hy, half.z);
                Aabb3::new(*center - e, *center + e)
            }
            Shape::Frustum { base, axis, r0, r1, height } => {
                let r = r0.max(*r1);
                let lo = from_axis_frame(*axis, Vec3::new(-r, -r, 0.0));
                let hi = from_axis_frame(*axis, Vec3::new(r, r, *height));
                Aabb3::new(*base + lo.min(hi), *base + lo.max(hi))
            }
            Shape::Sphere { center, radius } => Aabb3::new(*center - *radius, *center + *radius),
            Shape::Triangle { v0, e1, e2, .. } => {
                let mut b = Aabb3::EMPTY;
                for p in [*v0, *v0 + *e1, *v0 + *e2] {
                    b.grow(p);
                }
                // keep flat triangles from giving zero-thickness boxes
                Aabb3::new(b.min - 1e-6, b.max + 1e-6)
            }
        }
    }

    /// Nearest hit with `t` in `(t_min, t_max)`.
    #[inline]
    pub fn intersect(&self, o: Vec3, d: Vec3, t_min: f32, t_max: f32) -> Option<ShapeHit> {
        match self {
            Shape::Box { center, half, cos, sin } => {
                // into the box frame: rotate by -yaw
                let rot = |v: Vec3| Vec3::new(cos * v.x + sin * v.y, -sin * v.x + cos * v.y, v.z);
                let (lo, ld) = (rot(o - *center), rot(d));
                let inv = ld.recip();
                let ta = (-*half - lo) * inv;
                let tb = (*half - lo) * inv;
                let tn = ta.min(tb);
                let tf = ta.max(tb);
                let t0 = tn.max_element();
                let t1 = tf.min_element();
                if t0 > t1 {
                    return None;
                }
                let (t, tsel) = if t0 > t_min { (t0, tn) } else { (t1, tf) };
                if t <= t_min || t >= t_max {
                    return None;
                }
                let k = if tsel.x == t {
                    0
                } else if tsel.y == t {
                    1
                } else {
                    2
                };
                let mut n = Vec3::ZERO;
                n[k] = -ld[k].signum();
                if t0 <= t_min {
                    n = -n;
                }
                let n_local = Vec3::new(cos * n.x - sin * n.y, sin * n.x + cos * n.y, n.z);
                let p = lo + ld * t;
                let uv = Vec2::new(p.x / half.x.max(1e-9), p.y / half.y.max(1e-9)) * 0.5 + 0.5;
                Some(ShapeHit { t, normal: n_local, uv })
            }
            Shape::Sphere { center, radius } => {
                let oc = o - *center;
                let (t0, t1) =
                    quadratic_hits(d.dot(d), 2.0 * oc.dot(d), oc.dot(oc) - radius * radius)?;
                let t = if t0 > t_min { t0 } else { t1 };
                if t <= t_min || t >= t_max {
                    return None;
                }
                let n = (oc + d * t) / *radius;
                Some(ShapeHit { t, normal: n, uv: Vec2::new(n.x.atan2(n.y), n.z) })
            }
            Shape::Frustum { base, axis, r0, r1, height } => {
                let lo = to_axis_frame(*axis, o - *base);
                let ld = to_axis_frame(*axis, d);
                let k = (r1 - r0) / height;
                let mut best: Option<ShapeHit> = None;
                let mut consider = |t: f32, n: Vec3| {
                    if t > t_min && t < t_max && best.is_none_or(|b| t < b.t) {
                        best =
                            Some(ShapeHit { t, normal: from_axis_frame(*axis, n), uv: Vec2::ZERO });
                    }
                };
                // side: x^2 + y^2 = (r0 + k z)^2, 0 <= z <= h
                let (rz0, rz1) = (r0 + k * lo.z, k * ld.z);
                let a = ld.x * ld.x + ld.y * ld.y - rz1 * rz1;
                let b = 2.0 * (lo.x * ld.x + lo.y * ld.y - rz0 * rz1);
                let c = lo.x * lo.x + lo.y * lo.y - rz0 * rz0;
                if let Some((t0, t1)) = quadratic_hits(a, b, c) {
                    for t in [t0, t1] {
                        let p = lo + ld * t;
                        if p.z >= 0.0 && p.z <= *height && r0 + k * p.z >= 0.0 {
                            let radial = Vec2::new(p.x, p.y).normalize_or_zero();
                            let n = Vec3::new(radial.x, radial.y, -k).normalize();
                            consider(t, n);
                        }
                    }
                }
                // caps
                if ld.z.abs() > 1e-12 {
                    for (z, r, nz) in [(0.0, *r0, -1.0), (*height, *r1, 1.0)] {
                        let t = (z - lo.z) / ld.z;
                        let p = lo + ld * t;
                        if r > 0.0 && p.x * p.x + p.y * p.y <= r * r {
                            consider(t, Vec3::new(0.0, 0.0, nz));
                        }
                    }
                }
                best
            }
            Shape::Triangle { v0, e1, e2, n, uv, smooth } => {
                let p = d.cross(*e2);
                let det = e1.dot(p);
                if det.abs() < 1e-12 {
                    return None;
                }
                let inv = 1.0 / det;
                let s = o - *v0;
                let u = s.dot(p) * inv;
                if !(0.0..=1.0).contains(&u) {
                    return None;
                }
                let q = s.cross(*e1);
                let v = d.dot(q) * inv;
                if v < 0.0 || u + v > 1.0 {
                    return None;
                }
                let t = e2.dot(q) * inv;
                if t <= t_min || t >= t_max {
                    return None;
                }
                let w = 1.0 - u - v;
                let normal = if *smooth {
                    (n[0] * w + n[1] * u + n[2] * v).normalize_or(e1.cross(*e2).normalize())
                } else {
                    e1.cross(*e2).normalize()
                };
                Some(ShapeHit { t, normal, uv: uv[0] * w + uv[1] * u + uv[2] * v })
            }
        }
    }
}

/// The geometry of one asset: shapes with materials under a BVH, in the asset's local frame.
#[derive(Debug, Clone, Default)]
pub struct AssetGeometry {
    pub shapes: Vec<Shape>,
    pub shape_material: Vec<u32>,
    pub materials: Vec<Material>,
    pub textures: Vec<Texture>,
    bvh: Bvh,
}

/// A hit on an asset, in its local frame.
#[derive(Debug, Clone, Copy)]
pub struct AssetHit {
    pub t: f32,
    pub normal: Vec3,
    pub color: Vec3,
}

impl AssetGeometry {
    /// Geometry from primitive parts.
    pub fn from_parts(parts: &[Part]) -> Self {
        let mut g = AssetGeometry::default();
        for part in parts {
            g.push_part(part);
        }
        g.finish();
        g
    }

    pub fn push_part(&mut self, part: &Part) {
        let v = |t: (f32, f32, f32)| Vec3::new(t.0, t.1, t.2);
        let (shape, color) = match part {
            Part::Box { center, size, color, yaw } => {
                let (s, c) = yaw.to_radians().sin_cos();
                (Shape::Box { center: v(*center), half: v(*size) * 0.5, cos: c, sin: s }, color)
            }
            Part::Cylinder { base, radius, height, color, axis } => (
                Shape::Frustum {
                    base: v(*base),
                    axis: *axis,
                    r0: *radius,
                    r1: *radius,
                    height: *height,
                },
                color,
            ),
            Part::Cone { base, radius, top_radius, height, color } => (
                Shape::Frustum {
                    base: v(*base),
                    axis: Axis::Z,
                    r0: *radius,
                    r1: *top_radius,
                    height: *height,
                },
                color,
            ),
            Part::Sphere { center, radius, color } => {
                (Shape::Sphere { center: v(*center), radius: *radius }, color)
            }
        };
        self.materials.push(Material { color: v(*color), texture: None });
        self.shapes.push(shape);
        self.shape_material.push(self.materials.len() as u32 - 1);
    }

    /// The convex hull of the geometry seen from above (local `(x, y)`, counter-clockwise):
    /// box corners, circles of cylinders, cones and spheres (as 64-gons through their
    /// rim), triangle vertices. Empty for no geometry.
    pub fn ground_outline(&self) -> Vec<Vec2> {
        const RIM: usize = 64;
        let mut pts: Vec<Vec2> = Vec::new();
        let circle = |pts: &mut Vec<Vec2>, c: Vec2, r: f32| {
            for i in 0..RIM {
                let a = std::f32::consts::TAU * i as f32 / RIM as f32;
                pts.push(c + r * Vec2::new(a.cos(), a.sin()));
            }
        };
        for s in &self.shapes {
            match s {
                Shape::Box { center, half, cos, sin } => {
                    for (sx, sy) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
                        let (x, y) = (sx * half.x, sy * half.y);
                        pts.push(
                            center.truncate() + Vec2::new(cos * x - sin * y, sin * x + cos * y),
                        );
                    }
                }
                Shape::Frustum { base, axis: Axis::Z, r0, r1, .. } => {
                    circle(&mut pts, base.truncate(), r0.max(*r1));
                }
                Shape::Frustum { .. } => {
                    let b = s.bounds();
                    pts.extend([
                        b.min.truncate(),
                        Vec2::new(b.max.x, b.min.y),
                        b.max.truncate(),
                        Vec2::new(b.min.x, b.max.y),
                    ]);
                }
                Shape::Sphere { center, radius } => circle(&mut pts, center.truncate(), *radius),
                Shape::Triangle { v0, e1, e2, .. } => {
                    pts.extend([v0.truncate(), (*v0 + *e1).truncate(), (*v0 + *e2).truncate()]);
                }
            }
        }
        convex_hull(pts)
    }

    /// Build the BVH; call after adding shapes.
    pub fn finish(&mut self) {
        let boxes: Vec<Aabb3> = self.shapes.iter().map(Shape::bounds).collect();
        self.bvh = Bvh::build(&boxes);
    }

    pub fn bounds(&self) -> Aabb3 {
        self.bvh.bounds()
    }

    /// Nearest hit along a ray in the asset's frame (`d` need not be unit length; `t` is in
    /// units of `d`).
    #[inline]
    pub fn intersect(&self, o: Vec3, d: Vec3, t_max: f32) -> Option<AssetHit> {
        let mut best: Option<(ShapeHit, u32)> = None;
        self.bvh.traverse(o, d, t_max, |i, tm| {
            let h = self.shapes[i as usize].intersect(o, d, 1e-6, tm)?;
            best = Some((h, i));
            Some(h.t)
        })?;
        let (h, i) = best?;
        let m = &self.materials[self.shape_material[i as usize] as usize];
        let color = match m.texture {
            Some(t) => m.color * self.textures[t].sample(h.uv),
            None => m.color,
        };
        Some(AssetHit { t: h.t, normal: h.normal, color })
    }
}

/// Convex hull of points (Andrew's monotone chain), counter-clockwise, without collinear
/// points; fewer than three distinct points come back as they are (deduplicated).
pub fn convex_hull(mut pts: Vec<Vec2>) -> Vec<Vec2> {
    pts.retain(|p| p.is_finite());
    pts.sort_by(|a, b| a.x.total_cmp(&b.x).then(a.y.total_cmp(&b.y)));
    pts.dedup();
    if pts.len() < 3 {
        return pts;
    }
    let cross = |o: Vec2, a: Vec2, b: Vec2| (a - o).perp_dot(b - o);
    let mut h: Vec<Vec2> = Vec::with_capacity(2 * pts.len());
    for pass in 0..2 {
        let start = h.len();
        let ordered: Box<dyn Iterator<Item = &Vec2>> =
            if pass == 0 { Box::new(pts.iter()) } else { Box::new(pts.iter().rev()) };
        for &p in ordered {
            while h.len() >= start + 2 && cross(h[h.len() - 2], h[h.len() - 1], p) <= 0.0 {
                h.pop();
            }
            h.push(p);
        }
        h.pop();
    }
    h
}

#[cfg(test)]
mod tests {
    use super::*;

    fn hit(s: &Shape, o: Vec3, d: Vec3) -> Option<ShapeHit> {
        s.intersect(o, d, 1e-6, f32::INFINITY)
    }

    #[test]
    fn box_hits_with_yaw() {
        let s =
            Shape::Box { center: Vec3::ZERO, half: Vec3::new(1.0, 0.5, 0.5), cos: 0.0, sin: 1.0 };
        // turned by 90 degrees: now 1.0 deep along y, 0.5 along x
        let h = hit(&s, Vec3::new(-5.0, 0.0, 0.0), Vec3::X).unwrap();
        assert!((h.t - 4.5).abs() < 1e-5);
        assert!((h.normal - -Vec3::X).length() < 1e-5);
        let h = hit(&s, Vec3::new(0.0, 5.0, 0.0), -Vec3::Y).unwrap();
        assert!((h.t - 4.0).abs() < 1e-5);
        assert!((h.normal - Vec3::Y).length() < 1e-5);
        assert!(hit(&s, Vec3::new(0.8, 5.0, 0.0), -Vec3::Y).is_none());
    }

    #[test]
    fn frustum_side_and_caps() {
        let cyl = Shape::Frustum { base: Vec3::ZERO, axis: Axis::Z, r0: 1.0, r1: 1.0, height: 2.0 };
        let h = hit(&cyl, Vec3::new(-5.0, 0.0, 1.0), Vec3::X).unwrap();
        assert!((h.t - 4.0).abs() < 1e-5 && (h.normal - -Vec3::X).length() < 1e-4);
        let h = hit(&cyl, Vec3::new(0.3, 0.2, 5.0), -Vec3::Z).unwrap();
        assert!((h.t - 3.0).abs() < 1e-5 && (h.normal - Vec3::Z).length() < 1e-5);
        assert!(hit(&cyl, Vec3::new(-5.0, 0.0, 2.5), Vec3::X).is_none());
        // a cone: radius 1 at z=0, 0 at z=1; at z = 0.5 the radius is 0.5
        let cone =
            Shape::Frustum { base: Vec3::ZERO, axis: Axis::Z, r0: 1.0, r1: 0.0, height: 1.0 };
        let h = hit(&cone, Vec3::new(-5.0, 0.0, 0.5), Vec3::X).unwrap();
        assert!((h.t - 4.5).abs() < 1e-4, "{}", h.t);
        assert!(h.normal.z > 0.0 && h.normal.x < 0.0);
        // a horizontal cylinder along x
        let wheel = Shape::Frustum {
            base: Vec3::new(-0.1, 0.0, 0.3),
            axis: Axis::X,
            r0: 0.3,
            r1: 0.3,
            height: 0.2,
        };
        let h = hit(&wheel, Vec3::new(0.0, 0.0, 5.0), -Vec3::Z).unwrap();
        assert!((h.t - 4.4).abs() < 1e-4 && h.normal.z > 0.99);
        let b = wheel.bounds();
        assert!((b.min - Vec3::new(-0.1, -0.3, 0.0)).length() < 1e-5);
        assert!((b.max - Vec3::new(0.1, 0.3, 0.6)).length() < 1e-5);
    }

    #[test]
    fn sphere_and_triangle() {
        let s = Shape::Sphere { center: Vec3::new(0.0, 0.0, 1.0), radius: 0.5 };
        let h = hit(&s, Vec3::new(0.0, 0.0, 5.0), -Vec3::Z).unwrap();
        assert!((h.t - 3.5).abs() < 1e-5);
        let tri = Shape::Triangle {
            v0: Vec3::ZERO,
            e1: Vec3::X,
            e2: Vec3::Y,
            n: [Vec3::Z; 3],
            uv: [Vec2::ZERO, Vec2::X, Vec2::Y],
            smooth: false,
        };
        let h = hit(&tri, Vec3::new(0.25, 0.25, 1.0), -Vec3::Z).unwrap();
        assert!((h.t - 1.0).abs() < 1e-6 && (h.uv - Vec2::new(0.25, 0.25)).length() < 1e-6);
        assert!(hit(&tri, Vec3::new(0.75, 0.75, 1.0), -Vec3::Z).is_none());
    }

    #[test]
    fn shape_bounds_match_layout_part_bounds() {
        let parts = [
            Part::Box {
                center: (0.1, 0.2, 0.3),
                size: (1.0, 0.4, 0.2),
                color: (1.0, 0.0, 0.0),
                yaw: 30.0,
            },
            Part::Cylinder {
                base: (0.0, 0.0, 0.0),
                radius: 0.2,
                height: 0.7,
                color: (0.0, 1.0, 0.0),
                axis: Axis::Y,
            },
            Part::Cone {
                base: (0.5, 0.0, 0.1),
                radius: 0.3,
                top_radius: 0.1,
                height: 0.5,
                color: (0.0, 0.0, 1.0),
            },
            Part::Sphere { center: (0.0, 0.0, 1.0), radius: 0.25, color: (1.0, 1.0, 1.0) },
        ];
        let g = AssetGeometry::from_parts(&parts);
        for (p, s) in parts.iter().zip(&g.shapes) {
            let (a, b) = (p.bounds(), s.bounds());
            assert!((a.min - b.min).length() < 1e-5 && (a.max - b.max).length() < 1e-5, "{p:?}");
        }
    }
}
