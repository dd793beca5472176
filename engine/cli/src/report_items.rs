//! Every rejected building and load warning with its file, source id and reason, for the
//! summaries of `preprocess` and `inspect` (text and `--json`); the counts alone do not say
//! which building to look at.

use citywalk_scenes::LoadReport;
use serde::Serialize;

/// At most this many rejections and as many warnings are printed in a text summary; `--json`
/// and the log hold them all.
const PRINTED: usize = 20;

/// One rejection or warning.
#[derive(Debug, Serialize)]
pub struct ReportItem {
    /// `building`, `street` or `ground area` for a rejection; empty for a warning.
    pub kind: &'static str,
    pub file: String,
    pub source_id: String,
    pub reason: String,
}

/// The rejections (buildings, then streets, then ground areas) and the warnings of a load
/// report.
pub fn items(report: &LoadReport) -> (Vec<ReportItem>, Vec<ReportItem>) {
    let buildings = report.rejected.iter().map(|r| ("building", r));
    let streets = report.streets_rejected.iter().map(|r| ("street", r));
    let ground = report
        .ground_areas_rejected
        .iter()
        .map(|r| ("ground area", r));
    let rejected = buildings
        .chain(streets)
        .chain(ground)
        .map(|(kind, r)| ReportItem {
            kind,
            file: r.file.display().to_string(),
            source_id: r.source_id.clone(),
            reason: r.reason.to_string(),
        })
        .collect();
    let warnings = report
        .warnings
        .iter()
        .map(|w| ReportItem {
            kind: "",
            file: w.file.display().to_string(),
            source_id: w.source_id.clone(),
            reason: w.message.clone(),
        })
        .collect();
    (rejected, warnings)
}

/// Prints `rejected: FILE: building ID: REASON` (or `street ID`, `ground area ID`) and `load
/// warning: FILE: ID: MESSAGE` lines, the first [`PRINTED`] of each.
pub fn print(rejected: &[ReportItem], warnings: &[ReportItem]) {
    for (label, list) in [("rejected", rejected), ("load warning", warnings)] {
        for item in list.iter().take(PRINTED) {
            if item.source_id.is_empty() {
                println!("{label}: {}: {}", item.file, item.reason);
            } else if label == "rejected" {
                println!(
                    "{label}: {}: {} {}: {}",
                    item.file, item.kind, item.source_id, item.reason
                );
            } else {
                println!(
                    "{label}: {}: {}: {}",
                    item.file, item.source_id, item.reason
                );
            }
        }
        if list.len() > PRINTED {
            println!(
                "{label}: {} more (all of them in --json and in the log)",
                list.len() - PRINTED
            );
        }
    }
}
