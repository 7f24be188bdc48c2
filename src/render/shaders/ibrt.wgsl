// Image-based ray tracing through a lens into a layered depth image.
//
// One invocation per output pixel. For each lens sample it builds the film-side ray (film point to
// exit-pupil point), maps it to an object-space ray with the lens model, clamps that ray to the
// depth range the min/max pyramid allows under its footprint and marches the pyramid's cells
// along it, skipping every cell whose depth bounds the ray's depths there cannot meet, testing
// every layer of every pixel it reaches as a square at constant depth. The Rust twin is
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
// Where each layer pixel's surfels start in layer_surfels (one entry per pixel and one past
// the last); a pixel's surfels are consecutive, nearest first.
@group(1) @binding(1) var<storage, read> layer_starts: array<u32>;
// 1 / depth (mm from the eye) of each surfel, in layer_surfels' order.
@group(1) @binding(2) var<storage, read> surfel_inverse_depths: array<f32>;
// Each surfel: depth (mm) and linear RGB radiance.
@group(1) @binding(3) var<storage, read> layer_surfels: array<vec4<f32>>;
// Min/max inverse depth over all layers, a pyramid of 2x2 reductions, level 0 first.
@group(1) @binding(4) var<storage, read> depth_bounds: array<vec2<f32>>;
// Running sum of weighted radiance per output pixel.
@group(1) @binding(5) var<storage, read_write> radiance_sum: array<vec4<f32>>;

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

@group(1) @binding(6) var<uniform> channels: ChannelParams;

// Each output pixel's film shift under a focal surface (x, y, z mm, unused), row-major; one zero
// entry when the film is one plane. In group 3 beside the Seidel polynomial, as both entry points
// bind that group whole.
@group(3) @binding(1) var<storage, read> film_shift: array<vec4<f32>>;

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

// sin(x) and cos(x) for |x| <= pi/4: the CPU twin's polynomials (kernel.rs, sin_cos_octant),
// the same arithmetic on every device instead of each device's own builtins.
fn sin_cos_octant(x: f32) -> vec2<f32> {
    let x2 = x * x;
    let sin_tail = ((SIN_TAYLOR_9 * x2 + SIN_TAYLOR_7) * x2 + SIN_TAYLOR_5) * x2 + SIN_TAYLOR_3;
    let cos_tail = (((COS_TAYLOR_10 * x2 + COS_TAYLOR_8) * x2 + COS_TAYLOR_6) * x2 + COS_TAYLOR_4) * x2
        + COS_TAYLOR_2;
    return vec2<f32>(x + x * x2 * sin_tail, 1.0 + x2 * cos_tail);
}

// Shirley-Chiu concentric map from the unit square to the unit disc: the angle within the
// octant is QUARTER_PI times the smaller coordinate over the larger, and the larger one's axis
// decides whether its cosine or its sine is the point's x.
fn concentric_disc(u: vec2<f32>) -> vec2<f32> {
    let a = 2.0 * u - vec2<f32>(1.0, 1.0);
    let x_dominant = abs(a.x) > abs(a.y);
    var r = a.y;
    var ratio = a.x / a.y;
    if x_dominant {
        r = a.x;
        ratio = a.y / a.x;
    }
    // The centre of the square (0 / 0 above) is the centre of the disc.
    if r == 0.0 {
        return vec2<f32>(0.0, 0.0);
    }
    let sin_cos = sin_cos_octant(QUARTER_PI * ratio);
    if x_dominant {
        return r * vec2<f32>(sin_cos.y, sin_cos.x);
    }
    return r * sin_cos;
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

// Width and height in texels of level `level` of the depth pyramid.
fn level_size(level: u32) -> vec2<u32> {
    return vec2<u32>(
        (frame.layer_width + (1u << level) - 1u) >> level,
        (frame.layer_height + (1u << level) - 1u) >> level,
    );
}

// Where level `level` of the depth pyramid starts in `depth_bounds`, and its width in texels.
fn pyramid_level(level: u32) -> vec2<u32> {
    var offset = 0u;
    for (var l = 0u; l < level; l += 1u) {
        let size = level_size(l);
        offset += size.x * size.y;
    }
    return vec2<u32>(offset, level_size(level).x);
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

// The nearest layer at `pixel` whose inverse depth lies in `window` (lower, upper; see
// depth_window).
fn hit_in_pixel(pixel: u32, window: vec2<f32>) -> LayerHit {
    let end = layer_starts[pixel + 1u];
    for (var index = layer_starts[pixel]; index < end; index += 1u) {
        let w = surfel_inverse_depths[index];
        if (w < window.x) {
            return LayerHit(vec3<f32>(0.0), false);
        }
        if (w <= window.y) {
            return LayerHit(layer_surfels[index].yzw, true);
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

// The stretch of an object ray the march walks: its points a (near depth) and b (far depth) in
// layer-image coordinates (column, row, inverse depth), the parameters (0 at a, 1 at b) the image
// and the depth pyramid leave, and the depth tests' absolute slack.
struct Segment {
    a: vec3<f32>,
    b: vec3<f32>,
    range: vec2<f32>,
    slack: f32,
    valid: bool,
}

// The inverse depths (lower, upper) a layer must lie within to be hit while the march passes the
// parameters s_in to s_out; monotone in both, so a window over a longer stretch holds the window
// of every part of it.
fn depth_window(segment: Segment, s_in: f32, s_out: f32) -> vec2<f32> {
    let dw = segment.b.z - segment.a.z;
    let w_in = segment.a.z + s_in * dw;
    let w_out = segment.a.z + s_out * dw;
    return vec2<f32>(
        w_out * (1.0 - DEPTH_TOLERANCE) - segment.slack,
        w_in * (1.0 + DEPTH_TOLERANCE) + segment.slack,
    );
}

// The layer pixel the march starts in.
fn first_pixel(segment: Segment) -> vec2<i32> {
    let start = mix(segment.a, segment.b, segment.range.x);
    return vec2<i32>(
        clamp(i32(floor(start.x)), 0, i32(frame.layer_width) - 1),
        clamp(i32(floor(start.y)), 0, i32(frame.layer_height) - 1),
    );
}

// The ray's stretch between the near and far depth, clipped to the layer image and shrunk
// FOOTPRINT_CLAMP_ITERATIONS times to the depths the pyramid finds under its footprint; invalid
// where nothing is left.
fn layer_segment(ray: ObjectRay) -> Segment {
    let none = Segment(vec3<f32>(0.0), vec3<f32>(0.0), vec2<f32>(1.0, 0.0), 0.0, false);
    if (!ray.valid || ray.direction.z <= 0.0) {
        return none;
    }
    let a = project(ray, frame.near_depth);
    let b = project(ray, frame.far_depth);
    let lw = f32(frame.layer_width);
    let lh = f32(frame.layer_height);
    var range = clip_axis(a.x, b.x, lw, vec2<f32>(0.0, 1.0));
    range = clip_axis(a.y, b.y, lh, range);
    if (range.x >= range.y) {
        return none;
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
            return none;
        }
        let enter = (bounds.y * (1.0 + DEPTH_TOLERANCE) + slack - a.z) / dw;
        let leave = (bounds.x * (1.0 - DEPTH_TOLERANCE) - slack - a.z) / dw;
        range = vec2<f32>(max(range.x, enter), min(range.y, leave));
        if (range.x > range.y) {
            return none;
        }
    }
    return Segment(a, b, range, slack, true);
}

// One image axis of a march: the segment's coordinate at its near end, the inverse of its run
// (0 where the run is too short to cross a grid line before NO_CROSSING), and its step, +1 or
// -1. Grid line k is the edge between pixels k - 1 and k; every crossing is computed from its line
// alone, so a line's crossing is the same number at every pyramid level.
struct Axis {
    start: f32,
    inverse_run: f32,
    step: i32,
}

fn axis_between(a: f32, b: f32) -> Axis {
    let run = b - a;
    var inverse_run = 0.0;
    if (abs(run) * NO_CROSSING > 1.0) {
        inverse_run = 1.0 / run;
    }
    return Axis(a, inverse_run, select(-1, 1, b > a));
}

// The parameter where the segment crosses grid line `line`.
fn axis_crossing(axis: Axis, line: i32) -> f32 {
    if (axis.inverse_run == 0.0) {
        return NO_CROSSING;
    }
    return (f32(line) - axis.start) * axis.inverse_run;
}

// The grid line the march leaves the cell of `level` holding `pixel` through.
fn line_ahead(axis: Axis, pixel: i32, level: u32) -> i32 {
    let cell = pixel >> level;
    if (axis.step > 0) {
        return (cell + 1) << level;
    }
    return cell << level;
}

// The pixel the march enters by crossing `line`.
fn pixel_past(axis: Axis, line: i32) -> i32 {
    return select(line - 1, line, axis.step > 0);
}

// The pixel the march is in along this axis once it has crossed every grid line in the cell of
// `level` holding `pixel` that it crosses before parameter `until` (at `until` too where
// `inclusive`): a binary search, at most `level` crossings.
fn axis_advance(axis: Axis, pixel: i32, level: u32, until: f32, inclusive: bool) -> i32 {
    let first = (pixel >> level) << level;
    let last = first + (1 << level) - 1;
    var reached = pixel;
    for (var k = i32(level) - 1; k >= 0; k -= 1) {
        let candidate = reached + (axis.step << u32(k));
        let line = select(candidate + 1, candidate, axis.step > 0);
        let s = axis_crossing(axis, line);
        if (candidate >= first && candidate <= last && (s < until || (inclusive && s == until))) {
            reached = candidate;
        }
    }
    return reached;
}

// The first layer the segment hits: a DDA over the cells of the depth pyramid, from the
// segment's first pixel. In each cell it forms the depth window from where it is to where it
// leaves the cell, descends into the cell where the cell's bounds meet that window, else leaves
// it in one step, climbing a level when that takes it into another parent cell; at the bottom it
// tests the pixel's layers. Leaving a cell it takes the smaller crossing (a row on a tie) and
// puts itself on the other axis where a pixel-by-pixel DDA would be (axis_advance), so it tests
// the pixels that DDA tests, in its order with its windows, less those whose cell ruled a hit out
// (kernel.rs `march`).
fn march(segment: Segment) -> LayerHit {
    let miss = LayerHit(vec3<f32>(0.0), false);
    let x = axis_between(segment.a.x, segment.b.x);
    let y = axis_between(segment.a.y, segment.b.y);
    let last_column = i32(frame.layer_width) - 1;
    let last_row = i32(frame.layer_height) - 1;
    var pixel = first_pixel(segment);
    var s_in = segment.range.x;
    var level = 0u;
    var level_offset = 0u;
    var level_width = frame.layer_width;
    loop {
        let line = vec2<i32>(line_ahead(x, pixel.x, level), line_ahead(y, pixel.y, level));
        let next = vec2<f32>(axis_crossing(x, line.x), axis_crossing(y, line.y));
        let s_out = min(min(next.x, next.y), segment.range.y);
        let window = depth_window(segment, s_in, s_out);
        if (level == 0u) {
            let found = hit_in_pixel(u32(pixel.y) * frame.layer_width + u32(pixel.x), window);
            if (found.hit) {
                return found;
            }
        } else {
            let texel = level_offset + u32(pixel.y >> level) * level_width + u32(pixel.x >> level);
            let bounds = depth_bounds[texel];
            if (bounds.x <= window.y && bounds.y >= window.x) {
                level -= 1u;
                let size = level_size(level);
                level_offset -= size.x * size.y;
                level_width = size.x;
                continue;
            }
        }
        if (s_out >= segment.range.y) {
            return miss;
        }
        let before = pixel;
        if (next.x < next.y) {
            pixel = vec2<i32>(pixel_past(x, line.x), axis_advance(y, pixel.y, level, next.x, true));
            s_in = next.x;
        } else {
            pixel = vec2<i32>(axis_advance(x, pixel.x, level, next.y, false), pixel_past(y, line.y));
            s_in = next.y;
        }
        if (pixel.x < 0 || pixel.x > last_column || pixel.y < 0 || pixel.y > last_row) {
            return miss;
        }
        let parent = level + 1u;
        if (parent < frame.pyramid_levels
            && ((pixel.x >> parent) != (before.x >> parent) || (pixel.y >> parent) != (before.y >> parent))) {
            let size = level_size(level);
            level_offset += size.x * size.y;
            level = parent;
            level_width = level_size(level).x;
        }
    }
    return miss;
}

fn trace_layers(ray: ObjectRay) -> LayerHit {
    let segment = layer_segment(ray);
    if (!segment.valid) {
        return LayerHit(vec3<f32>(0.0), false);
    }
    return march(segment);
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

// Output pixel `pixel`'s film shift under a focal surface (camera.rs, Camera::film_shifts); the
// last entry's past the end, so the one zero entry bound without a surface shifts nothing.
fn pixel_film_shift(pixel: u32) -> vec3<f32> {
    return film_shift[min(pixel, arrayLength(&film_shift) - 1u)].xyz;
}

// Sample `index` of output pixel `id`: its film point (moved by the pixel's film shift) and
// unit-square lens sample.
fn pixel_sample(id: vec2<u32>, scrambles: vec4<u32>, index: u32) -> PixelSample {
    let lens_u = lattice_point(index, frame.samples_per_pixel, scrambles.x, scrambles.y);
    let jitter = lattice_point(index, frame.samples_per_pixel, scrambles.z, scrambles.w).yx;
    let film = film_point(vec2<f32>(f32(id.x), f32(id.y)) + jitter);
    return PixelSample(film + pixel_film_shift(id.y * frame.width + id.x), lens_u);
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
