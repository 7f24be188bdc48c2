//! Triangle-mesh scenes: what glTF files and the built-in demo become before depth peeling.
//!
//! Units and frame: millimetres in the lens frame (z along the optical axis, light travels
//! towards +z, origin at the first lens vertex), so the scene lies at negative z, x right and
//! y up as seen from the lens — the same frame as the panels of [`super::scene`].
//!
//! Shading is unlit: a surface's linear RGB radiance is its base colour (factor times texture,
//! read as the albedo under a uniform white environment of unit radiance, no shadows) plus its
//! emission. The panels' radiance is reproduced exactly (see [`MeshScene::from_panels`]).

use super::layers::View;
use super::scene::{Outline, Scene, Texture};

/// How texture coordinates outside [0, 1] wrap (glTF sampler wrap modes).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Wrap {
    Repeat,
    ClampToEdge,
    MirroredRepeat,
}

/// Texel filter. There are no mipmaps: layers are point samples at pixel centres anyway.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Filter {
    Nearest,
    Linear,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Sampler {
    pub wrap: [Wrap; 2],
    pub filter: Filter,
}

/// A decoded image: linear RGBA texels, row-major, row 0 at texture coordinate v = 0 (glTF's
/// convention: v grows downwards in the image).
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    pub width: u32,
    pub height: u32,
    pub texels: Vec<[f32; 4]>,
}

/// A texture as a material uses it: an image and how it is sampled.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TextureRef {
    pub image: usize,
    pub sampler: Sampler,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    /// Linear RGB factor, multiplied by the texture when there is one.
    pub base_colour: [f32; 3],
    pub base_texture: Option<TextureRef>,
    /// Emitted linear RGB radiance (glTF emissive factor times emissive strength).
    pub emissive: [f32; 3],
    /// Single-sided triangles are seen only from the side their counter-clockwise winding faces.
    pub double_sided: bool,
}

impl Material {
    /// Uniform radiance, no texture, visible from both sides.
    pub fn emitter(radiance: [f32; 3]) -> Material {
        Material {
            base_colour: [0.0; 3],
            base_texture: None,
            emissive: radiance,
            double_sided: true,
        }
    }
}

/// One triangle: lens-frame corners (mm), their texture coordinates, and a material index.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Triangle {
    pub corners: [[f64; 3]; 3],
    pub uvs: [[f64; 2]; 3],
    pub material: usize,
}

#[derive(Clone, Debug, Default, PartialEq)]
pub struct MeshScene {
    pub triangles: Vec<Triangle>,
    pub materials: Vec<Material>,
    pub images: Vec<Image>,
}

/// Sides of the regular polygon that stands in for a disc panel.
pub const DISC_SIDES: usize = 64;

impl MeshScene {
    /// The scene as a camera sees it after orbiting `yaw_deg` to its right and `pitch_deg` up
    /// about the point on the axis `pivot_mm` in front of the first vertex, still looking at
    /// it: the scene turned the other way about that point (about the vertical axis by -yaw,
    /// then about the horizontal one by -pitch), so what lies at the pivot stays where it is.
    ///
    /// ```
    /// use lensbake::render::mesh::MeshScene;
    /// use lensbake::render::scene::Scene;
    /// let scene = MeshScene::from_panels(&Scene::demo());
    /// // Orbiting 90 degrees right about the chart (2 m): a chart corner x mm right of the axis
    /// // now lies on the axis, x mm nearer the camera than the pivot; its height stays.
    /// let turned = scene.clone().orbited(2000.0, [90.0, 0.0]);
    /// let chart = scene.triangles.iter().position(|t| t.corners[0][2] == -2000.0).unwrap();
    /// for (before, after) in scene.triangles[chart].corners.iter().zip(turned.triangles[chart].corners) {
    ///     assert!(after[0].abs() < 1e-9 && after[1] == before[1]);
    ///     assert!((after[2] - (before[0] - 2000.0)).abs() < 1e-9);
    /// }
    /// ```
    pub fn orbited(mut self, pivot_mm: f64, [yaw_deg, pitch_deg]: [f64; 2]) -> MeshScene {
        let (sy, cy) = (-yaw_deg).to_radians().sin_cos();
        let (sp, cp) = (-pitch_deg).to_radians().sin_cos();
        for triangle in &mut self.triangles {
            for corner in &mut triangle.corners {
                let [x, y, z] = [corner[0], corner[1], corner[2] + pivot_mm];
                // About y (vertical), then about x (horizontal), right-handed.
                let (x, z) = (cy * x + sy * z, -sy * x + cy * z);
                let (y, z) = (cp * y - sp * z, sp * y + cp * z);
                *corner = [x, y, z - pivot_mm];
            }
        }
        self
    }

    /// The panels as meshes: each rectangle two triangles, each disc a fan of [`DISC_SIDES`]
    /// with the disc's area. Solid panels emit their colour; a checker becomes a 2 x 2 texture,
    /// nearest-sampled and repeated with texture coordinates (x, y) / (2 period), so at every
    /// pixel centre off a checker line the mesh gives the panel's radiance bit for bit.
    pub fn from_panels(scene: &Scene) -> MeshScene {
        let mut mesh = MeshScene::default();
        for panel in &scene.panels {
            let material = mesh.materials.len();
            match panel.texture {
                Texture::Solid(radiance) => mesh.materials.push(Material::emitter(radiance)),
                Texture::Checker { a, b, .. } => {
                    let image = mesh.images.len();
                    let rgba = |c: [f32; 3]| [c[0], c[1], c[2], 1.0];
                    // Texel (column, row) = floor(x / period), floor(y / period) modulo 2.
                    mesh.images.push(Image {
                        width: 2,
                        height: 2,
                        texels: vec![rgba(a), rgba(b), rgba(b), rgba(a)],
                    });
                    mesh.materials.push(Material {
                        base_colour: [1.0; 3],
                        base_texture: Some(TextureRef {
                            image,
                            sampler: Sampler {
                                wrap: [Wrap::Repeat; 2],
                                filter: Filter::Nearest,
                            },
                        }),
                        emissive: [0.0; 3],
                        double_sided: true,
                    });
                }
            }
            let uv_scale = match panel.texture {
                Texture::Checker { period_mm, .. } => 0.5 / period_mm,
                Texture::Solid(_) => 0.0,
            };
            let z = -panel.distance_mm;
            let vertex = |p: [f64; 2]| ([p[0], p[1], z], [p[0] * uv_scale, p[1] * uv_scale]);
            let outline: Vec<([f64; 3], [f64; 2])> = match panel.outline {
                Outline::Rect { min, max } => [
                    [min[0], min[1]],
                    [max[0], min[1]],
                    [max[0], max[1]],
                    [min[0], max[1]],
                ]
                .map(vertex)
                .to_vec(),
                Outline::Disc { centre, radius } => {
                    let step = std::f64::consts::TAU / DISC_SIDES as f64;
                    // Equal area: n r^2 sin(2 pi / n) / 2 = pi R^2.
                    let r =
                        radius * (std::f64::consts::TAU / (DISC_SIDES as f64 * step.sin())).sqrt();
                    (0..DISC_SIDES)
                        .map(|k| {
                            let angle = k as f64 * step;
                            vertex([centre[0] + r * angle.cos(), centre[1] + r * angle.sin()])
                        })
                        .collect()
                }
            };
            // A fan over the convex outline, counter-clockwise seen from the lens (+z side).
            for k in 1..outline.len() - 1 {
                let (a, b, c) = (outline[0], outline[k], outline[k + 1]);
                mesh.triangles.push(Triangle {
                    corners: [a.0, b.0, c.0],
                    uvs: [a.1, b.1, c.1],
                    material,
                });
            }
        }
        mesh
    }

    /// Why no triangle reached a pixel of `view`: how many have no area, how many lie wholly
    /// behind its eye, and how many are left, which cover no pixel centre: outside the view, or
    /// between its pixels (a view of nearly 180 degrees across a few pixels).
    pub fn why_unseen(&self, view: &View) -> String {
        let flat = |t: &Triangle| {
            let n = cross3(
                sub3(t.corners[1], t.corners[0]),
                sub3(t.corners[2], t.corners[0]),
            );
            n.iter().all(|c| *c == 0.0)
        };
        let behind = |t: &Triangle| t.corners.iter().all(|c| view.eye_z - c[2] <= 0.0);
        let without_area = self.triangles.iter().filter(|t| flat(t)).count();
        let behind_eye = self
            .triangles
            .iter()
            .filter(|t| !flat(t) && behind(t))
            .count();
        let outside = self.triangles.len() - without_area - behind_eye;
        let degrees = view.tan_half.map(|t| 2.0 * t.atan().to_degrees());
        format!(
            "of its {} triangles, {without_area} have no area, {behind_eye} lie behind the \
             camera and {outside} cover no pixel centre of its {} x {} view, {:.1} x {:.1} \
             degrees across (outside it, or between its pixels)",
            self.triangles.len(),
            view.width,
            view.height,
            degrees[0],
            degrees[1]
        )
    }

    /// Nearest corner distance in front of the first vertex (mm), or None without triangles.
    pub fn nearest_distance_mm(&self) -> Option<f64> {
        self.triangles
            .iter()
            .flat_map(|t| t.corners.iter().map(|c| -c[2]))
            .reduce(f64::min)
    }

    /// Farthest corner distance in front of the first vertex (mm), or None without triangles.
    pub fn farthest_distance_mm(&self) -> Option<f64> {
        self.triangles
            .iter()
            .flat_map(|t| t.corners.iter().map(|c| -c[2]))
            .reduce(f64::max)
    }
}

pub(crate) fn sub3(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

pub(crate) fn cross3(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

pub(crate) fn dot3(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
