// The viewer's frame composed from the renderer's running sums where they are held on the GPU:
// the twin of `Viewer::display` (tone map, split view, zone-of-focus tint) and of the HUD's box
// drawn over it, written as 8-bit RGBA rows the window's frame texture copies.

struct DisplayParams {
    width: u32,
    height: u32,
    // Words per row of `frame`: the width padded to the 256-byte rows a texture copy takes.
    row_words: u32,
    split: u32,
    // Running sum to shown radiance: 2^EV over the samples accumulated.
    scale: f32,
    zone: u32,
    hud_width: u32,
    hud_height: u32,
}

@group(0) @binding(0) var<uniform> params: DisplayParams;
@group(0) @binding(1) var<storage, read> view_sums: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> twin_sums: array<vec4<f32>>;
// One bit per pixel, row-major: set where the pixel is in the zone of focus.
@group(0) @binding(3) var<storage, read> zone_bits: array<u32>;
// The HUD text's coverage over its box, one byte per pixel (0 none, 255 full), four a word.
@group(0) @binding(4) var<storage, read> hud_coverage: array<u32>;
@group(0) @binding(5) var<storage, read_write> frame: array<u32>;

// SPLIT_LINE (the split view's grey column) and HUD_SHADE (the opacity of the HUD box's black)
// are prepended from the Rust constants by `compose_shader`.

fn tone_map(linear: f32) -> u32 {
    let x = max(linear, 0.0);
    let compressed = x / (1.0 + x);
    var srgb: f32;
    if compressed <= 0.0031308 {
        srgb = 12.92 * compressed;
    } else {
        srgb = 1.055 * pow(compressed, 1.0 / 2.4) - 0.055;
    }
    return u32(clamp(srgb * 255.0 + 0.5, 0.0, 255.0));
}

@compute @workgroup_size(8, 8)
fn compose(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= params.width || id.y >= params.height {
        return;
    }
    let pixel = id.y * params.width + id.x;
    var rgb: vec3<u32>;
    if params.split != 0u && id.x == params.width / 2u {
        rgb = vec3<u32>(SPLIT_LINE);
    } else {
        var sum = view_sums[pixel];
        if params.split != 0u && id.x > params.width / 2u {
            sum = twin_sums[pixel];
        }
        let shown = sum.xyz * params.scale;
        rgb = vec3<u32>(tone_map(shown.x), tone_map(shown.y), tone_map(shown.z));
    }
    if params.zone != 0u && ((zone_bits[pixel / 32u] >> (pixel % 32u)) & 1u) != 0u {
        rgb = vec3<u32>(rgb.x / 2u, rgb.y / 2u + 128u, rgb.z / 2u);
    }
    if id.x < params.hud_width && id.y < params.hud_height {
        let at = id.y * params.hud_width + id.x;
        let text = f32((hud_coverage[at / 4u] >> (8u * (at % 4u))) & 255u);
        let shaded = vec3<f32>(rgb) * (1.0 - HUD_SHADE);
        rgb = vec3<u32>(round(shaded * (1.0 - text / 255.0) + text));
    }
    frame[id.y * params.row_words + id.x] = rgb.x | (rgb.y << 8u) | (rgb.z << 16u) | (255u << 24u);
}
