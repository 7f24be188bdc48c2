//! glTF 2.0 scenes (`.gltf` with embedded or adjacent buffers and images, or `.glb`) as
//! [`MeshScene`]s.
//!
//! Units and camera: glTF lengths are metres; the scene becomes millimetres. The view is that of
//! the first camera node met walking the default scene depth-first (its projection is ignored:
//! the lens and film set the field), else the world origin looking down world -z. glTF camera
//! space (x right, y up, looking down -z) is the lens frame as seen from the lens, so a point
//! is mapped by p_lens = 1000 * inverse(camera world matrix) * p_world: the camera's origin is
//! the lens's first vertex and the scene lies at negative lens-frame z, where the lens looks.
//!
//! What is read: triangle primitives (lists, strips, fans) with their node transforms, indices,
//! positions and the base-colour texture's coordinate set; base colour factor and texture
//! (sRGB decoded to linear, the sampler's wrap modes and magnification filter), emissive
//! factor times `KHR_materials_emissive_strength`, `doubleSided`. Not read: points and lines
//! (no area), alpha (every surface is opaque), emissive textures, vertex colours, texture
//! transforms, skins and morph targets (the bind pose is used), lights.
//!
//! Hostile files are refused before the `gltf` crate walks them: buffers and images load only
//! from data: URIs and relative paths inside the file's folder (regular files under the input
//! limit); nodes must form trees no deeper than [`limits::MAX_SCENE_DEPTH`]; every accessor a
//! primitive reads must have the component type its attribute allows, no sparse part, and lie
//! inside its buffer view and buffer (the crate panics on float indices and silently drops
//! overrunning items); colours must be radiances ([`limits::is_radiance`]).

use super::RenderError;
use super::mesh::{Filter, Image, Material, MeshScene, Sampler, TextureRef, Triangle, Wrap};
use crate::limits;
use gltf::mesh::Mode;
use nalgebra::Matrix4;
use std::path::{Path, PathBuf};

const MM_PER_METRE: f64 = 1000.0;

fn read_error(path: &Path, reason: String) -> RenderError {
    RenderError::Read {
        path: path.to_path_buf(),
        reason,
    }
}

fn matrix(node: &gltf::Node) -> Matrix4<f64> {
    let columns = node.transform().matrix();
    Matrix4::from_fn(|row, column| f64::from(columns[column][row]))
}

/// The world matrix of the first camera node under `nodes` (depth-first), if any.
fn find_camera(
    nodes: &mut dyn Iterator<Item = gltf::Node>,
    parent: Matrix4<f64>,
) -> Option<Matrix4<f64>> {
    for node in nodes {
        let world = parent * matrix(&node);
        if node.camera().is_some() {
            return Some(world);
        }
        if let Some(found) = find_camera(&mut node.children(), world) {
            return Some(found);
        }
    }
    None
}

fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// Linear RGBA texels of a decoded glTF image (colour channels sRGB-decoded when stored as
/// integers; float images are linear already).
fn linear_image(data: &gltf::image::Data) -> Result<Image, String> {
    use gltf::image::Format;
    let (channels, bytes_per_channel) = match data.format {
        Format::R8 => (1, 1),
        Format::R8G8 => (2, 1),
        Format::R8G8B8 => (3, 1),
        Format::R8G8B8A8 => (4, 1),
        Format::R16 => (1, 2),
        Format::R16G16 => (2, 2),
        Format::R16G16B16 => (3, 2),
        Format::R16G16B16A16 => (4, 2),
        Format::R32G32B32FLOAT => (3, 4),
        Format::R32G32B32A32FLOAT => (4, 4),
    };
    let texel_bytes = channels * bytes_per_channel;
    let count = data.width as usize * data.height as usize;
    if data.pixels.len() != count * texel_bytes || count == 0 {
        return Err(format!(
            "image of {}x{} has {} bytes of pixels",
            data.width,
            data.height,
            data.pixels.len()
        ));
    }
    let channel = |bytes: &[u8]| -> f32 {
        match bytes_per_channel {
            1 => srgb_to_linear(f32::from(bytes[0]) / 255.0),
            2 => srgb_to_linear(f32::from(u16::from_le_bytes([bytes[0], bytes[1]])) / 65535.0),
            _ => f32::from_le_bytes([bytes[0], bytes[1], bytes[2], bytes[3]]),
        }
    };
    let texels = data
        .pixels
        .chunks_exact(texel_bytes)
        .map(|t| {
            let c: Vec<f32> = t.chunks_exact(bytes_per_channel).map(channel).collect();
            // Grey images replicate their one channel; alpha is not used.
            match channels {
                1 | 2 => [c[0], c[0], c[0], 1.0],
                _ => [c[0], c[1], c[2], 1.0],
            }
        })
        .collect();
    Ok(Image {
        width: data.width,
        height: data.height,
        texels,
    })
}

fn wrap(mode: gltf::texture::WrappingMode) -> Wrap {
    use gltf::texture::WrappingMode;
    match mode {
        WrappingMode::Repeat => Wrap::Repeat,
        WrappingMode::ClampToEdge => Wrap::ClampToEdge,
        WrappingMode::MirroredRepeat => Wrap::MirroredRepeat,
    }
}

/// Builds the scene's materials and images on first use.
struct Converter<'a> {
    path: &'a Path,
    images: &'a [gltf::image::Data],
    scene: MeshScene,
    /// glTF material index (None: the default material) -> ours, with its texture coordinate set.
    materials: Vec<(Option<usize>, usize, u32)>,
    image_indices: Vec<(usize, usize)>,
}

impl Converter<'_> {
    fn image(&mut self, index: usize) -> Result<usize, RenderError> {
        if let Some(&(_, ours)) = self.image_indices.iter().find(|(i, _)| *i == index) {
            return Ok(ours);
        }
        let data = self
            .images
            .get(index)
            .ok_or_else(|| read_error(self.path, format!("image {index} is missing")))?;
        let image =
            linear_image(data).map_err(|e| read_error(self.path, format!("image {index}: {e}")))?;
        self.scene.images.push(image);
        let ours = self.scene.images.len() - 1;
        self.image_indices.push((index, ours));
        Ok(ours)
    }

    /// Our material for a glTF material, and the texture coordinate set its texture reads.
    fn material(&mut self, material: gltf::Material) -> Result<(usize, u32), RenderError> {
        let key = material.index();
        if let Some(&(_, ours, set)) = self.materials.iter().find(|(k, _, _)| *k == key) {
            return Ok((ours, set));
        }
        let pbr = material.pbr_metallic_roughness();
        let factor = pbr.base_color_factor();
        let (base_texture, set) = match pbr.base_color_texture() {
            Some(info) => {
                let texture = info.texture();
                let sampler = texture.sampler();
                let filter = match sampler.mag_filter() {
                    Some(gltf::texture::MagFilter::Nearest) => Filter::Nearest,
                    _ => Filter::Linear,
                };
                let image = self.image(texture.source().index())?;
                (
                    Some(TextureRef {
                        image,
                        sampler: Sampler {
                            wrap: [wrap(sampler.wrap_s()), wrap(sampler.wrap_t())],
                            filter,
                        },
                    }),
                    info.tex_coord(),
                )
            }
            None => (None, 0),
        };
        let strength = material.emissive_strength().unwrap_or(1.0);
        let ours = Material {
            base_colour: [factor[0], factor[1], factor[2]],
            base_texture,
            emissive: material.emissive_factor().map(|e| e * strength),
            double_sided: material.double_sided(),
        };
        let finite = ours
            .base_colour
            .iter()
            .chain(&ours.emissive)
            .all(|&v| limits::is_radiance(v as f64));
        if !finite {
            return Err(read_error(
                self.path,
                format!(
                    "material {}: colours must be finite, non-negative and at most {:e}",
                    key.map_or("(default)".to_string(), |k| k.to_string()),
                    limits::MAX_RADIANCE
                ),
            ));
        }
        self.scene.materials.push(ours);
        let index = self.scene.materials.len() - 1;
        self.materials.push((key, index, set));
        Ok((index, set))
    }

    fn node(
        &mut self,
        node: gltf::Node,
        parent: Matrix4<f64>,
        view: &Matrix4<f64>,
        buffers: &[gltf::buffer::Data],
    ) -> Result<(), RenderError> {
        let world = parent * matrix(&node);
        if let Some(mesh) = node.mesh() {
            let to_lens = view * world;
            for primitive in mesh.primitives() {
                let what = format!("mesh {} primitive {}", mesh.index(), primitive.index());
                let corners_of: fn(usize) -> Vec<[usize; 3]> = match primitive.mode() {
                    Mode::Triangles => {
                        |n| (0..n / 3).map(|t| [3 * t, 3 * t + 1, 3 * t + 2]).collect()
                    }
                    // Every other strip triangle is flipped to keep the winding.
                    Mode::TriangleStrip => |n| {
                        (0..n.saturating_sub(2))
                            .map(|t| {
                                if t % 2 == 0 {
                                    [t, t + 1, t + 2]
                                } else {
                                    [t + 1, t, t + 2]
                                }
                            })
                            .collect()
                    },
                    Mode::TriangleFan => {
                        |n| (1..n.saturating_sub(1)).map(|t| [0, t, t + 1]).collect()
                    }
                    Mode::Points | Mode::Lines | Mode::LineLoop | Mode::LineStrip => continue,
                };
                let (material, set) = self.material(primitive.material())?;
                check_accessors(&primitive, set, buffers)
                    .map_err(|reason| read_error(self.path, format!("{what}: {reason}")))?;
                let reader = primitive.reader(|b| buffers.get(b.index()).map(|d| &d.0[..]));
                let positions: Vec<[f64; 3]> = reader
                    .read_positions()
                    .ok_or_else(|| read_error(self.path, format!("{what}: no POSITION attribute")))?
                    .map(|p| {
                        let q = to_lens
                            * nalgebra::Vector4::new(p[0] as f64, p[1] as f64, p[2] as f64, 1.0);
                        [
                            q[0] * MM_PER_METRE,
                            q[1] * MM_PER_METRE,
                            q[2] * MM_PER_METRE,
                        ]
                    })
                    .collect();
                if positions.iter().flatten().any(|v| !v.is_finite()) {
                    return Err(read_error(
                        self.path,
                        format!("{what}: non-finite position"),
                    ));
                }
                let uvs: Vec<[f64; 2]> = match reader.read_tex_coords(set) {
                    Some(uvs) => uvs.into_f32().map(|t| [t[0] as f64, t[1] as f64]).collect(),
                    None => vec![[0.0; 2]; positions.len()],
                };
                if uvs.len() != positions.len() {
                    return Err(read_error(
                        self.path,
                        format!(
                            "{what}: {} texture coordinates for {} positions",
                            uvs.len(),
                            positions.len()
                        ),
                    ));
                }
                let indices: Vec<usize> = match reader.read_indices() {
                    Some(indices) => indices.into_u32().map(|i| i as usize).collect(),
                    None => (0..positions.len()).collect(),
                };
                if let Some(bad) = indices.iter().find(|&&i| i >= positions.len()) {
                    return Err(read_error(
                        self.path,
                        format!(
                            "{what}: index {bad} beyond its {} vertices",
                            positions.len()
                        ),
                    ));
                }
                let triangles = self.scene.triangles.len() as u64 + indices.len() as u64 / 3;
                limits::check(
                    "the scene's triangle count",
                    triangles,
                    limits::MAX_TRIANGLES,
                )
                .map_err(|e| read_error(self.path, e.to_string()))?;
                for corners in corners_of(indices.len()) {
                    let v = corners.map(|c| indices[c]);
                    self.scene.triangles.push(Triangle {
                        corners: v.map(|i| positions[i]),
                        uvs: v.map(|i| uvs[i]),
                        material,
                    });
                }
            }
        }
        for child in node.children() {
            self.node(child, world, view, buffers)?;
        }
        Ok(())
    }
}

/// Loads a glTF 2.0 file (`.gltf` or `.glb`) as a mesh scene in the lens frame (see the module
/// notes for units and camera).
pub fn load_gltf(path: &Path) -> Result<MeshScene, RenderError> {
    let bytes = limits::read_input(path).map_err(|e| read_error(path, e.to_string()))?;
    let unreadable =
        |e: gltf::Error| read_error(path, format!("not a readable glTF 2.0 file: {e}"));
    let gltf::Gltf { document, mut blob } = gltf::Gltf::from_slice(&bytes).map_err(unreadable)?;
    check_node_trees(&document).map_err(|reason| read_error(path, reason))?;
    let folder = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let mut buffers = Vec::new();
    for buffer in document.buffers() {
        if let gltf::buffer::Source::Uri(uri) = buffer.source() {
            check_uri(folder, uri).map_err(|reason| {
                read_error(path, format!("buffer {}: {reason}", buffer.index()))
            })?;
        }
        let data =
            gltf::buffer::Data::from_source_and_blob(buffer.source(), Some(folder), &mut blob)
                .map_err(unreadable)?;
        if data.len() < buffer.length() {
            return Err(read_error(
                path,
                format!(
                    "buffer {} holds {} bytes, its byteLength says {}",
                    buffer.index(),
                    data.len(),
                    buffer.length()
                ),
            ));
        }
        buffers.push(data);
    }
    let mut images = Vec::new();
    for image in document.images() {
        if let gltf::image::Source::Uri { uri, .. } = image.source() {
            check_uri(folder, uri)
                .map_err(|reason| read_error(path, format!("image {}: {reason}", image.index())))?;
        }
        let decoded = gltf::image::Data::from_source(image.source(), Some(folder), &buffers)
            .map_err(|e| match e {
                // The decoder reads the size from the header and refuses before allocating.
                gltf::Error::Image(image::ImageError::Limits(_)) => read_error(
                    path,
                    format!(
                        "image {}: its header claims a size that needs more than the decoder's \
                         512 MiB (docs/limits.md)",
                        image.index()
                    ),
                ),
                other => unreadable(other),
            })?;
        images.push(decoded);
    }
    let scene = document
        .default_scene()
        .or_else(|| document.scenes().next())
        .ok_or_else(|| read_error(path, "the file has no scene".to_string()))?;
    let view = match find_camera(&mut scene.nodes(), Matrix4::identity()) {
        Some(camera) => camera.try_inverse().ok_or_else(|| {
            read_error(path, "the camera node's transform is singular".to_string())
        })?,
        None => Matrix4::identity(),
    };
    let mut converter = Converter {
        path,
        images: &images,
        scene: MeshScene::default(),
        materials: Vec::new(),
        image_indices: Vec::new(),
    };
    for node in scene.nodes() {
        converter.node(node, Matrix4::identity(), &view, &buffers)?;
    }
    if converter.scene.triangles.is_empty() {
        return Err(read_error(path, "the scene has no triangles".to_string()));
    }
    Ok(converter.scene)
}

/// Refuses a buffer or image URI that is not a data: URI or a relative path to a regular file
/// inside `folder` (no absolute path, no `..`, no other scheme, no link out of the folder).
fn check_uri(folder: &Path, uri: &str) -> Result<(), String> {
    if uri.starts_with("data:") {
        return Ok(());
    }
    let refuse = |why: &str| {
        Err(format!(
            "uri `{}` {why}; only data: URIs and relative paths inside the glTF file's folder are read",
            uri.chars().take(80).collect::<String>()
        ))
    };
    if uri.contains(':') {
        return refuse("names a scheme or drive");
    }
    let Some(decoded) = percent_decode(uri) else {
        return refuse("has a malformed percent escape");
    };
    let relative = Path::new(&decoded);
    if relative.as_os_str().is_empty()
        || !relative.components().all(|c| {
            matches!(
                c,
                std::path::Component::Normal(_) | std::path::Component::CurDir
            )
        })
    {
        return refuse("leaves the folder");
    }
    let full = folder.join(relative);
    let metadata = std::fs::metadata(&full).map_err(|e| format!("{}: {e}", full.display()))?;
    if !metadata.is_file() {
        return refuse("is not a regular file");
    }
    limits::check(
        "the referenced file's size in bytes",
        metadata.len(),
        limits::MAX_INPUT_BYTES,
    )
    .map_err(|e| e.to_string())?;
    let inside = match (full.canonicalize(), folder.canonicalize()) {
        (Ok(file), Ok(folder)) => file.starts_with(folder),
        _ => false,
    };
    if !inside {
        return refuse("links out of the folder");
    }
    Ok(())
}

/// `%XX` escapes decoded; None when an escape is malformed or the result is not UTF-8.
fn percent_decode(text: &str) -> Option<String> {
    let bytes = text.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%' {
            let hex = std::str::from_utf8(bytes.get(i + 1..i + 3)?).ok()?;
            out.push(u8::from_str_radix(hex, 16).ok()?);
            i += 3;
        } else {
            out.push(bytes[i]);
            i += 1;
        }
    }
    String::from_utf8(out).ok()
}

/// Refuses node graphs that are not trees (a node with two parents, a scene root that is also a
/// child, so also every cycle reachable from a scene) and trees deeper than
/// [`limits::MAX_SCENE_DEPTH`], before anything recurses over them.
fn check_node_trees(document: &gltf::Document) -> Result<(), String> {
    let mut parents = vec![0usize; document.nodes().len()];
    for node in document.nodes() {
        for child in node.children() {
            parents[child.index()] += 1;
            if parents[child.index()] > 1 {
                return Err(format!(
                    "node {} has more than one parent (glTF nodes form trees)",
                    child.index()
                ));
            }
        }
    }
    for scene in document.scenes() {
        let mut stack: Vec<(gltf::Node, u64)> = Vec::new();
        for root in scene.nodes() {
            if parents[root.index()] > 0 {
                return Err(format!(
                    "scene {} lists node {} as a root, but it is a child",
                    scene.index(),
                    root.index()
                ));
            }
            stack.push((root, 1));
        }
        while let Some((node, depth)) = stack.pop() {
            limits::check("the node tree's depth", depth, limits::MAX_SCENE_DEPTH)
                .map_err(|e| e.to_string())?;
            stack.extend(node.children().map(|child| (child, depth + 1)));
        }
    }
    Ok(())
}

/// Refuses accessors the `gltf` reader cannot read safely: a component type its attribute does
/// not allow (the reader panics on float indices), a sparse part, or items beyond the end of the
/// buffer view or buffer (the reader silently yields fewer).
fn check_accessors(
    primitive: &gltf::Primitive,
    tex_coord_set: u32,
    buffers: &[gltf::buffer::Data],
) -> Result<(), String> {
    use gltf::Semantic;
    use gltf::accessor::{DataType, Dimensions};
    let mut checks = Vec::new();
    if let Some(indices) = primitive.indices() {
        checks.push((
            "indices",
            indices,
            &[DataType::U8, DataType::U16, DataType::U32][..],
            Dimensions::Scalar,
        ));
    }
    if let Some(positions) = primitive.get(&Semantic::Positions) {
        checks.push((
            "POSITION",
            positions,
            &[DataType::F32][..],
            Dimensions::Vec3,
        ));
    }
    if let Some(uvs) = primitive.get(&Semantic::TexCoords(tex_coord_set)) {
        checks.push((
            "TEXCOORD",
            uvs,
            &[DataType::U8, DataType::U16, DataType::F32][..],
            Dimensions::Vec2,
        ));
    }
    for (name, accessor, types, dimensions) in checks {
        let at = format!("{name} (accessor {})", accessor.index());
        if !types.contains(&accessor.data_type()) || accessor.dimensions() != dimensions {
            return Err(format!(
                "{at} is {:?} {:?}; it must be {dimensions:?} of {types:?}",
                accessor.dimensions(),
                accessor.data_type()
            ));
        }
        if accessor.sparse().is_some() {
            return Err(format!("{at} is sparse, which is not read"));
        }
        let view = accessor
            .view()
            .ok_or_else(|| format!("{at} has no buffer view"))?;
        let item = accessor.size();
        let stride = view.stride().unwrap_or(item);
        let end = accessor
            .count()
            .checked_sub(1)
            .and_then(|n| n.checked_mul(stride))
            .and_then(|n| n.checked_add(accessor.offset()))
            .and_then(|n| n.checked_add(item));
        let view_end = view.offset().checked_add(view.length());
        let buffer_length = buffers.get(view.buffer().index()).map(|b| b.len());
        match (end, view_end, buffer_length) {
            (Some(end), Some(view_end), Some(buffer_length))
                if end <= view.length() && view_end <= buffer_length => {}
            _ => {
                return Err(format!(
                    "{at} reaches beyond its buffer view {} or buffer {}",
                    view.index(),
                    view.buffer().index()
                ));
            }
        }
    }
    Ok(())
}

/// Where a `--scene` argument points: a glTF file by its extension, else None.
pub fn gltf_path(spec: &str) -> Option<PathBuf> {
    let path = PathBuf::from(spec);
    let extension = path.extension()?.to_str()?.to_ascii_lowercase();
    matches!(extension.as_str(), "gltf" | "glb").then_some(path)
}
