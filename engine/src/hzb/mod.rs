//! The hierarchical-Z depth pyramid: its CPU reference (`reference`), which the GPU pass is
//! tested against, and the occlusion test of a box against it.

pub mod build;
pub mod cull;
pub mod reference;

pub use build::HzbPyramid;
pub use cull::{CullResults, HzbCull};
