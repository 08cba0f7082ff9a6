//! Pictures people read: line plots (training curves), false-colour pictures of learned
//! feature planes (PCA to RGB, as in the AssetField paper's Fig. 3) and of scalar planes
//! (density), all drawn on a [`Canvas`] or returned as RGB triples.

use crate::CoreError;
use crate::canvas::{BLACK, Canvas, Rgba, WHITE};
use glam::Vec2;
use rayon::prelude::*;
use std::path::Path;

/// Control points of the colour ramp used for errors and scalar planes: a perceptually
/// ordered ramp from dark violet through blue and green to yellow (viridis-like).
const RAMP: [[f32; 3]; 5] = [
    [68.0, 1.0, 84.0],
    [59.0, 82.0, 139.0],
    [33.0, 145.0, 140.0],
    [94.0, 201.0, 98.0],
    [253.0, 231.0, 37.0],
];

/// Colour of `t` in `[0, 1]` on the dark-violet-to-yellow ramp (piecewise linear between
/// five control points). Values outside are clamped; NaN maps to the bottom colour.
pub fn colormap(t: f32) -> [u8; 3] {
    let t = if t.is_nan() { 0.0 } else { t.clamp(0.0, 1.0) };
    let pos = t * (RAMP.len() - 1) as f32;
    let i = (pos.floor() as usize).min(RAMP.len() - 2);
    let f = pos - i as f32;
    let (lo, hi) = (RAMP[i], RAMP[i + 1]);
    std::array::from_fn(|k| (lo[k] + (hi[k] - lo[k]) * f).round().clamp(0.0, 255.0) as u8)
}

/// One curve of a [`line_plot`].
#[derive(Debug, Clone, PartialEq)]
pub struct Series {
    /// Shown in the legend; series with an empty label are left out of it.
    pub label: String,
    /// `(x, y)` points, drawn in the given order; non-finite points are skipped.
    pub points: Vec<(f64, f64)>,
    pub color: Rgba,
}

/// Layout and labels of a [`line_plot`].
#[derive(Debug, Clone, PartialEq)]
pub struct PlotOptions {
    pub title: String,
    pub x_label: String,
    pub y_label: String,
    /// Picture size in pixels.
    pub width: u32,
    pub height: u32,
    /// Fixed y range; `None` fits the data (with a 5% margin). Curves are clipped to it.
    pub y_range: Option<(f64, f64)>,
}

impl Default for PlotOptions {
    fn default() -> Self {
        PlotOptions {
            title: String::new(),
            x_label: String::new(),
            y_label: String::new(),
            width: 800,
            height: 500,
            y_range: None,
        }
    }
}

/// "Nice" tick values inside `[lo, hi]`: multiples of a step of 1, 2 or 5 times a power of
/// ten, the smallest such step that gives at most `max_ticks` ticks (at least 2 ticks are
/// aimed for; fewer only when the range is degenerate). Returns the ticks and the step.
pub fn nice_ticks(lo: f64, hi: f64, max_ticks: usize) -> (Vec<f64>, f64) {
    if !lo.is_finite() || !hi.is_finite() {
        return (Vec::new(), 0.0);
    }
    let (lo, hi) = if lo <= hi { (lo, hi) } else { (hi, lo) };
    let span = hi - lo;
    if !span.is_finite() || span <= 0.0 {
        return (vec![lo], 0.0);
    }
    let max_ticks = max_ticks.max(2);
    let mut mag = 10f64.powf((span / max_ticks as f64).log10().floor());
    loop {
        for mult in [1.0, 2.0, 5.0] {
            let step = mult * mag;
            let (first, last) = tick_index_range(lo, hi, step);
            if last - first < max_ticks as i64 {
                let ticks = (first..=last).map(|i| clean(i as f64 * step, step)).collect();
                return (ticks, step);
            }
        }
        mag *= 10.0;
    }
}

/// Indices `i` with `lo <= i * step <= hi`, tolerant to rounding.
fn tick_index_range(lo: f64, hi: f64, step: f64) -> (i64, i64) {
    let eps = 1e-9;
    ((lo / step - eps).ceil() as i64, (hi / step + eps).floor() as i64)
}

/// Remove rounding noise such as 12.120000000000001 from a tick value.
fn clean(v: f64, step: f64) -> f64 {
    let decimals = tick_decimals(step) as i32 + 2;
    let s = 10f64.powi(decimals);
    let r = (v * s).round() / s;
    if r == 0.0 { 0.0 } else { r }
}

/// Decimals needed to print multiples of `step` exactly.
fn tick_decimals(step: f64) -> usize {
    if step <= 0.0 || !step.is_finite() {
        return 2;
    }
    (-step.log10() - 1e-9).ceil().max(0.0) as usize
}

/// Tick label for value `v` on an axis with tick spacing `step`.
pub fn tick_label(v: f64, step: f64) -> String {
    let s = format!("{:.*}", tick_decimals(step), v);
    if s.starts_with('-') && s[1..].chars().all(|c| c == '0' || c == '.') {
        s[1..].to_string()
    } else {
        s
    }
}

/// Data range of the finite values, widened when degenerate; `None` when there are none.
fn data_range(values: impl Iterator<Item = f64>) -> Option<(f64, f64)> {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for v in values.filter(|v| v.is_finite()) {
        lo = lo.min(v);
        hi = hi.max(v);
    }
    (lo <= hi).then(|| widen(lo, hi))
}

fn widen(lo: f64, hi: f64) -> (f64, f64) {
    if hi - lo > 1e-12 * lo.abs().max(hi.abs()).max(1e-300) {
        (lo, hi)
    } else {
        let d = (lo.abs() * 0.05).max(0.5);
        (lo - d, hi + d)
    }
}

/// Clip segment `a`-`b` to the rectangle `[lo, hi]` (Liang-Barsky).
fn clip_segment(a: Vec2, b: Vec2, lo: Vec2, hi: Vec2) -> Option<(Vec2, Vec2)> {
    let d = b - a;
    let (mut t0, mut t1) = (0.0f32, 1.0f32);
    for (p, q) in [(-d.x, a.x - lo.x), (d.x, hi.x - a.x), (-d.y, a.y - lo.y), (d.y, hi.y - a.y)] {
        if p == 0.0 {
            if q < 0.0 {
                return None;
            }
        } else {
            let r = q / p;
            if p < 0.0 {
                t0 = t0.max(r);
            } else {
                t1 = t1.min(r);
            }
        }
    }
    (t0 <= t1).then(|| (a + d * t0, a + d * t1))
}

const GRID: Rgba = [225, 225, 225, 255];
const FRAME: Rgba = [90, 90, 90, 255];

/// A line plot with nice ticks, light grey grid lines, a legend (in the corner of the plot
/// area that covers the fewest data points) and a title. Empty series and single points are
/// fine (a single point is drawn as a dot). Text uses the canvas's built-in upper-case font.
pub fn line_plot(series: &[Series], opts: &PlotOptions) -> Canvas {
    let (width, height) = (opts.width.max(32), opts.height.max(32));
    let mut canvas = Canvas::new(width, height, WHITE);
    let st = Style::for_size(width, height);
    let (s, char_h, pad, tick_len) = (st.scale, st.char_h, st.pad, st.tick_len);

    let finite = |&(x, y): &(f64, f64)| x.is_finite() && y.is_finite();
    let all_points = || series.iter().flat_map(|se| se.points.iter().copied()).filter(finite);
    let has_data = all_points().next().is_some();
    let (x_lo, x_hi) = data_range(all_points().map(|p| p.0)).unwrap_or((0.0, 1.0));
    let (y_lo, y_hi) = match opts.y_range {
        Some((a, b)) if a.is_finite() && b.is_finite() => widen(a.min(b), a.max(b)),
        _ => match data_range(all_points().map(|p| p.1)) {
            Some((a, b)) => {
                let m = (b - a) * 0.05;
                (a - m, b + m)
            }
            None => (0.0, 1.0),
        },
    };

    // vertical layout
    let title_scale = s + 1;
    let mut top = pad;
    if !opts.title.is_empty() {
        top += 7.0 * title_scale as f32 + pad;
    }
    if !opts.y_label.is_empty() {
        top += char_h + pad * 0.75;
    }
    let mut bottom = pad + tick_len + pad * 0.5 + char_h;
    if !opts.x_label.is_empty() {
        bottom += pad + char_h;
    }
    let plot_h = (height as f32 - top - bottom).max(8.0);
    let max_y_ticks = ((plot_h / (char_h * 4.0)) as usize).clamp(2, 10);
    let (y_ticks, y_step) = nice_ticks(y_lo, y_hi, max_y_ticks);
    let y_labels: Vec<String> = y_ticks.iter().map(|&v| tick_label(v, y_step)).collect();
    let y_label_w = y_labels.iter().map(|l| Canvas::text_width(l, s)).max().unwrap_or(0) as f32;

    // horizontal layout
    let left = pad + y_label_w + tick_len + pad * 0.5;
    let right = pad + 3.0 * Canvas::text_width("0", s) as f32;
    let plot_w = (width as f32 - left - right).max(8.0);
    let (mut x_ticks, mut x_step) = (Vec::new(), 0.0);
    for max_ticks in (2..=10).rev() {
        (x_ticks, x_step) = nice_ticks(x_lo, x_hi, max_ticks);
        let widest = x_ticks
            .iter()
            .map(|&v| Canvas::text_width(&tick_label(v, x_step), s))
            .max()
            .unwrap_or(0) as f32;
        if (widest + 4.0 * char_h) * x_ticks.len() as f32 <= plot_w {
            break;
        }
    }
    let area = PlotArea {
        lo: Vec2::new(left.round(), top.round()),
        hi: Vec2::new((left + plot_w).round(), (top + plot_h).round()),
        x: (x_lo, x_hi),
        y: (y_lo, y_hi),
    };
    let (px0, py0, px1, py1) = (area.lo.x, area.lo.y, area.hi.x, area.hi.y);

    // grid, ticks and tick labels (lines at pixel centres so 1-pixel lines stay crisp)
    for (&v, label) in y_ticks.iter().zip(&y_labels) {
        let y = area.to_px(x_lo, v).y.round() + 0.5;
        canvas.line(Vec2::new(px0, y), Vec2::new(px1, y), 1.0, GRID);
        canvas.line(Vec2::new(px0 - tick_len, y), Vec2::new(px0, y), 1.0, FRAME);
        let w = Canvas::text_width(label, s) as f32;
        canvas.text(Vec2::new(px0 - tick_len - pad * 0.5 - w, y - char_h * 0.5), label, s, BLACK);
    }
    for &v in &x_ticks {
        let x = area.to_px(v, y_lo).x.round() + 0.5;
        canvas.line(Vec2::new(x, py0), Vec2::new(x, py1), 1.0, GRID);
        canvas.line(Vec2::new(x, py1), Vec2::new(x, py1 + tick_len), 1.0, FRAME);
        let label = tick_label(v, x_step);
        let w = Canvas::text_width(&label, s) as f32;
        canvas.text(Vec2::new(x - w * 0.5, py1 + tick_len + pad * 0.5), &label, s, BLACK);
    }
    canvas.rect(Vec2::new(px0 + 0.5, py0 + 0.5), Vec2::new(px1 + 0.5, py1 + 0.5), 1.0, FRAME);

    draw_curves(&mut canvas, series, &area, &st);
    if !has_data {
        let msg = "NO DATA";
        let w = Canvas::text_width(msg, s) as f32;
        canvas.text(Vec2::new((px0 + px1 - w) * 0.5, (py0 + py1 - char_h) * 0.5), msg, s, FRAME);
    }
    let points: Vec<Vec2> = all_points().map(|(x, y)| area.to_px(x, y)).collect();
    draw_legend(&mut canvas, series, &area, &points, &st);

    // axis labels and title
    if !opts.y_label.is_empty() {
        canvas.text(Vec2::new(px0, py0 - pad * 0.75 - char_h), &opts.y_label, s, BLACK);
    }
    if !opts.x_label.is_empty() {
        let w = Canvas::text_width(&opts.x_label, s) as f32;
        canvas.text(
            Vec2::new((px0 + px1 - w) * 0.5, height as f32 - pad - char_h),
            &opts.x_label,
            s,
            BLACK,
        );
    }
    if !opts.title.is_empty() {
        let w = Canvas::text_width(&opts.title, title_scale) as f32;
        canvas.text(Vec2::new((width as f32 - w) * 0.5, pad), &opts.title, title_scale, BLACK);
    }
    canvas
}

/// Sizes of a plot's text and spacing, pixels.
struct Style {
    /// The font's scale: 2 on plots of 400 pixels a side or more, else 1.
    scale: u32,
    /// The scale as a float.
    sf: f32,
    char_h: f32,
    pad: f32,
    tick_len: f32,
}

impl Style {
    fn for_size(width: u32, height: u32) -> Self {
        let scale = if width.min(height) >= 400 { 2u32 } else { 1 };
        let sf = scale as f32;
        Style { scale, sf, char_h: 7.0 * sf, pad: 8.0 * sf, tick_len: 4.0 * sf }
    }
}

/// The plot area in pixels (`lo` top left, `hi` bottom right) and the data ranges it shows.
struct PlotArea {
    lo: Vec2,
    hi: Vec2,
    x: (f64, f64),
    y: (f64, f64),
}

impl PlotArea {
    /// The pixel of data point `(x, y)`.
    fn to_px(&self, x: f64, y: f64) -> Vec2 {
        let ((x_lo, x_hi), (y_lo, y_hi)) = (self.x, self.y);
        Vec2::new(
            self.lo.x + ((x - x_lo) / (x_hi - x_lo)) as f32 * (self.hi.x - self.lo.x),
            self.hi.y - ((y - y_lo) / (y_hi - y_lo)) as f32 * (self.hi.y - self.lo.y),
        )
    }
}

/// Every series' curve (a dot for a single point), clipped to the plot area.
fn draw_curves(canvas: &mut Canvas, series: &[Series], area: &PlotArea, st: &Style) {
    let finite = |&(x, y): &(f64, f64)| x.is_finite() && y.is_finite();
    let (clip_lo, clip_hi) = (area.lo, area.hi + Vec2::ONE);
    for se in series {
        let pts: Vec<Vec2> =
            se.points.iter().filter(|p| finite(p)).map(|&(x, y)| area.to_px(x, y)).collect();
        if pts.len() == 1 {
            if clip_segment(pts[0], pts[0], clip_lo, clip_hi).is_some() {
                canvas.disc(pts[0], 2.0 * st.sf, se.color);
            }
            continue;
        }
        for w in pts.windows(2) {
            if let Some((a, b)) = clip_segment(w[0], w[1], clip_lo, clip_hi) {
                canvas.line(a, b, 1.5 * st.sf, se.color);
            }
        }
    }
}

/// The legend of the labelled series, in the corner of the plot area that covers the fewest
/// of the data's pixels `points`.
fn draw_legend(
    canvas: &mut Canvas,
    series: &[Series],
    area: &PlotArea,
    points: &[Vec2],
    st: &Style,
) {
    let entries: Vec<&Series> = series.iter().filter(|se| !se.label.is_empty()).collect();
    if entries.is_empty() {
        return;
    }
    let (s, sf, char_h, pad) = (st.scale, st.sf, st.char_h, st.pad);
    let (px0, py0, px1, py1) = (area.lo.x, area.lo.y, area.hi.x, area.hi.y);
    let sample = 16.0 * sf;
    let row_h = char_h + 4.0 * sf;
    let text_w = entries.iter().map(|e| Canvas::text_width(&e.label, s)).max().unwrap_or(0);
    let box_w = pad + sample + pad * 0.75 + text_w as f32 + pad;
    let box_h = pad + row_h * entries.len() as f32 - 4.0 * sf + pad;
    let inset = pad;
    let corners = [
        Vec2::new(px1 - inset - box_w, py0 + inset),
        Vec2::new(px1 - inset - box_w, py1 - inset - box_h),
        Vec2::new(px0 + inset, py0 + inset),
        Vec2::new(px0 + inset, py1 - inset - box_h),
    ];
    let covered = |c: Vec2| {
        points
            .iter()
            .filter(|p| {
                p.x >= c.x - pad
                    && p.x <= c.x + box_w + pad
                    && p.y >= c.y - pad
                    && p.y <= c.y + box_h + pad
            })
            .count()
    };
    let mut at = corners[0];
    let mut best = usize::MAX;
    for c in corners {
        let n = covered(c);
        if n < best {
            best = n;
            at = c;
        }
    }
    let at = at.round();
    canvas.fill_rect(at, at + Vec2::new(box_w, box_h), WHITE);
    canvas.rect(at + Vec2::splat(0.5), at + Vec2::new(box_w, box_h) + Vec2::splat(0.5), 1.0, FRAME);
    for (i, e) in entries.iter().enumerate() {
        let y = at.y + pad + row_h * i as f32;
        let mid = y + char_h * 0.5;
        canvas.line(
            Vec2::new(at.x + pad, mid),
            Vec2::new(at.x + pad + sample, mid),
            1.5 * sf,
            e.color,
        );
        canvas.text(Vec2::new(at.x + pad + sample + pad * 0.75, y), &e.label, s, BLACK);
    }
}

/// Draw a [`line_plot`] and save it as PNG, atomically.
pub fn save_line_plot(path: &Path, series: &[Series], opts: &PlotOptions) -> Result<(), CoreError> {
    line_plot(series, opts).save_png(path)
}

/// The `q`-quantile (`q` in `[0, 1]`) of sorted values, linearly interpolated between
/// neighbours (numpy's default). `sorted` must not be empty.
fn quantile_sorted(sorted: &[f32], q: f64) -> f32 {
    let pos = q.clamp(0.0, 1.0) * (sorted.len() - 1) as f64;
    let i = pos.floor() as usize;
    let j = (i + 1).min(sorted.len() - 1);
    let f = (pos - i as f64) as f32;
    sorted[i] + (sorted[j] - sorted[i]) * f
}

/// 1st and 99th percentiles of the finite values, or `None` when there are none.
fn robust_range(values: &[f32]) -> Option<(f32, f32)> {
    let mut v: Vec<f32> = values.iter().copied().filter(|x| x.is_finite()).collect();
    if v.is_empty() {
        return None;
    }
    v.sort_unstable_by(f32::total_cmp);
    Some((quantile_sorted(&v, 0.01), quantile_sorted(&v, 0.99)))
}

/// `(v - lo) / (hi - lo)` clamped to `[0, 1]`; 0 when the range is empty.
fn normalise(v: f32, (lo, hi): (f32, f32)) -> f32 {
    if hi > lo { ((v - lo) / (hi - lo)).clamp(0.0, 1.0) } else { 0.0 }
}

/// Colours of a scalar plane (density, say): values normalised by their 1st..99th
/// percentiles and mapped through [`colormap`]. Non-finite values are drawn black.
pub fn scalar_colors(values: &[f32]) -> Vec<[u8; 3]> {
    let range = robust_range(values).unwrap_or((0.0, 1.0));
    values
        .iter()
        .map(|&v| if v.is_finite() { colormap(normalise(v, range)) } else { [0, 0, 0] })
        .collect()
}

/// Colours of a feature plane: every pixel's feature vector (`features[p * channels + c]`)
/// projected onto the first three principal components of all pixels (mean-centred
/// covariance), each component mapped to 0..255 by its 1st..99th percentile range. Missing
/// components (fewer than three channels, or a component with no spread) are 0. Components'
/// signs are fixed (largest entry of each principal axis positive), so the colours are
/// deterministic.
///
/// # Panics
/// If `features.len() != n_pixels * channels`.
pub fn pca_colors(features: &[f32], n_pixels: usize, channels: usize) -> Vec<[u8; 3]> {
    assert_eq!(
        features.len(),
        n_pixels * channels,
        "pca_colors: {} values for {n_pixels} pixels of {channels} channels",
        features.len()
    );
    if n_pixels == 0 {
        return Vec::new();
    }
    if channels == 0 {
        return vec![[0, 0, 0]; n_pixels];
    }
    let c = channels;
    let mut mean = vec![0.0f64; c];
    for px in features.chunks_exact(c) {
        for (m, &v) in mean.iter_mut().zip(px) {
            *m += f64::from(v);
        }
    }
    for m in &mut mean {
        *m /= n_pixels as f64;
    }
    // covariance (upper triangle accumulated in parallel over blocks of pixels)
    let cov_sum = features
        .par_chunks(4096 * c)
        .map(|block| {
            let mut acc = vec![0.0f64; c * c];
            let mut d = vec![0.0f64; c];
            for px in block.chunks_exact(c) {
                for k in 0..c {
                    d[k] = f64::from(px[k]) - mean[k];
                }
                for i in 0..c {
                    let di = d[i];
                    let row = &mut acc[i * c..(i + 1) * c];
                    for j in i..c {
                        row[j] += di * d[j];
                    }
                }
            }
            acc
        })
        .reduce(
            || vec![0.0f64; c * c],
            |mut a, b| {
                for (x, y) in a.iter_mut().zip(&b) {
                    *x += y;
                }
                a
            },
        );
    let mut cov = cov_sum;
    for i in 0..c {
        for j in i..c {
            let v = cov[i * c + j] / n_pixels as f64;
            cov[i * c + j] = v;
            cov[j * c + i] = v;
        }
    }
    let (values, vectors) = symmetric_eigen(&cov, c);
    let mut order: Vec<usize> = (0..c).collect();
    order.sort_by(|&a, &b| values[b].total_cmp(&values[a]).then(a.cmp(&b)));

    let mut axes: Vec<Vec<f64>> = Vec::new();
    for &k in order.iter().take(3) {
        let mut axis: Vec<f64> = (0..c).map(|i| vectors[i * c + k]).collect();
        let biggest =
            axis.iter().copied().fold(0.0f64, |m, v| if v.abs() > m.abs() { v } else { m });
        if biggest < 0.0 {
            axis.iter_mut().for_each(|v| *v = -*v);
        }
        axes.push(axis);
    }
    let projections: Vec<Vec<f32>> = axes
        .iter()
        .map(|axis| {
            features
                .par_chunks(c)
                .map(|px| {
                    px.iter()
                        .zip(&mean)
                        .zip(axis)
                        .map(|((&v, m), a)| (f64::from(v) - m) * a)
                        .sum::<f64>() as f32
                })
                .collect()
        })
        .collect();
    let ranges: Vec<Option<(f32, f32)>> = projections.iter().map(|p| robust_range(p)).collect();
    (0..n_pixels)
        .map(|p| {
            std::array::from_fn(|k| match (projections.get(k), ranges.get(k)) {
                (Some(proj), Some(Some(range))) => {
                    (normalise(proj[p], *range) * 255.0).round() as u8
                }
                _ => 0,
            })
        })
        .collect()
}

/// Eigen-decomposition of the symmetric `n x n` matrix `m` (row-major) by cyclic Jacobi
/// rotations. Returns the eigenvalues and the eigenvectors as the columns of a row-major
/// matrix.
fn symmetric_eigen(m: &[f64], n: usize) -> (Vec<f64>, Vec<f64>) {
    let mut a = m.to_vec();
    let mut v = vec![0.0f64; n * n];
    for i in 0..n {
        v[i * n + i] = 1.0;
    }
    let scale: f64 = a.iter().map(|x| x * x).sum::<f64>().max(f64::MIN_POSITIVE);
    for _sweep in 0..64 {
        let off: f64 = (0..n)
            .flat_map(|p| (p + 1..n).map(move |q| (p, q)))
            .map(|(p, q)| a[p * n + q].powi(2))
            .sum();
        if off <= 1e-30 * scale {
            break;
        }
        for p in 0..n {
            for q in p + 1..n {
                let apq = a[p * n + q];
                if apq.abs() <= 1e-300 {
                    continue;
                }
                let theta = (a[q * n + q] - a[p * n + p]) / (2.0 * apq);
                let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
                let cs = 1.0 / (t * t + 1.0).sqrt();
                let sn = t * cs;
                for k in 0..n {
                    let (akp, akq) = (a[k * n + p], a[k * n + q]);
                    a[k * n + p] = cs * akp - sn * akq;
                    a[k * n + q] = sn * akp + cs * akq;
                }
                for k in 0..n {
                    let (apk, aqk) = (a[p * n + k], a[q * n + k]);
                    a[p * n + k] = cs * apk - sn * aqk;
                    a[q * n + k] = sn * apk + cs * aqk;
                }
                for k in 0..n {
                    let (vkp, vkq) = (v[k * n + p], v[k * n + q]);
                    v[k * n + p] = cs * vkp - sn * vkq;
                    v[k * n + q] = sn * vkp + cs * vkq;
                }
            }
        }
    }
    ((0..n).map(|i| a[i * n + i]).collect(), v)
}

/// An RGB picture from per-pixel colours in row-major order.
///
/// # Panics
/// If `colors.len() != width * height`.
pub fn rgb_image(colors: &[[u8; 3]], width: u32, height: u32) -> image::RgbImage {
    assert_eq!(colors.len(), (width * height) as usize, "rgb_image: wrong number of colours");
    let raw: Vec<u8> = colors.iter().flatten().copied().collect();
    image::RgbImage::from_raw(width, height, raw).expect("size matches")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn is_nice(step: f64) -> bool {
        let mag = 10f64.powf(step.log10().floor());
        let m = step / mag;
        [1.0, 2.0, 5.0, 10.0].iter().any(|n| (m - n).abs() < 1e-9)
    }

    #[test]
    fn nice_ticks_for_typical_ranges() {
        let (t, step) = nice_ticks(0.0, 37.3, 6);
        assert_eq!(step, 10.0);
        assert_eq!(t, vec![0.0, 10.0, 20.0, 30.0]);
        let (t, step) = nice_ticks(0.0, 37.3, 8);
        assert_eq!(step, 5.0);
        assert_eq!(t.len(), 8);

        let (t, step) = nice_ticks(12.1, 12.2, 8);
        assert!((step - 0.02).abs() < 1e-12, "{step}");
        assert_eq!(t, vec![12.1, 12.12, 12.14, 12.16, 12.18, 12.2]);
        let labels: Vec<String> = t.iter().map(|&v| tick_label(v, step)).collect();
        assert_eq!(labels, ["12.10", "12.12", "12.14", "12.16", "12.18", "12.20"]);

        let (t, step) = nice_ticks(-5.0, 5.0, 8);
        assert_eq!(step, 2.0);
        assert_eq!(t, vec![-4.0, -2.0, 0.0, 2.0, 4.0]);
        let (t, _) = nice_ticks(-5.0, 5.0, 11);
        assert_eq!(t.len(), 11);
        assert_eq!(tick_label(0.0, 1.0), "0");

        for (lo, hi) in [(0.0, 37.3), (12.1, 12.2), (-5.0, 5.0), (3e-4, 9e-4), (100.0, 1e6)] {
            for max in 2..12 {
                let (t, step) = nice_ticks(lo, hi, max);
                assert!(is_nice(step), "{lo}..{hi}: step {step}");
                assert!(t.len() <= max && !t.is_empty(), "{lo}..{hi} max {max}: {t:?}");
                assert!(t.iter().all(|&v| v >= lo - 1e-9 && v <= hi + 1e-9));
            }
        }
    }

    #[test]
    fn degenerate_ranges_do_not_panic() {
        assert_eq!(nice_ticks(3.0, 3.0, 5).0, vec![3.0]);
        assert!(nice_ticks(f64::NAN, 1.0, 5).0.is_empty());
        assert!(!nice_ticks(5.0, -5.0, 5).0.is_empty());
    }

    fn opts(w: u32, h: u32) -> PlotOptions {
        PlotOptions {
            title: "Training".into(),
            x_label: "seconds".into(),
            y_label: "PSNR (dB)".into(),
            width: w,
            height: h,
            y_range: None,
        }
    }

    #[test]
    fn line_plot_draws_the_curve_inside_the_axes() {
        let red = [220, 30, 30, 255];
        let curve = Series {
            label: "train".into(),
            points: (0..50)
                .map(|i| (i as f64 * 6.0, 12.0 + 20.0 * (1.0 - (-(i as f64) / 10.0).exp())))
                .collect(),
            color: red,
        };
        let c = line_plot(&[curve], &opts(320, 200));
        assert_eq!((c.width(), c.height()), (320, 200));
        let mut reddish = 0;
        for y in 0..c.height() {
            for x in 0..c.width() {
                let p = c.get(x, y);
                if p[0] > 180 && p[1] < 90 && p[2] < 90 {
                    reddish += 1;
                }
            }
        }
        assert!(reddish > 200, "curve barely visible: {reddish} red pixels");
        // corners stay background
        assert_eq!(c.get(0, c.height() - 1), WHITE);
    }

    #[test]
    fn line_plot_handles_empty_and_single_points() {
        let empty = line_plot(&[], &opts(200, 120));
        assert_eq!((empty.width(), empty.height()), (200, 120));
        let nothing = Series { label: "none".into(), points: vec![], color: BLACK };
        line_plot(&[nothing], &opts(200, 120));
        let blue = [20, 40, 230, 255];
        let one = Series { label: "one".into(), points: vec![(5.0, 20.0)], color: blue };
        let c = line_plot(&[one], &opts(200, 120));
        let blue_px = (0..c.height())
            .flat_map(|y| (0..c.width()).map(move |x| (x, y)))
            .filter(|&(x, y)| {
                let p = c.get(x, y);
                p[2] > 180 && p[0] < 100
            })
            .count();
        assert!(blue_px > 5, "the single point is not drawn");
        let weird = Series {
            label: String::new(),
            points: vec![(f64::NAN, 1.0), (1.0, f64::INFINITY), (2.0, 3.0), (2.0, 3.0)],
            color: blue,
        };
        let fixed = PlotOptions { y_range: Some((0.0, 1.0)), ..opts(150, 100) };
        line_plot(&[weird], &fixed);
        line_plot(&[], &PlotOptions { width: 1, height: 1, ..PlotOptions::default() });
    }

    /// Deterministic noise in [-1, 1).
    fn noise(i: usize) -> f32 {
        let x = (i as u64).wrapping_mul(2654435761).wrapping_add(12345) % 10007;
        x as f32 / 5003.5 - 1.0
    }

    #[test]
    fn pca_separates_two_clusters() {
        let (n, c) = (400, 6);
        let centre_a = [0.9f32, 0.1, 0.4, 0.0, 0.3, 0.5];
        let centre_b = [0.1f32, 0.8, 0.4, 0.6, 0.3, 0.1];
        let mut f = Vec::with_capacity(n * c);
        for p in 0..n {
            let centre = if p % 2 == 0 { centre_a } else { centre_b };
            for k in 0..c {
                f.push(centre[k] + 0.03 * noise(p * c + k));
            }
        }
        let colors = pca_colors(&f, n, c);
        assert_eq!(colors.len(), n);
        let mean = |parity: usize| {
            let mut m = [0.0f32; 3];
            for (p, col) in colors.iter().enumerate().filter(|(p, _)| p % 2 == parity) {
                let _ = p;
                for k in 0..3 {
                    m[k] += col[k] as f32 / (n / 2) as f32;
                }
            }
            m
        };
        let (ma, mb) = (mean(0), mean(1));
        let dist = (0..3).map(|k| (ma[k] - mb[k]).powi(2)).sum::<f32>().sqrt();
        assert!(dist > 200.0, "cluster colours too close: {ma:?} vs {mb:?}");
        // the first component carries the split: within a cluster its colour barely changes
        for (p, col) in colors.iter().enumerate() {
            let m = if p % 2 == 0 { ma } else { mb };
            assert!((col[0] as f32 - m[0]).abs() < 40.0, "pixel {p}: {col:?} vs mean {m:?}");
        }
        // deterministic
        assert_eq!(colors, pca_colors(&f, n, c));
    }

    #[test]
    fn pca_with_few_channels_pads_with_zeros() {
        let f: Vec<f32> = (0..50).map(|i| i as f32).collect();
        let colors = pca_colors(&f, 50, 1);
        assert_eq!(colors.len(), 50);
        assert!(colors.iter().all(|c| c[1] == 0 && c[2] == 0));
        assert!(colors[0][0] < 10 && colors[49][0] > 245);
        assert!(pca_colors(&[], 0, 4).is_empty());
    }

    #[test]
    fn jacobi_diagonalises() {
        let m = [4.0, 1.0, 0.5, 1.0, 3.0, 0.2, 0.5, 0.2, 1.0];
        let (vals, vecs) = symmetric_eigen(&m, 3);
        for k in 0..3 {
            for i in 0..3 {
                let mv: f64 = (0..3).map(|j| m[i * 3 + j] * vecs[j * 3 + k]).sum();
                assert!((mv - vals[k] * vecs[i * 3 + k]).abs() < 1e-10);
            }
        }
        let trace: f64 = vals.iter().sum();
        assert!((trace - 8.0).abs() < 1e-10);
    }

    #[test]
    fn scalar_colors_use_robust_range() {
        let mut v: Vec<f32> = (0..200).map(|i| i as f32 / 199.0).collect();
        v[7] = 1e6; // an outlier does not squash the rest
        v[8] = f32::NAN;
        let c = scalar_colors(&v);
        assert_eq!(c.len(), 200);
        assert_eq!(c[8], [0, 0, 0]);
        assert_eq!(c[0], colormap(0.0));
        assert_eq!(c[7], colormap(1.0));
        assert_ne!(c[100], colormap(0.0));
        assert_ne!(c[100], colormap(1.0));
    }

    #[test]
    fn colormap_is_ordered_dark_to_bright() {
        let lum = |c: [u8; 3]| 0.3 * c[0] as f32 + 0.59 * c[1] as f32 + 0.11 * c[2] as f32;
        let mut last = -1.0;
        for i in 0..=20 {
            let l = lum(colormap(i as f32 / 20.0));
            assert!(l > last, "luminance not increasing at {i}");
            last = l;
        }
        assert_eq!(colormap(-3.0), colormap(0.0));
        assert_eq!(colormap(f32::NAN), colormap(0.0));
    }
}
