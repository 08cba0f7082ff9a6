//! A field's tensors, how a point reads them (density per sample, colour in batched tiles),
//! and the hand-written backward passes.

use crate::config::{DecoderKind, FieldConfig, ModelKind};
use crate::interp::{Bilinear, Linear};
use crate::mlp::{
    DenseDims, dense_accumulate, dense_backward, dense_forward, dot, relu, relu_backward, sigmoid,
    softplus,
};
use crate::params::{Group, ParamSet};
use crate::touched::TouchedBlocks;
use glam::Vec3;

/// A plane-axis pair: a plane over grid axes `axes[0]` (columns) and `axes[1]` (rows), and an
/// optional line over `axes[2]`. Offsets point into the flat parameter buffer.
#[derive(Debug, Clone, Copy)]
pub struct Comp {
    pub plane: usize,
    pub line: Option<usize>,
    pub axes: [usize; 3],
    pub cols: usize,
    pub rows: usize,
    pub len: usize,
    pub ch: usize,
}

impl Comp {
    #[inline]
    fn plane_at(&self, g: Vec3) -> Bilinear {
        Bilinear::new(g[self.axes[0]], g[self.axes[1]], self.cols, self.rows, self.ch)
    }
    #[inline]
    fn line_at(&self, g: Vec3) -> Linear {
        Linear::new(g[self.axes[2]], self.len, self.ch)
    }

    /// The four plane texels and two line samples (each `ch` channels) that `b` and `l` read.
    #[inline]
    fn taps<'a>(&self, d: &'a [f32], b: &Bilinear, l: &Linear) -> ([&'a [f32]; 4], [&'a [f32]; 2]) {
        let ch = self.ch;
        let line = self.line.expect("density components have lines");
        (b.idx.map(|i| &d[self.plane + i..][..ch]), l.idx.map(|i| &d[line + i..][..ch]))
    }
}

/// A dense layer's weight `[out][inn]` and bias offsets.
#[derive(Debug, Clone, Copy)]
pub struct Dense {
    pub w: usize,
    pub b: usize,
    pub inn: usize,
    pub out: usize,
}

impl Dense {
    /// Backward of [`Dense::forward`]: weight and bias gradients accumulated into `grad`
    /// (the flat layout), `dx = dy W` written when asked.
    #[inline]
    fn backward(
        &self,
        d: &[f32],
        grad: &mut [f32],
        x: &[f32],
        dy: &[f32],
        dx: Option<&mut [f32]>,
        n: usize,
    ) {
        let (gw, gb) = split_wb(grad, self);
        dense_backward(
            &d[self.w..][..self.inn * self.out],
            x,
            dy,
            dx,
            gw,
            Some(gb),
            DenseDims { batch: n, inn: self.inn, out: self.out },
        );
    }

    /// `y = W x + b` over a tile of `n` samples, reading the layer from the parameters `d`.
    #[inline]
    fn forward(&self, d: &[f32], x: &[f32], y: &mut [f32], n: usize) {
        dense_forward(
            &d[self.w..][..self.inn * self.out],
            Some(&d[self.b..][..self.out]),
            x,
            y,
            DenseDims { batch: n, inn: self.inn, out: self.out },
        );
    }
}

/// A radiance field on ground feature planes (or the VM baseline).
#[derive(Debug, Clone)]
pub struct Field {
    pub config: FieldConfig,
    pub params: ParamSet,
    density: Vec<Comp>,
    color: Vec<Comp>,
    basis: usize,
    decoder: Vec<Dense>,
    guide: Vec<Dense>,
    /// I-AssetField's semantic head: guidance MLP (2 layers) and linear decoder.
    guide_sem: Vec<Dense>,
    semantic: Option<Dense>,
    grid_min: Vec3,
    grid_scale: Vec3,
}

const AXIS_NAMES: [&str; 3] = ["x", "y", "z"];

/// Most channels a density or colour component may have (checked when a field file is
/// loaded; the backward passes work through any count in blocks of [`BACKWARD_BLOCK`]).
pub const MAX_CHANNELS: usize = 256;

/// Channels the backward passes of the grids handle at once (two stack buffers of this many
/// floats per sample): the default 16 density channels in one block, the 48 colour
/// channels in three.
const BACKWARD_BLOCK: usize = 16;

/// Deterministic normal samples (Box-Muller over SplitMix64).
struct Normal(u64);
impl Normal {
    fn next_u(&mut self) -> f32 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 40) as f32 / (1u64 << 24) as f32
    }
    fn normal(&mut self) -> f32 {
        let u1 = self.next_u().max(1e-7);
        let u2 = self.next_u();
        (-2.0 * u1.ln()).sqrt() * (std::f32::consts::TAU * u2).cos()
    }
}

impl Field {
    /// A new field with TensoRF-style random initialisation (grids ~ N(0, 0.1^2), layers
    /// uniform in +-1/sqrt(fan_in)).
    pub fn new(config: FieldConfig, seed: u64) -> Self {
        let mut rng = Normal(seed ^ 0xA55E_7F1E);
        let mut params = ParamSet::default();
        let res = config.res;
        let comps = |params: &mut ParamSet,
                     rng: &mut Normal,
                     prefix: &str,
                     ch: usize,
                     with_line: bool|
         -> Vec<Comp> {
            let sets: &[[usize; 3]] = if config.kind == ModelKind::Vm {
                &[[0, 1, 2], [0, 2, 1], [1, 2, 0]]
            } else {
                &[[0, 1, 2]]
            };
            sets.iter()
                .map(|&axes| {
                    let (cols, rows, len) = (res[axes[0]], res[axes[1]], res[axes[2]]);
                    let (pname, lname) = if config.kind == ModelKind::Vm {
                        (
                            format!(
                                "{prefix}.plane_{}{}",
                                AXIS_NAMES[axes[0]], AXIS_NAMES[axes[1]]
                            ),
                            format!("{prefix}.line_{}", AXIS_NAMES[axes[2]]),
                        )
                    } else {
                        (format!("{prefix}.plane"), format!("{prefix}.axis"))
                    };
                    let plane =
                        params.add(&pname, &[rows, cols, ch], Group::Grid, |_| 0.1 * rng.normal());
                    let line = with_line.then(|| {
                        params.add(&lname, &[len, ch], Group::Grid, |_| 0.1 * rng.normal())
                    });
                    Comp { plane, line, axes, cols, rows, len, ch }
                })
                .collect()
        };
        let density = comps(&mut params, &mut rng, "density", config.density_channels, true);
        let color = comps(
            &mut params,
            &mut rng,
            "color",
            config.color_channels,
            config.kind != ModelKind::Integrated,
        );
        let dense = |params: &mut ParamSet,
                     rng: &mut Normal,
                     name: &str,
                     inn: usize,
                     out: usize,
                     with_bias: bool| {
            let k = 1.0 / (inn as f32).sqrt();
            let w = params.add(&format!("{name}.weight"), &[out, inn], Group::Network, |_| {
                k * (2.0 * rng.next_u() - 1.0)
            });
            let b = if with_bias {
                params.add(&format!("{name}.bias"), &[out], Group::Network, |_| {
                    k * (2.0 * rng.next_u() - 1.0)
                })
            } else {
                usize::MAX
            };
            Dense { w, b, inn, out }
        };
        let guide = if config.kind == ModelKind::Integrated {
            vec![
                dense(
                    &mut params,
                    &mut rng,
                    "guide.0",
                    config.density_channels,
                    config.guide_hidden,
                    true,
                ),
                dense(
                    &mut params,
                    &mut rng,
                    "guide.1",
                    config.guide_hidden,
                    config.color_channels,
                    true,
                ),
            ]
        } else {
            Vec::new()
        };
        let basis = dense(
            &mut params,
            &mut rng,
            "color.basis",
            config.app_dim(),
            config.features_dim(),
            false,
        )
        .w;
        let decoder = match &config.decoder {
            DecoderKind::Mlp { hidden, .. } => {
                let mut inn = config.features_dim() + config.view_encoding_dim();
                let mut layers = Vec::new();
                for (k, &h) in hidden.iter().chain(std::iter::once(&3)).enumerate() {
                    layers.push(dense(
                        &mut params,
                        &mut rng,
                        &format!("decoder.{k}"),
                        inn,
                        h,
                        true,
                    ));
                    inn = h;
                }
                layers
            }
            DecoderKind::Sh { .. } => Vec::new(),
        };
        // the semantic head comes last so fields without one keep their layout
        let sem = config.semantic_dim();
        let (guide_sem, semantic) = if sem > 0 {
            let (nd, gh, app) = (config.density_channels, config.guide_hidden, config.app_dim());
            (
                vec![
                    dense(&mut params, &mut rng, "guide_semantic.0", nd, gh, true),
                    dense(&mut params, &mut rng, "guide_semantic.1", gh, app, true),
                ],
                Some(dense(&mut params, &mut rng, "semantic.decoder", app, sem, true)),
            )
        } else {
            (Vec::new(), None)
        };
        let mut f = Field {
            config,
            params,
            density,
            color,
            basis,
            decoder,
            guide,
            guide_sem,
            semantic,
            grid_min: Vec3::ZERO,
            grid_scale: Vec3::ONE,
        };
        f.update_grid_transform();
        f
    }

    fn update_grid_transform(&mut self) {
        let a = self.config.aabb();
        let res = self.config.res;
        self.grid_min = a.min;
        self.grid_scale = Vec3::new((res[0] - 1) as f32, (res[1] - 1) as f32, (res[2] - 1) as f32)
            / a.extent().max(Vec3::splat(1e-9));
    }

    /// World position to continuous grid coordinates.
    #[inline]
    pub fn to_grid(&self, p: Vec3) -> Vec3 {
        (p - self.grid_min) * self.grid_scale
    }

    /// Density feature (before shift and softplus) at a world point.
    #[inline]
    pub fn density_feature<'a>(&'a self, p: Vec3) -> f32 {
        let g = self.to_grid(p);
        let d = &self.params.data;
        let mut acc = [0.0f32; 8];
        let mut tail = 0.0f32;
        for c in &self.density {
            let b = c.plane_at(g);
            let l = c.line_at(g);
            let ch = c.ch;
            let ([p0, p1, p2, p3], [l0, l1]) = c.taps(d, &b, &l);
            let [w0, w1, w2, w3] = b.w;
            let [v0, v1] = l.w;
            // eight independent lanes over fixed-width chunks so the channel loop vectorises
            let full = ch / 8 * 8;
            let lanes = |s: &'a [f32]| s[..full].as_chunks::<8>().0;
            let taps = lanes(p0).iter().zip(lanes(p1)).zip(lanes(p2)).zip(lanes(p3));
            for ((((a, b), c), e), (f, h)) in taps.zip(lanes(l0).iter().zip(lanes(l1))) {
                for k in 0..8 {
                    let m = w0 * a[k] + w1 * b[k] + w2 * c[k] + w3 * e[k];
                    acc[k] += m * (v0 * f[k] + v1 * h[k]);
                }
            }
            for i in full..ch {
                let m = w0 * p0[i] + w1 * p1[i] + w2 * p2[i] + w3 * p3[i];
                tail += m * (v0 * l0[i] + v1 * l1[i]);
            }
        }
        acc.iter().sum::<f32>() + tail
    }

    /// Volume density at a world point.
    #[inline]
    pub fn density(&self, p: Vec3) -> f32 {
        softplus(self.density_feature(p) + self.config.density_shift)
    }

    /// Volume densities at `(x, y, z)` for every `z` of `zs`, into `out` (same length): equal
    /// to [`Field::density`] at each point, bit for bit, but a ground plane (an XY plane
    /// with a Z axis: S- and I-AssetField) is interpolated once per column instead of once
    /// per point. `scratch` is reused between calls.
    pub fn density_column(
        &self,
        x: f32,
        y: f32,
        zs: &[f32],
        scratch: &mut Vec<f32>,
        out: &mut [f32],
    ) {
        debug_assert_eq!(zs.len(), out.len());
        let d = &self.params.data;
        let n = zs.len();
        // per point: eight lanes and a tail, summed at the end exactly as density_feature does
        let mut lanes = vec![[0.0f32; 8]; n];
        let mut tails = vec![0.0f32; n];
        for c in &self.density {
            let ch = c.ch;
            let full = ch / 8 * 8;
            if c.axes == [0, 1, 2] {
                let g0 = self.to_grid(Vec3::new(x, y, zs.first().copied().unwrap_or(0.0)));
                let b = c.plane_at(g0);
                let [w0, w1, w2, w3] = b.w;
                let p = b.idx.map(|i| &d[c.plane + i..][..ch]);
                scratch.clear();
                scratch.extend(
                    (0..ch).map(|i| w0 * p[0][i] + w1 * p[1][i] + w2 * p[2][i] + w3 * p[3][i]),
                );
                let line = c.line.expect("density components have lines");
                for (k, &z) in zs.iter().enumerate() {
                    let l = c.line_at(self.to_grid(Vec3::new(x, y, z)));
                    let [v0, v1] = l.w;
                    let (l0, l1) = (&d[line + l.idx[0]..][..ch], &d[line + l.idx[1]..][..ch]);
                    let acc = &mut lanes[k];
                    for q in (0..full).step_by(8) {
                        for j in 0..8 {
                            let i = q + j;
                            acc[j] += scratch[i] * (v0 * l0[i] + v1 * l1[i]);
                        }
                    }
                    for i in full..ch {
                        tails[k] += scratch[i] * (v0 * l0[i] + v1 * l1[i]);
                    }
                }
            } else {
                for (k, &z) in zs.iter().enumerate() {
                    let g = self.to_grid(Vec3::new(x, y, z));
                    let (b, l) = (c.plane_at(g), c.line_at(g));
                    let ([p0, p1, p2, p3], [l0, l1]) = c.taps(d, &b, &l);
                    let [w0, w1, w2, w3] = b.w;
                    let [v0, v1] = l.w;
                    let acc = &mut lanes[k];
                    for q in (0..full).step_by(8) {
                        for j in 0..8 {
                            let i = q + j;
                            let m = w0 * p0[i] + w1 * p1[i] + w2 * p2[i] + w3 * p3[i];
                            acc[j] += m * (v0 * l0[i] + v1 * l1[i]);
                        }
                    }
                    for i in full..ch {
                        let m = w0 * p0[i] + w1 * p1[i] + w2 * p2[i] + w3 * p3[i];
                        tails[k] += m * (v0 * l0[i] + v1 * l1[i]);
                    }
                }
            }
        }
        for k in 0..n {
            let f = lanes[k].iter().sum::<f32>() + tails[k];
            out[k] = softplus(f + self.config.density_shift);
        }
    }

    /// `d density_feature / d params * d_feat`, accumulated into `grad`, for each point of
    /// `points` with its `d_feats` (points with a zero gradient are passed over): the plane
    /// taps get `w_t * d_feat * line`, the line taps `v_t * d_feat * plane`, channel by
    /// channel in blocks of [`BACKWARD_BLOCK`]. Consecutive points that read the same four
    /// texels (or the same two line samples), as the samples of one ray mostly do, add up
    /// in a small buffer that reaches `grad` once: the gradient's memory is written once per
    /// texel met, not once per sample.
    /// The plane blocks written are marked in `touched` (see [`crate::touched`]).
    pub fn density_backward(
        &self,
        points: &[Vec3],
        d_feats: &[f32],
        grad: &mut [f32],
        touched: &mut TouchedBlocks,
    ) {
        const B: usize = BACKWARD_BLOCK;
        let d = &self.params.data;
        for c in &self.density {
            let line = c.line.expect("density components have lines");
            for q0 in (0..c.ch).step_by(B) {
                let n = (c.ch - q0).min(B);
                let (mut quad, mut pair) = (None::<[usize; 4]>, None::<[usize; 2]>);
                let mut dp = [[0.0f32; B]; 4];
                let mut dl = [[0.0f32; B]; 2];
                for (&p, &d_feat) in points.iter().zip(d_feats) {
                    if d_feat == 0.0 {
                        continue;
                    }
                    let g = self.to_grid(p);
                    let (b, l) = (c.plane_at(g), c.line_at(g));
                    let ([p0, p1, p2, p3], [l0, l1]) = c.taps(d, &b, &l);
                    if quad != Some(b.idx) {
                        if let Some(q) = quad {
                            flush(grad, c.plane + q0, q, &mut dp, n, touched);
                        }
                        quad = Some(b.idx);
                    }
                    if pair != Some(l.idx) {
                        if let Some(q) = pair {
                            flush(grad, line + q0, q, &mut dl, n, touched);
                        }
                        pair = Some(l.idx);
                    }
                    let [w0, w1, w2, w3] = b.w;
                    let [v0, v1] = l.w;
                    for k in 0..n {
                        let i = q0 + k;
                        let m = w0 * p0[i] + w1 * p1[i] + w2 * p2[i] + w3 * p3[i];
                        let h = v0 * l0[i] + v1 * l1[i];
                        let (dm, dh) = (d_feat * h, d_feat * m);
                        dp[0][k] += w0 * dm;
                        dp[1][k] += w1 * dm;
                        dp[2][k] += w2 * dm;
                        dp[3][k] += w3 * dm;
                        dl[0][k] += v0 * dh;
                        dl[1][k] += v1 * dh;
                    }
                }
                if let Some(q) = quad {
                    flush(grad, c.plane + q0, q, &mut dp, n, touched);
                }
                if let Some(q) = pair {
                    flush(grad, line + q0, q, &mut dl, n, touched);
                }
            }
        }
    }

    /// Evaluate colours of the tile's samples (`work.pos`, `work.dir`) into `work.rgb`.
    pub fn color_forward(&self, w: &mut ColorWork) {
        let n = w.pos.len();
        let cfg = &self.config;
        let d = &self.params.data;
        let app_dim = cfg.app_dim();
        let fdim = cfg.features_dim();
        w.resize(n, cfg, &self.decoder);
        // 1. appearance features
        match cfg.kind {
            ModelKind::Standard | ModelKind::Vm => {
                for j in 0..n {
                    let g = self.to_grid(w.pos[j]);
                    let mut off = 0;
                    for c in &self.color {
                        let (m, h) = (
                            &mut w.m[j * app_dim + off..][..c.ch],
                            &mut w.h[j * app_dim + off..][..c.ch],
                        );
                        c.plane_at(g).gather(&d[c.plane..], m);
                        c.line_at(g).gather(&d[c.line.expect("colour line")..], h);
                        let app = &mut w.app[j * app_dim + off..][..c.ch];
                        for k in 0..c.ch {
                            app[k] = m[k] * h[k];
                        }
                        off += c.ch;
                    }
                }
            }
            ModelKind::Integrated => {
                let dc = &self.density[0];
                let (nd, gh) = (dc.ch, cfg.guide_hidden);
                for j in 0..n {
                    let g = self.to_grid(w.pos[j]);
                    let (gm, gl) = (&mut w.gm[j * nd..][..nd], &mut w.gh[j * nd..][..nd]);
                    dc.plane_at(g).gather(&d[dc.plane..], gm);
                    dc.line_at(g).gather(&d[dc.line.expect("density line")..], gl);
                    for k in 0..nd {
                        w.gin[j * nd + k] = gm[k] * gl[k];
                    }
                    let cc = &self.color[0];
                    cc.plane_at(g).gather(&d[cc.plane..], &mut w.m[j * app_dim..][..app_dim]);
                }
                let (l0, l1) = (self.guide[0], self.guide[1]);
                l0.forward(d, &w.gin, &mut w.ghid, n);
                relu(&mut w.ghid[..n * gh]);
                l1.forward(d, &w.ghid, &mut w.h, n);
                for k in 0..n * app_dim {
                    w.app[k] = w.m[k] * w.h[k];
                }
                if let Some(sem) = self.semantic.filter(|_| w.want_semantic) {
                    let (s0, s1) = (self.guide_sem[0], self.guide_sem[1]);
                    s0.forward(d, &w.gin, &mut w.shid, n);
                    relu(&mut w.shid[..n * gh]);
                    s1.forward(d, &w.shid, &mut w.sv, n);
                    for k in 0..n * app_dim {
                        w.sapp[k] = w.m[k] * w.sv[k];
                    }
                    sem.forward(d, &w.sapp, &mut w.sem, n);
                }
            }
        }
        // 2. basis
        dense_forward(
            &d[self.basis..][..fdim * app_dim],
            None,
            &w.app,
            &mut w.feat,
            DenseDims { batch: n, inn: app_dim, out: fdim },
        );
        // 3. decoder
        match &cfg.decoder {
            DecoderKind::Mlp { view_freqs, .. } => {
                self.view_runs(w, *view_freqs);
                // layer 0: the features' share per sample, the view inputs' share per run of
                // samples along one direction (a bias per ray)
                let l0 = self.decoder[0];
                let vdim = cfg.view_encoding_dim();
                let runs = w.runs.len() - 1;
                w.vbias.resize(runs * l0.out, 0.0);
                let (wt, bias) = (&d[l0.w..][..l0.inn * l0.out], &d[l0.b..][..l0.out]);
                for r in 0..runs {
                    let enc = &w.venc[r * vdim..][..vdim];
                    for o in 0..l0.out {
                        w.vbias[r * l0.out + o] =
                            bias[o] + dot(&wt[o * l0.inn + fdim..][..vdim], enc);
                    }
                }
                let y0 = &mut w.acts[1];
                for r in 0..runs {
                    let b = &w.vbias[r * l0.out..][..l0.out];
                    for j in w.runs[r] as usize..w.runs[r + 1] as usize {
                        y0[j * l0.out..][..l0.out].copy_from_slice(b);
                    }
                }
                dense_accumulate(wt, l0.inn, &w.feat, y0, n, fdim, l0.out);
                let last = self.decoder.len() - 1;
                for (k, l) in self.decoder.iter().enumerate() {
                    let (head, tail) = w.acts.split_at_mut(k + 1);
                    if k > 0 {
                        l.forward(d, &head[k], &mut tail[0], n);
                    }
                    if k < last {
                        relu(&mut tail[0][..n * l.out]);
                    }
                }
                let out = &w.acts[last + 1];
                for k in 0..n * 3 {
                    w.rgb[k] = sigmoid(out[k]);
                }
            }
            DecoderKind::Sh { degree } => {
                let kk = (degree + 1) * (degree + 1);
                let mut y = [0.0f32; 9];
                for j in 0..n {
                    sh_basis(w.dir[j], *degree, &mut y);
                    for c in 0..3 {
                        let f = &w.feat[j * fdim + c * kk..][..kk];
                        let z: f32 = (0..kk).map(|k| y[k] * f[k]).sum();
                        w.rgb[j * 3 + c] = sigmoid(z);
                    }
                }
            }
        }
    }

    /// Backward of [`Field::color_forward`] for `d_rgb` (`[n][3]`) and, when the field has a
    /// semantic head and the forward pass evaluated it, `d_sem` (`[n][semantic_channels]`),
    /// accumulated into `grad`; the plane blocks written are marked in `touched`.
    pub fn color_backward(
        &self,
        w: &mut ColorWork,
        d_rgb: &[f32],
        d_sem: Option<&[f32]>,
        grad: &mut [f32],
        touched: &mut TouchedBlocks,
    ) {
        let n = w.pos.len();
        let cfg = &self.config;
        let d = &self.params.data;
        let app_dim = cfg.app_dim();
        let fdim = cfg.features_dim();
        // decoder
        match &cfg.decoder {
            DecoderKind::Mlp { .. } => {
                let last = self.decoder.len() - 1;
                // d pre-sigmoid
                let mut dy = std::mem::take(&mut w.dtmp[last + 1]);
                dy.resize(n * 3, 0.0);
                for k in 0..n * 3 {
                    dy[k] = d_rgb[k] * w.rgb[k] * (1.0 - w.rgb[k]);
                }
                for (k, l) in self.decoder.iter().enumerate().rev().take(last) {
                    let mut dx = std::mem::take(&mut w.dtmp[k]);
                    dx.resize(n * l.inn, 0.0);
                    l.backward(d, grad, &w.acts[k], &dy, Some(&mut dx), n);
                    relu_backward(&w.acts[k][..n * l.inn], &mut dx);
                    w.dtmp[k + 1] = dy;
                    dy = dx;
                }
                self.first_layer_backward(w, &dy, grad);
                w.dtmp[0] = dy;
            }
            DecoderKind::Sh { degree } => {
                let kk = (degree + 1) * (degree + 1);
                let mut y = [0.0f32; 9];
                for j in 0..n {
                    sh_basis(w.dir[j], *degree, &mut y);
                    for c in 0..3 {
                        let r = w.rgb[j * 3 + c];
                        let dz = d_rgb[j * 3 + c] * r * (1.0 - r);
                        for k in 0..kk {
                            w.dfeat[j * fdim + c * kk + k] = dz * y[k];
                        }
                    }
                }
            }
        }
        // basis
        dense_backward(
            &d[self.basis..][..fdim * app_dim],
            &w.app,
            &w.dfeat,
            Some(&mut w.dapp),
            &mut grad[self.basis..][..fdim * app_dim],
            None,
            DenseDims { batch: n, inn: app_dim, out: fdim },
        );
        // appearance features
        match cfg.kind {
            ModelKind::Standard | ModelKind::Vm => {
                // plane taps get dapp * line, line taps dapp * plane, in channel blocks
                for j in 0..n {
                    let g = self.to_grid(w.pos[j]);
                    let mut off = j * app_dim;
                    for c in &self.color {
                        let (b, l) = (c.plane_at(g), c.line_at(g));
                        let line = c.line.expect("colour line");
                        for &t in &b.idx {
                            touched.mark(c.plane + t, c.ch);
                        }
                        for q0 in (0..c.ch).step_by(BACKWARD_BLOCK) {
                            let nq = (c.ch - q0).min(BACKWARD_BLOCK);
                            let mut dm = [0.0f32; BACKWARD_BLOCK];
                            let mut dh = [0.0f32; BACKWARD_BLOCK];
                            let at = off + q0;
                            for k in 0..nq {
                                let da = w.dapp[at + k];
                                dm[k] = da * w.h[at + k];
                                dh[k] = da * w.m[at + k];
                            }
                            b.scatter(&mut grad[c.plane + q0..], &dm[..nq]);
                            l.scatter(&mut grad[line + q0..], &dh[..nq]);
                        }
                        off += c.ch;
                    }
                }
            }
            ModelKind::Integrated => {
                let dc = self.density[0];
                let (nd, gh) = (dc.ch, cfg.guide_hidden);
                // d m_c = dapp * v ; d v = dapp * m_c
                for k in 0..n * app_dim {
                    w.dv[k] = w.dapp[k] * w.m[k];
                    w.dapp[k] *= w.h[k];
                }
                // semantic head: d s -> d sapp -> (d m_c, d v_sem) -> guidance -> d gin
                let sem_head = match (self.semantic, d_sem) {
                    (Some(sem), Some(ds)) if w.want_semantic => Some((sem, ds)),
                    _ => None,
                };
                if let Some((sem, ds)) = sem_head {
                    sem.backward(d, grad, &w.sapp, ds, Some(&mut w.dsapp), n);
                    for k in 0..n * app_dim {
                        w.dsv[k] = w.dsapp[k] * w.m[k];
                        w.dapp[k] += w.dsapp[k] * w.sv[k];
                    }
                    let (s0, s1) = (self.guide_sem[0], self.guide_sem[1]);
                    s1.backward(d, grad, &w.shid, &w.dsv, Some(&mut w.dshid), n);
                    relu_backward(&w.shid[..n * gh], &mut w.dshid[..n * gh]);
                    s0.backward(d, grad, &w.gin, &w.dshid, Some(&mut w.dsgin), n);
                }
                let (l0, l1) = (self.guide[0], self.guide[1]);
                l1.backward(d, grad, &w.ghid, &w.dv, Some(&mut w.dghid), n);
                relu_backward(&w.ghid[..n * gh], &mut w.dghid[..n * gh]);
                l0.backward(d, grad, &w.gin, &w.dghid, Some(&mut w.dgin), n);
                if sem_head.is_some() {
                    for k in 0..n * nd {
                        w.dgin[k] += w.dsgin[k];
                    }
                }
                let cc = self.color[0];
                let mut tmp = vec![0.0f32; nd];
                for j in 0..n {
                    let g = self.to_grid(w.pos[j]);
                    let (cb, db) = (cc.plane_at(g), dc.plane_at(g));
                    for (&ct, &dt) in cb.idx.iter().zip(&db.idx) {
                        touched.mark(cc.plane + ct, cc.ch);
                        touched.mark(dc.plane + dt, dc.ch);
                    }
                    cb.scatter(&mut grad[cc.plane..], &w.dapp[j * app_dim..][..app_dim]);
                    for k in 0..nd {
                        tmp[k] = w.dgin[j * nd + k] * w.gh[j * nd + k];
                    }
                    db.scatter(&mut grad[dc.plane..], &tmp);
                    for k in 0..nd {
                        tmp[k] = w.dgin[j * nd + k] * w.gm[j * nd + k];
                    }
                    dc.line_at(g).scatter(&mut grad[dc.line.expect("density line")..], &tmp);
                }
            }
        }
    }

    /// Group the tile's samples into runs of one view direction (`w.runs`: run starts and
    /// the end) and encode each run's direction once (`w.venc`). Samples of one ray are
    /// adjacent, so a run is a ray (or one whole tile, as mining's fixed view).
    fn view_runs(&self, w: &mut ColorWork, view_freqs: usize) {
        let vdim = self.config.view_encoding_dim();
        w.runs.clear();
        w.venc.clear();
        for (j, dir) in w.dir.iter().enumerate() {
            if j == 0 || *dir != w.dir[j - 1] {
                w.runs.push(j as u32);
                let at = w.venc.len();
                w.venc.resize(at + vdim, 0.0);
                encode_view(*dir, view_freqs, &mut w.venc[at..]);
            }
        }
        w.runs.push(w.dir.len() as u32);
    }

    /// Backward of the decoder's first layer for `dy` (`[n][out]`, after the ReLU of its
    /// output): the feature columns' weights and `w.dfeat` from the samples, the view
    /// columns' weights from each run's summed `dy` (their inputs are one per run), the bias.
    fn first_layer_backward(&self, w: &mut ColorWork, dy: &[f32], grad: &mut [f32]) {
        let n = w.pos.len();
        let l0 = self.decoder[0];
        let fdim = self.config.features_dim();
        let vdim = l0.inn - fdim;
        let d = &self.params.data;
        let (out, inn) = (l0.out, l0.inn);
        // the feature columns as a contiguous [out][fdim] matrix, and their gradient
        w.w0f.clear();
        for o in 0..out {
            w.w0f.extend_from_slice(&d[l0.w + o * inn..][..fdim]);
        }
        w.dw0f.clear();
        w.dw0f.resize(out * fdim, 0.0);
        let (gw, gb) = split_wb(grad, &l0);
        dense_backward(
            &w.w0f,
            &w.feat,
            dy,
            Some(&mut w.dfeat),
            &mut w.dw0f,
            Some(gb),
            DenseDims { batch: n, inn: fdim, out },
        );
        for o in 0..out {
            let row = &mut gw[o * inn..][..fdim];
            for (g, v) in row.iter_mut().zip(&w.dw0f[o * fdim..][..fdim]) {
                *g += v;
            }
        }
        if vdim == 0 {
            return;
        }
        let mut sum = vec![0.0f32; out];
        for r in 0..w.runs.len() - 1 {
            sum.fill(0.0);
            for j in w.runs[r] as usize..w.runs[r + 1] as usize {
                for (s, v) in sum.iter_mut().zip(&dy[j * out..][..out]) {
                    *s += v;
                }
            }
            let enc = &w.venc[r * vdim..][..vdim];
            for o in 0..out {
                let row = &mut gw[o * inn + fdim..][..vdim];
                for (g, e) in row.iter_mut().zip(enc) {
                    *g = sum[o].mul_add(*e, *g);
                }
            }
        }
    }

    /// Components of the density field (for pictures and mining).
    pub fn density_components(&self) -> &[Comp] {
        &self.density
    }
    pub fn color_components(&self) -> &[Comp] {
        &self.color
    }
    /// Whether the field decodes a semantic feature (I-AssetField trained on feature maps).
    pub fn has_semantic(&self) -> bool {
        self.semantic.is_some()
    }
}

/// `grad[base + idx[t] ..][..n] += acc[t][..n]` for every tap `t`, tap by tap (border taps
/// may name the same texel twice), leaving `acc` zero; the blocks written are marked in
/// `touched`.
fn flush<const T: usize>(
    grad: &mut [f32],
    base: usize,
    idx: [usize; T],
    acc: &mut [[f32; BACKWARD_BLOCK]; T],
    n: usize,
    touched: &mut TouchedBlocks,
) {
    for (t, a) in idx.iter().zip(acc.iter_mut()) {
        touched.mark(base + t, n);
        for (o, v) in grad[base + t..][..n].iter_mut().zip(a.iter_mut()) {
            *o += *v;
            *v = 0.0;
        }
    }
}

fn split_wb<'a>(grad: &'a mut [f32], l: &Dense) -> (&'a mut [f32], &'a mut [f32]) {
    // weights and bias are adjacent (bias right after the weight) in the flat layout
    debug_assert_eq!(l.b, l.w + l.inn * l.out);
    let (w, rest) = grad[l.w..].split_at_mut(l.inn * l.out);
    (w, &mut rest[..l.out])
}

/// View direction followed by `sin(2^k d)`, `cos(2^k d)` for `k < freqs`.
#[inline]
pub fn encode_view(d: Vec3, freqs: usize, out: &mut [f32]) {
    out[..3].copy_from_slice(&d.to_array());
    for k in 0..freqs {
        let f = (1u32 << k) as f32;
        for a in 0..3 {
            out[3 + k * 6 + a] = (d[a] * f).sin();
            out[3 + k * 6 + 3 + a] = (d[a] * f).cos();
        }
    }
}

/// Real spherical harmonics up to degree 2 (9 values) of a unit direction.
#[inline]
pub fn sh_basis(d: Vec3, degree: usize, y: &mut [f32; 9]) {
    let (x, yy, z) = (d.x, d.y, d.z);
    y[0] = 0.282_094_8;
    if degree >= 1 {
        y[1] = -0.488_602_5 * yy;
        y[2] = 0.488_602_5 * z;
        y[3] = -0.488_602_5 * x;
    }
    if degree >= 2 {
        y[4] = 1.092_548_4 * x * yy;
        y[5] = -1.092_548_4 * yy * z;
        y[6] = 0.315_391_57 * (2.0 * z * z - x * x - yy * yy);
        y[7] = -1.092_548_4 * x * z;
        y[8] = 0.546_274_2 * (x * x - yy * yy);
    }
}

/// Reusable buffers for a tile of colour samples (no allocation per sample).
#[derive(Debug, Default, Clone)]
pub struct ColorWork {
    pub pos: Vec<Vec3>,
    pub dir: Vec<Vec3>,
    pub rgb: Vec<f32>,
    /// Evaluate the semantic head too (fields that have one).
    pub want_semantic: bool,
    /// Semantic features `[n][semantic_channels]` (when evaluated).
    pub sem: Vec<f32>,
    m: Vec<f32>,
    h: Vec<f32>,
    app: Vec<f32>,
    feat: Vec<f32>,
    acts: Vec<Vec<f32>>,
    dtmp: Vec<Vec<f32>>,
    dfeat: Vec<f32>,
    dapp: Vec<f32>,
    gm: Vec<f32>,
    gh: Vec<f32>,
    gin: Vec<f32>,
    ghid: Vec<f32>,
    dv: Vec<f32>,
    dghid: Vec<f32>,
    dgin: Vec<f32>,
    shid: Vec<f32>,
    sv: Vec<f32>,
    sapp: Vec<f32>,
    dsapp: Vec<f32>,
    dsv: Vec<f32>,
    dshid: Vec<f32>,
    dsgin: Vec<f32>,
    /// Start of each run of samples with one view direction, and the end (see
    /// [`Field::view_runs`]); the encoded direction and the first layer's bias per run.
    runs: Vec<u32>,
    venc: Vec<f32>,
    vbias: Vec<f32>,
    w0f: Vec<f32>,
    dw0f: Vec<f32>,
}

impl ColorWork {
    pub fn clear(&mut self) {
        self.pos.clear();
        self.dir.clear();
    }

    fn resize(&mut self, n: usize, cfg: &FieldConfig, decoder: &[Dense]) {
        let a = cfg.app_dim();
        let f = cfg.features_dim();
        for (v, len) in [
            (&mut self.rgb, n * 3),
            (&mut self.m, n * a),
            (&mut self.h, n * a),
            (&mut self.app, n * a),
            (&mut self.feat, n * f),
            (&mut self.dfeat, n * f),
            (&mut self.dapp, n * a),
            (&mut self.dv, n * a),
        ] {
            v.resize(len, 0.0);
        }
        if cfg.kind == ModelKind::Integrated {
            let (nd, gh) = (cfg.density_channels, cfg.guide_hidden);
            for (v, len) in [
                (&mut self.gm, n * nd),
                (&mut self.gh, n * nd),
                (&mut self.gin, n * nd),
                (&mut self.ghid, n * gh),
                (&mut self.dghid, n * gh),
                (&mut self.dgin, n * nd),
            ] {
                v.resize(len, 0.0);
            }
            let sem = cfg.semantic_dim();
            if sem > 0 && self.want_semantic {
                for (v, len) in [
                    (&mut self.sem, n * sem),
                    (&mut self.shid, n * gh),
                    (&mut self.dshid, n * gh),
                    (&mut self.sv, n * a),
                    (&mut self.sapp, n * a),
                    (&mut self.dsapp, n * a),
                    (&mut self.dsv, n * a),
                    (&mut self.dsgin, n * nd),
                ] {
                    v.resize(len, 0.0);
                }
            }
        }
        if !decoder.is_empty() {
            self.acts.resize(decoder.len() + 1, Vec::new());
            self.dtmp.resize(decoder.len() + 2, Vec::new());
            // the first layer reads the features (`feat`) and the runs' view encodings
            for (k, l) in decoder.iter().enumerate() {
                self.acts[k + 1].resize(n * l.out, 0.0);
            }
        }
    }
}

impl Field {
    /// The same field at another plane resolution (coarse-to-fine): grids are resampled
    /// bilinearly (align corners), networks copied.
    pub fn resized(&self, plane_res: usize) -> Field {
        self.resized_to(self.config.resolution_for(plane_res))
    }

    /// The field resampled to the resolutions `res` (x, y, z); tensors that are not grids
    /// are copied.
    pub fn resized_to(&self, res: [usize; 3]) -> Field {
        let mut cfg = self.config.clone();
        cfg.res = res;
        let mut out = Field::new(cfg, 0);
        for spec in out.params.specs.clone() {
            let old = self.params.spec(&spec.name).expect("same model kind, same tensor names");
            let src = &self.params.data[old.offset..old.offset + old.len];
            let dst = match (spec.group, spec.shape.as_slice()) {
                (Group::Grid, [rows, cols, ch]) => crate::interp::resample_plane(
                    src,
                    old.shape[1],
                    old.shape[0],
                    *ch,
                    *cols,
                    *rows,
                ),
                (Group::Grid, [len, ch]) => {
                    crate::interp::resample_line(src, old.shape[0], *ch, *len)
                }
                _ => src.to_vec(),
            };
            out.params.data[spec.offset..spec.offset + spec.len].copy_from_slice(&dst);
        }
        out
    }

    /// Offsets and lengths of the tensors several scenes share (every tensor but the ground
    /// planes, see [`FieldConfig::is_plane_tensor`]), by name, in layout order.
    pub fn shared_ranges(&self) -> Vec<(&str, std::ops::Range<usize>)> {
        self.params
            .specs
            .iter()
            .filter(|s| !FieldConfig::is_plane_tensor(&s.name))
            .map(|s| (s.name.as_str(), s.offset..s.offset + s.len))
            .collect()
    }

    /// Copy the shared tensors (see [`Field::shared_ranges`]) of `from`, a field whose
    /// configuration can share with this one's ([`FieldConfig::sharing_mismatch`]).
    pub fn copy_shared_from(&mut self, from: &Field) {
        for (name, src) in from.shared_ranges() {
            let dst = self.params.spec(name).expect("sharing configurations have the same tensors");
            let dst = dst.offset..dst.offset + dst.len;
            self.params.data[dst].copy_from_slice(&from.params.data[src]);
        }
    }

    /// The planes whose gradient blocks the backward passes mark (see [`crate::touched`]):
    /// every density and colour component's plane. Everything else (lines, networks) is
    /// written on every iteration and not marked.
    pub fn marked_plane_ranges(&self) -> impl Iterator<Item = std::ops::Range<usize>> + '_ {
        self.density.iter().chain(&self.color).map(|c| c.plane..c.plane + c.rows * c.cols * c.ch)
    }
}
