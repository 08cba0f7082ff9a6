//! Relative yaw between a template patch and an instance patch (Sec. 3.3, template matching):
//! `theta* = argmin_theta sum_i || instance_i - R_theta(template)_i ||^2`.
//!
//! Sign convention: the **template is rotated onto the instance**, with the rotation and
//! offset convention of [`mod@crate::rotate`]. Hence if `instance = rotate(template, phi, d, ..)`
//! the estimate is `yaw_deg ≈ phi` and `offset ≈ d`: the instance's pose is the template's
//! pose turned counter-clockwise (x-right / y-up ground frame) by `yaw_deg` and shifted by
//! `offset` texels (x = columns, y = rows) relative to the patch centres. (The paper writes
//! the loss with the instance rotated onto the template; its angle is the negative of ours.)
//!
//! Patches may differ in size: both are placed on a common canvas with their centres
//! coinciding, the canvas covering the instance and (for [`CompareRegion::Union`]) padded to
//! hold the rotated template's diagonal.
//!
//! Search: a coarse scan over `[0, period)` in `step_deg` steps (in parallel). From each
//! coarse minimum lower than the scan's median (every basin better than a typical angle, at
//! most `starts` of them when bounded): golden-section refinement of the angle, then the
//! sub-texel offset (a 5 x 5 grid over `±max_offset`), then three rounds alternating a
//! compass search of the offset (down to 1/32 texel) with golden-section passes on the angle
//! over shrinking brackets; the lowest refined residual wins. Each residual evaluation is a
//! single pass over the canvas with flat arrays (one channel-sized scratch buffer).

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::error::{MiningError, Result, check_values};
use crate::image::PlaneImage;

/// Which canvas texels enter the residual.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum CompareRegion {
    /// Only where **both** patches have data: inside the instance and covered by the rotated
    /// template. The template value is border-normalised (bilinear taps outside the template
    /// are dropped and the rest re-weighted). Per-texel weight
    /// `coverage * max(w_template, w_instance)`. Right for crops of a plane whose background
    /// is not zero (the default).
    #[default]
    Overlap,
    /// The canvas padded to the rotated template's diagonal, with **zero** outside either
    /// patch; per-texel weight `max(w_template, w_instance)` (template weight bilinearly
    /// resampled, zero outside). Penalises parts of one patch that fall outside the other;
    /// right when the background is zero (e.g. masked patches).
    Union,
}

/// Parameters of [`estimate_yaw`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct YawOptions {
    /// Coarse angular step in degrees (> 0).
    pub step_deg: f32,
    /// Angles are searched in `[0, period_deg)`, `0 < period_deg <= 360`: use e.g. 180 or 90
    /// for objects with a known rotational symmetry. The result lies in that range.
    pub period_deg: f32,
    /// Angular tolerance of the refinement in degrees (> 0).
    pub tol_deg: f32,
    /// Half-width of the sub-texel offset search per axis, in texels (0 disables it).
    pub max_offset: f32,
    /// Align weighted centroids before the offset search: for each angle the offset starts at
    /// `c_instance - R(theta) c_template` (centroids relative to the patch centres). With
    /// uniform weights both centroids are the centres and this changes nothing.
    pub align_centroids: bool,
    /// Which texels are compared.
    pub region: CompareRegion,
    /// At most how many coarse minima are refined, lowest first (at least 1; `None`: every
    /// one lower than the scan's median); the best refined pose wins. Refining every basin
    /// better than a typical angle guards against near-symmetric shapes whose coarse ranking
    /// at zero offset is wrong (a laptop seen the other way round), at the cost of one
    /// refinement each.
    #[serde(default)]
    pub starts: Option<usize>,
}

/// The search mining runs ([`crate::pose::PoseOptions`] takes it as it is): a 4-degree coarse
/// scan, refined to 0.05 degrees, offsets within half the field's blur
/// ([`DetectParams::blur_levels`](crate::detect::DetectParams::blur_levels), 3 texels across
/// as up, the voxels being cubic): a blurred edge lies anywhere within it, so a patch's
/// position is known to half of it either way (1.5 texels, which was a value of its own).
impl Default for YawOptions {
    fn default() -> Self {
        YawOptions {
            step_deg: 4.0,     // tuned: pose.yaw.step_deg
            period_deg: 360.0, // fixed: a full turn (no symmetry known)
            tol_deg: 0.05,     // fixed: a precision (0.01 mined the same, medians within 0.002 deg)
            max_offset: 0.5 * crate::detect::DetectParams::default().blur_levels as f32,
            align_centroids: true,
            region: CompareRegion::Overlap,
            starts: None,
        }
    }
}

/// Result of [`estimate_yaw`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct YawFit {
    /// Counter-clockwise yaw (x-right / y-up) taking the template onto the instance, in
    /// `[0, period_deg)`.
    pub yaw_deg: f32,
    /// Offset `(dx, dy)` in texels (x = columns, y = rows) of the rotated template centre
    /// relative to the instance centre, including the centroid alignment if enabled.
    pub offset: (f32, f32),
    /// Weighted mean squared difference per compared texel and channel at the optimum.
    pub residual: f32,
}

/// Estimate the yaw taking `template` onto `instance` (same channel count) with uniform
/// weights. See the module docs for conventions and the search.
pub fn estimate_yaw(
    template: &PlaneImage,
    instance: &PlaneImage,
    opts: &YawOptions,
) -> Result<YawFit> {
    estimate_yaw_weighted(template, None, instance, None, opts)
}

/// [`estimate_yaw`] with optional non-negative per-texel weights (`rows * cols` of the
/// respective patch), e.g. footprint masks or density: they steer which texels matter (see
/// [`CompareRegion`]) and the centroid alignment.
pub fn estimate_yaw_weighted(
    template: &PlaneImage,
    template_weights: Option<&[f32]>,
    instance: &PlaneImage,
    instance_weights: Option<&[f32]>,
    opts: &YawOptions,
) -> Result<YawFit> {
    check_options(opts)?;
    let p = Problem::new(template, template_weights, instance, instance_weights, opts)?;
    let step = f64::from(opts.step_deg);
    let period = f64::from(opts.period_deg);
    let tol = f64::from(opts.tol_deg);

    // 1. Coarse scan.
    let n = ((period / step).ceil() as usize).max(1);
    let coarse: Vec<f64> =
        (0..n).into_par_iter().map(|i| p.residual(i as f64 * step, (0.0, 0.0))).collect();
    let (best_i, best_r) = coarse
        .iter()
        .enumerate()
        .fold((0, f64::INFINITY), |b, (i, &r)| if r < b.1 { (i, r) } else { b });
    if !best_r.is_finite() {
        return Err(MiningError::NoOverlap);
    }
    // 2-3. Refine from the best few coarse minima and keep the best result: at zero offset
    // a half-texel misalignment can rank a near-symmetric wrong turn (a laptop seen the
    // other way round) just below the right one, which only the offset search exposes.
    let mut best: Option<Pose> = None;
    for start in coarse_minima(&coarse, opts.starts.unwrap_or(usize::MAX)) {
        let pose = refine(
            &p,
            Pose { theta: start as f64 * step, delta: (0.0, 0.0), r: coarse[start] },
            step,
            tol,
            opts.max_offset,
        );
        if best.is_none_or(|b| pose.r < b.r) {
            best = Some(pose);
        }
    }
    let best = best.unwrap_or(Pose { theta: best_i as f64 * step, delta: (0.0, 0.0), r: best_r });
    Ok(p.fit(best, opts.period_deg))
}

/// [`estimate_yaw_weighted`] without the coarse scan: the pose is refined from `start_deg`
/// only (golden-section over one coarse step either side, then the offset rounds), so the
/// basin is the caller's (e.g. chosen on other patches of the same pair) and only the optimum
/// within it is found here. The yaw is reported in `[0, period_deg)`.
pub fn estimate_yaw_near(
    template: &PlaneImage,
    template_weights: Option<&[f32]>,
    instance: &PlaneImage,
    instance_weights: Option<&[f32]>,
    start_deg: f32,
    opts: &YawOptions,
) -> Result<YawFit> {
    check_options(opts)?;
    if !start_deg.is_finite() {
        return Err(MiningError::InvalidParameter {
            name: "start_deg",
            reason: format!("must be finite, got {start_deg}"),
        });
    }
    let p = Problem::new(template, template_weights, instance, instance_weights, opts)?;
    let theta = f64::from(start_deg);
    let r = p.residual(theta, (0.0, 0.0));
    if !r.is_finite() {
        return Err(MiningError::NoOverlap);
    }
    let best = refine(
        &p,
        Pose { theta, delta: (0.0, 0.0), r },
        f64::from(opts.step_deg),
        f64::from(opts.tol_deg),
        opts.max_offset,
    );
    Ok(p.fit(best, opts.period_deg))
}

/// Golden-section refinement of the angle at zero offset, then the sub-texel offset (a 5 x 5
/// grid over `±max_offset`), then rounds alternating a compass search of the offset with
/// angle passes over shrinking brackets.
fn refine(p: &Problem<'_>, start: Pose, step: f64, tol: f64, m: f32) -> Pose {
    let mut best = golden_theta(p, start, step, tol * 0.5);
    if m > 0.0 {
        for gy in -2..=2 {
            for gx in -2..=2 {
                let delta = (gx as f32 * 0.5 * m, gy as f32 * 0.5 * m);
                let r = p.residual(best.theta, delta);
                if r < best.r {
                    best = Pose { delta, r, ..best };
                }
            }
        }
        // Alternate offset and angle refinement with shrinking brackets: a sub-texel shift
        // can masquerade as a small rotation at zero offset, so the first angle pass must be
        // allowed to move back by up to half a coarse step.
        // fixed: the refinement's shrinking brackets (degrees), ending at the precision
        for (round, half) in [0.5 * step, 1.0, 0.25].into_iter().enumerate() {
            // fixed: the refinement's shrinking offset steps
            best = compass(p, best, m, 0.25 * m * 0.5f32.powi(round as i32));
            best = golden_theta(p, best, half.max(2.0 * tol), tol * 0.5);
        }
        best = compass(p, best, m, 1.0 / 16.0); // fixed: the refinement's last offset step (texels)
    }
    best
}

/// Indices of the local minima of a circular scan lower than its median, at most `k`, lowest
/// first (non-finite values count as infinite); the global minimum always comes first,
/// whatever the median. A flat stretch counts once (its first index), and only if the
/// nearest different values on both sides are higher: a shoulder on the way down is not a
/// minimum.
fn coarse_minima(r: &[f64], k: usize) -> Vec<usize> {
    let n = r.len();
    let v = |i: usize| if r[i].is_finite() { r[i] } else { f64::INFINITY };
    let mut minima: Vec<usize> = Vec::new();
    for i in 0..n {
        let x = v(i);
        if !x.is_finite() || (n > 1 && v((i + n - 1) % n) == x) {
            continue; // infinite, or not the first of its flat stretch
        }
        let next = (1..n).map(|s| v((i + s) % n)).find(|&y| y != x);
        let prev = (1..n).map(|s| v((i + n - s) % n)).find(|&y| y != x);
        if next.is_none_or(|y| y > x) && prev.is_none_or(|y| y > x) {
            minima.push(i);
        }
    }
    if minima.is_empty() {
        // constant scans: the first finite sample
        minima.extend((0..n).find(|&i| v(i).is_finite()));
    }
    minima.sort_by(|&a, &b| r[a].total_cmp(&r[b]).then(a.cmp(&b)));
    // a basin worth refining is better than a typical angle: below the scan's median (the
    // majority, not a tuned value)
    let mut finite: Vec<f64> = r.iter().copied().filter(|x| x.is_finite()).collect();
    finite.sort_by(f64::total_cmp);
    let median = finite.get(finite.len() / 2).copied().unwrap_or(f64::INFINITY);
    let below = minima.iter().filter(|&&i| r[i] < median).count();
    minima.truncate(below.clamp(1, k.max(1)));
    minima
}

/// The residual of one pose (yaw in degrees, offset in texels, exactly as reported by
/// [`YawFit`]; centroid alignment is not applied here), for diagnostics and custom searches.
pub fn yaw_residual(
    template: &PlaneImage,
    instance: &PlaneImage,
    yaw_deg: f32,
    offset: (f32, f32),
    region: CompareRegion,
) -> Result<f32> {
    yaw_residual_weighted(template, None, instance, None, yaw_deg, offset, region)
}

/// [`yaw_residual`] with per-texel weights, as [`estimate_yaw_weighted`] weighs them: the
/// residual it reports for its fit is this function at the fit's yaw and offset. Used to
/// judge a pose found on one kind of patch by how well it reproduces another.
pub fn yaw_residual_weighted(
    template: &PlaneImage,
    template_weights: Option<&[f32]>,
    instance: &PlaneImage,
    instance_weights: Option<&[f32]>,
    yaw_deg: f32,
    offset: (f32, f32),
    region: CompareRegion,
) -> Result<f32> {
    let opts = YawOptions { align_centroids: false, region, ..YawOptions::default() };
    let p = Problem::new(template, template_weights, instance, instance_weights, &opts)?;
    let r = p.residual(f64::from(yaw_deg), offset);
    if r.is_finite() { Ok(r as f32) } else { Err(MiningError::NoOverlap) }
}

fn check_options(o: &YawOptions) -> Result<()> {
    let bad = |name: &'static str, v: f32| MiningError::InvalidParameter {
        name,
        reason: format!("out of range: {v}"),
    };
    if !(o.step_deg.is_finite() && o.step_deg > 0.0) {
        return Err(bad("step_deg", o.step_deg));
    }
    // fixed: a full turn
    if !(o.period_deg.is_finite() && o.period_deg > 0.0 && o.period_deg <= 360.0) {
        return Err(bad("period_deg", o.period_deg));
    }
    if !(o.tol_deg.is_finite() && o.tol_deg > 0.0) {
        return Err(bad("tol_deg", o.tol_deg));
    }
    if !(o.max_offset.is_finite() && o.max_offset >= 0.0) {
        return Err(bad("max_offset", o.max_offset));
    }
    Ok(())
}

#[derive(Debug, Clone, Copy)]
struct Pose {
    theta: f64,
    delta: (f32, f32),
    r: f64,
}

/// Golden-section search of the angle over `[theta - half, theta + half]`, offset fixed;
/// never returns a pose worse than `start`.
fn golden_theta(p: &Problem<'_>, start: Pose, half: f64, tol: f64) -> Pose {
    let g = (5f64.sqrt() - 1.0) * 0.5; // fixed: the golden section
    let f = |t: f64| p.residual(t, start.delta);
    let (mut a, mut b) = (start.theta - half, start.theta + half);
    let mut c = b - g * (b - a);
    let mut d = a + g * (b - a);
    let (mut fc, mut fd) = (f(c), f(d));
    let mut best = start;
    while b - a > tol {
        if fc < fd {
            b = d;
            d = c;
            fd = fc;
            c = b - g * (b - a);
            fc = f(c);
        } else {
            a = c;
            c = d;
            fc = fd;
            d = a + g * (b - a);
            fd = f(d);
        }
        for (t, r) in [(c, fc), (d, fd)] {
            if r < best.r {
                best = Pose { theta: t, r, ..best };
            }
        }
    }
    best
}

/// Compass (pattern) search of the offset within `±limit`, from `step` down to 1/32 texel.
fn compass(p: &Problem<'_>, start: Pose, limit: f32, step: f32) -> Pose {
    let mut best = start;
    let mut s = step;
    // fixed: the offset precision (texels)
    while s >= 1.0 / 32.0 {
        let mut moved = false;
        for (ux, uy) in [(1.0, 0.0), (-1.0, 0.0), (0.0, 1.0), (0.0, -1.0)] {
            let delta = (best.delta.0 + ux * s, best.delta.1 + uy * s);
            if delta.0.abs() > limit + 1e-6 || delta.1.abs() > limit + 1e-6 {
                continue;
            }
            let r = p.residual(best.theta, delta);
            if r < best.r {
                best = Pose { delta, r, ..best };
                moved = true;
            }
        }
        if !moved {
            s *= 0.5;
        }
    }
    best
}

/// Weighted centroid relative to the patch centre; `None` if the weights sum to zero.
fn centroid(rows: usize, cols: usize, w: &[f32]) -> Option<(f32, f32)> {
    let (cx, cy) = ((cols as f64 - 1.0) * 0.5, (rows as f64 - 1.0) * 0.5);
    let (mut sx, mut sy, mut sw) = (0f64, 0f64, 0f64);
    for r in 0..rows {
        for c in 0..cols {
            let v = f64::from(w[r * cols + c]);
            sx += v * (c as f64 - cx);
            sy += v * (r as f64 - cy);
            sw += v;
        }
    }
    (sw > 0.0).then(|| ((sx / sw) as f32, (sy / sw) as f32))
}

fn check_weights(what: &'static str, w: Option<&[f32]>, n: usize) -> Result<Vec<f32>> {
    match w {
        None => Ok(vec![1.0; n]),
        Some(w) => {
            if w.len() != n {
                return Err(MiningError::ShapeMismatch { what, expected: n, actual: w.len() });
            }
            check_values(what, w, true)?;
            if !w.iter().any(|&v| v > 0.0) {
                return Err(MiningError::ZeroWeight { what });
            }
            Ok(w.to_vec())
        }
    }
}

/// Prepared data of one template/instance pair.
struct Problem<'a> {
    ch: usize,
    /// Template values with a one-texel zero frame, `(rows + 2) * (cols + 2) * ch`.
    t: Vec<f32>,
    /// Per padded template texel: (inside flag, weight), both zero on the frame.
    tvw: Vec<[f32; 2]>,
    tpr: usize,
    tpc: usize,
    /// Template centre in padded coordinates.
    tc: (f32, f32),
    inst: &'a PlaneImage,
    iw: Vec<f32>,
    ic: (f32, f32),
    /// Canvas margin around the instance (0 for `Overlap`).
    margin: usize,
    region: CompareRegion,
    /// Weighted centroids relative to the patch centres (zero if alignment is off).
    ct: (f32, f32),
    ci: (f32, f32),
}

impl<'a> Problem<'a> {
    fn new(
        template: &PlaneImage,
        template_weights: Option<&[f32]>,
        instance: &'a PlaneImage,
        instance_weights: Option<&[f32]>,
        opts: &YawOptions,
    ) -> Result<Self> {
        template.validate()?;
        instance.validate()?;
        if template.ch != instance.ch {
            return Err(MiningError::SizeMismatch {
                what: "template vs instance channels",
                left: template.ch,
                right: instance.ch,
            });
        }
        let tw = check_weights("template weights", template_weights, template.texels())?;
        let iw = check_weights("instance weights", instance_weights, instance.texels())?;
        let ch = template.ch;
        let (tpr, tpc) = (template.rows + 2, template.cols + 2);
        let mut t = vec![0f32; tpr * tpc * ch];
        let mut tvw = vec![[0f32; 2]; tpr * tpc];
        for r in 0..template.rows {
            let src = &template.data[r * template.cols * ch..(r + 1) * template.cols * ch];
            let dst = ((r + 1) * tpc + 1) * ch;
            t[dst..dst + src.len()].copy_from_slice(src);
            for c in 0..template.cols {
                tvw[(r + 1) * tpc + c + 1] = [1.0, tw[r * template.cols + c]];
            }
        }
        let (tcx, tcy) = template.centre_xy();
        let (ct, ci) = if opts.align_centroids {
            (
                centroid(template.rows, template.cols, &tw).unwrap_or((0.0, 0.0)),
                centroid(instance.rows, instance.cols, &iw).unwrap_or((0.0, 0.0)),
            )
        } else {
            ((0.0, 0.0), (0.0, 0.0))
        };
        let margin = match opts.region {
            CompareRegion::Overlap => 0,
            CompareRegion::Union => {
                let diag = (template.rows as f32).hypot(template.cols as f32);
                let reach =
                    0.5 * diag + opts.max_offset + ct.0.hypot(ct.1) + ci.0.hypot(ci.1) + 2.0
                        - 0.5 * instance.rows.min(instance.cols) as f32;
                reach.max(0.0).ceil() as usize
            }
        };
        Ok(Problem {
            ch,
            t,
            tvw,
            tpr,
            tpc,
            tc: (tcx + 1.0, tcy + 1.0),
            inst: instance,
            iw,
            ic: instance.centre_xy(),
            margin,
            region: opts.region,
            ct,
            ci,
        })
    }

    /// Total offset for an angle: centroid alignment plus the searched correction.
    fn offset(&self, theta_deg: f64, delta: (f32, f32)) -> (f32, f32) {
        let (s, c) = theta_deg.to_radians().sin_cos();
        let (s, c) = (s as f32, c as f32);
        let rx = c * self.ct.0 - s * self.ct.1;
        let ry = s * self.ct.0 + c * self.ct.1;
        (self.ci.0 - rx + delta.0, self.ci.1 - ry + delta.1)
    }

    /// A searched pose as the caller sees it: the yaw in `[0, period_deg)`, the total offset.
    fn fit(&self, best: Pose, period_deg: f32) -> YawFit {
        YawFit {
            yaw_deg: best.theta.rem_euclid(f64::from(period_deg)) as f32 % period_deg,
            offset: self.offset(best.theta, best.delta),
            residual: best.r as f32,
        }
    }

    /// Normalised residual at a pose (`+inf` when nothing is compared).
    fn residual(&self, theta_deg: f64, delta: (f32, f32)) -> f64 {
        let (dx, dy) = self.offset(theta_deg, delta);
        let (s, c) = theta_deg.to_radians().sin_cos();
        let (s, c) = (s as f32, c as f32);
        let ch = self.ch;
        let (rows, cols) = (self.inst.rows as isize, self.inst.cols as isize);
        let m = self.margin as isize;
        let union = self.region == CompareRegion::Union;
        let (mut acc, mut wsum) = (0f64, 0f64);
        for y in -m..rows + m {
            let qy = y as f32 - self.ic.1 - dy;
            let inside_row = y >= 0 && y < rows;
            let mut row_acc = 0f32;
            let mut row_w = 0f32;
            for x in -m..cols + m {
                let qx = x as f32 - self.ic.0 - dx;
                let sx = c * qx + s * qy + self.tc.0;
                let sy = -s * qx + c * qy + self.tc.1;
                let inside = inside_row && x >= 0 && x < cols;
                let ii = if inside { (y * cols + x) as usize } else { 0 };
                let inst = if inside { &self.inst.data[ii * ch..(ii + 1) * ch] } else { &[][..] };
                let wi = if inside { self.iw[ii] } else { 0.0 };
                let (x0, y0) = (sx.floor(), sy.floor());
                let hit = x0 >= 0.0
                    && y0 >= 0.0
                    && x0 < (self.tpc - 1) as f32
                    && y0 < (self.tpr - 1) as f32;
                if !hit {
                    // Template absent: only the zero-padded comparison counts it.
                    if union && wi > 0.0 {
                        row_acc += wi * sum_of_squares(inst);
                        row_w += wi;
                    }
                    continue;
                }
                let (fx, fy) = (sx - x0, sy - y0);
                let i00 = y0 as usize * self.tpc + x0 as usize;
                let i10 = i00 + self.tpc;
                let b = [(1.0 - fx) * (1.0 - fy), fx * (1.0 - fy), (1.0 - fx) * fy, fx * fy];
                let taps = [i00, i00 + 1, i10, i10 + 1];
                let mut cov = 0f32;
                let mut wt = 0f32;
                for (bk, &ti) in b.iter().zip(&taps) {
                    cov += bk * self.tvw[ti][0];
                    wt += bk * self.tvw[ti][1];
                }
                let (t00, t01) = (&self.t[i00 * ch..][..ch], &self.t[(i00 + 1) * ch..][..ch]);
                let (t10, t11) = (&self.t[i10 * ch..][..ch], &self.t[(i10 + 1) * ch..][..ch]);
                let taps = [t00, t01, t10, t11];
                if union {
                    let w = wt.max(wi);
                    if w <= 0.0 {
                        continue;
                    }
                    let e = squared_error(b, taps, 1.0, inside.then_some(inst));
                    row_acc += w * e;
                    row_w += w;
                } else {
                    // fixed: a coverage floor (no overlap)
                    if !inside || cov <= 1e-4 {
                        continue;
                    }
                    let inv = 1.0 / cov;
                    let w = cov * (wt * inv).max(wi);
                    if w <= 0.0 {
                        continue;
                    }
                    let e = squared_error(b, taps, inv, Some(inst));
                    row_acc += w * e;
                    row_w += w;
                }
            }
            acc += f64::from(row_acc);
            wsum += f64::from(row_w);
        }
        if wsum <= 0.0 { f64::INFINITY } else { acc / (wsum * ch as f64) }
    }
}

/// Lanes of [`squared_error`]: the f32s of one 256-bit vector.
const LANES: usize = 8; // fixed: eight f32 lanes of a 256-bit vector

/// `sum_k (scale * sum_j b[j] t[j][k] - x[k])^2` over the channels `k` of one texel (`x` zero
/// when `None`): the template's bilinear value against the instance's, in [`LANES`]
/// independent sums, so that the channels vectorise instead of waiting on one another's
/// additions.
#[inline]
fn squared_error(b: [f32; 4], t: [&[f32]; 4], scale: f32, x: Option<&[f32]>) -> f32 {
    let n = t[0].len();
    debug_assert!(t.iter().all(|s| s.len() == n) && x.is_none_or(|x| x.len() == n));
    let full = n / LANES * LANES;
    fn lanes(s: &[f32], full: usize) -> &[[f32; LANES]] {
        s[..full].as_chunks::<LANES>().0
    }
    let [t0, t1, t2, t3] = t.map(|s| lanes(s, full));
    let value = |i: usize, j: usize| {
        scale * (b[0] * t0[i][j] + b[1] * t1[i][j] + b[2] * t2[i][j] + b[3] * t3[i][j])
    };
    let mut acc = [0f32; LANES];
    match x {
        Some(x) => {
            let xs = lanes(x, full);
            for (i, xi) in xs.iter().enumerate() {
                for j in 0..LANES {
                    let d = value(i, j) - xi[j];
                    acc[j] += d * d;
                }
            }
        }
        None => {
            for i in 0..t0.len() {
                for (j, a) in acc.iter_mut().enumerate() {
                    let d = value(i, j);
                    *a += d * d;
                }
            }
        }
    }
    let mut tail = 0f32;
    for k in full..n {
        let v = scale * (b[0] * t[0][k] + b[1] * t[1][k] + b[2] * t[2][k] + b[3] * t[3][k]);
        let d = v - x.map_or(0.0, |x| x[k]);
        tail += d * d;
    }
    acc.iter().sum::<f32>() + tail
}

/// `sum_k x[k]^2` in [`LANES`] independent sums (an instance texel where the template is
/// absent).
#[inline]
fn sum_of_squares(x: &[f32]) -> f32 {
    let (chunks, rest) = x.as_chunks::<LANES>();
    let mut acc = [0f32; LANES];
    for v in chunks {
        for j in 0..LANES {
            acc[j] += v[j] * v[j];
        }
    }
    acc.iter().sum::<f32>() + rest.iter().map(|v| v * v).sum::<f32>()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn texel_errors_in_lanes_match_a_plain_sum() {
        for n in [0, 1, 7, 8, 9, 17] {
            let chan = |s: f32| (0..n).map(|k| ((k as f32 + s) * 0.37).sin()).collect::<Vec<_>>();
            let (t0, t1, t2, t3, x) = (chan(0.0), chan(1.0), chan(2.0), chan(3.0), chan(4.0));
            let b = [0.1, 0.2, 0.3, 0.4];
            let tv = |k: usize| b[0] * t0[k] + b[1] * t1[k] + b[2] * t2[k] + b[3] * t3[k];
            let plain = |f: &dyn Fn(usize) -> f32| (0..n).map(|k| f(k) * f(k)).sum::<f32>();
            let close = |a: f32, b: f32| (a - b).abs() <= 1e-5 * (1.0 + b.abs());
            let taps = [&t0[..], &t1, &t2, &t3];
            let got = squared_error(b, taps, 1.0, Some(&x));
            assert!(close(got, plain(&|k| tv(k) - x[k])), "{n}: {got}");
            let got = squared_error(b, taps, 1.0, None);
            assert!(close(got, plain(&|k| tv(k))), "{n}: {got}");
            let got = squared_error(b, taps, 2.5, Some(&x));
            assert!(close(got, plain(&|k| tv(k) * 2.5 - x[k])), "{n}: {got}");
            assert!(close(sum_of_squares(&x), plain(&|k| x[k])), "{n}");
        }
    }
    use crate::rotate::rotate;

    /// A smooth, asymmetric, 3-channel "L" made of Gaussian blobs, as a function of the
    /// position relative to the object centre.
    fn l_shape(x: f32, y: f32) -> [f32; 3] {
        let mut v = [0f32; 3];
        let blob = |cx: f32, cy: f32| (-((x - cx).powi(2) + (y - cy).powi(2)) / 4.5).exp();
        for i in 0..7 {
            let a = -6.0 + 2.0 * i as f32;
            let h = blob(a, -6.0); // horizontal arm along +x
            let w = blob(-6.0, a + 2.0); // vertical arm along +y
            v[0] += h + w;
            v[1] += h * (i as f32 / 6.0);
            v[2] += 0.8 * w;
        }
        v
    }

    fn sample_plane(rows: usize, cols: usize, f: impl Fn(f32, f32) -> [f32; 3]) -> PlaneImage {
        let (cx, cy) = ((cols as f32 - 1.0) * 0.5, (rows as f32 - 1.0) * 0.5);
        PlaneImage::from_fn(rows, cols, 3, |r, c, k| f(c as f32 - cx, r as f32 - cy)[k]).unwrap()
    }

    /// Instance sampled analytically (no resampling of the template involved).
    fn analytic_instance(rows: usize, cols: usize, phi: f32, d: (f32, f32)) -> PlaneImage {
        let (s, c) = phi.to_radians().sin_cos();
        sample_plane(rows, cols, |x, y| {
            let (qx, qy) = (x - d.0, y - d.1);
            l_shape(c * qx + s * qy, -s * qx + c * qy)
        })
    }

    fn angle_err(a: f32, b: f32) -> f32 {
        let d = (a - b).rem_euclid(360.0);
        d.min(360.0 - d)
    }

    #[test]
    fn recovers_known_angles_from_rotated_template() {
        let template = sample_plane(33, 33, l_shape);
        let shift = (0.3, -0.4);
        for phi in [0.0f32, 37.0, 90.0, 180.0, 271.0, 333.3] {
            let inst = rotate(&template, phi, shift, 41, 45).unwrap();
            let fit = estimate_yaw(&template, &inst, &YawOptions::default()).unwrap();
            assert!(angle_err(fit.yaw_deg, phi) < 1.5, "phi {phi}: got {fit:?}");
            assert!((fit.offset.0 - shift.0).abs() < 0.25, "phi {phi}: got {fit:?}");
            assert!((fit.offset.1 - shift.1).abs() < 0.25, "phi {phi}: got {fit:?}");
            assert!(fit.residual < 1e-3, "phi {phi}: got {fit:?}");
        }
    }

    #[test]
    fn recovers_known_angles_from_analytic_instances() {
        let template = sample_plane(31, 35, l_shape);
        for (phi, shift) in [(37.0f32, (0.5, 0.25)), (90.0, (-0.3, 0.0)), (271.0, (0.2, 0.6))] {
            for region in [CompareRegion::Overlap, CompareRegion::Union] {
                let inst = analytic_instance(39, 37, phi, shift);
                let opts = YawOptions { region, ..YawOptions::default() };
                let fit = estimate_yaw(&template, &inst, &opts).unwrap();
                assert!(angle_err(fit.yaw_deg, phi) < 1.5, "{phi} {region:?}: {fit:?}");
                assert!((fit.offset.0 - shift.0).abs() < 0.3, "{phi} {region:?}: {fit:?}");
                assert!((fit.offset.1 - shift.1).abs() < 0.3, "{phi} {region:?}: {fit:?}");
            }
        }
    }

    #[test]
    fn symmetric_period_and_wrong_orientation() {
        // A 2-fold symmetric bar: with period 180 the answer lies in [0, 180).
        let bar = |x: f32, y: f32| {
            let v = (-(y * y) / 3.0).exp() * (-(x * x) / 60.0).exp();
            [v, 0.5 * v, 0.0]
        };
        let template = sample_plane(31, 31, bar);
        let inst = rotate(&template, 250.0, (0.0, 0.0), 31, 31).unwrap();
        let opts = YawOptions { period_deg: 180.0, ..YawOptions::default() };
        let fit = estimate_yaw(&template, &inst, &opts).unwrap();
        assert!((fit.yaw_deg - 70.0).abs() < 1.5, "{fit:?}");
        // The residual is much larger away from the optimum.
        let at_best =
            yaw_residual(&template, &inst, fit.yaw_deg, fit.offset, CompareRegion::Overlap);
        let off =
            yaw_residual(&template, &inst, fit.yaw_deg + 90.0, fit.offset, Default::default());
        assert!(off.unwrap() > 10.0 * at_best.unwrap().max(1e-6));
    }

    #[test]
    fn weighted_centroid_alignment_handles_large_shifts() {
        // The instance crop is off-centre by several texels; footprint weights fix it.
        let template = sample_plane(33, 33, l_shape);
        let shift = (3.0, -2.5);
        let inst = analytic_instance(37, 37, 120.0, shift);
        let weights = |img: &PlaneImage| -> Vec<f32> {
            img.data.chunks(3).map(|t| if t[0] > 0.2 { 1.0 } else { 0.0 }).collect()
        };
        let (tw, iw) = (weights(&template), weights(&inst));
        let fit =
            estimate_yaw_weighted(&template, Some(&tw), &inst, Some(&iw), &YawOptions::default())
                .unwrap();
        assert!(angle_err(fit.yaw_deg, 120.0) < 1.5, "{fit:?}");
        assert!((fit.offset.0 - shift.0).abs() < 0.4 && (fit.offset.1 - shift.1).abs() < 0.4);
        // the reported residual is the weighted residual at the reported pose
        let again = yaw_residual_weighted(
            &template,
            Some(&tw),
            &inst,
            Some(&iw),
            fit.yaw_deg,
            fit.offset,
            CompareRegion::Overlap,
        )
        .unwrap();
        assert!((again - fit.residual).abs() <= 1e-6 * fit.residual.max(1.0), "{again} {fit:?}");
        let turned = yaw_residual_weighted(
            &template,
            Some(&tw),
            &inst,
            Some(&iw),
            fit.yaw_deg + 90.0,
            fit.offset,
            CompareRegion::Overlap,
        )
        .unwrap();
        assert!(turned > 10.0 * again.max(1e-6), "{turned} vs {again}");
    }

    /// Deterministic numbers in [0, 1) for the generated shapes below.
    fn lcg(s: &mut u64) -> f32 {
        *s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((*s >> 40) as f32) / ((1u64 << 24) as f32)
    }

    #[test]
    fn near_symmetric_shapes_are_turned_the_right_way_round() {
        // Three pairs of blobs, each pair point-symmetric about the centre except for an
        // amplitude 0-15% lower on one side: turned by 180 degrees the shape almost matches
        // itself, like a laptop whose screen edge is only slightly denser. The instance is
        // the shape turned and shifted by up to half a texel, plus noise.
        let (mut wrong_single, mut wrong_multi) = (0, 0);
        for seed in 0..40u64 {
            let mut s = seed;
            let mut blobs: Vec<[f32; 5]> = Vec::new();
            for _ in 0..3 {
                let (x, y) = (lcg(&mut s) * 12.0 - 6.0, lcg(&mut s) * 8.0 - 4.0);
                let (amp, width, mix) = (0.5 + lcg(&mut s), 0.5 + 2.0 * lcg(&mut s), lcg(&mut s));
                let other = amp * (0.85 + 0.15 * lcg(&mut s));
                blobs.push([x, y, amp, width, mix]);
                blobs.push([-x, -y, other, width, mix]);
            }
            let shape = |x: f32, y: f32| {
                let mut v = [0f32; 3];
                for &[bx, by, amp, width, mix] in &blobs {
                    let g = amp * (-((x - bx).powi(2) + (y - by).powi(2)) / width).exp();
                    v[0] += g;
                    v[1] += g * mix;
                    v[2] += g * (1.0 - mix);
                }
                v
            };
            let phi = lcg(&mut s) * 360.0;
            let d = (lcg(&mut s) - 0.5, lcg(&mut s) - 0.5);
            let template = sample_plane(15, 19, shape);
            let (sn, cs) = phi.to_radians().sin_cos();
            let mut inst = sample_plane(15, 19, |x, y| {
                let (qx, qy) = (x - d.0, y - d.1);
                shape(cs * qx + sn * qy, -sn * qx + cs * qy)
            });
            for v in &mut inst.data {
                *v += 0.08 * (lcg(&mut s) - 0.5);
            }
            let single = YawOptions { starts: Some(1), ..YawOptions::default() };
            let fit1 = estimate_yaw(&template, &inst, &single).unwrap();
            let fit3 = estimate_yaw(&template, &inst, &YawOptions::default()).unwrap();
            assert!(fit3.residual <= fit1.residual, "seed {seed}: {fit3:?} vs {fit1:?}");
            wrong_single += usize::from(angle_err(fit1.yaw_deg, phi) > 1.5);
            wrong_multi += usize::from(angle_err(fit3.yaw_deg, phi) > 1.5);
        }
        // Refining only the best coarse angle turns several of them the wrong way round.
        assert!(wrong_single >= 3, "single start wrong {wrong_single} times");
        assert_eq!(wrong_multi, 0, "every deep basin refined: wrong {wrong_multi} times");
    }

    #[test]
    fn coarse_minima_are_circular_local_minima_lowest_first() {
        let r = [0.5, 3.0, 1.0, 2.0, 0.2, 0.2, 4.0, f64::INFINITY, 0.9];
        // 0.5 at index 0 has 0.9 before it (circularly): a minimum; the flat 0.2 counts once;
        // the minimum 1.0 at index 2 is the scan's median, no better than a typical angle
        assert_eq!(coarse_minima(&r, 5), vec![4, 0]);
        assert_eq!(coarse_minima(&r, usize::MAX), vec![4, 0]);
        // a scan mostly high: every dip lies below its median
        assert_eq!(coarse_minima(&[0.1, 5.0, 5.0, 0.3, 5.0, 5.0, 0.4, 5.0], 9), vec![0, 3, 6]);
        assert_eq!(coarse_minima(&r, 1), vec![4]);
        assert_eq!(coarse_minima(&[1.0, 1.0, 1.0], 3), vec![0]);
        assert_eq!(coarse_minima(&[f64::INFINITY, 2.0], 3), vec![1]);
        // a flat step on the way down is a shoulder, not a minimum
        assert_eq!(coarse_minima(&[3.0, 1.0, 1.0, 0.0, 2.0], 3), vec![3]);
        // a flat bottom wrapping around the end counts once, at its first index
        assert_eq!(coarse_minima(&[0.5, 2.0, 3.0, 0.5], 3), vec![3]);
        assert_eq!(coarse_minima(&[f64::NAN, 1.0, 2.0], 3), vec![1]);
    }

    #[test]
    fn bad_input_is_an_error() {
        let a = PlaneImage::zeros(5, 5, 3).unwrap();
        let b = PlaneImage::zeros(5, 5, 2).unwrap();
        assert!(estimate_yaw(&a, &b, &YawOptions::default()).is_err());
        let bad = YawOptions { step_deg: 0.0, ..YawOptions::default() };
        assert!(estimate_yaw(&a, &a, &bad).is_err());
        let bad = YawOptions { period_deg: 400.0, ..YawOptions::default() };
        assert!(estimate_yaw(&a, &a, &bad).is_err());
        let opts = YawOptions::default();
        assert!(estimate_yaw_weighted(&a, Some(&[1.0; 3]), &a, None, &opts).is_err());
        assert!(estimate_yaw_weighted(&a, Some(&[0.0; 25]), &a, None, &opts).is_err());
        let broken = PlaneImage { rows: 5, cols: 5, ch: 3, data: vec![0.0; 10] };
        assert!(estimate_yaw(&broken, &a, &opts).is_err());
        assert!(rotate(&broken, 10.0, (0.0, 0.0), 5, 5).is_err());
        // Flat patches: any angle fits, residual zero.
        assert_eq!(estimate_yaw(&a, &a, &opts).unwrap().residual, 0.0);
    }
}
