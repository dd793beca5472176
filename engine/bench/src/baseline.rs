//! The pseudo-mode `decimated`: the whole city decimated to a triangle budget
//! ([`decimate_city`](crate::decimate::decimate_city)) and drawn without culling, measured
//! like every mode against the full-detail brute-force frame (Chang et al. 2008, §9 compare
//! their method with QSlim this way: same budget, image error).
//!
//! Its `false_culls` are not culling errors in the usual sense: a frame counts a visible
//! building (oracle of the full city) whose decimated mesh has no triangles left. `drawn` counts
//! the buildings with triangles left and `culled_fraction` the share without.

use citywalk_scenes::camera_path::CameraPath;
use std::time::Instant;

use crate::mode::Mode;
use crate::pixel_error::pixel_error;
use crate::run::{BenchConfig, BenchError, BenchScene, FrameRecord, pose_camera};
use citywalk_runtime::cpu_clock::CpuClock;
use citywalk_runtime::gpu::GpuContext;
use citywalk_runtime::oracle::Oracle;
use citywalk_runtime::render::targets::OffscreenTarget;
use citywalk_runtime::render::{BruteRenderer, GroundSurfacePass, SurfaceMeshes};
use citywalk_runtime::scene_gpu::SceneGpu;

/// The name the pseudo-mode has in every output.
pub const DECIMATED_MODE: &str = "decimated";

/// How large the decimated city is: `--baseline decimate:N` (triangles), `decimate:P%` (share
/// of the city) or `decimate:MODE` (the mean triangles per frame a measured mode drew on the
/// same scene, over all its paths).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum BaselineTarget {
    Triangles(usize),
    Percent(f64),
    MeanOfMode(Mode),
}

impl BaselineTarget {
    /// Parses `decimate:N`, `decimate:P%` or `decimate:MODE` (MODE an available mode).
    pub fn parse(s: &str) -> Result<BaselineTarget, String> {
        let arg = s.trim().strip_prefix("decimate:").ok_or_else(|| {
            format!(
                "unknown baseline '{s}' (expected decimate:TRIANGLES, decimate:P% or decimate:MODE)"
            )
        })?;
        if let Some(p) = arg.strip_suffix('%') {
            return p
                .trim()
                .parse::<f64>()
                .ok()
                .filter(|p| *p > 0.0 && *p <= 100.0)
                .map(BaselineTarget::Percent)
                .ok_or_else(|| format!("baseline share '{arg}' is not a percentage in (0, 100]"));
        }
        if let Ok(n) = arg.trim().parse::<usize>() {
            return if n == 0 {
                Err("baseline triangle count must be positive".into())
            } else {
                Ok(BaselineTarget::Triangles(n))
            };
        }
        let modes = Mode::parse_list(arg)?;
        match modes.as_slice() {
            [mode] => Ok(BaselineTarget::MeanOfMode(*mode)),
            _ => Err(format!(
                "baseline 'decimate:{arg}' names more than one mode"
            )),
        }
    }

    /// The triangle budget for a scene of `total_triangles` whose measured frames are
    /// `records`; `None` for a mode with no frames of this scene.
    pub fn triangles(
        &self,
        scene: &str,
        total_triangles: usize,
        records: &[FrameRecord],
    ) -> Option<usize> {
        match *self {
            BaselineTarget::Triangles(n) => Some(n),
            BaselineTarget::Percent(p) => {
                Some(((total_triangles as f64 * p / 100.0).round() as usize).max(1))
            }
            BaselineTarget::MeanOfMode(mode) => {
                let rows: Vec<u64> = records
                    .iter()
                    .filter(|r| r.scene == scene && r.mode == mode.name())
                    .map(|r| r.triangles)
                    .collect();
                if rows.is_empty() {
                    return None;
                }
                let mean = rows.iter().sum::<u64>() as f64 / rows.len() as f64;
                Some((mean.round() as usize).max(1))
            }
        }
    }
}

/// Renderers for the decimated pseudo-mode.
#[derive(Debug)]
pub struct DecimatedBaseline {
    brute: BruteRenderer,
    /// The streets and ground areas, over the reference and the decimated city alike.
    surfaces: GroundSurfacePass,
    oracle: Oracle,
}

impl DecimatedBaseline {
    pub fn new(gpu: &GpuContext) -> DecimatedBaseline {
        DecimatedBaseline {
            brute: BruteRenderer::new(gpu, BruteRenderer::PNG_FORMAT),
            surfaces: GroundSurfacePass::new(gpu, BruteRenderer::PNG_FORMAT),
            oracle: Oracle::new(gpu),
        }
    }

    /// Renders `path` with the `decimated` scene (same building ids as `scene`) and measures
    /// every frame against the full scene's oracle and brute-force frame.
    pub fn run_path(
        &mut self,
        gpu: &GpuContext,
        scene: &BenchScene,
        decimated: &SceneGpu,
        path: &CameraPath,
        config: &BenchConfig,
    ) -> Result<Vec<FrameRecord>, BenchError> {
        let (w, h) = (config.width, config.height);
        let target = OffscreenTarget::new(gpu, w, h, BruteRenderer::PNG_FORMAT)?;
        let reference = OffscreenTarget::new(gpu, w, h, BruteRenderer::PNG_FORMAT)?;
        let total = scene.drawable.buildings.building_count();
        let kept: Vec<bool> = (0..total)
            .map(|b| decimated.records.get(b).is_some_and(|r| r.index_count > 0))
            .collect();
        let drawn = kept.iter().filter(|k| **k).count();
        let triangles: u64 = decimated
            .records
            .iter()
            .map(|r| u64::from(r.index_count / 3))
            .sum();
        let mut records = Vec::new();
        if path.poses.is_empty() {
            return Ok(records);
        }
        // Warm-up (pipeline compilation) before timing.
        let surfaces = scene.drawable.surfaces.as_ref();
        self.render(gpu, (decimated, surfaces), &pose_camera(path, 0), &target);
        for i in 0..path.poses.len() {
            let camera = pose_camera(path, i);
            let ids = self
                .oracle
                .id_image(gpu, &scene.drawable.buildings, &camera, w, h)?;
            let visible = citywalk_runtime::oracle::VisibleSet::from_id_image(
                &ids,
                scene.drawable.buildings.building_count(),
            );
            let false_culls = (0..total)
                .filter(|&b| visible.contains(citywalk_scenes::BuildingId(b as u32)) && !kept[b])
                .count();
            self.render(
                gpu,
                (&scene.drawable.buildings, surfaces),
                &camera,
                &reference,
            );
            let reference_rgba = reference.read_colour(gpu)?;
            let (frame_ms, cpu_ms) = self.render(gpu, (decimated, surfaces), &camera, &target);
            let rgba = target.read_colour(gpu)?;
            let error = pixel_error(&reference_rgba, &rgba);
            let bound_px = crate::run::bound_px(scene, &camera);
            let bound = crate::bound::EdgeDistance::of_frame(&reference_rgba, &ids.pixels, w, h)
                .check(&reference_rgba, &rgba, bound_px);
            if let Some(dir) = &config.frames_dir
                && config.png_every > 0
                && i % config.png_every == 0
            {
                let file = dir.join(format!(
                    "{}-{}-{DECIMATED_MODE}-{i:04}.png",
                    scene.name, path.name
                ));
                let image =
                    image::RgbaImage::from_raw(w, h, rgba).ok_or_else(|| BenchError::Write {
                        path: file.clone(),
                        reason: "bad size".into(),
                    })?;
                image.save(&file).map_err(|e| BenchError::Write {
                    path: file.clone(),
                    reason: e.to_string(),
                })?;
            }
            records.push(FrameRecord {
                scene: scene.name.clone(),
                path: path.name.clone(),
                mode: DECIMATED_MODE.to_string(),
                frame: i,
                visible: visible.len(),
                drawn,
                clusters: 0,
                false_culls,
                culled_fraction: if total == 0 {
                    0.0
                } else {
                    1.0 - drawn as f64 / total as f64
                },
                triangles,
                triangle_share: crate::far::triangle_share(scene, triangles),
                distance_diameters: crate::far::distance_in_diameters(scene, &camera),
                draw_calls: total as u32 + 1,
                select_ms: 0.0,
                frame_ms,
                cpu_ms,
                pixel_error_grey: error.grey_fraction,
                pixel_error_colour: error.colour_fraction,
                bound_px,
                differing_px: bound.differing,
                beyond_bound_px: bound.beyond,
                gpu: citywalk_runtime::gpu_timer::GpuTimes::default(),
            });
        }
        Ok(records)
    }

    /// Draws `scene` unculled into `target` and waits for the GPU; returns the wall time and the
    /// thread CPU time of recording and submission (ms), as the bench's single-pass modes.
    fn render(
        &self,
        gpu: &GpuContext,
        (scene, surfaces): (&SceneGpu, Option<&SurfaceMeshes>),
        camera: &citywalk_runtime::camera::Camera,
        target: &OffscreenTarget,
    ) -> (f64, f64) {
        let start = Instant::now();
        let cpu = CpuClock::start();
        let mut encoder = gpu
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("bench decimated"),
            });
        self.brute.encode(
            gpu,
            &mut encoder,
            scene,
            camera,
            &target.colour_view,
            &target.depth,
        );
        if let Some(meshes) = surfaces {
            self.surfaces.encode(
                gpu,
                &mut encoder,
                meshes,
                camera,
                (&target.colour_view, &target.depth),
                &self.brute.style,
            );
        }
        gpu.queue.submit([encoder.finish()]);
        let cpu_ms = cpu.elapsed_ms();
        gpu.wait_idle();
        (start.elapsed().as_secs_f64() * 1e3, cpu_ms)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn targets_parse() {
        assert_eq!(
            BaselineTarget::parse("decimate:5000"),
            Ok(BaselineTarget::Triangles(5000))
        );
        assert_eq!(
            BaselineTarget::parse("decimate:25%"),
            Ok(BaselineTarget::Percent(25.0))
        );
        assert_eq!(
            BaselineTarget::parse("decimate:frustum"),
            Ok(BaselineTarget::MeanOfMode(Mode::Frustum))
        );
        assert!(BaselineTarget::parse("qslim:5").is_err());
        assert!(BaselineTarget::parse("decimate:0").is_err());
        assert!(BaselineTarget::parse("decimate:150%").is_err());
        assert!(
            BaselineTarget::parse("decimate:nonsense")
                .unwrap_err()
                .contains("unknown mode")
        );
    }

    #[test]
    fn budgets() {
        let r = |mode: &str, triangles: u64| FrameRecord {
            scene: "s".into(),
            path: "p".into(),
            mode: mode.into(),
            frame: 0,
            visible: 1,
            drawn: 1,
            clusters: 0,
            false_culls: 0,
            culled_fraction: 0.0,
            triangles,
            triangle_share: 0.0,
            distance_diameters: 0.0,
            draw_calls: 2,
            select_ms: 0.0,
            frame_ms: 1.0,
            cpu_ms: 0.5,
            pixel_error_grey: 0.0,
            pixel_error_colour: 0.0,
            bound_px: 2.0,
            differing_px: 0,
            beyond_bound_px: 0,
            gpu: citywalk_runtime::gpu_timer::GpuTimes::default(),
        };
        let records = [r("frustum", 100), r("frustum", 300), r("brute", 1000)];
        let mean = BaselineTarget::MeanOfMode(Mode::Frustum);
        assert_eq!(mean.triangles("s", 1000, &records), Some(200));
        assert_eq!(mean.triangles("other", 1000, &records), None);
        assert_eq!(
            BaselineTarget::Percent(25.0).triangles("s", 1000, &records),
            Some(250)
        );
    }
}
