//! What must hold after any load that succeeded, whatever the input: the report balances
//! (`loaded + rejected = found`, for buildings and for streets), it counts the buildings the
//! city holds, and the city passes its own invariant checker. A violation is a loader bug,
//! reported as a panic so that the fuzzer records it as a crash.

use std::path::Path;

use citywalk_scenes::City;
use citywalk_scenes::report::LoadError;

/// Checks the outcome of loading `path`; an `Err` is a fine answer to bad input, but it must
/// name the file it is about (`path`, or a file of its folder that `path` refers to).
pub fn loaded(path: &Path, result: Result<City, LoadError>) {
    let city = match result {
        Ok(city) => city,
        Err(e) => {
            let folder = path.parent().unwrap_or(path).display().to_string();
            let message = e.to_string();
            assert!(
                message.contains(&folder),
                "an error that names no file of {folder}: {message}"
            );
            return;
        }
    };
    let report = &city.report;
    assert!(
        report.is_balanced(),
        "unbalanced report: {} buildings found, {} loaded, {} rejected; {} streets found, \
         {} loaded, {} rejected",
        report.buildings_found,
        report.buildings_loaded,
        report.rejected.len(),
        report.streets_found,
        report.streets_loaded,
        report.streets_rejected.len()
    );
    assert_eq!(
        city.buildings.len(),
        report.buildings_loaded,
        "the city holds {} buildings, the report says {} loaded",
        city.buildings.len(),
        report.buildings_loaded
    );
    if let Err(e) = city.check_invariants() {
        panic!("a loaded city breaks its invariants: {e}");
    }
}
