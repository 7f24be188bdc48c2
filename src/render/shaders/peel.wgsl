// One depth-peeling pass over triangle meshes. CPU twin: src/render/raster.rs (functions of the
// same name); the data comes from gpu_types.rs (PeelData).
//
// The vertex stage only places corners (eye-space x, y, depth -> clip space, never clipped: the
// CPU clipped to the near plane already). Each fragment recomputes its depth and texture
// coordinates from its pixel centre's ray and its triangle's plane, so both rasterisers agree to
// rounding, writes that depth (times a power of two) as its depth-buffer value for the LESS
// test, and in passes after the first is discarded unless deeper than the previous layer's
// threshold.

struct PeelParams {
    width: u32,
    height: u32,
    pass_index: u32,
    peeling: u32,
    tan_half_x: f32,
    tan_half_y: f32,
    inverse_depth_scale: f32,
    pixel_tangent: f32,
    aperture_diameter: f32,
    umbra_pixels: f32,
    separation: f32,
    pad: u32,
}

struct PeelTriangle {
    plane: vec4<f32>,
    u_map: vec4<f32>,
    v_map: vec4<f32>,
    material: u32,
    pad0: u32,
    pad1: u32,
    pad2: u32,
}

struct PeelMaterial {
    base_colour: vec3<f32>,
    texture: u32,
    emissive: vec3<f32>,
    pad: u32,
}

struct PeelTexture {
    offset: u32,
    width: u32,
    height: u32,
    wrap_u: u32,
    wrap_v: u32,
    filter_mode: u32,
    pad0: u32,
    pad1: u32,
}

// PEEL_UMBRA, WRAP_*, FILTER_NEAREST, NO_TEXTURE, BEYOND_ALL, MAX_DEPTH and TEXEL_LIMIT come
// from the Rust prelude (src/render/wgsl.rs; gpu_types.rs and raster.rs).

@group(0) @binding(0) var<uniform> params: PeelParams;
@group(0) @binding(1) var<storage, read> triangles: array<PeelTriangle>;
@group(0) @binding(2) var<storage, read> materials: array<PeelMaterial>;
@group(0) @binding(3) var<storage, read> textures: array<PeelTexture>;
@group(0) @binding(4) var<storage, read> texels: array<vec4<f32>>;
// The previous layer: radiance in rgb, depth in a (0 where the pixel had no surface).
@group(0) @binding(5) var previous_layer: texture_2d<f32>;

struct Corner {
    @builtin(position) clip: vec4<f32>,
    @location(0) @interpolate(flat) triangle: u32,
}

@vertex
fn peel_vertex(@location(0) position: vec3<f32>, @location(1) triangle: u32) -> Corner {
    var out: Corner;
    // w = depth gives x / (depth tan) after the divide; z / w = 0.5 keeps every corner inside
    // the depth range (the fragment writes its own depth).
    out.clip = vec4<f32>(
        position.x / params.tan_half_x,
        position.y / params.tan_half_y,
        0.5 * position.z,
        position.z
    );
    out.triangle = triangle;
    return out;
}

fn pixel_ray(x: f32, y: f32) -> vec3<f32> {
    return vec3<f32>(
        (2.0 * x / f32(params.width) - 1.0) * params.tan_half_x,
        (1.0 - 2.0 * y / f32(params.height)) * params.tan_half_y,
        1.0
    );
}

// Depth where the ray meets the plane, or -1 when the fragment is to be dropped.
fn fragment_depth(triangle: PeelTriangle, ray: vec3<f32>) -> f32 {
    let p = triangle.plane;
    let along = p.x * ray.x + p.y * ray.y + p.z * ray.z;
    if !(along > 0.0) {
        return -1.0;
    }
    let depth = p.w / along;
    if !(depth > 0.0 && depth < MAX_DEPTH) {
        return -1.0;
    }
    return depth;
}

fn peel_threshold(previous: f32) -> f32 {
    let plain = previous * (1.0 + params.separation);
    if params.peeling != PEEL_UMBRA {
        return plain;
    }
    let sample = params.pixel_tangent * params.umbra_pixels * previous;
    if sample >= params.aperture_diameter {
        return BEYOND_ALL;
    }
    return max(plain, previous + previous * sample / (params.aperture_diameter - sample));
}

fn depth_buffer_value(depth: f32) -> f32 {
    return min(depth * params.inverse_depth_scale, 1.0);
}

fn wrap_index(i: i32, size: i32, mode: u32) -> i32 {
    if mode == WRAP_REPEAT {
        return ((i % size) + size) % size;
    }
    if mode == WRAP_CLAMP {
        return clamp(i, 0, size - 1);
    }
    let period = 2 * size;
    let m = ((i % period) + period) % period;
    if m >= size {
        return period - 1 - m;
    }
    return m;
}

fn texel(texture: PeelTexture, column: i32, row: i32) -> vec3<f32> {
    let x = wrap_index(column, i32(texture.width), texture.wrap_u);
    let y = wrap_index(row, i32(texture.height), texture.wrap_v);
    return texels[texture.offset + u32(y) * texture.width + u32(x)].rgb;
}

fn mix3(a: vec3<f32>, b: vec3<f32>, t: f32) -> vec3<f32> {
    let u = 1.0 - t;
    return vec3<f32>(a.x * u + b.x * t, a.y * u + b.y * t, a.z * u + b.z * t);
}

fn sample_texture(texture: PeelTexture, uv: vec2<f32>) -> vec3<f32> {
    let size = vec2<f32>(f32(texture.width), f32(texture.height));
    let scaled = clamp(uv * size, vec2<f32>(-TEXEL_LIMIT), vec2<f32>(TEXEL_LIMIT));
    if texture.filter_mode == FILTER_NEAREST {
        return texel(texture, i32(floor(scaled.x)), i32(floor(scaled.y)));
    }
    let x = scaled.x - 0.5;
    let y = scaled.y - 0.5;
    let x0 = floor(x);
    let y0 = floor(y);
    let fx = x - x0;
    let fy = y - y0;
    let c = i32(x0);
    let r = i32(y0);
    let top = mix3(texel(texture, c, r), texel(texture, c + 1, r), fx);
    let bottom = mix3(texel(texture, c, r + 1), texel(texture, c + 1, r + 1), fx);
    return mix3(top, bottom, fy);
}

fn shade(triangle: PeelTriangle, ray: vec3<f32>, depth: f32) -> vec3<f32> {
    let p = vec3<f32>(ray.x * depth, ray.y * depth, depth);
    let um = triangle.u_map;
    let vm = triangle.v_map;
    let uv = vec2<f32>(
        um.x * p.x + um.y * p.y + um.z * p.z + um.w,
        vm.x * p.x + vm.y * p.y + vm.z * p.z + vm.w
    );
    let material = materials[triangle.material];
    var base = vec3<f32>(1.0);
    if material.texture != NO_TEXTURE {
        base = sample_texture(textures[material.texture], uv);
    }
    return material.base_colour * base + material.emissive;
}

struct LayerOut {
    @location(0) layer: vec4<f32>,
    @builtin(frag_depth) depth: f32,
}

@fragment
fn peel_fragment(corner: Corner) -> LayerOut {
    let triangle = triangles[corner.triangle];
    let ray = pixel_ray(corner.clip.x, corner.clip.y);
    let depth = fragment_depth(triangle, ray);
    if depth <= 0.0 {
        discard;
    }
    if params.pass_index > 0u {
        let previous = textureLoad(previous_layer, vec2<i32>(corner.clip.xy), 0).a;
        if previous <= 0.0 || depth <= peel_threshold(previous) {
            discard;
        }
    }
    var out: LayerOut;
    out.layer = vec4<f32>(shade(triangle, ray, depth), depth);
    out.depth = depth_buffer_value(depth);
    return out;
}
