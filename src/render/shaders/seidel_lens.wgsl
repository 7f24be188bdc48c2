// The Seidel lens model: the thick lens plus the third-order transverse aberration of one object
// conjugate. Its Rust twin is `seidel_aberration` / `seidel_lens_ray` in src/render/kernel.rs
// (statement by statement, f32); its f64 statement is `SeidelLens::object_ray` in
// src/render/models.rs, which the tests compare it with ray by ray.
//
// Compiled after ibrt.wgsl (it uses `ObjectRay`, `blocked_ray` and `paraxial_lens_ray`, which
// reads the thick lens from `frame`); bind group 3. See ibrt_shader in src/render/wgsl.rs.

// Mirrors `SeidelParams` in src/render/gpu_types.rs. Coefficients in mm of the monomials of
// normalised field h and pupil (px across the field direction, py along it):
// eps_x = spherical rho^2 px + 2 coma h px py + sagittal h^2 px,
// eps_y = spherical rho^2 py + coma h (rho^2 + 2 py^2) + tangential h^2 py + distortion h^3.
struct SeidelParams {
    image_z: f32,
    exit_pupil_z: f32,
    inverse_chief_height: f32,
    inverse_marginal_height: f32,
    spherical: f32,
    coma: f32,
    sagittal: f32,
    tangential: f32,
    distortion: f32,
    pad0: f32,
    pad1: f32,
    pad2: f32,
}

@group(3) @binding(0) var<uniform> seidel: SeidelParams;

// SEIDEL_INVERSE_STEPS, SEIDEL_CONVERGED_MM and SEIDEL_SETTLED_MM come from the Rust prelude
// (src/render/models.rs).

// Transverse aberration (mm) of the ray to Gaussian image point `g` through normalised
// exit-pupil point `p`.
fn seidel_aberration(g: vec2<f32>, p: vec2<f32>) -> vec2<f32> {
    let radius = sqrt(g.x * g.x + g.y * g.y);
    var u = vec2<f32>(1.0, 0.0);
    if radius > 0.0 {
        u = g / radius;
    }
    let v = vec2<f32>(-u.y, u.x);
    let h = radius * seidel.inverse_chief_height;
    let py = p.x * u.x + p.y * u.y;
    let px = p.x * v.x + p.y * v.y;
    let rho2 = px * px + py * py;
    let ex = seidel.spherical * rho2 * px + 2.0 * seidel.coma * h * px * py
        + seidel.sagittal * h * h * px;
    let ey = seidel.spherical * rho2 * py
        + seidel.coma * h * (rho2 + 2.0 * py * py)
        + seidel.tangential * h * h * py
        + seidel.distortion * h * h * h;
    return ey * u + ex * v;
}

// The Gaussian image point whose aberrated ray through the film-side ray's exit-pupil point lands
// where the film-side ray does (fixed point), then the thick lens's ray from it; blocked where the
// fixed point does not settle (far outside the field the polynomial describes).
fn seidel_lens_ray(film: vec3<f32>, pupil: vec3<f32>) -> ObjectRay {
    let d = pupil - film;
    let t_exit = (seidel.exit_pupil_z - film.z) / d.z;
    let exit = film.xy + t_exit * d.xy;
    let t_image = (seidel.image_z - film.z) / d.z;
    let landing = film.xy + t_image * d.xy;
    let p = exit * seidel.inverse_marginal_height;
    var g = landing;
    var step = 0.0;
    for (var i = 0u; i < SEIDEL_INVERSE_STEPS; i += 1u) {
        let next = landing - seidel_aberration(g, p);
        let moved = next - g;
        step = sqrt(moved.x * moved.x + moved.y * moved.y);
        g = next;
        if step <= SEIDEL_CONVERGED_MM {
            break;
        }
    }
    // Written so that NaN fails the test too.
    if step <= SEIDEL_SETTLED_MM {
        return paraxial_lens_ray(vec3<f32>(g, seidel.image_z), vec3<f32>(exit, seidel.exit_pupil_z));
    }
    return blocked_ray();
}
