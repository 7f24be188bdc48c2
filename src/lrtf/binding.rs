//! What an engine binds for the exported sampler (`lensbake export shader`, docs/engines.md):
//! every layer of a table packed the way `lrtf_sample.wgsl` addresses layers, plus its uniform
//! block, as plain arrays ready to upload.

use super::param::Parameterisation;
use super::table::{GpuParams, Layer, LrtfTable};

/// The sampler's bindings for one table, one stop radius and one render film plane.
///
/// Texture texels run x (first coordinate) fastest, then y, then z; layer k's nodes follow
/// layer k - 1's along z, so the textures are `dims[0] x dims[1] x (dims[2] * layers)`.
/// `pupil` holds each layer's coordinate circles as blocks of `params.pupil_count` (block k
/// for layer k), then layer 0's sampling pupil from block [`EngineBinding::sampling_block`].
#[derive(Clone, Debug, PartialEq)]
pub struct EngineBinding {
    /// The uniform block `LrtfParams` (64 bytes, std140), layer 0's frame.
    pub params: GpuParams,
    /// Binding 0: (exit.x, exit.y, dir.a, dir.b) per node.
    pub transfer: Vec<[f32; 4]>,
    /// Binding 1: (margin, stop.x, stop.y, exit.z) per node.
    pub aux: Vec<[f32; 4]>,
    /// Binding 2: (centre_x, radius) circles.
    pub pupil: Vec<[f32; 2]>,
    /// Width, height and depth of both textures.
    pub texture_size: [u32; 3],
    /// The block of `pupil` where the sampling pupil starts: the layer count.
    pub sampling_block: u32,
}

/// Why a table's layers cannot share one binding.
#[derive(Debug, thiserror::Error)]
pub enum BindingError {
    #[error(
        "layer {layer} ({wavelength_nm} nm) differs from layer 0 in {what}; the sampler reads one {what} for every layer"
    )]
    LayersDiffer {
        layer: usize,
        wavelength_nm: f64,
        what: &'static str,
    },
}

impl Layer {
    /// Appends this layer's entries to the sampler's two RGBA textures, in the file's
    /// row-major node order.
    pub fn append_texels(&self, transfer: &mut Vec<[f32; 4]>, aux: &mut Vec<[f32; 4]>) {
        transfer.reserve(self.entries.len());
        aux.reserve(self.entries.len());
        for e in self.entries.row_major() {
            transfer.push([e[0], e[1], e[2], e[3]]);
            aux.push([e[4], e[5], e[6], e[7]]);
        }
    }
}

impl LrtfTable {
    /// Every layer of the table bound for the sampler at `stop_radius` (see
    /// [`LrtfTable::stop_radius`]) and lens samples drawn for the film plane `film_z`.
    ///
    /// The layers must share the film plane, rear plane, film radius and pupil circle count
    /// (for the spherical parameterisation, the whole frame), as one bake with several
    /// wavelengths gives.
    ///
    /// ```
    /// # use lensbake::lrtf::bake::{bake, BakeRequest};
    /// # let lens = lensbake::load_lens("cooke-triplet", &Default::default()).unwrap();
    /// # let request = BakeRequest { resolution: [8, 8, 8], ..BakeRequest::default() };
    /// # let table = bake(&lens.system, &request).unwrap();
    /// let stop = table.stop_radius(0, table.info.f_number).unwrap();
    /// let binding = table.engine_binding(stop, table.layers[0].frame.film_plane_z).unwrap();
    /// assert_eq!(binding.texture_size, [8, 8, 8]);
    /// assert_eq!(binding.transfer.len(), 8 * 8 * 8);
    /// assert_eq!(binding.params.format_version, lensbake::lrtf::io::FORMAT_VERSION);
    /// ```
    pub fn engine_binding(
        &self,
        stop_radius: f64,
        film_z: f64,
    ) -> Result<EngineBinding, BindingError> {
        let first = &self.layers[0];
        let spherical = self.info.parameterisation == Parameterisation::Spherical;
        for (k, layer) in self.layers.iter().enumerate().skip(1) {
            let (a, b) = (&first.frame, &layer.frame);
            let differs = if a.rear_plane_z != b.rear_plane_z || a.film_plane_z != b.film_plane_z {
                Some("film and rear planes")
            } else if a.max_film_radius != b.max_film_radius {
                Some("film radius")
            } else if spherical && a != b {
                Some("spherical frame")
            } else if layer.pupil.circles.len() != first.pupil.circles.len() {
                Some("pupil circle count")
            } else {
                None
            };
            if let Some(what) = differs {
                return Err(BindingError::LayersDiffer {
                    layer: k,
                    wavelength_nm: layer.wavelength_nm,
                    what,
                });
            }
        }
        let params = self.gpu_params(0, stop_radius, film_z);
        let (mut transfer, mut aux) = (Vec::new(), Vec::new());
        let mut pupil = Vec::new();
        for layer in &self.layers {
            layer.append_texels(&mut transfer, &mut aux);
            pupil.extend(
                layer
                    .pupil
                    .circles
                    .iter()
                    .map(|c| [c.centre_x as f32, c.radius as f32]),
            );
        }
        pupil.extend(
            self.gpu_pupil(0)
                .into_iter()
                .skip(first.pupil.circles.len()),
        );
        let [n0, n1, n2] = params.dims;
        Ok(EngineBinding {
            params,
            transfer,
            aux,
            pupil,
            texture_size: [n0, n1, n2 * self.layers.len() as u32],
            sampling_block: self.layers.len() as u32,
        })
    }
}
