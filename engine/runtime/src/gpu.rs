//! The GPU context: instance, adapter, device and queue, chosen the same way for the headless
//! renderer, the tests and the windowed viewer.
//!
//! Backends come from the environment (`WGPU_BACKEND=vulkan|gl|...`); a hardware adapter is
//! preferred, else the software one (lavapipe / llvmpipe). Optional features are requested as
//! `adapter.features() & wanted` and every user keeps a path for their absence.

use std::sync::{Arc, Mutex};

use thiserror::Error;

/// Why no GPU context could be made.
#[derive(Debug, Error)]
pub enum GpuError {
    #[error(
        "no GPU adapter found (backends: {backends:?}); on Debian/Ubuntu install a software \
         Vulkan driver with `apt-get install mesa-vulkan-drivers libvulkan1` (and `libegl1 \
         libegl-mesa0 libgl1-mesa-dri` for WGPU_BACKEND=gl)"
    )]
    NoAdapter { backends: wgpu::Backends },
    #[error("no GPU adapter can present to this window's surface (adapters seen: {seen})")]
    NoSurfaceAdapter { seen: String },
    #[error("requesting a device from adapter {adapter:?}: {source}")]
    RequestDevice {
        adapter: String,
        #[source]
        source: wgpu::RequestDeviceError,
    },
}

/// The device is lost: a driver reset, a removed GPU, memory pressure, or `Device::destroy`.
/// Every later call on it fails; the reason is wgpu's.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
#[error("the GPU device was lost ({reason})")]
pub struct DeviceLost {
    /// Why, as wgpu reported it: `destroyed: ...` for `Device::destroy`.
    pub reason: String,
}

/// The optional features citywalk uses when the adapter has them. `MAPPABLE_PRIMARY_BUFFERS`
/// only on a software adapter, whose GPU memory is process memory: the scene's arrays are
/// written straight into their buffers there ([`crate::upload`]).
pub const WANTED_FEATURES: wgpu::Features = wgpu::Features::TIMESTAMP_QUERY
    .union(wgpu::Features::INDIRECT_FIRST_INSTANCE)
    .union(wgpu::Features::MULTI_DRAW_INDIRECT_COUNT)
    .union(wgpu::Features::MAPPABLE_PRIMARY_BUFFERS);

/// Everything needed to talk to one GPU.
#[derive(Debug)]
pub struct GpuContext {
    pub instance: wgpu::Instance,
    pub adapter: wgpu::Adapter,
    pub device: wgpu::Device,
    pub queue: wgpu::Queue,
    /// Name, backend, device type and driver of the adapter in use.
    pub adapter_info: wgpu::AdapterInfo,
    /// The optional features actually enabled: `adapter.features() & WANTED_FEATURES` (narrowed
    /// further by [`GpuContext::headless_with_features`]).
    pub features: wgpu::Features,
    /// Why the device was lost, once it is ([`GpuContext::lost`]).
    lost: Arc<Mutex<Option<DeviceLost>>>,
}

/// The instance descriptor from the environment, without wgpu's validation of indirect calls
/// unless `WGPU_VALIDATION_INDIRECT_CALL` asks for it. That validation (on by default in release
/// builds) runs a compute pass over every indirect command before each indirect draw, up to the
/// draw's maximum count; citywalk's indirect commands are all written by its own cull passes from
/// records whose index ranges the package reader checks, and the tree cull's draws are bounded
/// by the scene's draw ids (2.35 M at 1M buildings). Measured on lavapipe, generated 1M city,
/// 640×360: with it, brute force spent 24–39 ms of CPU per frame and street frames of the LOD
/// frame stalled for 2–4 s in some runs (LLVM compiling compute shaders); without it, 1.5–2 ms
/// and no stall.
fn instance_descriptor() -> wgpu::InstanceDescriptor {
    let mut descriptor = wgpu::InstanceDescriptor::new_without_display_handle_from_env();
    if std::env::var_os("WGPU_VALIDATION_INDIRECT_CALL").is_none() {
        descriptor
            .flags
            .remove(wgpu::InstanceFlags::VALIDATION_INDIRECT_CALL);
    }
    descriptor
}

impl GpuContext {
    /// An instance with backends and flags from the environment (`WGPU_BACKEND`, ...), without a
    /// display handle. The viewer creates its surface from this instance and then calls
    /// [`GpuContext::for_surface`].
    pub fn instance_from_env() -> wgpu::Instance {
        wgpu::Instance::new(instance_descriptor())
    }

    /// A context with no surface, for offscreen rendering, the oracle, tests and benchmarks.
    pub fn headless() -> Result<GpuContext, GpuError> {
        pollster::block_on(Self::headless_async())
    }

    /// Async form of [`GpuContext::headless`]. Without `WGPU_BACKEND`, the primary backends
    /// (Vulkan, Metal, DX12) are tried first and GL only when they offer no adapter, which also
    /// keeps EGL's start-up noise out of the common case.
    pub async fn headless_async() -> Result<GpuContext, GpuError> {
        Self::headless_with_features_async(WANTED_FEATURES).await
    }

    /// As [`GpuContext::headless`], enabling only `adapter.features() & wanted` (a subset of
    /// [`WANTED_FEATURES`]): exercises the paths taken when an adapter lacks a feature, e.g.
    /// `WANTED_FEATURES - Features::TIMESTAMP_QUERY`.
    pub fn headless_with_features(wanted: wgpu::Features) -> Result<GpuContext, GpuError> {
        pollster::block_on(Self::headless_with_features_async(wanted))
    }

    /// A headless context whose device has `limits`, each no better than the adapter's: how a
    /// scene fares on a smaller GPU (the limits' errors are reached without one).
    pub fn headless_with_limits(limits: wgpu::Limits) -> Result<GpuContext, GpuError> {
        pollster::block_on(Self::headless_requesting(WANTED_FEATURES, Some(limits)))
    }

    /// Async form of [`GpuContext::headless_with_features`].
    pub async fn headless_with_features_async(
        wanted: wgpu::Features,
    ) -> Result<GpuContext, GpuError> {
        Self::headless_requesting(wanted, None).await
    }

    /// The headless context of `wanted` features and `limits` (the adapter's when `None`).
    async fn headless_requesting(
        wanted: wgpu::Features,
        limits: Option<wgpu::Limits>,
    ) -> Result<GpuContext, GpuError> {
        let attempts = match wgpu::Backends::from_env() {
            Some(backends) => vec![backends],
            None => vec![wgpu::Backends::PRIMARY, wgpu::Backends::SECONDARY],
        };
        for backends in &attempts {
            let mut descriptor = instance_descriptor();
            descriptor.backends = *backends;
            let instance = wgpu::Instance::new(descriptor);
            let adapters = instance.enumerate_adapters(*backends).await;
            if let Some(adapter) = adapters
                .into_iter()
                .max_by_key(|a| adapter_rank(&a.get_info()))
            {
                return Self::from_adapter(instance, adapter, wanted, limits).await;
            }
        }
        Err(GpuError::NoAdapter {
            backends: attempts
                .into_iter()
                .fold(wgpu::Backends::empty(), |a, b| a | b),
        })
    }

    /// A context whose adapter can present to `surface` (created from `instance`, which must
    /// come from [`GpuContext::instance_from_env`] or an equivalent instance).
    pub fn for_surface(
        instance: wgpu::Instance,
        surface: &wgpu::Surface<'_>,
    ) -> Result<GpuContext, GpuError> {
        pollster::block_on(async {
            let adapters = instance.enumerate_adapters(wgpu::Backends::all()).await;
            let seen = adapters
                .iter()
                .map(|a| {
                    let i = a.get_info();
                    format!("{} ({:?})", i.name, i.backend)
                })
                .collect::<Vec<_>>()
                .join(", ");
            let adapter = adapters
                .into_iter()
                .filter(|a| a.is_surface_supported(surface))
                .max_by_key(|a| adapter_rank(&a.get_info()))
                .ok_or(GpuError::NoSurfaceAdapter { seen })?;
            Self::from_adapter(instance, adapter, WANTED_FEATURES, None).await
        })
    }

    async fn from_adapter(
        instance: wgpu::Instance,
        adapter: wgpu::Adapter,
        wanted: wgpu::Features,
        limits: Option<wgpu::Limits>,
    ) -> Result<GpuContext, GpuError> {
        let adapter_info = adapter.get_info();
        let mut features = adapter.features() & WANTED_FEATURES & wanted;
        if adapter_info.device_type != wgpu::DeviceType::Cpu {
            // On a GPU of its own, mappable vertex and index buffers would live in slow memory.
            features.remove(wgpu::Features::MAPPABLE_PRIMARY_BUFFERS);
        }
        let limits = match limits {
            Some(limits) => limits.or_worse_values_from(&adapter.limits()),
            None => adapter.limits(),
        };
        let (device, queue) = adapter
            .request_device(&wgpu::DeviceDescriptor {
                label: Some("citywalk device"),
                required_features: features,
                required_limits: limits,
                experimental_features: wgpu::ExperimentalFeatures::disabled(),
                memory_hints: wgpu::MemoryHints::Performance,
                trace: wgpu::Trace::Off,
            })
            .await
            .map_err(|source| GpuError::RequestDevice {
                adapter: adapter_info.name.clone(),
                source,
            })?;
        tracing::info!(
            adapter = %adapter_info.name,
            backend = ?adapter_info.backend,
            device_type = ?adapter_info.device_type,
            driver = %adapter_info.driver_info,
            features = ?features,
            "GPU adapter"
        );
        let lost = watch_for_loss(&device);
        Ok(GpuContext {
            instance,
            adapter,
            device,
            queue,
            adapter_info,
            features,
            lost,
        })
    }

    /// One line naming the adapter: `"llvmpipe (LLVM 15.0.6, 256 bits) (Vulkan, Cpu)"`.
    pub fn adapter_summary(&self) -> String {
        format!(
            "{} ({:?}, {:?})",
            self.adapter_info.name, self.adapter_info.backend, self.adapter_info.device_type
        )
    }

    /// Whether the adapter is a software rasteriser (lavapipe, llvmpipe, WARP).
    pub fn is_software(&self) -> bool {
        self.adapter_info.device_type == wgpu::DeviceType::Cpu
    }

    /// Whether `feature` (one of [`WANTED_FEATURES`]) is enabled on this device.
    pub fn has(&self, feature: wgpu::Features) -> bool {
        self.features.contains(feature)
    }

    /// Why the device was lost (a driver reset, a removed GPU, `destroy`), or `None` while it
    /// works, as far as wgpu has reported. Once lost, every later call on it fails.
    pub fn lost(&self) -> Option<DeviceLost> {
        self.lost
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
            .clone()
    }

    /// `Err` naming the loss once the device is lost: a frame loop checks this before each
    /// frame and stops with the reason instead of drawing. Polls the device first, without
    /// waiting: wgpu reports a device destroyed by `Device::destroy` only from a poll that finds
    /// its queue empty, and calls made before that report fail silently.
    pub fn alive(&self) -> Result<(), DeviceLost> {
        // A failed poll means the loss itself, which the callback records.
        let _ = self.device.poll(wgpu::PollType::Poll);
        self.lost().map_or(Ok(()), Err)
    }

    /// Memory the device's allocator holds for buffers and textures (MiB; `None` where the
    /// backend keeps no report). On a software adapter it is process memory.
    pub fn allocated_mib(&self) -> Option<f64> {
        let report = self.device.generate_allocator_report()?;
        Some(report.total_allocated_bytes as f64 / (1024.0 * 1024.0))
    }

    /// Blocks until all submitted work has finished.
    pub fn wait_idle(&self) {
        // An error here means the device was lost; later calls report it.
        if let Err(e) = self.device.poll(wgpu::PollType::wait_indefinitely()) {
            tracing::warn!("device poll failed: {e}");
        }
    }
}

/// Records the device's loss for [`GpuContext::lost`], and keeps the errors of calls made on a
/// lost device (which wgpu reports as uncaptured errors) from panicking: those are expected
/// and the loss is reported once. Any other uncaptured error is a bug and panics, as wgpu's
/// default handler does.
fn watch_for_loss(device: &wgpu::Device) -> Arc<Mutex<Option<DeviceLost>>> {
    let lost = Arc::new(Mutex::new(None::<DeviceLost>));
    let record = Arc::clone(&lost);
    device.set_device_lost_callback(move |reason, message| {
        let reason = match reason {
            wgpu::DeviceLostReason::Destroyed if message.is_empty() => "destroyed".to_string(),
            wgpu::DeviceLostReason::Destroyed => format!("destroyed: {message}"),
            wgpu::DeviceLostReason::Unknown => message,
        };
        let lost = DeviceLost { reason };
        tracing::error!("{lost}");
        *record
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner) = Some(lost);
    });
    let seen = Arc::clone(&lost);
    device.on_uncaptured_error(Arc::new(move |error: wgpu::Error| {
        let is_lost = seen
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
            .is_some();
        if is_lost {
            tracing::debug!("after the device was lost: {error}");
        } else {
            panic!("wgpu error: {error}");
        }
    }));
    lost
}

/// Preference order of adapters: hardware first, software last; Vulkan before GL among equals.
fn adapter_rank(info: &wgpu::AdapterInfo) -> (u8, u8) {
    let device = match info.device_type {
        wgpu::DeviceType::DiscreteGpu => 4,
        wgpu::DeviceType::IntegratedGpu => 3,
        wgpu::DeviceType::VirtualGpu => 2,
        wgpu::DeviceType::Other => 1,
        wgpu::DeviceType::Cpu => 0,
    };
    let backend = match info.backend {
        wgpu::Backend::Vulkan | wgpu::Backend::Metal | wgpu::Backend::Dx12 => 2,
        wgpu::Backend::Gl => 1,
        _ => 0,
    };
    (device, backend)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A device that is lost says why, and the calls made on it afterwards (which fail) do not
    /// panic.
    #[test]
    fn a_lost_device_says_why_and_later_calls_do_not_panic() {
        let Ok(gpu) = GpuContext::headless() else {
            assert!(std::env::var_os("CI").is_none(), "no adapter in CI");
            return;
        };
        assert_eq!(gpu.lost(), None);
        assert_eq!(gpu.alive(), Ok(()));
        gpu.device.destroy();
        // `alive` polls: the loss is seen without waiting for the queue.
        let why = gpu.alive().expect_err("the loss is recorded").to_string();
        assert!(
            why.contains("GPU device was lost") && why.contains("destroyed"),
            "{why}"
        );
        // Calls on the lost device fail without panicking.
        let buffer = gpu.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("after the loss"),
            size: 64,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        gpu.queue.write_buffer(&buffer, 0, &[0u8; 64]);
        gpu.queue.submit([]);
        gpu.wait_idle();
    }
}
