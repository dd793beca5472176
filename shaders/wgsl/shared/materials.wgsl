// Material colours of the city, shared by the scene pass and the cluster texture bake.

// A well-mixed 32-bit hash (lowbias32 by Chris Wellons), for per-building colour variation.
fn hash_u32(x_in: u32) -> u32 {
    var x = x_in;
    x ^= x >> 16u;
    x *= 0x7feb352du;
    x ^= x >> 15u;
    x *= 0x846ca68bu;
    x ^= x >> 16u;
    return x;
}

// sRGB colour to linear (a 2.2 power is close enough for material colours).
fn srgb_to_linear(c: vec3<f32>) -> vec3<f32> {
    return pow(c, vec3<f32>(2.2));
}

// Base colour (linear RGB) of a building: a few facade materials, varied per building.
fn facade_colour(id: u32) -> vec3<f32> {
    let h = hash_u32(id);
    var palette = array<vec3<f32>, 6>(
        vec3<f32>(0.80, 0.72, 0.58), // sandstone
        vec3<f32>(0.64, 0.36, 0.27), // red brick
        vec3<f32>(0.90, 0.88, 0.82), // white render
        vec3<f32>(0.60, 0.61, 0.62), // concrete
        vec3<f32>(0.78, 0.66, 0.48), // yellow stock brick
        vec3<f32>(0.47, 0.56, 0.66), // glass and steel
    );
    let base = palette[h % 6u];
    let jitter = f32((h >> 8u) & 255u) / 255.0;
    return srgb_to_linear(base * (0.88 + 0.2 * jitter));
}

// The bare ground between streets and areas: a plain earth tone (linear RGB).
fn bare_ground_colour() -> vec3<f32> {
    return srgb_to_linear(vec3<f32>(BARE_GROUND_SRGB_R, BARE_GROUND_SRGB_G, BARE_GROUND_SRGB_B));
}

// Roof colour (linear RGB) of a building: greys, varied per building.
fn roof_colour(id: u32) -> vec3<f32> {
    let h = hash_u32(id ^ 0x9e3779b9u);
    let shade = 0.40 + 0.16 * f32(h & 255u) / 255.0;
    return srgb_to_linear(vec3<f32>(shade * 1.02, shade, shade * 0.98));
}
