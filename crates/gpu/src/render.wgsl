// Volume rendering of a trained field, one ray per invocation: the same march, density,
// colour decoding and compositing as the CPU reference (`assetfield_field::march::forward`
// with `MarchSettings::default()` and no jitter). Dispatched by `render.rs`.
//
// Grids are read from the field's flat parameters (the CPU layout, offsets in the header).
// The networks (colour basis, guidance MLP, decoder) are read from `net`, a copy padded to
// multiples of four in both dimensions (zeros), so matrix-vector products run over 4 x 4
// blocks. Sums are accumulated in the CPU's order, so both round alike.
//
// Loop iterations are bounded on purpose: llvmpipe (Mesa's software Vulkan) ends every loop
// of a group of invocations once they have iterated 65535 times in total. A dispatch marches
// a ray for at most `max_steps` samples and records at most `max_colors` samples that need a
// colour, decodes those, and saves the march in `state`; the host dispatches again until
// every ray is done (the budgets come from the layer sizes so that a dispatch stays well
// inside the limit). A last loop with a known trip count detects a driver that cut loops
// short anyway: the ray is counted in `status` and the host refuses the image.

const MAX_VEC4: u32 = 48u;
// most colour samples recorded per dispatch
const K: u32 = 32u;

const KIND_INTEGRATED: u32 = 1u;
const DECODER_SH: u32 = 1u;

// A plane over grid axes a0 (columns) and a1 (rows), optionally times a line over a2.
struct Comp {
    plane: u32,
    line: u32,
    a0: u32,
    a1: u32,
    a2: u32,
    cols: u32,
    rows: u32,
    len: u32,
    ch: u32,
}

// A dense layer in `net`: weight rows of n_in4 vec4 each (n_out4 x 4 rows), bias (n_out4
// vec4), offsets in vec4 units.
struct Layer {
    w: u32,
    b: u32,
    n_in4: u32,
    n_out4: u32,
}

// Mirrors the host's header in render.rs member for member (checked by
// tests/shaders_validate.rs).
struct Header {
    kind: u32,
    n_density: u32,
    n_color: u32,
    decoder: u32,
    sh_degree: u32,
    view_freqs: u32,
    n_layers: u32,
    app_dim: u32,
    fdim: u32,
    guide_in: u32,
    has_occ: u32,
    occ_nx: u32,
    occ_ny: u32,
    occ_nz: u32,
    max_samples: u32,
    max_steps: u32,
    max_colors: u32,
    canary: u32,
    aabb_min_x: f32,
    aabb_min_y: f32,
    aabb_min_z: f32,
    aabb_max_x: f32,
    aabb_max_y: f32,
    aabb_max_z: f32,
    grid_scale_x: f32,
    grid_scale_y: f32,
    grid_scale_z: f32,
    occ_scale_x: f32,
    occ_scale_y: f32,
    occ_scale_z: f32,
    step: f32,
    delta: f32,
    shift: f32,
    weight_threshold: f32,
    stop_transmittance: f32,
    density: array<Comp, 3>,
    color: array<Comp, 3>,
    basis: Layer,
    guide0: Layer,
    guide1: Layer,
    layers: array<Layer, 4>,
}

// One ray: origin (xyz, w unused) and unit direction (xyz, w unused).
struct Ray {
    origin: vec4<f32>,
    dir: vec4<f32>,
}

// A ray's march between dispatches; `c` ends as the pixel's colour.
struct State {
    c: vec4<f32>,
    t: f32,
    trans: f32,
    n: u32,
    flag: u32,
}

const FRESH: u32 = 0u;
const MARCHING: u32 = 1u;
const DONE: u32 = 2u;

// Per dispatch: the background colour (xyz) and how many rays of the ray buffer are valid.
struct Dispatch {
    background: vec4<f32>,
    n_rays: u32,
    pad0: u32,
    pad1: u32,
    pad2: u32,
}

@group(0) @binding(0) var<storage, read> hdr: Header;
@group(0) @binding(1) var<storage, read> params: array<f32>;
@group(0) @binding(2) var<storage, read> occupancy: array<u32>;
@group(0) @binding(3) var<storage, read> net: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read> rays: array<Ray>;
@group(0) @binding(5) var<storage, read_write> state: array<State>;
@group(0) @binding(6) var<uniform> dispatch: Dispatch;
// [0]: rays whose loops the driver cut short, [1]: rays not done yet
@group(0) @binding(7) var<storage, read_write> status: array<atomic<u32>, 4>;

alias Vec = array<vec4<f32>, MAX_VEC4>;

// ping-pong vectors of the colour decoder (zero beyond their length)
var<private> va: Vec;
var<private> vb: Vec;

// Grid index and fraction along an axis of `res` samples (align corners, clamped at the
// edges; the last cell is used for the far edge), as `interp::split` on the CPU.
struct Split {
    i: u32,
    f: f32,
}

fn split(g: f32, res: u32) -> Split {
    let gc = clamp(g, 0.0, f32(res - 1u));
    let i = min(u32(floor(gc)), res - 2u);
    return Split(i, gc - f32(i));
}

// Four plane texels (offsets into `params`, channel 0) and their weights.
struct Taps {
    i0: u32,
    i1: u32,
    i2: u32,
    i3: u32,
    w: vec4<f32>,
}

fn plane_taps(c: Comp, g: vec3<f32>) -> Taps {
    let su = split(g[c.a0], c.cols);
    let sv = split(g[c.a1], c.rows);
    let i1 = min(su.i + 1u, c.cols - 1u);
    let j1 = min(sv.i + 1u, c.rows - 1u);
    let fu = su.f;
    let fv = sv.f;
    return Taps(
        c.plane + (sv.i * c.cols + su.i) * c.ch,
        c.plane + (sv.i * c.cols + i1) * c.ch,
        c.plane + (j1 * c.cols + su.i) * c.ch,
        c.plane + (j1 * c.cols + i1) * c.ch,
        vec4<f32>((1.0 - fu) * (1.0 - fv), fu * (1.0 - fv), (1.0 - fu) * fv, fu * fv),
    );
}

// Two line samples (offsets into `params`, channel 0) and their weights.
struct LineTaps {
    i0: u32,
    i1: u32,
    w: vec2<f32>,
}

fn line_taps(c: Comp, g: vec3<f32>) -> LineTaps {
    let s = split(g[c.a2], c.len);
    let i1 = min(s.i + 1u, c.len - 1u);
    return LineTaps(c.line + s.i * c.ch, c.line + i1 * c.ch, vec2<f32>(1.0 - s.f, s.f));
}

fn p4(at: u32) -> vec4<f32> {
    return vec4<f32>(params[at], params[at + 1u], params[at + 2u], params[at + 3u]);
}

// Channels k..k+3 of a plane (bilinear) and of a line (linear).
fn plane4(t: Taps, k: u32) -> vec4<f32> {
    return t.w.x * p4(t.i0 + k) + t.w.y * p4(t.i1 + k) + t.w.z * p4(t.i2 + k)
        + t.w.w * p4(t.i3 + k);
}

fn line4(t: LineTaps, k: u32) -> vec4<f32> {
    return t.w.x * p4(t.i0 + k) + t.w.y * p4(t.i1 + k);
}

fn plane1(t: Taps, k: u32) -> f32 {
    return t.w.x * params[t.i0 + k] + t.w.y * params[t.i1 + k] + t.w.z * params[t.i2 + k]
        + t.w.w * params[t.i3 + k];
}

fn line1(t: LineTaps, k: u32) -> f32 {
    return t.w.x * params[t.i0 + k] + t.w.y * params[t.i1 + k];
}

fn to_grid(p: vec3<f32>) -> vec3<f32> {
    let lo = vec3<f32>(hdr.aabb_min_x, hdr.aabb_min_y, hdr.aabb_min_z);
    let scale = vec3<f32>(hdr.grid_scale_x, hdr.grid_scale_y, hdr.grid_scale_z);
    return (p - lo) * scale;
}

// Sum over components and channels of plane x line: channels in blocks of eight summed in
// eight lanes, the rest in a tail, the lanes added in order at the end (as the CPU does).
fn density_feature(g: vec3<f32>) -> f32 {
    var lo = vec4<f32>(0.0);
    var hi = vec4<f32>(0.0);
    var tail = 0.0;
    for (var ci = 0u; ci < hdr.n_density; ci++) {
        let c = hdr.density[ci];
        let pt = plane_taps(c, g);
        let lt = line_taps(c, g);
        let full = c.ch / 8u * 8u;
        for (var q = 0u; q < full; q += 8u) {
            lo += plane4(pt, q) * line4(lt, q);
            hi += plane4(pt, q + 4u) * line4(lt, q + 4u);
        }
        for (var i = full; i < c.ch; i++) {
            tail += plane1(pt, i) * line1(lt, i);
        }
    }
    return lo.x + lo.y + lo.z + lo.w + hi.x + hi.y + hi.z + hi.w + tail;
}

// ln(1 + e^x) = max(x, 0) + ln1p(e^-|x|), with ln1p(z) = 2 atanh(z / (2 + z)) as an odd
// series (z in (0, 1]): accurate where the density is tiny (x far below zero).
fn softplus(x: f32) -> f32 {
    let z = exp(-abs(x));
    let s = z / (2.0 + z);
    let s2 = s * s;
    let l = 2.0 * s * (1.0 + s2 * (1.0 / 3.0 + s2 * (1.0 / 5.0 + s2 * (1.0 / 7.0
        + s2 * (1.0 / 9.0 + s2 * (1.0 / 11.0 + s2 / 13.0))))));
    return max(x, 0.0) + l;
}

// 1 - e^-x for x >= 0, accurate for thin samples.
fn opacity(x: f32) -> f32 {
    if x < 0.03 {
        let u = -x;
        return -(u * (1.0 + u * (0.5 + u * (1.0 / 6.0 + u * (1.0 / 24.0 + u * (1.0 / 120.0))))));
    }
    return 1.0 - exp(-x);
}

fn sigmoid(x: f32) -> f32 {
    return 1.0 / (1.0 + exp(-x));
}

// acc + x . w summed left to right, as the CPU's dense layers do.
fn mac(acc: f32, x: vec4<f32>, w: vec4<f32>) -> f32 {
    return acc + x.x * w.x + x.y * w.y + x.z * w.z + x.w * w.w;
}

// y = W x (+ b), optionally ReLU, four outputs per block; `y` beyond the outputs is zero.
fn dense(x: ptr<private, Vec>, y: ptr<private, Vec>, l: Layer, bias: bool, relu: bool) {
    let n = l.n_in4;
    for (var og = 0u; og < l.n_out4; og++) {
        var acc = vec4<f32>(0.0);
        if bias {
            acc = net[l.b + og];
        }
        let row = l.w + og * 4u * n;
        for (var ig = 0u; ig < n; ig++) {
            let xv = (*x)[ig];
            acc = vec4<f32>(
                mac(acc.x, xv, net[row + ig]),
                mac(acc.y, xv, net[row + n + ig]),
                mac(acc.z, xv, net[row + 2u * n + ig]),
                mac(acc.w, xv, net[row + 3u * n + ig]),
            );
        }
        if relu {
            acc = max(acc, vec4<f32>(0.0));
        }
        (*y)[og] = acc;
    }
}

fn put(v: ptr<private, Vec>, i: u32, x: f32) {
    (*v)[i >> 2u][i & 3u] = x;
}

fn clear(v: ptr<private, Vec>, n4: u32) {
    for (var i = 0u; i < n4; i++) {
        (*v)[i] = vec4<f32>(0.0);
    }
}

// The colour basis features of the sample at grid position g, in `vb` (fdim values).
fn features(g: vec3<f32>) {
    let app4 = hdr.basis.n_in4;
    if hdr.kind == KIND_INTEGRATED {
        // guidance v = L1(relu(L0(density plane * density line))), app = colour plane * v
        let dc = hdr.density[0];
        let dpt = plane_taps(dc, g);
        let dlt = line_taps(dc, g);
        clear(&va, hdr.guide0.n_in4);
        let nd = hdr.guide_in;
        let nd4 = nd / 4u * 4u;
        for (var k = 0u; k < nd4; k += 4u) {
            va[k >> 2u] = plane4(dpt, k) * line4(dlt, k);
        }
        for (var k = nd4; k < nd; k++) {
            put(&va, k, plane1(dpt, k) * line1(dlt, k));
        }
        dense(&va, &vb, hdr.guide0, true, true);
        dense(&vb, &va, hdr.guide1, true, false);
        let cc = hdr.color[0];
        let cpt = plane_taps(cc, g);
        let n = hdr.app_dim;
        let n4 = n / 4u * 4u;
        for (var k = 0u; k < n4; k += 4u) {
            va[k >> 2u] = plane4(cpt, k) * va[k >> 2u];
        }
        for (var k = n4; k < n; k++) {
            put(&va, k, plane1(cpt, k) * va[k >> 2u][k & 3u]);
        }
        // padding beyond app_dim: the guidance output is zero there (zero rows, zero bias)
    } else {
        // plane x line per channel, components concatenated
        clear(&va, app4);
        var off = 0u;
        for (var ci = 0u; ci < hdr.n_color; ci++) {
            let c = hdr.color[ci];
            let pt = plane_taps(c, g);
            let lt = line_taps(c, g);
            let full = c.ch / 4u * 4u;
            for (var k = 0u; k < full; k += 4u) {
                let v = plane4(pt, k) * line4(lt, k);
                put(&va, off + k, v.x);
                put(&va, off + k + 1u, v.y);
                put(&va, off + k + 2u, v.z);
                put(&va, off + k + 3u, v.w);
            }
            for (var k = full; k < c.ch; k++) {
                put(&va, off + k, plane1(pt, k) * line1(lt, k));
            }
            off += c.ch;
        }
    }
    dense(&va, &vb, hdr.basis, false, false);
}

// Real spherical harmonics basis value k (k < 9) of a unit direction.
fn sh(d: vec3<f32>, k: u32) -> f32 {
    switch k {
        case 0u: { return 0.2820948; }
        case 1u: { return -0.4886025 * d.y; }
        case 2u: { return 0.4886025 * d.z; }
        case 3u: { return -0.4886025 * d.x; }
        case 4u: { return 1.0925484 * d.x * d.y; }
        case 5u: { return -1.0925484 * d.y * d.z; }
        case 6u: { return 0.31539157 * (2.0 * d.z * d.z - d.x * d.x - d.y * d.y); }
        case 7u: { return -1.0925484 * d.x * d.z; }
        default: { return 0.5462742 * (d.x * d.x - d.y * d.y); }
    }
}

// RGB of a sample at world position p seen along the unit direction d.
fn color(p: vec3<f32>, d: vec3<f32>) -> vec3<f32> {
    features(to_grid(p));
    let fdim = hdr.fdim;
    if hdr.decoder == DECODER_SH {
        let kk = (hdr.sh_degree + 1u) * (hdr.sh_degree + 1u);
        var rgb = vec3<f32>(0.0);
        for (var c = 0u; c < 3u; c++) {
            var z = 0.0;
            for (var k = 0u; k < kk; k++) {
                let i = c * kk + k;
                z += sh(d, k) * vb[i >> 2u][i & 3u];
            }
            rgb[c] = sigmoid(z);
        }
        return rgb;
    }
    // MLP input: [features, d, sin(2^k d), cos(2^k d) for k < view_freqs], zero padded
    // (the basis output is zero up to a multiple of four; clear what follows)
    for (var i = (fdim + 3u) / 4u; i < hdr.layers[0].n_in4; i++) {
        vb[i] = vec4<f32>(0.0);
    }
    put(&vb, fdim, d.x);
    put(&vb, fdim + 1u, d.y);
    put(&vb, fdim + 2u, d.z);
    for (var k = 0u; k < hdr.view_freqs; k++) {
        let f = f32(1u << k);
        let base = fdim + 3u + k * 6u;
        put(&vb, base, sin(d.x * f));
        put(&vb, base + 1u, sin(d.y * f));
        put(&vb, base + 2u, sin(d.z * f));
        put(&vb, base + 3u, cos(d.x * f));
        put(&vb, base + 4u, cos(d.y * f));
        put(&vb, base + 5u, cos(d.z * f));
    }
    // layers alternate vb -> va -> vb ...; ReLU on all but the last
    let last = hdr.n_layers - 1u;
    for (var l = 0u; l < hdr.n_layers; l += 2u) {
        dense(&vb, &va, hdr.layers[l], true, l < last);
        if l + 1u <= last {
            dense(&va, &vb, hdr.layers[l + 1u], true, l + 1u < last);
        }
    }
    var o: vec4<f32>;
    if last % 2u == 0u {
        o = va[0];
    } else {
        o = vb[0];
    }
    return vec3<f32>(sigmoid(o.x), sigmoid(o.y), sigmoid(o.z));
}

fn occupied(p: vec3<f32>) -> bool {
    let lo = vec3<f32>(hdr.aabb_min_x, hdr.aabb_min_y, hdr.aabb_min_z);
    let g = (p - lo) * vec3<f32>(hdr.occ_scale_x, hdr.occ_scale_y, hdr.occ_scale_z);
    let i = u32(clamp(i32(g.x), 0, i32(hdr.occ_nx) - 1));
    let j = u32(clamp(i32(g.y), 0, i32(hdr.occ_ny) - 1));
    let k = u32(clamp(i32(g.z), 0, i32(hdr.occ_nz) - 1));
    let cell = (k * hdr.occ_ny + j) * hdr.occ_nx + i;
    return ((occupancy[cell / 32u] >> (cell % 32u)) & 1u) != 0u;
}

@compute @workgroup_size(64)
fn render(@builtin(global_invocation_id) gid: vec3<u32>,
          @builtin(num_workgroups) groups: vec3<u32>) {
    // 2D dispatches cover more than 65535 workgroups
    let r = gid.y * groups.x * 64u + gid.x;
    if r >= dispatch.n_rays {
        return;
    }
    var s = state[r];
    if s.flag == DONE {
        return;
    }
    let ray = rays[r];
    let o = ray.origin.xyz;
    let d = ray.dir.xyz;
    let lo = vec3<f32>(hdr.aabb_min_x, hdr.aabb_min_y, hdr.aabb_min_z);
    let hi = vec3<f32>(hdr.aabb_max_x, hdr.aabb_max_y, hdr.aabb_max_z);
    let inv = 1.0 / d;
    let ta = (lo - o) * inv;
    let tb = (hi - o) * inv;
    let tmin = min(ta, tb);
    let tmax = max(ta, tb);
    let t0 = max(max(max(tmin.x, tmin.y), tmin.z), 0.0);
    let t1 = min(min(tmax.x, tmax.y), tmax.z);
    let step = hdr.step;
    var done = false;
    if s.flag == FRESH {
        s = State(vec4<f32>(0.0), t0 + step * 0.5, 1.0, 0u, MARCHING);
        done = !(t0 <= t1);
    }
    var t = s.t;
    var n = s.n;
    var trans = s.trans;
    var c = s.c.xyz;
    // distances and weights of samples waiting for their colour
    var ct: array<f32, K>;
    var cw: array<f32, K>;
    var count = 0u;
    var steps = 0u;
    loop {
        if done || count == hdr.max_colors || steps == hdr.max_steps {
            break;
        }
        if !(t < t1 && n < hdr.max_samples) {
            done = true;
            break;
        }
        let ts = t;
        let p = o + d * ts;
        t += step;
        n += 1u;
        steps += 1u;
        if hdr.has_occ != 0u && !occupied(p) {
            continue;
        }
        let sigma = softplus(density_feature(to_grid(p)) + hdr.shift);
        let alpha = opacity(sigma * hdr.delta);
        if alpha <= 0.0 {
            continue;
        }
        let weight = trans * alpha;
        if weight > hdr.weight_threshold {
            ct[count] = ts;
            cw[count] = weight;
            count += 1u;
        }
        trans *= 1.0 - alpha;
        if trans < hdr.stop_transmittance {
            done = true;
            break;
        }
    }
    for (var i = 0u; i < count; i++) {
        c += cw[i] * color(o + d * ct[i], d);
    }
    // llvmpipe ends every further loop once the iteration budget is spent: this one then
    // stops after one pass instead of `canary` (2)
    var canary = 0u;
    loop {
        canary += 1u;
        if canary >= hdr.canary {
            break;
        }
    }
    if canary != hdr.canary {
        atomicAdd(&status[0], 1u);
    }
    if done {
        s.flag = DONE;
        c += trans * dispatch.background.xyz;
    } else {
        atomicAdd(&status[1], 1u);
    }
    state[r] = State(vec4<f32>(c, 0.0), t, trans, n, s.flag);
}

// ---------------------------------------------------------------------------------------
// The occupancy grid of a composed scene, rebuilt on the device over the cell columns that
// an edit of the ground planes touched (dispatched by `raster.rs` after the rasterisation),
// with the rule of `Occupancy::from_field` / `Occupancy::update_region` on the CPU: a cell
// is occupied when the opacity of one march step exceeds `threshold` at any of its eight
// corners or at its centre, the points placed exactly as the CPU places them.
//
// Two passes. `occupancy_points`: one invocation per vertical line of points (cell corners,
// `gid.z == 0`, or cell centres, `gid.z == 1`) interpolates the density plane once (the
// field has one density component, a ground plane times a vertical line, as every
// composable field) and walks the layers, evaluating the density of each point as
// `density_feature` does (same sums in the same order); corners go to the bit mask
// `occ_corners`, centres straight to the grid. `occupancy_cells`: one invocation per cell
// column sets the cells with a dense corner. The host splits the layers over dispatches so
// each stays inside llvmpipe's loop limit (see `render`), and the canaries count
// invocations cut short in `status[2]` (bound to the composer's status buffer, not the
// render pass's; its [0] counts the raster pass's).

// The cell columns i0..i1 x j0..j1 and cell layers k0..k1 of one dispatch.
struct OccPass {
    i0: u32,
    j0: u32,
    i1: u32,
    j1: u32,
    k0: u32,
    k1: u32,
    canary: u32,
    threshold: f32,
}

// the bit mask the render pass reads as `occupancy`
@group(0) @binding(8) var<storage, read_write> occ_cells: array<atomic<u32>>;
@group(0) @binding(9) var<uniform> occ_pass: OccPass;
// whether each cell corner is dense: (occ_nz + 1) x (occ_ny + 1) x (occ_nx + 1) bits
@group(0) @binding(10) var<storage, read_write> occ_corners: array<atomic<u32>>;

fn occ_canary() {
    var canary = 0u;
    loop {
        canary += 1u;
        if canary >= occ_pass.canary {
            break;
        }
    }
    if canary != occ_pass.canary {
        atomicAdd(&status[2], 1u);
    }
}

@compute @workgroup_size(8, 8, 1)
fn occupancy_points(@builtin(global_invocation_id) gid: vec3<u32>) {
    let centre = gid.z == 1u;
    let i = occ_pass.i0 + gid.x;
    let j = occ_pass.j0 + gid.y;
    // corners i0..=i1 x j0..=j1 on the layer boundaries k0..=k1; centres i0..i1 x j0..j1
    // in the layers k0..k1
    var end = vec3<u32>(occ_pass.i1 + 1u, occ_pass.j1 + 1u, occ_pass.k1 + 1u);
    var off = 0.0;
    if centre {
        end = vec3<u32>(occ_pass.i1, occ_pass.j1, occ_pass.k1);
        off = 0.5;
    }
    if i >= end.x || j >= end.y {
        return;
    }
    let lo = vec3<f32>(hdr.aabb_min_x, hdr.aabb_min_y, hdr.aabb_min_z);
    let cell = vec3<f32>(1.0) / vec3<f32>(hdr.occ_scale_x, hdr.occ_scale_y, hdr.occ_scale_z);
    let c = hdr.density[0];
    // the plane's channels along this line (its x and y are the same at every layer)
    let pt = plane_taps(c, to_grid(lo + (vec3<f32>(f32(i), f32(j), 0.0) + off) * cell));
    let n4 = c.ch / 4u * 4u;
    for (var q = 0u; q < n4; q += 4u) {
        va[q >> 2u] = plane4(pt, q);
    }
    for (var q = n4; q < c.ch; q++) {
        put(&va, q, plane1(pt, q));
    }
    let full = c.ch / 8u * 8u;
    let nx = hdr.occ_nx;
    let ny = hdr.occ_ny;
    for (var k = occ_pass.k0; k < end.z; k++) {
        let g = to_grid(lo + (vec3<f32>(f32(i), f32(j), f32(k)) + off) * cell);
        let lt = line_taps(c, g);
        var s0 = vec4<f32>(0.0);
        var s1 = vec4<f32>(0.0);
        var tail = 0.0;
        for (var q = 0u; q < full; q += 8u) {
            s0 += va[q >> 2u] * line4(lt, q);
            s1 += va[(q >> 2u) + 1u] * line4(lt, q + 4u);
        }
        for (var q = full; q < c.ch; q++) {
            tail += va[q >> 2u][q & 3u] * line1(lt, q);
        }
        let feature = s0.x + s0.y + s0.z + s0.w + s1.x + s1.y + s1.z + s1.w + tail;
        let sigma = softplus(feature + hdr.shift);
        let dense = opacity(sigma * hdr.delta) > occ_pass.threshold;
        if centre {
            let at = (k * ny + j) * nx + i;
            let bit = 1u << (at % 32u);
            if dense {
                atomicOr(&occ_cells[at / 32u], bit);
            } else {
                atomicAnd(&occ_cells[at / 32u], ~bit);
            }
        } else {
            let at = (k * (ny + 1u) + j) * (nx + 1u) + i;
            let bit = 1u << (at % 32u);
            if dense {
                atomicOr(&occ_corners[at / 32u], bit);
            } else {
                atomicAnd(&occ_corners[at / 32u], ~bit);
            }
        }
    }
    occ_canary();
}

fn corner_dense(i: u32, j: u32, k: u32) -> bool {
    let at = (k * (hdr.occ_ny + 1u) + j) * (hdr.occ_nx + 1u) + i;
    return ((atomicLoad(&occ_corners[at / 32u]) >> (at % 32u)) & 1u) != 0u;
}

@compute @workgroup_size(8, 8, 1)
fn occupancy_cells(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = occ_pass.i0 + gid.x;
    let j = occ_pass.j0 + gid.y;
    if i >= occ_pass.i1 || j >= occ_pass.j1 {
        return;
    }
    for (var k = occ_pass.k0; k < occ_pass.k1; k++) {
        let dense = corner_dense(i, j, k) || corner_dense(i + 1u, j, k)
            || corner_dense(i, j + 1u, k) || corner_dense(i + 1u, j + 1u, k)
            || corner_dense(i, j, k + 1u) || corner_dense(i + 1u, j, k + 1u)
            || corner_dense(i, j + 1u, k + 1u) || corner_dense(i + 1u, j + 1u, k + 1u);
        if dense {
            let at = (k * hdr.occ_ny + j) * hdr.occ_nx + i;
            atomicOr(&occ_cells[at / 32u], 1u << (at % 32u));
        }
    }
    occ_canary();
}
