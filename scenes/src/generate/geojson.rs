//! Streaming GeoJSON output of a city in local metres (see the contract in [`super`]).
//!
//! Features are formatted by hand into a reusable buffer and written one at a time, so a
//! million-building city never sits in memory as text. Coordinates are printed with two
//! decimals (centimetres, the generator's grid), heights with the shortest form that reads
//! back to the same `f32`.

use std::io::{self, Write};

use geo::{LineString, MultiPolygon, Polygon};

use crate::city::{Building, City, Street, StreetClass};

/// The legacy `crs` member naming the local frame (loaders map it to `Frame::local()`).
pub const LOCAL_CRS_NAME: &str = "citywalk:local";

/// The OSM `highway=*` value written for a street class; `StreetClass::from_osm_highway`
/// maps each back to its class.
pub fn highway_value(class: StreetClass) -> &'static str {
    match class {
        StreetClass::Major => "primary",
        StreetClass::Minor => "tertiary",
        StreetClass::Residential => "residential",
        StreetClass::Service => "service",
        StreetClass::Pedestrian => "pedestrian",
        StreetClass::Other => "road",
    }
}

/// Writes a GeoJSON FeatureCollection feature by feature.
#[derive(Debug)]
pub struct GeoJsonWriter<W: Write> {
    out: W,
    buf: Vec<u8>,
    features: usize,
}

impl<W: Write> GeoJsonWriter<W> {
    /// Starts the collection (writes the header).
    pub fn new(mut out: W) -> io::Result<GeoJsonWriter<W>> {
        write!(
            out,
            "{{\"type\":\"FeatureCollection\",\"crs\":{{\"type\":\"name\",\"properties\":{{\"name\":\"{LOCAL_CRS_NAME}\"}}}},\"features\":["
        )?;
        Ok(GeoJsonWriter {
            out,
            buf: Vec::with_capacity(4096),
            features: 0,
        })
    }

    /// Features written so far.
    pub fn features(&self) -> usize {
        self.features
    }

    fn begin_feature(&mut self) {
        self.buf.clear();
        if self.features > 0 {
            self.buf.push(b',');
        }
        self.buf
            .extend_from_slice(b"\n{\"type\":\"Feature\",\"properties\":{");
    }

    fn end_feature(&mut self) -> io::Result<()> {
        self.buf.extend_from_slice(b"}");
        self.features += 1;
        self.out.write_all(&self.buf)
    }

    /// Writes a building, and one `building:part` feature per part when it has several.
    pub fn write_building(&mut self, b: &Building) -> io::Result<()> {
        self.begin_feature();
        self.buf.extend_from_slice(b"\"id\":");
        push_str(&mut self.buf, &b.source_id);
        self.buf.extend_from_slice(b",\"height\":");
        push_f32(&mut self.buf, b.top_m);
        self.buf.extend_from_slice(b",\"min_height\":");
        push_f32(&mut self.buf, b.base_m);
        self.buf.extend_from_slice(b",\"building\":\"yes\"");
        if b.tags.get("landmark").is_some_and(|v| v == "yes") {
            self.buf.extend_from_slice(b",\"landmark\":true");
        }
        if let Some(form) = b.tags.get("citywalk:form") {
            self.buf.extend_from_slice(b",\"form\":");
            push_str(&mut self.buf, form);
        }
        self.buf.extend_from_slice(b"},\"geometry\":");
        push_multipolygon(&mut self.buf, &b.footprint);
        self.end_feature()?;
        if b.parts.len() > 1 {
            for part in &b.parts {
                self.begin_feature();
                self.buf
                    .extend_from_slice(b"\"kind\":\"building:part\",\"id\":");
                push_str(&mut self.buf, &part.source_id);
                self.buf.extend_from_slice(b",\"part_of\":");
                push_str(&mut self.buf, &b.source_id);
                self.buf.extend_from_slice(b",\"height\":");
                push_f32(&mut self.buf, part.top_m);
                self.buf.extend_from_slice(b",\"min_height\":");
                push_f32(&mut self.buf, part.base_m);
                self.buf.extend_from_slice(b"},\"geometry\":");
                push_multipolygon(&mut self.buf, &part.footprint);
                self.end_feature()?;
            }
        }
        Ok(())
    }

    /// Writes a street centre line.
    pub fn write_street(&mut self, s: &Street) -> io::Result<()> {
        self.begin_feature();
        self.buf.extend_from_slice(b"\"id\":");
        push_str(&mut self.buf, &s.source_id);
        self.buf.extend_from_slice(b",\"highway\":");
        push_str(&mut self.buf, highway_value(s.class));
        if let Some(name) = &s.name {
            self.buf.extend_from_slice(b",\"name\":");
            push_str(&mut self.buf, name);
        }
        self.buf.extend_from_slice(b",\"width\":");
        push_cm(&mut self.buf, super::layout::street_width_m(s.class));
        self.buf
            .extend_from_slice(b"},\"geometry\":{\"type\":\"LineString\",\"coordinates\":");
        push_line(&mut self.buf, &s.line);
        self.buf.push(b'}');
        self.end_feature()
    }

    /// Closes the collection and returns the output, flushed.
    pub fn finish(mut self) -> io::Result<W> {
        self.out.write_all(b"\n]}\n")?;
        self.out.flush()?;
        Ok(self.out)
    }
}

/// Writes a whole in-memory city (buildings, then streets).
pub fn write_city_geojson<W: Write>(city: &City, out: W) -> io::Result<W> {
    let mut w = GeoJsonWriter::new(out)?;
    for b in &city.buildings {
        w.write_building(b)?;
    }
    for s in &city.streets {
        w.write_street(s)?;
    }
    w.finish()
}

fn push_str(buf: &mut Vec<u8>, s: &str) {
    buf.push(b'"');
    for ch in s.chars() {
        match ch {
            '"' => buf.extend_from_slice(b"\\\""),
            '\\' => buf.extend_from_slice(b"\\\\"),
            c if (c as u32) < 0x20 => {
                buf.extend_from_slice(format!("\\u{:04x}", c as u32).as_bytes());
            }
            c => {
                let mut tmp = [0u8; 4];
                buf.extend_from_slice(c.encode_utf8(&mut tmp).as_bytes());
            }
        }
    }
    buf.push(b'"');
}

fn push_f32(buf: &mut Vec<u8>, v: f32) {
    if v.is_finite() {
        buf.extend_from_slice(v.to_string().as_bytes());
    } else {
        buf.extend_from_slice(b"null");
    }
}

fn push_u64(buf: &mut Vec<u8>, mut v: u64) {
    let mut tmp = [0u8; 20];
    let mut i = tmp.len();
    loop {
        i -= 1;
        tmp[i] = b'0' + (v % 10) as u8;
        v /= 10;
        if v == 0 {
            break;
        }
    }
    buf.extend_from_slice(&tmp[i..]);
}

/// A number in metres with two decimals.
fn push_cm(buf: &mut Vec<u8>, v: f64) {
    if !v.is_finite() {
        buf.extend_from_slice(b"null");
        return;
    }
    let cm = (v * 100.0).round();
    if cm.abs() >= 9.0e15 {
        buf.extend_from_slice(format!("{v:.2}").as_bytes());
        return;
    }
    let cm = cm as i64;
    if cm < 0 {
        buf.push(b'-');
    }
    let cm = cm.unsigned_abs();
    push_u64(buf, cm / 100);
    buf.push(b'.');
    let frac = (cm % 100) as u8;
    buf.push(b'0' + frac / 10);
    buf.push(b'0' + frac % 10);
}

fn push_line(buf: &mut Vec<u8>, line: &LineString<f64>) {
    buf.push(b'[');
    for (k, c) in line.0.iter().enumerate() {
        if k > 0 {
            buf.push(b',');
        }
        buf.push(b'[');
        push_cm(buf, c.x);
        buf.push(b',');
        push_cm(buf, c.y);
        buf.push(b']');
    }
    buf.push(b']');
}

fn push_polygon_rings(buf: &mut Vec<u8>, p: &Polygon<f64>) {
    buf.push(b'[');
    push_line(buf, p.exterior());
    for hole in p.interiors() {
        buf.push(b',');
        push_line(buf, hole);
    }
    buf.push(b']');
}

fn push_multipolygon(buf: &mut Vec<u8>, mp: &MultiPolygon<f64>) {
    if let [only] = mp.0.as_slice() {
        buf.extend_from_slice(b"{\"type\":\"Polygon\",\"coordinates\":");
        push_polygon_rings(buf, only);
    } else {
        buf.extend_from_slice(b"{\"type\":\"MultiPolygon\",\"coordinates\":[");
        for (k, p) in mp.0.iter().enumerate() {
            if k > 0 {
                buf.push(b',');
            }
            push_polygon_rings(buf, p);
        }
        buf.push(b']');
    }
    buf.push(b'}');
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_are_formatted_in_centimetres() {
        let mut buf = Vec::new();
        for v in [0.0, 1.5, -0.05, -12.346, 123_456.789, 0.004] {
            push_cm(&mut buf, v);
            buf.push(b' ');
        }
        assert_eq!(
            String::from_utf8(buf).unwrap(),
            "0.00 1.50 -0.05 -12.35 123456.79 0.00 "
        );
        let mut s = Vec::new();
        push_str(&mut s, "a\"b\\c\n");
        assert_eq!(String::from_utf8(s).unwrap(), "\"a\\\"b\\\\c\\u000a\"");
        for class in [
            StreetClass::Major,
            StreetClass::Minor,
            StreetClass::Residential,
            StreetClass::Service,
            StreetClass::Pedestrian,
        ] {
            assert_eq!(StreetClass::from_osm_highway(highway_value(class)), class);
        }
    }
}
