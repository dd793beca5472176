//! Which texture page views are resident in the GPU's layers: the least recently drawn view
//! gives its layer to one a drawn cluster needs. Bookkeeping only (no GPU), so that the policy
//! is tested on its own; [`super::ClusterTexturing`] carries out what it decides.
//!
//! A page view is the unit of upload and eviction: per frame a textured cluster needs its
//! page's side view and the one roof view closest to the look vector (Chang et al. 2008 §7),
//! so a page's other four views are never resident for nothing.

use std::collections::HashMap;

/// A page and one of its views (the index into `AtlasView::ALL`).
pub type PageView = (u32, u8);

/// A load to start: decode `view` into `layer`, which `evicted` held until now.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Load {
    pub view: PageView,
    pub layer: u32,
    pub evicted: Option<PageView>,
}

#[derive(Debug, Clone, Copy, Default)]
struct Layer {
    view: Option<PageView>,
    /// The last frame a drawn cluster needed it.
    last_used: u64,
    /// Its texels are uploaded (a loading layer is never evicted).
    ready: bool,
}

/// Layers and the page views in them.
#[derive(Debug, Clone)]
pub struct Residency {
    layers: Vec<Layer>,
    by_view: HashMap<PageView, u32>,
    in_flight: usize,
    max_in_flight: usize,
    /// Views wanted in the last frame that found no layer to take (all needed that frame).
    pub starved: usize,
    /// Page views that gave their layer to another, in all.
    pub evictions: u64,
}

impl Residency {
    /// `layers` layers, at most `max_in_flight` loads outstanding at once (so that a jump to a
    /// new part of the city queues a few decodes per frame, not hundreds).
    pub fn new(layers: u32, max_in_flight: usize) -> Residency {
        Residency {
            layers: vec![Layer::default(); layers as usize],
            by_view: HashMap::new(),
            in_flight: 0,
            max_in_flight: max_in_flight.max(1),
            starved: 0,
            evictions: 0,
        }
    }

    /// Marks `views` as needed in `frame` (frames count up) and returns the loads to start
    /// for those not resident: each into a free layer or the least recently used one that
    /// `frame` does not need.
    pub fn want(&mut self, views: impl IntoIterator<Item = PageView>, frame: u64) -> Vec<Load> {
        let mut loads = Vec::new();
        self.starved = 0;
        let mut missing = Vec::new();
        for view in views {
            match self.by_view.get(&view) {
                Some(&layer) => self.layers[layer as usize].last_used = frame,
                None if !missing.contains(&view) => missing.push(view),
                None => {}
            }
        }
        for view in missing {
            if self.in_flight >= self.max_in_flight {
                break;
            }
            let Some(layer) = self.victim(frame) else {
                self.starved += 1;
                continue;
            };
            let slot = &mut self.layers[layer as usize];
            let evicted = slot.view.replace(view);
            *slot = Layer {
                view: Some(view),
                last_used: frame,
                ready: false,
            };
            if let Some(old) = evicted {
                self.by_view.remove(&old);
                self.evictions += 1;
            }
            self.by_view.insert(view, layer);
            self.in_flight += 1;
            loads.push(Load {
                view,
                layer,
                evicted,
            });
        }
        loads
    }

    /// A free layer, else the ready one least recently used before `frame`.
    fn victim(&self, frame: u64) -> Option<u32> {
        if let Some(free) = self.layers.iter().position(|l| l.view.is_none()) {
            return Some(free as u32);
        }
        self.layers
            .iter()
            .enumerate()
            .filter(|(_, l)| l.ready && l.last_used < frame)
            .min_by_key(|(_, l)| l.last_used)
            .map(|(i, _)| i as u32)
    }

    /// `view`'s load finished: its layer, now ready (`None` if it is no longer wanted).
    pub fn loaded(&mut self, view: PageView) -> Option<u32> {
        self.in_flight = self.in_flight.saturating_sub(1);
        let layer = *self.by_view.get(&view)?;
        self.layers[layer as usize].ready = true;
        Some(layer)
    }

    /// `view`'s load failed: its layer is free again.
    pub fn failed(&mut self, view: PageView) {
        self.in_flight = self.in_flight.saturating_sub(1);
        if let Some(layer) = self.by_view.remove(&view) {
            self.layers[layer as usize] = Layer::default();
        }
    }

    /// Loads started and not finished.
    pub fn in_flight(&self) -> usize {
        self.in_flight
    }

    /// Layers in all.
    pub fn layers(&self) -> usize {
        self.layers.len()
    }

    /// Page views whose texels are on the GPU.
    pub fn resident(&self) -> usize {
        self.layers.iter().filter(|l| l.ready).count()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn finish(r: &mut Residency, loads: &[Load]) {
        for load in loads {
            assert_eq!(r.loaded(load.view), Some(load.layer));
        }
    }

    #[test]
    fn views_fill_free_layers_then_evict_the_least_recently_drawn() {
        let mut r = Residency::new(3, 8);
        let loads = r.want([(0, 0), (0, 1), (0, 0)], 1);
        assert_eq!(loads.len(), 2, "a view wanted twice loads once");
        assert!(loads.iter().all(|l| l.evicted.is_none()));
        finish(&mut r, &loads);
        let loads = r.want([(1, 0)], 2);
        assert_eq!(
            loads,
            [Load {
                view: (1, 0),
                layer: 2,
                evicted: None
            }]
        );
        finish(&mut r, &loads);
        // Frame 3 needs (0, 1) and a new view: (0, 0), last drawn in frame 1, goes.
        let loads = r.want([(0, 1), (2, 0)], 3);
        assert_eq!(
            loads,
            [Load {
                view: (2, 0),
                layer: 0,
                evicted: Some((0, 0))
            }]
        );
        finish(&mut r, &loads);
        assert!(
            r.want([(0, 1), (2, 0), (1, 0)], 4).is_empty(),
            "all resident"
        );
        assert_eq!(r.resident(), 3);
    }

    #[test]
    fn nothing_a_frame_needs_is_evicted_for_it_and_loading_layers_stay() {
        let mut r = Residency::new(2, 8);
        let loads = r.want([(0, 0), (1, 0), (2, 0)], 1);
        assert_eq!(loads.len(), 2);
        assert_eq!(r.starved, 1, "the third has no layer this frame");
        // Still loading: never a victim, even when the next frame needs something else.
        assert!(r.want([(3, 0)], 2).is_empty());
        finish(&mut r, &loads);
        let loads = r.want([(3, 0)], 3);
        assert_eq!(loads.len(), 1);
        assert!(loads[0].evicted.is_some());
    }

    #[test]
    fn loads_in_flight_are_bounded_and_a_failed_load_frees_its_layer() {
        let mut r = Residency::new(8, 2);
        let loads = r.want((0..5).map(|p| (p, 0)), 1);
        assert_eq!(loads.len(), 2);
        assert_eq!(r.in_flight(), 2);
        r.failed(loads[0].view);
        assert_eq!(r.loaded(loads[1].view), Some(loads[1].layer));
        assert_eq!(r.in_flight(), 0);
        assert_eq!(r.resident(), 1);
        let again = r.want((0..5).map(|p| (p, 0)), 2);
        assert_eq!(again.len(), 2);
        assert_eq!(again[0].view, (0, 0), "the failed view is asked for again");
    }
}
