//! The `auto` plan: the frame's culling stages chosen from what they cost on the adapter at hand,
//! so that a stage that does not pay here (occlusion culling in a high flyover, the occluder
//! gate on a small city, a depth pyramid on a software rasteriser) is skipped and the frame is
//! never much slower than the cheapest plan.
//!
//! A small bandit over a fixed ladder of plans: brute force (no culling and no LOD, the frame the
//! others must beat), then CPU frustum culling, with the HZB frame, with occluders, with the
//! gate, these four with the LOD cut as the caller asks. Every plan is
//! tried for a few frames first (the first frame of each is not counted: its early set is empty),
//! then the cheapest by a moving average of measured frame cost is run, and every `PROBE_EVERY`
//! frames one other plan is tried again, so the choice follows the view. Every plan is
//! conservative, so the choice never touches correctness.

use crate::plan::{FramePlan, SceneFeatures};
use crate::runner::FrameReport;

/// Frames each plan runs when it is tried: the first is warm-up (shaders, an empty early set),
/// the others are measured.
const TRIAL_FRAMES: u32 = 3;

/// One other plan is re-tried after this many frames of the chosen one (about two seconds at
/// 60 frames a second: a probe costs a few frames of a possibly slower plan).
const PROBE_EVERY: u64 = 120;

/// Weight of a new measurement in a plan's moving average.
const SMOOTHING: f64 = 0.3;

/// A plan must be cheaper than the current one by this factor to replace it (hysteresis: no
/// flapping between two plans that cost the same).
const SWITCH_MARGIN: f64 = 0.9;

/// The planner: the ladder of candidate plans and their measured costs.
#[derive(Debug, Clone)]
pub struct AutoPlanner {
    candidates: Vec<FramePlan>,
    /// Moving average of each candidate's frame cost (ms), `None` until measured.
    cost_ms: Vec<Option<f64>>,
    /// The candidate run now, and how many frames it has run since it was (re)started.
    current: usize,
    run_frames: u32,
    /// The plan that is best so far, to come back to after a probe.
    best: usize,
    frames: u64,
    next_probe: usize,
}

impl AutoPlanner {
    /// A planner over the culling stages the scene offers, with the LOD cut on when `lod`
    /// (but for brute force, which draws everything at full detail).
    pub fn new(features: SceneFeatures, lod: bool) -> AutoPlanner {
        let base = FramePlan {
            frustum: true,
            quadtree: true,
            lod,
            ..FramePlan::NONE
        };
        let hzb = FramePlan { hzb: true, ..base };
        let occluders = FramePlan {
            occluders: true,
            ..hzb
        };
        let gated = FramePlan {
            occluder_gate: true,
            ..occluders
        };
        let mut candidates: Vec<FramePlan> = Vec::new();
        for plan in [FramePlan::NONE, base, hzb, occluders, gated] {
            let plan = plan.resolve(features);
            if !candidates.contains(&plan) {
                candidates.push(plan);
            }
        }
        AutoPlanner {
            cost_ms: vec![None; candidates.len()],
            candidates,
            current: 0,
            run_frames: 0,
            best: 0,
            frames: 0,
            next_probe: 0,
        }
    }

    /// The candidate plans, in ladder order.
    pub fn candidates(&self) -> &[FramePlan] {
        &self.candidates
    }

    /// The plan of the next frame.
    pub fn plan(&self) -> FramePlan {
        self.candidates[self.current]
    }

    /// Whether some candidate has not been measured yet (the first frames try each in turn).
    pub fn exploring(&self) -> bool {
        self.cost_ms.iter().any(Option::is_none)
    }

    /// The measured cost of each candidate so far (ms).
    pub fn costs_ms(&self) -> &[Option<f64>] {
        &self.cost_ms
    }

    /// Takes the report of the frame run with [`AutoPlanner::plan`] and picks the next plan.
    pub fn record(&mut self, report: &FrameReport) {
        self.frames += 1;
        self.run_frames += 1;
        if self.run_frames > 1
            && let Some(ms) = frame_cost_ms(report)
        {
            let slot = &mut self.cost_ms[self.current];
            *slot = Some(match *slot {
                Some(avg) => avg + SMOOTHING * (ms - avg),
                None => ms,
            });
        }
        // Still trying plans nobody has measured yet.
        if self.run_frames >= TRIAL_FRAMES
            && let Some(unmeasured) = self.cost_ms.iter().position(Option::is_none)
        {
            self.start(unmeasured);
            return;
        }
        if self.run_frames < TRIAL_FRAMES {
            return;
        }
        self.best = self.cheapest();
        if self.current != self.best {
            // A probe (or a plan that lost) ends: back to the best.
            self.start(self.best);
        } else if self.frames.is_multiple_of(PROBE_EVERY) && self.candidates.len() > 1 {
            let others: Vec<usize> = (0..self.candidates.len())
                .filter(|&i| i != self.best)
                .collect();
            let probe = others[self.next_probe % others.len()];
            self.next_probe += 1;
            self.start(probe);
        }
    }

    fn start(&mut self, candidate: usize) {
        self.current = candidate;
        self.run_frames = 0;
    }

    /// The candidate with the lowest cost, the current best kept unless another beats it by the
    /// switch margin.
    fn cheapest(&self) -> usize {
        let cost = |i: usize| self.cost_ms[i].unwrap_or(f64::INFINITY);
        let (mut pick, mut pick_cost) = (self.best, cost(self.best));
        for i in 0..self.candidates.len() {
            if cost(i) < pick_cost * SWITCH_MARGIN {
                (pick, pick_cost) = (i, cost(i));
            }
        }
        pick
    }
}

/// What a frame cost (ms): its wall time to GPU completion where the caller waited for it,
/// else the GPU time its timestamps measured, else its CPU time.
pub fn frame_cost_ms(report: &FrameReport) -> Option<f64> {
    if report.frame_ms > 0.0 {
        return Some(report.frame_ms);
    }
    report
        .gpu
        .total_ms()
        .map(|gpu| gpu.max(report.cpu_ms))
        .or((report.cpu_ms > 0.0).then_some(report.cpu_ms))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn report(frame_ms: f64) -> FrameReport {
        FrameReport {
            frame_ms,
            ..FrameReport::default()
        }
    }

    /// Runs `frames` frames where each plan costs `cost(plan)`; returns the plans run.
    fn simulate(
        planner: &mut AutoPlanner,
        frames: usize,
        cost: impl Fn(FramePlan) -> f64,
    ) -> Vec<FramePlan> {
        (0..frames)
            .map(|_| {
                let plan = planner.plan();
                planner.record(&report(cost(plan)));
                plan
            })
            .collect()
    }

    #[test]
    fn the_ladder_follows_what_the_scene_has() {
        assert_eq!(
            AutoPlanner::new(SceneFeatures::ALL, true)
                .candidates()
                .len(),
            5
        );
        // No occluders: brute force, CPU culling alone and the HZB frame.
        let plain = AutoPlanner::new(SceneFeatures::default(), true);
        assert_eq!(plain.candidates().len(), 3);
        assert_eq!(plain.candidates()[0], FramePlan::NONE);
        assert!(plain.candidates().iter().all(|p| !p.lod && !p.occluders));
    }

    #[test]
    fn settles_on_the_cheapest_plan_and_probes_the_others() {
        let mut planner = AutoPlanner::new(SceneFeatures::ALL, false);
        // Occlusion culling pays here: the gated plan is the cheapest.
        let cost = |p: FramePlan| match (p.hzb, p.occluders, p.occluder_gate) {
            (false, ..) => 40.0,
            (true, false, _) => 30.0,
            (true, true, false) => 25.0,
            (true, true, true) => 10.0,
        };
        let ran = simulate(&mut planner, 400, cost);
        let tail = &ran[40..];
        let gated = tail.iter().filter(|p| p.occluder_gate).count();
        assert!(
            gated as f64 > 0.9 * tail.len() as f64,
            "{gated} of {}",
            tail.len()
        );
        // Probes keep measuring the others.
        assert!(tail.iter().any(|p| !p.hzb));
        assert!(planner.costs_ms().iter().all(Option::is_some));
    }

    #[test]
    fn falls_back_to_brute_force_when_no_culling_pays() {
        let mut planner = AutoPlanner::new(SceneFeatures::ALL, true);
        // A small city seen from above: every culling stage costs more than it saves.
        let ran = simulate(&mut planner, 300, |p| {
            if p == FramePlan::NONE { 30.0 } else { 40.0 }
        });
        let brute = ran[20..].iter().filter(|&&p| p == FramePlan::NONE).count();
        assert!(brute > 260, "{brute} of {}", ran.len() - 20);
    }

    #[test]
    fn skips_occlusion_that_does_not_pay_and_follows_a_change() {
        let mut planner = AutoPlanner::new(SceneFeatures::ALL, false);
        // A software rasteriser: the pyramid costs more than it saves.
        let ran = simulate(&mut planner, 200, |p| if p.hzb { 60.0 } else { 20.0 });
        assert!(ran[20..].iter().filter(|p| !p.hzb).count() > 170);
        assert!(planner.costs_ms().iter().all(Option::is_some));
        // The view changes (street level, heavy occlusion): the probes find the HZB plans.
        let ran = simulate(&mut planner, 400, |p| if p.hzb { 5.0 } else { 50.0 });
        assert!(ran[200..].iter().filter(|p| p.hzb).count() > 180);
    }
}
