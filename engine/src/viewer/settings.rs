//! What the viewer draws with: the culling stages switched on, the LOD criterion and its
//! tolerances, and the debug view. Plain data, edited by the overlay panel and the keys, read by
//! the next frame; [`RenderSettings::draw_path`] turns it into the frame to render for a scene.

use crate::lod::LodCriterion;

/// The culling stages, each switched on or off. All off is brute force.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Stages {
    /// View-frustum culling on the CPU: the B-Quadtree of urban blocks (Pina et al. 2013) when
    /// the scene has one, else per building; with LOD, also the cluster tree's own frustum test.
    /// With HZB occlusion on the cull shader tests the frustum anyway.
    pub frustum: bool,
    /// Two-phase hierarchical-Z occlusion culling on the GPU ([`crate::frame`]).
    pub hzb: bool,
    /// The virtual-occluder pre-pass of the HZB frame (needs `hzb` and occluders).
    pub occluders: bool,
    /// The occluder gate of the pre-pass: last frame's visible set is drawn early only where the
    /// occluders' own pyramid does not hide it ([`crate::frame::CullingOptions::occluder_gate`];
    /// needs `occluders`).
    pub occluder_gate: bool,
    /// The screen-space LOD cut of the cluster tree (Chang et al. 2008 / Yang et al. 2011).
    pub lod: bool,
}

impl Stages {
    /// Every stage on (occluders and LOD where the scene has them).
    pub const ALL: Stages = Stages {
        frustum: true,
        hzb: true,
        occluders: true,
        occluder_gate: true,
        lod: true,
    };
    /// Every stage off: brute force.
    pub const NONE: Stages = Stages {
        frustum: false,
        hzb: false,
        occluders: false,
        occluder_gate: false,
        lod: false,
    };
}

/// Which paper's criterion the LOD cut uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CriterionKind {
    /// Chang et al. 2008 §8: ε and τ.
    Chang,
    /// Yang et al. 2011 §4: δh and δa.
    Yang,
}

impl CriterionKind {
    pub fn name(self) -> &'static str {
        match self {
            CriterionKind::Chang => "chang",
            CriterionKind::Yang => "yang",
        }
    }

    /// Inverse of [`CriterionKind::name`].
    pub fn parse(name: &str) -> Option<CriterionKind> {
        [CriterionKind::Chang, CriterionKind::Yang]
            .into_iter()
            .find(|k| k.name() == name.trim())
    }
}

/// The LOD criterion and both papers' tolerances (the one not chosen keeps its values).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LodSettings {
    pub kind: CriterionKind,
    /// Chang ε (px): the largest projected size of a drawn cluster's negative-space box
    /// ([`crate::lod`]).
    pub epsilon_px: f32,
    /// Chang τ: landmark tolerance (px).
    pub tau_px: f32,
    /// Yang δh_screen (px).
    pub delta_h_px: f32,
    /// Yang δa_screen (px²).
    pub delta_a_px2: f32,
}

impl Default for LodSettings {
    /// Chang's walkthrough tolerances ([`LodCriterion::CHANG_WALKTHROUGH`]) and Yang's paper
    /// values ([`LodCriterion::YANG_PAPER`]), Chang chosen.
    fn default() -> Self {
        let LodCriterion::Chang { epsilon_px, tau_px } = LodCriterion::CHANG_WALKTHROUGH else {
            unreachable!("CHANG_WALKTHROUGH is a Chang criterion")
        };
        let LodCriterion::Yang {
            delta_h_px,
            delta_a_px,
        } = LodCriterion::YANG_PAPER
        else {
            unreachable!("YANG_PAPER is a Yang criterion")
        };
        LodSettings {
            kind: CriterionKind::Chang,
            epsilon_px,
            tau_px,
            delta_h_px,
            delta_a_px2: delta_a_px,
        }
    }
}

impl LodSettings {
    /// Slider ranges: ε (px), τ (px), δh (px), δa (px²).
    pub const EPSILON_RANGE_PX: std::ops::RangeInclusive<f32> = 0.25..=100_000.0;
    pub const TAU_RANGE_PX: std::ops::RangeInclusive<f32> = 0.25..=100.0;
    pub const DELTA_H_RANGE_PX: std::ops::RangeInclusive<f32> = 1.0..=400.0;
    pub const DELTA_A_RANGE_PX2: std::ops::RangeInclusive<f32> = 10.0..=40_000.0;

    /// The criterion the cut uses.
    pub fn criterion(&self) -> LodCriterion {
        match self.kind {
            CriterionKind::Chang => LodCriterion::Chang {
                epsilon_px: self.epsilon_px,
                tau_px: self.tau_px,
            },
            CriterionKind::Yang => LodCriterion::Yang {
                delta_h_px: self.delta_h_px,
                delta_a_px: self.delta_a_px2,
            },
        }
    }
}

/// A debug view drawn instead of (or over) the frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DebugView {
    /// The frame as it is.
    Off,
    /// Level K of the hierarchical-Z pyramid, greyscale.
    Pyramid,
    /// Every drawn building and cluster in its own colour (Chang et al. 2008 Fig. 1c).
    Clusters,
    /// The virtual occluders over the frame, the selected ones highlighted.
    Occluders,
}

impl DebugView {
    pub const ALL: [DebugView; 4] = [
        DebugView::Off,
        DebugView::Pyramid,
        DebugView::Clusters,
        DebugView::Occluders,
    ];

    pub fn name(self) -> &'static str {
        match self {
            DebugView::Off => "off",
            DebugView::Pyramid => "pyramid",
            DebugView::Clusters => "clusters",
            DebugView::Occluders => "occluders",
        }
    }

    /// Inverse of [`DebugView::name`].
    pub fn parse(name: &str) -> Option<DebugView> {
        Self::ALL.into_iter().find(|v| v.name() == name.trim())
    }

    /// The next view (G cycles through them).
    pub fn next(self) -> DebugView {
        let i = Self::ALL.iter().position(|&v| v == self).unwrap_or(0);
        Self::ALL[(i + 1) % Self::ALL.len()]
    }
}

/// Everything the next frame is drawn with.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RenderSettings {
    pub stages: Stages,
    pub lod: LodSettings,
    pub debug_view: DebugView,
    /// The pyramid level the pyramid view shows (clamped to the pyramid's last level).
    pub mip_level: u32,
}

impl Default for RenderSettings {
    /// Frustum, HZB and occluders on, LOD off (it changes the image), no debug view.
    fn default() -> Self {
        RenderSettings {
            stages: Stages {
                lod: false,
                ..Stages::ALL
            },
            lod: LodSettings::default(),
            debug_view: DebugView::Off,
            mip_level: 0,
        }
    }
}

/// What the loaded scene offers.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct SceneFeatures {
    /// Virtual occluders (scene packages).
    pub occluders: bool,
    /// A cluster tree (scene packages built with one).
    pub cluster_tree: bool,
    /// A B-Quadtree of urban blocks (scene packages).
    pub quadtree: bool,
}

/// The frame the settings ask for, given what the scene offers.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DrawPath {
    /// Every building, no culling.
    Brute,
    /// CPU frustum culling: of urban blocks through the B-Quadtree, or per building.
    Frustum { quadtree: bool },
    /// The two-phase HZB frame over every building (the cull shader tests the frustum).
    Hzb { occluders: bool },
    /// The LOD cut drawn as it is (after B-Quadtree / frustum culling when `frustum`).
    Lod { frustum: bool, quadtree: bool },
    /// The LOD cut's candidates (after B-Quadtree / frustum culling when `frustum`) through
    /// the two-phase HZB frame.
    LodHzb {
        occluders: bool,
        frustum: bool,
        quadtree: bool,
    },
}

impl DrawPath {
    /// A short description for the overlay.
    pub fn describe(self) -> &'static str {
        match self {
            DrawPath::Brute => "brute force (no culling)",
            DrawPath::Frustum { quadtree: true } => "B-Quadtree frustum culling",
            DrawPath::Frustum { quadtree: false } => "frustum culling",
            DrawPath::Hzb { occluders: false } => "two-phase HiZ culling",
            DrawPath::Hzb { occluders: true } => "two-phase HiZ culling + occluders",
            DrawPath::Lod { frustum: true, .. } => "LOD cut + frustum culling",
            DrawPath::Lod { frustum: false, .. } => "LOD cut (no culling)",
            DrawPath::LodHzb {
                occluders: false, ..
            } => "LOD cut + two-phase HiZ culling",
            DrawPath::LodHzb {
                occluders: true, ..
            } => "LOD cut + HiZ culling + occluders",
        }
    }
}

impl RenderSettings {
    /// The frame to draw: stages the scene cannot support (LOD without a cluster tree,
    /// occluders without occluders or without HZB) count as off.
    pub fn draw_path(&self, features: SceneFeatures) -> DrawPath {
        let s = self.stages;
        let occluders = s.occluders && s.hzb && features.occluders;
        let quadtree = s.frustum && features.quadtree;
        match (s.lod && features.cluster_tree, s.hzb) {
            (true, true) => DrawPath::LodHzb {
                occluders,
                frustum: s.frustum,
                quadtree,
            },
            (true, false) => DrawPath::Lod {
                frustum: s.frustum,
                quadtree,
            },
            (false, true) => DrawPath::Hzb { occluders },
            (false, false) if s.frustum => DrawPath::Frustum { quadtree },
            (false, false) => DrawPath::Brute,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_the_papers_and_criteria_follow_the_sliders() {
        let lod = LodSettings::default();
        assert_eq!(lod.criterion(), LodCriterion::CHANG_WALKTHROUGH);
        let yang = LodSettings {
            kind: CriterionKind::Yang,
            ..lod
        };
        assert_eq!(yang.criterion(), LodCriterion::YANG_PAPER);
        let moved = LodSettings {
            epsilon_px: 7.5,
            tau_px: 3.0,
            ..lod
        };
        assert_eq!(
            moved.criterion(),
            LodCriterion::Chang {
                epsilon_px: 7.5,
                tau_px: 3.0
            }
        );
        assert!(LodSettings::EPSILON_RANGE_PX.contains(&lod.epsilon_px));
        assert!(LodSettings::DELTA_A_RANGE_PX2.contains(&lod.delta_a_px2));
        assert_eq!(CriterionKind::parse("yang"), Some(CriterionKind::Yang));
        assert_eq!(CriterionKind::parse("fast"), None);
    }

    #[test]
    fn the_draw_path_follows_the_stages_and_what_the_scene_has() {
        let package = SceneFeatures {
            occluders: true,
            cluster_tree: true,
            quadtree: true,
        };
        let plain = SceneFeatures::default();
        let with = |stages: Stages| RenderSettings {
            stages,
            ..RenderSettings::default()
        };
        assert_eq!(with(Stages::NONE).draw_path(package), DrawPath::Brute);
        assert_eq!(
            with(Stages::ALL).draw_path(package),
            DrawPath::LodHzb {
                occluders: true,
                frustum: true,
                quadtree: true
            }
        );
        // No cluster tree: LOD is off; no occluders: the pre-pass is off.
        assert_eq!(
            with(Stages::ALL).draw_path(plain),
            DrawPath::Hzb { occluders: false }
        );
        let frustum_only = Stages {
            frustum: true,
            ..Stages::NONE
        };
        assert_eq!(
            with(frustum_only).draw_path(package),
            DrawPath::Frustum { quadtree: true }
        );
        assert_eq!(
            with(frustum_only).draw_path(plain),
            DrawPath::Frustum { quadtree: false }
        );
        // Occluders need the HZB frame.
        let no_hzb = Stages {
            hzb: false,
            ..Stages::ALL
        };
        assert_eq!(
            with(no_hzb).draw_path(package),
            DrawPath::Lod {
                frustum: true,
                quadtree: true
            }
        );
        let lod_only = Stages {
            lod: true,
            ..Stages::NONE
        };
        assert_eq!(
            with(lod_only).draw_path(package),
            DrawPath::Lod {
                frustum: false,
                quadtree: false
            }
        );
        assert_eq!(with(lod_only).draw_path(plain), DrawPath::Brute);
    }

    #[test]
    fn debug_views_cycle_and_parse() {
        let mut v = DebugView::Off;
        let mut seen = Vec::new();
        for _ in 0..4 {
            v = v.next();
            seen.push(v);
        }
        assert_eq!(seen.last(), Some(&DebugView::Off));
        assert_eq!(seen.len(), 4);
        for view in DebugView::ALL {
            assert_eq!(DebugView::parse(view.name()), Some(view));
        }
        assert_eq!(DebugView::parse("mips"), None);
    }
}
