//! Draws the cluster meshes with their baked textures (Chang et al. 2008 §7): the runtime half
//! of `preprocess --cluster-textures`.
//!
//! The package holds, per texture page, six PNG views (the walls' side view and five roof
//! views). The GPU holds a `texture_2d_array` of `layers` page views under a memory budget
//! (`--texture-budget-mib`); which views are resident follows what is drawn: after each frame
//! the drawn cluster meshes name their pages, and the side view and this frame's roof view
//! (the one closest to the look vector, Chang §7) of each are wanted; missing ones are decoded
//! on a worker thread and uploaded at the start of a later frame, into a free layer or the
//! least recently drawn one ([`residency`]). Until its view is resident a cluster is drawn in
//! its flat colours, so a frame never waits for a texture (the benchmark and `render` may,
//! [`ClusterTexturing::settle`]). Per frame the CPU does O(drawn clusters) work.
//!
//! The scene pass's `fs_textured` entry point reads the tables of [`TextureTables`]: which wall
//! or roof of which cluster a fragment lies on, from the flat vertex index of its triangle.

pub mod residency;

use std::collections::BTreeMap;
use std::sync::Arc;
use std::sync::Mutex;
use std::sync::mpsc::{Receiver, Sender, channel};

use citywalk_scenes::cluster_texture::atlas::AtlasView;
use citywalk_scenes::cluster_texture::baked::{ClusterTextures, TextureImage};
use citywalk_scenes::cluster_texture::roof_views::RoofView;
use citywalk_shaders::constants::{
    CLUSTER_SHADING_BINS, CLUSTER_SHADING_FLAT, CLUSTER_SHADING_TEXTURED, NO_TEXTURE_PAGE,
};
use citywalk_shaders::{ClusterTexturingParams, TexturedCluster, TexturedWall};
use glam::Vec3;

use crate::camera::Camera;
use crate::gpu::GpuContext;
use crate::upload::{UploadError, array_buffer};
pub use citywalk_scenes::cluster_texture::tables::{MeshArrays, TextureTables};
use residency::{PageView, Residency};

/// The default GPU memory for resident page views.
pub const DEFAULT_BUDGET_MIB: u64 = 256;

/// Decodes outstanding at once.
const MAX_LOADS_IN_FLIGHT: usize = 8;

/// Format of the page views: the bake's (sRGB albedo; the sampler returns linear).
const FORMAT: wgpu::TextureFormat = crate::texture_bake::FORMAT;

/// What texturing the scene got at load.
#[derive(Debug, Clone, PartialEq)]
pub struct TexturingSummary {
    pub textured_clusters: usize,
    /// Placed clusters the scene's meshes do not match: (node, reason), drawn flat.
    pub rejected: Vec<(u32, String)>,
    /// Page views the GPU holds at once, and their side.
    pub layers: u32,
    pub page_px: u32,
}

/// How the scene pass shades the cluster meshes of a textured scene.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum ClusterShading {
    /// One colour per wall and roof, as without textures.
    Flat,
    /// With their baked textures, where resident.
    #[default]
    Textured,
    /// Each textured cluster in the colour of its texture bin, untextured ones dark grey.
    Bins,
}

impl ClusterShading {
    fn constant(self) -> u32 {
        match self {
            ClusterShading::Flat => CLUSTER_SHADING_FLAT,
            ClusterShading::Textured => CLUSTER_SHADING_TEXTURED,
            ClusterShading::Bins => CLUSTER_SHADING_BINS,
        }
    }
}

/// Where the page views' residency stands ([`ClusterTexturing::residency`]).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TextureResidency {
    pub shading: ClusterShading,
    /// Page views resident, of `layers`, and their texels' size.
    pub resident: usize,
    pub layers: usize,
    pub resident_mib: f64,
    /// Loads in flight.
    pub loading: usize,
    /// Page views uploaded and evicted, in all.
    pub uploaded: u64,
    pub evictions: u64,
    /// Page views the last frame wanted that found no layer (every layer needed by it).
    pub starved: usize,
    /// Page views that failed to decode (drawn flat), with the reason.
    pub broken: Vec<(PageView, String)>,
}

/// The cluster textures on the GPU and their residency.
#[derive(Debug)]
pub struct ClusterTexturing {
    group: wgpu::BindGroup,
    params_buffer: wgpu::Buffer,
    layers_buffer: wgpu::Buffer,
    texture: wgpu::Texture,
    base_params: ClusterTexturingParams,
    /// Per tree node, its page (`NO_TEXTURE_PAGE`: untextured).
    node_pages: Vec<u32>,
    pub summary: TexturingSummary,
    state: Mutex<State>,
}

/// A decoded page view, or why it could not be.
type Decoded = (PageView, Result<TextureImage, String>);

#[derive(Debug)]
struct State {
    residency: Residency,
    frame: u64,
    roof_view: RoofView,
    shading: ClusterShading,
    requests: Sender<PageView>,
    decoded: Receiver<Decoded>,
    /// Page views that failed to decode: never asked for again, drawn flat.
    broken: BTreeMap<PageView, String>,
    uploaded: u64,
}

/// The right and down axes of `view`'s image (unit, world space): what `fs_textured`'s
/// `roof_texel` projects a roof point on (`ClusterTexturingParams::roof_right`, `roof_down`),
/// the axes [`RoofView::frame`] gives the baker.
pub fn roof_image_axes(view: RoofView) -> [Vec3; 2] {
    let [right, down, _] = view.frame(Vec3::ZERO, Vec3::ONE).axes;
    [right, down]
}

/// The bind-group layout of group 1 of the textured scene pass (`citywalk_shaders::SCENE_WGSL`).
pub fn bind_group_layout(device: &wgpu::Device) -> wgpu::BindGroupLayout {
    let fragment = wgpu::ShaderStages::FRAGMENT;
    let storage = |binding| wgpu::BindGroupLayoutEntry {
        binding,
        visibility: fragment,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Storage { read_only: true },
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    };
    device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("cluster texturing"),
        entries: &[
            wgpu::BindGroupLayoutEntry {
                binding: 0,
                visibility: fragment,
                ty: wgpu::BindingType::Buffer {
                    ty: wgpu::BufferBindingType::Uniform,
                    has_dynamic_offset: false,
                    min_binding_size: wgpu::BufferSize::new(
                        size_of::<ClusterTexturingParams>() as u64
                    ),
                },
                count: None,
            },
            storage(1),
            storage(2),
            storage(3),
            wgpu::BindGroupLayoutEntry {
                binding: 4,
                visibility: fragment,
                ty: wgpu::BindingType::Texture {
                    sample_type: wgpu::TextureSampleType::Float { filterable: true },
                    view_dimension: wgpu::TextureViewDimension::D2Array,
                    multisampled: false,
                },
                count: None,
            },
            wgpu::BindGroupLayoutEntry {
                binding: 5,
                visibility: fragment,
                ty: wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering),
                count: None,
            },
        ],
    })
}

/// Why a scene's cluster textures cannot be drawn.
#[derive(Debug, thiserror::Error)]
pub enum TexturingError {
    #[error(transparent)]
    Upload(#[from] UploadError),
    #[error(
        "a page view of {page_px}×{page_px} texels ({mib:.1} MiB) does not fit the texture budget of {budget_mib} MiB"
    )]
    OverBudget {
        page_px: u32,
        mib: f64,
        budget_mib: u64,
    },
    #[error("pages of {page_px} texels exceed the adapter's largest texture ({max_px})")]
    PageTooLarge { page_px: u32, max_px: u32 },
}

impl ClusterTexturing {
    /// Uploads the tables of `textures` over the scene's `meshes` and a texture array of as
    /// many page views as `budget_mib` holds (no more than two per page, nor than the
    /// adapter's array layers); starts the decode worker. Nothing is resident yet.
    pub fn new(
        gpu: &GpuContext,
        textures: Arc<ClusterTextures>,
        meshes: MeshArrays<'_>,
        budget_mib: u64,
    ) -> Result<ClusterTexturing, TexturingError> {
        let layout = &textures.layout;
        let page_px = layout.page_px;
        let limits = gpu.device.limits();
        if page_px > limits.max_texture_dimension_2d {
            return Err(TexturingError::PageTooLarge {
                page_px,
                max_px: limits.max_texture_dimension_2d,
            });
        }
        let view_bytes = u64::from(page_px).pow(2) * 4;
        let fit = budget_mib.saturating_mul(1 << 20) / view_bytes.max(1);
        if fit == 0 {
            return Err(TexturingError::OverBudget {
                page_px,
                mib: view_bytes as f64 / f64::from(1 << 20),
                budget_mib,
            });
        }
        let views = u64::from(layout.page_count) * AtlasView::ALL.len() as u64;
        // A frame wants at most two views of a page (its side view and the frame's roof
        // view): more layers would only keep old roof views, so a small scene does not take
        // the whole budget.
        let layers = fit
            .min(2 * u64::from(layout.page_count).max(1))
            .min(u64::from(limits.max_texture_array_layers)) as u32;
        let tables = TextureTables::build(layout, meshes);
        let node_pages = tables.clusters.iter().map(|c| c.page).collect();
        let summary = TexturingSummary {
            textured_clusters: tables.textured(),
            rejected: tables.rejected.clone(),
            layers,
            page_px,
        };
        let device = &gpu.device;
        let storage = wgpu::BufferUsages::STORAGE;
        let keep = &|_: &[u8]| {};
        let clusters = array_buffer::<TexturedCluster>(
            gpu,
            "textured clusters",
            &tables.clusters,
            storage,
            keep,
        )?;
        let walls =
            array_buffer::<TexturedWall>(gpu, "textured walls", &tables.walls, storage, keep)?;
        let layers_buffer = array_buffer(
            gpu,
            "page view layers",
            &vec![NO_TEXTURE_PAGE; views.max(1) as usize],
            storage | wgpu::BufferUsages::COPY_DST,
            keep,
        )?;
        let params_buffer = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("cluster texturing params"),
            size: size_of::<ClusterTexturingParams>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let texture = device.create_texture(&wgpu::TextureDescriptor {
            label: Some("cluster texture pages"),
            size: wgpu::Extent3d {
                width: page_px,
                height: page_px,
                depth_or_array_layers: layers,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: FORMAT,
            usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
            view_formats: &[],
        });
        let view = texture.create_view(&wgpu::TextureViewDescriptor {
            dimension: Some(wgpu::TextureViewDimension::D2Array),
            ..Default::default()
        });
        let sampler = device.create_sampler(&wgpu::SamplerDescriptor {
            label: Some("cluster texture pages"),
            mag_filter: wgpu::FilterMode::Linear,
            min_filter: wgpu::FilterMode::Linear,
            ..Default::default()
        });
        let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("cluster texturing"),
            layout: &bind_group_layout(device),
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: params_buffer.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: clusters.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: walls.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 3,
                    resource: layers_buffer.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 4,
                    resource: wgpu::BindingResource::TextureView(&view),
                },
                wgpu::BindGroupEntry {
                    binding: 5,
                    resource: wgpu::BindingResource::Sampler(&sampler),
                },
            ],
        });
        let (requests, decoded) = spawn_decoder(textures);
        Ok(ClusterTexturing {
            group,
            params_buffer,
            layers_buffer,
            texture,
            base_params: ClusterTexturingParams {
                page_px: page_px as f32,
                building_count: meshes.building_count,
                ..ClusterTexturingParams::default()
            },
            node_pages,
            summary,
            state: Mutex::new(State {
                residency: Residency::new(layers, MAX_LOADS_IN_FLIGHT),
                frame: 0,
                roof_view: RoofView::Top,
                shading: ClusterShading::Textured,
                requests,
                decoded,
                broken: BTreeMap::new(),
                uploaded: 0,
            }),
        })
    }

    /// Group 1 of the textured scene pass.
    pub fn bind_group(&self) -> &wgpu::BindGroup {
        &self.group
    }

    /// How the next frames shade cluster meshes (textured by default).
    pub fn set_shading(&self, shading: ClusterShading) {
        self.state().shading = shading;
    }

    pub fn shading(&self) -> ClusterShading {
        self.state().shading
    }

    fn state(&self) -> std::sync::MutexGuard<'_, State> {
        // A panic while the lock was held left bookkeeping, not memory, inconsistent: the
        // worst is a page drawn flat.
        self.state.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Before a frame from `camera` is recorded: uploads the page views decoded since the last
    /// frame and picks the frame's roof view. Never waits.
    pub fn begin_frame(&self, gpu: &GpuContext, camera: &Camera) {
        let mut state = self.state();
        while let Ok((view, image)) = state.decoded.try_recv() {
            self.finish_load(gpu, &mut state, view, image);
        }
        state.roof_view = RoofView::closest_to(camera.forward());
        let [right, down] = roof_image_axes(state.roof_view);
        let params = ClusterTexturingParams {
            roof_right: right.extend(0.0).to_array(),
            roof_down: down.extend(0.0).to_array(),
            roof_view: AtlasView::Roof(state.roof_view).index() as u32,
            shading: state.shading.constant(),
            ..self.base_params
        };
        gpu.queue
            .write_buffer(&self.params_buffer, 0, bytemuck::bytes_of(&params));
    }

    /// After a frame: the draw ids it drew (buildings and cluster meshes of the LOD scene)
    /// name the page views the next frames want; the missing ones start loading.
    pub fn note_drawn(&self, gpu: &GpuContext, draw_ids: &[u32]) {
        let mut state = self.state();
        if state.shading != ClusterShading::Textured {
            return;
        }
        state.frame += 1;
        let roof = AtlasView::Roof(state.roof_view).index() as u8;
        let building_count = self.base_params.building_count;
        let pages = draw_ids
            .iter()
            .filter_map(|&id| id.checked_sub(building_count))
            .filter_map(|node| self.node_pages.get(node as usize).copied())
            .filter(|&page| page != NO_TEXTURE_PAGE);
        let wanted: Vec<PageView> = pages
            .flat_map(|page| [(page, 0u8), (page, roof)])
            .filter(|view| !state.broken.contains_key(view))
            .collect();
        let frame = state.frame;
        for load in state.residency.want(wanted, frame) {
            if let Some(old) = load.evicted {
                self.set_layer(gpu, old, NO_TEXTURE_PAGE);
            }
            // A closed channel means the worker is gone: the view stays flat, as broken.
            if state.requests.send(load.view).is_err() {
                state.residency.failed(load.view);
                state.broken.insert(load.view, "the decoder stopped".into());
            }
        }
    }

    /// Waits for every load in flight and uploads it: for a frame that must show all it can
    /// (`render`, tests), drawn again after this.
    pub fn settle(&self, gpu: &GpuContext) {
        let mut state = self.state();
        while state.residency.in_flight() > 0 {
            let Ok((view, image)) = state.decoded.recv() else {
                break;
            };
            self.finish_load(gpu, &mut state, view, image);
        }
    }

    /// Loads in flight (decoding or decoded, not yet uploaded).
    pub fn loading(&self) -> usize {
        self.state().residency.in_flight()
    }

    /// Where the residency stands.
    pub fn residency(&self) -> TextureResidency {
        let state = self.state();
        let resident = state.residency.resident();
        TextureResidency {
            shading: state.shading,
            resident,
            layers: state.residency.layers(),
            resident_mib: (resident as u64 * u64::from(self.summary.page_px).pow(2) * 4) as f64
                / f64::from(1 << 20),
            loading: state.residency.in_flight(),
            uploaded: state.uploaded,
            evictions: state.residency.evictions,
            starved: state.residency.starved,
            broken: state
                .broken
                .iter()
                .map(|(view, why)| (*view, why.clone()))
                .collect(),
        }
    }

    fn finish_load(
        &self,
        gpu: &GpuContext,
        state: &mut State,
        view: PageView,
        image: Result<TextureImage, String>,
    ) {
        match image {
            Ok(image) => {
                let Some(layer) = state.residency.loaded(view) else {
                    return;
                };
                self.upload(gpu, layer, &image);
                self.set_layer(gpu, view, layer);
                state.uploaded += 1;
            }
            Err(reason) => {
                state.residency.failed(view);
                tracing::warn!("cluster texture page {} view {}: {reason}", view.0, view.1);
                state.broken.insert(view, reason);
            }
        }
    }

    fn upload(&self, gpu: &GpuContext, layer: u32, image: &TextureImage) {
        gpu.queue.write_texture(
            wgpu::TexelCopyTextureInfo {
                texture: &self.texture,
                mip_level: 0,
                origin: wgpu::Origin3d {
                    x: 0,
                    y: 0,
                    z: layer,
                },
                aspect: wgpu::TextureAspect::All,
            },
            &image.rgba,
            wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(4 * image.width),
                rows_per_image: Some(image.height),
            },
            wgpu::Extent3d {
                width: image.width,
                height: image.height,
                depth_or_array_layers: 1,
            },
        );
    }

    /// Points page view `view` at `layer` (`NO_TEXTURE_PAGE`: not resident).
    fn set_layer(&self, gpu: &GpuContext, (page, view): PageView, layer: u32) {
        let slot = u64::from(page) * AtlasView::ALL.len() as u64 + u64::from(view);
        gpu.queue
            .write_buffer(&self.layers_buffer, slot * 4, bytemuck::bytes_of(&layer));
    }
}

/// The decode worker: page views in, decoded texels (or why not) out. It stops when the
/// texturing is dropped (its request channel closes).
fn spawn_decoder(textures: Arc<ClusterTextures>) -> (Sender<PageView>, Receiver<Decoded>) {
    let (request_tx, request_rx) = channel::<PageView>();
    let (decoded_tx, decoded_rx) = channel();
    let spawned = std::thread::Builder::new()
        .name("cluster texture decode".into())
        .spawn(move || {
            for (page, view) in request_rx {
                let image = AtlasView::ALL
                    .get(view as usize)
                    .ok_or_else(|| format!("no view {view}"))
                    .and_then(|v| textures.decode(page as usize, *v));
                if decoded_tx.send(((page, view), image)).is_err() {
                    break;
                }
            }
        });
    if let Err(e) = spawned {
        // No thread: every request fails at once (its channel is closed), drawn flat.
        tracing::warn!("no cluster texture decoder thread: {e}");
    }
    (request_tx, decoded_rx)
}
