//! What the viewer draws with: the culling stages switched on (a [`FramePlan`]), the LOD
//! criterion and its tolerances, and the debug view. Plain data, edited by the overlay panel and
//! the keys, read by the next frame; [`RenderSettings::plan`] turns it into the plan the frame
//! runner carries out for a scene.

use citywalk_runtime::lod::LodCriterion;
pub use citywalk_runtime::plan::{FramePlan, SceneFeatures};

/// Which criterion the LOD cut uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CriterionKind {
    /// citywalk's geometric error against a pixel tolerance (the default).
    Geometric,
    /// Chang et al. 2008 §8: ε and τ.
    Chang,
    /// Yang et al. 2011 §4: δh and δa.
    Yang,
}

impl CriterionKind {
    pub fn name(self) -> &'static str {
        match self {
            CriterionKind::Geometric => "geometric",
            CriterionKind::Chang => "chang",
            CriterionKind::Yang => "yang",
        }
    }

    /// Inverse of [`CriterionKind::name`].
    pub fn parse(name: &str) -> Option<CriterionKind> {
        [
            CriterionKind::Geometric,
            CriterionKind::Chang,
            CriterionKind::Yang,
        ]
        .into_iter()
        .find(|k| k.name() == name.trim())
    }

    /// The next criterion (the K key): geometric → Chang → Yang → geometric.
    pub fn next(self) -> CriterionKind {
        match self {
            CriterionKind::Geometric => CriterionKind::Chang,
            CriterionKind::Chang => CriterionKind::Yang,
            CriterionKind::Yang => CriterionKind::Geometric,
        }
    }
}

/// The LOD criterion and every criterion's tolerances (those not chosen keep their values).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LodSettings {
    pub kind: CriterionKind,
    /// Geometric: the largest projected error of a drawn cluster (px), its shape's and its
    /// colour's ([`citywalk_runtime::lod::LodCriterion::Geometric`]).
    pub tolerance_px: f32,
    /// Chang ε (px): the largest projected size of a drawn cluster's negative-space box
    /// ([`citywalk_runtime::lod`]).
    pub epsilon_px: f32,
    /// Chang τ: landmark tolerance (px).
    pub tau_px: f32,
    /// Yang δh_screen (px).
    pub delta_h_px: f32,
    /// Yang δa_screen (px²).
    pub delta_a_px2: f32,
}

impl Default for LodSettings {
    /// The geometric criterion at street level ([`LodCriterion::GEOMETRIC_STREET`]), chosen;
    /// Chang's walkthrough tolerances ([`LodCriterion::CHANG_WALKTHROUGH`]) and Yang's paper
    /// values ([`LodCriterion::YANG_PAPER`]).
    fn default() -> Self {
        let LodCriterion::Geometric { tolerance_px } = LodCriterion::GEOMETRIC_STREET else {
            unreachable!("GEOMETRIC_STREET is a geometric criterion")
        };
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
            kind: CriterionKind::Geometric,
            tolerance_px,
            epsilon_px,
            tau_px,
            delta_h_px,
            delta_a_px2: delta_a_px,
        }
    }
}

impl LodSettings {
    /// Slider ranges: the geometric tolerance (px), ε (px), τ (px), δh (px), δa (px²).
    pub const TOLERANCE_RANGE_PX: std::ops::RangeInclusive<f32> = 0.25..=100.0;
    pub const EPSILON_RANGE_PX: std::ops::RangeInclusive<f32> = 0.25..=100_000.0;
    pub const TAU_RANGE_PX: std::ops::RangeInclusive<f32> = 0.25..=100.0;
    pub const DELTA_H_RANGE_PX: std::ops::RangeInclusive<f32> = 1.0..=400.0;
    pub const DELTA_A_RANGE_PX2: std::ops::RangeInclusive<f32> = 10.0..=40_000.0;

    /// The criterion the cut uses.
    pub fn criterion(&self) -> LodCriterion {
        match self.kind {
            CriterionKind::Geometric => LodCriterion::Geometric {
                tolerance_px: self.tolerance_px,
            },
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
    /// Every textured cluster mesh in the colour of its texture bin (Chang et al. 2008 §7),
    /// untextured ones dark grey.
    Bins,
}

impl DebugView {
    pub const ALL: [DebugView; 5] = [
        DebugView::Off,
        DebugView::Pyramid,
        DebugView::Clusters,
        DebugView::Occluders,
        DebugView::Bins,
    ];

    pub fn name(self) -> &'static str {
        match self {
            DebugView::Off => "off",
            DebugView::Pyramid => "pyramid",
            DebugView::Clusters => "clusters",
            DebugView::Occluders => "occluders",
            DebugView::Bins => "bins",
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
    /// The stages switched on (the viewer's frustum culling goes through the B-Quadtree when
    /// the scene has one: [`RenderSettings::plan`]).
    pub stages: FramePlan,
    /// The `auto` plan ([`citywalk_runtime::auto::AutoPlanner`]): the culling stages chosen by their
    /// measured cost on this adapter and view; `stages` then only says whether the LOD cut is
    /// on (a quality choice, the user's).
    pub auto: bool,
    pub lod: LodSettings,
    pub debug_view: DebugView,
    /// The pyramid level the pyramid view shows (clamped to the pyramid's last level).
    pub mip_level: u32,
    /// Cluster meshes drawn with their baked textures (packages made with
    /// `preprocess --cluster-textures`), else in flat colours.
    pub cluster_textures: bool,
}

impl Default for RenderSettings {
    /// The `auto` plan over frustum, HZB and occluders, LOD off (it changes the image), no debug
    /// view.
    fn default() -> Self {
        RenderSettings {
            stages: FramePlan {
                lod: false,
                ..FramePlan::ALL
            },
            auto: true,
            lod: LodSettings::default(),
            debug_view: DebugView::Off,
            mip_level: 0,
            cluster_textures: true,
        }
    }
}

impl RenderSettings {
    /// The plan to run for a scene that offers `features`: the stages switched on, frustum
    /// culling through the B-Quadtree where the scene has one, and what the scene cannot run
    /// turned off ([`FramePlan::resolve`]).
    pub fn plan(&self, features: SceneFeatures) -> FramePlan {
        FramePlan {
            quadtree: self.stages.frustum,
            ..self.stages
        }
        .resolve(features)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_the_papers_and_criteria_follow_the_sliders() {
        let lod = LodSettings::default();
        assert_eq!(lod.criterion(), LodCriterion::GEOMETRIC_STREET);
        let chang = LodSettings {
            kind: CriterionKind::Chang,
            ..lod
        };
        assert_eq!(chang.criterion(), LodCriterion::CHANG_WALKTHROUGH);
        let yang = LodSettings {
            kind: CriterionKind::Yang,
            ..lod
        };
        assert_eq!(yang.criterion(), LodCriterion::YANG_PAPER);
        let moved = LodSettings {
            kind: CriterionKind::Chang,
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
        assert_eq!(
            CriterionKind::parse("geometric"),
            Some(CriterionKind::Geometric)
        );
        let mut k = CriterionKind::Geometric;
        for want in [
            CriterionKind::Chang,
            CriterionKind::Yang,
            CriterionKind::Geometric,
        ] {
            k = k.next();
            assert_eq!(k, want);
        }
        assert!(LodSettings::TOLERANCE_RANGE_PX.contains(&lod.tolerance_px));
    }

    #[test]
    fn the_plan_follows_the_stages_and_what_the_scene_has() {
        let package = SceneFeatures::ALL;
        let plain = SceneFeatures::default();
        let with = |stages: FramePlan| RenderSettings {
            stages,
            ..RenderSettings::default()
        };
        assert_eq!(with(FramePlan::NONE).plan(package), FramePlan::NONE);
        assert_eq!(with(FramePlan::ALL).plan(package), FramePlan::ALL);
        // No cluster tree: LOD is off; no occluders: the pre-pass is off.
        let plain_all = with(FramePlan::ALL).plan(plain);
        assert!(plain_all.hzb && !plain_all.lod && !plain_all.occluders && !plain_all.quadtree);
        // Frustum culling goes through the B-Quadtree where there is one.
        let frustum_only = FramePlan {
            frustum: true,
            ..FramePlan::NONE
        };
        assert!(with(frustum_only).plan(package).quadtree);
        assert!(!with(frustum_only).plan(plain).quadtree);
        let lod_only = FramePlan {
            lod: true,
            ..FramePlan::NONE
        };
        let lod = with(lod_only).plan(package);
        assert!(lod.lod && !lod.frustum && !lod.quadtree && !lod.hzb);
        assert_eq!(with(lod_only).plan(plain), FramePlan::NONE);
    }

    #[test]
    fn debug_views_cycle_and_parse() {
        let mut v = DebugView::Off;
        let mut seen = Vec::new();
        for _ in 0..DebugView::ALL.len() {
            v = v.next();
            seen.push(v);
        }
        assert_eq!(seen.last(), Some(&DebugView::Off));
        assert_eq!(seen[2], DebugView::Occluders);
        assert_eq!(seen[3], DebugView::Bins);
        for view in DebugView::ALL {
            assert_eq!(DebugView::parse(view.name()), Some(view));
        }
        assert_eq!(DebugView::parse("mips"), None);
    }
}
