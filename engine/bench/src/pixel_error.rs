//! Image-space error of a culled or simplified frame against the brute-force frame.
//!
//! Chang et al. 2008, §9 (pixel-error evaluation): the share of pixels whose grey level
//! differs, and the share whose colour differs by more than 40 in any channel (8-bit).

/// Per-channel difference above which a pixel counts as a colour error (Chang et al. §9).
pub const COLOUR_THRESHOLD: u8 = 40;

/// The two measures for one frame, as fractions of all pixels in `[0, 1]`.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct PixelError {
    /// Share of pixels whose grey level (Rec. 601 luma, 8-bit) differs at all.
    pub grey_fraction: f64,
    /// Share of pixels differing by more than [`COLOUR_THRESHOLD`] in some channel.
    pub colour_fraction: f64,
}

/// Compares two RGBA8 images of the same size (row-major, 4 bytes a pixel).
///
/// # Panics
/// If the buffers differ in length or are not a whole number of pixels: both come from the
/// same renderer at the same size, so a mismatch is a programming error.
pub fn pixel_error(reference: &[u8], frame: &[u8]) -> PixelError {
    assert_eq!(reference.len(), frame.len(), "images differ in size");
    assert_eq!(reference.len() % 4, 0, "not RGBA8");
    let pixels = reference.len() / 4;
    if pixels == 0 {
        return PixelError::default();
    }
    let (mut grey, mut colour) = (0usize, 0usize);
    for (a, b) in reference.chunks_exact(4).zip(frame.chunks_exact(4)) {
        if luma(a) != luma(b) {
            grey += 1;
        }
        if a.iter()
            .zip(b)
            .take(3)
            .any(|(x, y)| x.abs_diff(*y) > COLOUR_THRESHOLD)
        {
            colour += 1;
        }
    }
    PixelError {
        grey_fraction: grey as f64 / pixels as f64,
        colour_fraction: colour as f64 / pixels as f64,
    }
}

/// Rec. 601 luma of an RGB(A) pixel, rounded to 8 bits.
pub(crate) fn luma(p: &[u8]) -> u8 {
    let y = 0.299 * f64::from(p[0]) + 0.587 * f64::from(p[1]) + 0.114 * f64::from(p[2]);
    y.round().clamp(0.0, 255.0) as u8
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn identical_images_have_no_error() {
        let img = vec![10, 20, 30, 255, 200, 100, 50, 255];
        assert_eq!(pixel_error(&img, &img), PixelError::default());
    }

    #[test]
    fn known_pairs() {
        // Four pixels: same; slight change (grey differs, colour within 40); big change in
        // blue only; alpha-only change (no error).
        let a = vec![
            0, 0, 0, 255, //
            100, 100, 100, 255, //
            50, 50, 50, 255, //
            9, 9, 9, 255,
        ];
        let b = vec![
            0, 0, 0, 255, //
            110, 100, 100, 255, //
            50, 50, 120, 255, //
            9, 9, 9, 0,
        ];
        let e = pixel_error(&a, &b);
        assert_eq!(e.grey_fraction, 0.5);
        assert_eq!(e.colour_fraction, 0.25);
    }

    #[test]
    fn threshold_is_strict() {
        let a = vec![0, 0, 0, 255];
        let at = vec![40, 0, 0, 255];
        let over = vec![41, 0, 0, 255];
        assert_eq!(pixel_error(&a, &at).colour_fraction, 0.0);
        assert_eq!(pixel_error(&a, &over).colour_fraction, 1.0);
    }
}
