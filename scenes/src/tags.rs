//! A building's source tags (OSM tags, GeoJSON properties, CityJSON attributes), kept compact.
//!
//! A city of a million buildings holds millions of tags. As a `BTreeMap<String, String>`, five
//! short tags take about 700 bytes (a 540-byte tree node and ten small allocations); here they
//! take one string and one array of offsets. Tags are read far more often than changed: a
//! loader builds them once, so an insertion rebuilds them.

use std::collections::BTreeMap;
use std::fmt;

use serde::{Deserialize, Deserializer, Serialize, Serializer};

/// Keys and their values, sorted by key (byte order, as a `BTreeMap<String, String>`), each key
/// once. Serialized as that map is, so packages keep their bytes.
#[derive(Clone, Default, PartialEq, Eq)]
pub struct Tags {
    /// Key 0, value 0, key 1, value 1, … one after another.
    text: Box<str>,
    /// The end of each key and each value in `text`.
    ends: Box<[usize]>,
}

impl Tags {
    pub fn new() -> Tags {
        Tags::default()
    }

    pub fn len(&self) -> usize {
        self.ends.len() / 2
    }

    pub fn is_empty(&self) -> bool {
        self.ends.is_empty()
    }

    /// The text of key or value `slot` (key `i` is slot `2 i`, its value `2 i + 1`).
    fn slot(&self, slot: usize) -> &str {
        let start = slot.checked_sub(1).map_or(0, |s| self.ends[s]);
        &self.text[start..self.ends[slot]]
    }

    /// The value of `key`, if tagged.
    pub fn get(&self, key: &str) -> Option<&str> {
        let (mut lo, mut hi) = (0, self.len());
        while lo < hi {
            let mid = lo + (hi - lo) / 2;
            match self.slot(2 * mid).cmp(key) {
                std::cmp::Ordering::Less => lo = mid + 1,
                std::cmp::Ordering::Greater => hi = mid,
                std::cmp::Ordering::Equal => return Some(self.slot(2 * mid + 1)),
            }
        }
        None
    }

    pub fn contains_key(&self, key: &str) -> bool {
        self.get(key).is_some()
    }

    /// Every key and its value, in key order.
    pub fn iter(&self) -> impl ExactSizeIterator<Item = (&str, &str)> + '_ {
        (0..self.len()).map(|i| (self.slot(2 * i), self.slot(2 * i + 1)))
    }

    /// Tags `key` with `value`, returning the value it replaces.
    pub fn insert(&mut self, key: String, value: String) -> Option<String> {
        let mut map = self.to_map();
        let old = map.insert(key, value);
        *self = Tags::from(map);
        old
    }

    pub fn clear(&mut self) {
        *self = Tags::default();
    }

    /// The tags as a map.
    pub fn to_map(&self) -> BTreeMap<String, String> {
        self.iter()
            .map(|(k, v)| (k.to_string(), v.to_string()))
            .collect()
    }
}

impl From<BTreeMap<String, String>> for Tags {
    fn from(map: BTreeMap<String, String>) -> Tags {
        let mut text = String::with_capacity(map.iter().map(|(k, v)| k.len() + v.len()).sum());
        let mut ends = Vec::with_capacity(2 * map.len());
        for (k, v) in &map {
            text.push_str(k);
            ends.push(text.len());
            text.push_str(v);
            ends.push(text.len());
        }
        Tags {
            text: text.into_boxed_str(),
            ends: ends.into_boxed_slice(),
        }
    }
}

/// As a map collects pairs: a later value of a key replaces an earlier one.
impl<K: Into<String>, V: Into<String>> FromIterator<(K, V)> for Tags {
    fn from_iter<I: IntoIterator<Item = (K, V)>>(pairs: I) -> Tags {
        let map: BTreeMap<String, String> = pairs
            .into_iter()
            .map(|(k, v)| (k.into(), v.into()))
            .collect();
        Tags::from(map)
    }
}

impl<const N: usize> From<[(&str, &str); N]> for Tags {
    fn from(pairs: [(&str, &str); N]) -> Tags {
        pairs.into_iter().collect()
    }
}

impl fmt::Debug for Tags {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_map().entries(self.iter()).finish()
    }
}

impl Serialize for Tags {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_map(self.iter())
    }
}

impl<'de> Deserialize<'de> for Tags {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Tags, D::Error> {
        BTreeMap::<String, String>::deserialize(d).map(Tags::from)
    }
}

#[cfg(test)]
mod tests {
    use proptest::prelude::*;

    use super::*;

    proptest! {
        /// Tags answer every question as the map they were made from, and serialize to its
        /// bytes.
        #[test]
        fn tags_behave_as_their_map(
            pairs in prop::collection::vec(("[a-z:]{0,6}", "\\PC{0,8}"), 0..12),
            probe in "[a-z:]{0,6}",
        ) {
            let map: BTreeMap<String, String> = pairs.iter().cloned().collect();
            let tags: Tags = pairs.iter().cloned().collect();
            prop_assert_eq!(tags.len(), map.len());
            prop_assert_eq!(tags.is_empty(), map.is_empty());
            prop_assert!(tags.iter().eq(map.iter().map(|(k, v)| (k.as_str(), v.as_str()))));
            prop_assert_eq!(tags.get(&probe), map.get(&probe).map(String::as_str));
            for (k, v) in &map {
                prop_assert_eq!(tags.get(k), Some(v.as_str()));
            }
            prop_assert_eq!(tags.to_map(), map.clone());
            let bytes = postcard::to_stdvec(&tags).expect("encode");
            prop_assert_eq!(&bytes, &postcard::to_stdvec(&map).expect("encode"));
            prop_assert_eq!(postcard::from_bytes::<Tags>(&bytes).expect("decode"), tags.clone());

            let mut inserted = tags.clone();
            let mut map_inserted = map.clone();
            prop_assert_eq!(
                inserted.insert(probe.clone(), "x".into()),
                map_inserted.insert(probe, "x".into())
            );
            prop_assert_eq!(inserted, Tags::from(map_inserted));
        }
    }
}
