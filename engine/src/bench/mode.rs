//! Culling modes of the benchmark and the CPU selection each makes.
//!
//! Modes build on each other: `brute` draws everything; `frustum` tests every building's box
//! against the view frustum; `quadtree` culls whole urban blocks top-down through the
//! B-Quadtree (Pina et al. 2013, §3-4: hierarchical frustum culling of blocks). The GPU
//! occlusion modes `hzb` and `occluders` select on the GPU inside the two-phase frame
//! ([`crate::frame::CullingRenderer`]), not here; `lod` cuts the cluster tree on the CPU after
//! B-Quadtree culling ([`crate::lod::scene::LodScene::select`], called by the bench runner);
//! `all` feeds that cut's buildings and clusters through the two-phase frame with occluders
//! ([`crate::frame::CullingRenderer::render_lod`]); modes the runtime does not implement are
//! named so the command line can refuse them clearly. The pseudo-mode `oracle` draws exactly the
//! buildings the ID-buffer oracle sees: no culler can draw less without a false cull, so its
//! frame time is the floor every mode is measured against (`oracle_ratio` in `bench.json`).

use std::fmt;

use citywalk_scenes::blocks::UrbanBlocks;
use citywalk_scenes::frustum::Frustum;
use citywalk_scenes::quadtree::BQuadtree;
use glam::Mat4;

use crate::camera::Camera;
use crate::scene_gpu::SceneGpu;

/// A culling configuration measured by the benchmark.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Mode {
    /// Everything, no culling: the reference.
    Brute,
    /// Per-building view-frustum culling.
    Frustum,
    /// B-Quadtree hierarchical frustum culling of urban blocks.
    Quadtree,
    /// + hierarchical-Z occlusion culling without occluders.
    Hzb,
    /// + the virtual-occluder pre-pass.
    Occluders,
    /// + screen-space-error level of detail.
    Lod,
    /// Everything on.
    All,
    /// Exactly the oracle's visible set of the frame, in one plain pass: the fastest any
    /// culling could be.
    Oracle,
    /// Test-only: brute force minus the first building the oracle sees, so tests can prove
    /// that the benchmark catches a false cull. Not reachable from the command line.
    DropOneVisibleForTest,
}

impl Mode {
    /// The modes the command line knows, in order.
    pub const NAMED: [Mode; 8] = [
        Mode::Brute,
        Mode::Frustum,
        Mode::Quadtree,
        Mode::Hzb,
        Mode::Occluders,
        Mode::Lod,
        Mode::All,
        Mode::Oracle,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Mode::Brute => "brute",
            Mode::Frustum => "frustum",
            Mode::Quadtree => "quadtree",
            Mode::Hzb => "hzb",
            Mode::Occluders => "occluders",
            Mode::Lod => "lod",
            Mode::All => "all",
            Mode::Oracle => "oracle",
            Mode::DropOneVisibleForTest => "drop-one-visible-for-test",
        }
    }

    /// Parses a comma-separated list, refusing unknown modes (a name no build has is refused
    /// with the list of those this one runs).
    pub fn parse_list(list: &str) -> Result<Vec<Mode>, String> {
        let mut modes = Vec::new();
        for word in list.split(',').map(str::trim).filter(|w| !w.is_empty()) {
            let mode = Mode::NAMED
                .into_iter()
                .find(|m| m.name() == word)
                .ok_or_else(|| {
                    format!(
                        "unknown mode '{word}' (modes: {})",
                        Mode::NAMED.map(Mode::name).join(", ")
                    )
                })?;
            if !modes.contains(&mode) {
                modes.push(mode);
            }
        }
        if modes.is_empty() {
            return Err("no mode given".into());
        }
        Ok(modes)
    }
}

impl fmt::Display for Mode {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// The urban blocks the B-Quadtree finds in the frustum of `camera` on a
/// `width_px`×`height_px` viewport, one flag per block (Pina et al. 2013 §4): the
/// `visible_blocks` argument of [`crate::lod::scene::LodScene::select`].
pub fn visible_blocks(
    quadtree: &BQuadtree,
    block_count: usize,
    camera: &Camera,
    width_px: u32,
    height_px: u32,
) -> Vec<bool> {
    let aspect = width_px.max(1) as f32 / height_px.max(1) as f32;
    let frustum = Frustum::from_view_proj(camera.view_proj(aspect));
    let mut visible = vec![false; block_count];
    for block in quadtree.cull(&frustum) {
        if let Some(v) = visible.get_mut(block as usize) {
            *v = true;
        }
    }
    visible
}

/// What a mode needs to select buildings on the CPU.
#[derive(Debug)]
pub struct CullingData<'a> {
    pub scene: &'a SceneGpu,
    pub blocks: &'a UrbanBlocks,
    pub quadtree: &'a BQuadtree,
}

/// The buildings `mode` draws for a camera with `view_proj`, in id order, or `None` for a mode
/// the runtime does not implement yet, or one not selected here (`lod` needs the scene's
/// cluster tree: [`crate::lod::scene::LodScene::select`]; `oracle` draws the frame's visible
/// set, which the bench runner holds). `visible_first` is the first building of the oracle's
/// visible set, used only by the test-only mode.
pub fn select(
    mode: Mode,
    data: &CullingData<'_>,
    view_proj: Mat4,
    visible_first: Option<u32>,
) -> Option<Vec<u32>> {
    let all = || (0..data.scene.building_count() as u32).collect::<Vec<u32>>();
    Some(match mode {
        Mode::Brute => all(),
        Mode::DropOneVisibleForTest => {
            let mut v = all();
            v.retain(|&b| Some(b) != visible_first);
            v
        }
        Mode::Frustum => data
            .scene
            .buildings_in_frustum(&Frustum::from_view_proj(view_proj)),
        Mode::Quadtree => {
            let frustum = Frustum::from_view_proj(view_proj);
            let mut out: Vec<u32> = data
                .quadtree
                .cull(&frustum)
                .into_iter()
                .filter_map(|block| data.blocks.blocks.get(block as usize))
                .flat_map(|block| block.buildings.iter().map(|b| b.0))
                .collect();
            out.sort_unstable();
            out
        }
        Mode::Hzb | Mode::Occluders | Mode::Lod | Mode::All | Mode::Oracle => return None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parse_refuses_unknown_and_test_only_modes() {
        assert_eq!(
            Mode::parse_list("brute, frustum,brute").unwrap(),
            vec![Mode::Brute, Mode::Frustum]
        );
        assert!(
            Mode::parse_list("fast")
                .unwrap_err()
                .contains("unknown mode")
        );
        // Every named mode is built now, `all` and `oracle` included; the test-only mode stays
        // unreachable.
        assert_eq!(
            Mode::parse_list("brute,all,lod,oracle").unwrap(),
            vec![Mode::Brute, Mode::All, Mode::Lod, Mode::Oracle]
        );
        assert!(Mode::parse_list("").is_err());
        assert!(Mode::parse_list("drop-one-visible-for-test").is_err());
    }
}
