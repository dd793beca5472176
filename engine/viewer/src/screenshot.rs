//! Turning a frame read back from the GPU ([`citywalk_runtime::render::targets::read_texture`]) into an
//! RGBA image (for `--screenshot`).

/// Why read-back pixels could not become an image.
#[derive(Debug, thiserror::Error)]
pub enum ScreenshotError {
    #[error("cannot convert texture format {0:?} (8-bit RGBA or BGRA only)")]
    Format(wgpu::TextureFormat),
    #[error("{got} bytes read back for a {width}x{height} frame")]
    Length { got: usize, width: u32, height: u32 },
    #[error(transparent)]
    Readback(#[from] citywalk_runtime::render::ReadbackError),
}

/// Whether `format` is one [`to_rgba_image`] converts.
pub fn is_rgba8_or_bgra8(format: wgpu::TextureFormat) -> bool {
    matches!(
        format,
        wgpu::TextureFormat::Rgba8Unorm
            | wgpu::TextureFormat::Rgba8UnormSrgb
            | wgpu::TextureFormat::Bgra8Unorm
            | wgpu::TextureFormat::Bgra8UnormSrgb
    )
}

/// Tightly packed texels of `format` → an opaque RGBA image (alpha forced to 255: the window
/// is opaque whatever the driver leaves in alpha).
pub fn to_rgba_image(
    mut texels: Vec<u8>,
    width: u32,
    height: u32,
    format: wgpu::TextureFormat,
) -> Result<image::RgbaImage, ScreenshotError> {
    if !is_rgba8_or_bgra8(format) {
        return Err(ScreenshotError::Format(format));
    }
    let bgra = matches!(
        format,
        wgpu::TextureFormat::Bgra8Unorm | wgpu::TextureFormat::Bgra8UnormSrgb
    );
    let length_error = |got| ScreenshotError::Length { got, width, height };
    if texels.len() != width as usize * height as usize * 4 {
        return Err(length_error(texels.len()));
    }
    for px in texels.chunks_exact_mut(4) {
        if bgra {
            px.swap(0, 2);
        }
        px[3] = 255;
    }
    let got = texels.len();
    image::RgbaImage::from_raw(width, height, texels).ok_or_else(|| length_error(got))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bgra_is_swizzled_and_alpha_forced() {
        let texels = vec![1, 2, 3, 0, 10, 20, 30, 40];
        let image = to_rgba_image(texels.clone(), 2, 1, wgpu::TextureFormat::Bgra8UnormSrgb)
            .expect("converts");
        assert_eq!(image.as_raw(), &vec![3, 2, 1, 255, 30, 20, 10, 255]);
        let image =
            to_rgba_image(texels.clone(), 1, 2, wgpu::TextureFormat::Rgba8Unorm).expect("converts");
        assert_eq!(image.as_raw(), &vec![1, 2, 3, 255, 10, 20, 30, 255]);
        assert!(to_rgba_image(texels.clone(), 2, 2, wgpu::TextureFormat::Rgba8Unorm).is_err());
        assert!(to_rgba_image(texels, 2, 1, wgpu::TextureFormat::Rgba16Float).is_err());
    }
}
