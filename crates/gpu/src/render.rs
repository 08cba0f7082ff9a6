//! Uploading a field and dispatching the volume rendering shader (`render.wgsl`).

use crate::context::DeviceErrors;
use crate::{GpuContext, GpuError, RENDER_WGSL};
use assetfield_core::{Camera, Ray};
use assetfield_field::model::Comp;
use assetfield_field::{DecoderKind, Field, FieldConfig, MarchSettings, ModelKind, Occupancy};
use glam::Vec3;
use std::sync::mpsc;

/// Widest vector the shader keeps per sample (its `MAX_VEC4` times 4).
const MAX_WIDTH: usize = 192;
/// Plane-line components per field (VM has three).
const MAX_COMPS: usize = 3;
/// Dense layers in the MLP decoder.
const MAX_LAYERS: usize = 4;
/// The shader's workgroup size (rays per workgroup).
const WORKGROUP: u32 = 64;
/// Rays per pass at most: a 400 x 400 view is one pass; bigger batches take several.
const PASS_RAYS: u64 = 1 << 18;
/// Bytes per ray in the ray buffer (origin and direction as two vec4).
const RAY_BYTES: u64 = 32;
/// Bytes per ray of the march state (and the final colour).
const STATE_BYTES: u64 = 32;
const NO_LINE: u32 = u32::MAX;
const NO_BIAS: usize = usize::MAX;
/// Trip count of the shader's last loop, which detects loops cut short by the driver.
const CANARY: u32 = 2;
/// Bytes of the status counters read back after each pass.
const STATUS_BYTES: u64 = 16;

/// One 32-bit member of the shader's header, by the name it has in `render.wgsl`
/// (nested members as `density[0].plane`); floats are stored as their bits.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct HeaderField {
    pub name: String,
    pub bits: u32,
}

/// What [`FieldRenderer::new`] uploads for a field, checked against the device's limits.
#[derive(Debug, Clone)]
pub struct UploadPlan {
    /// The header in member order (member `k` at byte offset `4 k`).
    pub header: Vec<HeaderField>,
    /// Bytes of the parameter buffer (the field's flat `f32` tensors).
    pub params_bytes: u64,
    /// Bytes of the occupancy bit mask (4 when there is no grid).
    pub occupancy_bytes: u64,
    /// The networks (colour basis, guidance MLP, decoder) padded to multiples of four in
    /// both dimensions, row-major, biases after their weights.
    pub network: Vec<f32>,
    /// Rays per dispatch.
    pub pass_rays: u64,
    /// The most rays per dispatch the device's limits allow (at most 2^18).
    pub max_pass_rays: u64,
    /// Samples per ray at most (as the CPU renderer).
    pub max_samples: u64,
    /// Samples a ray marches per dispatch at most.
    pub max_steps: u64,
    /// Colours a ray decodes per dispatch at most.
    pub max_colors: u64,
}

impl UploadPlan {
    fn header_words(&self) -> Vec<u32> {
        self.header.iter().map(|f| f.bits).collect()
    }
}

#[derive(Default)]
struct HeaderBuilder(Vec<HeaderField>);

impl HeaderBuilder {
    fn u(&mut self, name: impl Into<String>, v: u32) {
        self.0.push(HeaderField { name: name.into(), bits: v });
    }
    fn f(&mut self, name: impl Into<String>, v: f32) {
        self.u(name, v.to_bits());
    }
    fn layer(&mut self, name: &str, l: [u32; 4]) {
        for (member, v) in ["w", "b", "n_in4", "n_out4"].into_iter().zip(l) {
            self.u(format!("{name}.{member}"), v);
        }
    }
}

fn unsupported(msg: impl Into<String>) -> GpuError {
    GpuError::Unsupported(msg.into())
}

fn to_u32(v: usize, what: &str) -> Result<u32, GpuError> {
    u32::try_from(v).map_err(|_| unsupported(format!("{what} = {v} does not fit in 32 bits")))
}

/// `[weight offset, bias offset, inn, out]` of a named dense layer (`NO_BIAS` for none).
fn dense(field: &Field, name: &str, bias: bool) -> Result<[usize; 4], GpuError> {
    let w = field
        .params
        .spec(&format!("{name}.weight"))
        .ok_or_else(|| unsupported(format!("the field has no tensor {name}.weight")))?;
    let [out, inn] = w.shape[..] else {
        return Err(unsupported(format!("{name}.weight has shape {:?}", w.shape)));
    };
    let b = if bias {
        let b = field
            .params
            .spec(&format!("{name}.bias"))
            .ok_or_else(|| unsupported(format!("the field has no tensor {name}.bias")))?;
        if b.len != out {
            return Err(unsupported(format!("{name}.bias has {} values, not {out}", b.len)));
        }
        b.offset
    } else {
        NO_BIAS
    };
    Ok([w.offset, b, inn, out])
}

fn max_width(what: &str, n: usize) -> Result<(), GpuError> {
    if n > MAX_WIDTH {
        return Err(unsupported(format!(
            "{what} is {n} wide; the shader keeps at most {MAX_WIDTH} values per sample"
        )));
    }
    Ok(())
}

/// Check that `field` (and its occupancy grid) fit the shader and the device's `limits`, and
/// lay out the shader's header. Needs no device: [`FieldRenderer::new`] calls it with the
/// device's limits.
pub fn plan_upload(
    field: &Field,
    occ: Option<&Occupancy>,
    limits: &wgpu::Limits,
) -> Result<UploadPlan, GpuError> {
    let cfg = &field.config;
    let settings = MarchSettings::default();
    let mut h = HeaderBuilder::default();
    let mut net = Network::default();
    let kind = match cfg.kind {
        ModelKind::Standard => 0,
        ModelKind::Integrated => 1,
        ModelKind::Vm => 2,
    };
    let density = field.density_components();
    let color = field.color_components();
    if density.is_empty() || density.len() > MAX_COMPS || color.len() > MAX_COMPS {
        return Err(unsupported(format!(
            "{} density and {} colour components (1 to {MAX_COMPS} each)",
            density.len(),
            color.len()
        )));
    }
    let app_dim = cfg.app_dim();
    let fdim = cfg.features_dim();
    max_width("the colour features (app_dim)", app_dim)?;
    max_width("the colour basis output", fdim)?;
    h.u("kind", kind);
    h.u("n_density", density.len() as u32);
    h.u("n_color", color.len() as u32);
    let (decoder, sh_degree, view_freqs, layers) = decoder_layers(field)?;
    h.u("decoder", decoder);
    h.u("sh_degree", sh_degree as u32);
    h.u("view_freqs", to_u32(view_freqs, "view_freqs")?);
    h.u("n_layers", layers.len() as u32);
    h.u("app_dim", app_dim as u32);
    h.u("fdim", fdim as u32);
    let basis = dense(field, "color.basis", false)?;
    if basis[2] != app_dim || basis[3] != fdim {
        return Err(unsupported("colour basis shape does not match the configuration"));
    }
    let guide = guidance_layers(field, density[0].ch)?;
    h.u("guide_in", guide.map_or(0, |(g0, _)| g0[2] as u32));
    let occupancy_bytes = occupancy_words(&mut h, occ)?;
    h.u("max_samples", to_u32(settings.max_samples, "max_samples")?);
    let (max_steps, max_colors) =
        budgets(settings.max_samples, density, color, cfg, basis, guide, &layers);
    h.u("max_steps", max_steps as u32);
    h.u("max_colors", max_colors as u32);
    h.u("canary", CANARY);
    geometry_words(&mut h, cfg, occ, &settings);
    for (prefix, comps) in [("density", density), ("color", color)] {
        component_words(&mut h, prefix, comps)?;
    }
    let data = &field.params.data;
    let basis = net.add(data, basis);
    h.layer("basis", basis);
    let (g0, g1) = match guide {
        Some((g0, g1)) => (net.add(data, g0), net.add(data, g1)),
        None => ([0; 4], [0; 4]),
    };
    h.layer("guide0", g0);
    h.layer("guide1", g1);
    for i in 0..MAX_LAYERS {
        let l = match layers.get(i) {
            Some(l) => net.add(data, *l),
            None => [0; 4],
        };
        h.layer(&format!("layers[{i}]"), l);
    }
    // buffers against the device's limits
    let limit = limits.max_storage_buffer_binding_size.min(limits.max_buffer_size);
    let params_bytes = data.len() as u64 * 4;
    if data.len() >= u32::MAX as usize || net.0.len() >= u32::MAX as usize {
        return Err(unsupported("more than 2^32 parameters"));
    }
    for (what, bytes) in [
        ("the field's parameters", params_bytes),
        ("the occupancy grid", occupancy_bytes),
        ("the networks", net.0.len() as u64 * 4),
        ("the shader header", h.0.len() as u64 * 4),
    ] {
        if bytes > limit {
            return Err(GpuError::BufferTooLarge { what, bytes, limit });
        }
    }
    let pass_rays = PASS_RAYS.min(limit / RAY_BYTES).min((limit - STATUS_BYTES) / STATE_BYTES);
    let groups = pass_rays.div_ceil(WORKGROUP as u64);
    let max_groups = limits.max_compute_workgroups_per_dimension as u64;
    if pass_rays == 0 || groups > max_groups * max_groups {
        return Err(unsupported("the device's limits leave no room for a pass of rays"));
    }
    Ok(UploadPlan {
        header: h.0,
        params_bytes,
        occupancy_bytes,
        network: net.0,
        pass_rays,
        max_pass_rays: pass_rays,
        max_samples: settings.max_samples as u64,
        max_steps,
        max_colors,
    })
}

/// The colour decoder as the shader reads it: its kind (0 MLP, 1 SH), SH degree, view
/// frequencies and MLP layers (`[weight, bias, inn, out]` each).
type DecoderPlan = (u32, usize, usize, Vec<[usize; 4]>);

/// The colour decoder ([`DecoderPlan`]), checked against the shader's bounds and the
/// configuration.
fn decoder_layers(field: &Field) -> Result<DecoderPlan, GpuError> {
    let cfg = &field.config;
    match &cfg.decoder {
        DecoderKind::Mlp { hidden, view_freqs } => {
            let mut layers = Vec::new();
            for k in 0..=hidden.len() {
                layers.push(dense(field, &format!("decoder.{k}"), true)?);
            }
            if layers.len() > MAX_LAYERS {
                return Err(unsupported(format!(
                    "{} decoder layers (at most {MAX_LAYERS})",
                    layers.len()
                )));
            }
            let input = cfg.features_dim() + cfg.view_encoding_dim();
            if layers[0][2] != input || layers.last().is_some_and(|l| l[3] != 3) {
                return Err(unsupported("decoder shapes do not match the configuration"));
            }
            for (k, l) in layers.iter().enumerate() {
                max_width(&format!("decoder layer {k} input"), l[2])?;
                max_width(&format!("decoder layer {k} output"), l[3])?;
            }
            Ok((0, 0, *view_freqs, layers))
        }
        DecoderKind::Sh { degree } => {
            if *degree > 2 {
                return Err(unsupported(format!("SH degree {degree} (at most 2)")));
            }
            Ok((1, *degree, 0, Vec::new()))
        }
    }
}

/// I-AssetField's guidance MLP (its two layers), checked against the density channels
/// (`density_ch`) and the colour features; `None` for the other models.
fn guidance_layers(field: &Field, density_ch: usize) -> Result<Option<GuideLayers>, GpuError> {
    if field.config.kind != ModelKind::Integrated {
        return Ok(None);
    }
    let g0 = dense(field, "guide.0", true)?;
    let g1 = dense(field, "guide.1", true)?;
    max_width("the guidance input (density channels)", g0[2])?;
    max_width("the guidance hidden layer", g0[3])?;
    if g0[2] != density_ch || g1[2] != g0[3] || g1[3] != field.config.app_dim() {
        return Err(unsupported("guidance MLP shapes do not match the configuration"));
    }
    Ok(Some((g0, g1)))
}

/// The two layers of I-AssetField's guidance MLP (`[weight, bias, inn, out]` each).
type GuideLayers = ([usize; 4], [usize; 4]);

/// The occupancy grid's header words (its cells, or none); the bytes of its bitfield.
fn occupancy_words(h: &mut HeaderBuilder, occ: Option<&Occupancy>) -> Result<u64, GpuError> {
    match occ {
        Some(o) => {
            let cells = o.res.iter().product::<usize>();
            if o.res.contains(&0) || o.cells_u8().len() != cells {
                return Err(unsupported(format!("occupancy grid {:?} is malformed", o.res)));
            }
            h.u("has_occ", 1);
            for (name, v) in ["occ_nx", "occ_ny", "occ_nz"].into_iter().zip(o.res) {
                h.u(name, to_u32(v, name)?);
            }
            Ok((cells.div_ceil(32) * 4) as u64)
        }
        None => {
            for name in ["has_occ", "occ_nx", "occ_ny", "occ_nz"] {
                h.u(name, 0);
            }
            Ok(4)
        }
    }
}

/// The box, the lattice's and the occupancy grid's scales, and the march's step, shift and
/// thresholds.
fn geometry_words(
    h: &mut HeaderBuilder,
    cfg: &FieldConfig,
    occ: Option<&Occupancy>,
    settings: &MarchSettings,
) {
    let aabb = cfg.aabb();
    let extent = aabb.extent().max(Vec3::splat(1e-9));
    let vec3 = |h: &mut HeaderBuilder, name: &str, v: Vec3| {
        for (axis, x) in ["x", "y", "z"].into_iter().zip(v.to_array()) {
            h.f(format!("{name}_{axis}"), x);
        }
    };
    vec3(h, "aabb_min", aabb.min);
    vec3(h, "aabb_max", aabb.max);
    // as `Field::to_grid` and `Occupancy::occupied` compute them (both private)
    let r = cfg.res;
    vec3(
        h,
        "grid_scale",
        Vec3::new((r[0] - 1) as f32, (r[1] - 1) as f32, (r[2] - 1) as f32) / extent,
    );
    let occ_scale = occ.map_or(Vec3::ZERO, |o| {
        Vec3::new(o.res[0] as f32, o.res[1] as f32, o.res[2] as f32) / extent
    });
    vec3(h, "occ_scale", occ_scale);
    let step = cfg.step_size();
    h.f("step", step);
    h.f("delta", step * cfg.distance_scale);
    h.f("shift", cfg.density_shift);
    h.f("weight_threshold", settings.weight_threshold);
    h.f("stop_transmittance", settings.stop_transmittance);
}

/// The header words of the density or colour components (`prefix`), [`MAX_COMPS`] of them
/// (zeros past the field's).
fn component_words(h: &mut HeaderBuilder, prefix: &str, comps: &[Comp]) -> Result<(), GpuError> {
    for i in 0..MAX_COMPS {
        let v = match comps.get(i) {
            Some(c) => {
                if c.cols < 2 || c.rows < 2 || (c.line.is_some() && c.len < 2) {
                    return Err(unsupported(format!(
                        "{prefix} component {i} has fewer than 2 samples along an axis"
                    )));
                }
                if prefix == "density" && c.line.is_none() {
                    return Err(unsupported("a density component without a line"));
                }
                let line = match c.line {
                    Some(l) => to_u32(l, "line offset")?,
                    None => NO_LINE,
                };
                [
                    to_u32(c.plane, "plane offset")?,
                    line,
                    c.axes[0] as u32,
                    c.axes[1] as u32,
                    c.axes[2] as u32,
                    to_u32(c.cols, "cols")?,
                    to_u32(c.rows, "rows")?,
                    to_u32(c.len, "len")?,
                    to_u32(c.ch, "channels")?,
                ]
            }
            None => [0; 9],
        };
        let names = ["plane", "line", "a0", "a1", "a2", "cols", "rows", "len", "ch"];
        for (name, v) in names.into_iter().zip(v) {
            h.u(format!("{prefix}[{i}].{name}"), v);
        }
    }
    Ok(())
}

/// Loop iterations one dispatch may spend per group of invocations (llvmpipe ends all loops
/// of a group after 65535; the rest is slack for the estimates below).
const LOOP_BUDGET: u64 = 56_000;
/// Of which the march (samples and their density) may take at most this much.
const MARCH_BUDGET: u64 = 24_000;
/// The shader's `K`: most colour samples recorded per dispatch.
const MAX_COLORS: u64 = 32;

/// Samples marched and colours decoded per ray and dispatch, from upper bounds of the loop
/// iterations the shader spends on one sample and on one colour.
fn budgets(
    max_samples: usize,
    density: &[Comp],
    color: &[Comp],
    cfg: &FieldConfig,
    basis: [usize; 4],
    guide: Option<([usize; 4], [usize; 4])>,
    layers: &[[usize; 4]],
) -> (u64, u64) {
    let q = |n: usize| n.div_ceil(4) as u64;
    // a matrix-vector product: 4 x 4 blocks, one loop per four outputs
    let dense = |l: [usize; 4]| q(l[3]) * (q(l[2]) + 1) + 1;
    let channels8 = |c: &Comp| 2 + (c.ch / 8 + c.ch % 8) as u64;
    let channels4 = |c: &Comp| 2 + (c.ch / 4 + c.ch % 4) as u64;
    let step = 2 + density.iter().map(channels8).sum::<u64>();
    let features = dense(basis)
        + match guide {
            Some((g0, g1)) => {
                q(g0[2]) + channels4(&density[0]) + dense(g0) + dense(g1) + channels4(&color[0])
            }
            None => q(basis[2]) + color.iter().map(channels4).sum::<u64>(),
        };
    let decoder = match &cfg.decoder {
        DecoderKind::Mlp { view_freqs, .. } => {
            q(layers[0][2])
                + *view_freqs as u64
                + 2
                + layers.iter().map(|l| dense(*l) + 1).sum::<u64>()
        }
        DecoderKind::Sh { degree } => 3 * ((degree + 1) * (degree + 1) + 2) as u64,
    };
    let color_cost = (features + decoder) * 5 / 4 + 8;
    let max_steps = (MARCH_BUDGET / step).clamp(1, max_samples as u64);
    let max_colors = ((LOOP_BUDGET - max_steps * step) / color_cost).clamp(1, MAX_COLORS);
    (max_steps, max_colors)
}

/// The networks, padded for the shader's 4 x 4 blocks.
#[derive(Default)]
struct Network(Vec<f32>);

impl Network {
    /// Append a layer (`[weight offset, bias offset, inn, out]` in the parameters) padded
    /// with zeros; returns its header entry (offsets in vec4 units).
    fn add(&mut self, data: &[f32], [w, b, inn, out]: [usize; 4]) -> [u32; 4] {
        let (in4, out4) = (inn.div_ceil(4), out.div_ceil(4));
        let at = self.0.len() / 4;
        for o in 0..out4 * 4 {
            for i in 0..in4 * 4 {
                let v = if o < out && i < inn { data[w + o * inn + i] } else { 0.0 };
                self.0.push(v);
            }
        }
        let bias = self.0.len() / 4;
        for o in 0..out4 * 4 {
            self.0.push(if b != NO_BIAS && o < out { data[b + o] } else { 0.0 });
        }
        [at as u32, bias as u32, in4 as u32, out4 as u32]
    }
}

/// A field uploaded to the device with the rendering pipeline, ready to render cameras.
#[derive(Debug)]
pub struct FieldRenderer {
    device: wgpu::Device,
    queue: wgpu::Queue,
    pipeline: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
    header: wgpu::Buffer,
    params: wgpu::Buffer,
    occupancy: wgpu::Buffer,
    network: wgpu::Buffer,
    module: wgpu::ShaderModule,
    plan: UploadPlan,
    max_groups: u32,
    errors: DeviceErrors,
}

/// Buffers for one pass of rays.
struct Slot {
    rays: wgpu::Buffer,
    state: wgpu::Buffer,
    status: wgpu::Buffer,
    staging: wgpu::Buffer,
    dispatch: wgpu::Buffer,
    bind: wgpu::BindGroup,
}

pub(crate) fn storage_entry(binding: u32, read_only: bool) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Storage { read_only },
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    }
}

pub(crate) fn bytes_of(words: &[u32]) -> &[u8] {
    bytemuck::cast_slice(words)
}

pub(crate) async fn scoped<T>(
    device: &wgpu::Device,
    stage: &'static str,
    work: impl FnOnce() -> T,
) -> Result<T, GpuError> {
    let oom = device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
    let validation = device.push_error_scope(wgpu::ErrorFilter::Validation);
    let out = work();
    let v = validation.pop().await;
    let m = oom.pop().await;
    match v.or(m) {
        Some(e) => Err(GpuError::Wgpu { stage, reason: e.to_string() }),
        None => Ok(out),
    }
}

impl FieldRenderer {
    /// Upload `field` (and its occupancy grid, if any) and build the pipeline.
    pub fn new(ctx: &GpuContext, field: &Field, occ: Option<&Occupancy>) -> Result<Self, GpuError> {
        let plan = plan_upload(field, occ, &ctx.limits())?;
        let device = ctx.device().clone();
        let queue = ctx.queue().clone();
        let occ_words: Vec<u32> = match occ {
            Some(o) => {
                let mut w = vec![0u32; (plan.occupancy_bytes / 4) as usize];
                for (k, c) in o.cells_u8().iter().enumerate() {
                    w[k / 32] |= u32::from(*c != 0) << (k % 32);
                }
                w
            }
            None => vec![0],
        };
        let (pipeline, layout, header, params, occupancy, network, module) =
            pollster::block_on(scoped(&device, "pipeline and upload", || {
                let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
                    label: Some("render.wgsl"),
                    source: wgpu::ShaderSource::Wgsl(RENDER_WGSL.into()),
                });
                let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                    label: Some("render"),
                    entries: &[
                        storage_entry(0, true),
                        storage_entry(1, true),
                        storage_entry(2, true),
                        storage_entry(3, true),
                        storage_entry(4, true),
                        storage_entry(5, false),
                        storage_entry(7, false),
                        wgpu::BindGroupLayoutEntry {
                            binding: 6,
                            visibility: wgpu::ShaderStages::COMPUTE,
                            ty: wgpu::BindingType::Buffer {
                                ty: wgpu::BufferBindingType::Uniform,
                                has_dynamic_offset: false,
                                min_binding_size: None,
                            },
                            count: None,
                        },
                    ],
                });
                let pipeline =
                    crate::context::compute_pipeline(&device, "render", &layout, &module, "render");
                let storage = |label, bytes: &[u8]| {
                    use wgpu::BufferUsages as U;
                    let buf = device.create_buffer(&wgpu::BufferDescriptor {
                        label: Some(label),
                        size: bytes.len() as u64,
                        // COPY_SRC: the composer reads its planes back from `params`
                        usage: U::STORAGE | U::COPY_DST | U::COPY_SRC,
                        mapped_at_creation: false,
                    });
                    queue.write_buffer(&buf, 0, bytes);
                    buf
                };
                let header = storage("header", bytes_of(&plan.header_words()));
                let params = storage("params", bytemuck::cast_slice(&field.params.data));
                let occupancy = storage("occupancy", bytes_of(&occ_words));
                let network = storage("network", bytemuck::cast_slice(&plan.network));
                (pipeline, layout, header, params, occupancy, network, module)
            }))?;
        let max_groups = ctx.limits().max_compute_workgroups_per_dimension;
        Ok(FieldRenderer {
            device,
            queue,
            pipeline,
            layout,
            header,
            params,
            occupancy,
            network,
            module,
            plan,
            max_groups,
            errors: ctx.errors().clone(),
        })
    }

    /// What wgpu reported outside the error scopes (checked after every readback).
    pub(crate) fn device_errors(&self) -> &DeviceErrors {
        &self.errors
    }

    /// What was uploaded.
    pub fn plan(&self) -> &UploadPlan {
        &self.plan
    }

    /// The field's parameters on the device (the composer writes its planes there).
    pub(crate) fn params_buffer(&self) -> &wgpu::Buffer {
        &self.params
    }

    /// The shader's header on the device (the composer's occupancy pass reads it).
    pub(crate) fn header_buffer(&self) -> &wgpu::Buffer {
        &self.header
    }

    /// The occupancy bit mask on the device (the composer's occupancy pass writes it).
    pub(crate) fn occupancy_buffer(&self) -> &wgpu::Buffer {
        &self.occupancy
    }

    /// `render.wgsl`, compiled (it also holds the composer's occupancy entry point).
    pub(crate) fn module(&self) -> &wgpu::ShaderModule {
        &self.module
    }

    /// Whether the march skips the cells the occupancy grid marks empty (only for a
    /// renderer made with a grid; `false` marches every sample).
    pub fn occupancy_enabled(&self) -> bool {
        self.plan.header.iter().any(|f| f.name == "has_occ" && f.bits != 0)
    }

    /// Turn the use of the uploaded occupancy grid on or off (no effect without a grid).
    pub(crate) fn set_occupancy_enabled(&mut self, on: bool) {
        if self.occ_cells() == 0 {
            return;
        }
        for f in &mut self.plan.header {
            if f.name == "has_occ" {
                f.bits = on.into();
            }
        }
        self.queue.write_buffer(&self.header, 0, bytes_of(&self.plan.header_words()));
    }

    /// Cells of the uploaded occupancy grid (0 without one).
    pub(crate) fn occ_cells(&self) -> u64 {
        let dim = |name: &str| {
            self.plan.header.iter().find(|f| f.name == name).map_or(0, |f| f.bits as u64)
        };
        dim("occ_nx") * dim("occ_ny") * dim("occ_nz")
    }

    /// Rays per pass (default: the largest the device allows, at most 2^18): smaller passes
    /// take less memory and return control to the device more often. Rounded up to whole
    /// workgroups; larger values than the device allows are capped.
    pub fn with_pass_rays(mut self, rays: u64) -> Self {
        let rays = rays.max(1).next_multiple_of(WORKGROUP as u64);
        self.plan.pass_rays = rays.min(self.plan.max_pass_rays);
        self
    }

    /// Lower the work per ray and dispatch (samples marched, colours decoded; at least 1,
    /// at most the planned budgets): more dispatches for the same image. For tests of the
    /// resumed march, or to keep dispatches short on a device with a watchdog.
    pub fn with_dispatch_budget(mut self, max_steps: u64, max_colors: u64) -> Self {
        self.plan.max_steps = max_steps.clamp(1, self.plan.max_steps);
        self.plan.max_colors = max_colors.clamp(1, self.plan.max_colors);
        for f in &mut self.plan.header {
            match f.name.as_str() {
                "max_steps" => f.bits = self.plan.max_steps as u32,
                "max_colors" => f.bits = self.plan.max_colors as u32,
                _ => {}
            }
        }
        self.queue.write_buffer(&self.header, 0, bytes_of(&self.plan.header_words()));
        self
    }

    /// Render one view: `[height][width][3]` RGB, as [`assetfield_field::render_view`].
    pub fn render(&self, camera: &Camera, background: Vec3) -> Result<Vec<f32>, GpuError> {
        Ok(self.render_batch(std::slice::from_ref(camera), background)?.remove(0))
    }

    /// Render many views with one upload of their rays and a few large passes.
    pub fn render_batch(
        &self,
        cameras: &[Camera],
        background: Vec3,
    ) -> Result<Vec<Vec<f32>>, GpuError> {
        let rgb = self.render_rays(&rays_of(cameras), background)?;
        Ok(split_views(&rgb, cameras))
    }

    /// Composited RGB of each ray (`[rays][3]`).
    pub fn render_rays(&self, rays: &[Ray], background: Vec3) -> Result<Vec<f32>, GpuError> {
        pollster::block_on(self.render_rays_async(rays, background))
    }

    /// [`FieldRenderer::render_rays`] as a future.
    pub async fn render_rays_async(
        &self,
        rays: &[Ray],
        background: Vec3,
    ) -> Result<Vec<f32>, GpuError> {
        let mut out = vec![0.0f32; rays.len() * 3];
        if rays.is_empty() {
            return Ok(out);
        }
        let pass = (self.plan.pass_rays as usize).min(rays.len());
        let slot = scoped(&self.device, "buffers", || self.slot(pass)).await?;
        let bg = background.extend(0.0).to_array();
        for (k, chunk) in rays.chunks(pass).enumerate() {
            let data: Vec<f32> = chunk
                .iter()
                .flat_map(|r| {
                    [r.origin.x, r.origin.y, r.origin.z, 0.0, r.dir.x, r.dir.y, r.dir.z, 0.0]
                })
                .collect();
            let mut dispatch = [0u32; 8];
            for (d, v) in dispatch.iter_mut().zip(bg) {
                *d = v.to_bits();
            }
            dispatch[4] = chunk.len() as u32;
            self.queue.write_buffer(&slot.rays, 0, bytemuck::cast_slice(&data));
            self.queue.write_buffer(&slot.dispatch, 0, bytes_of(&dispatch));
            let states = chunk.len() as u64 * STATE_BYTES;
            let mut enc = self.device.create_command_encoder(&Default::default());
            enc.clear_buffer(&slot.state, 0, Some(states));
            self.queue.submit([enc.finish()]);
            // dispatch until every ray is done: each dispatch advances every ray that is not
            // by `max_steps` samples or `max_colors` colours, or finishes it
            let max_dispatches = self.plan.max_samples.div_ceil(self.plan.max_steps)
                + self.plan.max_samples.div_ceil(self.plan.max_colors)
                + 2;
            let mut dispatches = 0;
            loop {
                dispatches += 1;
                let [cut_short, running] = self.dispatch(&slot, chunk.len() as u32).await?;
                if cut_short > 0 {
                    return Err(GpuError::LoopLimit { rays: cut_short });
                }
                if running == 0 {
                    break;
                }
                if dispatches >= max_dispatches {
                    return Err(GpuError::Readback(format!(
                        "{running} rays still marching after {dispatches} dispatches"
                    )));
                }
            }
            let view =
                map(&self.device, &self.errors, &slot.staging, STATUS_BYTES..STATUS_BYTES + states)
                    .await?;
            let dst = &mut out[k * pass * 3..(k * pass + chunk.len()) * 3];
            for (d, st) in dst.chunks_exact_mut(3).zip(view.chunks_exact(STATE_BYTES as usize)) {
                for (c, b) in d.iter_mut().zip(st.chunks_exact(4)) {
                    *c = f32::from_le_bytes([b[0], b[1], b[2], b[3]]);
                }
            }
            drop(view);
            slot.staging.unmap();
        }
        Ok(out)
    }

    /// One dispatch over a pass of `n` rays; its status counters (rays cut short by the
    /// driver, rays still marching) once it has run. The rays' states are copied to the
    /// staging buffer after the counters.
    async fn dispatch(&self, slot: &Slot, n: u32) -> Result<[u32; 2], GpuError> {
        let states = n as u64 * STATE_BYTES;
        scoped(&self.device, "render pass", || {
            let mut enc = self
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("render") });
            enc.clear_buffer(&slot.status, 0, None);
            {
                let mut cp = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some("render"),
                    timestamp_writes: None,
                });
                cp.set_pipeline(&self.pipeline);
                cp.set_bind_group(0, &slot.bind, &[]);
                let groups = n.div_ceil(WORKGROUP);
                let x = groups.min(self.max_groups);
                cp.dispatch_workgroups(x, groups.div_ceil(x), 1);
            }
            enc.copy_buffer_to_buffer(&slot.status, 0, &slot.staging, 0, STATUS_BYTES);
            enc.copy_buffer_to_buffer(&slot.state, 0, &slot.staging, STATUS_BYTES, states);
            self.queue.submit([enc.finish()]);
        })
        .await?;
        let view = map(&self.device, &self.errors, &slot.staging, 0..STATUS_BYTES).await?;
        let word = |k: usize| u32::from_le_bytes([view[k], view[k + 1], view[k + 2], view[k + 3]]);
        let status = [word(0), word(4)];
        drop(view);
        slot.staging.unmap();
        Ok(status)
    }

    fn slot(&self, pass: usize) -> Slot {
        let buf = |label, size: u64, usage| {
            self.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size,
                usage,
                mapped_at_creation: false,
            })
        };
        use wgpu::BufferUsages as U;
        let states = pass as u64 * STATE_BYTES;
        let rays = buf("rays", pass as u64 * RAY_BYTES, U::STORAGE | U::COPY_DST);
        let state = buf("state", states, U::STORAGE | U::COPY_SRC | U::COPY_DST);
        let status = buf("status", STATUS_BYTES, U::STORAGE | U::COPY_DST | U::COPY_SRC);
        let staging = buf("readback", STATUS_BYTES + states, U::MAP_READ | U::COPY_DST);
        let dispatch = buf("dispatch", 32, U::UNIFORM | U::COPY_DST);
        let entries: Vec<wgpu::BindGroupEntry> = [
            &self.header,
            &self.params,
            &self.occupancy,
            &self.network,
            &rays,
            &state,
            &dispatch,
            &status,
        ]
        .into_iter()
        .enumerate()
        .map(|(k, b)| wgpu::BindGroupEntry { binding: k as u32, resource: b.as_entire_binding() })
        .collect();
        let bind = self.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("render"),
            layout: &self.layout,
            entries: &entries,
        });
        Slot { rays, state, status, staging, dispatch, bind }
    }
}

/// Every pixel's ray of every camera, in order (rows top to bottom, pixels left to right).
pub(crate) fn rays_of(cameras: &[Camera]) -> Vec<Ray> {
    let mut rays = Vec::new();
    for c in cameras {
        let (w, h) = (c.intrinsics.width, c.intrinsics.height);
        rays.reserve(w as usize * h as usize);
        for j in 0..h {
            for i in 0..w {
                rays.push(c.pixel_ray(i, j));
            }
        }
    }
    rays
}

/// The RGB of [`rays_of`]'s rays cut into one image per camera.
pub(crate) fn split_views(rgb: &[f32], cameras: &[Camera]) -> Vec<Vec<f32>> {
    let mut out = Vec::with_capacity(cameras.len());
    let mut at = 0;
    for c in cameras {
        let n = c.intrinsics.width as usize * c.intrinsics.height as usize * 3;
        out.push(rgb[at..at + n].to_vec());
        at += n;
    }
    out
}

/// Map `range` of a staging buffer for reading once the device has finished with it.
pub(crate) async fn map(
    device: &wgpu::Device,
    errors: &DeviceErrors,
    buffer: &wgpu::Buffer,
    range: std::ops::Range<u64>,
) -> Result<wgpu::BufferView, GpuError> {
    let (tx, rx) = mpsc::channel();
    let slice = buffer.slice(range);
    slice.map_async(wgpu::MapMode::Read, move |r| {
        let _ = tx.send(r);
    });
    let polled = device.poll(wgpu::PollType::wait_indefinitely());
    // a lost device or an error outside the scopes explains a failed mapping best
    errors.check()?;
    polled.map_err(|e| GpuError::Readback(e.to_string()))?;
    rx.recv()
        .map_err(|_| GpuError::Readback("the mapping callback never ran".into()))?
        .map_err(|e| GpuError::Readback(e.to_string()))?;
    slice.get_mapped_range().map_err(|e| GpuError::Readback(e.to_string()))
}
