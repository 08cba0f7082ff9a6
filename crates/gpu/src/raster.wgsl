// Rasterising instances' feature patches onto the composed ground planes: the same rule as
// the CPU composer (`assetfield_scene::Composition::rasterise`). Dispatched by `raster.rs`.
//
// One invocation per texel (llvmpipe pays ~0.1 us per invocation, so fewer, longer ones are
// cheaper); its channels in groups of 16, density groups first, then colour, one after the
// other. For every instance whose texel rectangle holds the texel (in the order of the
// layout), the texel's world position is taken into the instance's frame, and the patch's
// four bilinear taps, each weighted by its bilinear weight times the patch's object weight
// (premultiplied, zero outside the patch), are added to the sums, and the bilinear weights
// times the patch's core weights to the core sum. Then the canvas keeps the share
// `max(0, 1 - sum w)`: density = share * canvas + sum (or max(0, 1 - sum core) * canvas +
// sum when the composition's density rule is `Add`), colour = (share * canvas + sum) /
// (share + sum w) (the canvas colour where that is ~0). Sums run in the CPU's order.
//
// The instances that may reach a texel come from a per-tile list (TILE x TILE texels) built
// on the host, so the cost follows coverage. Only texels inside the dirty rectangle
// `r0..r1 x c0..c1` are written.
//
// llvmpipe (Mesa's software Vulkan) ends every loop of a group of invocations once they have
// iterated 65535 times in total: a dispatch walks at most `entry1 - entry0` entries of each
// tile's list per channel group (the host keeps groups x entries well inside the limit).
// When a list is longer, several dispatches share the work: the partial sums wait in the
// planes (features) and in `scratch` (the weight and core sums) between them. A last loop with a known
// trip count detects a driver that cut loops short anyway: the texel is counted in `status`
// and the host refuses the planes.

const TILE: u32 = 16u;
// vec4 of channels per group
const G: u32 = 4u;

// Mirrors the host's `Raster` words in raster.rs (checked by tests/shaders_validate.rs).
struct Raster {
    min_x: f32,
    min_y: f32,
    step_x: f32,
    step_y: f32,
    rows: u32,
    cols: u32,
    // channels of the planes, and vec4 per texel in the canvas and the patches (padded)
    nd: u32,
    nc: u32,
    dv: u32,
    cv: u32,
    // channel groups: `gd` of density, then colour, `n_groups` in all
    gd: u32,
    n_groups: u32,
    // offsets of the planes in `params` (f32), of the colour canvas in `canvas` (vec4)
    density_at: u32,
    color_at: u32,
    canvas_color: u32,
    // tiles per row, tiles in all (the lists start at `n_tiles + 1` in `tiles`)
    tiles_x: u32,
    n_tiles: u32,
    // the dirty rectangle, and the texel of the dispatch's first invocation
    r0: u32,
    c0: u32,
    r1: u32,
    c1: u32,
    r_base: u32,
    c_base: u32,
    // 1: density features add to the canvas outside the patches' cores (`DensityRule::Add`),
    // 0: they replace its share
    density_add: u32,
    canary: u32,
}

// Per dispatch: the entries `entry0..entry1` of each tile's list; whether the sums start
// from zero (`first`) and whether they are resolved into the planes (`last`).
struct Chunk {
    entry0: u32,
    entry1: u32,
    first: u32,
    last: u32,
}

// An instance: the inverse of its ground transform (position, cos and sin of -yaw, scale),
// the texels it may reach (as the CPU's `PlaneGrid::texels_of` of its bounds), and its patch
// (size, offsets of its features in `pfeat` (vec4) and of its weights and core weights
// (f32), texel size and centre).
struct Inst {
    pos_x: f32,
    pos_y: f32,
    cos: f32,
    sin: f32,
    scale: f32,
    r0: u32,
    c0: u32,
    r1: u32,
    c1: u32,
    rows: u32,
    cols: u32,
    dens: u32,
    colr: u32,
    wt: u32,
    core: u32,
    texel_x: f32,
    texel_y: f32,
    half_cols: f32,
    half_rows: f32,
}

@group(0) @binding(0) var<uniform> ra: Raster;
@group(0) @binding(1) var<uniform> chunk: Chunk;
// canvas density (`dv` vec4 per texel), then canvas colour (`cv` vec4 per texel)
@group(0) @binding(2) var<storage, read> canvas: array<vec4<f32>>;
// every template: density features, colour features (padded to vec4), weights
@group(0) @binding(3) var<storage, read> pfeat: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read> insts: array<Inst>;
// tile starts (n_tiles + 1), then the lists of instance indices
@group(0) @binding(5) var<storage, read> tiles: array<u32>;
// the field's parameters: the composed planes are written here
@group(0) @binding(6) var<storage, read_write> params: array<f32>;
// the weight and core sums of each texel between dispatches (two per texel)
@group(0) @binding(7) var<storage, read_write> scratch: array<f32>;
// [0]: invocations whose loops the driver cut short
@group(0) @binding(8) var<storage, read_write> status: array<atomic<u32>, 4>;

fn weight_at(i: u32) -> f32 {
    return pfeat[i >> 2u][i & 3u];
}

// The per-texel weights starting at `at` (f32 offset) of the four taps `idx`.
fn weights4(at: u32, idx: vec4<u32>) -> vec4<f32> {
    return vec4<f32>(
        weight_at(at + idx.x),
        weight_at(at + idx.y),
        weight_at(at + idx.z),
        weight_at(at + idx.w),
    );
}

// a + w.x f(o.x) + w.y f(o.y) + w.z f(o.z) + w.w f(o.w), left to right.
fn taps4(a: vec4<f32>, o: vec4<u32>, w: vec4<f32>) -> vec4<f32> {
    var s = a + w.x * pfeat[o.x];
    s = s + w.y * pfeat[o.y];
    s = s + w.z * pfeat[o.z];
    s = s + w.w * pfeat[o.w];
    return s;
}

// Channels ch..ch+3 (those below n) of the plane at `at` (f32 offset of the texel).
fn load4(at: u32, ch: u32, n: u32) -> vec4<f32> {
    var v = vec4<f32>(0.0);
    if ch < n {
        v.x = params[at + ch];
    }
    if ch + 1u < n {
        v.y = params[at + ch + 1u];
    }
    if ch + 2u < n {
        v.z = params[at + ch + 2u];
    }
    if ch + 3u < n {
        v.w = params[at + ch + 3u];
    }
    return v;
}

fn store4(at: u32, ch: u32, n: u32, v: vec4<f32>) {
    if ch < n {
        params[at + ch] = v.x;
    }
    if ch + 1u < n {
        params[at + ch + 1u] = v.y;
    }
    if ch + 2u < n {
        params[at + ch + 2u] = v.z;
    }
    if ch + 3u < n {
        params[at + ch + 3u] = v.w;
    }
}

// The resolved value of one vec4 of channels: density share * canvas + sum
// (`core_share` * canvas + sum with `density_add`); colour (share * canvas + sum) /
// (share + sum w), or the canvas where the norm is ~0.
fn resolve(dens: bool, share: f32, core_share: f32, norm: f32, cv: vec4<f32>, a: vec4<f32>) -> vec4<f32> {
    if dens {
        if ra.density_add != 0u {
            return core_share * cv + a;
        }
        return share * cv + a;
    }
    if norm > 1e-9 {
        return (share * cv + a) / norm;
    }
    return cv;
}

// The sums of one texel for one group of channels (vec4 `v0..v0+nv` of the texel's
// `nvec`), over the entries `lo..hi` of its tile's list, added to the partial sums `a*`
// (zero, or those of earlier dispatches); `wsum` and `csum` get the texel's weight and core
// sums.
struct Sums {
    a0: vec4<f32>,
    a1: vec4<f32>,
    a2: vec4<f32>,
    a3: vec4<f32>,
    wsum: f32,
    csum: f32,
}

fn accumulate(r: u32, c: u32, lo: u32, hi: u32, dens: bool, v0: u32, nvec: u32, s0: Sums) -> Sums {
    var s = s0;
    let nv = min(G, nvec - v0);
    let list = ra.n_tiles + 1u;
    // the texel's world position, as `PlaneGrid::world`
    let step = vec2<f32>(ra.step_x, ra.step_y);
    let p = vec2<f32>(ra.min_x, ra.min_y) + vec2<f32>(f32(c), f32(r)) * step;
    for (var e = lo; e < hi; e++) {
        let it = insts[tiles[list + e]];
        if r < it.r0 || r >= it.r1 || c < it.c0 || c >= it.c1 {
            continue;
        }
        // the texel in the instance's frame, then in patch texels
        let d = p - vec2<f32>(it.pos_x, it.pos_y);
        let q = vec2<f32>(it.cos * d.x - it.sin * d.y, it.sin * d.x + it.cos * d.y) / it.scale;
        let x = q.x / it.texel_x + it.half_cols;
        let y = q.y / it.texel_y + it.half_rows;
        if !(x > -1.0 && y > -1.0 && x < f32(it.cols) && y < f32(it.rows)) {
            continue;
        }
        let xf = floor(x);
        let yf = floor(y);
        let fx = x - xf;
        let fy = y - yf;
        let x0 = i32(xf);
        let y0 = i32(yf);
        let cols = i32(it.cols);
        let rows = i32(it.rows);
        let okx0 = x0 >= 0;
        let okx1 = x0 + 1 < cols;
        let oky0 = y0 >= 0;
        let oky1 = y0 + 1 < rows;
        let ok = vec4<bool>(okx0 && oky0, okx1 && oky0, okx0 && oky1, okx1 && oky1);
        // texel indices (0 for taps outside the patch, whose weight is 0)
        let xs = vec4<i32>(x0, x0 + 1, x0, x0 + 1);
        let ys = vec4<i32>(y0, y0, y0 + 1, y0 + 1);
        let idx = select(vec4<u32>(0u), vec4<u32>(ys * cols + xs), ok);
        let bw = vec4<f32>((1.0 - fx) * (1.0 - fy), fx * (1.0 - fy), (1.0 - fx) * fy, fx * fy);
        let w = select(vec4<f32>(0.0), bw * weights4(it.wt, idx), ok);
        s.wsum += w.x + w.y + w.z + w.w;
        let cs = select(vec4<f32>(0.0), bw * weights4(it.core, idx), ok);
        s.csum += cs.x + cs.y + cs.z + cs.w;
        var base = it.colr;
        if dens {
            base = it.dens;
        }
        let o = idx * nvec + vec4<u32>(base + v0);
        s.a0 = taps4(s.a0, o, w);
        if nv > 1u {
            s.a1 = taps4(s.a1, o + vec4<u32>(1u), w);
        }
        if nv > 2u {
            s.a2 = taps4(s.a2, o + vec4<u32>(2u), w);
        }
        if nv > 3u {
            s.a3 = taps4(s.a3, o + vec4<u32>(3u), w);
        }
    }
    return s;
}

// One invocation per texel: its channel groups in turn (each walks the tile's list again;
// the host sizes a dispatch's share of the list for all of them).
@compute @workgroup_size(8, 8, 1)
fn raster(@builtin(global_invocation_id) gid: vec3<u32>) {
    let c = ra.c_base + gid.x;
    let r = ra.r_base + gid.y;
    if r < ra.r0 || r >= ra.r1 || c < ra.c0 || c >= ra.c1 {
        return;
    }
    let k = r * ra.cols + c;
    let t = (r / TILE) * ra.tiles_x + c / TILE;
    let start = tiles[t];
    let lo = start + chunk.entry0;
    let hi = min(tiles[t + 1u], start + chunk.entry1);
    var wsum0 = 0.0;
    var csum0 = 0.0;
    if chunk.first == 0u {
        wsum0 = scratch[2u * k];
        csum0 = scratch[2u * k + 1u];
    }
    var wsum = wsum0;
    var csum = csum0;
    for (var g = 0u; g < ra.n_groups; g++) {
        let dens = g < ra.gd;
        // this group's vec4s: v0.. of the texel's `nvec`; its channels ch.. of `n`
        var v0 = (g - ra.gd) * G;
        var nvec = ra.cv;
        var n = ra.nc;
        var at = ra.color_at + k * ra.nc;
        var cb = ra.canvas_color + k * ra.cv;
        if dens {
            v0 = g * G;
            nvec = ra.dv;
            n = ra.nd;
            at = ra.density_at + k * ra.nd;
            cb = k * ra.dv;
        }
        cb += v0;
        let ch = v0 * 4u;
        var s = Sums(vec4<f32>(0.0), vec4<f32>(0.0), vec4<f32>(0.0), vec4<f32>(0.0), wsum0, csum0);
        if chunk.first == 0u {
            s.a0 = load4(at, ch, n);
            s.a1 = load4(at, ch + 4u, n);
            s.a2 = load4(at, ch + 8u, n);
            s.a3 = load4(at, ch + 12u, n);
        }
        s = accumulate(r, c, lo, hi, dens, v0, nvec, s);
        wsum = s.wsum;
        csum = s.csum;
        if chunk.last == 0u {
            store4(at, ch, n, s.a0);
            store4(at, ch + 4u, n, s.a1);
            store4(at, ch + 8u, n, s.a2);
            store4(at, ch + 12u, n, s.a3);
            continue;
        }
        let share = max(1.0 - wsum, 0.0);
        let core_share = max(1.0 - csum, 0.0);
        let norm = share + wsum;
        let nv = min(G, nvec - v0);
        store4(at, ch, n, resolve(dens, share, core_share, norm, canvas[cb], s.a0));
        if nv > 1u {
            store4(at, ch + 4u, n, resolve(dens, share, core_share, norm, canvas[cb + 1u], s.a1));
        }
        if nv > 2u {
            store4(at, ch + 8u, n, resolve(dens, share, core_share, norm, canvas[cb + 2u], s.a2));
        }
        if nv > 3u {
            store4(at, ch + 12u, n, resolve(dens, share, core_share, norm, canvas[cb + 3u], s.a3));
        }
    }
    // llvmpipe ends every further loop once the iteration budget is spent: this one then
    // stops after one pass instead of `canary` (2)
    var canary = 0u;
    loop {
        canary += 1u;
        if canary >= ra.canary {
            break;
        }
    }
    if canary != ra.canary {
        atomicAdd(&status[0], 1u);
    }
    if chunk.last == 0u {
        scratch[2u * k] = wsum;
        scratch[2u * k + 1u] = csum;
    }
}
