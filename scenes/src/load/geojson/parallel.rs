//! The GeoJSON document parsed on every thread. Parsing is most of a GeoJSON load (0.51 of
//! 0.80 s on the generated 100k city) and a stream parse runs on one thread, so the top level
//! is read once, keeping each feature as its slice of the mapped file (`serde_json`'s
//! `RawValue`: checked and skipped, not parsed), and the features are then parsed and converted
//! in chunks on the worker threads and merged in file order: the same areas, streets and
//! warnings as the stream, on any number of threads.

use rayon::prelude::*;
use serde::{Deserialize, Deserializer};
use serde_json::Value;
use serde_json::value::RawValue;

use super::{RawFeature, Sink, Top};
use crate::load::LoadOptions;

/// Features a worker parses and converts at a time.
const FEATURES_PER_CHUNK: usize = 1024;

/// A top-level member: `None` when absent, else its value (`null` included, which an `Option`
/// would make absent), so that this parse reads what the stream reads.
struct Member<T>(Option<T>);

impl<T> Default for Member<T> {
    fn default() -> Self {
        Member(None)
    }
}

impl<'de, T: Deserialize<'de>> Deserialize<'de> for Member<T> {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        T::deserialize(d).map(|v| Member(Some(v)))
    }
}

/// The document's top level, its features unparsed.
#[derive(Deserialize)]
struct TopLevel<'a> {
    #[serde(rename = "type", default)]
    kind: Member<Value>,
    #[serde(default)]
    crs: Member<Value>,
    #[serde(borrow, default)]
    features: Member<Vec<&'a RawValue>>,
}

/// The document `bytes` parsed on the worker threads: its top level and its converted
/// features. `None` where anything is out of the ordinary (a syntax error, a member given
/// twice, no features, a feature that is not an object, ...): the caller then streams the
/// document, which reports what is wrong and where, as it always has. `parsed` is handed each
/// chunk's stretch of `bytes` once its features are converted (a mapped file's pages are
/// given back then: half a gigabyte at a million buildings).
pub(super) fn parse<'a>(
    bytes: &[u8],
    options: &'a LoadOptions,
    parsed: &(dyn Fn(&[u8]) + Sync),
) -> Option<(Top, Sink<'a>)> {
    let top: TopLevel<'_> = serde_json::from_slice(bytes).ok()?;
    let features = top.features.0?;
    let chunks: Vec<Sink<'a>> = features
        .par_chunks(FEATURES_PER_CHUNK)
        .enumerate()
        .map(|(chunk, raw)| {
            let mut sink = Sink::new(options, chunk * FEATURES_PER_CHUNK);
            for feature in raw {
                sink.push(serde_json::from_str::<RawFeature>(feature.get()).ok()?);
            }
            if let (Some(first), Some(last)) = (raw.first(), raw.last()) {
                let start = first.get().as_ptr() as usize - bytes.as_ptr() as usize;
                let end = last.get().as_ptr() as usize + last.get().len() - bytes.as_ptr() as usize;
                parsed(&bytes[start..end]);
            }
            Some(sink)
        })
        .collect::<Option<_>>()?;
    let mut sink = Sink::new(options, 0);
    // Sized once: grown by doubling, the merged array would hold up to twice the streets (the
    // areas' chunks are moved, not copied).
    sink.streets
        .reserve_exact(chunks.iter().map(|c| c.streets.len()).sum());
    for chunk in chunks {
        sink.append(chunk);
    }
    let kind = top
        .kind
        .0
        .map(|v| v.as_str().map_or_else(|| v.to_string(), str::to_string));
    let top = Top {
        kind,
        crs: top.crs.0,
        saw_features: true,
    };
    Some((top, sink))
}

#[cfg(test)]
mod tests {
    use std::fmt::Write as _;

    use super::*;

    /// What a parse gave, comparable: the top level and the sink's contents.
    fn outcome(top: &Top, sink: &Sink<'_>) -> String {
        format!(
            "{:?} {:?} {} | {:?} | {:?} | {:?} | {} {}",
            top.kind,
            top.crs,
            top.saw_features,
            sink.areas,
            sink.streets,
            sink.warnings,
            sink.ignored,
            sink.index
        )
    }

    /// The document parsed by the stream, as the loader does where it cannot map a file.
    fn streamed(document: &str, options: &LoadOptions) -> Result<String, String> {
        let mut sink = Sink::new(options, 0);
        let de = serde_json::Deserializer::from_slice(document.as_bytes());
        let top = super::super::parse(std::path::Path::new("t.geojson"), de, &mut sink)
            .map_err(|e| e.to_string())?;
        Ok(outcome(&top, &sink))
    }

    fn in_parallel(document: &str, options: &LoadOptions) -> Option<String> {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(4)
            .build()
            .expect("a pool of 4");
        // Each chunk's stretch, handed back once parsed, lies in the document and starts a
        // feature (an object).
        let bytes = document.as_bytes();
        let parsed = |piece: &[u8]| {
            let start = piece.as_ptr() as usize - bytes.as_ptr() as usize;
            assert!(start + piece.len() <= bytes.len());
            assert_eq!(piece.first(), Some(&b'{'));
            assert_eq!(piece.last(), Some(&b'}'));
        };
        pool.install(|| parse(bytes, options, &parsed))
            .map(|(top, sink)| outcome(&top, &sink))
    }

    /// A collection of `n` features of every kind: buildings with and without ids (whose
    /// source id is their index in the file), parts, streets, ground areas, points, and a
    /// feature without geometry.
    fn collection(n: usize, crs: &str) -> String {
        let mut features = Vec::new();
        for i in 0..n {
            let (x, y) = ((i % 100) as f64 * 1e-4, (i / 100) as f64 * 1e-4);
            let square = format!(
                "[[[{x},{y}],[{},{y}],[{},{}],[{x},{}],[{x},{y}]]]",
                x + 5e-5,
                x + 5e-5,
                y + 5e-5,
                y + 5e-5
            );
            let mut f = String::from("{\"type\":\"Feature\",");
            let _ = match i % 7 {
                0 => write!(
                    f,
                    "\"geometry\":{{\"type\":\"Polygon\",\"coordinates\":{square}}},\"properties\":{{\"building\":\"yes\",\"height\":{}}}",
                    3 + i % 20
                ),
                1 => write!(
                    f,
                    "\"id\":\"way/{i}\",\"geometry\":{{\"type\":\"Polygon\",\"coordinates\":{square}}},\"properties\":{{\"building\":\"yes\",\"building:levels\":\"{}\"}}",
                    1 + i % 5
                ),
                2 => write!(
                    f,
                    "\"geometry\":{{\"type\":\"Polygon\",\"coordinates\":{square}}},\"properties\":{{\"kind\":\"building:part\",\"height\":\"x\"}}"
                ),
                3 => write!(
                    f,
                    "\"geometry\":{{\"type\":\"LineString\",\"coordinates\":[[{x},{y}],[{},{y}]]}},\"properties\":{{\"highway\":\"residential\",\"name\":\"S{i}\"}}",
                    x + 1e-3
                ),
                4 => write!(
                    f,
                    "\"geometry\":{{\"type\":\"Polygon\",\"coordinates\":{square}}},\"properties\":{{\"leisure\":\"park\"}}"
                ),
                5 => write!(
                    f,
                    "\"geometry\":{{\"type\":\"Point\",\"coordinates\":[{x},{y}]}},\"properties\":null"
                ),
                _ => write!(f, "\"properties\":{{\"building\":\"yes\"}}"),
            };
            f.push('}');
            features.push(f);
        }
        format!(
            "{{\"type\":\"FeatureCollection\",{crs}\"features\":[{}],\"name\":\"t\"}}",
            features.join(",\n")
        )
    }

    #[test]
    fn parsed_on_every_thread_as_the_stream_parses_it() {
        let options = LoadOptions::default();
        // Several chunks, the last one short.
        for n in [0, 1, 7, FEATURES_PER_CHUNK + 1, 3 * FEATURES_PER_CHUNK - 5] {
            for crs in [
                "",
                "\"crs\":null,",
                "\"crs\":{\"type\":\"name\",\"properties\":{\"name\":\"EPSG:28992\"}},",
            ] {
                let document = collection(n, crs);
                let parallel = in_parallel(&document, &options).expect("an ordinary document");
                assert_eq!(
                    Ok(parallel),
                    streamed(&document, &options),
                    "{n} features, {crs}"
                );
            }
        }
    }

    #[test]
    fn anything_out_of_the_ordinary_is_left_to_the_stream() {
        let options = LoadOptions::default();
        let one = collection(3, "");
        for document in [
            // A syntax error, a member given twice, no features, features not an array, a
            // feature that is not an object, trailing characters, not an object at all.
            one.replacen("\"Feature\"", "\"Feature", 1),
            one.replacen(
                "\"type\":\"FeatureCollection\"",
                "\"type\":\"FeatureCollection\",\"type\":\"x\"",
                1,
            ),
            "{\"type\":\"FeatureCollection\"}".to_string(),
            "{\"type\":\"FeatureCollection\",\"features\":{}}".to_string(),
            "{\"type\":\"FeatureCollection\",\"features\":[\"feature\"]}".to_string(),
            format!("{one} x"),
            "[1, 2]".to_string(),
        ] {
            assert_eq!(in_parallel(&document, &options), None, "{document}");
        }
        // A member given twice is no error to the stream: the last one counts.
        let twice = one.replacen(
            "\"type\":\"FeatureCollection\"",
            "\"type\":\"x\",\"type\":\"FeatureCollection\"",
            1,
        );
        assert!(streamed(&twice, &options).is_ok());
        // A `type` of null is read as the stream reads it.
        let null_type = one.replacen("\"FeatureCollection\"", "null", 1);
        assert_eq!(
            in_parallel(&null_type, &options).ok_or(()),
            streamed(&null_type, &options).map_err(|_| ())
        );
    }
}
