#!/usr/bin/env python3
"""An engine lensbake did not write: runs the exported GLSL sampler on OpenGL (Mesa's llvmpipe
through a headless EGL context, via moderngl) with a table bound as docs/engines.md says.

    engine_consumer.py SHADER.comp BINDING_DIR RAYS OUT

SHADER.comp is `lensbake export shader --lang glsl` (entry point lrtf_sample_rays), BINDING_DIR
is `lensbake export binding`. Or SHADER.comp is `lensbake export shader --shader trace --lang
glsl` (trace_lens_rays) and BINDING_DIR `lensbake export lens`; RAYS.f32 then holds 8 f32 per
ray (origin, 0, direction, 0) and OUT.f32 receives 8 (exit origin, status, direction, the
surface that stopped the ray). For the sampler, rays come in one of two forms:
- RAYS.json as `lensbake lrtf eval` reads them ([{"origin": [x, y, z], "direction": [dx, dy,
  dz]}], layer 0); OUT.json then holds what `lrtf eval --json` prints for them (status "ok",
  "vignetted" or "missed", position, direction).
- RAYS.f32 with 8 little-endian f32 per ray: origin x, y, z, table layer, direction x, y, z,
  sampling-pupil block; OUT.f32 then receives the shader's 12 f32 per ray: exit origin x, y, z,
  status, direction x, y, z, 0, sampling circle centre_x, radius, 0, 0.

Only moderngl and the files are used: the bindings below are the ones docs/engines.md documents
for GLSL (each resource kind numbered from 0 in (group, binding) order).

Run:  python3 -m venv /tmp/engines && /tmp/engines/bin/pip install moderngl==5.12.0
      /tmp/engines/bin/python tools/engine_consumer.py ...
"""
import json
import os
import struct
import sys

import moderngl

RAY_FLOATS_IN = 8
RAY_FLOATS_OUT = 12
# The trace harness writes (origin, status) and (direction, surface) per ray.
TRACE_FLOATS_OUT = 8
WORKGROUP = 64
# LrtfResult::status codes (LRTF_PASSES, LRTF_BLOCKED, LRTF_OUTSIDE) as `lrtf eval` names them.
STATUS_NAMES = {0: "ok", 1: "vignetted", 2: "missed"}


def rays_from_json(path, sampling_block):
    with open(path) as f:
        rays = json.load(f)
    return b"".join(
        struct.pack("<8f", *r["origin"], 0.0, *r["direction"], float(sampling_block)) for r in rays
    )


def json_from_output(output, rays):
    results = []
    for k, ray in enumerate(json.loads(rays)):
        values = struct.unpack_from("<12f", output, 4 * RAY_FLOATS_OUT * k)
        status = STATUS_NAMES.get(int(values[3]), f"status {int(values[3])}")
        passes = status == "ok"
        results.append(
            {
                "status": status,
                "surface": None,
                # A ray the table stops keeps where it started, as `lrtf eval` prints it.
                "position": list(values[0:3]) if passes else ray["origin"],
                "direction": list(values[4:7]) if passes else ray["direction"],
            }
        )
    return json.dumps(results, indent=1) + "\n"


def read_file(directory, name):
    with open(os.path.join(directory, name), "rb") as f:
        return f.read()


def bind_table(ctx, directory, description):
    """The sampler's resources (docs/engines.md, Bindings); returns what must stay alive."""
    data = {name: read_file(directory, file) for name, file in description["files"].items()}
    size = tuple(description["texture_size"])
    alive = []
    for unit, name in enumerate(["transfer", "aux"]):
        texture = ctx.texture3d(size, 4, data[name], dtype="f4")
        # texelFetch reads a level of a complete texture: without mipmaps the default
        # minification filter (which uses them) would leave it incomplete and read zeros.
        texture.filter = (moderngl.NEAREST, moderngl.NEAREST)
        texture.use(location=unit)
        alive.append(texture)
    params = ctx.buffer(data["params"])
    pupil = ctx.buffer(data["pupil"])
    params.bind_to_uniform_block(0)
    pupil.bind_to_storage_buffer(0)
    return alive + [params, pupil]


def bind_lens(ctx, directory, description):
    """The trace's resources: surfaces (SSBO 0) and LensParams (UBO 0)."""
    surfaces = ctx.buffer(read_file(directory, description["files"]["surfaces"]))
    params = ctx.buffer(read_file(directory, description["files"]["params"]))
    surfaces.bind_to_storage_buffer(0)
    params.bind_to_uniform_block(0)
    return [surfaces, params]


def main():
    shader_path, binding_dir, rays_path, out_path = sys.argv[1:5]
    # A table's binding (export binding) or a lens's (export lens, for --shader trace).
    tracing = os.path.exists(os.path.join(binding_dir, "lens.json"))
    with open(os.path.join(binding_dir, "lens.json" if tracing else "binding.json")) as f:
        description = json.load(f)
    floats_out = TRACE_FLOATS_OUT if tracing else RAY_FLOATS_OUT

    with open(shader_path) as f:
        source = f.read()
    as_json = rays_path.endswith(".json")
    if as_json:
        rays = rays_from_json(rays_path, description["sampling_block"])
    else:
        with open(rays_path, "rb") as f:
            rays = f.read()
    count = len(rays) // (4 * RAY_FLOATS_IN)

    ctx = moderngl.create_context(standalone=True, backend="egl")
    program = ctx.compute_shader(source)
    bind = bind_lens if tracing else bind_table
    alive = bind(ctx, binding_dir, description)
    rays_in = ctx.buffer(rays)
    rays_out = ctx.buffer(reserve=count * 4 * floats_out)
    rays_in.bind_to_storage_buffer(1)
    rays_out.bind_to_storage_buffer(2)
    program.run(group_x=(count + WORKGROUP - 1) // WORKGROUP)
    ctx.finish()
    output = rays_out.read()
    if as_json:
        with open(rays_path) as f:
            output = json_from_output(output, f.read()).encode()
    with open(out_path, "wb") as f:
        f.write(output)
    print(f"{count} rays through {ctx.info['GL_RENDERER']} ({len(alive)} resources bound)")


if __name__ == "__main__":
    main()
