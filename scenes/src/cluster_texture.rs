//! Chang et al. 2008 §7, hierarchical textures for the cluster meshes: how much texture each
//! cluster gets ([`bins`]), where each wall of a cluster mesh lies in its side texture
//! ([`side_layout`]), the five roof views with the one a look vector picks ([`roof_views`]),
//! where each cluster's cells lie on its bin's pages of six views ([`atlas`]), and the baked
//! textures as a package stores them ([`baked`]). These are the layout decisions that the
//! texture baker, the cluster meshes' texture coordinates and the runtime's choice of roof
//! view share.

pub mod atlas;
pub mod baked;
pub mod bins;
pub mod roof_views;
pub mod side_layout;
pub mod tables;
