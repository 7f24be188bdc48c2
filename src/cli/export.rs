//! `lensbake export`: the renderer's shaders in other languages, and a baked table packed for the
//! exported sampler (docs/engines.md).

use std::path::PathBuf;

use anyhow::{Context, bail};
use clap::{Args, Subcommand};
use lensbake::export::{Language, Shader, export_shader};
use lensbake::lrtf::io::{FORMAT_VERSION, read_table};
use lensbake::output::{publish_dir, write_bytes};
use lensbake::render::gpu_types::{LensSurface, lens_surfaces};

use super::lens::LensArgs;
use super::lrtf::{FocusArg, parse_focus};

#[derive(Subcommand, Debug)]
pub enum ExportCommand {
    /// The baked-table sampler, the exact lens trace or the whole renderer (with the Seidel
    /// lens) as GLSL, HLSL, MSL, SPIR-V or WGSL, written by naga from the renderer's own WGSL.
    Shader(ShaderArgs),
    /// A baked table packed for the exported sampler: its two textures, pupil circles and
    /// uniform block as raw little-endian files, described by binding.json.
    Binding(BindingArgs),
    /// A lens packed for the exported trace (`--shader trace`): its surfaces and uniform block
    /// at one wavelength as raw little-endian files, described by lens.json.
    Lens(LensExportArgs),
}

#[derive(Args, Debug)]
pub struct ShaderArgs {
    /// Target language.
    #[arg(long, value_parser = ["glsl", "hlsl", "msl", "spirv", "wgsl"])]
    lang: String,
    /// Which kernel: the table sampler (entry point lrtf_sample_rays), the lens trace
    /// (trace_lens_rays) or the renderer (render, render_chromatic).
    #[arg(long, default_value = "sampler", value_parser = ["sampler", "trace", "renderer"])]
    shader: String,
    /// The entry point a GLSL file holds (GLSL holds one; default: the first).
    #[arg(long)]
    entry: Option<String>,
    /// Output file (default: stdout; SPIR-V, being binary, needs a file).
    #[arg(long)]
    out: Option<PathBuf>,
}

#[derive(Args, Debug)]
pub struct BindingArgs {
    /// The table's directory (its lrtf.exr and lrtf.ron).
    table: PathBuf,
    /// Output directory (replaced as a whole).
    #[arg(long)]
    out: PathBuf,
    /// Stop down to this f-number (at or above the baked one; default: the baked one).
    #[arg(long)]
    f_number: Option<f64>,
    /// The focus lens samples are drawn for (mm, `inf` for infinity; default: the table's far
    /// focus); refused outside the table's focus range.
    #[arg(long, value_name = "D", value_parser = parse_focus)]
    focus_mm: Option<FocusArg>,
}

#[derive(Args, Debug)]
pub struct LensExportArgs {
    #[command(flatten)]
    lens: LensArgs,
    /// Output directory (replaced as a whole).
    #[arg(long)]
    out: PathBuf,
    /// Wavelength the media's indices are taken at (default: the lens's design wavelength).
    #[arg(long)]
    wavelength_nm: Option<f64>,
}

pub fn run(command: ExportCommand) -> anyhow::Result<()> {
    match command {
        ExportCommand::Shader(args) => run_shader(args),
        ExportCommand::Binding(args) => run_binding(args),
        ExportCommand::Lens(args) => run_lens(args),
    }
}

fn run_shader(args: ShaderArgs) -> anyhow::Result<()> {
    let language = Language::from_name(&args.lang).context("unknown --lang")?;
    let shader = Shader::from_name(&args.shader).context("unknown --shader")?;
    let exported = export_shader(shader, language, args.entry.as_deref())?;
    match args.out {
        Some(path) => {
            write_bytes(&path, &exported.bytes)?;
            note!(
                "wrote {} ({} {}, entry point {})",
                path.display(),
                shader.name(),
                language.name(),
                exported.entry_point
            );
        }
        None if language == Language::Spirv => {
            bail!("SPIR-V is binary: name a file with --out")
        }
        None => say_raw!("{}", String::from_utf8_lossy(&exported.bytes)),
    }
    Ok(())
}

fn floats<const N: usize>(values: &[[f32; N]]) -> Vec<u8> {
    values
        .iter()
        .flatten()
        .flat_map(|v| v.to_le_bytes())
        .collect()
}

fn run_binding(args: BindingArgs) -> anyhow::Result<()> {
    let table = read_table(&args.table, None)?;
    let f = args.f_number.unwrap_or(table.info.f_number);
    let stop = table.stop_radius(0, f).with_context(|| {
        format!(
            "f-number {f} is faster than the table's f/{}",
            table.info.f_number
        )
    })?;
    let film_z = match args.focus_mm {
        Some(focus) => table
            .info
            .focus
            .film_z_for(focus.single("export binding --focus-mm")?)
            .with_context(|| format!("table {}", args.table.display()))?,
        None => table.layers[0].frame.film_plane_z,
    };
    let binding = table
        .engine_binding(stop, film_z)
        .with_context(|| format!("table {}", args.table.display()))?;
    let p = &binding.params;
    let description = serde_json::json!({
        "format_version": FORMAT_VERSION,
        "table": args.table.display().to_string(),
        "f_number": f,
        "stop_radius_mm": stop,
        "film_z_mm": film_z,
        "wavelengths_nm": table.layers.iter().map(|l| l.wavelength_nm).collect::<Vec<_>>(),
        "texture_size": binding.texture_size,
        "pupil_circles": binding.pupil.len(),
        "sampling_block": binding.sampling_block,
        "files": {
            "params": "lrtf_params.bin",
            "transfer": "lrtf_transfer.f32",
            "aux": "lrtf_aux.f32",
            "pupil": "lrtf_pupil.f32",
        },
        "params": {
            "rear_plane_z": p.rear_plane_z,
            "film_plane_z": p.film_plane_z,
            "max_film_radius": p.max_film_radius,
            "max_rear_radius": p.max_rear_radius,
            "max_polar_angle": p.max_polar_angle,
            "stop_radius_sq": p.stop_radius_sq,
            "parameterisation": p.parameterisation,
            "pupil_count": p.pupil_count,
            "dims": p.dims,
            "format_version": p.format_version,
            "sampling_max_film_radius": p.sampling_max_film_radius,
            "sampling_count": p.sampling_count,
            "focus_count": p.focus_count,
            "focus_coordinate": p.focus_coordinate,
        },
    });
    let json = serde_json::to_string_pretty(&description)? + "\n";
    publish_dir(&args.out, |dir| -> anyhow::Result<()> {
        write_bytes(&dir.join("binding.json"), json.as_bytes())?;
        write_bytes(&dir.join("lrtf_params.bin"), bytemuck::bytes_of(p))?;
        write_bytes(&dir.join("lrtf_transfer.f32"), &floats(&binding.transfer))?;
        write_bytes(&dir.join("lrtf_aux.f32"), &floats(&binding.aux))?;
        write_bytes(&dir.join("lrtf_pupil.f32"), &floats(&binding.pupil))?;
        Ok(())
    })?;
    note!(
        "wrote {} (textures {}x{}x{}, {} pupil circles, format_version {FORMAT_VERSION})",
        args.out.display(),
        binding.texture_size[0],
        binding.texture_size[1],
        binding.texture_size[2],
        binding.pupil.len()
    );
    Ok(())
}

fn run_lens(args: LensExportArgs) -> anyhow::Result<()> {
    let lens = args.lens.load()?;
    let wavelength_nm = args
        .wavelength_nm
        .unwrap_or_else(|| lens.system.design_wavelength_nm());
    let at = lens.system.at_checked(wavelength_nm)?;
    let (params, surfaces) = lens_surfaces(&at);
    let description = serde_json::json!({
        "lens": args.lens.lens,
        "wavelength_nm": wavelength_nm,
        "surface_count": params.surface_count,
        "surface_bytes": std::mem::size_of::<LensSurface>(),
        "files": {
            "params": "lens_params.bin",
            "surfaces": "lens_surfaces.bin",
        },
    });
    let json = serde_json::to_string_pretty(&description)? + "\n";
    publish_dir(&args.out, |dir| -> anyhow::Result<()> {
        write_bytes(&dir.join("lens.json"), json.as_bytes())?;
        write_bytes(&dir.join("lens_params.bin"), bytemuck::bytes_of(&params))?;
        write_bytes(
            &dir.join("lens_surfaces.bin"),
            bytemuck::cast_slice(&surfaces),
        )?;
        Ok(())
    })?;
    note!(
        "wrote {} ({} surfaces at {wavelength_nm} nm)",
        args.out.display(),
        params.surface_count
    );
    Ok(())
}
