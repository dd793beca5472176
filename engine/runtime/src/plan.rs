//! Which stages a frame runs: one [`FramePlan`], chosen in one place per user (the benchmark's
//! fixed modes, the viewer's toggles, the [`crate::auto`] planner) and carried out by the one
//! frame runner ([`crate::runner::FrameRunner`]) that `render`, `view` and `bench` all go
//! through.

/// What a scene offers the stages (a plain input has no cluster tree, occluders or quadtree).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct SceneFeatures {
    pub occluders: bool,
    pub cluster_tree: bool,
    pub quadtree: bool,
}

impl SceneFeatures {
    /// Everything (a scene package with every stage built).
    pub const ALL: SceneFeatures = SceneFeatures {
        occluders: true,
        cluster_tree: true,
        quadtree: true,
    };
}

/// The stages of a frame. Every combination is conservative: each stage only removes what it
/// proves hidden or replaces it by a cluster within the LOD bound.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct FramePlan {
    /// View-frustum culling on the CPU: urban blocks through the B-Quadtree (Pina et al. 2013)
    /// when `quadtree` and the scene has one, else per building; with `lod`, also the cluster
    /// tree's own frustum test. The HZB cull tests the frustum anyway.
    pub frustum: bool,
    /// With `frustum`: through the B-Quadtree (when the scene has one) rather than per
    /// building.
    pub quadtree: bool,
    /// Two-phase hierarchical-Z occlusion culling on the GPU ([`crate::frame`]).
    pub hzb: bool,
    /// The virtual-occluder pre-pass of the HZB frame (needs `hzb` and occluders).
    pub occluders: bool,
    /// The occluder gate of the pre-pass ([`crate::frame::CullingOptions::occluder_gate`];
    /// needs `occluders`).
    pub occluder_gate: bool,
    /// The screen-space LOD cut of the cluster tree (Chang et al. 2008 / Yang et al. 2011).
    pub lod: bool,
}

impl FramePlan {
    /// Every stage on (occluders, LOD and the quadtree where the scene has them).
    pub const ALL: FramePlan = FramePlan {
        frustum: true,
        quadtree: true,
        hzb: true,
        occluders: true,
        occluder_gate: true,
        lod: true,
    };
    /// Every stage off: brute force.
    pub const NONE: FramePlan = FramePlan {
        frustum: false,
        quadtree: false,
        hzb: false,
        occluders: false,
        occluder_gate: false,
        lod: false,
    };

    /// The plan as the scene can run it: stages it cannot support (LOD without a cluster tree,
    /// occluders without occluders or without HZB, the gate without occluders, the quadtree
    /// without one or without frustum culling) turned off.
    pub fn resolve(self, features: SceneFeatures) -> FramePlan {
        let occluders = self.occluders && self.hzb && features.occluders;
        FramePlan {
            frustum: self.frustum,
            quadtree: self.quadtree && self.frustum && features.quadtree,
            hzb: self.hzb,
            occluders,
            occluder_gate: self.occluder_gate && occluders,
            lod: self.lod && features.cluster_tree,
        }
    }

    /// A short description for the overlay and logs (of a resolved plan).
    pub fn describe(self) -> String {
        let mut parts: Vec<&str> = Vec::new();
        if self.lod {
            parts.push(if self.frustum {
                "LOD cut"
            } else {
                "LOD cut (no frustum culling)"
            });
        }
        if self.frustum && !self.hzb {
            parts.push(if self.quadtree {
                "B-Quadtree frustum culling"
            } else {
                "frustum culling"
            });
        } else if self.frustum && self.quadtree && self.lod {
            parts.push("B-Quadtree");
        }
        if self.hzb {
            parts.push("two-phase HiZ culling");
        }
        if self.occluders {
            parts.push(if self.occluder_gate {
                "occluders (gated)"
            } else {
                "occluders"
            });
        }
        if parts.is_empty() {
            return "brute force (no culling)".into();
        }
        parts.join(" + ")
    }
}

impl Default for FramePlan {
    fn default() -> Self {
        FramePlan::ALL
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn resolve_turns_off_what_the_scene_cannot_run() {
        let bare = SceneFeatures::default();
        let plain = FramePlan::ALL.resolve(bare);
        assert!(plain.hzb && plain.frustum);
        assert!(!plain.lod && !plain.occluders && !plain.occluder_gate && !plain.quadtree);
        assert_eq!(FramePlan::ALL.resolve(SceneFeatures::ALL), FramePlan::ALL);
        // Occluders need the HZB frame; the gate needs occluders.
        let no_hzb = FramePlan {
            hzb: false,
            ..FramePlan::ALL
        }
        .resolve(SceneFeatures::ALL);
        assert!(!no_hzb.occluders && !no_hzb.occluder_gate && no_hzb.lod);
        assert_eq!(
            FramePlan::NONE.resolve(SceneFeatures::ALL).describe(),
            "brute force (no culling)"
        );
        assert_eq!(
            FramePlan::ALL.describe(),
            "LOD cut + B-Quadtree + two-phase HiZ culling + occluders (gated)"
        );
    }
}
