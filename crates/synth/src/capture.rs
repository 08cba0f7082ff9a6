//! Hand-held captures (`assetfield synth --capture`): a room photographed the way a person
//! photographs it, not from an orbit around it.
//!
//! - Cameras walk a closed path at eye height inside the room: the script's `extent` inset
//!   by [`CaptureConfig::path_inset`], walked once counter-clockwise, each camera a little
//!   off its even spacing, bobbing, rolled a little, looking at a point drawn around the
//!   room's centre near the floor.
//! - Each photo has its own exposure (a gain of `2^N(0, stops)`) and white balance (a gain
//!   per channel of `1 + N(0, white_balance)`), and sensor noise (`N(0, noise)` per pixel
//!   and channel, after the gain, before 8-bit rounding): what auto-exposure and a small
//!   sensor do.
//! - Photos are opaque (RGB, no alpha): what the walls do not hide is a sky
//!   ([`sky`]: a gradient from the horizon to the zenith with a glow around the light).
//!
//! Every draw comes from [`assetfield_layout::rng::Rng`] streams of the capture's seed, so
//! a script gives the same photos on every machine.

use crate::SynthError;
use crate::synth::RigView;
use assetfield_core::{Camera, Intrinsics, Rect2};
use assetfield_layout::CaptureSettings;
use assetfield_layout::rng::Rng;
use glam::{Quat, Vec2, Vec3};
use serde::Serialize;

/// Eye height of the cameras, metres (a standing adult holding a phone).
pub const EYE_HEIGHT_M: f32 = 1.6;
/// Distance of the walking path inside the room's edges, metres (half a step from the wall).
pub const PATH_INSET_M: f32 = 0.5;
/// Spread of the exposure between photos, stops: auto-exposure swings of a quarter stop are
/// common between neighbouring phone photos.
pub const EXPOSURE_STOPS: f32 = 0.25;
/// Spread of each channel's white-balance gain, fraction (auto white balance drifting by a
/// few percent per photo).
pub const WHITE_BALANCE: f32 = 0.04;
/// Sensor noise, fraction of full scale (2.5 of 255: a phone's sensor in room light).
pub const NOISE: f32 = 0.01;
/// Photos of a capture unless the scene or `--views` says otherwise (200, a phone video's
/// worth at a few frames a second: a walk round a room sees each place near its path from
/// two or three of 50 photos, and 50 trained to 16.2 dB held out where 200 trained to 22.1,
/// docs/training.md).
pub const VIEWS: u32 = 200;
/// One photo in this many is held out unless the scene or `--test-views` says otherwise
/// (every 8th, as COLMAP-posed captures are held out by name).
pub const HOLDOUT_EVERY: u32 = 8;
/// Field of view of a capture unless the scene or `--fov` says otherwise, degrees (a phone's
/// main camera is 65-75 degrees across its long side; 60 across a square crop).
pub const FOV_DEG: f32 = 60.0;
/// Where the cameras look: a point drawn uniformly within this fraction of the room's half
/// sides around its centre, so that neighbouring photos do not share one optical axis.
const TARGET_SPREAD: f32 = 0.35;
/// Height of the point looked at, fraction of the eye height (a little above the floor:
/// cameras pitch down 15-25 degrees across a room).
const TARGET_HEIGHT: f32 = 0.2;
/// A walker's bob: standard deviation of the eye height, fraction of it.
const EYE_JITTER: f32 = 0.03;
/// Standard deviation of each camera's place along the path, fraction of the spacing.
const STEP_JITTER: f32 = 0.25;
/// Standard deviation of each camera's roll, degrees (a hand-held phone is rarely level).
const ROLL_DEG: f32 = 2.0;

/// A capture's settings in scene units, resolved from [`CaptureSettings`] and the script's
/// units per metre.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct CaptureConfig {
    /// Camera height above the ground, scene units.
    pub eye_height: f32,
    /// Distance of the walking path inside the room's edges, scene units.
    pub path_inset: f32,
    pub exposure_stops: f32,
    pub white_balance: f32,
    pub noise: f32,
    pub seed: u64,
}

impl CaptureConfig {
    /// The settings given, the defaults above (metres times `units_per_metre`) for the rest.
    pub fn resolve(s: &CaptureSettings, units_per_metre: f32) -> Self {
        CaptureConfig {
            eye_height: s.eye_height.unwrap_or(EYE_HEIGHT_M * units_per_metre),
            path_inset: s.path_inset.unwrap_or(PATH_INSET_M * units_per_metre),
            exposure_stops: s.exposure_stops.unwrap_or(EXPOSURE_STOPS),
            white_balance: s.white_balance.unwrap_or(WHITE_BALANCE),
            noise: s.noise.unwrap_or(NOISE),
            seed: s.seed.unwrap_or(0),
        }
    }
}

/// How one photo of a capture was developed: its colour gain per channel (exposure times
/// white balance).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Photo {
    pub gain: [f32; 3],
}

/// A standard normal draw (Box-Muller on two uniforms).
fn normal(rng: &mut Rng) -> f32 {
    let u1 = rng.f32().max(1e-7);
    let u2 = rng.f32();
    (-2.0 * u1.ln()).sqrt() * (std::f32::consts::TAU * u2).cos()
}

/// The point at arc length `s` (wrapped) of the rectangle `r`, walked counter-clockwise from
/// its lower-left corner.
fn along_rect(r: Rect2, s: f32) -> Vec2 {
    let (w, h) = (r.max.x - r.min.x, r.max.y - r.min.y);
    let s = s.rem_euclid(2.0 * (w + h));
    if s < w {
        Vec2::new(r.min.x + s, r.min.y)
    } else if s < w + h {
        Vec2::new(r.max.x, r.min.y + (s - w))
    } else if s < 2.0 * w + h {
        Vec2::new(r.max.x - (s - w - h), r.max.y)
    } else {
        Vec2::new(r.min.x, r.max.y - (s - 2.0 * w - h))
    }
}

/// The cameras of a capture of the room `room` (the script's extent, scene units, floor at
/// z = 0): `views` cameras along the walking path with `test` of them held out (the same
/// interleaving as the orbit), and each photo's development. The room must be wider than
/// twice the path's inset.
pub fn capture_rig(
    room: Rect2,
    intrinsics: Intrinsics,
    views: u32,
    test: &[u32],
    cap: &CaptureConfig,
) -> Result<Vec<(RigView, Photo)>, SynthError> {
    let d = cap.path_inset;
    let path = Rect2::new(room.min + Vec2::splat(d), room.max - Vec2::splat(d));
    let size = path.max - path.min;
    if !(size.x > 0.0 && size.y > 0.0) {
        let r = room.max - room.min;
        return Err(SynthError::Config(format!(
            "the room ({:.3} x {:.3} scene units) is too small for a walking path {d:.3} inside its edges: give the script an `extent`, or a smaller `capture: (path_inset: ...)`",
            r.x, r.y
        )));
    }
    let perimeter = 2.0 * (size.x + size.y);
    let centre = 0.5 * (room.min + room.max);
    let half = 0.5 * (room.max - room.min);
    let mut rng = Rng::stream(cap.seed, "capture-rig");
    let n = views.max(1);
    let step = perimeter / n as f32;
    Ok((0..n)
        .map(|k| {
            let s = (k as f32 + 0.5 + STEP_JITTER * normal(&mut rng)) * step;
            let p = along_rect(path, s);
            let z = cap.eye_height * (1.0 + EYE_JITTER * normal(&mut rng));
            let eye = p.extend(z);
            let jitter = Vec2::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0));
            let target =
                (centre + jitter * half * TARGET_SPREAD).extend(cap.eye_height * TARGET_HEIGHT);
            let roll = (ROLL_DEG * normal(&mut rng)).to_radians();
            let forward = (target - eye).normalize_or(Vec3::X);
            let up = Quat::from_axis_angle(forward, roll) * Vec3::Z;
            let camera = Camera::look_at(intrinsics, eye, target, up);
            let exposure = (cap.exposure_stops * normal(&mut rng)).exp2();
            let gain = [0, 1, 2].map(|_| exposure * (1.0 + cap.white_balance * normal(&mut rng)));
            (RigView { camera, test: test.contains(&k) }, Photo { gain })
        })
        .collect())
}

/// The sky a capture sees over the walls, in the direction `d` (unit): a gradient from a
/// pale horizon to a blue zenith (below the horizon, a dull ground), with a glow around
/// `light` (the scene's light direction) so that the sky varies with azimuth too.
pub fn sky(d: Vec3, light: Vec3) -> Vec3 {
    const HORIZON: Vec3 = Vec3::new(0.86, 0.86, 0.83);
    const ZENITH: Vec3 = Vec3::new(0.36, 0.54, 0.86);
    const GROUND: Vec3 = Vec3::new(0.42, 0.40, 0.36);
    const GLOW: Vec3 = Vec3::new(0.35, 0.3, 0.2);
    let up = d.z.clamp(-1.0, 1.0);
    let base = if up >= 0.0 {
        HORIZON.lerp(ZENITH, up.sqrt())
    } else {
        HORIZON.lerp(GROUND, (-up).sqrt())
    };
    base + GLOW * d.dot(light).max(0.0).powi(16)
}

/// Develop a rendered view (linear colours, row-major `width` x `height`) into the photo a
/// camera would have written: the photo's gain, then sensor noise, clamped to 8 bits.
/// `view` seeds the noise (the same view develops the same way in every layout).
pub fn develop(
    pixels: &[Vec3],
    width: u32,
    height: u32,
    photo: &Photo,
    cap: &CaptureConfig,
    view: u64,
) -> image::RgbImage {
    let mut rng = Rng::stream(cap.seed.wrapping_mul(0x9E37).wrapping_add(view), "capture-noise");
    let mut buf = Vec::with_capacity(pixels.len() * 3);
    for c in pixels {
        for (ch, g) in c.to_array().into_iter().zip(photo.gain) {
            let v = ch * g + cap.noise * normal(&mut rng);
            buf.push((v.clamp(0.0, 1.0) * 255.0).round() as u8);
        }
    }
    image::RgbImage::from_raw(width, height, buf).expect("buffer matches the image size")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn room() -> Rect2 {
        Rect2::new(Vec2::new(-4.0, -3.0), Vec2::new(4.0, 3.0))
    }

    #[test]
    fn cameras_walk_inside_the_room_at_eye_height_looking_down() {
        let cap = CaptureConfig::resolve(&CaptureSettings::default(), 1.0);
        let intr = Intrinsics::from_fov_x(64, 64, FOV_DEG.to_radians());
        let rig = capture_rig(room(), intr, 40, &[3, 11], &cap).unwrap();
        assert_eq!(rig.len(), 40);
        assert_eq!(rig.iter().filter(|(v, _)| v.test).count(), 2);
        for (v, photo) in &rig {
            let p = v.camera.position();
            // on the path (0.5 inside the edges), give or take the step jitter along it
            let off_x = (p.x.abs() - 3.5).abs();
            let off_y = (p.y.abs() - 2.5).abs();
            assert!(off_x < 1e-3 || off_y < 1e-3, "camera off the path: {p}");
            assert!(p.x.abs() <= 3.5 + 1e-3 && p.y.abs() <= 2.5 + 1e-3, "{p}");
            assert!((p.z - 1.6).abs() < 0.3, "eye height {}", p.z);
            let f = v.camera.forward();
            let pitch = f.z.asin().to_degrees();
            assert!((-40.0..-5.0).contains(&pitch), "pitch {pitch}");
            // looking into the room, not at the nearest wall
            assert!(f.truncate().dot(-p.truncate()) > 0.0, "camera at {p} looks out along {f}");
            assert!(photo.gain.iter().all(|g| (0.4..2.5).contains(g)), "{:?}", photo.gain);
        }
        // the walk goes all the way round: cameras on all four sides
        let sides = [
            rig.iter().any(|(v, _)| v.camera.position().x > 3.4),
            rig.iter().any(|(v, _)| v.camera.position().x < -3.4),
            rig.iter().any(|(v, _)| v.camera.position().y > 2.4),
            rig.iter().any(|(v, _)| v.camera.position().y < -2.4),
        ];
        assert_eq!(sides, [true; 4]);
        // exposures vary from photo to photo
        let gains: Vec<f32> = rig.iter().map(|(_, p)| p.gain[1]).collect();
        let mean = gains.iter().sum::<f32>() / gains.len() as f32;
        let var = gains.iter().map(|g| (g - mean).powi(2)).sum::<f32>() / gains.len() as f32;
        assert!(var.sqrt() > 0.05, "gain spread {}", var.sqrt());
    }

    #[test]
    fn a_room_too_small_for_the_path_is_refused() {
        let cap = CaptureConfig::resolve(&CaptureSettings::default(), 1.0);
        let intr = Intrinsics::from_fov_x(8, 8, 1.0);
        let tiny = Rect2::new(Vec2::splat(-0.4), Vec2::splat(0.4));
        let e = capture_rig(tiny, intr, 4, &[1], &cap).unwrap_err();
        assert!(e.to_string().contains("too small for a walking path"), "{e}");
    }

    #[test]
    fn development_applies_the_gain_and_the_noise() {
        let cap = CaptureConfig { noise: 0.02, ..CaptureConfig::resolve(&Default::default(), 1.0) };
        let grey = vec![Vec3::splat(0.4); 64 * 64];
        let photo = Photo { gain: [1.5, 1.0, 0.5] };
        let img = develop(&grey, 64, 64, &photo, &cap, 7);
        let mean =
            |ch: usize| img.pixels().map(|p| p.0[ch] as f32 / 255.0).sum::<f32>() / (64.0 * 64.0);
        for (ch, want) in [0.6, 0.4, 0.2].into_iter().enumerate() {
            assert!((mean(ch) - want).abs() < 0.005, "channel {ch}: {} vs {want}", mean(ch));
        }
        let sd = {
            let m = mean(1);
            let v = img.pixels().map(|p| (p.0[1] as f32 / 255.0 - m).powi(2)).sum::<f32>()
                / (64.0 * 64.0);
            v.sqrt()
        };
        assert!((sd - 0.02).abs() < 0.004, "noise sd {sd}");
        // the same view develops the same way
        assert_eq!(img, develop(&grey, 64, 64, &photo, &cap, 7));
        assert_ne!(img, develop(&grey, 64, 64, &photo, &cap, 8));
    }

    #[test]
    fn the_sky_is_brighter_at_the_horizon_and_around_the_light() {
        let light = Vec3::new(0.35, 0.25, 1.0).normalize();
        let zenith = sky(Vec3::Z, light);
        let horizon = sky(Vec3::new(-1.0, 0.0, 0.0), light);
        assert!(horizon.x > zenith.x && zenith.z > zenith.x);
        assert!(
            sky(light, light).length()
                > sky(Vec3::new(-0.35, -0.25, 1.0).normalize(), light).length()
        );
    }
}
