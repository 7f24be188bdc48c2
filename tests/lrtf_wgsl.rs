//! The LRTF shader parses and validates with naga (no GPU needed), and its uniform block has the
//! layout of the Rust struct that fills it.

use lensbake::lrtf::table::GpuParams;

const SHADER: &str = include_str!("../src/lrtf/lrtf_sample.wgsl");

fn module() -> naga::Module {
    naga::front::wgsl::parse_str(SHADER).unwrap_or_else(|e| panic!("{}", e.emit_to_string(SHADER)))
}

#[test]
fn lrtf_shader_validates() {
    let module = module();
    naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        naga::valid::Capabilities::all(),
    )
    .validate(&module)
    .unwrap_or_else(|e| panic!("{}", e.emit_to_string(SHADER)));
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
    let module = module();
    let mut layouter = naga::proc::Layouter::default();
    layouter.update(module.to_ctx()).unwrap();
    let (handle, ty) = module
        .types
        .iter()
        .find(|(_, t)| t.name.as_deref() == Some("LrtfParams"))
        .expect("LrtfParams in the shader");
    let naga::TypeInner::Struct { members, span } = &ty.inner else {
        panic!("LrtfParams is not a struct")
    };
    assert_eq!(*span as usize, std::mem::size_of::<GpuParams>());
    assert_eq!(
        layouter[handle].size as usize,
        std::mem::size_of::<GpuParams>()
    );
    let offsets: Vec<(String, u32)> = members
        .iter()
        .map(|m| (m.name.clone().unwrap(), m.offset))
        .collect();
    let expected = [
        (
            "rear_plane_z",
            std::mem::offset_of!(GpuParams, rear_plane_z),
        ),
        (
            "film_plane_z",
            std::mem::offset_of!(GpuParams, film_plane_z),
        ),
        (
            "max_film_radius",
            std::mem::offset_of!(GpuParams, max_film_radius),
        ),
        (
            "max_rear_radius",
            std::mem::offset_of!(GpuParams, max_rear_radius),
        ),
        (
            "max_polar_angle",
            std::mem::offset_of!(GpuParams, max_polar_angle),
        ),
        (
            "stop_radius_sq",
            std::mem::offset_of!(GpuParams, stop_radius_sq),
        ),
        (
            "parameterisation",
            std::mem::offset_of!(GpuParams, parameterisation),
        ),
        ("pupil_count", std::mem::offset_of!(GpuParams, pupil_count)),
        ("dims", std::mem::offset_of!(GpuParams, dims)),
        (
            "sampling_max_film_radius",
            std::mem::offset_of!(GpuParams, sampling_max_film_radius),
        ),
        (
            "sampling_count",
            std::mem::offset_of!(GpuParams, sampling_count),
        ),
        ("focus_count", std::mem::offset_of!(GpuParams, focus_count)),
        (
            "focus_coordinate",
            std::mem::offset_of!(GpuParams, focus_coordinate),
        ),
    ];
    for (name, offset) in expected {
        let found = offsets.iter().find(|(n, _)| n == name).map(|(_, o)| *o);
        assert_eq!(found, Some(offset as u32), "member {name}");
    }
}
