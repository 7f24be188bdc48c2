//! The WGSL modules the GPU runs, each assembled from its `.wgsl` sources behind a prelude of
//! `const` declarations generated from the Rust constants.
//!
//! Why generated: the kernels and their Rust twins (the CPU kernel, the rasteriser, the f64
//! tracer, the table sampler) must agree on every code and tolerance, and a value typed twice
//! drifts. The `.wgsl` files declare no module-scope constant of their own; everything they
//! name comes from [`SHARED_CONSTANTS`], whose entries read the Rust constants themselves.
//! `tests/shader_twins.rs` parses every assembled module with naga and checks that each of its
//! constants is in the table with exactly the Rust value (so a constant typed into a `.wgsl` file
//! fails the test, and so does a literal naga would round differently).

use std::sync::LazyLock;

use super::gpu_types as gpu;
use super::{kernel, raster};
use crate::lrtf::param as lrtf_param;
use crate::lrtf::table as lrtf_table;
use crate::model;

/// A constant's value as the shader sees it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum WgslValue {
    U32(u32),
    F32(f32),
}

impl WgslValue {
    /// The WGSL declaration of `name` with this value. An f32 is written in the shortest decimal
    /// that reads back to the same f32, with WGSL's `f` suffix so it is parsed as an f32 and not
    /// rounded through an abstract float first.
    pub fn declaration(self, name: &str) -> String {
        match self {
            WgslValue::U32(v) => format!("const {name}: u32 = {v}u;"),
            // Rust's `{:?}` (1e-5, 3.1415927, 16777216.0) is also a WGSL decimal literal.
            WgslValue::F32(v) => format!("const {name}: f32 = {v:?}f;"),
        }
    }
}

/// Every constant the shaders share with Rust: its WGSL name and the Rust constant it is.
pub const SHARED_CONSTANTS: &[(&str, WgslValue)] = {
    use WgslValue::{F32, U32};
    &[
        ("PI", F32(std::f32::consts::PI)),
        // Lens models (FrameParams::model).
        ("MODEL_PARAXIAL", U32(gpu::MODEL_PARAXIAL)),
        ("MODEL_TRACED", U32(gpu::MODEL_TRACED)),
        ("MODEL_BAKED", U32(gpu::MODEL_BAKED)),
        ("MODEL_SEIDEL", U32(gpu::MODEL_SEIDEL)),
        // The IBRT march (kernel.rs).
        (
            "FOOTPRINT_CLAMP_ITERATIONS",
            U32(kernel::FOOTPRINT_CLAMP_ITERATIONS),
        ),
        ("DEPTH_TOLERANCE", F32(kernel::DEPTH_TOLERANCE)),
        ("DEPTH_SLACK", F32(kernel::DEPTH_SLACK)),
        ("NO_CROSSING", F32(kernel::NO_CROSSING)),
        (
            "MONOCHROME_SAMPLING_BLOCK",
            U32(kernel::MONOCHROME_SAMPLING_BLOCK),
        ),
        ("HASH_MULTIPLIER_1", U32(kernel::HASH_MULTIPLIER_1)),
        ("HASH_MULTIPLIER_2", U32(kernel::HASH_MULTIPLIER_2)),
        ("LATTICE_GOLDEN", U32(kernel::LATTICE_GOLDEN)),
        // The concentric disc's sine and cosine (kernel::sin_cos_octant).
        ("QUARTER_PI", F32(kernel::QUARTER_PI)),
        ("SIN_TAYLOR_3", F32(kernel::SIN_TAYLOR[0])),
        ("SIN_TAYLOR_5", F32(kernel::SIN_TAYLOR[1])),
        ("SIN_TAYLOR_7", F32(kernel::SIN_TAYLOR[2])),
        ("SIN_TAYLOR_9", F32(kernel::SIN_TAYLOR[3])),
        ("COS_TAYLOR_2", F32(kernel::COS_TAYLOR[0])),
        ("COS_TAYLOR_4", F32(kernel::COS_TAYLOR[1])),
        ("COS_TAYLOR_6", F32(kernel::COS_TAYLOR[2])),
        ("COS_TAYLOR_8", F32(kernel::COS_TAYLOR[3])),
        ("COS_TAYLOR_10", F32(kernel::COS_TAYLOR[4])),
        // The lens trace (LensSurface::kind, TracedRay::status, the asphere search).
        ("SURFACE_PLANE", U32(gpu::SURFACE_PLANE)),
        ("SURFACE_SPHERE", U32(gpu::SURFACE_SPHERE)),
        ("SURFACE_CONIC", U32(gpu::SURFACE_CONIC)),
        ("SURFACE_ASPHERE", U32(gpu::SURFACE_ASPHERE)),
        ("SURFACE_IDEAL_LENS", U32(gpu::SURFACE_IDEAL_LENS)),
        ("SURFACE_ODD_ASPHERE", U32(gpu::SURFACE_ODD_ASPHERE)),
        ("TRACE_OK", U32(gpu::TRACE_OK)),
        ("TRACE_VIGNETTED", U32(gpu::TRACE_VIGNETTED)),
        ("TRACE_TIR", U32(gpu::TRACE_TIR)),
        ("TRACE_MISSED", U32(gpu::TRACE_MISSED)),
        (
            "ASPHERE_MAX_STEPS",
            U32(crate::trace::ASPHERE_MAX_STEPS as u32),
        ),
        ("ASPHERE_SAG_TOLERANCE", F32(gpu::ASPHERE_SAG_TOLERANCE)),
        ("ASPHERE_STEP_TOLERANCE", F32(gpu::ASPHERE_STEP_TOLERANCE)),
        // The table sampler (LrtfParams::parameterisation, LrtfResult::status).
        (
            "PARAMETERISATION_SPHERICAL",
            U32(lrtf_param::PARAMETERISATION_SPHERICAL),
        ),
        (
            "PARAMETERISATION_PUPIL_PLANES",
            U32(lrtf_param::PARAMETERISATION_PUPIL_PLANES),
        ),
        ("LRTF_PASSES", U32(lrtf_table::LRTF_PASSES)),
        ("LRTF_BLOCKED", U32(lrtf_table::LRTF_BLOCKED)),
        ("LRTF_OUTSIDE", U32(lrtf_table::LRTF_OUTSIDE)),
        (
            "LRTF_VERSION_MISMATCH",
            U32(lrtf_table::LRTF_VERSION_MISMATCH),
        ),
        ("LRTF_FORMAT_VERSION", U32(crate::lrtf::io::FORMAT_VERSION)),
        // The Seidel model's inverse map (model::seidel; f32 on the GPU, as in the CPU twin).
        ("SEIDEL_INVERSE_STEPS", U32(model::SEIDEL_INVERSE_STEPS)),
        (
            "SEIDEL_CONVERGED_MM",
            F32(model::SEIDEL_CONVERGED_MM as f32),
        ),
        ("SEIDEL_SETTLED_MM", F32(model::SEIDEL_SETTLED_MM as f32)),
        // Depth peeling (raster.rs, PeelParams, PeelTexture, PeelMaterial).
        ("PEEL_UMBRA", U32(gpu::PEEL_UMBRA)),
        ("WRAP_REPEAT", U32(gpu::WRAP_REPEAT)),
        ("WRAP_CLAMP", U32(gpu::WRAP_CLAMP)),
        ("FILTER_NEAREST", U32(gpu::FILTER_NEAREST)),
        ("NO_TEXTURE", U32(gpu::NO_TEXTURE)),
        ("BEYOND_ALL", F32(raster::BEYOND_ALL)),
        ("MAX_DEPTH", F32(raster::MAX_DEPTH)),
        ("TEXEL_LIMIT", F32(raster::TEXEL_LIMIT)),
    ]
};

/// The `const` declarations of [`SHARED_CONSTANTS`], one a line.
pub fn prelude() -> String {
    let mut text = String::from("// Generated from the Rust constants (src/render/wgsl.rs).\n");
    for (name, value) in SHARED_CONSTANTS {
        text.push_str(&value.declaration(name));
        text.push('\n');
    }
    text
}

fn assemble(sources: &[&str]) -> String {
    let mut text = prelude();
    for source in sources {
        text.push_str(source);
    }
    text
}

const LRTF_SAMPLE: &str = include_str!("../lrtf/lrtf_sample.wgsl");
const LRTF_SAMPLE_HARNESS: &str = include_str!("../lrtf/lrtf_sample_harness.wgsl");
const LENS_TRACE: &str = include_str!("shaders/lens_trace.wgsl");
const LENS_TRACE_HARNESS: &str = include_str!("shaders/lens_trace_harness.wgsl");
const IBRT: &str = include_str!("shaders/ibrt.wgsl");
const SEIDEL_LENS: &str = include_str!("shaders/seidel_lens.wgsl");
const PEEL: &str = include_str!("shaders/peel.wgsl");

static IBRT_MODULE: LazyLock<String> =
    LazyLock::new(|| assemble(&[LRTF_SAMPLE, LENS_TRACE, IBRT, SEIDEL_LENS]));
static LENS_TRACE_MODULE: LazyLock<String> =
    LazyLock::new(|| assemble(&[LENS_TRACE, LENS_TRACE_HARNESS]));
static LRTF_SAMPLE_MODULE: LazyLock<String> = LazyLock::new(|| assemble(&[LRTF_SAMPLE]));
static LRTF_SAMPLE_RAYS_MODULE: LazyLock<String> =
    LazyLock::new(|| assemble(&[LRTF_SAMPLE, LRTF_SAMPLE_HARNESS]));
static PEEL_MODULE: LazyLock<String> = LazyLock::new(|| assemble(&[PEEL]));

/// The renderer: the LRTF sampler (group 0), the IBRT kernel (group 1), the lens trace (group
/// 2) and the Seidel model (group 3).
pub fn ibrt_shader() -> &'static str {
    &IBRT_MODULE
}

/// The lens trace with the test harness `trace_lens_rays` (groups 2 and 3): the same
/// `lens_trace.wgsl` the renderer compiles, run ray by ray.
pub fn lens_trace_shader() -> &'static str {
    &LENS_TRACE_MODULE
}

/// The LRTF sampler alone (group 0).
pub fn lrtf_sample_shader() -> &'static str {
    &LRTF_SAMPLE_MODULE
}

/// The LRTF sampler with the entry point `lrtf_sample_rays` (group 1), which looks rays up one
/// per invocation: the module `lensbake export shader` writes for engines and the exported-code
/// tests run.
pub fn lrtf_sample_rays_shader() -> &'static str {
    &LRTF_SAMPLE_RAYS_MODULE
}

/// The depth peeler (`peel.wgsl`).
pub fn peel_shader() -> &'static str {
    &PEEL_MODULE
}

/// Every assembled module by name, for validation.
pub fn modules() -> [(&'static str, &'static str); 5] {
    [
        ("ibrt", ibrt_shader()),
        ("lens_trace", lens_trace_shader()),
        ("lrtf_sample", lrtf_sample_shader()),
        ("lrtf_sample_rays", lrtf_sample_rays_shader()),
        ("peel", peel_shader()),
    ]
}
