// Entry point for engines and tests: runs lrtf_sample (and the sampling pupil) ray by ray, in a
// module of its own so the renderer's module carries no such bindings. docs/engines.md binds it.
// Per ray, lrtf_rays_in holds two vec4: (origin.xyz, table layer) and (direction.xyz, the block
// of lrtf_pupil where the sampling pupil starts); lrtf_rays_out three: (origin.xyz, status),
// (direction.xyz, 0) and (the sampling circle's centre_x and radius at the film radius of the
// ray's origin, 0, 0). Layer and block are small whole numbers carried as floats.
@group(1) @binding(0) var<storage, read> lrtf_rays_in: array<vec4<f32>>;
@group(1) @binding(1) var<storage, read_write> lrtf_rays_out: array<vec4<f32>>;

@compute @workgroup_size(64, 1, 1)
fn lrtf_sample_rays(@builtin(global_invocation_id) id: vec3<u32>) {
    let n = arrayLength(&lrtf_rays_in) / 2u;
    if id.x >= n {
        return;
    }
    let origin = lrtf_rays_in[2u * id.x];
    let direction = lrtf_rays_in[2u * id.x + 1u];
    lrtf_layer = u32(origin.w);
    let sampled = lrtf_sample(origin.xyz, direction.xyz);
    let circle = lrtf_sampling_pupil_at(length(origin.xy), u32(direction.w));
    lrtf_rays_out[3u * id.x] = vec4<f32>(sampled.origin, f32(sampled.status));
    lrtf_rays_out[3u * id.x + 1u] = vec4<f32>(sampled.direction, 0.0);
    lrtf_rays_out[3u * id.x + 2u] = vec4<f32>(circle, 0.0, 0.0);
}
