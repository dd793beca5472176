//! Culling modes of the benchmark: each a name for a [`FramePlan`] (the science of the
//! benchmark is comparing fixed plans), carried out by the frame runner
//! ([`citywalk_runtime::runner::FrameRunner`]) as `view` and `render` carry out theirs.
//!
//! Modes build on each other: `brute` draws everything; `frustum` tests every building's box
//! against the view frustum; `quadtree` culls whole urban blocks top-down through the
//! B-Quadtree (Pina et al. 2013, §3-4: hierarchical frustum culling of blocks); `hzb` and
//! `occluders` cull on the GPU inside the two-phase frame ([`citywalk_runtime::frame::CullingRenderer`]);
//! `lod` cuts the cluster tree on the CPU after B-Quadtree culling; `all` feeds that cut's
//! buildings and clusters through the two-phase frame with occluders. The pseudo-mode `oracle`
//! The mode `auto` has no fixed plan: [`citywalk_runtime::auto::AutoPlanner`] picks one per frame. The
//! pseudo-mode `oracle` draws exactly the buildings the ID-buffer oracle sees: no culler can draw less without a false
//! cull, so its frame time is the floor every mode is measured against (`oracle_ratio` in
//! `bench.json`).

use std::fmt;

use citywalk_runtime::plan::FramePlan;

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
    /// `lod` with the cluster meshes in flat colours, not their baked textures: the same cut,
    /// for Chang et al. 2008 §9's comparison of textured and untextured clusters at equal
    /// triangles (the same as `lod` for a package without cluster textures).
    LodFlat,
    /// Everything on.
    All,
    /// The `auto` plan ([`citywalk_runtime::auto::AutoPlanner`]): the culling stages chosen frame by frame
    /// from their measured cost, with the LOD cut as in `all`.
    Auto,
    /// Exactly the oracle's visible set of the frame, in one plain pass: the fastest any
    /// culling could be.
    Oracle,
    /// Test-only: brute force minus the first building the oracle sees, so tests can prove
    /// that the benchmark catches a false cull. Not reachable from the command line.
    DropOneVisibleForTest,
}

impl Mode {
    /// The modes the command line knows, in order.
    pub const NAMED: [Mode; 10] = [
        Mode::Brute,
        Mode::Frustum,
        Mode::Quadtree,
        Mode::Hzb,
        Mode::Occluders,
        Mode::Lod,
        Mode::LodFlat,
        Mode::All,
        Mode::Auto,
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
            Mode::LodFlat => "lod-flat",
            Mode::All => "all",
            Mode::Auto => "auto",
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

impl Mode {
    /// The stages the mode runs, or `None` for the pseudo-modes drawn as a plain selection
    /// (`oracle`, the test-only mode).
    pub fn plan(self) -> Option<FramePlan> {
        let none = FramePlan::NONE;
        Some(match self {
            Mode::Brute => none,
            Mode::Frustum => FramePlan {
                frustum: true,
                ..none
            },
            Mode::Quadtree => FramePlan {
                frustum: true,
                quadtree: true,
                ..none
            },
            Mode::Hzb => FramePlan { hzb: true, ..none },
            Mode::Occluders => FramePlan {
                hzb: true,
                occluders: true,
                occluder_gate: true,
                ..none
            },
            Mode::Lod | Mode::LodFlat => FramePlan {
                lod: true,
                frustum: true,
                quadtree: true,
                ..none
            },
            Mode::All => FramePlan::ALL,
            Mode::Auto | Mode::Oracle | Mode::DropOneVisibleForTest => return None,
        })
    }
}

impl fmt::Display for Mode {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
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
