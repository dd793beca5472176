//! Heights of 2.5D buildings from OSM-style tags (also used for GeoJSON properties).
//!
//! The rules follow the OSM Simple 3D Buildings specification
//! (<https://wiki.openstreetmap.org/wiki/Simple_3D_Buildings>, "Building height and levels"):
//! - `height` is the distance from the ground to the top of the roof, roof included;
//! - `min_height` is the distance from the ground to the bottom of the building (part);
//! - `building:levels` counts the storeys below the roof, `roof:levels` those in the roof, and
//!   `roof:height` the height of the roof; without `height`, the top is estimated as
//!   `levels × level height + roof height` (the roof height is `roof:height` when tagged,
//!   else `roof:levels × level height`);
//! - `building:min_level` is the number of storeys skipped below the part, used for the base
//!   when `min_height` is missing.
//!
//! With neither `height` nor levels, the top is [`LoadOptions::default_height_m`]
//! (marked [`HeightSource::Estimated`]). Lengths may carry units: `"12"`, `"12.5"`, `"12 m"`,
//! `"12m"`, `"40'"`, `"40 ft"`, `"12'6\""` (feet and inches), `"1200 cm"`.

use crate::city::HeightSource;
use crate::load::LoadOptions;

/// Metres per international foot.
const M_PER_FOOT: f64 = 0.3048;
/// Metres per inch.
const M_PER_INCH: f64 = 0.0254;

/// Parses an OSM length value into metres: a number with an optional unit (`m`, `km`, `cm`,
/// `mm`, `ft`, `feet`, `'`, `"`, `in`), or feet and inches (`12'6"`). A decimal comma is
/// accepted when it is the only separator (`"12,5"`). Returns `None` when the value is not a
/// length; negative and non-finite values are returned as such for the caller to reject.
pub fn parse_length_m(value: &str) -> Option<f64> {
    let v = value.trim();
    if v.is_empty() {
        return None;
    }
    // Feet and inches: 12'6" or 12' 6".
    if let Some((feet, rest)) = v.split_once('\'') {
        let feet = parse_number(feet.trim())?;
        let rest = rest.trim();
        if rest.is_empty() {
            return Some(feet * M_PER_FOOT);
        }
        let inches = rest.strip_suffix('"').unwrap_or(rest).trim();
        let inches = parse_number(inches)?;
        return Some(feet * M_PER_FOOT + inches * M_PER_INCH);
    }
    let split = v
        .find(|ch: char| !(ch.is_ascii_digit() || matches!(ch, '.' | ',' | '-' | '+' | 'e' | 'E')))
        .unwrap_or(v.len());
    // An exponent letter directly followed by a unit ("12e") is not a number; keep it simple by
    // letting `parse_number` fail on the numeric part.
    let (number, unit) = v.split_at(split);
    let number = parse_number(number.trim())?;
    let factor = match unit.trim().to_ascii_lowercase().as_str() {
        "" | "m" | "meter" | "meters" | "metre" | "metres" => 1.0,
        "km" => 1000.0,
        "cm" => 0.01,
        "mm" => 0.001,
        "ft" | "feet" | "foot" => M_PER_FOOT,
        "\"" | "in" | "inch" | "inches" => M_PER_INCH,
        _ => return None,
    };
    Some(number * factor)
}

/// Parses a number of levels (`"4"`, `"4.5"`, `"4,5"`).
pub fn parse_levels(value: &str) -> Option<f64> {
    parse_number(value.trim())
}

fn parse_number(s: &str) -> Option<f64> {
    if s.is_empty() {
        return None;
    }
    let n = if s.contains(',') && !s.contains('.') && s.matches(',').count() == 1 {
        s.replace(',', ".").parse::<f64>().ok()?
    } else {
        s.parse::<f64>().ok()?
    };
    Some(n)
}

/// The keys to read heights from, in order of precedence within each list.
#[derive(Debug, Clone, Default)]
pub struct HeightKeys<'a> {
    /// Height of the top in metres (`height`).
    pub top: Vec<&'a str>,
    /// Height of the base in metres (`min_height`).
    pub base: Vec<&'a str>,
    /// Storeys below the roof (`building:levels`).
    pub levels: Vec<&'a str>,
    /// Storeys skipped below the part (`building:min_level`).
    pub min_levels: Vec<&'a str>,
    /// Roof height in metres (`roof:height`).
    pub roof_height: Vec<&'a str>,
    /// Storeys in the roof (`roof:levels`).
    pub roof_levels: Vec<&'a str>,
}

impl HeightKeys<'static> {
    /// The OSM Simple 3D Buildings keys.
    pub fn osm() -> HeightKeys<'static> {
        HeightKeys {
            top: vec!["height"],
            base: vec!["min_height"],
            levels: vec!["building:levels"],
            min_levels: vec!["building:min_level"],
            roof_height: vec!["roof:height"],
            roof_levels: vec!["roof:levels"],
        }
    }
}

/// Heights resolved from tags, before validation with [`crate::validate::check_heights`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ResolvedHeights {
    pub base_m: f32,
    pub top_m: f32,
    pub source: HeightSource,
}

/// Heights read from tags: `None` fields were not tagged (or not parseable).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TaggedHeights {
    /// Top from a height tag (metres).
    pub top_m: Option<f64>,
    /// Top from levels (metres).
    pub top_from_levels_m: Option<f64>,
    /// Base from `min_height` or `building:min_level` (metres).
    pub base_m: Option<f64>,
    /// Values that were present but could not be parsed, as `key=value`.
    pub unparsed: Vec<String>,
}

impl TaggedHeights {
    /// Reads the heights named by `keys` through `get` (which returns a tag's value).
    pub fn read<'v>(
        get: impl Fn(&str) -> Option<&'v str>,
        keys: &HeightKeys<'_>,
        options: &LoadOptions,
    ) -> TaggedHeights {
        let level_m = f64::from(options.level_height_m);
        let mut out = TaggedHeights::default();
        let first = |list: &[&str], parse: fn(&str) -> Option<f64>, out: &mut TaggedHeights| {
            for key in list {
                if let Some(value) = get(key) {
                    match parse(value) {
                        Some(v) => return Some(v),
                        None => out.unparsed.push(format!("{key}={value}")),
                    }
                }
            }
            None
        };
        out.top_m = first(&keys.top, parse_length_m, &mut out);
        let levels = first(&keys.levels, parse_levels, &mut out);
        let roof_height = first(&keys.roof_height, parse_length_m, &mut out);
        let roof_levels = first(&keys.roof_levels, parse_levels, &mut out);
        if let Some(levels) = levels {
            let roof = roof_height.unwrap_or(roof_levels.unwrap_or(0.0) * level_m);
            out.top_from_levels_m = Some(levels * level_m + roof);
        }
        let base = first(&keys.base, parse_length_m, &mut out);
        let min_level = first(&keys.min_levels, parse_levels, &mut out);
        out.base_m = base.or(min_level.map(|l| l * level_m));
        out
    }

    /// Whether any top height (metres or levels) was tagged.
    pub fn has_top(&self) -> bool {
        self.top_m.is_some() || self.top_from_levels_m.is_some()
    }

    /// The heights, with the default top when none was tagged. An estimated top is never
    /// below the base: it is then the base plus one storey.
    pub fn resolve(&self, options: &LoadOptions) -> ResolvedHeights {
        let base_m = self.base_m.unwrap_or(0.0) as f32;
        let (top_m, source) = match (&self.top_m, self.top_from_levels_m) {
            (Some(top), _) => (*top as f32, HeightSource::Tagged),
            (None, Some(top)) => (top as f32, HeightSource::Levels),
            (None, None) => {
                let top = options
                    .default_height_m
                    .max(base_m + options.level_height_m);
                (top, HeightSource::Estimated)
            }
        };
        ResolvedHeights {
            base_m,
            top_m,
            source,
        }
    }
}

#[cfg(test)]
mod tests {
    use std::collections::HashMap;

    use super::*;

    #[test]
    fn length_table() {
        let table: &[(&str, Option<f64>)] = &[
            ("12", Some(12.0)),
            ("12.5", Some(12.5)),
            (" 12.5 ", Some(12.5)),
            ("12 m", Some(12.0)),
            ("12m", Some(12.0)),
            ("12 metres", Some(12.0)),
            ("12,5", Some(12.5)),
            ("40'", Some(40.0 * 0.3048)),
            ("40 ft", Some(40.0 * 0.3048)),
            ("40ft", Some(40.0 * 0.3048)),
            ("12'6\"", Some(12.0 * 0.3048 + 6.0 * 0.0254)),
            ("12' 6\"", Some(12.0 * 0.3048 + 6.0 * 0.0254)),
            ("1200 cm", Some(12.0)),
            ("-5", Some(-5.0)),
            ("99999", Some(99999.0)),
            ("", None),
            ("tall", None),
            ("12 storeys", None),
            ("1,2,3", None),
            ("m", None),
            ("'", None),
        ];
        for (input, expected) in table {
            let got = parse_length_m(input);
            match (got, expected) {
                (Some(g), Some(e)) => assert!((g - e).abs() < 1e-9, "{input:?}: {g} != {e}"),
                (None, None) => {}
                _ => panic!("{input:?}: got {got:?}, expected {expected:?}"),
            }
        }
    }

    fn heights(tags: &[(&str, &str)]) -> TaggedHeights {
        let map: HashMap<&str, &str> = tags.iter().copied().collect();
        TaggedHeights::read(
            |k| map.get(k).copied(),
            &HeightKeys::osm(),
            &LoadOptions::default(),
        )
    }

    #[test]
    fn s3db_rules() {
        let o = LoadOptions::default();
        let h = heights(&[
            ("height", "20"),
            ("min_height", "5"),
            ("building:levels", "9"),
        ])
        .resolve(&o);
        assert_eq!(
            (h.base_m, h.top_m, h.source),
            (5.0, 20.0, HeightSource::Tagged)
        );
        let h = heights(&[("building:levels", "4"), ("roof:levels", "1")]).resolve(&o);
        assert_eq!(
            (h.base_m, h.top_m, h.source),
            (0.0, 15.0, HeightSource::Levels)
        );
        let h = heights(&[
            ("building:levels", "4"),
            ("roof:height", "2.5"),
            ("building:min_level", "2"),
        ])
        .resolve(&o);
        assert_eq!(
            (h.base_m, h.top_m, h.source),
            (6.0, 14.5, HeightSource::Levels)
        );
        let h = heights(&[]).resolve(&o);
        assert_eq!(
            (h.base_m, h.top_m, h.source),
            (0.0, o.default_height_m, HeightSource::Estimated)
        );
        let h = heights(&[("min_height", "30")]).resolve(&o);
        assert_eq!((h.base_m, h.top_m), (30.0, 33.0));
        let t = heights(&[("height", "tall"), ("building:levels", "2")]);
        assert_eq!(t.unparsed, vec!["height=tall".to_string()]);
        assert_eq!(t.resolve(&o).source, HeightSource::Levels);
    }
}
