//! Wavefront OBJ city models, as 3dfier and CAD tools write them.
//!
//! * Read line by line (no line longer than [`MAX_LINE_BYTES`] is held), `v` and `f` statements
//!   only; texture coordinates, normals, smoothing groups, lines and `mtllib` are ignored.
//!   Face corners `i`, `i/t`, `i//n`, `i/t/n`, 1-based or negative (relative to the vertices
//!   read so far). Line continuations (`\` at the end of a line) are not supported.
//! * Objects: `o NAME` starts (or re-enters) an object. In a file without `o`, `g NAME` does;
//!   after an `o`, group names only add to the object's names. Faces before any `o` / `g`
//!   form an object of their own.
//! * An object is a building when its name, a group name or a material it uses (`usemtl`)
//!   contains one of [`LoadOptions::obj_building_markers`] (default `building`, matching
//!   3dfier's `Building` class). Each building object is one building of one part, its
//!   footprint and heights derived from the mesh as for CityJSON ([`super::mesh_building`]).
//!   Every other object (3dfier's `Terrain`, `Road`, `Water`, `Forest`, `Bridge`, ...) is a
//!   ground area: its class from the first of its name, group names and materials that
//!   [`GroundClass::from_class_name`] knows (else [`GroundClass::Other`]), its polygon the
//!   plan of its non-vertical faces ([`crate::mesh_footprint::footprint_from_mesh`], as a
//!   building's footprint). One that fails (a broken face, nothing but walls) is rejected
//!   into the report's ground-area list.
//! * Frame: OBJ names no CRS and no up axis, so [`LoadOptions::source_crs`] and
//!   [`LoadOptions::up_axis`] give them; origin at the centre of the vertices' xy extent and
//!   at the lowest building base, as for CityJSON: large absolute coordinates (RD New, UTM)
//!   are subtracted in f64 before the mesh is stored in f32.
//!
//! Bad input: a line that cannot be read (a vertex that is not three numbers, an unknown
//! statement, an over-long line) is a file warning naming its line; a face that cannot be used
//! (an index 0, out of range or not a number, fewer than three corners) spoils its object,
//! which is rejected with the face's line; a vertex that is not finite spoils the objects that
//! use it. Every other object still loads and `loaded + rejected = found`.

use std::collections::{BTreeMap, HashMap};
use std::io::{BufRead, BufReader};
use std::path::Path;

use glam::DVec3;

use super::mesh_building::{MeshBuilding, MeshPart, append_surface, assemble, xy_extent_centre};
use super::{LoadOptions, UpAxis};
use crate::city::{City, GroundArea, GroundClass, TriangleMesh};
use crate::frame::{Crs, Frame};
use crate::mesh_footprint::footprint_from_mesh;
use crate::report::{LoadError, LoadReport, LoadWarning, RejectReason, Rejection};

const FORMAT: &str = "OBJ";

/// Lines longer than this are cut off and reported (a face of ~100k corners fits).
pub const MAX_LINE_BYTES: usize = 1 << 20;

/// File warnings about single lines beyond this many are summed up in one more warning.
const MAX_LINE_WARNINGS: usize = 32;

/// Loads an OBJ file.
pub fn load(path: &Path, options: &LoadOptions) -> Result<City, LoadError> {
    let file = std::fs::File::open(path).map_err(|source| LoadError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    load_reader(path, BufReader::new(file), options)
}

/// Loads OBJ text from `reader`; `path` names the source in errors and the report.
pub fn load_reader(
    path: &Path,
    reader: impl BufRead,
    options: &LoadOptions,
) -> Result<City, LoadError> {
    let parsed = parse(path, reader, options.up_axis)?;
    let markers: Vec<String> = options
        .obj_building_markers
        .iter()
        .map(|m| m.to_ascii_lowercase())
        .filter(|m| !m.is_empty())
        .collect();
    let mut report = LoadReport {
        files: vec![path.to_path_buf()],
        warnings: parsed.warnings,
        ..LoadReport::default()
    };

    let origin = xy_extent_centre(&parsed.vertices);
    let frame = match &options.source_crs {
        Some(name) => Frame::projected(name.clone(), origin),
        None => Frame {
            crs: Crs::Local,
            origin,
        },
    };
    let origin = DVec3::from_array(origin);

    // Every object that is not a building is a ground area; the count per class names what
    // a file without buildings holds.
    let mut others: BTreeMap<&'static str, usize> = BTreeMap::new();
    let mut ground_areas = Vec::new();
    let mut buildings = Vec::new();
    for object in &parsed.objects {
        // An object without faces is no geometry at all (a name, a material); one whose only
        // face is broken is rejected below, with that face's line.
        if object.faces.is_empty() && object.broken.is_none() {
            continue;
        }
        if object.is_building(&markers) {
            buildings.push(MeshBuilding {
                source_id: object.source_id(),
                parts: vec![MeshPart {
                    source_id: object.source_id(),
                    mesh: object.mesh(&parsed.vertices, &parsed.bad_vertices, origin),
                }],
                tags: object.tags(),
            });
        } else {
            let class = object.ground_class();
            *others.entry(class.name()).or_insert(0) += 1;
            report.ground_areas_found += 1;
            let polygon = object
                .mesh(&parsed.vertices, &parsed.bad_vertices, origin)
                .and_then(|mesh| footprint_from_mesh(&mesh));
            match polygon {
                Ok(clean) => {
                    for message in clean.repairs {
                        report.warnings.push(LoadWarning {
                            file: path.to_path_buf(),
                            source_id: object.source_id(),
                            message,
                        });
                    }
                    ground_areas.push(GroundArea {
                        source_id: object.source_id(),
                        class,
                        polygon: clean.footprint,
                    });
                }
                Err(reason) => report.ground_areas_rejected.push(Rejection {
                    file: path.to_path_buf(),
                    source_id: object.source_id(),
                    reason,
                }),
            }
        }
    }
    report.ground_areas_loaded = ground_areas.len();
    if buildings.is_empty() {
        let found: Vec<String> = others
            .iter()
            .map(|(class, n)| format!("{n} {class}"))
            .collect();
        return Err(LoadError::Malformed {
            path: path.to_path_buf(),
            format: FORMAT,
            reason: format!(
                "no object marked as a building (name, group or material containing one of \
                 {:?}); objects found: {}",
                options.obj_building_markers,
                if found.is_empty() {
                    "none with faces".to_string()
                } else {
                    found.join(", ")
                }
            ),
        });
    }
    let mut city = assemble(path, FORMAT, frame, buildings, report)?;
    city.ground_areas = ground_areas;
    Ok(city)
}

/// One face: its corners (0-based vertex indices, checked against the vertex count at the end)
/// and its line.
#[derive(Debug, Clone)]
struct Face {
    line: usize,
    corners: std::ops::Range<usize>,
}

/// One object or group of the file.
#[derive(Debug, Default)]
struct Object {
    name: String,
    /// Line of the statement that opened it (or of its first face).
    line: usize,
    groups: Vec<String>,
    materials: Vec<String>,
    faces: Vec<Face>,
    corners: Vec<u32>,
    /// The first face that could not be read: why, with its line.
    broken: Option<String>,
}

impl Object {
    fn source_id(&self) -> String {
        if self.name.is_empty() {
            format!("object at line {}", self.line)
        } else {
            self.name.clone()
        }
    }

    fn is_building(&self, markers: &[String]) -> bool {
        let names = std::iter::once(&self.name)
            .chain(&self.groups)
            .chain(&self.materials);
        names
            .map(|n| n.to_ascii_lowercase())
            .any(|n| markers.iter().any(|m| n.contains(m.as_str())))
    }

    /// The ground class of a non-building object: the first of its name, group names and
    /// materials that names a class, else [`GroundClass::Other`] (3dfier's `Terrain`).
    fn ground_class(&self) -> GroundClass {
        std::iter::once(&self.name)
            .chain(&self.groups)
            .chain(&self.materials)
            .find_map(|n| GroundClass::from_class_name(n))
            .unwrap_or(GroundClass::Other)
    }

    fn tags(&self) -> BTreeMap<String, String> {
        let mut tags = BTreeMap::new();
        if !self.materials.is_empty() {
            tags.insert("obj:material".to_string(), self.materials.join(";"));
        }
        if !self.groups.is_empty() {
            tags.insert("obj:group".to_string(), self.groups.join(";"));
        }
        tags
    }

    fn add_material(&mut self, material: &str) {
        if !self.materials.iter().any(|m| m == material) {
            self.materials.push(material.to_string());
        }
    }

    /// The object's triangles in the local frame, or why it has none.
    fn mesh(
        &self,
        vertices: &[DVec3],
        bad_vertices: &HashMap<u32, usize>,
        origin: DVec3,
    ) -> Result<TriangleMesh, RejectReason> {
        if let Some(reason) = &self.broken {
            return Err(RejectReason::InvalidGeometry(reason.clone()));
        }
        let mut mesh = TriangleMesh::default();
        let mut local: HashMap<u32, u32> = HashMap::new();
        let mut ring: Vec<DVec3> = Vec::new();
        for face in &self.faces {
            let corners = &self.corners[face.corners.clone()];
            ring.clear();
            for &i in corners {
                let Some(p) = vertices.get(i as usize) else {
                    return Err(RejectReason::InvalidGeometry(format!(
                        "line {}: vertex {} is not one of the file's {} vertices",
                        face.line,
                        u64::from(i) + 1,
                        vertices.len()
                    )));
                };
                if !p.is_finite() {
                    let at = bad_vertices
                        .get(&i)
                        .map(|l| format!(" (line {l})"))
                        .unwrap_or_default();
                    return Err(RejectReason::InvalidGeometry(format!(
                        "line {}: vertex {}{at} is not finite",
                        face.line,
                        u64::from(i) + 1
                    )));
                }
                ring.push(*p - origin);
            }
            append_surface(
                &mut mesh,
                &mut local,
                std::slice::from_ref(&ring),
                corners,
                |v| vertices[v as usize] - origin,
            );
        }
        if mesh.indices.is_empty() {
            return Err(RejectReason::ZeroArea);
        }
        Ok(mesh)
    }
}

/// What the line-by-line pass gives.
#[derive(Debug, Default)]
struct Parsed {
    /// Source coordinates (east, north, up), NaN for a vertex line that could not be read.
    vertices: Vec<DVec3>,
    /// Vertex index → line, for the vertices that are not finite.
    bad_vertices: HashMap<u32, usize>,
    objects: Vec<Object>,
    warnings: Vec<LoadWarning>,
}

/// The line-by-line pass.
fn parse(path: &Path, mut reader: impl BufRead, up: UpAxis) -> Result<Parsed, LoadError> {
    let mut out = Parsed::default();
    let mut by_name: HashMap<String, usize> = HashMap::new();
    let mut current: Option<usize> = None;
    let mut seen_o = false;
    let mut material: Option<String> = None;
    let mut line_warnings = 0usize;
    let mut warn = |out: &mut Parsed, line: usize, message: String| {
        line_warnings += 1;
        if line_warnings <= MAX_LINE_WARNINGS {
            out.warnings.push(LoadWarning {
                file: path.to_path_buf(),
                source_id: String::new(),
                message: format!("line {line}: {message}"),
            });
        }
    };
    let mut buf = Vec::new();
    let mut line_no = 0usize;
    loop {
        let truncated = match read_line_bounded(&mut reader, &mut buf) {
            Ok(Some(truncated)) => truncated,
            Ok(None) => break,
            Err(source) => {
                return Err(LoadError::Io {
                    path: path.to_path_buf(),
                    source,
                });
            }
        };
        line_no += 1;
        if truncated {
            warn(
                &mut out,
                line_no,
                format!("longer than {MAX_LINE_BYTES} bytes: ignored"),
            );
            continue;
        }
        let text = String::from_utf8_lossy(&buf);
        let text = text.split('#').next().unwrap_or("").trim();
        let mut words = text.split_ascii_whitespace();
        let Some(keyword) = words.next() else {
            continue;
        };
        match keyword {
            "v" => {
                let p = read_vertex(&mut words, up);
                let index =
                    u32::try_from(out.vertices.len()).map_err(|_| LoadError::Malformed {
                        path: path.to_path_buf(),
                        format: FORMAT,
                        reason: format!("line {line_no}: more than {} vertices", u32::MAX),
                    })?;
                match p {
                    Some(p) if p.is_finite() => out.vertices.push(p),
                    other => {
                        if other.is_none() {
                            warn(&mut out, line_no, "vertex is not three numbers".into());
                        }
                        out.bad_vertices.insert(index, line_no);
                        out.vertices.push(DVec3::NAN);
                    }
                }
            }
            "o" | "g" => {
                let name = words.collect::<Vec<_>>().join(" ");
                if keyword == "g" && seen_o {
                    if let Some(object) = current.map(|i| &mut out.objects[i])
                        && !name.is_empty()
                        && !object.groups.contains(&name)
                    {
                        object.groups.push(name);
                    }
                    continue;
                }
                seen_o |= keyword == "o";
                let index = match by_name.get(&name).filter(|_| !name.is_empty()) {
                    Some(&i) => i,
                    None => {
                        let i = out.objects.len();
                        out.objects.push(Object {
                            name: name.clone(),
                            line: line_no,
                            ..Object::default()
                        });
                        if !name.is_empty() {
                            by_name.insert(name, i);
                        }
                        i
                    }
                };
                current = Some(index);
            }
            "usemtl" => {
                let name = words.collect::<Vec<_>>().join(" ");
                if let Some(i) = current {
                    out.objects[i].add_material(&name);
                }
                material = Some(name);
            }
            "f" => {
                let index = *current.get_or_insert_with(|| {
                    out.objects.push(Object {
                        line: line_no,
                        ..Object::default()
                    });
                    out.objects.len() - 1
                });
                let vertex_count = out.vertices.len();
                let object = &mut out.objects[index];
                if let Some(m) = &material {
                    object.add_material(m);
                }
                if object.broken.is_some() {
                    continue;
                }
                let start = object.corners.len();
                let mut failed = None;
                for word in words {
                    match read_corner(word, vertex_count) {
                        Ok(i) => object.corners.push(i),
                        Err(reason) => {
                            failed = Some(reason);
                            break;
                        }
                    }
                }
                let count = object.corners.len() - start;
                if failed.is_none() && count < 3 {
                    failed = Some(format!("a face of {count} corner(s)"));
                }
                match failed {
                    Some(reason) => {
                        object.corners.truncate(start);
                        object.broken = Some(format!("line {line_no}: {reason}"));
                    }
                    None => object.faces.push(Face {
                        line: line_no,
                        corners: start..object.corners.len(),
                    }),
                }
            }
            "vt" | "vn" | "vp" | "s" | "l" | "p" | "mtllib" | "usemap" | "maplib"
            | "shadow_obj" | "trace_obj" | "lod" | "bevel" | "c_interp" | "d_interp" => {}
            other => {
                let shown: String = other.chars().take(32).collect();
                warn(
                    &mut out,
                    line_no,
                    format!("unknown statement {shown:?}: ignored"),
                );
            }
        }
    }
    if line_warnings > MAX_LINE_WARNINGS {
        out.warnings.push(LoadWarning {
            file: path.to_path_buf(),
            source_id: String::new(),
            message: format!(
                "{} more unreadable lines not listed",
                line_warnings - MAX_LINE_WARNINGS
            ),
        });
    }
    Ok(out)
}

/// The first three numbers of a `v` line, in (east, north, up); `None` if they are not
/// numbers. A fourth (weight) or colour values are ignored.
fn read_vertex<'a>(words: &mut impl Iterator<Item = &'a str>, up: UpAxis) -> Option<DVec3> {
    let mut next = || words.next()?.parse::<f64>().ok();
    let (x, y, z) = (next()?, next()?, next()?);
    Some(match up {
        UpAxis::Z => DVec3::new(x, y, z),
        UpAxis::Y => DVec3::new(x, -z, y),
    })
}

/// The 0-based vertex of a face corner `i`, `i/t`, `i//n` or `i/t/n`. Positive indices are
/// 1-based and checked against the final vertex count later (some writers refer forward);
/// negative ones count back from the vertices read so far.
fn read_corner(word: &str, vertex_count: usize) -> Result<u32, String> {
    let first = word.split('/').next().unwrap_or("");
    let index: i64 = first
        .parse()
        .map_err(|_| format!("face corner {word:?} is not a vertex index"))?;
    let resolved = match index {
        0 => return Err("face corner index 0 (OBJ indices start at 1)".into()),
        i if i > 0 => i - 1,
        i => vertex_count as i64 + i,
    };
    if resolved < 0 {
        return Err(format!(
            "face corner {index} refers before the first vertex ({vertex_count} read so far)"
        ));
    }
    u32::try_from(resolved).map_err(|_| format!("face corner index {index} is too large"))
}

/// Reads one line into `buf` without its line ending, keeping at most [`MAX_LINE_BYTES`];
/// `Ok(Some(true))` when the line was longer (the rest is skipped), `Ok(None)` at the end.
fn read_line_bounded(
    reader: &mut impl BufRead,
    buf: &mut Vec<u8>,
) -> std::io::Result<Option<bool>> {
    buf.clear();
    let mut truncated = false;
    let mut any = false;
    loop {
        let available = match reader.fill_buf() {
            Ok(b) => b,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(e) => return Err(e),
        };
        if available.is_empty() {
            return Ok(any.then_some(truncated));
        }
        any = true;
        let newline = available.iter().position(|&b| b == b'\n');
        let chunk = &available[..newline.unwrap_or(available.len())];
        let room = MAX_LINE_BYTES.saturating_sub(buf.len());
        if chunk.len() > room {
            truncated = true;
        }
        buf.extend_from_slice(&chunk[..chunk.len().min(room)]);
        let used = newline.map_or(available.len(), |i| i + 1);
        reader.consume(used);
        if newline.is_some() {
            if buf.last() == Some(&b'\r') {
                buf.pop();
            }
            return Ok(Some(truncated));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn corners_resolve_and_refuse() {
        assert_eq!(read_corner("1", 0), Ok(0));
        assert_eq!(read_corner("3/7/2", 5), Ok(2));
        assert_eq!(read_corner("4//1", 5), Ok(3));
        assert_eq!(read_corner("-1", 5), Ok(4));
        assert_eq!(read_corner("-5", 5), Ok(0));
        assert!(read_corner("-6", 5).is_err());
        assert!(read_corner("0", 5).is_err());
        assert!(read_corner("99999999999999999999", 5).is_err());
        assert!(read_corner("9999999999", 5).is_err());
        assert!(read_corner("x", 5).is_err());
        assert!(read_corner("", 5).is_err());
    }

    #[test]
    fn long_lines_are_cut_and_line_endings_dropped() {
        let mut text = b"v 1 2 3\r\n".to_vec();
        text.extend(std::iter::repeat_n(b'f', MAX_LINE_BYTES + 10));
        text.extend_from_slice(b"\nlast");
        let mut reader = BufReader::with_capacity(1000, text.as_slice());
        let mut buf = Vec::new();
        assert_eq!(
            read_line_bounded(&mut reader, &mut buf).unwrap(),
            Some(false)
        );
        assert_eq!(buf, b"v 1 2 3");
        assert_eq!(
            read_line_bounded(&mut reader, &mut buf).unwrap(),
            Some(true)
        );
        assert_eq!(buf.len(), MAX_LINE_BYTES);
        assert_eq!(
            read_line_bounded(&mut reader, &mut buf).unwrap(),
            Some(false)
        );
        assert_eq!(buf, b"last");
        assert_eq!(read_line_bounded(&mut reader, &mut buf).unwrap(), None);
    }

    #[test]
    fn y_up_maps_to_east_north_up() {
        let mut words = "1 2 3".split_ascii_whitespace();
        assert_eq!(
            read_vertex(&mut words, UpAxis::Y),
            Some(DVec3::new(1.0, -3.0, 2.0))
        );
        let mut words = "1 2 nan".split_ascii_whitespace();
        assert!(!read_vertex(&mut words, UpAxis::Z).unwrap().is_finite());
        let mut words = "1 2".split_ascii_whitespace();
        assert_eq!(read_vertex(&mut words, UpAxis::Z), None);
    }
}
