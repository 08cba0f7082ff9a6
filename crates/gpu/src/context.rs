//! Device setup, apart from any rendering: instance, adapter, device and queue; and the
//! choice between the GPU and the CPU that commands offer (`--backend gpu|cpu|auto`).

use crate::GpuError;
use std::sync::{Arc, Mutex};

/// A wgpu device ready for compute work.
///
/// Errors wgpu reports outside the error scopes this crate opens, and the loss of the
/// device, are recorded instead of panicking (wgpu's default handler panics);
/// [`GpuContext::device_lost`] and [`GpuContext::explain`] turn them into errors.
#[derive(Debug)]
pub struct GpuContext {
    // kept alive for the adapter and device made from it
    _instance: wgpu::Instance,
    adapter: wgpu::Adapter,
    device: wgpu::Device,
    queue: wgpu::Queue,
    errors: DeviceErrors,
}

/// What wgpu reported about a device outside the error scopes: its loss, and the first
/// error no scope caught. Shared by the context and what is made from it; checked after
/// every readback, so such an error fails the call instead of panicking or going unseen.
#[derive(Debug, Clone, Default)]
pub(crate) struct DeviceErrors {
    lost: Arc<Mutex<Option<String>>>,
    uncaptured: Arc<Mutex<Option<String>>>,
}

impl DeviceErrors {
    fn read(slot: &Mutex<Option<String>>) -> Option<String> {
        slot.lock().ok().and_then(|g| g.clone())
    }

    /// [`GpuError::DeviceLost`] once the device is lost; [`GpuError::Wgpu`] once an error
    /// escaped the scopes (the device's state is then unknown: every later check fails).
    pub(crate) fn check(&self) -> Result<(), GpuError> {
        if let Some(reason) = Self::read(&self.lost) {
            return Err(GpuError::DeviceLost(reason));
        }
        if let Some(reason) = Self::read(&self.uncaptured) {
            return Err(GpuError::Wgpu { stage: "device (outside an error scope)", reason });
        }
        Ok(())
    }
}

impl GpuContext {
    /// The default adapter (high performance preferred) with the best limits it offers.
    /// Instance options come from the environment (`WGPU_BACKEND`, `WGPU_ADAPTER_NAME`, ...).
    pub fn new() -> Result<Self, GpuError> {
        pollster::block_on(Self::new_async())
    }

    /// [`GpuContext::new`] as a future.
    pub async fn new_async() -> Result<Self, GpuError> {
        let desc = wgpu::InstanceDescriptor::new_without_display_handle_from_env();
        let instance = wgpu::Instance::new(desc);
        let adapter = instance
            .request_adapter(&wgpu::RequestAdapterOptions {
                power_preference: wgpu::PowerPreference::HighPerformance,
                force_fallback_adapter: false,
                compatible_surface: None,
                apply_limit_buckets: false,
            })
            .await
            .map_err(|e| GpuError::NoAdapter(e.to_string()))?;
        let info = adapter.get_info();
        let name = format!("{} ({:?}, {:?})", info.name, info.backend, info.device_type);
        let caps = adapter.get_downlevel_capabilities();
        if !caps.flags.contains(wgpu::DownlevelFlags::COMPUTE_SHADERS) {
            return Err(GpuError::NoAdapter(format!("{name} has no compute shaders")));
        }
        let (device, queue) = adapter
            .request_device(&wgpu::DeviceDescriptor {
                label: Some("assetfield-gpu"),
                required_features: wgpu::Features::empty(),
                // everything the adapter offers: large fields need large storage buffers
                required_limits: adapter.limits(),
                experimental_features: wgpu::ExperimentalFeatures::disabled(),
                memory_hints: wgpu::MemoryHints::Performance,
                trace: wgpu::Trace::Off,
            })
            .await
            .map_err(|e| GpuError::RequestDevice { adapter: name, reason: e.to_string() })?;
        let errors = DeviceErrors::default();
        let l = errors.lost.clone();
        device.set_device_lost_callback(move |reason, msg| {
            if let Ok(mut g) = l.lock() {
                *g = Some(format!("{reason:?}: {msg}"));
            }
        });
        let u = errors.uncaptured.clone();
        device.on_uncaptured_error(Arc::new(move |e: wgpu::Error| {
            if let Ok(mut g) = u.lock() {
                g.get_or_insert_with(|| e.to_string());
            }
        }));
        Ok(GpuContext { _instance: instance, adapter, device, queue, errors })
    }

    /// Why the device was lost, if it was (no more work can run on it).
    pub fn device_lost(&self) -> Option<String> {
        DeviceErrors::read(&self.errors.lost)
    }

    /// The first wgpu error reported outside an error scope, if any.
    pub fn uncaptured_error(&self) -> Option<String> {
        DeviceErrors::read(&self.errors.uncaptured)
    }

    pub(crate) fn errors(&self) -> &DeviceErrors {
        &self.errors
    }

    /// `e`, or [`GpuError::DeviceLost`] when the device was lost meanwhile (a lost device
    /// makes later work fail with less telling errors, such as a failed readback).
    pub fn explain(&self, e: GpuError) -> GpuError {
        match (self.device_lost(), e) {
            (_, e @ GpuError::DeviceLost(_)) => e,
            (Some(reason), e) => GpuError::DeviceLost(format!("{reason} (then: {e})")),
            (None, e) => e,
        }
    }

    /// Name, backend, device type and driver of the adapter in use.
    pub fn adapter_info(&self) -> wgpu::AdapterInfo {
        self.adapter.get_info()
    }

    /// One line describing the adapter, for logs.
    pub fn describe(&self) -> String {
        let i = self.adapter_info();
        format!(
            "{} ({:?}, {:?}, driver {} {})",
            i.name, i.backend, i.device_type, i.driver, i.driver_info
        )
    }

    /// The device's limits (as requested: the adapter's).
    pub fn limits(&self) -> wgpu::Limits {
        self.device.limits()
    }

    pub fn device(&self) -> &wgpu::Device {
        &self.device
    }

    pub fn queue(&self) -> &wgpu::Queue {
        &self.queue
    }
}

/// A compute pipeline with one bind group layout and no immediates (the shape every pass of
/// this crate uses).
pub(crate) fn compute_pipeline(
    device: &wgpu::Device,
    label: &str,
    layout: &wgpu::BindGroupLayout,
    module: &wgpu::ShaderModule,
    entry: &str,
) -> wgpu::ComputePipeline {
    let pl = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some(label),
        bind_group_layouts: &[Some(layout)],
        immediate_size: 0,
    });
    device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some(label),
        layout: Some(&pl),
        module,
        entry_point: Some(entry),
        compilation_options: Default::default(),
        cache: None,
    })
}

/// Where a command should render, as the user asked (`--backend gpu|cpu|auto`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum BackendChoice {
    /// The GPU; no adapter is an error.
    Gpu,
    /// The CPU reference renderer; no device is looked for.
    Cpu,
    /// The GPU when a hardware adapter exists, else the CPU (with a note saying so; a
    /// software adapter such as llvmpipe counts as none).
    #[default]
    Auto,
}

/// The device [`select_backend`] found.
#[derive(Debug)]
pub enum Backend {
    Gpu(GpuContext),
    /// The CPU; `fallback` says why the GPU was not used when it was asked for by `Auto`
    /// (one line, for stderr).
    Cpu {
        fallback: Option<String>,
    },
}

impl Backend {
    /// `"gpu"` or `"cpu"`.
    pub fn name(&self) -> &'static str {
        match self {
            Backend::Gpu(_) => "gpu",
            Backend::Cpu { .. } => "cpu",
        }
    }
}

/// Look for a device as `choice` asks: `Gpu` fails with the reason when there is no usable
/// adapter ([`GpuError::NoAdapter`], [`GpuError::RequestDevice`]); `Auto` then settles for
/// the CPU with a one-line note; `Cpu` looks for nothing.
pub fn select_backend(choice: BackendChoice) -> Result<Backend, GpuError> {
    match choice {
        BackendChoice::Cpu => Ok(Backend::Cpu { fallback: None }),
        BackendChoice::Gpu => GpuContext::new().map(Backend::Gpu),
        BackendChoice::Auto => match GpuContext::new() {
            // a software rasteriser (Mesa's llvmpipe) is an adapter but no GPU: the CPU
            // reference renderer is about ten times faster than it on the same cores
            Ok(c) if c.adapter_info().device_type == wgpu::DeviceType::Cpu => Ok(Backend::Cpu {
                fallback: Some(format!(
                    "the only wgpu adapter is a software one ({}); using the CPU renderer, which is faster on the same cores (--backend gpu uses the adapter anyway)",
                    c.describe()
                )),
            }),
            Ok(c) => Ok(Backend::Gpu(c)),
            Err(e) => Ok(Backend::Cpu { fallback: Some(fallback_note(&e)) }),
        },
    }
}

/// One line saying that `e` sent the work to the CPU.
pub fn fallback_note(e: &GpuError) -> String {
    let what = match e {
        GpuError::NoAdapter(reason) => format!("no wgpu adapter found ({reason})"),
        e => format!("the GPU could not be used: {e}"),
    };
    format!(
        "{what}; using the CPU instead (--backend cpu skips the search, --backend gpu makes it an error)"
    )
}

impl GpuError {
    /// Whether the CPU renderer could do what failed here: every error of the device or the
    /// driver (no adapter, limits, loops cut short, lost device, readback), not a bad input.
    pub fn cpu_can_do_it(&self) -> bool {
        !matches!(self, GpuError::Input(_))
    }
}
