//! citywalk preprocessing: the offline geometry that turns a [`citywalk_scenes::City`] into a
//! scene package — virtual occluders (Germs & Jansen), the legibility cluster tree (Chang et
//! al., Yang et al.), urban blocks and the B-Quadtree (Pina et al.).

pub mod blocks;
pub mod cluster;
pub mod memory_budget;
pub mod occluders;
pub mod pipeline;
pub mod quadtree;
pub mod tile_jobs;
pub mod tile_occluders;
pub mod tiles;
