//! citywalk engine: the runtime renderer (wgpu), culling, level of detail, cameras, the viewer
//! and the benchmark. The `citywalk` binary is the command line for everything.

pub mod auto;
pub mod bench;
pub mod camera;
pub mod camera_path_io;
pub mod controller;
pub mod cpu_clock;
pub mod frame;
pub mod gpu;
pub mod gpu_timer;
pub mod hzb;
pub mod lod;
pub mod oracle;
pub mod plan;
pub mod render;
pub mod runner;
pub mod scene_gpu;
pub mod viewer;
