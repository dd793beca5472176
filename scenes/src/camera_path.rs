//! Camera paths: a documented text format, and default paths generated for any city — a street
//! walk along its streets, a flyover, Chang et al.'s "fly over, then dive in" from the sky to
//! street level, and their far-to-near-to-far overview ([`overview`]) — so the same cameras can
//! be replayed by citywalk and by other engines.
//!
//! # File format (`.path`, UTF-8 text, version 1)
//!
//! ```text
//! citywalk-path 1
//! # Local frame of the scene: metres, x east, y north, z up.
//! # yaw: degrees counter-clockwise from east (0 = east, 90 = north); pitch: degrees, > 0 up.
//! name street
//! fov_y_deg 60
//! pose 12.5 -40.0 1.7 90.0 0.0
//! pose 12.5 -38.6 1.7 90.0 0.0
//! ```
//!
//! The first line is the magic and version. `#` starts a comment; blank lines are ignored.
//! `name` and `fov_y_deg` are optional and come before the first `pose`; each `pose` line is
//! `x y z yaw_deg pitch_deg`, one per frame.

use std::fmt::Write as _;
use std::path::Path;

use geo::{BoundingRect, Contains, Coord, Euclidean, Length, LineString, Point};
use glam::Vec3;
use rstar::{AABB, RTree, RTreeObject};
use serde::{Deserialize, Serialize};

use crate::city::City;

mod overview;

pub use overview::overview;

/// Eye height of a pedestrian (metres).
pub const EYE_HEIGHT_M: f32 = 1.7;
/// Default vertical field of view (degrees).
pub const DEFAULT_FOV_Y_DEG: f32 = 60.0;
const MAGIC: &str = "citywalk-path";
const VERSION: u32 = 1;

/// One camera: position in the local frame and orientation in degrees.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CameraPose {
    pub position: Vec3,
    /// Degrees counter-clockwise from east.
    pub yaw_deg: f32,
    /// Degrees above the horizon.
    pub pitch_deg: f32,
}

/// A sequence of camera poses, one per frame.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CameraPath {
    pub name: String,
    pub fov_y_deg: f32,
    pub poses: Vec<CameraPose>,
}

/// Why a path file could not be read.
#[derive(Debug, thiserror::Error)]
pub enum PathError {
    #[error("{path}: cannot read: {source}")]
    Io {
        path: String,
        #[source]
        source: std::io::Error,
    },
    #[error("{path}:{line}: {reason}")]
    Syntax {
        path: String,
        line: usize,
        reason: String,
    },
}

impl CameraPath {
    /// Writes the path in the text format described in the module documentation.
    pub fn to_text(&self) -> String {
        let mut out = String::new();
        let _ = writeln!(out, "{MAGIC} {VERSION}");
        out.push_str("# Local frame of the scene: metres, x east, y north, z up.\n");
        out.push_str("# yaw: degrees counter-clockwise from east; pitch: degrees, > 0 up.\n");
        let _ = writeln!(out, "name {}", self.name);
        let _ = writeln!(out, "fov_y_deg {}", self.fov_y_deg);
        for p in &self.poses {
            let _ = writeln!(
                out,
                "pose {} {} {} {} {}",
                p.position.x, p.position.y, p.position.z, p.yaw_deg, p.pitch_deg
            );
        }
        out
    }

    /// Parses the text format; `origin` names the source in errors.
    pub fn from_text(text: &str, origin: &str) -> Result<CameraPath, PathError> {
        let err = |line: usize, reason: String| PathError::Syntax {
            path: origin.to_string(),
            line,
            reason,
        };
        let mut lines = text.lines().enumerate().map(|(i, l)| (i + 1, l.trim()));
        let header = lines
            .by_ref()
            .find(|(_, l)| !l.is_empty() && !l.starts_with('#'));
        match header {
            Some((n, l)) => {
                let mut words = l.split_whitespace();
                if words.next() != Some(MAGIC) {
                    return Err(err(n, format!("expected '{MAGIC} {VERSION}' first")));
                }
                let version = words.next().and_then(|v| v.parse::<u32>().ok());
                if version != Some(VERSION) {
                    return Err(err(
                        n,
                        format!("unsupported version (this reads {VERSION})"),
                    ));
                }
            }
            None => return Err(err(1, "empty file".into())),
        }
        let mut path = CameraPath {
            name: String::new(),
            fov_y_deg: DEFAULT_FOV_Y_DEG,
            poses: Vec::new(),
        };
        for (n, line) in lines {
            if line.is_empty() || line.starts_with('#') {
                continue;
            }
            let (key, rest) = line.split_once(char::is_whitespace).unwrap_or((line, ""));
            match key {
                "name" => path.name = rest.trim().to_string(),
                "fov_y_deg" => {
                    let fov: f32 = rest
                        .trim()
                        .parse()
                        .map_err(|_| err(n, format!("bad fov_y_deg '{}'", rest.trim())))?;
                    if !(fov > 1.0 && fov < 179.0) {
                        return Err(err(n, format!("fov_y_deg {fov} outside 1..179")));
                    }
                    path.fov_y_deg = fov;
                }
                "pose" => {
                    let values: Vec<f32> = rest
                        .split_whitespace()
                        .map(|w| w.parse::<f32>())
                        .collect::<Result<_, _>>()
                        .map_err(|e| err(n, format!("bad number in pose: {e}")))?;
                    let [x, y, z, yaw, pitch] = values[..] else {
                        return Err(err(
                            n,
                            format!(
                                "pose needs 5 numbers (x y z yaw pitch), got {}",
                                values.len()
                            ),
                        ));
                    };
                    if !values.iter().all(|v| v.is_finite()) {
                        return Err(err(n, "non-finite number in pose".into()));
                    }
                    if !(-90.0..=90.0).contains(&pitch) {
                        return Err(err(n, format!("pitch {pitch} outside -90..90")));
                    }
                    path.poses.push(CameraPose {
                        position: Vec3::new(x, y, z),
                        yaw_deg: yaw,
                        pitch_deg: pitch,
                    });
                }
                other => return Err(err(n, format!("unknown key '{other}'"))),
            }
        }
        if path.poses.is_empty() {
            return Err(err(text.lines().count().max(1), "no pose".into()));
        }
        Ok(path)
    }

    /// Reads a path file.
    pub fn read(file: &Path) -> Result<CameraPath, PathError> {
        let text = std::fs::read_to_string(file).map_err(|source| PathError::Io {
            path: file.display().to_string(),
            source,
        })?;
        CameraPath::from_text(&text, &file.display().to_string())
    }

    /// Writes a path file.
    pub fn write(&self, file: &Path) -> std::io::Result<()> {
        std::fs::write(file, self.to_text())
    }
}

/// The paths generated for any city, by the names the command line gives them (`bench
/// --paths`, `view --play`, `render --path`): the one list of them.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum GeneratedPath {
    /// [`street_walk`].
    Street,
    /// [`walkthrough`].
    Walk,
    /// [`flyover`].
    Flyover,
    /// [`dive`].
    Dive,
    /// [`overview`].
    Overview,
}

impl GeneratedPath {
    /// Every generated path, in the order help texts list them.
    pub const ALL: [GeneratedPath; 5] = [
        GeneratedPath::Street,
        GeneratedPath::Walk,
        GeneratedPath::Flyover,
        GeneratedPath::Dive,
        GeneratedPath::Overview,
    ];
    /// The paths the benchmark measures unless told otherwise ([`default_paths`]); the overview
    /// is measured on request, for its far views.
    pub const DEFAULT: [GeneratedPath; 4] = [
        GeneratedPath::Street,
        GeneratedPath::Walk,
        GeneratedPath::Flyover,
        GeneratedPath::Dive,
    ];

    /// The name on the command line, and the generated path's [`CameraPath::name`].
    pub fn name(self) -> &'static str {
        match self {
            GeneratedPath::Street => "street",
            GeneratedPath::Walk => "walk",
            GeneratedPath::Flyover => "flyover",
            GeneratedPath::Dive => "dive",
            GeneratedPath::Overview => "overview",
        }
    }

    /// The generated path called `name`, if any.
    pub fn named(name: &str) -> Option<GeneratedPath> {
        Self::ALL.into_iter().find(|g| g.name() == name)
    }

    /// `paths`' names, comma-separated (for help and error messages).
    pub fn list(paths: &[GeneratedPath]) -> String {
        paths.iter().map(|g| g.name()).collect::<Vec<_>>().join(",")
    }

    /// The path for `city`, `frames` poses long.
    pub fn generate(self, city: &City, frames: usize) -> CameraPath {
        match self {
            GeneratedPath::Street => street_walk(city, frames),
            GeneratedPath::Walk => walkthrough(city, frames),
            GeneratedPath::Flyover => flyover(city, frames),
            GeneratedPath::Dive => dive(city, frames),
            GeneratedPath::Overview => overview(city, frames),
        }
    }
}

/// The default paths of a city ([`GeneratedPath::DEFAULT`]), in the order street, walk,
/// flyover, dive.
pub fn default_paths(city: &City, frames: usize) -> Vec<CameraPath> {
    GeneratedPath::DEFAULT
        .iter()
        .map(|g| g.generate(city, frames))
        .collect()
}

/// Where most of the city is: the 5th to 95th percentile of building centres on each axis, and
/// the 95th percentile of building tops. Real extracts have stray buildings far from the dense
/// part (ways that reach out of the extract's box); paths aimed at the full bounds miss the city.
#[derive(Debug, Clone, Copy)]
struct CoreExtent {
    lo: glam::Vec2,
    hi: glam::Vec2,
    top_m: f32,
}

impl CoreExtent {
    fn of(city: &City) -> CoreExtent {
        let mut xs = Vec::with_capacity(city.buildings.len());
        let mut ys = Vec::with_capacity(city.buildings.len());
        let mut tops = Vec::with_capacity(city.buildings.len());
        for b in &city.buildings {
            let (lo, hi) = b.bounds();
            xs.push(0.5 * (lo.x + hi.x));
            ys.push(0.5 * (lo.y + hi.y));
            tops.push(hi.z);
        }
        if xs.is_empty() {
            return CoreExtent {
                lo: glam::Vec2::splat(-50.0),
                hi: glam::Vec2::splat(50.0),
                top_m: 20.0,
            };
        }
        let pick = |v: &mut Vec<f32>, q: f32| {
            v.sort_by(f32::total_cmp);
            v[((v.len() - 1) as f32 * q).round() as usize]
        };
        let mut lo = glam::Vec2::new(pick(&mut xs, 0.05), pick(&mut ys, 0.05));
        let mut hi = glam::Vec2::new(pick(&mut xs, 0.95), pick(&mut ys, 0.95));
        // At least 40 m across, so tiny scenes still get a path.
        let grow = (glam::Vec2::splat(40.0) - (hi - lo)).max(glam::Vec2::ZERO) * 0.5;
        lo -= grow;
        hi += grow;
        CoreExtent {
            lo,
            hi,
            top_m: pick(&mut tops, 0.95).max(10.0),
        }
    }

    fn centre(&self) -> Coord<f64> {
        let c = (self.lo + self.hi) * 0.5;
        Coord {
            x: f64::from(c.x),
            y: f64::from(c.y),
        }
    }

    fn size(&self) -> f32 {
        (self.hi - self.lo).max_element()
    }

    /// The margin (metres) by which walks may leave the core: a tenth of its size plus 30 m.
    fn margin_m(&self) -> f32 {
        0.1 * self.size() + 30.0
    }

    /// Whether `p` is inside the core grown by [`CoreExtent::margin_m`].
    fn contains(&self, p: Coord<f64>) -> bool {
        let m = self.margin_m();
        let (x, y) = (p.x as f32, p.y as f32);
        x >= self.lo.x - m && x <= self.hi.x + m && y >= self.lo.y - m && y <= self.hi.y + m
    }

    /// The core grown by [`CoreExtent::margin_m`], as a polygon.
    fn grown_polygon(&self) -> geo::Polygon<f64> {
        let m = self.margin_m();
        let (lo, hi) = (self.lo - m, self.hi + m);
        geo::Rect::new(
            Coord {
                x: f64::from(lo.x),
                y: f64::from(lo.y),
            },
            Coord {
                x: f64::from(hi.x),
                y: f64::from(hi.y),
            },
        )
        .to_polygon()
    }
}

/// How far around a walk position the buildings' bases tell the ground height.
const GROUND_RADIUS_M: f64 = 30.0;

/// Footprint bounding boxes of the city's buildings, for free-space tests.
struct Obstacles {
    tree: RTree<FootprintBox>,
}

struct FootprintBox {
    building: usize,
    lo: [f64; 2],
    hi: [f64; 2],
}

impl RTreeObject for FootprintBox {
    type Envelope = AABB<[f64; 2]>;
    fn envelope(&self) -> Self::Envelope {
        AABB::from_corners(self.lo, self.hi)
    }
}

impl Obstacles {
    fn new(city: &City) -> Obstacles {
        let boxes = city
            .buildings
            .iter()
            .enumerate()
            .filter_map(|(i, b)| {
                let r = b.footprint.bounding_rect()?;
                Some(FootprintBox {
                    building: i,
                    lo: [r.min().x, r.min().y],
                    hi: [r.max().x, r.max().y],
                })
            })
            .collect();
        Obstacles {
            tree: RTree::bulk_load(boxes),
        }
    }

    /// The ground height at `p`: the median base of the buildings within
    /// [`GROUND_RADIUS_M`] (mesh cities on sloping terrain stand at their own heights; cities
    /// of footprints stand on z = 0), or 0 where no building is near.
    fn ground_m(&self, city: &City, p: Coord<f64>) -> f32 {
        let r = GROUND_RADIUS_M;
        let mut bases: Vec<f32> = self
            .tree
            .locate_in_envelope_intersecting(AABB::from_corners(
                [p.x - r, p.y - r],
                [p.x + r, p.y + r],
            ))
            .map(|b| city.buildings[b.building].base_m)
            .filter(|z| z.is_finite())
            .collect();
        if bases.is_empty() {
            return 0.0;
        }
        bases.sort_by(f32::total_cmp);
        bases[bases.len() / 2]
    }

    /// Whether `p` lies inside a building footprint.
    fn blocked(&self, city: &City, p: Coord<f64>) -> bool {
        self.tree
            .locate_in_envelope_intersecting(AABB::from_point([p.x, p.y]))
            .any(|b| {
                city.buildings[b.building]
                    .footprint
                    .contains(&Point::from(p))
            })
    }
}

/// A street-level walk along the city's streets (the longest chain of connected street
/// segments through the centre), or, for cities without streets, along the longest straight
/// line through free space near the centre. Eye at [`EYE_HEIGHT_M`] above the local ground
/// (the median base of the buildings around, for mesh cities on sloping terrain), looking along
/// the walk.
pub fn street_walk(city: &City, frames: usize) -> CameraPath {
    along_street(city, GeneratedPath::Street.name(), |length| {
        (0..frames).map(|i| spread(i, frames) * length).collect()
    })
}

/// Where frame `i` of `frames` lies from the start (0) to the end (1) of a generated path,
/// evenly spaced; a path of one frame is its start. Exactly `frames` frames, never more:
/// `bench --frames 1` measures one frame.
fn spread(i: usize, frames: usize) -> f64 {
    if frames > 1 {
        i as f64 / (frames - 1) as f64
    } else {
        0.0
    }
}

/// Metres the eye moves between two frames of the [`walkthrough`]: 3 m, so 180 m/s at 60 frames
/// per second, many times a walker's speed (what a frame inherits from the one before is, if
/// anything, understated).
pub const WALKTHROUGH_STEP_M: f64 = 3.0;

/// An interactive walkthrough: the [`street_walk`]'s route at [`WALKTHROUGH_STEP_M`] per frame,
/// centred on the middle of the route (the city's centre), `frames` poses, fewer when the route
/// is shorter. Where the street walk spreads its frames over the whole route (hundreds of metres
/// apart in a large city, each frame nearly a cold start for the two-phase cull, which carries
/// last frame's visible set), this is the walk a user makes in the viewer.
pub fn walkthrough(city: &City, frames: usize) -> CameraPath {
    along_street(city, GeneratedPath::Walk.name(), |length| {
        let span = WALKTHROUGH_STEP_M * frames.saturating_sub(1) as f64;
        let start = ((length - span) * 0.5).max(0.0);
        (0..frames)
            .map(|i| start + i as f64 * WALKTHROUGH_STEP_M)
            .take_while(|&d| d <= length)
            .collect()
    })
}

/// Poses at street level along the city's street route (or free line), at the distances along
/// it that `distances` gives for the route's length, named `name`.
fn along_street(city: &City, name: &str, distances: impl Fn(f64) -> Vec<f64>) -> CameraPath {
    let obstacles = Obstacles::new(city);
    let line = street_route(city).unwrap_or_else(|| free_line(city, &obstacles));
    let length = Euclidean.length(&line);
    let poses = distances(length)
        .into_iter()
        .map(|d| {
            let (p, dir) = point_along(&line, d);
            // Look slightly ahead, smoothing corners.
            let (_, ahead) = point_along(&line, (d + 8.0).min(length));
            let look = dir + ahead;
            CameraPose {
                position: Vec3::new(
                    p.x as f32,
                    p.y as f32,
                    obstacles.ground_m(city, p) + EYE_HEIGHT_M,
                ),
                yaw_deg: look.y.atan2(look.x).to_degrees() as f32,
                pitch_deg: 0.0,
            }
        })
        .collect();
    CameraPath {
        name: name.into(),
        fov_y_deg: DEFAULT_FOV_Y_DEG,
        poses,
    }
}

/// A flyover: a straight pass along the diagonal of the city's dense core at a height above
/// its tall buildings, looking forward and down so that the point looked at runs from one corner
/// of the core to the other.
pub fn flyover(city: &City, frames: usize) -> CameraPath {
    const PITCH_DEG: f32 = -40.0;
    let core = CoreExtent::of(city);
    let altitude = (core.top_m * 2.0).max(0.35 * core.size());
    let (a, b) = (core.lo, core.hi);
    let dir = (b - a).normalize_or(glam::Vec2::X);
    // Horizontal distance from the camera to the point it looks at.
    let lead = altitude / (-PITCH_DEG).to_radians().tan();
    let yaw = dir.y.atan2(dir.x).to_degrees();
    let poses = (0..frames)
        .map(|i| {
            let look_at = a.lerp(b, spread(i, frames) as f32);
            let p = look_at - dir * lead;
            CameraPose {
                position: Vec3::new(p.x, p.y, altitude),
                yaw_deg: yaw,
                pitch_deg: PITCH_DEG,
            }
        })
        .collect();
    CameraPath {
        name: GeneratedPath::Flyover.name().into(),
        fov_y_deg: DEFAULT_FOV_Y_DEG,
        poses,
    }
}

/// Chang et al.'s "fly over, then dive in": from high above the city, looking down, to eye
/// height on a street near the centre, levelling out on the way.
pub fn dive(city: &City, frames: usize) -> CameraPath {
    let obstacles = Obstacles::new(city);
    let core = CoreExtent::of(city);
    let extent = core.size();
    let walk = street_route(city).unwrap_or_else(|| free_line(city, &obstacles));
    let length = Euclidean.length(&walk);
    let (target, dir) = point_along(&walk, 0.5 * length);
    let yaw = dir.y.atan2(dir.x).to_degrees() as f32;
    let ground = Vec3::new(target.x as f32, target.y as f32, EYE_HEIGHT_M);
    let back = -Vec3::new(dir.x as f32, dir.y as f32, 0.0);
    let sky = ground + back * 0.6 * extent + Vec3::Z * (core.top_m * 2.0 + 0.5 * extent);
    let poses = (0..frames)
        .map(|i| {
            let t = spread(i, frames) as f32;
            // Ease in height faster than distance so the end is a street-level glide.
            let s = 1.0 - (1.0 - t).powi(2);
            let mut p = sky.lerp(ground, s);
            p.z = sky.z + (ground.z - sky.z) * (1.0 - (1.0 - t).powi(3));
            let to_target = ground - p;
            let pitch = if t < 1.0 {
                to_target
                    .z
                    .atan2(to_target.truncate().length().max(1e-3))
                    .to_degrees()
                    .clamp(-85.0, 0.0)
            } else {
                0.0
            };
            CameraPose {
                position: p,
                yaw_deg: yaw,
                pitch_deg: pitch * (1.0 - t * t),
            }
        })
        .collect();
    CameraPath {
        name: GeneratedPath::Dive.name().into(),
        fov_y_deg: DEFAULT_FOV_Y_DEG,
        poses,
    }
}

/// The longest chain of connected street polylines starting from the street nearest the
/// city's centre, greedily extended at both ends by the straightest continuation.
fn street_route(city: &City) -> Option<LineString<f64>> {
    let streets: Vec<&LineString<f64>> = city
        .streets
        .iter()
        .filter(|s| s.class.bounds_blocks() && s.line.0.len() >= 2)
        .map(|s| &s.line)
        .collect();
    if streets.is_empty() {
        return None;
    }
    let core = CoreExtent::of(city);
    let centre = core.centre();
    let dist = |l: &LineString<f64>| {
        l.0.iter()
            .map(|c| (c.x - centre.x).hypot(c.y - centre.y))
            .fold(f64::MAX, f64::min)
    };
    let start = streets
        .iter()
        .copied()
        .min_by(|a, b| dist(a).total_cmp(&dist(b)))?;
    let mut route: Vec<Coord<f64>> = start.0.clone();
    let mut used = vec![false; streets.len()];
    if let Some(i) = streets.iter().position(|s| std::ptr::eq(*s, start)) {
        used[i] = true;
    }
    // Endpoints closer than this (metres) count as connected.
    const JOIN_M: f64 = 1.0;
    for _ in 0..2 {
        loop {
            let n = route.len();
            let (end, prev) = (route[n - 1], route[n - 2]);
            let heading = (end.x - prev.x, end.y - prev.y);
            let mut best: Option<(usize, bool, f64)> = None;
            for (i, s) in streets.iter().enumerate() {
                if used[i] {
                    continue;
                }
                for (reversed, first, second) in [
                    (false, s.0[0], s.0[1]),
                    (true, s.0[s.0.len() - 1], s.0[s.0.len() - 2]),
                ] {
                    if (first.x - end.x).hypot(first.y - end.y) > JOIN_M {
                        continue;
                    }
                    let d = (second.x - first.x, second.y - first.y);
                    let cos = (heading.0 * d.0 + heading.1 * d.1)
                        / (heading.0.hypot(heading.1) * d.0.hypot(d.1)).max(1e-9);
                    if best.is_none_or(|b| cos > b.2) {
                        best = Some((i, reversed, cos));
                    }
                }
            }
            // Continue only roughly straight on (within ~60°), like a walker on one street,
            // and only while inside the city's dense core.
            match best {
                Some((i, reversed, cos)) if cos > 0.5 && core.contains(end) => {
                    used[i] = true;
                    let mut pts = streets[i].0.clone();
                    if reversed {
                        pts.reverse();
                    }
                    route.extend(pts.into_iter().skip(1));
                }
                _ => break,
            }
        }
        route.reverse();
    }
    // Keep the longest piece of the route inside the (grown) core.
    use geo::BooleanOps;
    let pieces = core.grown_polygon().clip(
        &geo::MultiLineString::new(vec![LineString::new(route)]),
        false,
    );
    let line = pieces
        .0
        .into_iter()
        .max_by(|a, b| Euclidean.length(a).total_cmp(&Euclidean.length(b)))?;
    (line.0.len() >= 2 && Euclidean.length(&line) > 1.0).then_some(line)
}

/// The longest straight segment through free space among lines through the centre at a few
/// angles and offsets, for cities without streets.
fn free_line(city: &City, obstacles: &Obstacles) -> LineString<f64> {
    let core = CoreExtent::of(city);
    let centre = core.centre();
    let half = f64::from(core.size()).max(20.0) * 0.5;
    let step = (half / 200.0).max(0.5);
    let mut best: Option<(f64, Coord<f64>, Coord<f64>)> = None;
    for angle_i in 0..12 {
        let a = std::f64::consts::PI * angle_i as f64 / 12.0;
        let (dx, dy) = (a.cos(), a.sin());
        for offset_i in -4i32..=4 {
            let off = f64::from(offset_i) * half * 0.1;
            let base = Coord {
                x: centre.x - dy * off,
                y: centre.y + dx * off,
            };
            // Walk from -half to +half; keep the longest run of free samples.
            let mut run_start: Option<f64> = None;
            let mut s = -half;
            while s <= half + step {
                let p = Coord {
                    x: base.x + dx * s,
                    y: base.y + dy * s,
                };
                let free = s <= half && !obstacles.blocked(city, p);
                match (free, run_start) {
                    (true, None) => run_start = Some(s),
                    (false, Some(s0)) => {
                        let len = s - step - s0;
                        if best.is_none_or(|b| len > b.0) {
                            let at = |t: f64| Coord {
                                x: base.x + dx * t,
                                y: base.y + dy * t,
                            };
                            best = Some((len, at(s0), at(s - step)));
                        }
                        run_start = None;
                    }
                    _ => {}
                }
                s += step;
            }
        }
    }
    match best {
        Some((len, a, b)) if len > 1.0 => LineString::new(vec![a, b]),
        _ => LineString::new(vec![
            Coord {
                x: centre.x - half,
                y: centre.y,
            },
            Coord {
                x: centre.x + half,
                y: centre.y,
            },
        ]),
    }
}

/// The point at arc length `s` along `line` and the unit direction of its segment.
fn point_along(line: &LineString<f64>, s: f64) -> (Coord<f64>, Coord<f64>) {
    let mut left = s.max(0.0);
    let mut last = (line.0[0], Coord { x: 1.0, y: 0.0 });
    for seg in line.lines() {
        let d = seg.delta();
        let len = d.x.hypot(d.y);
        if len <= 0.0 {
            continue;
        }
        let dir = Coord {
            x: d.x / len,
            y: d.y / len,
        };
        if left <= len {
            return (
                Coord {
                    x: seg.start.x + dir.x * left,
                    y: seg.start.y + dir.y * left,
                },
                dir,
            );
        }
        left -= len;
        last = (seg.end, dir);
    }
    last
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::city::{Building, BuildingId, BuildingPart, HeightSource, Street, StreetClass};
    use crate::frame::Frame;
    use crate::report::LoadReport;
    use geo::{MultiPolygon, polygon};

    fn block(id: u32, x0: f64, y0: f64, x1: f64, y1: f64, h: f32) -> Building {
        let fp = MultiPolygon::new(vec![polygon![
            (x: x0, y: y0), (x: x1, y: y0), (x: x1, y: y1), (x: x0, y: y1)
        ]]);
        Building {
            id: BuildingId(id),
            source_id: format!("b{id}"),
            footprint: fp.clone(),
            parts: vec![BuildingPart {
                source_id: format!("b{id}"),
                footprint: fp,
                base_m: 0.0,
                top_m: h,
            }],
            base_m: 0.0,
            top_m: h,
            height_source: HeightSource::Tagged,
            mesh: None,
            tags: Default::default(),
        }
    }

    pub(crate) fn city(with_streets: bool) -> City {
        let buildings = vec![
            block(0, -50.0, 5.0, -5.0, 50.0, 20.0),
            block(1, 5.0, 5.0, 50.0, 50.0, 30.0),
            block(2, -50.0, -50.0, -5.0, -5.0, 10.0),
            block(3, 5.0, -50.0, 50.0, -5.0, 60.0),
        ];
        let streets = if with_streets {
            vec![
                Street {
                    source_id: "s0".into(),
                    class: StreetClass::Residential,
                    name: None,
                    tagged_width_m: None,
                    line: LineString::from(vec![(-60.0, 0.0), (0.0, 0.0)]),
                },
                Street {
                    source_id: "s1".into(),
                    class: StreetClass::Residential,
                    name: None,
                    tagged_width_m: None,
                    line: LineString::from(vec![(0.0, 0.0), (60.0, 0.0)]),
                },
                Street {
                    source_id: "s2".into(),
                    class: StreetClass::Residential,
                    name: None,
                    tagged_width_m: None,
                    line: LineString::from(vec![(0.0, -60.0), (0.0, 60.0)]),
                },
            ]
        } else {
            vec![]
        };
        City {
            frame: Frame::local(),
            buildings,
            streets,
            ground_areas: Vec::new(),
            report: LoadReport::default(),
        }
    }

    #[test]
    fn text_round_trip() {
        let path = default_paths(&city(true), 7).remove(0);
        let text = path.to_text();
        let back = CameraPath::from_text(&text, "mem").unwrap();
        assert_eq!(back, path);
    }

    #[test]
    fn bad_files_name_the_line() {
        let e = CameraPath::from_text("citywalk-path 1\npose 1 2 3\n", "f.path").unwrap_err();
        assert!(e.to_string().contains("f.path:2"), "{e}");
        assert!(CameraPath::from_text("hello\n", "f").is_err());
        assert!(CameraPath::from_text("citywalk-path 2\npose 0 0 0 0 0\n", "f").is_err());
        assert!(CameraPath::from_text("citywalk-path 1\n", "f").is_err());
        assert!(CameraPath::from_text("citywalk-path 1\npose 0 0 NaN 0 0\n", "f").is_err());
        assert!(CameraPath::from_text("citywalk-path 1\npose 0 0 0 0 95\n", "f").is_err());
    }

    #[test]
    fn street_walk_follows_the_straight_street_at_eye_height() {
        let c = city(true);
        let p = street_walk(&c, 20);
        assert_eq!(p.poses.len(), 20);
        let obstacles = Obstacles::new(&c);
        for pose in &p.poses {
            assert_eq!(pose.position.z, EYE_HEIGHT_M);
            let at = Coord {
                x: f64::from(pose.position.x),
                y: f64::from(pose.position.y),
            };
            assert!(!obstacles.blocked(&c, at), "{pose:?} inside a building");
        }
        // The walk joins s0 and s1 straight on, 120 m along y = 0.
        let first = p.poses[0].position;
        let last = p.poses[19].position;
        assert!((first - last).length() > 100.0, "{first} {last}");
    }

    #[test]
    fn walkthrough_steps_along_the_street_from_its_middle() {
        let c = city(true);
        let street = street_walk(&c, 20);
        let walk = walkthrough(&c, 10);
        assert_eq!(walk.name, "walk");
        assert_eq!(walk.poses.len(), 10);
        for pair in walk.poses.windows(2) {
            let step = (pair[1].position - pair[0].position).length();
            assert!(
                (f64::from(step) - WALKTHROUGH_STEP_M).abs() < 1e-3,
                "{step}"
            );
            assert_eq!(pair[0].yaw_deg, street.poses[0].yaw_deg, "straight street");
        }
        // Centred: as far from the street walk's first pose as its last from the street's end.
        let (first, last) = (walk.poses[0].position, walk.poses[9].position);
        let (start, end) = (street.poses[0].position, street.poses[19].position);
        assert!(((first - start).length() - (end - last).length()).abs() < 1e-2);
        // A route shorter than the walk: it stops at the route's end.
        let long = walkthrough(&c, 1000);
        assert!(
            long.poses.len() < 1000 && long.poses.len() > 30,
            "{}",
            long.poses.len()
        );
    }

    /// Issue 14: `bench --frames 1` gave 2 frames (every generator raised the count to 2).
    #[test]
    fn issue14_small_generated_paths_have_exactly_the_frames_asked_for() {
        let c = city(true);
        for frames in [0, 1, 2, 7] {
            for g in GeneratedPath::ALL {
                let path = g.generate(&c, frames);
                assert_eq!(path.poses.len(), frames, "{} with {frames}", path.name);
            }
        }
        // One frame is the path's start.
        assert_eq!(street_walk(&c, 1).poses[0], street_walk(&c, 5).poses[0]);
        assert_eq!(flyover(&c, 1).poses[0], flyover(&c, 5).poses[0]);
        assert_eq!(dive(&c, 1).poses[0], dive(&c, 5).poses[0]);
    }

    #[test]
    fn generated_paths_are_named_as_the_command_line_names_them() {
        let c = city(true);
        for g in GeneratedPath::ALL {
            assert_eq!(g.generate(&c, 2).name, g.name());
            assert_eq!(GeneratedPath::named(g.name()), Some(g));
        }
        assert_eq!(GeneratedPath::named("street.path"), None);
        assert_eq!(
            GeneratedPath::list(&GeneratedPath::DEFAULT),
            "street,walk,flyover,dive"
        );
        let names: Vec<String> = default_paths(&c, 2).into_iter().map(|p| p.name).collect();
        assert_eq!(names, ["street", "walk", "flyover", "dive"]);
    }

    #[test]
    fn street_walk_stands_on_the_buildings_ground() {
        let flat = city(true);
        let mut raised = flat.clone();
        for b in &mut raised.buildings {
            b.base_m += 10.0;
            b.top_m += 10.0;
        }
        let (low, high) = (street_walk(&flat, 12), street_walk(&raised, 12));
        for (a, b) in low.poses.iter().zip(&high.poses) {
            assert_eq!(a.position.z, EYE_HEIGHT_M, "{a:?}");
            assert!((b.position.z - (10.0 + EYE_HEIGHT_M)).abs() < 1e-4, "{b:?}");
        }
    }

    #[test]
    fn free_line_avoids_buildings_without_streets() {
        let c = city(false);
        let p = street_walk(&c, 30);
        let obstacles = Obstacles::new(&c);
        for pose in &p.poses {
            let at = Coord {
                x: f64::from(pose.position.x),
                y: f64::from(pose.position.y),
            };
            assert!(!obstacles.blocked(&c, at), "{pose:?} inside a building");
        }
    }

    #[test]
    fn flyover_is_above_the_city_and_dive_ends_at_street_level() {
        let c = city(true);
        let f = flyover(&c, 10);
        assert!(f.poses.iter().all(|p| p.position.z > 60.0));
        let d = dive(&c, 10);
        assert!(d.poses[0].position.z > 100.0);
        assert!(d.poses[0].pitch_deg < -10.0);
        let end = d.poses[9];
        assert!((end.position.z - EYE_HEIGHT_M).abs() < 1e-3);
        assert!(end.pitch_deg.abs() < 1e-3);
        // Monotone descent.
        assert!(
            d.poses
                .windows(2)
                .all(|w| w[1].position.z <= w[0].position.z)
        );
    }
}
