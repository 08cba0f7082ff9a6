//! Camera rays through pixel centres, one at a time, as an iterator or as flat arrays for
//! training code.

use crate::{Dataset, Frame};
use assetfield_core::{Camera, Ray};
use rayon::prelude::*;

impl Dataset {
    /// The ray through the centre of pixel `(i, j)` of frame `frame`. Panics if `frame` is
    /// out of range.
    pub fn ray(&self, frame: usize, i: u32, j: u32) -> Ray {
        self.frames[frame].camera.pixel_ray(i, j)
    }
}

impl Frame {
    /// The ray through the centre of pixel `(i, j)`.
    pub fn ray(&self, i: u32, j: u32) -> Ray {
        self.camera.pixel_ray(i, j)
    }

    /// Rays through every pixel centre, row-major (same order as the image's pixels).
    pub fn rays(&self) -> PixelRays<'_> {
        PixelRays::new(&self.camera)
    }
}

/// Iterator over the rays through every pixel centre of a camera, row by row.
#[derive(Debug, Clone)]
pub struct PixelRays<'a> {
    camera: &'a Camera,
    next: usize,
    end: usize,
}

impl<'a> PixelRays<'a> {
    /// All pixel rays of `camera`, row-major.
    pub fn new(camera: &'a Camera) -> Self {
        let k = &camera.intrinsics;
        PixelRays { camera, next: 0, end: k.width as usize * k.height as usize }
    }
}

impl Iterator for PixelRays<'_> {
    type Item = Ray;

    fn next(&mut self) -> Option<Ray> {
        if self.next >= self.end {
            return None;
        }
        let w = self.camera.intrinsics.width as usize;
        let (i, j) = (self.next % w, self.next / w);
        self.next += 1;
        Some(self.camera.pixel_ray(i as u32, j as u32))
    }

    fn size_hint(&self) -> (usize, Option<usize>) {
        let n = self.end - self.next;
        (n, Some(n))
    }
}

impl ExactSizeIterator for PixelRays<'_> {}

/// Fill `origins` and `dirs` (each `3 * width * height` floats, xyz interleaved, row-major
/// like [`crate::ImageF32::rgb`]) with the rays through every pixel centre of `camera`.
/// Directions are unit length. Rows are computed in parallel.
///
/// Panics if a slice has the wrong length.
pub fn fill_rays(camera: &Camera, origins: &mut [f32], dirs: &mut [f32]) {
    let (w, h) = (camera.intrinsics.width as usize, camera.intrinsics.height as usize);
    assert_eq!(origins.len(), 3 * w * h, "origins must hold 3 * {w} * {h} floats");
    assert_eq!(dirs.len(), 3 * w * h, "dirs must hold 3 * {w} * {h} floats");
    if w == 0 || h == 0 {
        return;
    }
    let o = camera.position().to_array();
    origins.par_chunks_mut(3 * w).zip(dirs.par_chunks_mut(3 * w)).enumerate().for_each(
        |(j, (orow, drow))| {
            for (i, (oc, dc)) in orow.chunks_exact_mut(3).zip(drow.chunks_exact_mut(3)).enumerate()
            {
                let r = camera.pixel_ray(i as u32, j as u32);
                oc.copy_from_slice(&o);
                dc.copy_from_slice(&r.dir.to_array());
            }
        },
    );
}

/// Rays through every pixel centre of `camera` as flat `(origins, dirs)` arrays (see
/// [`fill_rays`]).
pub fn rays_flat(camera: &Camera) -> (Vec<f32>, Vec<f32>) {
    let n = 3 * camera.intrinsics.width as usize * camera.intrinsics.height as usize;
    let (mut o, mut d) = (vec![0.0; n], vec![0.0; n]);
    fill_rays(camera, &mut o, &mut d);
    (o, d)
}

#[cfg(test)]
mod tests {
    use super::*;
    use assetfield_core::Intrinsics;
    use glam::Vec3;

    #[test]
    fn flat_rays_match_the_iterator() {
        let k = Intrinsics::from_fov_x(7, 5, 0.9);
        let cam = Camera::look_at(k, Vec3::new(2.0, -1.0, 1.0), Vec3::ZERO, Vec3::Z);
        let (o, d) = rays_flat(&cam);
        let it = PixelRays::new(&cam);
        assert_eq!(it.len(), 35);
        for (n, r) in it.enumerate() {
            assert_eq!(&o[3 * n..3 * n + 3], &r.origin.to_array());
            assert_eq!(&d[3 * n..3 * n + 3], &r.dir.to_array());
            assert!((r.dir.length() - 1.0).abs() < 1e-5);
        }
        let r = cam.pixel_ray(6, 4);
        assert_eq!(&d[3 * 34..], &r.dir.to_array());
    }
}
