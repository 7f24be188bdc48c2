# Sourced by .ci/run before the tests: the tools lensbake did not write that tests/engine_export.rs
# checks the exported shaders with. glslangValidator (glslang-tools) compiles the GLSL and, through
# its HLSL front end, the HLSL; spirv-val (spirv-tools) validates the SPIR-V; spirv-cross
# translates it to HLSL and MSL; moderngl runs the GLSL sampler on Mesa's llvmpipe through a
# headless EGL context. Exports LENSBAKE_ENGINE_PYTHON, the Python the consumer runs under.
engine_missing=()
command -v glslangValidator >/dev/null 2>&1 || engine_missing+=(glslang-tools)
command -v spirv-val >/dev/null 2>&1 || engine_missing+=(spirv-tools)
command -v spirv-cross >/dev/null 2>&1 || engine_missing+=(spirv-cross)
python3 -m venv --help >/dev/null 2>&1 || engine_missing+=(python3-venv)
# moderngl's context library opens libEGL and libGL (found through ldconfig); Mesa drives them.
ldconfig -p | grep -q 'libEGL_mesa.so.0' || engine_missing+=(libegl-mesa0 libegl1 libgl1-mesa-dri)
ldconfig -p | grep -q 'libGL.so.1' || engine_missing+=(libgl1)
if [ "${#engine_missing[@]}" -gt 0 ]; then
  export DEBIAN_FRONTEND=noninteractive
  engine_sudo=""
  [ "$(id -u)" -eq 0 ] || engine_sudo="sudo"
  $engine_sudo apt-get update -qq
  $engine_sudo apt-get install -y -qq "${engine_missing[@]}" >/dev/null
fi
engine_venv="${TMPDIR:-/tmp}/lensbake-engines-venv"
[ -x "$engine_venv/bin/python" ] || python3 -m venv "$engine_venv"
"$engine_venv/bin/pip" install -q moderngl==5.12.0 jsonschema==4.23.0
"$engine_venv/bin/python" -c "import moderngl; moderngl.create_context(standalone=True, backend='egl').release()"
export LENSBAKE_ENGINE_PYTHON="$engine_venv/bin/python"
