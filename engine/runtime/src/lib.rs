//! citywalk runtime: the GPU scene, the frame's passes (two-phase hierarchical-Z culling with
//! virtual occluders), the frame plan and its runner, the LOD cut, cameras and controllers. It
//! links wgpu, glam, the scene model and the shaders, and nothing for windows, UI, plots, the
//! command line or preprocessing: the viewer (`citywalk-viewer`), the benchmark
//! (`citywalk-bench`) and the `citywalk` binary build on it.

pub mod auto;
pub mod camera;
pub mod camera_path_io;
pub mod cluster_textures;
pub mod controller;
pub mod cpu_clock;
pub mod drawable;
pub mod frame;
pub mod gpu;
pub mod gpu_timer;
pub mod hzb;
pub mod lod;
pub mod oracle;
pub mod pick;
pub mod plan;
pub mod render;
pub mod runner;
pub mod scene_gpu;
pub mod texture_bake;
pub mod upload;
