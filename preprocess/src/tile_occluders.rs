//! The tile jobs' occluder sets, gathered for the merge one tile file at a time (issue 17).
//!
//! A tile's buildings are scattered through the city's building order, so the city's set
//! (outcomes and occluders in building order) can only be put together once every tile is
//! in. Held in memory, the tiles' sets were the merge's peak (about a gigabyte at a million
//! buildings, beside the city and the trees); here each tile's occluders go to a scratch file
//! as the tile is read, each building's as one record, and only their places and outcomes
//! stay. [`TileOccluders::drain`] then reads the records back in building order, numbering
//! the occluders as one run does, and hands them on in batches (the pipeline spills them as
//! it spills the ones it builds).

use std::io::{BufWriter, Read, Seek, SeekFrom, Write};
use std::path::Path;

use citywalk_scenes::occluder::{Occluder, OccluderOutcome, OccluderSet};

use crate::pipeline::PreprocessError;

/// Occluders [`TileOccluders::drain`] gathers before handing them on (as the occluder stage's
/// own batches, about 40 MB).
const OCCLUDERS_PER_BATCH: usize = 1 << 16;

/// Where one building's occluders are in the scratch file, and its outcome (its range
/// counted in its tile's set until [`TileOccluders::drain`] renumbers it).
#[derive(Debug)]
struct Place {
    offset: u64,
    length: u32,
    outcome: OccluderOutcome,
}

/// The occluders of the tiles added so far (module documentation).
#[derive(Debug)]
pub struct TileOccluders {
    file: BufWriter<std::fs::File>,
    written: u64,
    /// Each building's place, `None` until a tile gives it.
    places: Vec<Option<Place>>,
    given: usize,
}

/// Why a tile's set cannot be added.
#[derive(Debug, thiserror::Error)]
pub enum TileOccluderError {
    #[error("its occluders are for building {0}, which the city does not have")]
    UnknownBuilding(u32),
    #[error("building {0}'s occluders are in two tiles")]
    GivenTwice(u32),
    #[error("building {0}'s occluder range {1:?} is not where its set holds its occluders")]
    BadRange(u32, std::ops::Range<u32>),
    #[error("cannot write the scratch file of the tiles' occluders: {0}")]
    Scratch(#[from] std::io::Error),
}

impl TileOccluders {
    /// Nothing gathered yet for a city of `buildings` buildings; the scratch file in `dir`
    /// (removed by the system once dropped).
    pub fn new_in(dir: &Path, buildings: usize) -> std::io::Result<TileOccluders> {
        let file = tempfile::tempfile_in(dir)?;
        Ok(TileOccluders {
            file: BufWriter::with_capacity(1 << 20, file),
            written: 0,
            places: (0..buildings).map(|_| None).collect(),
            given: 0,
        })
    }

    /// Adds one tile's set (outcomes ascending by building, occluders in their order, as
    /// [`crate::occluders::build_occluders_of`] makes it).
    pub fn add(&mut self, set: OccluderSet) -> Result<(), TileOccluderError> {
        let mut occluders = set.occluders.into_iter();
        let mut taken = 0u32;
        for outcome in set.per_building {
            let b = outcome.building.0;
            let range = outcome.occluder_range.clone();
            if range.start != taken || range.end < taken {
                return Err(TileOccluderError::BadRange(b, range));
            }
            let count = (range.end - taken) as usize;
            taken = range.end;
            let own: Vec<Occluder> = occluders.by_ref().take(count).collect();
            if own.len() != count {
                return Err(TileOccluderError::BadRange(b, range));
            }
            let slot = self
                .places
                .get_mut(b as usize)
                .ok_or(TileOccluderError::UnknownBuilding(b))?;
            if slot.is_some() {
                return Err(TileOccluderError::GivenTwice(b));
            }
            let bytes = postcard::to_stdvec(&own)
                .map_err(|e| std::io::Error::other(format!("cannot encode: {e}")))?;
            self.file.write_all(&bytes)?;
            *slot = Some(Place {
                offset: self.written,
                length: bytes.len() as u32,
                outcome,
            });
            self.written += bytes.len() as u64;
            self.given += 1;
        }
        Ok(())
    }

    /// Whether every building of the city has its outcome (each was given once: [`Self::add`]
    /// refuses a second).
    pub fn covers_every_building(&self) -> bool {
        self.given == self.places.len()
    }

    /// Hands the occluders on to `take` in building order, in batches, and returns the
    /// outcomes, numbered as in the city's set.
    pub fn drain(
        self,
        take: &mut dyn FnMut(&[Occluder]) -> Result<(), PreprocessError>,
    ) -> Result<Vec<OccluderOutcome>, PreprocessError> {
        let scratch = |e: std::io::Error| {
            PreprocessError::Scratch(std::io::Error::new(
                e.kind(),
                format!("the tiles' occluders: {e}"),
            ))
        };
        let mut file = self
            .file
            .into_inner()
            .map_err(|e| scratch(e.into_error()))?;
        let mut outcomes = Vec::with_capacity(self.places.len());
        let mut batch: Vec<Occluder> = Vec::new();
        let mut numbered = 0u32;
        let mut bytes = Vec::new();
        for (b, place) in self.places.into_iter().enumerate() {
            let Some(Place {
                offset,
                length,
                mut outcome,
            }) = place
            else {
                let missing = format!("building {b} is in no tile's occluder set");
                return Err(scratch(std::io::Error::other(missing)));
            };
            bytes.resize(length as usize, 0);
            file.seek(SeekFrom::Start(offset)).map_err(scratch)?;
            file.read_exact(&mut bytes).map_err(scratch)?;
            let own: Vec<Occluder> = postcard::from_bytes(&bytes)
                .map_err(|e| scratch(std::io::Error::other(format!("cannot decode: {e}"))))?;
            let start = numbered;
            numbered += own.len() as u32;
            outcome.occluder_range = start..numbered;
            outcomes.push(outcome);
            batch.extend(own);
            if batch.len() >= OCCLUDERS_PER_BATCH {
                take(&batch)?;
                batch.clear();
            }
        }
        take(&batch)?;
        Ok(outcomes)
    }

    /// The city's set, whole in memory.
    pub fn into_set(self) -> Result<OccluderSet, PreprocessError> {
        let mut occluders = Vec::new();
        let per_building = self.drain(&mut |batch| {
            occluders.extend_from_slice(batch);
            Ok(())
        })?;
        Ok(OccluderSet {
            occluders,
            per_building,
        })
    }
}
