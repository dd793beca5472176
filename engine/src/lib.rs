//! citywalk engine: the runtime renderer (wgpu), culling, level of detail, cameras, the viewer
//! and the benchmark. The `citywalk` binary is the command line for everything.
