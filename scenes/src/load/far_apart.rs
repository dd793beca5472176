//! Inputs whose buildings lie far apart ([`super::load_cities`]): two cities merged into one
//! frame by mistake (the wrong extract, a CRS read wrongly) load without any other sign, so
//! each input whose buildings are further than [`MAX_INPUT_GAP_M`] from those of every earlier
//! input gets a [`LoadWarning`] naming it and the nearest earlier input. The warning is in the
//! load report, so it reaches `--json` and the package's provenance.

use geo::{BoundingRect, Rect};

use super::duplicates::InputSpan;
use crate::city::City;
use crate::report::LoadWarning;

/// The widest gap between the inputs of one city (metres): 100 km is more than the largest
/// city model spans, and far less than the distance between two cities of one country.
pub(crate) const MAX_INPUT_GAP_M: f64 = 100_000.0;

/// Warns of inputs further than [`MAX_INPUT_GAP_M`] from every earlier input (see the module
/// documentation). Distances are between the footprint bounds in the merged frame.
pub(super) fn warn_far_apart(city: &mut City, spans: &[InputSpan]) {
    let extents: Vec<Option<Rect<f64>>> = spans
        .iter()
        .map(|span| {
            city.buildings
                .get(span.buildings.clone())
                .unwrap_or_default()
                .iter()
                .filter_map(|b| b.footprint.bounding_rect())
                .reduce(|a, b| union(&a, &b))
        })
        .collect();
    for (j, (span, extent)) in spans.iter().zip(&extents).enumerate() {
        let Some(extent) = extent else {
            continue;
        };
        let nearest = spans[..j]
            .iter()
            .zip(&extents[..j])
            .filter_map(|(s, e)| e.as_ref().map(|e| (s, gap_m(e, extent))))
            .min_by(|a, b| a.1.total_cmp(&b.1));
        if let Some((other, gap)) = nearest
            && gap > MAX_INPUT_GAP_M
        {
            let warning = LoadWarning {
                file: span.file.clone(),
                source_id: String::new(),
                message: format!(
                    "its buildings lie {:.0} km from those of {} (more than the {:.0} km one \
                     city spans): two cities in one frame? (check the inputs and their CRS)",
                    gap / 1000.0,
                    other.file.display(),
                    MAX_INPUT_GAP_M / 1000.0
                ),
            };
            tracing::warn!("{warning}");
            city.report.warnings.push(warning);
        }
    }
}

fn union(a: &Rect<f64>, b: &Rect<f64>) -> Rect<f64> {
    Rect::new(
        (a.min().x.min(b.min().x), a.min().y.min(b.min().y)),
        (a.max().x.max(b.max().x), a.max().y.max(b.max().y)),
    )
}

/// The distance between two rectangles (0 when they overlap).
fn gap_m(a: &Rect<f64>, b: &Rect<f64>) -> f64 {
    let dx = (b.min().x - a.max().x).max(a.min().x - b.max().x).max(0.0);
    let dy = (b.min().y - a.max().y).max(a.min().y - b.max().y).max(0.0);
    dx.hypot(dy)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gap_is_zero_when_overlapping_and_euclidean_otherwise() {
        let r = |x0: f64, y0: f64, x1: f64, y1: f64| Rect::new((x0, y0), (x1, y1));
        assert_eq!(gap_m(&r(0., 0., 10., 10.), &r(5., 5., 20., 20.)), 0.0);
        assert_eq!(gap_m(&r(0., 0., 10., 10.), &r(13., 0., 20., 10.)), 3.0);
        assert_eq!(gap_m(&r(13., 14., 20., 20.), &r(0., 0., 10., 10.)), 5.0);
    }
}
