//! Which buildings were visible in the last frame: the early pass's set.

use crate::hzb::cull::CULL_VISIBLE;

/// Per-building "visible last frame" flags, carried from frame to frame.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Visibility {
    visible: Vec<bool>,
}

impl Visibility {
    /// Nothing visible (the state at the start of a camera path).
    pub fn reset(&mut self) {
        self.visible.clear();
    }

    /// Whether building `id` was visible in the last frame.
    pub fn is_visible(&self, id: u32) -> bool {
        self.visible.get(id as usize).copied().unwrap_or(false)
    }

    /// The visible buildings, in id order.
    pub fn visible_ids(&self) -> Vec<u32> {
        (0..self.visible.len() as u32)
            .filter(|&b| self.visible[b as usize])
            .collect()
    }

    /// Sets the flags from a cull status (`CULL_VISIBLE` = visible).
    pub(super) fn update(&mut self, status: &[u32]) {
        self.visible.clear();
        self.visible
            .extend(status.iter().map(|&s| s == CULL_VISIBLE));
    }

    /// Sets the flags to `visible` (one per building): for a frame whose candidates are not
    /// the buildings themselves (a LOD cut), the caller maps candidates to buildings.
    pub(super) fn set(&mut self, visible: Vec<bool>) {
        self.visible = visible;
    }

    /// Adjusts to a scene of `building_count` buildings: a visibility of another size belongs
    /// to another scene and is dropped.
    pub(super) fn fit(&mut self, building_count: usize) {
        if self.visible.len() != building_count {
            self.visible.clear();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::hzb::cull::{CULL_FRUSTUM_OUTSIDE, CULL_OCCLUDED};

    #[test]
    fn visibility_follows_the_status_and_resets_for_another_scene() {
        let mut v = Visibility::default();
        assert!(!v.is_visible(0));
        v.fit(3);
        v.update(&[CULL_VISIBLE, CULL_OCCLUDED, CULL_VISIBLE]);
        assert_eq!(v.visible_ids(), vec![0, 2]);
        assert!(v.is_visible(2) && !v.is_visible(1) && !v.is_visible(7));
        v.fit(3);
        assert_eq!(v.visible_ids(), vec![0, 2]);
        // Another building count: another scene, nothing carried over.
        v.fit(4);
        assert!(v.visible_ids().is_empty());
        v.update(&[CULL_FRUSTUM_OUTSIDE, CULL_VISIBLE, 0, 0]);
        v.reset();
        assert!(!v.is_visible(1));
    }
}
