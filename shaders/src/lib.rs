//! citywalk shaders: the WGSL sources (validated by naga in `build.rs`, so a broken shader
//! breaks the build) and the `#[repr(C)]` Pod twins of every struct the GPU reads.
