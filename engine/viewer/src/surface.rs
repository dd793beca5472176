//! The window's swap chain: surface configuration, resizing, loss and the depth buffer that
//! goes with it.

use std::sync::Arc;

use winit::window::Window;

use super::ViewerError;
use citywalk_runtime::gpu::GpuContext;
use citywalk_runtime::render::DepthTarget;

/// A window, its surface and the GPU that presents to it.
#[derive(Debug)]
pub struct WindowSurface {
    pub window: Arc<Window>,
    pub gpu: GpuContext,
    surface: wgpu::Surface<'static>,
    pub config: wgpu::SurfaceConfiguration,
    depth: DepthTarget,
    /// Whether the surface textures can be copied from (for `--screenshot`).
    pub copyable: bool,
}

/// What acquiring a frame gave.
#[derive(Debug)]
pub enum Acquired {
    Frame(wgpu::SurfaceTexture),
    /// Nothing to draw this time (minimised, occluded, timed out, surface rebuilt).
    Skip,
}

impl WindowSurface {
    /// Makes a surface for `window`, a GPU context able to present to it, and configures it
    /// with vsync (Fifo). `want_copy` asks for `COPY_SRC` surface textures where supported.
    pub fn new(window: Arc<Window>, want_copy: bool) -> Result<WindowSurface, ViewerError> {
        let instance = GpuContext::instance_from_env();
        let surface = instance.create_surface(window.clone()).map_err(|e| {
            // Every backend failing here means no driver is installed at all.
            ViewerError::Surface(format!(
                "no GPU adapter or backend can make a surface for this window ({e}); on \
                     Debian/Ubuntu install mesa-vulkan-drivers and libvulkan1"
            ))
        })?;
        let gpu = GpuContext::for_surface(instance, &surface)?;
        let size = window.inner_size();
        let caps = surface.get_capabilities(&gpu.adapter);
        let format = caps
            .formats
            .iter()
            .copied()
            .find(|f| f.is_srgb() && super::screenshot::is_rgba8_or_bgra8(*f))
            .or_else(|| caps.formats.first().copied())
            .ok_or_else(|| {
                ViewerError::Surface(format!(
                    "adapter {} offers no format for this surface",
                    gpu.adapter_summary()
                ))
            })?;
        let copyable = want_copy && caps.usages.contains(wgpu::TextureUsages::COPY_SRC);
        let usage = if copyable {
            wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC
        } else {
            wgpu::TextureUsages::RENDER_ATTACHMENT
        };
        let config = wgpu::SurfaceConfiguration {
            usage,
            format,
            color_space: wgpu::SurfaceColorSpace::Auto,
            width: size.width.max(1),
            height: size.height.max(1),
            present_mode: wgpu::PresentMode::AutoVsync,
            desired_maximum_frame_latency: 2,
            alpha_mode: caps
                .alpha_modes
                .first()
                .copied()
                .unwrap_or(wgpu::CompositeAlphaMode::Auto),
            view_formats: vec![],
        };
        surface.configure(&gpu.device, &config);
        let depth = DepthTarget::new(&gpu, config.width, config.height);
        tracing::info!(
            adapter = %gpu.adapter_summary(),
            ?format,
            width = config.width,
            height = config.height,
            copyable,
            "window surface"
        );
        Ok(WindowSurface {
            window,
            gpu,
            surface,
            config,
            depth,
            copyable,
        })
    }

    /// The depth buffer (`Depth32Float`, the surface's size).
    pub fn depth(&self) -> &DepthTarget {
        &self.depth
    }

    /// Follows a window resize; a zero size (minimised) keeps the old configuration.
    pub fn resize(&mut self, width: u32, height: u32) {
        if width == 0 || height == 0 {
            return;
        }
        self.config.width = width;
        self.config.height = height;
        self.surface.configure(&self.gpu.device, &self.config);
        self.depth = DepthTarget::new(&self.gpu, width, height);
    }

    /// The next frame to draw into, rebuilding the surface when it is outdated or lost.
    pub fn acquire(&mut self) -> Result<Acquired, ViewerError> {
        let size = self.window.inner_size();
        if size.width == 0 || size.height == 0 {
            return Ok(Acquired::Skip);
        }
        match self.surface.get_current_texture() {
            wgpu::CurrentSurfaceTexture::Success(frame) => Ok(Acquired::Frame(frame)),
            wgpu::CurrentSurfaceTexture::Suboptimal(frame) => {
                if (size.width, size.height) == (self.config.width, self.config.height) {
                    return Ok(Acquired::Frame(frame));
                }
                // The window changed size before its resize event came: reconfigure for the
                // next frame. The surface must not be configured while one of its textures is
                // held (a wgpu validation error): this one is given back first.
                drop(frame);
                self.resize(size.width, size.height);
                Ok(Acquired::Skip)
            }
            wgpu::CurrentSurfaceTexture::Timeout | wgpu::CurrentSurfaceTexture::Occluded => {
                Ok(Acquired::Skip)
            }
            wgpu::CurrentSurfaceTexture::Outdated => {
                self.resize(size.width, size.height);
                Ok(Acquired::Skip)
            }
            wgpu::CurrentSurfaceTexture::Lost => {
                tracing::warn!("surface lost; recreating it");
                self.surface = self
                    .gpu
                    .instance
                    .create_surface(self.window.clone())
                    .map_err(|e| ViewerError::Surface(e.to_string()))?;
                self.resize(size.width, size.height);
                Ok(Acquired::Skip)
            }
            wgpu::CurrentSurfaceTexture::Validation => Err(ViewerError::Surface(
                "validation error while acquiring the next frame".into(),
            )),
        }
    }
}
