//! The LRTF shader parses and validates with naga (no GPU needed), and its uniform block has the
//! layout of the Rust struct that fills it.
#![cfg(feature = "render")]

mod common;

use lensbake::lrtf::table::GpuParams;
use lensbake::render::wgsl::lrtf_sample_shader;

fn module() -> naga::Module {
    naga::front::wgsl::parse_str(lrtf_sample_shader())
        .unwrap_or_else(|e| panic!("{}", e.emit_to_string(lrtf_sample_shader())))
}

#[test]
fn lrtf_shader_validates() {
    let module = module();
    naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        naga::valid::Capabilities::all(),
    )
    .validate(&module)
    .unwrap_or_else(|e| panic!("{}", e.emit_to_string(lrtf_sample_shader())));
    assert!(
        module
            .functions
            .iter()
            .any(|(_, f)| f.name.as_deref() == Some("lrtf_sample"))
    );
    assert!(
        module
            .functions
            .iter()
            .any(|(_, f)| f.name.as_deref() == Some("lrtf_sampling_pupil_at"))
    );
}

#[test]
fn uniform_block_matches_the_rust_struct() {
    common::assert_wgsl_layout!(
        lrtf_sample_shader(),
        GpuParams as "LrtfParams" {
            rear_plane_z,
            film_plane_z,
            max_film_radius,
            max_rear_radius,
            max_polar_angle,
            stop_radius_sq,
            parameterisation,
            pupil_count,
            dims,
            format_version,
            sampling_max_film_radius,
            sampling_count,
            focus_count,
            focus_coordinate,
        }
    );
}
