// The exact sequential trace through a lens, backward (film side to object side, travelling -z),
// in f32: the port of src/trace (intersect.rs, refract.rs, aperture.rs, Tracer::cross), statement
// by statement. The Rust f64 tracer is its oracle: tests/shader_twins.rs traces the same rays
// through both for every surface kind and outcome.
//
// Per surface, as in the Rust tracer: intersect the vertex sheet in the travel sense (a miss is
// TRACE_MISSED), test the clear semi-aperture and, on the stop, the blades (TRACE_VIGNETTED),
// then refract (a negative Snell radicand is TRACE_TIR). No NaN leaves: every division that
// could produce one is guarded and turns into a miss.

struct LensSurface {
    vertex_z: f32,
    curvature: f32,
    conic_factor: f32,
    semi_aperture_sq: f32,
    mu: f32,
    search_radius: f32,
    kind: u32,
    asphere_terms: u32,
    same_medium: u32,
    bladed: u32,
    reflects: u32,
    obscuration_sq: f32,
    ideal_power: f32,
    coefficients: array<f32, 10>,
}

struct LensParams {
    surface_count: u32,
    blade_count: u32,
    has_arc: u32,
    pad: u32,
    blade_rotation: f32,
    blade_apothem: f32,
    arc_centre: f32,
    arc_radius_sq: f32,
}

@group(2) @binding(0) var<storage, read> lens_surfaces: array<LensSurface>;
@group(2) @binding(1) var<uniform> lens: LensParams;

// The entry of lens_surfaces where the traced lens starts. A chromatic render stores one lens per
// colour channel, each after the one before (surface_count entries each); render_chromatic
// (ibrt.wgsl) sets it per channel.
var<private> lens_first_surface: u32 = 0u;

// SURFACE_*, TRACE_*, ASPHERE_* and PI come from the Rust prelude (src/render/wgsl.rs).

struct SurfaceHit {
    point: vec3<f32>,
    normal: vec3<f32>,
    hit: bool,
}

struct TracedRay {
    // For TRACE_OK the ray leaving surface 1; otherwise where the trace stopped.
    origin: vec3<f32>,
    direction: vec3<f32>,
    status: u32,
    // 1-based surface where the trace stopped (0 for TRACE_OK).
    surface: u32,
}

fn no_hit() -> SurfaceHit {
    return SurfaceHit(vec3<f32>(0.0), vec3<f32>(0.0), false);
}

fn intersect_plane(p: vec3<f32>, d: vec3<f32>, sense: f32) -> SurfaceHit {
    if !(d.z * sense > 0.0) {
        return no_hit();
    }
    let t = -p.z / d.z;
    return SurfaceHit(vec3<f32>(p.xy + t * d.xy, 0.0), vec3<f32>(0.0, 0.0, -1.0), true);
}

// The root of a t^2 - 2 b t + c = 0 on the vertex sheet in the travel sense, in whichever of
// its two forms adds numbers of the same sign (src/trace/intersect.rs); x = t, y = 1 when it
// exists. A zero denominator is the f64 tracer's non-finite root: no hit.
fn quadratic_root(a: f32, b: f32, c: f32, sense: f32) -> vec2<f32> {
    let disc = b * b - a * c;
    if !(disc >= 0.0) {
        return vec2<f32>(0.0, 0.0);
    }
    let root = sqrt(disc);
    if sense * b >= 0.0 {
        let denominator = b + sense * root;
        if denominator == 0.0 {
            return vec2<f32>(0.0, 0.0);
        }
        return vec2<f32>(c / denominator, 1.0);
    }
    if a == 0.0 {
        return vec2<f32>(0.0, 0.0);
    }
    return vec2<f32>((b - sense * root) / a, 1.0);
}

// The point of the line p + t d (d unit) nearest the vertex: from a distant start the
// quadratic's coefficients grow as the squared distance and cancel to garbage.
fn nearest_to_vertex(p: vec3<f32>, d: vec3<f32>) -> vec3<f32> {
    return p - dot(p, d) * d;
}

// The sphere c (x^2 + y^2 + z^2) - 2 z = 0 on its vertex sheet; its normal (c x, c y, c z - 1)
// is unit on the sphere.
fn intersect_sphere(p0: vec3<f32>, d: vec3<f32>, c: f32, sense: f32) -> SurfaceHit {
    let p = nearest_to_vertex(p0, d);
    let b = d.z - c * dot(p, d);
    let cc = c * dot(p, p) - 2.0 * p.z;
    let root = quadratic_root(c, b, cc, sense);
    if root.y == 0.0 {
        return no_hit();
    }
    let q = p + root.x * d;
    let nz = c * q.z - 1.0;
    if !(nz < 0.0) {
        return no_hit();
    }
    return SurfaceHit(q, vec3<f32>(c * q.x, c * q.y, nz), true);
}

// The conic c (x^2 + y^2 + e z^2) - 2 z = 0 (e = 1 + k) on its vertex sheet.
fn intersect_conic(p0: vec3<f32>, d: vec3<f32>, c: f32, e: f32, sense: f32) -> SurfaceHit {
    let p = nearest_to_vertex(p0, d);
    let a = c * (d.x * d.x + d.y * d.y + e * d.z * d.z);
    let b = d.z - c * (p.x * d.x + p.y * d.y + e * p.z * d.z);
    let cc = c * (p.x * p.x + p.y * p.y + e * p.z * p.z) - 2.0 * p.z;
    let root = quadratic_root(a, b, cc, sense);
    if root.y == 0.0 {
        return no_hit();
    }
    let q = p + root.x * d;
    let nz = c * e * q.z - 1.0;
    if !(nz < 0.0) {
        return no_hit();
    }
    return SurfaceHit(q, normalize(vec3<f32>(c * q.x, c * q.y, nz)), true);
}

// Sag and d(sag)/d(r^2) at rho = r^2 (z = 1 when the conic base exists there).
fn asphere_sag(rho: f32, s: LensSurface) -> vec3<f32> {
    let c = s.curvature;
    let under = 1.0 - s.conic_factor * c * c * rho;
    if !(under > 0.0) {
        return vec3<f32>(0.0, 0.0, 0.0);
    }
    let root = sqrt(under);
    var sag = c * rho / (1.0 + root);
    var slope = 0.5 * c / root;
    // Horner in r^2, or in r for an odd asphere (d/d(r^2) = d/dr / (2 r); on the axis the
    // r^2 coefficient).
    let odd = s.kind == SURFACE_ODD_ASPHERE;
    var x = rho;
    if odd {
        x = sqrt(rho);
    }
    var poly = 0.0;
    var dpoly = 0.0;
    for (var k = 0u; k < s.asphere_terms; k += 1u) {
        let i = s.asphere_terms - 1u - k;
        let a = s.coefficients[i];
        poly = poly * x + a;
        dpoly = dpoly * x + f32(i + 1u) * a;
    }
    sag += poly * x;
    if !odd {
        slope += dpoly;
    } else if x > 0.0 {
        slope += dpoly / (2.0 * x);
    } else {
        // Zero-padded when the asphere has no r^2 term.
        slope += s.coefficients[1];
    }
    return vec3<f32>(sag, slope, 1.0);
}

// Accepts an asphere crossing only in the travel sense.
fn finish_asphere(q: vec3<f32>, gradient: vec3<f32>, d: vec3<f32>, sense: f32) -> SurfaceHit {
    let normal = normalize(gradient);
    if sense * dot(normal, d) < 0.0 {
        return SurfaceHit(q, normal, true);
    }
    return no_hit();
}

// Newton on the ray parameter from the conic base's crossing (or the vertex plane's), from the
// line's point nearest the vertex; steps bounded by the search radius, and once two iterates
// bracket the surface every step stays inside the bracket (one that would leave it bisects).
fn intersect_asphere(p0: vec3<f32>, d: vec3<f32>, s: LensSurface, sense: f32) -> SurfaceHit {
    let p = nearest_to_vertex(p0, d);
    var start = intersect_conic(p, d, s.curvature, s.conic_factor, sense);
    if !start.hit {
        start = intersect_plane(p, d, sense);
        if !start.hit {
            return no_hit();
        }
    }
    var t = dot(start.point - p, d);
    let max_step = s.search_radius;
    let max_rho = s.search_radius * s.search_radius;
    let scale = 1.0 + s.search_radius;
    // Ray parameters known to lie on the object side (g > 0) and on the image side (g < 0).
    var t_object = 0.0;
    var t_image = 0.0;
    var have_object = false;
    var have_image = false;
    var last_inside = 0.0;
    var have_inside = false;
    for (var step = 0u; step < ASPHERE_MAX_STEPS; step += 1u) {
        let q = p + t * d;
        let rho = q.x * q.x + q.y * q.y;
        var sag = vec3<f32>(0.0);
        if rho <= max_rho {
            sag = asphere_sag(rho, s);
        }
        if sag.z == 0.0 {
            // Outside the region where the surface exists: fall back towards known ground.
            if have_object && have_image {
                t = 0.5 * (t_object + t_image);
            } else if have_inside {
                t = 0.5 * (t + last_inside);
            } else {
                return no_hit();
            }
            continue;
        }
        last_inside = t;
        have_inside = true;
        let g = sag.x - q.z;
        let gradient = vec3<f32>(2.0 * sag.y * q.x, 2.0 * sag.y * q.y, -1.0);
        if abs(g) <= ASPHERE_SAG_TOLERANCE * scale {
            return finish_asphere(q, gradient, d, sense);
        }
        if g > 0.0 {
            t_object = t;
            have_object = true;
        } else {
            t_image = t;
            have_image = true;
        }
        let dg = 2.0 * sag.y * (q.x * d.x + q.y * d.y) - d.z;
        // A flat g (dg = 0) is the f64 tracer's infinite step, clamped to the search radius.
        var newton = -sign(g) * max_step;
        if dg != 0.0 {
            newton = -g / dg;
        }
        var next = t + clamp(newton, -max_step, max_step);
        if have_object && have_image {
            let lo = min(t_object, t_image);
            let hi = max(t_object, t_image);
            if !(next > lo && next < hi) {
                next = 0.5 * (lo + hi);
            }
        }
        if abs(next - t) <= ASPHERE_STEP_TOLERANCE * (1.0 + abs(t)) {
            return finish_asphere(q, gradient, d, sense);
        }
        t = next;
    }
    return no_hit();
}

fn intersect_surface(p: vec3<f32>, d: vec3<f32>, s: LensSurface, sense: f32) -> SurfaceHit {
    switch s.kind {
        case SURFACE_SPHERE: {
            return intersect_sphere(p, d, s.curvature, sense);
        }
        case SURFACE_CONIC: {
            return intersect_conic(p, d, s.curvature, s.conic_factor, sense);
        }
        case SURFACE_ASPHERE, SURFACE_ODD_ASPHERE: {
            return intersect_asphere(p, d, s, sense);
        }
        default: {
            return intersect_plane(p, d, sense);
        }
    }
}

// Whether stop-plane point q passes the blades (src/trace/aperture.rs): the edge with the
// largest outward projection holds the point; inside its wedge the opening is bounded by the
// edge (or its arc).
fn blades_contain(q: vec2<f32>) -> bool {
    let half = PI / f32(lens.blade_count);
    var along = -1e30;
    var best = vec2<f32>(1.0, 0.0);
    for (var j = 0u; j < lens.blade_count; j += 1u) {
        let angle = lens.blade_rotation + f32(2u * j + 1u) * half;
        let edge = vec2<f32>(cos(angle), sin(angle));
        let u = dot(q, edge);
        if u > along {
            along = u;
            best = edge;
        }
    }
    if lens.has_arc == 0u {
        return along <= lens.blade_apothem;
    }
    let across = -q.x * best.y + q.y * best.x;
    let u = along - lens.arc_centre;
    return u * u + across * across <= lens.arc_radius_sq;
}

// Snell's law with unit d and unit normal n (either orientation), mu = n_in / n_out;
// w = 0 on total internal reflection.
fn refract_ray(d: vec3<f32>, n: vec3<f32>, mu: f32) -> vec4<f32> {
    let cos_signed = dot(n, d);
    let radicand = 1.0 - mu * mu * (1.0 - cos_signed * cos_signed);
    if !(radicand >= 0.0) {
        return vec4<f32>(0.0);
    }
    let root = sqrt(radicand);
    let along = select(-root, root, cos_signed >= 0.0) - mu * cos_signed;
    return vec4<f32>(mu * d + along * n, 1.0);
}

// An ideal thin lens met at q: the direction tangents along the travel lose power * q
// (refract.rs `ideal_lens`), and the ray keeps its sense along z.
fn ideal_lens(d: vec3<f32>, q: vec2<f32>, power: f32) -> vec3<f32> {
    let t = d.xy / abs(d.z) - power * q;
    return normalize(vec3<f32>(t, select(-1.0, 1.0, d.z >= 0.0)));
}

fn refract_plane(d: vec3<f32>, mu: f32) -> vec4<f32> {
    let xy = mu * d.xy;
    let radicand = 1.0 - dot(xy, xy);
    if !(radicand >= 0.0) {
        return vec4<f32>(0.0);
    }
    let z = sqrt(radicand);
    return vec4<f32>(xy, select(-z, z, d.z >= 0.0), 1.0);
}

// Backward trace of the ray from `origin` along `direction` (towards -z) through surfaces N..1.
// Only lenses that image behind themselves are rendered, so the ray starts travelling -z and
// each mirror turns it round.
fn trace_lens(origin: vec3<f32>, direction: vec3<f32>) -> TracedRay {
    var position = origin;
    var d = normalize(direction);
    var sense = -1.0;
    for (var k = 0u; k < lens.surface_count; k += 1u) {
        let i = lens.surface_count - 1u - k;
        let s = lens_surfaces[lens_first_surface + i];
        let p = position - vec3<f32>(0.0, 0.0, s.vertex_z);
        let hit = intersect_surface(p, d, s, sense);
        if !hit.hit {
            return TracedRay(position, d, TRACE_MISSED, i + 1u);
        }
        let q = hit.point;
        let at = q + vec3<f32>(0.0, 0.0, s.vertex_z);
        let r_sq = q.x * q.x + q.y * q.y;
        if r_sq > s.semi_aperture_sq || r_sq < s.obscuration_sq
            || (s.bladed != 0u && !blades_contain(q.xy)) {
            return TracedRay(at, d, TRACE_VIGNETTED, i + 1u);
        }
        position = at;
        if s.reflects != 0u {
            d = d - 2.0 * dot(d, hit.normal) * hit.normal;
            sense = -sense;
        } else if s.kind == SURFACE_IDEAL_LENS {
            // A ray grazing the plane leaves with tangents past what f32 holds (NaN here): no
            // direction, so no later surface is met, as in Tracer::cross.
            let turned = ideal_lens(d, q.xy, s.ideal_power);
            if !all(abs(turned) <= vec3<f32>(1.0)) {
                return TracedRay(at, d, TRACE_MISSED, i + 1u);
            }
            d = turned;
        } else if s.same_medium == 0u {
            var refracted: vec4<f32>;
            if s.kind == SURFACE_PLANE {
                refracted = refract_plane(d, s.mu);
            } else {
                refracted = refract_ray(d, hit.normal, s.mu);
            }
            if refracted.w == 0.0 {
                return TracedRay(at, d, TRACE_TIR, i + 1u);
            }
            // Each f32 refraction leaves the length an ulp or so off 1 where the f64 tracer's
            // stays unit to 1e-16; renormalising keeps the port on the f64 ray (through the
            // double Gauss the largest direction error falls from 2.1e-6 to 1.3e-6).
            d = normalize(refracted.xyz);
        }
    }
    return TracedRay(position, d, TRACE_OK, 0u);
}
