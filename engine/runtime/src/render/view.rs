//! Per-view uniforms ([`ViewUniforms`]) from a camera, a viewport and the scene's look.

use citywalk_shaders::ViewUniforms;
use glam::Vec3;

use crate::camera::Camera;

/// The look of the flat-shaded scene: sky, sun and fog.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SceneStyle {
    /// Linear RGB of the sky (clear colour and fog colour).
    pub sky_colour: [f32; 3],
    /// Direction towards the sun (normalised on use): from the south-south-west, 40° high, so
    /// south and west facades are lit and east facades are in shade.
    pub sun_direction: Vec3,
    /// Fog density per metre: the colour is mixed `1 − exp(−density · distance)` towards the
    /// sky. Zero disables fog.
    pub fog_density_per_m: f32,
    /// A draw tinted to stand out (a building or cluster mesh the user picked): its vertices'
    /// id, the draw id.
    pub highlight: Option<u32>,
}

impl Default for SceneStyle {
    fn default() -> Self {
        SceneStyle {
            sky_colour: [0.30, 0.50, 0.82],
            sun_direction: Vec3::new(-0.35, -0.62, 0.70),
            fog_density_per_m: 1.0 / 20_000.0,
            highlight: None,
        }
    }
}

impl SceneStyle {
    /// The sky as a clear colour (linear; an sRGB target stores it encoded).
    pub fn clear_colour(&self) -> wgpu::Color {
        let [r, g, b] = self.sky_colour;
        wgpu::Color {
            r: f64::from(r),
            g: f64::from(g),
            b: f64::from(b),
            a: 1.0,
        }
    }
}

/// The uniforms of one view: camera at the viewport `width_px × height_px`.
pub fn view_uniforms(
    camera: &Camera,
    width_px: u32,
    height_px: u32,
    style: &SceneStyle,
) -> ViewUniforms {
    let aspect = width_px.max(1) as f32 / height_px.max(1) as f32;
    let [r, g, b] = style.sky_colour;
    ViewUniforms {
        view_proj: camera.view_proj(aspect).to_cols_array_2d(),
        camera_position_m: camera.position.extend(1.0).to_array(),
        sun_direction: style
            .sun_direction
            .normalize_or(Vec3::Z)
            .extend(0.0)
            .to_array(),
        sky_colour: [r, g, b, 1.0],
        params: [
            style.fog_density_per_m,
            width_px as f32,
            height_px as f32,
            // Exact as f32 up to 2^24 draws; 0: none.
            style.highlight.map_or(0.0, |id| (id + 1) as f32),
        ],
    }
}
