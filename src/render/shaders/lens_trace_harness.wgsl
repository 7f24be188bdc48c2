// Test harness: runs lens_trace.wgsl's trace_lens ray by ray (GpuRenderer::trace_rays), in a
// module of its own so the renderer's module carries no test bindings.
// rays_in holds (origin, direction) pairs as two vec4 each, rays_out (origin, status) and
// (direction, surface) as two vec4 each.
@group(3) @binding(0) var<storage, read> rays_in: array<vec4<f32>>;
@group(3) @binding(1) var<storage, read_write> rays_out: array<vec4<f32>>;

@compute @workgroup_size(64, 1, 1)
fn trace_lens_rays(@builtin(global_invocation_id) id: vec3<u32>) {
    let n = arrayLength(&rays_in) / 2u;
    if id.x >= n {
        return;
    }
    let traced = trace_lens(rays_in[2u * id.x].xyz, rays_in[2u * id.x + 1u].xyz);
    rays_out[2u * id.x] = vec4<f32>(traced.origin, f32(traced.status));
    rays_out[2u * id.x + 1u] = vec4<f32>(traced.direction, f32(traced.surface));
}
