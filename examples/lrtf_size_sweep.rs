//! Accuracy per byte (issue 61, docs/lrtf.md): for each lens and grid, the p99 image error
//! (px of a 1920-pixel frame) and validity agreement against the exact trace of the table in
//! f32, f16 and u16, on `RAYS` renderer rays.
//!
//! cargo run --release --example lrtf_size_sweep -- RAYS LENS:FOCUS_MM...
//! e.g. `-- 50000 dgauss-50mm:2000 fisheye-10mm:2000`. Grids from $RES (default
//! 16,24,32,48,64,96,128; `AxBxC` for an anisotropic one). With $CUBIC set, also the same f32
//! nodes looked up with Catmull-Rom weights along the axes named in $CUBIC_AXES (default "012";
//! linear along the others), to measure what a higher-order lookup would buy.
use lensbake::lenses;
use lensbake::lrtf::Precision;
use lensbake::lrtf::bake::{BakeRequest, bake, first_order};
use lensbake::lrtf::measure::table_error;
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
            if v.len() == 1 {
                [v[0]; 3]
            } else {
                [v[0], v[1], v[2]]
            }
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
                    r[0],
                    r[1],
                    r[2],
                    table.entry_bytes(),
                    p99,
                    100.0 * agree
                );
            }
            for precision in ["f32", "f16", "u16"] {
                let t = match precision {
                    "f32" => table.clone(),
                    "f16" => table.to_precision(Precision::F16),
                    _ => table.to_precision(Precision::U16),
                };
                let bytes = t.entry_bytes();
                let e = table_error(&t, 0, &tracer, efl, 1920.0, rays, 0x5eed);
                println!(
                    "{name} {}x{}x{} {} bytes {} img p99 {:.4} px max {:.3} pos p99 {:.2} um agree {:.4} %",
                    r[0],
                    r[1],
                    r[2],
                    precision,
                    bytes,
                    e.image_px.p99,
                    e.image_px.max,
                    e.position_um.p99,
                    100.0 * (1.0 - e.validity_mismatch)
                );
            }
        }
    }
    Ok(())
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
    use lensbake::lrtf::measure::{Stats, angle_between, pixel_pitch, renderer_rays};
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
                for (k, node) in idx[a].iter_mut().enumerate() {
                    *node = (i as isize + k as isize - 1).clamp(0, n as isize - 1) as usize;
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
