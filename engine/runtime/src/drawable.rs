//! A scene ready to draw with any [`crate::plan::FramePlan`]: its buildings on the GPU and, where
//! the scene has them, the structures the plan's stages use (the cluster tree's LOD scene, the
//! urban blocks with their B-Quadtree, the virtual occluders). One upload for `render`, `view`
//! and `bench`, so each draws the same buffers the same way.

use citywalk_scenes::City;
use citywalk_scenes::blocks::UrbanBlocks;
use citywalk_scenes::cluster_tree::ClusterTree;
use citywalk_scenes::ground_surfaces::GroundSurfaces;
use citywalk_scenes::package::GpuScene;
use citywalk_scenes::quadtree::BQuadtree;

use std::sync::Arc;

use citywalk_scenes::cluster_texture::baked::ClusterTextures;

use crate::cluster_textures::{ClusterTexturing, MeshArrays, TexturingError};
use crate::frame::OccluderMeshes;
use crate::gpu::GpuContext;
use crate::lod::scene::LodScene;
use crate::plan::SceneFeatures;
use crate::render::SurfaceMeshes;
use crate::runner::SceneRefs;
use crate::scene_gpu::SceneGpu;
use crate::upload::UploadError;

/// The scene's buildings on the GPU, with the optional structures of the frame's stages.
#[derive(Debug)]
pub struct DrawableScene {
    pub buildings: SceneGpu,
    /// Buildings and cluster meshes over the same buffers, for the LOD cut (`None` without a
    /// cluster tree).
    pub lod: Option<LodScene>,
    /// Urban blocks and their B-Quadtree, for frustum culling of whole blocks.
    pub blocks: Option<(UrbanBlocks, BQuadtree)>,
    /// The virtual occluders (`None` when the scene has none).
    pub occluders: Option<OccluderMeshes>,
    /// Streets and ground areas drawn over the ground (`None` when the scene has none).
    pub surfaces: Option<SurfaceMeshes>,
}

impl DrawableScene {
    /// Uploads a package's GPU scene straight from its mapping (no meshing): buildings, the LOD
    /// scene of `cluster_tree` over the same buffers, and the occluders the package holds. The
    /// mapping's pages leave resident memory as they are uploaded (the CPU copies of the
    /// records read them again from the page cache). An array over the GPU's limits or
    /// memory is an error naming it.
    pub fn upload_package(
        gpu: &GpuContext,
        gpu_scene: &GpuScene,
        cluster_tree: Option<ClusterTree>,
        blocks: Option<(UrbanBlocks, BQuadtree)>,
    ) -> Result<DrawableScene, UploadError> {
        let view = gpu_scene.view();
        let buildings = SceneGpu::upload_package(gpu, &view)?;
        let lod = cluster_tree
            .map(|tree| LodScene::upload_package(gpu, &buildings, &view, tree))
            .transpose()?;
        let occluders = (!view.occluders.records.is_empty())
            .then(|| OccluderMeshes::upload_package(gpu, &view))
            .transpose()?;
        view.release_resident(gpu_scene.bytes());
        Ok(DrawableScene {
            buildings,
            lod,
            blocks,
            occluders,
            surfaces: None,
        })
    }

    /// Uploads the streets and ground areas drawn over the ground plane (a package's
    /// [`citywalk_scenes::package::ScenePackage::ground_surfaces`], or
    /// [`GroundSurfaces::build`] of a city).
    pub fn with_surfaces(
        mut self,
        gpu: &GpuContext,
        surfaces: &GroundSurfaces,
    ) -> Result<DrawableScene, UploadError> {
        let ground_z = citywalk_scenes::scene_geometry::ground_plane_z(self.buildings.bounds.0.z);
        self.surfaces = SurfaceMeshes::upload(gpu, surfaces, ground_z)?;
        Ok(self)
    }

    /// Draws the LOD scene's cluster meshes with a package's baked `textures`, keeping at most
    /// `budget_mib` MiB of page views on the GPU ([`ClusterTexturing`]); `gpu_scene` is the
    /// package's GPU scene this was uploaded from (its meshes are checked against the layout).
    /// A scene without a cluster tree draws nothing textured. On an error the scene is as it
    /// was.
    pub fn add_cluster_textures(
        &mut self,
        gpu: &GpuContext,
        gpu_scene: &GpuScene,
        textures: ClusterTextures,
        budget_mib: u64,
    ) -> Result<(), TexturingError> {
        let Some(lod) = &mut self.lod else {
            return Ok(());
        };
        let view = gpu_scene.view();
        let meshes = MeshArrays {
            building_count: view.building_count,
            node_count: lod.tree.tree.nodes.len() as u32,
            records: view.records,
            vertices: view.vertices,
            indices: view.indices,
        };
        let texturing = ClusterTexturing::new(gpu, Arc::new(textures), meshes, budget_mib)?;
        view.release_resident(gpu_scene.bytes());
        lod.gpu_scene.texturing = Some(texturing);
        Ok(())
    }

    /// The LOD scene's cluster textures, if it draws any.
    pub fn texturing(&self) -> Option<&ClusterTexturing> {
        self.lod.as_ref()?.gpu_scene.texturing.as_ref()
    }

    /// Meshes and uploads a city loaded from a raw input, as preprocessing does for a package
    /// (once, the buildings and the cluster meshes of `cluster_tree` in shared buffers, and the
    /// streets and ground areas as surfaces): no occluders (preprocessing makes them) and no blocks unless given.
    pub fn upload_city(
        gpu: &GpuContext,
        city: &City,
        cluster_tree: Option<ClusterTree>,
        blocks: Option<(UrbanBlocks, BQuadtree)>,
    ) -> Result<DrawableScene, UploadError> {
        let gpu_scene = GpuScene::build(city, cluster_tree.as_ref(), None);
        Self::upload_package(gpu, &gpu_scene, cluster_tree, blocks)?
            .with_surfaces(gpu, &GroundSurfaces::build(city))
    }

    /// What a frame draws from.
    pub fn refs(&self) -> SceneRefs<'_> {
        SceneRefs {
            scene: &self.buildings,
            lod: self.lod.as_ref(),
            blocks: self.blocks.as_ref().map(|(b, q)| (b, q)),
            occluders: self.occluders.as_ref(),
            surfaces: self.surfaces.as_ref(),
        }
    }

    /// What the scene offers the stages.
    pub fn features(&self) -> SceneFeatures {
        self.refs().features()
    }
}
