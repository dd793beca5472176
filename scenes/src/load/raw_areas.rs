//! The raw areas a reader hands to the assembly, in input order, kept in the chunks they were
//! read in. Appending chunks moves them instead of copying every area into one array (which,
//! sized once or grown by doubling, held each area twice at the end of a parse: 0.3 GB at a
//! million buildings), and the assembly takes the chunks one at a time, so a chunk's raw areas
//! are freed as its assembled buildings are made instead of both forms being held for the
//! whole city (issue 17: the load's peak is the peak of every preprocessing route).

use std::fmt;

use super::assemble::RawArea;

/// Areas a chunk holds at most when areas are pushed one at a time.
const AREAS_PER_CHUNK: usize = 1024;

/// Raw areas in input order, in chunks; no chunk is empty.
#[derive(Default)]
pub(crate) struct RawAreas {
    chunks: Vec<Vec<RawArea>>,
    len: usize,
}

impl RawAreas {
    /// Appends one area, in a new chunk when the last one is full.
    pub fn push(&mut self, area: RawArea) {
        match self.chunks.last_mut() {
            Some(last) if last.len() < AREAS_PER_CHUNK => last.push(area),
            _ => {
                let mut chunk = Vec::with_capacity(AREAS_PER_CHUNK);
                chunk.push(area);
                self.chunks.push(chunk);
            }
        }
        self.len += 1;
    }

    /// Appends `next`'s areas after these, moving its chunks.
    pub fn append(&mut self, next: RawAreas) {
        self.len += next.len;
        self.chunks.extend(next.chunks);
    }

    pub fn len(&self) -> usize {
        self.len
    }

    pub fn iter(&self) -> impl Iterator<Item = &RawArea> {
        self.chunks.iter().flatten()
    }

    /// The chunks, in order, each of at least one area.
    pub fn into_chunks(self) -> Vec<Vec<RawArea>> {
        self.chunks
    }
}

impl FromIterator<RawArea> for RawAreas {
    fn from_iter<I: IntoIterator<Item = RawArea>>(areas: I) -> RawAreas {
        let mut raw = RawAreas::default();
        for area in areas {
            raw.push(area);
        }
        raw
    }
}

/// The areas as one list: how they were chunked is no part of what was read.
impl fmt::Debug for RawAreas {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_list().entries(self.iter()).finish()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::load::assemble::AreaKind;

    fn area(i: usize) -> RawArea {
        RawArea {
            source_id: format!("way/{i}"),
            kind: AreaKind::Building,
            polygons: Ok(Vec::new()),
            tags: Default::default(),
            heights: Default::default(),
            link_ids: Vec::new(),
            part_of: None,
        }
    }

    fn ids(raw: &RawAreas) -> Vec<String> {
        raw.iter().map(|a| a.source_id.clone()).collect()
    }

    #[test]
    fn pushed_and_appended_areas_keep_their_order_in_chunks_none_empty() {
        let n = 3 * AREAS_PER_CHUNK + 5;
        let pushed: RawAreas = (0..n).map(area).collect();
        assert_eq!(pushed.len(), n);
        assert_eq!(pushed.chunks.len(), 4);
        let mut appended = RawAreas::default();
        // Chunks of every size, an empty one included, as the parallel parse appends them.
        for range in [0..1, 1..1, 1..700, 700..n] {
            appended.append(range.map(area).collect());
        }
        assert_eq!(appended.len(), n);
        assert_eq!(ids(&appended), ids(&pushed));
        assert_eq!(format!("{appended:?}"), format!("{pushed:?}"));
        let chunks = appended.into_chunks();
        assert!(chunks.iter().all(|c| !c.is_empty()));
        assert_eq!(chunks.iter().map(Vec::len).sum::<usize>(), n);
    }
}
