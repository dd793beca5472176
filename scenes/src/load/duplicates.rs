//! Inputs and buildings read twice when several inputs are merged ([`super::load_cities`]).
//!
//! * The same file given twice (by any path: canonical paths are compared) is read once.
//! * A file already read as part of an earlier input (a tile of a tileset given after the
//!   tileset) is not read again.
//! * A building whose source id was already loaded from an input of the same format (a tile
//!   given before its tileset, overlapping OSM extracts, a way repeated in one file) is dropped
//!   when it is the same building (footprint bounds and heights within [`SAME_TOLERANCE_M`]);
//!   an id shared by two different buildings keeps both.
//!
//! Every skip, drop and shared id is a [`LoadWarning`] naming the file and the id: nothing is
//! dropped silently. A dropped duplicate no longer counts as found or loaded.

use std::collections::HashMap;
use std::ops::Range;
use std::path::{Path, PathBuf};

use geo::BoundingRect;

use super::InputFormat;
use crate::city::{Building, City, HeightSource};
use crate::report::LoadWarning;

/// Two buildings with one source id are the same when their footprint bounds, base and top
/// agree within this (metres): both copies come from the same source coordinates, moved into
/// the frame by the same transforms, so they agree to rounding.
const SAME_TOLERANCE_M: f64 = 0.01;

/// The inputs given and the files they read, by canonical path.
#[derive(Debug, Default)]
pub(super) struct ReadFiles {
    /// Canonical path → the input that read it (the file itself, or a tileset holding it).
    read_by: HashMap<PathBuf, PathBuf>,
}

impl ReadFiles {
    /// Why `input` is not to be read (already given, or already read as part of an earlier
    /// input), as a warning; `None` to read it. A path that cannot be resolved is read (and
    /// its load then names the problem).
    pub(super) fn skip(&self, input: &Path) -> Option<LoadWarning> {
        let canonical = std::fs::canonicalize(input).ok()?;
        let by = self.read_by.get(&canonical)?;
        let message = if std::fs::canonicalize(by).ok().as_ref() == Some(&canonical) {
            format!(
                "the same file as the input {} (given twice): read once",
                by.display()
            )
        } else {
            format!(
                "already read as part of the input {}: not read again",
                by.display()
            )
        };
        Some(LoadWarning {
            file: input.to_path_buf(),
            source_id: String::new(),
            message,
        })
    }

    /// Records that `input` was read, with every file its load read.
    pub(super) fn add(&mut self, input: &Path, files: &[PathBuf]) {
        for file in std::iter::once(input).chain(files.iter().map(PathBuf::as_path)) {
            if let Ok(canonical) = std::fs::canonicalize(file) {
                self.read_by
                    .entry(canonical)
                    .or_insert_with(|| input.to_path_buf());
            }
        }
    }
}

/// The buildings one input added to the merged city.
#[derive(Debug, Clone)]
pub(super) struct InputSpan {
    pub file: PathBuf,
    pub format: InputFormat,
    pub buildings: Range<usize>,
}

/// Drops the buildings that repeat an earlier building of the same format and source id (see
/// the module documentation), with a warning for each, and warns of ids shared by different
/// buildings. Ids are left for the caller to renumber.
pub(super) fn drop_duplicate_buildings(city: &mut City, spans: &[InputSpan]) {
    // The buildings kept so far under each (format, source id), with their input.
    let mut kept: HashMap<(InputFormat, &str), Vec<(usize, &Path)>> = HashMap::new();
    let mut drop = vec![false; city.buildings.len()];
    let mut warnings = Vec::new();
    for span in spans {
        for i in span.buildings.clone() {
            let Some(b) = city.buildings.get(i) else {
                continue;
            };
            let earlier = kept.entry((span.format, b.source_id.as_str())).or_default();
            let place = |file: &Path| {
                if file == span.file {
                    "earlier in this file".to_string()
                } else {
                    format!("in {}", file.display())
                }
            };
            let same = earlier
                .iter()
                .find(|(j, _)| city.buildings.get(*j).is_some_and(|e| same_building(e, b)));
            let message = match (same, earlier.first()) {
                (Some(&(_, file)), _) => {
                    drop[i] = true;
                    format!(
                        "the same building as the one with this id {}: duplicate dropped",
                        place(file)
                    )
                }
                (None, Some(&(_, file))) => {
                    earlier.push((i, &span.file));
                    format!(
                        "this id is also used by a different building {}: both kept",
                        place(file)
                    )
                }
                (None, None) => {
                    earlier.push((i, &span.file));
                    continue;
                }
            };
            let warning = LoadWarning {
                file: span.file.clone(),
                source_id: b.source_id.clone(),
                message,
            };
            tracing::warn!("{warning}");
            warnings.push(warning);
        }
    }
    let report = &mut city.report;
    for (b, _) in city.buildings.iter().zip(&drop).filter(|(_, d)| **d) {
        report.buildings_found = report.buildings_found.saturating_sub(1);
        report.buildings_loaded = report.buildings_loaded.saturating_sub(1);
        match b.height_source {
            HeightSource::Tagged => {
                report.buildings_with_height = report.buildings_with_height.saturating_sub(1);
            }
            HeightSource::Estimated => {
                report.buildings_estimated_height =
                    report.buildings_estimated_height.saturating_sub(1);
            }
            HeightSource::Levels | HeightSource::Geometry => {}
        }
    }
    report.warnings.extend(warnings);
    let mut keep = drop.iter().map(|d| !d);
    city.buildings.retain(|_| keep.next().unwrap_or(true));
}

/// Whether `a` and `b` are one building read twice (see [`SAME_TOLERANCE_M`]).
fn same_building(a: &Building, b: &Building) -> bool {
    let close = |x: f64, y: f64| (x - y).abs() <= SAME_TOLERANCE_M;
    let heights = close(f64::from(a.base_m), f64::from(b.base_m))
        && close(f64::from(a.top_m), f64::from(b.top_m));
    match (a.footprint.bounding_rect(), b.footprint.bounding_rect()) {
        (Some(ra), Some(rb)) => {
            heights
                && close(ra.min().x, rb.min().x)
                && close(ra.min().y, rb.min().y)
                && close(ra.max().x, rb.max().x)
                && close(ra.max().y, rb.max().y)
        }
        _ => false,
    }
}
