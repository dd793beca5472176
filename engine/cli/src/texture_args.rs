//! `--texture-budget-mib`: how the commands that draw (`render`, `view`, `bench`) draw a
//! package's baked cluster textures (`preprocess --cluster-textures`).

use anyhow::Context;
use citywalk_runtime::cluster_textures::DEFAULT_BUDGET_MIB;
use citywalk_runtime::drawable::DrawableScene;
use citywalk_runtime::gpu::GpuContext;
use citywalk_scenes::cluster_texture::baked::ClusterTextures;
use citywalk_scenes::package::GpuScene;

#[derive(Debug, Clone, Copy, clap::Args)]
pub struct TextureArgs {
    /// GPU memory for the cluster textures' resident pages, in MiB (a page view of 1024²
    /// texels is 4 MiB); 0 draws the cluster meshes in flat colours. Pages load as the
    /// clusters on them are drawn, the least recently drawn giving way.
    #[arg(long, default_value_t = DEFAULT_BUDGET_MIB)]
    pub texture_budget_mib: u64,
}

impl Default for TextureArgs {
    fn default() -> TextureArgs {
        TextureArgs {
            texture_budget_mib: DEFAULT_BUDGET_MIB,
        }
    }
}

impl TextureArgs {
    /// `scene` drawing the package's `textures` (when it has them and the budget is not 0),
    /// with a line on stderr saying what is textured.
    pub fn apply(
        &self,
        gpu: &GpuContext,
        mut scene: DrawableScene,
        gpu_scene: &GpuScene,
        textures: Option<ClusterTextures>,
    ) -> anyhow::Result<DrawableScene> {
        let Some(textures) = textures.filter(|_| self.texture_budget_mib > 0) else {
            return Ok(scene);
        };
        scene
            .add_cluster_textures(gpu, gpu_scene, textures, self.texture_budget_mib)
            .context("cannot draw the cluster textures")?;
        if let Some(t) = scene.texturing() {
            let s = &t.summary;
            eprintln!(
                "cluster textures: {} clusters textured, at most {} page views of {px}×{px} resident ({} MiB)",
                s.textured_clusters,
                s.layers,
                (u64::from(s.layers) * u64::from(s.page_px).pow(2) * 4) >> 20,
                px = s.page_px
            );
            if let Some((node, reason)) = s.rejected.first() {
                eprintln!(
                    "warning: {} placed clusters drawn untextured (node {node}: {reason})",
                    s.rejected.len()
                );
            }
        }
        Ok(scene)
    }
}
