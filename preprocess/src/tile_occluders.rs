//! The tile jobs' occluder sets, gathered for the merge one tile file at a time (issue 17).
//!
//! A tile's buildings are scattered through the city's building order, so the city's set
//! (outcomes and occluders in building order) can only be put together once every tile is
//! in. Held in memory, the tiles' sets were the merge's peak (about a gigabyte at a million
//! buildings, beside the city and the trees); here each tile's occluders go to a scratch file
//! as the tile is read, each building's as one record, and only the records' lengths and the
//! outcomes stay. [`TileOccluders::drain`] then reads the records back in building order,
//! numbering the occluders as one run does, and hands them on in batches (the pipeline spills
//! them as it spills the ones it builds).

use std::io::{BufWriter, Read, Seek, SeekFrom, Write};
use std::ops::Range;
use std::path::{Path, PathBuf};

use citywalk_scenes::occluder::{Occluder, OccluderOutcome, OccluderSet};

use crate::occluders::OCCLUDERS_PER_TAKE;
use crate::pipeline::PreprocessError;

/// Bytes read from the scratch file at a time for one tile: a tile's records lie together
/// and are read back in their order, so each tile is a sequential stream.
const READ_BYTES_PER_TILE: usize = 256 << 10;

/// One building's record: which tile wrote it, its length in the scratch file, and its
/// outcome (its range counted in its tile's set until [`TileOccluders::drain`] renumbers it).
#[derive(Debug)]
struct Record {
    tile: u32,
    length: u32,
    outcome: OccluderOutcome,
}

/// The occluders of the tiles added so far (module documentation).
#[derive(Debug)]
pub struct TileOccluders {
    dir: PathBuf,
    file: BufWriter<std::fs::File>,
    written: u64,
    /// Where each tile's records begin in the scratch file, in the order the tiles came.
    tile_starts: Vec<u64>,
    /// Each building's record, `None` until a tile gives it.
    records: Vec<Option<Record>>,
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
    BadRange(u32, Range<u32>),
    #[error("building {0}'s outcome comes after a later building's")]
    OutOfOrder(u32),
    #[error("its set holds {0} occluders that no building's range names")]
    Unclaimed(usize),
    #[error("the scratch file of the tiles' occluders in {0}: {1}")]
    Scratch(String, std::io::Error),
}

impl TileOccluders {
    /// Nothing gathered yet for a city of `buildings` buildings; the scratch file in `dir`
    /// (unnamed: it goes when dropped).
    pub fn new_in(dir: &Path, buildings: usize) -> std::io::Result<TileOccluders> {
        let file = tempfile::tempfile_in(dir)?;
        Ok(TileOccluders {
            dir: dir.to_path_buf(),
            file: BufWriter::with_capacity(1 << 20, file),
            written: 0,
            tile_starts: Vec::new(),
            records: (0..buildings).map(|_| None).collect(),
            given: 0,
        })
    }

    /// Adds one tile's set (outcomes ascending by building and in the order of their
    /// occluders, each naming its own; [`crate::occluders::build_occluders_of`] makes it so:
    /// a tile's records are read back in building order from where they were written).
    pub fn add(&mut self, set: &OccluderSet) -> Result<(), TileOccluderError> {
        let tile = self.tile_starts.len() as u32;
        self.tile_starts.push(self.written);
        let mut taken = 0u32;
        let mut encoded = Vec::new();
        let mut previous = None;
        for outcome in &set.per_building {
            let b = outcome.building.0;
            if previous.is_some_and(|p| p >= b) {
                return Err(TileOccluderError::OutOfOrder(b));
            }
            previous = Some(b);
            let range = outcome.occluder_range.clone();
            let own = (range.start == taken)
                .then(|| set.occluders.get(range.start as usize..range.end as usize))
                .flatten()
                .filter(|own| own.iter().all(|o| o.building == outcome.building))
                .ok_or_else(|| TileOccluderError::BadRange(b, range.clone()))?;
            taken = range.end;
            let record = self
                .records
                .get_mut(b as usize)
                .ok_or(TileOccluderError::UnknownBuilding(b))?;
            if record.is_some() {
                return Err(TileOccluderError::GivenTwice(b));
            }
            encoded.clear();
            let scratch = |e: std::io::Error| scratch_error(&self.dir, e);
            encoded = postcard::to_extend(own, encoded)
                .map_err(|e| scratch(std::io::Error::other(format!("cannot encode: {e}"))))?;
            let length = u32::try_from(encoded.len())
                .map_err(|_| scratch(std::io::Error::other("a building's occluders over 4 GiB")))?;
            self.file.write_all(&encoded).map_err(scratch)?;
            *record = Some(Record {
                tile,
                length,
                outcome: outcome.clone(),
            });
            self.written += u64::from(length);
            self.given += 1;
        }
        if taken as usize != set.occluders.len() {
            return Err(TileOccluderError::Unclaimed(
                set.occluders.len().saturating_sub(taken as usize),
            ));
        }
        Ok(())
    }

    /// Whether every building of the city has its outcome (each was given once: [`Self::add`]
    /// refuses a second).
    pub fn covers_every_building(&self) -> bool {
        self.given == self.records.len()
    }

    /// Hands the occluders on to `take` in building order, in batches of about
    /// [`OCCLUDERS_PER_TAKE`], and returns the outcomes, numbered as in the city's set.
    pub fn drain(
        self,
        take: &mut dyn FnMut(&[Occluder]) -> Result<(), PreprocessError>,
    ) -> Result<Vec<OccluderOutcome>, PreprocessError> {
        self.drain_in_batches(OCCLUDERS_PER_TAKE, take)
    }

    fn drain_in_batches(
        self,
        per_batch: usize,
        take: &mut dyn FnMut(&[Occluder]) -> Result<(), PreprocessError>,
    ) -> Result<Vec<OccluderOutcome>, PreprocessError> {
        let dir = self.dir;
        let scratch = |e: std::io::Error| {
            PreprocessError::Scratch(std::io::Error::new(
                e.kind(),
                scratch_error(&dir, e).to_string(),
            ))
        };
        let mut file = self
            .file
            .into_inner()
            .map_err(|e| scratch(e.into_error()))?;
        let mut ends = self.tile_starts[1..].to_vec();
        ends.push(self.written);
        let mut streams: Vec<TileStream> = self
            .tile_starts
            .iter()
            .zip(ends)
            .map(|(&start, end)| TileStream::new(start..end))
            .collect();
        let mut outcomes = Vec::with_capacity(self.records.len());
        let mut batch: Vec<Occluder> = Vec::new();
        let mut numbered = 0u32;
        for (b, record) in self.records.into_iter().enumerate() {
            let Some(Record {
                tile,
                length,
                mut outcome,
            }) = record
            else {
                let missing = format!("building {b} is in no tile's occluder set");
                return Err(scratch(std::io::Error::other(missing)));
            };
            let bytes = streams[tile as usize]
                .next(&mut file, length as usize)
                .map_err(scratch)?;
            let own: Vec<Occluder> = postcard::from_bytes(bytes)
                .map_err(|e| scratch(std::io::Error::other(format!("cannot decode: {e}"))))?;
            let start = numbered;
            numbered = u32::try_from(own.len())
                .ok()
                .and_then(|n| numbered.checked_add(n))
                .ok_or_else(|| scratch(std::io::Error::other("over 2^32 occluders")))?;
            outcome.occluder_range = start..numbered;
            outcomes.push(outcome);
            batch.extend(own);
            if batch.len() >= per_batch {
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

/// A scratch-file failure, naming the folder.
fn scratch_error(dir: &Path, e: std::io::Error) -> TileOccluderError {
    TileOccluderError::Scratch(dir.display().to_string(), e)
}

/// One tile's records, read back in their order through a buffer of their own.
struct TileStream {
    /// What of the tile's stretch of the file is not yet in the buffer.
    unread: Range<u64>,
    buffer: Vec<u8>,
    /// Where the next record begins in the buffer.
    at: usize,
}

impl TileStream {
    fn new(stretch: Range<u64>) -> TileStream {
        TileStream {
            unread: stretch,
            buffer: Vec::new(),
            at: 0,
        }
    }

    /// The tile's next record, of `length` bytes.
    fn next(&mut self, file: &mut std::fs::File, length: usize) -> std::io::Result<&[u8]> {
        if self.buffer.len() - self.at < length {
            self.buffer.drain(..self.at);
            self.at = 0;
            let left = self.unread.end - self.unread.start;
            let wanted = (length - self.buffer.len()).max(READ_BYTES_PER_TILE);
            let reading = left.min(wanted as u64) as usize;
            let have = self.buffer.len();
            self.buffer.resize(have + reading, 0);
            file.seek(SeekFrom::Start(self.unread.start))?;
            file.read_exact(&mut self.buffer[have..])?;
            self.unread.start += reading as u64;
            if self.buffer.len() < length {
                return Err(std::io::Error::other(
                    "a record runs past its tile's stretch",
                ));
            }
        }
        let record = &self.buffer[self.at..self.at + length];
        self.at += length;
        Ok(record)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::occluders::{OccluderParams, build_occluders};

    fn city_set() -> OccluderSet {
        let city = citywalk_scenes::generate::generate_city(
            &citywalk_scenes::generate::GenerateParams::new(300, 7),
        )
        .expect("generated city");
        build_occluders(&city, &OccluderParams::default())
    }

    /// The part of `set` for the buildings `keep` picks, as a tile job makes it.
    fn part_of(set: &OccluderSet, keep: impl Fn(usize) -> bool) -> OccluderSet {
        let mut part = OccluderSet::default();
        for outcome in set.per_building.iter().filter(|o| keep(o.building.index())) {
            let start = part.occluders.len() as u32;
            part.occluders
                .extend_from_slice(set.occluders_of(outcome.building));
            let mut outcome = outcome.clone();
            outcome.occluder_range = start..part.occluders.len() as u32;
            part.per_building.push(outcome);
        }
        part
    }

    /// Three interleaved tiles, added in any order and drained in small batches, give the
    /// city's set back; every batch but the last is full.
    #[test]
    fn tiles_drained_in_building_order_are_the_citys_set() {
        let set = city_set();
        let dir = tempfile::tempdir().expect("temp dir");
        let mut tiles = TileOccluders::new_in(dir.path(), set.per_building.len()).expect("new");
        for residue in [2, 0, 1] {
            tiles
                .add(&part_of(&set, |b| b % 3 == residue))
                .expect("add");
        }
        assert!(tiles.covers_every_building());
        let mut occluders = Vec::new();
        let mut batches = Vec::new();
        let per_building = tiles
            .drain_in_batches(50, &mut |batch| {
                batches.push(batch.len());
                occluders.extend_from_slice(batch);
                Ok(())
            })
            .expect("drain");
        assert!(batches.len() > 2, "{batches:?}");
        let (last, full) = batches.split_last().expect("batches");
        assert!(full.iter().all(|&n| n >= 50) && *last < 50, "{batches:?}");
        assert!(
            OccluderSet {
                occluders,
                per_building
            } == set
        );
    }

    #[test]
    fn bad_tile_sets_are_refused() {
        let set = city_set();
        let n = set.per_building.len();
        let dir = tempfile::tempdir().expect("temp dir");
        let new = || TileOccluders::new_in(dir.path(), n).expect("new");
        let with_occluders = set
            .per_building
            .iter()
            .position(|o| o.occluder_range.len() > 1)
            .expect("a building with two occluders");

        let mut shifted = set.clone();
        shifted.per_building[with_occluders].occluder_range.end -= 1;
        let err = new().add(&shifted).expect_err("a gap");
        assert!(matches!(err, TileOccluderError::BadRange(..)), "{err}");

        let mut extra = set.clone();
        extra.occluders.push(extra.occluders[0].clone());
        let err = new().add(&extra).expect_err("an occluder no range names");
        assert!(matches!(err, TileOccluderError::Unclaimed(1)), "{err}");

        let mut stranger = set.clone();
        stranger.per_building[0].building = citywalk_scenes::BuildingId(n as u32);
        stranger.occluders[..stranger.per_building[0].occluder_range.end as usize]
            .iter_mut()
            .for_each(|o| o.building = citywalk_scenes::BuildingId(n as u32));
        let err = new().add(&stranger).expect_err("a building the city lacks");
        assert!(
            matches!(err, TileOccluderError::UnknownBuilding(_)),
            "{err}"
        );

        // Buildings 1 then 0, each with its own occluders in that order.
        let mut swapped = part_of(&set, |b| b == 1);
        let zero = part_of(&set, |b| b == 0);
        let shift = swapped.occluders.len() as u32;
        let mut outcome = zero.per_building[0].clone();
        outcome.occluder_range =
            outcome.occluder_range.start + shift..outcome.occluder_range.end + shift;
        swapped.per_building.push(outcome);
        swapped.occluders.extend(zero.occluders);
        let err = new().add(&swapped).expect_err("out of building order");
        assert!(matches!(err, TileOccluderError::OutOfOrder(0)), "{err}");

        let mut tiles = new();
        tiles.add(&part_of(&set, |b| b < 10)).expect("add");
        let err = tiles
            .add(&part_of(&set, |b| b < 20))
            .expect_err("given twice");
        assert!(matches!(err, TileOccluderError::GivenTwice(0)), "{err}");
        assert!(!tiles.covers_every_building());
    }
}
