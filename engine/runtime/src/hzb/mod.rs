//! The hierarchical-Z depth pyramid: its CPU reference (`reference`), which the GPU passes are
//! tested against, and the occlusion test of a box against it; the GPU pyramid build (`build`)
//! and the GPU occlusion cull (`cull`).
//!
//! Use in a two-phase frame (early pass → pyramid → cull → late pass), with one
//! [`HzbPyramid`] per viewport size (make a new one on resize) and one [`HzbCull`]:
//!
//! ```text
//! early pass: draw last frame's visible set into depth (DepthTarget)
//! pyramid.build(&mut encoder, &depth.view);
//! cull.encode(&gpu, &mut encoder, (&all.records_buffer, Some(&scene.parts_buffer)), n,
//!             &pyramid, view_proj)?;
//! late pass:  multi_draw_indexed_indirect_count(cull.commands_buffer(), 0,
//!                                               cull.count_buffer(), 0, n)
//!             or, without MULTI_DRAW_INDIRECT_COUNT,
//!             multi_draw_indexed_indirect(cull.commands_buffer(), 0, n)
//! cull.status_buffer(): per building CULL_VISIBLE / CULL_FRUSTUM_OUTSIDE / CULL_OCCLUDED
//! ```

pub mod build;
pub mod cull;
pub mod reference;
pub mod tree_cull;

pub use build::HzbPyramid;
pub use cull::{CullResults, HzbCull};
