//! Ring geometry shared by the cluster-tree builder and its invariant checker.

pub use citywalk_scenes::cluster_tree::ring::*;
