// Baked lens ray transfer function lookup: the GPU twin of `LrtfTable::lookup` in
// src/lrtf/table.rs. Same coordinates, same node addressing (nodes at k / (n - 1), both ends
// sampled), same trilinear weights computed in the shader from `textureLoad` (no hardware
// filtering: its ~8-bit sub-texel weights would add error, and rgba32float is not filterable
// everywhere), same aperture test (interpolated margin >= 0) and stop test.
// Layout of the bound data: docs/lrtf.md.

struct LrtfParams {
    rear_plane_z: f32,
    film_plane_z: f32,
    max_film_radius: f32,
    max_rear_radius: f32,
    max_polar_angle: f32,
    // Squared stop radius realising the wanted f-number (baked stop * baked f / wanted f)^2.
    stop_radius_sq: f32,
    // 0 = spherical, 1 = pupil-planes.
    parameterisation: u32,
    // Circles of the coordinate pupil, at the head of lrtf_pupil.
    pupil_count: u32,
    dims: vec3<u32>,
    // The table file format this block was filled from (the sidecar's format_version); a
    // sampler compiled for another format answers LRTF_VERSION_MISMATCH for every ray.
    format_version: u32,
    // The sampling pupil after them: focus_count focus nodes of sampling_count circles each, at
    // film radii sampling_max_film_radius * k / (sampling_count - 1); focus_coordinate places
    // the render's film plane among the nodes (0 at the first).
    sampling_max_film_radius: f32,
    sampling_count: u32,
    focus_count: u32,
    focus_coordinate: f32,
}

// Exit x, exit y, direction a, direction b.
@group(0) @binding(0) var lrtf_transfer: texture_3d<f32>;
// Aperture margin, stop x, stop y, exit z.
@group(0) @binding(1) var lrtf_aux: texture_3d<f32>;
// Pupil circles (centre_x, radius): the coordinate pupil at film radii
// max_film_radius * k / (pupil_count - 1) on the reference film plane (one block of pupil_count
// per bound layer), then the sampling pupil.
@group(0) @binding(2) var<storage, read> lrtf_pupil: array<vec2<f32>>;
@group(0) @binding(3) var<uniform> lrtf: LrtfParams;

// LRTF_PASSES, LRTF_BLOCKED, LRTF_OUTSIDE, LRTF_VERSION_MISMATCH, LRTF_FORMAT_VERSION,
// PARAMETERISATION_* and PI come from the Rust prelude (src/render/wgsl.rs; src/lrtf/table.rs,
// io.rs and param.rs).

struct LrtfResult {
    // Where the ray leaves surface 1, and its unit direction (lens frame, mm).
    origin: vec3<f32>,
    direction: vec3<f32>,
    status: u32,
}

struct LrtfLocated {
    coords: vec3<f32>,
    // cos, sin of the rotation back to the lens frame.
    rotation: vec2<f32>,
    mirror: f32,
    in_domain: bool,
    reaches: bool,
}

// The table layer lookups read. A chromatic render binds one layer per colour channel: layer k's
// nodes follow layer k - 1's along the textures' third axis, and its pupil circles follow layer
// k - 1's in lrtf_pupil (blocks of pupil_count). render_chromatic (ibrt.wgsl) sets it per channel.
var<private> lrtf_layer: u32 = 0u;

// The circle of block `block` of lrtf_pupil at a film radius, linear between the stored radii.
fn lrtf_circle_at(film_radius: f32, block: u32) -> vec2<f32> {
    let n = lrtf.pupil_count;
    let first = block * n;
    if n == 1u || lrtf.max_film_radius <= 0.0 {
        return lrtf_pupil[first];
    }
    let t = clamp(film_radius / lrtf.max_film_radius, 0.0, 1.0) * f32(n - 1u);
    let i = min(u32(floor(t)), n - 2u);
    let f = t - f32(i);
    return mix(lrtf_pupil[first + i], lrtf_pupil[first + i + 1u], f);
}

fn lrtf_pupil_at(film_radius: f32) -> vec2<f32> {
    return lrtf_circle_at(film_radius, lrtf_layer);
}

// The sampling pupil's circle for a film radius on the render's film plane: bilinear in film
// radius and focus, conservative (it holds every passing ray) with the exact pdf 1 / (pi r^2).
// Its circles start at block `block` of lrtf_pupil (offset block * pupil_count): block 1 after
// the coordinate pupil in a monochrome render, after the three channels' in a chromatic one.
fn lrtf_sampling_pupil_at(film_radius: f32, block: u32) -> vec2<f32> {
    let n = lrtf.sampling_count;
    var i = 0u;
    var f = 0.0;
    if n > 1u && lrtf.sampling_max_film_radius > 0.0 {
        let t = clamp(film_radius / lrtf.sampling_max_film_radius, 0.0, 1.0) * f32(n - 1u);
        i = min(u32(floor(t)), n - 2u);
        f = t - f32(i);
    }
    let i1 = min(i + 1u, n - 1u);
    var j = 0u;
    var g = 0.0;
    if lrtf.focus_count > 1u {
        let s = clamp(lrtf.focus_coordinate, 0.0, f32(lrtf.focus_count - 1u));
        j = min(u32(floor(s)), lrtf.focus_count - 2u);
        g = s - f32(j);
    }
    let j1 = min(j + 1u, lrtf.focus_count - 1u);
    let first = block * lrtf.pupil_count;
    let row = first + j * n;
    let row1 = first + j1 * n;
    let near = mix(lrtf_pupil[row + i], lrtf_pupil[row + i1], f);
    let far = mix(lrtf_pupil[row1 + i], lrtf_pupil[row1 + i1], f);
    return mix(near, far, g);
}

fn lrtf_crossing(origin: vec3<f32>, direction: vec3<f32>, z: f32) -> vec2<f32> {
    let t = (z - origin.z) / direction.z;
    return origin.xy + t * direction.xy;
}

fn lrtf_azimuth(p: vec2<f32>) -> vec2<f32> {
    let r = length(p);
    if r > 0.0 {
        return p / r;
    }
    return vec2<f32>(1.0, 0.0);
}

// Rotation by the angle whose (cos, sin) is cs.
fn lrtf_rotate(v: vec2<f32>, cs: vec2<f32>) -> vec2<f32> {
    return vec2<f32>(cs.x * v.x - cs.y * v.y, cs.y * v.x + cs.x * v.y);
}

fn lrtf_in_unit(c: vec3<f32>) -> bool {
    return all(c >= vec3<f32>(0.0)) && all(c <= vec3<f32>(1.0));
}

fn lrtf_locate(origin: vec3<f32>, direction: vec3<f32>) -> LrtfLocated {
    var out: LrtfLocated;
    out.reaches = direction.z < 0.0;
    if !out.reaches {
        return out;
    }
    let rear = lrtf_crossing(origin, direction, lrtf.rear_plane_z);
    if lrtf.parameterisation == PARAMETERISATION_SPHERICAL {
        let cs = lrtf_azimuth(rear);
        let d = lrtf_rotate(direction.xy, vec2<f32>(cs.x, -cs.y));
        out.mirror = select(1.0, -1.0, d.y < 0.0);
        // atan2 rather than acos(-z): near the axis -z rounds to 1 in f32 and acos of it keeps
        // only half the digits of a small angle (measured: 4.9e-5 in direction, 1.4e-3 mm in
        // position against the f64 lookup); atan2 keeps f32 precision there.
        let polar = atan2(length(direction.xy), -direction.z);
        let azimuth = atan2(d.y * out.mirror, d.x);
        out.coords = vec3<f32>(
            length(rear) / lrtf.max_rear_radius,
            polar / lrtf.max_polar_angle,
            azimuth / PI,
        );
        out.rotation = cs;
    } else {
        let film = lrtf_crossing(origin, direction, lrtf.film_plane_z);
        let cs = lrtf_azimuth(film);
        let film_radius = length(film);
        let q = lrtf_rotate(rear, vec2<f32>(cs.x, -cs.y));
        out.mirror = select(1.0, -1.0, q.y < 0.0);
        out.rotation = cs;
        let circle = lrtf_pupil_at(film_radius);
        if circle.y <= 0.0 {
            out.coords = vec3<f32>(film_radius / lrtf.max_film_radius, 2.0, 2.0);
            out.in_domain = false;
            return out;
        }
        out.coords = vec3<f32>(
            film_radius / lrtf.max_film_radius,
            0.5 * ((q.x - circle.x) / circle.y + 1.0),
            q.y * out.mirror / circle.y,
        );
    }
    out.in_domain = lrtf_in_unit(out.coords);
    return out;
}

// Base node index and fraction of a coordinate on n nodes (nodes at k / (n - 1)).
fn lrtf_address(coord: f32, n: u32) -> vec2<f32> {
    let t = clamp(coord, 0.0, 1.0) * f32(n - 1u);
    let i = min(floor(t), f32(n - 2u));
    return vec2<f32>(i, t - i);
}

struct LrtfEntry {
    transfer: vec4<f32>,
    aux: vec4<f32>,
}

fn lrtf_fetch(coords: vec3<f32>) -> LrtfEntry {
    let a0 = lrtf_address(coords.x, lrtf.dims.x);
    let a1 = lrtf_address(coords.y, lrtf.dims.y);
    let a2 = lrtf_address(coords.z, lrtf.dims.z);
    let base = vec3<i32>(i32(a0.x), i32(a1.x), i32(a2.x) + i32(lrtf_layer * lrtf.dims.z));
    let f = vec3<f32>(a0.y, a1.y, a2.y);
    var out: LrtfEntry;
    out.transfer = vec4<f32>(0.0);
    out.aux = vec4<f32>(0.0);
    for (var corner = 0u; corner < 8u; corner++) {
        let d = vec3<u32>(corner & 1u, (corner >> 1u) & 1u, (corner >> 2u) & 1u);
        let w3 = select(vec3<f32>(1.0) - f, f, d == vec3<u32>(1u));
        let w = w3.x * w3.y * w3.z;
        let at = base + vec3<i32>(d);
        out.transfer += w * textureLoad(lrtf_transfer, at, 0);
        out.aux += w * textureLoad(lrtf_aux, at, 0);
    }
    return out;
}

fn lrtf_decode_direction(e: vec2<f32>) -> vec3<f32> {
    if lrtf.parameterisation == PARAMETERISATION_SPHERICAL {
        return vec3<f32>(sin(e.x) * cos(e.y), sin(e.x) * sin(e.y), -cos(e.x));
    }
    let m = dot(e, e);
    return normalize(vec3<f32>(2.0 * e, -(1.0 - m)) / (1.0 + m));
}

fn lrtf_to_lens_frame(v: vec2<f32>, at: LrtfLocated) -> vec2<f32> {
    return lrtf_rotate(vec2<f32>(v.x, v.y * at.mirror), at.rotation);
}

// A film-side ray travelling -z in, the ray leaving the front of the lens out.
fn lrtf_sample(origin: vec3<f32>, direction: vec3<f32>) -> LrtfResult {
    var result: LrtfResult;
    if lrtf.format_version != LRTF_FORMAT_VERSION {
        result.status = LRTF_VERSION_MISMATCH;
        return result;
    }
    let at = lrtf_locate(origin, direction);
    if !at.reaches {
        result.status = LRTF_OUTSIDE;
        return result;
    }
    if !at.in_domain {
        let beyond_film = lrtf.parameterisation == PARAMETERISATION_PUPIL_PLANES && at.coords.x > 1.0;
        result.status = select(LRTF_BLOCKED, LRTF_OUTSIDE, beyond_film);
        return result;
    }
    let v = lrtf_fetch(at.coords);
    let stop = v.aux.yz;
    if v.aux.x < 0.0 || dot(stop, stop) > lrtf.stop_radius_sq {
        result.status = LRTF_BLOCKED;
        return result;
    }
    let exit_xy = lrtf_to_lens_frame(v.transfer.xy, at);
    let d = lrtf_decode_direction(v.transfer.zw);
    result.origin = vec3<f32>(exit_xy, v.aux.w);
    result.direction = vec3<f32>(lrtf_to_lens_frame(d.xy, at), d.z);
    result.status = LRTF_PASSES;
    return result;
}
