//! citywalk scenes: the [`City`] model, its loaders (OSM PBF, GeoJSON, CityJSON, glTF),
//! procedural cities, camera paths and the scene-package format.
//!
//! Every loader turns one input into the same [`City`] in a local metric frame
//! (east, north, up), with a [`LoadReport`] in which `loaded + rejected = found`.

pub mod blocks;
pub mod camera_path;
pub mod city;
pub mod city_sphere;
pub mod cluster_texture;
pub mod cluster_tree;
pub mod cull_parts;
pub mod export;
pub mod extrude;
pub mod frame;
pub mod frustum;
pub mod generate;
pub mod ground_surfaces;
pub mod load;
pub mod mesh_footprint;
pub mod occluder;
pub mod occluder_draws;
mod overlay_guard;
pub use overlay_guard::panic_message;
pub mod package;
pub mod process_memory;
pub mod quadtree;
pub mod report;
pub mod scene_geometry;
pub mod tags;
pub mod validate;

pub use city::{
    Building, BuildingId, BuildingPart, City, GroundArea, GroundClass, HeightSource, Street,
    StreetClass, TriangleMesh,
};
pub use frame::{Crs, Frame};
pub use load::{LoadOptions, load_cities, load_city};
pub use report::{LoadError, LoadReport, LoadWarning, RejectReason, Rejection};
pub use tags::Tags;
