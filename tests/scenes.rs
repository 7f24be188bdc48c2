//! Mesh scenes: glTF loading, depth peeling by rasterisation (GPU against its CPU twin, meshes
//! against the exact panel path), umbra peeling, and rendering a glTF scene.
#![cfg(feature = "cli")]

mod common;

use common::{relative, test_data};
use lensbake::model::{LensModel, ParaxialLens};
use lensbake::render::camera::{Camera, Film, Focus};
use lensbake::render::gltf_scene::load_gltf;
use lensbake::render::gpu_peel::GpuPeeler;
use lensbake::render::gpu_types::{
    PeelData, PeelMaterial, PeelParams, PeelTexture, PeelTriangle, PeelVertex,
};
use lensbake::render::layers::{LayeredDepthImage, View};
use lensbake::render::mesh::{DISC_SIDES, MeshScene};
use lensbake::render::mesh_trace::TracedMesh;
use lensbake::render::raster::{Peeling, mesh_layer_view, peel_cpu};
use lensbake::render::reference::{psnr, render_reference};
use lensbake::render::scene::{Outline, Scene, Texture};
use lensbake::render::wgsl::peel_shader;
use lensbake::render::{Backend, RenderError, RenderSettings, layer_view, render_layers};

/// The GPU peeler, or None outside CI when this machine has no adapter (as in tests/render.rs).
fn gpu_or_skip(test: &str) -> Option<GpuPeeler> {
    match GpuPeeler::new() {
        Ok(gpu) => Some(gpu),
        Err(RenderError::NoAdapter(why)) if std::env::var("CI").as_deref() != Ok("true") => {
            eprintln!("SKIPPED {test}: no GPU adapter ({why}); install mesa-vulkan-drivers");
            None
        }
        Err(e) => panic!("{test}: GPU unavailable: {e}"),
    }
}

fn settings(width: u32, height: u32) -> RenderSettings {
    RenderSettings {
        width,
        height,
        samples_per_pixel: 32,
        seed: 3,
        max_layers: 8,
    }
}

/// A 50 mm thin lens at `f_number` focused at `focus_mm`, full-frame film.
fn thin_camera(f_number: f64, focus_mm: f64, settings: &RenderSettings) -> Camera {
    let lens = ParaxialLens::thin(50.0, f_number).unwrap();
    let film = Film::full_frame_for(settings.width, settings.height);
    Camera::new(LensModel::Thin(lens), film, Focus::ObjectDistance(focus_mm)).unwrap()
}

fn quads() -> MeshScene {
    load_gltf(&test_data("quads.gltf")).unwrap()
}

#[test]
fn peel_shader_validates_and_shares_the_rust_layouts() {
    let module = naga::front::wgsl::parse_str(peel_shader())
        .unwrap_or_else(|e| panic!("peel.wgsl: {}", e.emit_to_string(peel_shader())));
    naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        naga::valid::Capabilities::default(),
    )
    .validate(&module)
    .unwrap_or_else(|e| panic!("peel.wgsl: {e:?}"));
    common::assert_wgsl_layout!(
        peel_shader(),
        PeelParams {
            width,
            height,
            pass_index,
            peeling,
            tan_half_x,
            tan_half_y,
            inverse_depth_scale,
            pixel_tangent,
            aperture_diameter,
            umbra_pixels,
            separation,
            pad
        }
    );
    common::assert_wgsl_layout!(
        peel_shader(),
        PeelTriangle {
            plane,
            u_map,
            v_map,
            material
        }
    );
    common::assert_wgsl_layout!(
        peel_shader(),
        PeelMaterial {
            base_colour,
            texture,
            emissive,
            pad
        }
    );
    common::assert_wgsl_layout!(
        peel_shader(),
        PeelTexture {
            offset,
            width,
            height,
            wrap_u,
            wrap_v,
            filter_mode
        }
    );
    // The vertex buffer layout is declared in gpu_peel.rs: position then triangle, 16 bytes.
    assert_eq!(std::mem::size_of::<PeelVertex>(), 16);
    assert_eq!(std::mem::offset_of!(PeelVertex, triangle), 12);
}

#[test]
fn gltf_files_load_in_lens_frame_millimetres() {
    let scene = quads();
    // .glb and data-URI copies of the same document load to the same scene.
    assert_eq!(load_gltf(&test_data("quads.glb")).unwrap(), scene);
    assert_eq!(load_gltf(&test_data("quads_embedded.gltf")).unwrap(), scene);
    // Four quads of two triangles; the camera node is not geometry.
    assert_eq!(scene.triangles.len(), 8);
    // The camera looks down world -x from x = +0.5 m with world -z to its right: a quad at
    // world x lies at lens z = (x - 0.5) * 1000 mm, lens x = -world z.
    let extent = |t: usize, k: usize| {
        let corners = scene.triangles[t]
            .corners
            .iter()
            .chain(&scene.triangles[t + 1].corners);
        let values: Vec<f64> = corners.map(|c| c[k]).collect();
        [
            values.iter().copied().fold(f64::INFINITY, f64::min),
            values.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        ]
    };
    for (first, z, half) in [
        (0, -1500.0, 100.0),
        (2, -2500.0, 300.0),
        (4, -3500.0, 500.0),
        (6, -4500.0, 2000.0),
    ] {
        for (k, expected) in [(0, [-half, half]), (1, [-half, half]), (2, [z, z])] {
            let got = extent(first, k);
            for (g, e) in got.iter().zip(expected) {
                // f32 data and a rotation whose cos 90 degrees rounds to ~6e-8.
                assert!(
                    (g - e).abs() <= 1e-6 * 4500.0,
                    "quad {first}, axis {k}: {got:?} vs {expected:?}"
                );
            }
        }
    }
    let glow = &scene.materials[scene.triangles[6].material];
    assert_eq!(
        glow.emissive,
        [0.2f32 * 2.0, 0.3 * 2.0, 0.5 * 2.0],
        "factor x strength"
    );
    assert_eq!(glow.base_colour, [0.0; 3]);
    assert!(!glow.double_sided);
    assert_eq!(scene.images.len(), 1);
    let image = &scene.images[0];
    assert_eq!((image.width, image.height), (4, 4));
    // Texel (column 1, row 2) is sRGB (70, 130, 200): decoded to linear.
    let srgb = |b: f64| {
        let c = b / 255.0;
        if c <= 0.04045 {
            c / 12.92
        } else {
            ((c + 0.055) / 1.055).powf(2.4)
        }
    };
    let texel = image.texels[2 * 4 + 1];
    for (t, b) in texel.iter().zip([70.0, 130.0, 200.0]) {
        assert!(relative(*t as f64, srgb(b)) < 1e-6, "{texel:?}");
    }
}

#[test]
fn bad_gltf_is_a_read_error_naming_the_file() {
    let dir = std::env::temp_dir().join(format!("lensbake-scenes-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("broken.gltf");
    std::fs::write(&path, "{\"asset\": {\"version\": \"2.0\"}, \"scenes\": [{\"nodes\": [0]}], \"nodes\": [{\"mesh\": 7}]}").unwrap();
    let error = load_gltf(&path).unwrap_err();
    assert!(
        matches!(error, RenderError::Read { ref path, .. } if path.ends_with("broken.gltf")),
        "{error}"
    );
    let missing = load_gltf(&dir.join("absent.glb")).unwrap_err();
    assert!(missing.to_string().contains("absent.glb"), "{missing}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Pixels whose centre lies within 1/64 pixel of a projected triangle edge: there the GPU's
/// snapped vertices may decide coverage differently from the exact twin.
fn near_edges(data: &PeelData) -> Vec<bool> {
    let p = &data.params;
    let (w, h) = (p.width as f64, p.height as f64);
    let mut near = vec![false; (p.width * p.height) as usize];
    let screen = |v: &PeelVertex| {
        let [x, y, d] = v.position.map(f64::from);
        [
            (x / (d * p.tan_half_x as f64) + 1.0) * 0.5 * w,
            (1.0 - y / (d * p.tan_half_y as f64)) * 0.5 * h,
        ]
    };
    for triangle in data.vertices.chunks(3) {
        let s: Vec<[f64; 2]> = triangle.iter().map(screen).collect();
        for (a, b) in [(s[0], s[1]), (s[1], s[2]), (s[2], s[0])] {
            let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
            let length = dx.hypot(dy);
            let columns =
                (a[0].min(b[0]) - 1.0).max(0.0) as u32..(a[0].max(b[0]) + 1.0).clamp(0.0, w) as u32;
            let rows =
                (a[1].min(b[1]) - 1.0).max(0.0) as u32..(a[1].max(b[1]) + 1.0).clamp(0.0, h) as u32;
            for row in rows {
                for column in columns.clone() {
                    let c = [column as f64 + 0.5, row as f64 + 0.5];
                    let t = (((c[0] - a[0]) * dx + (c[1] - a[1]) * dy) / (length * length))
                        .clamp(0.0, 1.0);
                    let distance = (c[0] - a[0] - t * dx).hypot(c[1] - a[1] - t * dy);
                    if distance < 1.0 / 64.0 {
                        near[(row * p.width + column) as usize] = true;
                    }
                }
            }
        }
    }
    near
}

/// Asserts equal layer counts and, at every pixel not skipped, equal emptiness, depths within
/// `depth_tolerance` relative and radiance within `colour_tolerance` relative. Returns the
/// number of skipped pixels and the largest relative depth and radiance differences.
fn assert_layers_match(
    what: &str,
    a: &LayeredDepthImage,
    b: &LayeredDepthImage,
    skip: &[bool],
    depth_tolerance: f64,
    colour_tolerance: f64,
) -> (usize, f64, f64) {
    assert_eq!(a.view, b.view, "{what}: views");
    let mut worst = (0.0f64, 0.0f64);
    assert_eq!(a.layer_count(), b.layer_count(), "{what}: layer counts");
    for (l, (la, lb)) in a.layers().zip(b.layers()).enumerate() {
        for (pixel, (sa, sb)) in la.samples().zip(lb.samples()).enumerate() {
            if skip[pixel] {
                continue;
            }
            match (sa, sb) {
                (None, None) => {}
                (Some(sa), Some(sb)) => {
                    let depth = relative(sa.depth_mm as f64, sb.depth_mm as f64);
                    worst.0 = worst.0.max(depth);
                    assert!(
                        depth <= depth_tolerance,
                        "{what}: layer {l} pixel {pixel}: depth {} vs {}",
                        sa.depth_mm,
                        sb.depth_mm
                    );
                    for c in 0..3 {
                        let colour = relative(sa.radiance[c] as f64, sb.radiance[c] as f64);
                        worst.1 = worst.1.max(colour);
                        assert!(
                            colour <= colour_tolerance,
                            "{what}: layer {l} pixel {pixel}: {:?} vs {:?}",
                            sa.radiance,
                            sb.radiance
                        );
                    }
                }
                _ => panic!("{what}: layer {l} pixel {pixel}: {sa:?} vs {sb:?}"),
            }
        }
    }
    (skip.iter().filter(|&&s| s).count(), worst.0, worst.1)
}

#[test]
fn gpu_peeling_matches_cpu_twin() {
    let Some(gpu) = gpu_or_skip("gpu_peeling_matches_cpu_twin") else {
        return;
    };
    let settings = settings(160, 120);
    let camera = thin_camera(2.0, 2000.0, &settings);
    let demo = MeshScene::from_panels(&Scene::demo());
    let quads = quads();
    for (name, scene) in [("demo", &demo), ("quads.gltf", &quads)] {
        let view = mesh_layer_view(&camera, &settings, scene).unwrap();
        for peeling in [Peeling::Plain, Peeling::umbra_for(&camera)] {
            let data = PeelData::of(scene, &view, peeling);
            let cpu = peel_cpu(&data, view, settings.max_layers);
            let started = std::time::Instant::now();
            let on_gpu = gpu.peel(&data, view, settings.max_layers).unwrap();
            let what = format!("{name}, {peeling:?}");
            // Depth and radiance come from the same f32 statements; the GPU may fuse a
            // multiply-add, so allow a few ulps.
            let (skipped, depth, colour) =
                assert_layers_match(&what, &cpu, &on_gpu, &near_edges(&data), 1e-6, 1e-6);
            eprintln!(
                "{what}: {} layers, {} surfels, {skipped} pixels within 1/64 px of an edge not compared, largest difference: depth {depth:.1e}, radiance {colour:.1e} (relative), GPU peel {:.1} ms on {}",
                cpu.layer_count(),
                cpu.surfel_count(),
                started.elapsed().as_secs_f64() * 1e3,
                gpu.adapter_description
            );
            assert!(
                skipped * 50 < (view.width * view.height) as usize,
                "{what}: {skipped} pixels near edges"
            );
        }
    }
}

/// Pixels where the panel path and its mesh may legitimately differ: centres within `margin_mm`
/// of a panel's outline, of a checker line, or between a disc and its polygon.
fn ambiguous_for_panels(scene: &Scene, view: &View, margin_mm: f64) -> Vec<bool> {
    (0..view.width * view.height)
        .map(|i| {
            let tan = view.pixel_tangents(i % view.width, i / view.width);
            scene.panels.iter().any(|panel| {
                let depth = view.eye_z + panel.distance_mm;
                let p = [tan[0] * depth, tan[1] * depth];
                let near_outline = match panel.outline {
                    Outline::Rect { min, max } => {
                        let within =
                            |k: usize| p[k] > min[k] - margin_mm && p[k] < max[k] + margin_mm;
                        let on = |k: usize| {
                            (p[k] - min[k]).abs() < margin_mm || (p[k] - max[k]).abs() < margin_mm
                        };
                        (on(0) && within(1)) || (on(1) && within(0))
                    }
                    Outline::Disc { centre, radius } => {
                        let r = (p[0] - centre[0]).hypot(p[1] - centre[1]);
                        let step = std::f64::consts::TAU / DISC_SIDES as f64;
                        let polygon = radius
                            * (std::f64::consts::TAU / (DISC_SIDES as f64 * step.sin())).sqrt();
                        // Between the polygon's inscribed circle and its corners.
                        r > polygon * (step / 2.0).cos() - margin_mm && r < polygon + margin_mm
                    }
                };
                let near_line = match panel.texture {
                    Texture::Checker { period_mm, .. } => (0..2).any(|k| {
                        let q = p[k] / period_mm;
                        (q - q.round()).abs() * period_mm < margin_mm
                    }),
                    Texture::Solid(_) => false,
                };
                near_outline || near_line
            })
        })
        .collect()
}

#[test]
fn demo_as_meshes_peels_exactly_like_the_panels() {
    let settings = settings(200, 150);
    let camera = thin_camera(2.0, 2000.0, &settings);
    let scene = Scene::demo();
    let view = layer_view(
        &camera,
        &settings,
        scene.nearest_distance_mm().unwrap() + camera.eye_z(),
    );
    let panels = scene.peel(view, settings.max_layers);
    let meshes = peel_cpu(
        &PeelData::of(&MeshScene::from_panels(&scene), &view, Peeling::Plain),
        view,
        settings.max_layers,
    );
    // Both evaluate the same ray through each pixel centre: plane depths agree exactly (the
    // mesh planes are fronto-parallel), radiance exactly (the same f32 colours). Only centres
    // within 0.01 mm of an edge (f32 texture coordinates, f64 panel tests) or between a disc
    // and its 64-gon may differ.
    let skip = ambiguous_for_panels(&scene, &view, 0.01);
    let (skipped, _, _) =
        assert_layers_match("demo panels vs meshes", &panels, &meshes, &skip, 0.0, 0.0);
    eprintln!(
        "demo: {} layers, {skipped} of {} pixels on an edge not compared",
        panels.layer_count(),
        skip.len()
    );
    // An odd-sized view puts a column and a row of centres exactly on the checker lines
    // through the axis (x = 0, y = 0); beyond those, edges should catch very few.
    assert!(
        skipped <= (view.width + view.height) as usize + skip.len() / 200,
        "{skipped} ambiguous pixels"
    );
}

#[test]
fn gltf_scene_peels_its_three_visible_quads() {
    let settings = settings(96, 64);
    let camera = thin_camera(2.0, 2500.0, &settings);
    let scene = quads();
    let view = mesh_layer_view(&camera, &settings, &scene).unwrap();
    let ldi = peel_cpu(
        &PeelData::of(&scene, &view, Peeling::Plain),
        view,
        settings.max_layers,
    );
    // Near quad, chart, wall: the single-sided quad between chart and wall faces away.
    assert_eq!(ldi.layer_count(), 3);
    let (column, row) = (view.width / 2 + 3, view.height / 2 - 2);
    let pixel = (row * view.width + column) as usize;
    let tan = view.pixel_tangents(column, row);
    let samples: Vec<_> = ldi.layers().map(|l| l.get(pixel).unwrap()).collect();
    for (s, distance) in samples.iter().zip([1500.0, 2500.0, 4500.0]) {
        let depth = camera.eye_z() + distance;
        assert!(
            relative(s.depth_mm as f64, depth) < 1e-6,
            "{s:?} vs {depth}"
        );
    }
    assert_eq!(samples[0].radiance, [0.8, 0.1, 0.1]);
    assert_eq!(samples[2].radiance, [0.2f32 * 2.0, 0.3 * 2.0, 0.5 * 2.0]);
    // The chart's texel under this pixel: u runs with lens x, v against lens y, over 600 mm.
    let depth = camera.eye_z() + 2500.0;
    let uv = [
        (tan[0] * depth + 300.0) / 600.0 * 4.0,
        (300.0 - tan[1] * depth) / 600.0 * 4.0,
    ];
    assert!(
        uv.iter().all(|t| (t - t.round()).abs() > 0.05),
        "pick a pixel off texel edges: {uv:?}"
    );
    let texel = scene.images[0].texels[uv[1] as usize * 4 + uv[0] as usize];
    assert_eq!(samples[1].radiance, [texel[0], texel[1], texel[2]]);

    // Rendered through the lens: finite everywhere, and close to the true-geometry reference.
    let image = render_layers(&camera, &ldi, &settings, Backend::Cpu, None).unwrap();
    assert!(
        image
            .pixels
            .iter()
            .flatten()
            .all(|v| v.is_finite() && *v >= 0.0)
    );
    let reference = render_reference(&camera, &TracedMesh::new(&scene), &settings).unwrap();
    let score = psnr(&image, &reference);
    eprintln!("quads.gltf: IBRT vs ray-traced meshes {score:.1} dB");
    assert!(score > 25.0, "{score}");
}

#[test]
fn umbra_peeling_drops_exactly_the_hidden_layers() {
    // At 96 px a pixel spans 7.3e-3 in tangent: the near quad's sample (1500 mm) is 11 mm wide
    // and its umbra for a 25 mm pupil reaches 1500 * 11 / (25 - 11) mm behind it, past the
    // chart; the chart's (18 mm at 2500) reaches past the wall; the wall's sample is wider
    // than the pupil. So the near quad's pixels keep near + wall, the chart's keep the chart.
    let settings = settings(96, 64);
    let camera = thin_camera(2.0, 2500.0, &settings);
    let scene = quads();
    let view = mesh_layer_view(&camera, &settings, &scene).unwrap();
    let peeling = Peeling::umbra_for(&camera);
    let Peeling::Umbra {
        aperture_diameter_mm,
        ..
    } = peeling
    else {
        unreachable!()
    };
    assert!((aperture_diameter_mm - 25.0).abs() < 1e-12);
    let pitch = 2.0 * view.tan_half[0] / view.width as f64;
    let umbra = |d: f64| d * pitch * d / (aperture_diameter_mm - pitch * d);
    assert!(umbra(1500.0) > 1000.0 && umbra(2500.0) > 2000.0 && pitch * 4500.0 > 25.0);
    let plain = peel_cpu(&PeelData::of(&scene, &view, Peeling::Plain), view, 8);
    let ldi = peel_cpu(&PeelData::of(&scene, &view, peeling), view, 8);
    assert_eq!((plain.layer_count(), ldi.layer_count()), (3, 2));
    let pixel = ((view.height / 2) * view.width + view.width / 2) as usize;
    let depths: Vec<f32> = ldi
        .pixel_surfels(pixel)
        .iter()
        .map(|s| s.depth_mm)
        .collect();
    assert_eq!(
        depths,
        [
            plain.surfel(0, pixel).unwrap().depth_mm,
            plain.surfel(2, pixel).unwrap().depth_mm
        ]
    );
}

#[test]
fn umbra_peeling_on_the_demo_keeps_the_image() {
    // The demo's layers at the output pitch: umbra peeling keeps the layer count (post over
    // chart over wall needs 3 either way) but drops the wall behind the distant lights. What
    // it drops must be (nearly) invisible through the lens.
    let settings = RenderSettings {
        samples_per_pixel: 64,
        ..settings(160, 120)
    };
    let camera = thin_camera(2.0, 2000.0, &settings);
    let scene = MeshScene::from_panels(&Scene::demo());
    let view = mesh_layer_view(&camera, &settings, &scene).unwrap();
    let plain = peel_cpu(&PeelData::of(&scene, &view, Peeling::Plain), view, 8);
    let umbra = peel_cpu(
        &PeelData::of(&scene, &view, Peeling::umbra_for(&camera)),
        view,
        8,
    );
    let (kept, all) = (umbra.surfel_count(), plain.surfel_count());
    eprintln!(
        "demo at {}x{}: plain {} layers / {all} surfels, umbra {} layers / {kept} surfels",
        view.width,
        view.height,
        plain.layer_count(),
        umbra.layer_count()
    );
    assert!(kept < all && umbra.layer_count() <= plain.layer_count());
    // Every umbra surfel is one of the plain surfels of its pixel, in the same order.
    for pixel in 0..(view.width * view.height) as usize {
        let of = |ldi: &LayeredDepthImage| -> Vec<f32> {
            ldi.pixel_surfels(pixel)
                .iter()
                .map(|s| s.depth_mm)
                .collect()
        };
        let (u, p) = (of(&umbra), of(&plain));
        let mut rest = p.iter();
        assert!(
            u.iter().all(|d| rest.any(|q| q == d)),
            "pixel {pixel}: {u:?} not within {p:?}"
        );
    }
    let a = render_layers(&camera, &plain, &settings, Backend::Cpu, None).unwrap();
    let b = render_layers(&camera, &umbra, &settings, Backend::Cpu, None).unwrap();
    let score = psnr(&b, &a);
    eprintln!("demo: umbra vs plain layers, rendered: {score:.1} dB");
    assert!(score > 40.0, "{score}");
}

#[test]
fn umbra_peeling_saves_layers_on_overlapping_cards() {
    // Twelve cards 0.1 m apart in depth, each overlapping the next: plain peeling needs a layer
    // per card; umbra peeling skips the cards that a nearer card's pixel hides from the whole
    // entrance pupil. The rendered images must agree: what was skipped was not visible.
    let settings = RenderSettings {
        samples_per_pixel: 64,
        max_layers: 16,
        ..settings(200, 150)
    };
    let camera = thin_camera(2.0, 3500.0, &settings);
    let scene = load_gltf(&test_data("cards.glb")).unwrap();
    let view = mesh_layer_view(&camera, &settings, &scene).unwrap();
    let plain = peel_cpu(&PeelData::of(&scene, &view, Peeling::Plain), view, 16);
    let umbra = peel_cpu(
        &PeelData::of(&scene, &view, Peeling::umbra_for(&camera)),
        view,
        16,
    );
    eprintln!(
        "cards at {}x{}: plain {} layers / {} surfels, umbra {} layers / {} surfels",
        view.width,
        view.height,
        plain.layer_count(),
        plain.surfel_count(),
        umbra.layer_count(),
        umbra.surfel_count()
    );
    assert_eq!(plain.layer_count(), 13, "twelve cards and the wall");
    assert!(umbra.layer_count() <= 3, "{}", umbra.layer_count());
    let a = render_layers(&camera, &plain, &settings, Backend::Cpu, None).unwrap();
    let b = render_layers(&camera, &umbra, &settings, Backend::Cpu, None).unwrap();
    let reference = render_reference(&camera, &TracedMesh::new(&scene), &settings).unwrap();
    let (same, plain_score, umbra_score) =
        (psnr(&b, &a), psnr(&a, &reference), psnr(&b, &reference));
    eprintln!(
        "cards: umbra vs plain {same:.1} dB; against ray-traced meshes plain {plain_score:.1} dB, umbra {umbra_score:.1} dB"
    );
    assert!(
        same > 35.0 && umbra_score > plain_score - 1.0,
        "{same} {plain_score} {umbra_score}"
    );
}

#[test]
fn render_cli_takes_gltf_scenes_and_refuses_broken_ones() {
    let dir = std::env::temp_dir().join(format!("lensbake-scenes-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let run = |scene: &std::path::Path, out: &str| {
        std::process::Command::new(env!("CARGO_BIN_EXE_lensbake"))
            .args([
                "render",
                "--lens",
                "ideal:50",
                "--model",
                "thin",
                "--f-number",
                "2",
            ])
            .args([
                "--width",
                "48",
                "--height",
                "32",
                "--spp",
                "4",
                "--backend",
                "cpu",
                "--peel",
                "plain",
            ])
            .arg("--scene")
            .arg(scene)
            .arg("--out")
            .arg(dir.join(out))
            .output()
            .unwrap()
    };
    let ok = run(&test_data("quads.glb"), "quads.exr");
    let stdout = String::from_utf8_lossy(&ok.stdout);
    assert_eq!(
        ok.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&ok.stderr)
    );
    assert!(stdout.contains("peeled 3 layers"), "{stdout}");
    assert!(dir.join("quads.exr").exists() && dir.join("quads.png").exists());
    let broken = dir.join("broken.glb");
    std::fs::write(&broken, b"glTF not really").unwrap();
    let bad = run(&broken, "bad.exr");
    let stderr = String::from_utf8_lossy(&bad.stderr);
    assert_eq!(bad.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("broken.glb"), "{stderr}");
    assert!(!dir.join("bad.exr").exists());
    std::fs::remove_dir_all(&dir).unwrap();
}
