//! What lies beyond the scene box: a colour per ray direction.
//!
//! A capture's photos see the far walls, a window, the sky around the scene. With one
//! background colour the field can only explain them with density inside its box: haze in
//! front of the cameras, which mining then reads as objects. A [`BackgroundMap`] gives every
//! direction its own colour instead, learned with the field: an equirectangular map of the
//! world's directions (azimuth across, polar angle from +Z down), sampled bilinearly, wrapping
//! in azimuth. A ray's colour is `c + T * map(dir)`, `T` its transmittance through the box
//! (the same compositing as the constant background's, so the march's backward pass is the
//! constant case with a colour per ray).
//!
//! The map is at infinity: what lies beyond the box at a finite distance shows no parallax
//! between photos, and is blurred over the directions it covers.
//!
//! The map lies beyond the box's sides and top only. The box's bottom face is the ground the
//! planes stand on, and the ground is opaque: no light comes from under it, so a ray that
//! gets through the box's floor face brings black ([`BackgroundMap::backdrop`]), never the
//! map. A map that took those rays too learned the floor as a colour per direction: an
//! explanation without parallax, right for each photo alone and for none together once the
//! cameras stand inside the box (a walk through a room, the floor a metre or two below every
//! camera); the field then patched each photo with haze near its camera, and the floor never
//! formed. Black rather than the field's plain background colour: a bright colour there
//! pushes the young field to darken those rays with haze wherever it can, near the cameras
//! first (a walked room: 15.3 dB held out with white there, 22.1 with black).
//!
//! That holds where the box's bottom is the ground: a scene levelled on its floor, or a
//! render whose world stands on z = 0 ([`BackgroundMap::ground`]). A capture posed with no
//! floor found (the fox, from a `transforms.json`: its box is the region the cameras look
//! at) has whatever the room holds below its box, and there the map takes every ray (the
//! fox's held-out photos: 12.7 dB with black below the box, 17.7 with the map).

use assetfield_core::{Aabb3, Ray, TensorFile};
use glam::Vec3;

/// The tensor a field file holds the map in, `[height][width][3]`.
pub const TENSOR: &str = "background.map";

/// The tensor holding [`BackgroundMap::ground`] (`[1]`, u8); files without it are read with
/// the ground under the box (the rule since it was made).
pub const GROUND_TENSOR: &str = "background.ground";

/// The default size, texels `[width, height]`: 64 x 32, 5.6 degrees per texel, a few texels
/// across a window; finer maps start to hold what a photo sees once (no other view
/// constrains it), coarser ones blur a room's walls into one colour.
pub const DEFAULT_SIZE: [usize; 2] = [64, 32];

/// An equirectangular map of colours over the directions.
#[derive(Debug, Clone, PartialEq)]
pub struct BackgroundMap {
    pub width: usize,
    pub height: usize,
    /// `[height][width][3]`, row 0 looking straight up (+Z).
    pub rgb: Vec<f32>,
    /// The box's bottom face is the ground (opaque): rays through it bring black, not the
    /// map. Off for a capture whose ground was not found.
    pub ground: bool,
}

/// The four texels around a direction and their bilinear weights.
pub type Taps = [(usize, f32); 4];

impl BackgroundMap {
    /// A map of `width` x `height` texels of one colour.
    pub fn uniform(width: usize, height: usize, colour: Vec3) -> Self {
        let rgb = (0..width * height).flat_map(|_| colour.to_array()).collect();
        BackgroundMap { width: width.max(1), height: height.max(1), rgb, ground: true }
    }

    /// The texels (indices of their first channel in `rgb`) and weights of direction `d`.
    pub fn taps(&self, d: Vec3) -> Taps {
        let d = d.normalize_or(Vec3::Z);
        let (w, h) = (self.width, self.height);
        let u = (d.y.atan2(d.x) / std::f32::consts::TAU + 0.5) * w as f32 - 0.5;
        let v = d.z.clamp(-1.0, 1.0).acos() / std::f32::consts::PI * h as f32 - 0.5;
        let (u0, v0) = (u.floor(), v.floor());
        let (fu, fv) = (u - u0, v - v0);
        let col = |c: f32| (c as i64).rem_euclid(w as i64) as usize;
        let row = |r: f32| (r.max(0.0) as usize).min(h - 1);
        let (c0, c1) = (col(u0), col(u0 + 1.0));
        let (r0, r1) = (row(v0), row(v0 + 1.0));
        let at = |r: usize, c: usize| (r * w + c) * 3;
        [
            (at(r0, c0), (1.0 - fu) * (1.0 - fv)),
            (at(r0, c1), fu * (1.0 - fv)),
            (at(r1, c0), (1.0 - fu) * fv),
            (at(r1, c1), fu * fv),
        ]
    }

    /// What `ray` sees beyond the box `aabb` where the field lets it through: the map in
    /// its direction, or black where it leaves the box through its floor and that is the
    /// ground ([`Self::through_ground`]).
    pub fn backdrop(&self, aabb: &Aabb3, ray: &Ray) -> Vec3 {
        self.backdrop_of(ray, self.through_ground(aabb, ray))
    }

    /// Whether `ray` leaves `aabb` through the ground: through its floor
    /// ([`leaves_through_floor`]) where the box's floor is the ground ([`Self::ground`]).
    pub fn through_ground(&self, aabb: &Aabb3, ray: &Ray) -> bool {
        self.ground && leaves_through_floor(aabb, ray)
    }

    /// [`BackgroundMap::backdrop`] for a ray already known to leave through the floor or not.
    pub fn backdrop_of(&self, ray: &Ray, through_floor: bool) -> Vec3 {
        if through_floor { Vec3::ZERO } else { self.sample(ray.dir) }
    }

    /// The colour seen in direction `d`.
    pub fn sample(&self, d: Vec3) -> Vec3 {
        self.taps(d).iter().fold(Vec3::ZERO, |acc, &(k, wt)| {
            acc + wt * Vec3::new(self.rgb[k], self.rgb[k + 1], self.rgb[k + 2])
        })
    }

    /// Adds `g` (the loss gradient with respect to the colour sampled in direction `d`) into
    /// `grad` (laid out like `rgb`).
    pub fn scatter(&self, d: Vec3, g: Vec3, grad: &mut [f32]) {
        for (k, wt) in self.taps(d) {
            grad[k] += wt * g.x;
            grad[k + 1] += wt * g.y;
            grad[k + 2] += wt * g.z;
        }
    }

    /// Store the map in a field file.
    pub fn write(&self, f: &mut TensorFile) {
        f.insert_f32(TENSOR, &[self.height, self.width, 3], self.rgb.clone());
        f.insert_u8(GROUND_TENSOR, &[1], vec![u8::from(self.ground)]);
    }

    /// The map a field file (`path`, for messages) holds, if any; a tensor of the wrong
    /// shape or with values that are not finite is an error naming it.
    pub fn read(f: &TensorFile, path: &str) -> Result<Option<Self>, crate::FieldError> {
        let Some(shape) = f.shape_of(TENSOR).map(<[usize]>::to_vec) else { return Ok(None) };
        let invalid =
            |message: String| crate::FieldError::Invalid { path: path.to_owned(), message };
        if shape.len() != 3 || shape[2] != 3 || shape[0] == 0 || shape[1] == 0 {
            return Err(invalid(format!(
                "tensor {TENSOR} has shape {shape:?}, expected [height, width, 3]"
            )));
        }
        let rgb = f.get_f32(TENSOR, &shape)?.to_vec();
        if let Some(v) = rgb.iter().find(|v| !v.is_finite()) {
            return Err(invalid(format!("tensor {TENSOR} holds {v}")));
        }
        let ground = match f.shape_of(GROUND_TENSOR) {
            None => true,
            Some(_) => f.get_u8(GROUND_TENSOR, &[1])?[0] != 0,
        };
        Ok(Some(BackgroundMap { width: shape[1], height: shape[0], rgb, ground }))
    }
}

/// Whether `ray` leaves `aabb` through its bottom face (the ground): it goes down and meets
/// the floor's plane no later than any other face's on its way out. A ray that misses the
/// box, or leaves through a side or the top, does not.
pub fn leaves_through_floor(aabb: &Aabb3, ray: &Ray) -> bool {
    if ray.dir.z >= 0.0 || ray.dir.z.is_nan() {
        return false;
    }
    let inv = ray.dir.recip();
    let Some((_, exit)) = aabb.intersect(ray.origin, inv, f32::INFINITY) else { return false };
    // the same product the slab test takes for the floor's face, so a ray leaving through
    // the floor compares equal to its exit
    (aabb.min.z - ray.origin.z) * inv.z <= exit
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sampling_is_bilinear_and_its_gradient_is_its_transpose() {
        let mut m = BackgroundMap::uniform(8, 4, Vec3::ZERO);
        for (i, v) in m.rgb.iter_mut().enumerate() {
            *v = ((i * 37) % 11) as f32 / 10.0;
        }
        // the gradient of <g, sample(d)> with respect to the map is scatter(d, g)
        let g = Vec3::new(0.3, -1.2, 0.7);
        for d in [Vec3::new(0.3, -0.8, 0.5), Vec3::new(-1.0, 0.01, -0.2), Vec3::Z, -Vec3::Z] {
            let mut grad = vec![0.0; m.rgb.len()];
            m.scatter(d, g, &mut grad);
            let h = 1e-2;
            for k in 0..m.rgb.len() {
                let (mut a, mut b) = (m.clone(), m.clone());
                a.rgb[k] += h;
                b.rgb[k] -= h;
                let fd = (g.dot(a.sample(d)) - g.dot(b.sample(d))) / (2.0 * h);
                assert!((fd - grad[k]).abs() < 1e-4, "texel {k} of {d}: {fd} vs {}", grad[k]);
            }
        }
        // a uniform map is its colour everywhere; the seam in azimuth is continuous
        let u = BackgroundMap::uniform(8, 4, Vec3::new(0.2, 0.5, 0.9));
        assert!((u.sample(Vec3::new(-1.0, 1e-4, 0.1)) - Vec3::new(0.2, 0.5, 0.9)).length() < 1e-6);
        let (a, b) = (m.sample(Vec3::new(-1.0, 1e-4, 0.1)), m.sample(Vec3::new(-1.0, -1e-4, 0.1)));
        assert!((a - b).length() < 1e-3, "{a} vs {b} across the seam");
    }

    #[test]
    fn only_rays_that_leave_through_the_floor_see_the_ground() {
        let aabb = Aabb3::new(Vec3::new(-2.0, -1.0, 0.0), Vec3::new(2.0, 1.0, 1.0));
        let ray =
            |o: [f32; 3], d: [f32; 3]| Ray { origin: o.into(), dir: Vec3::from(d).normalize() };
        let floor = |r: &Ray| leaves_through_floor(&aabb, r);
        // a camera inside the room: down to the floor; level, up, and down but out through a
        // wall first
        let eye = [0.0, 0.0, 0.6];
        assert!(floor(&ray(eye, [0.3, 0.2, -1.0])));
        assert!(floor(&ray(eye, [0.0, 0.0, -1.0])));
        assert!(!floor(&ray(eye, [1.0, 0.0, 0.0])));
        assert!(!floor(&ray(eye, [0.2, 0.1, 1.0])));
        assert!(!floor(&ray(eye, [1.0, 0.0, -0.1])));
        // from outside and above (an orbit): into the box and out through its floor, or
        // past the box altogether
        assert!(floor(&ray([0.0, -4.0, 3.0], [0.0, 1.0, -0.8])));
        assert!(!floor(&ray([0.0, -4.0, 3.0], [0.0, 1.0, -0.1])));
        assert!(!floor(&ray([0.0, -4.0, 3.0], [0.0, -1.0, -1.0])));
        // what the map is asked for: black where the floor is met, its own colour elsewhere
        let m = BackgroundMap::uniform(8, 4, Vec3::new(0.2, 0.5, 0.9));
        assert_eq!(m.backdrop(&aabb, &ray(eye, [0.3, 0.2, -1.0])), Vec3::ZERO);
        assert_eq!(m.backdrop(&aabb, &ray(eye, [1.0, 0.0, -0.1])), m.sample(Vec3::X));
        // with no ground under the box (a capture whose floor was not found) the map takes
        // the rays through the floor too
        let open = BackgroundMap { ground: false, ..m };
        let down = ray(eye, [0.3, 0.2, -1.0]);
        assert!(!open.through_ground(&aabb, &down));
        assert_eq!(open.backdrop(&aabb, &down), open.sample(down.dir));
    }

    #[test]
    fn maps_round_trip_through_field_files() {
        let mut m = BackgroundMap::uniform(6, 3, Vec3::new(0.1, 0.2, 0.3));
        m.rgb[4] = 0.9;
        let mut f = TensorFile::new();
        assert_eq!(BackgroundMap::read(&f, "f").unwrap(), None);
        m.write(&mut f);
        assert_eq!(BackgroundMap::read(&f, "f").unwrap(), Some(m.clone()));
        // the ground flag round-trips; a file from before it reads with the ground on
        let open = BackgroundMap { ground: false, ..m.clone() };
        let mut g = TensorFile::new();
        open.write(&mut g);
        assert_eq!(BackgroundMap::read(&g, "f").unwrap(), Some(open));
        let mut old = TensorFile::new();
        old.insert_f32(TENSOR, &[3, 6, 3], m.rgb.clone());
        assert_eq!(BackgroundMap::read(&old, "f").unwrap(), Some(m));
        f.insert_f32(TENSOR, &[3, 6, 2], vec![0.0; 36]);
        let e = BackgroundMap::read(&f, "f").unwrap_err().to_string();
        assert!(e.contains(TENSOR) && e.contains("[3, 6, 2]"), "{e}");
    }
}
