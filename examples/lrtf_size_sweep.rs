//! Scratch: smallest table meeting p99 image error and validity agreement per lens.
//! cargo run --release --example lrtf_size_sweep -- RAYS LENS:FOCUS_MM... (resolutions in env RES, e.g. 32,48x48x48)
use lensbake::lenses;
use lensbake::lrtf::bake::{BakeRequest, bake, first_order};
use lensbake::lrtf::measure::table_error;
use lensbake::lrtf::Precision;
use lensbake::prescription::formats::LoadOptions;
use lensbake::trace::Tracer;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let rays: usize = args[1].parse()?;
    let res: Vec<[usize; 3]> = std::env::var("RES")
        .unwrap_or("16,24,32,48,64,96,128".into())
        .split(',')
        .map(|s| {
            let v: Vec<usize> = s.split('x').map(|x| x.parse().unwrap()).collect();
            if v.len() == 1 { [v[0]; 3] } else { [v[0], v[1], v[2]] }
        })
        .collect();
    for spec in &args[2..] {
        let (name, focus) = spec.split_once(':').unwrap();
        let lens = lenses::load(name, &LoadOptions::default())?;
        let system = lens.system;
        let design = system.at(system.design_wavelength_nm());
        let tracer = Tracer::new(&design);
        let efl = first_order(&design, None)?.first_order.efl;
        for &r in &res {
            let request = BakeRequest {
                resolution: r,
                focus_mm: Some(focus.parse()?),
                ..BakeRequest::default()
            };
            let table = bake(&system, &request)?;
            if std::env::var_os("CUBIC").is_some() {
                let (p99, agree) = cubic_error(&table, &tracer, efl, rays);
                println!(
                    "{name} {}x{}x{} cubic-f32 bytes {} img p99 {:.4} px agree {:.4} %",
                    r[0], r[1], r[2], table.entry_bytes(), p99, 100.0 * agree
                );
            }
            for precision in ["f32", "f16", "u16"] {
                let t = match precision {
                    "f32" => table.clone(),
                    "f16" => table.to_precision(Precision::F16),
                    _ => quantised(&table),
                };
                let bytes = if precision == "u16" { table.entry_bytes() / 2 } else { t.entry_bytes() };
                let e = table_error(&t, 0, &tracer, efl, 1920.0, rays, 0x5eed);
                println!(
                    "{name} {}x{}x{} {} bytes {} img p99 {:.4} px max {:.3} pos p99 {:.2} um agree {:.4} %",
                    r[0], r[1], r[2], precision, bytes,
                    e.image_px.p99, e.image_px.max, e.position_um.p99, 100.0 * (1.0 - e.validity_mismatch)
                );
            }
        }
    }
    Ok(())
}

/// Simulated u16 storage: each channel quantised to 65535 steps over its range.
fn quantised(table: &lensbake::lrtf::LrtfTable) -> lensbake::lrtf::LrtfTable {
    let mut t = table.clone();
    for l in &mut t.layers {
        let mut values: Vec<[f32; 8]> = l.entries.row_major().collect();
        for c in 0..8 {
            let lo = values.iter().map(|v| v[c]).fold(f32::INFINITY, f32::min) as f64;
            let hi = values.iter().map(|v| v[c]).fold(f32::NEG_INFINITY, f32::max) as f64;
            let step = ((hi - lo) / 65535.0).max(f64::MIN_POSITIVE);
            for v in &mut values {
                let q = ((v[c] as f64 - lo) / step).round();
                v[c] = (lo + q * step) as f32;
            }
        }
        l.entries = lensbake::lrtf::Entries::from_row_major(l.entries.dims(), Precision::F32, &values);
    }
    t
}

/// Catmull-Rom weights of the four nodes around fraction f (nodes -1, 0, 1, 2).
fn catmull_rom(f: f64) -> [f64; 4] {
    let (f2, f3) = (f * f, f * f * f);
    [
        0.5 * (-f3 + 2.0 * f2 - f),
        0.5 * (3.0 * f3 - 5.0 * f2 + 2.0),
        0.5 * (-3.0 * f3 + 4.0 * f2 + f),
        0.5 * (f3 - f2),
    ]
}

/// Measures a tricubic (Catmull-Rom, clamped at the borders) lookup of the same nodes.
fn cubic_error(
    table: &lensbake::lrtf::LrtfTable,
    tracer: &Tracer,
    efl: f64,
    count: usize,
) -> (f64, f64) {
    use lensbake::lrtf::bake::exact_transfer;
    use lensbake::lrtf::measure::{angle_between, pixel_pitch, renderer_rays, Stats};
    use lensbake::lrtf::param::to_lens_frame;
    let l = &table.layers[0];
    let dims = table.info.resolution;
    let rays = renderer_rays(
        &l.sampling.at_film_z(l.frame.film_plane_z),
        l.sampling.max_film_radius(),
        l.frame.film_plane_z,
        l.frame.rear_plane_z,
        count,
        0x5eed,
    );
    let stop = l.stop_semi_aperture;
    let mut mismatch = 0usize;
    let mut angles = Vec::new();
    for ray in &rays {
        let (exact, passes) = exact_transfer(tracer, ray);
        let exact = passes.then_some(exact).flatten();
        let looked = table.info.parameterisation.locate(&l.frame, &l.pupil, ray);
        let ours = looked.filter(|at| at.in_domain).and_then(|at| {
            let mut idx = [[0usize; 4]; 3];
            let mut w = [[0.0; 4]; 3];
            for a in 0..3 {
                let n = dims[a];
                let t = at.coords[a].clamp(0.0, 1.0) * (n - 1) as f64;
                let i = (t.floor() as usize).min(n - 2);
                let f = t - i as f64;
                // CUBIC_AXES: which axes are cubic (others linear), e.g. "12".
                let cubic_axes = std::env::var("CUBIC_AXES").unwrap_or("012".into());
                w[a] = if cubic_axes.contains(char::from(b'0' + a as u8)) {
                    catmull_rom(f)
                } else {
                    [0.0, 1.0 - f, f, 0.0]
                };
                for k in 0..4 {
                    idx[a][k] = (i as isize + k as isize - 1).clamp(0, n as isize - 1) as usize;
                }
            }
            let mut v = [0.0f64; 8];
            for a in 0..4 {
                for b in 0..4 {
                    for c in 0..4 {
                        let wt = w[0][a] * w[1][b] * w[2][c];
                        let e = l.entries.get([idx[0][a], idx[1][b], idx[2][c]]);
                        for ch in 0..8 {
                            v[ch] += wt * e[ch] as f64;
                        }
                    }
                }
            }
            let ok = v[4] >= 0.0 && v[5] * v[5] + v[6] * v[6] <= stop * stop;
            ok.then(|| {
                let d = table.info.parameterisation.decode_direction([v[2], v[3]]);
                let dxy = to_lens_frame([d[0], d[1]], &at);
                let n = (dxy[0] * dxy[0] + dxy[1] * dxy[1] + d[2] * d[2]).sqrt();
                [dxy[0] / n, dxy[1] / n, d[2] / n]
            })
        });
        match (exact, ours) {
            (Some(t), Some(d)) => angles.push(angle_between(t.exit_direction, d)),
            (None, None) => {}
            _ => mismatch += 1,
        }
    }
    let pitch = pixel_pitch(l.sampling.max_film_radius(), 1920.0);
    let p99 = Stats::of(angles.iter().map(|a| efl.abs() * a / pitch).collect()).p99;
    (p99, 1.0 - mismatch as f64 / count as f64)
}
