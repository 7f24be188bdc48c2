// Image-based ray tracing through a lens into a layered depth image.
//
// One invocation per output pixel. For each lens sample it builds the film-side ray (film point to
// exit-pupil point), maps it to an object-space ray with the lens model, clamps that ray to the
// depth range the min/max pyramid allows and walks its footprint over the layers, testing every
// layer of every visited pixel as a square at constant depth. The Rust twin is
// src/render/kernel.rs; keep the two in step statement by statement.
//
// This file is compiled after src/lrtf/lrtf_sample.wgsl (bind group 0: the baked table and the
// pupil circles every model samples in) and lens_trace.wgsl (group 2: the surfaces), and before
// seidel_lens.wgsl (group 3: the Seidel polynomial); see ibrt_shader in src/render/wgsl.rs.

struct FrameParams {
    width: u32,
    height: u32,
    samples_per_pixel: u32,
    seed: u32,
    layer_width: u32,
    layer_height: u32,
    layer_count: u32,
    layer_groups: u32,
    pyramid_levels: u32,
    sample_offset: u32,
    sample_count: u32,
    model: u32,
    film_origin_x: f32,
    film_origin_y: f32,
    film_step_x: f32,
    film_step_y: f32,
    film_z: f32,
    pupil_z: f32,
    pupil_weight: f32,
    focal_length: f32,
    front_principal_z: f32,
    rear_principal_z: f32,
    eye_z: f32,
    tan_half_x: f32,
    tan_half_y: f32,
    near_depth: f32,
    far_depth: f32,
    // Film point of pixel (x, y) = origin + x * column step + y * row step (see film_point);
    // film_z stays the plane through the sensor centre, where the pupil circles were fitted.
    film_origin_z: f32,
    film_step_x_y: f32,
    film_step_x_z: f32,
    film_step_y_x: f32,
    film_step_y_z: f32,
    film_normal_x: f32,
    film_normal_y: f32,
    film_normal_z: f32,
    // Off-plane pupil bound (src/render/models.rs OffPlaneBound).
    pupil_lipschitz: f32,
    pupil_centre_slack: f32,
    // Sample s of this dispatch is lattice point sample_offset + s * sample_stride.
    sample_stride: u32,
}

@group(1) @binding(0) var<uniform> frame: FrameParams;
// Inverse depth (1/mm from the eye) of four layers per pixel; negative = no surface.
@group(1) @binding(1) var<storage, read> layer_depths: array<vec4<f32>>;
// Linear RGB radiance per layer per pixel (alpha unused).
@group(1) @binding(2) var<storage, read> layer_colours: array<vec4<f32>>;
// Min/max inverse depth over all layers, a pyramid of 2x2 reductions, level 0 first.
@group(1) @binding(3) var<storage, read> depth_bounds: array<vec2<f32>>;
// Running sum of weighted radiance per output pixel.
@group(1) @binding(4) var<storage, read_write> radiance_sum: array<vec4<f32>>;

// A chromatic render's channels (render_chromatic only): which block of lrtf_pupil lens samples
// come from, and the paraxial channels' lenses, R, G, B in x, y, z.
struct ChannelParams {
    sampling_block: u32,
    pad0: u32,
    pad1: u32,
    pad2: u32,
    focal_length: vec4<f32>,
    front_principal_z: vec4<f32>,
    rear_principal_z: vec4<f32>,
    exit_pupil_z: vec4<f32>,
    // Squared exit-pupil radius, widened slightly (chromatic.rs, PUPIL_EDGE_TOLERANCE).
    exit_pupil_limit_sq: vec4<f32>,
}

@group(1) @binding(5) var<uniform> channels: ChannelParams;

// PI, MODEL_*, FOOTPRINT_CLAMP_ITERATIONS, DEPTH_TOLERANCE, DEPTH_SLACK, NO_CROSSING,
// MONOCHROME_SAMPLING_BLOCK and the hash constants come from the Rust prelude
// (src/render/wgsl.rs; the values and their reasons are in src/render/kernel.rs).

fn mix_bits(x: u32) -> u32 {
    var h = x;
    h ^= h >> 16u;
    h *= HASH_MULTIPLIER_1;
    h ^= h >> 15u;
    h *= HASH_MULTIPLIER_2;
    h ^= h >> 16u;
    return h;
}

fn unit_from_bits(bits: u32) -> f32 {
    return f32(bits >> 8u) * (1.0 / 16777216.0);
}

// Rank-1 lattice point `index` of `count`, shifted modulo 1 by the two scrambles: x is stratified
// into `count` strata, y follows the golden-ratio sequence. Integer arithmetic only, so every
// backend produces the same bits.
fn lattice_point(index: u32, count: u32, scramble_x: u32, scramble_y: u32) -> vec2<f32> {
    let stratum = 0xffffffffu / max(count, 1u);
    let x_bits = index * stratum + scramble_x;
    let y_bits = index * LATTICE_GOLDEN + scramble_y;
    return vec2<f32>(unit_from_bits(x_bits), unit_from_bits(y_bits));
}

// Shirley-Chiu concentric map from the unit square to the unit disc.
fn concentric_disc(u: vec2<f32>) -> vec2<f32> {
    let a = 2.0 * u - vec2<f32>(1.0, 1.0);
    if (a.x == 0.0 && a.y == 0.0) {
        return vec2<f32>(0.0, 0.0);
    }
    var r: f32;
    var phi: f32;
    if (abs(a.x) > abs(a.y)) {
        r = a.x;
        phi = (PI / 4.0) * (a.y / a.x);
    } else {
        r = a.y;
        phi = PI / 2.0 - (PI / 4.0) * (a.x / a.y);
    }
    return r * vec2<f32>(cos(phi), sin(phi));
}

struct ObjectRay {
    origin: vec3<f32>,
    // Direction of the light (towards +z); the scene lies in the opposite direction.
    direction: vec3<f32>,
    valid: bool,
}

fn paraxial_lens_ray(film: vec3<f32>, pupil: vec3<f32>) -> ObjectRay {
    return paraxial_map(frame.focal_length, frame.front_principal_z, frame.rear_principal_z, film, pupil);
}

// Thin or thick lens: unit magnification between the principal planes, power 1/f.
fn paraxial_map(
    focal_length: f32,
    front_principal_z: f32,
    rear_principal_z: f32,
    film: vec3<f32>,
    pupil: vec3<f32>,
) -> ObjectRay {
    let to_pupil = pupil - film;
    let t = (rear_principal_z - film.z) / to_pupil.z;
    let height = film.xy + t * to_pupil.xy;
    let image_slope = (film.xy - height) / (film.z - rear_principal_z);
    let object_slope = image_slope + height / focal_length;
    return ObjectRay(
        vec3<f32>(height, front_principal_z),
        vec3<f32>(object_slope, 1.0),
        true,
    );
}

fn blocked_ray() -> ObjectRay {
    return ObjectRay(vec3<f32>(0.0), vec3<f32>(0.0, 0.0, 1.0), false);
}

// The object-space ray for the film-side ray from `film` through `pupil`, by the frame's model;
// invalid when the lens blocks it.
fn lens_ray(film: vec3<f32>, pupil: vec3<f32>) -> ObjectRay {
    if frame.model == MODEL_TRACED {
        let traced = trace_lens(film, pupil - film);
        if traced.status != TRACE_OK {
            return blocked_ray();
        }
        return ObjectRay(traced.origin, -traced.direction, true);
    }
    if frame.model == MODEL_BAKED {
        let baked = lrtf_sample(film, normalize(pupil - film));
        if baked.status != LRTF_PASSES {
            return blocked_ray();
        }
        return ObjectRay(baked.origin, -baked.direction, true);
    }
    if frame.model == MODEL_SEIDEL {
        return seidel_lens_ray(film, pupil);
    }
    return paraxial_lens_ray(film, pupil);
}

// Paraxial channel `channel` of a chromatic render: blocked outside the channel's exit pupil,
// else the channel's thin or thick lens.
fn channel_paraxial_ray(channel: u32, film: vec3<f32>, pupil: vec3<f32>) -> ObjectRay {
    let to_pupil = pupil - film;
    let t = (channels.exit_pupil_z[channel] - film.z) / to_pupil.z;
    let crossing = film.xy + t * to_pupil.xy;
    if crossing.x * crossing.x + crossing.y * crossing.y > channels.exit_pupil_limit_sq[channel] {
        return blocked_ray();
    }
    return paraxial_map(
        channels.focal_length[channel],
        channels.front_principal_z[channel],
        channels.rear_principal_z[channel],
        film,
        pupil,
    );
}

// Channel `channel`'s object ray: traced channels' surfaces and baked channels' table layers
// follow each other in the lens bindings, R first.
fn channel_lens_ray(channel: u32, film: vec3<f32>, pupil: vec3<f32>) -> ObjectRay {
    if frame.model == MODEL_PARAXIAL {
        return channel_paraxial_ray(channel, film, pupil);
    }
    lens_first_surface = channel * lens.surface_count;
    lrtf_layer = channel;
    return lens_ray(film, pupil);
}

struct PupilSample {
    point: vec3<f32>,
    weight: f32,
}

// Uniform over the film radius's sampling-pupil circle (lrtf_sampling_pupil_at: its circles from
// block `block` of lrtf_pupil on, bilinear in film radius and focus), its centre turned
// to the film point's azimuth (the disc sample is not turned, so stratification does not flip
// across the axis), the circle widened for a film point off the plane it was fitted on
// (OffPlaneBound in models.rs); weight the disc's area times cos(at the pupil) cos(at the
// sensor) / distance^2, relative to the paraxial exit pupil seen from the film centre.
fn pupil_sample(film: vec3<f32>, lens_u: vec2<f32>, block: u32) -> PupilSample {
    let film_radius = sqrt(film.x * film.x + film.y * film.y);
    var azimuth = vec2<f32>(1.0, 0.0);
    if film_radius > 0.0 {
        azimuth = film.xy / film_radius;
    }
    let circle = lrtf_sampling_pupil_at(film_radius, block);
    let centre = azimuth * circle.x;
    var radius = circle.y;
    if film.z != frame.film_z {
        let growth = frame.pupil_lipschitz * abs(film.z - frame.film_z) / (film.z - frame.pupil_z);
        let drift = length(centre - film.xy);
        radius = (radius + growth * drift + frame.pupil_centre_slack) / (1.0 - growth);
    }
    let disc = concentric_disc(lens_u);
    let pupil = vec3<f32>(centre + radius * disc, frame.pupil_z);
    let to_pupil = pupil - film;
    let distance = length(to_pupil);
    let cos_pupil = abs(to_pupil.z) / distance;
    let normal = vec3<f32>(frame.film_normal_x, frame.film_normal_y, frame.film_normal_z);
    let cos_film = abs(dot(to_pupil, normal)) / distance;
    let reach = (frame.film_z - frame.pupil_z) / distance;
    return PupilSample(pupil, frame.pupil_weight * radius * radius * cos_pupil * cos_film * reach * reach);
}

// The film point at pixel coordinates p (pixel index plus jitter).
fn film_point(p: vec2<f32>) -> vec3<f32> {
    return vec3<f32>(
        frame.film_origin_x + p.x * frame.film_step_x + p.y * frame.film_step_y_x,
        frame.film_origin_y + p.x * frame.film_step_x_y + p.y * frame.film_step_y,
        frame.film_origin_z + p.x * frame.film_step_x_z + p.y * frame.film_step_y_z,
    );
}

// Layer-image coordinates (column, row, inverse depth) of the ray's point at `depth` from the eye.
fn project(ray: ObjectRay, depth: f32) -> vec3<f32> {
    let z = frame.eye_z - depth;
    let t = (z - ray.origin.z) / ray.direction.z;
    let p = ray.origin.xy + t * ray.direction.xy;
    let inverse_depth = 1.0 / depth;
    let column = (p.x * inverse_depth / frame.tan_half_x + 1.0) * 0.5 * f32(frame.layer_width);
    let row = (1.0 - p.y * inverse_depth / frame.tan_half_y) * 0.5 * f32(frame.layer_height);
    return vec3<f32>(column, row, inverse_depth);
}

// Where level `level` of the depth pyramid starts in `depth_bounds`, and its width in texels.
fn pyramid_level(level: u32) -> vec2<u32> {
    var offset = 0u;
    for (var l = 0u; l < level; l += 1u) {
        let w = (frame.layer_width + (1u << l) - 1u) >> l;
        let h = (frame.layer_height + (1u << l) - 1u) >> l;
        offset += w * h;
    }
    let w = (frame.layer_width + (1u << level) - 1u) >> level;
    return vec2<u32>(offset, w);
}

// The pyramid texel over layer pixel (column, row) at `level`, which starts where `pyramid_level`
// says (found once for the four texels a footprint reads).
fn pyramid_texel(start: vec2<u32>, level: u32, column: u32, row: u32) -> vec2<f32> {
    return depth_bounds[start.x + (row >> level) * start.y + (column >> level)];
}

// Min/max inverse depth over the texel rectangle [c0, c1] x [r0, r1], read from the coarsest
// level where the rectangle spans at most 2x2 texels.
fn footprint_bounds(c0: u32, c1: u32, r0: u32, r1: u32) -> vec2<f32> {
    var level = 0u;
    while (level + 1u < frame.pyramid_levels
        && (((c1 >> level) - (c0 >> level)) > 1u || ((r1 >> level) - (r0 >> level)) > 1u)) {
        level += 1u;
    }
    let start = pyramid_level(level);
    let a = pyramid_texel(start, level, c0, r0);
    let b = pyramid_texel(start, level, c1, r0);
    let c = pyramid_texel(start, level, c0, r1);
    let d = pyramid_texel(start, level, c1, r1);
    return vec2<f32>(min(min(a.x, b.x), min(c.x, d.x)), max(max(a.y, b.y), max(c.y, d.y)));
}

struct LayerHit {
    colour: vec3<f32>,
    hit: bool,
}

// The nearest layer at `pixel` whose square lies between the inverse depths where the ray enters
// (w_in) and leaves (w_out) the pixel.
fn hit_in_pixel(pixel: u32, w_in: f32, w_out: f32, slack: f32) -> LayerHit {
    let pixels = frame.layer_width * frame.layer_height;
    let upper = w_in * (1.0 + DEPTH_TOLERANCE) + slack;
    let lower = w_out * (1.0 - DEPTH_TOLERANCE) - slack;
    for (var group = 0u; group < frame.layer_groups; group += 1u) {
        let depths = layer_depths[group * pixels + pixel];
        for (var k = 0u; k < 4u; k += 1u) {
            let layer = group * 4u + k;
            let w = depths[k];
            if (layer >= frame.layer_count || w < 0.0 || w < lower) {
                return LayerHit(vec3<f32>(0.0), false);
            }
            if (w <= upper) {
                return LayerHit(layer_colours[layer * pixels + pixel].xyz, true);
            }
        }
    }
    return LayerHit(vec3<f32>(0.0), false);
}

// Parameter range along a -> b (s in [0, 1]) inside [0, extent] on one axis.
fn clip_axis(a: f32, b: f32, extent: f32, range: vec2<f32>) -> vec2<f32> {
    let d = b - a;
    if (d == 0.0) {
        if (a < 0.0 || a > extent) {
            return vec2<f32>(1.0, 0.0);
        }
        return range;
    }
    let t0 = (0.0 - a) / d;
    let t1 = (extent - a) / d;
    return vec2<f32>(max(range.x, min(t0, t1)), min(range.y, max(t0, t1)));
}

fn axis_crossing(position: f32, direction: f32, cell: i32) -> f32 {
    if (direction > 0.0) {
        return (f32(cell + 1) - position) / direction;
    }
    if (direction < 0.0) {
        return (f32(cell) - position) / direction;
    }
    return NO_CROSSING;
}

fn trace_layers(ray: ObjectRay) -> LayerHit {
    let miss = LayerHit(vec3<f32>(0.0), false);
    if (!ray.valid || ray.direction.z <= 0.0) {
        return miss;
    }
    let a = project(ray, frame.near_depth);
    let b = project(ray, frame.far_depth);
    let lw = f32(frame.layer_width);
    let lh = f32(frame.layer_height);
    var range = clip_axis(a.x, b.x, lw, vec2<f32>(0.0, 1.0));
    range = clip_axis(a.y, b.y, lh, range);
    if (range.x >= range.y) {
        return miss;
    }
    let dw = b.z - a.z;
    let slack = DEPTH_SLACK * (abs(a.z) + abs(b.z));
    for (var i = 0u; i < FOOTPRINT_CLAMP_ITERATIONS; i += 1u) {
        let p = mix(a, b, range.x);
        let q = mix(a, b, range.y);
        let c0 = u32(clamp(floor(min(p.x, q.x)), 0.0, lw - 1.0));
        let c1 = u32(clamp(floor(max(p.x, q.x)), 0.0, lw - 1.0));
        let r0 = u32(clamp(floor(min(p.y, q.y)), 0.0, lh - 1.0));
        let r1 = u32(clamp(floor(max(p.y, q.y)), 0.0, lh - 1.0));
        let bounds = footprint_bounds(c0, c1, r0, r1);
        if (bounds.x > bounds.y) {
            return miss;
        }
        let enter = (bounds.y * (1.0 + DEPTH_TOLERANCE) + slack - a.z) / dw;
        let leave = (bounds.x * (1.0 - DEPTH_TOLERANCE) - slack - a.z) / dw;
        range = vec2<f32>(max(range.x, enter), min(range.y, leave));
        if (range.x > range.y) {
            return miss;
        }
    }
    let start = mix(a, b, range.x);
    let end = mix(a, b, range.y);
    let last_column = i32(frame.layer_width) - 1;
    let last_row = i32(frame.layer_height) - 1;
    var cell = vec2<i32>(
        clamp(i32(floor(start.x)), 0, last_column),
        clamp(i32(floor(start.y)), 0, last_row),
    );
    let end_cell = vec2<i32>(
        clamp(i32(floor(end.x)), 0, last_column),
        clamp(i32(floor(end.y)), 0, last_row),
    );
    let step_x = select(-1, 1, b.x > a.x);
    let step_y = select(-1, 1, b.y > a.y);
    var next_x = axis_crossing(a.x, b.x - a.x, cell.x);
    var next_y = axis_crossing(a.y, b.y - a.y, cell.y);
    let delta_x = select(NO_CROSSING, 1.0 / abs(b.x - a.x), b.x != a.x);
    let delta_y = select(NO_CROSSING, 1.0 / abs(b.y - a.y), b.y != a.y);
    let steps = u32(abs(end_cell.x - cell.x) + abs(end_cell.y - cell.y)) + 1u;
    var s_in = range.x;
    for (var i = 0u; i < steps; i += 1u) {
        let s_out = min(min(next_x, next_y), range.y);
        let pixel = u32(cell.y) * frame.layer_width + u32(cell.x);
        let found = hit_in_pixel(pixel, a.z + s_in * dw, a.z + s_out * dw, slack);
        if (found.hit) {
            return found;
        }
        if (next_x < next_y) {
            cell.x += step_x;
            next_x += delta_x;
        } else {
            cell.y += step_y;
            next_y += delta_y;
        }
        if (cell.x < 0 || cell.x > last_column || cell.y < 0 || cell.y > last_row) {
            return miss;
        }
        s_in = s_out;
    }
    return miss;
}

struct PixelSample {
    film: vec3<f32>,
    lens_u: vec2<f32>,
}

// Lens scrambles (xy) and jitter scrambles (zw) of output pixel `pixel`.
fn pixel_scrambles(pixel: u32) -> vec4<u32> {
    let pixel_key = mix_bits(pixel ^ mix_bits(frame.seed));
    return vec4<u32>(
        mix_bits(pixel_key + 1u),
        mix_bits(pixel_key + 2u),
        mix_bits(pixel_key + 3u),
        mix_bits(pixel_key + 4u),
    );
}

// Sample `index` of output pixel `id`: its film point and unit-square lens sample.
fn pixel_sample(id: vec2<u32>, scrambles: vec4<u32>, index: u32) -> PixelSample {
    let lens_u = lattice_point(index, frame.samples_per_pixel, scrambles.x, scrambles.y);
    let jitter = lattice_point(index, frame.samples_per_pixel, scrambles.z, scrambles.w).yx;
    return PixelSample(film_point(vec2<f32>(f32(id.x), f32(id.y)) + jitter), lens_u);
}

@compute @workgroup_size(8, 8, 1)
fn render(@builtin(global_invocation_id) id: vec3<u32>) {
    if (id.x >= frame.width || id.y >= frame.height) {
        return;
    }
    let pixel = id.y * frame.width + id.x;
    let scrambles = pixel_scrambles(pixel);
    var sum = vec3<f32>(0.0);
    for (var s = 0u; s < frame.sample_count; s += 1u) {
        let at = pixel_sample(id.xy, scrambles, frame.sample_offset + s * frame.sample_stride);
        let sample = pupil_sample(at.film, at.lens_u, MONOCHROME_SAMPLING_BLOCK);
        let found = trace_layers(lens_ray(at.film, sample.point));
        if (found.hit) {
            sum += sample.weight * found.colour;
        }
    }
    radiance_sum[pixel] += vec4<f32>(sum, 0.0);
}

// Chromatic aberration: every sample's film and pupil point traced once per colour channel
// through that channel's lens (R, G, B at their own wavelengths), each keeping its own colour.
// The pupil samples come from a pupil that bounds all three channels' (chromatic.rs).
@compute @workgroup_size(8, 8, 1)
fn render_chromatic(@builtin(global_invocation_id) id: vec3<u32>) {
    if (id.x >= frame.width || id.y >= frame.height) {
        return;
    }
    let pixel = id.y * frame.width + id.x;
    let scrambles = pixel_scrambles(pixel);
    var sum = vec3<f32>(0.0);
    for (var s = 0u; s < frame.sample_count; s += 1u) {
        let at = pixel_sample(id.xy, scrambles, frame.sample_offset + s * frame.sample_stride);
        let sample = pupil_sample(at.film, at.lens_u, channels.sampling_block);
        for (var channel = 0u; channel < 3u; channel += 1u) {
            let found = trace_layers(channel_lens_ray(channel, at.film, sample.point));
            if (found.hit) {
                sum[channel] += sample.weight * found.colour[channel];
            }
        }
    }
    radiance_sum[pixel] += vec4<f32>(sum, 0.0);
}
