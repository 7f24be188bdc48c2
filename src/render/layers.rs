//! Layered depth images: per pixel, the surfaces a pinhole at the eye sees, nearest first.

/// The pinhole view layers are taken from: the eye on the axis at lens-frame z `eye_z`, looking
/// towards -z, the image covering tangents [-tan_half_x, tan_half_x] x [-tan_half_y, tan_half_y].
/// Row 0 is the top (+y), column 0 the left (-x).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct View {
    pub eye_z: f64,
    pub tan_half: [f64; 2],
    pub width: u32,
    pub height: u32,
}

impl View {
    /// Tangents (x/depth, y/depth) of the centre of pixel (column, row).
    pub fn pixel_tangents(&self, column: u32, row: u32) -> [f64; 2] {
        [
            self.tan_half[0] * (2.0 * (column as f64 + 0.5) / self.width as f64 - 1.0),
            self.tan_half[1] * (1.0 - 2.0 * (row as f64 + 0.5) / self.height as f64),
        ]
    }
}

/// One surface sample: its distance from the eye along the axis and its linear RGB radiance.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Surfel {
    pub depth_mm: f32,
    pub radiance: [f32; 3],
}

/// One peeled layer: at most one surfel per pixel, row-major.
#[derive(Clone, Debug, PartialEq)]
pub struct Layer {
    pub samples: Vec<Option<Surfel>>,
}

/// Layers ordered per pixel from near to far; a pixel empty in layer i is empty in every later
/// layer (the depth-peeling invariant the tracer's early exit relies on).
#[derive(Clone, Debug, PartialEq)]
pub struct LayeredDepthImage {
    pub view: View,
    pub layers: Vec<Layer>,
}

impl LayeredDepthImage {
    /// Builds the layers from per-pixel surfel lists, sorting each by depth; at most
    /// `max_layers` are kept per pixel (the farthest are dropped).
    pub fn from_pixel_lists(view: View, mut lists: Vec<Vec<Surfel>>, max_layers: usize) -> Self {
        let count = lists
            .iter()
            .map(Vec::len)
            .max()
            .unwrap_or(0)
            .clamp(1, max_layers.max(1));
        let pixels = (view.width * view.height) as usize;
        let mut layers = vec![
            Layer {
                samples: vec![None; pixels]
            };
            count
        ];
        for (pixel, list) in lists.iter_mut().enumerate() {
            list.sort_by(|a, b| a.depth_mm.total_cmp(&b.depth_mm));
            for (layer, surfel) in layers.iter_mut().zip(list.iter()) {
                layer.samples[pixel] = Some(*surfel);
            }
        }
        LayeredDepthImage { view, layers }
    }

    /// Nearest and farthest surfel depth over all layers, or None when every pixel is empty.
    pub fn depth_range(&self) -> Option<[f32; 2]> {
        let mut range: Option<[f32; 2]> = None;
        for s in self.layers.iter().flat_map(|l| l.samples.iter().flatten()) {
            let r = range.get_or_insert([s.depth_mm, s.depth_mm]);
            r[0] = r[0].min(s.depth_mm);
            r[1] = r[1].max(s.depth_mm);
        }
        range
    }

    /// Depth of the nearest surface under pixel (column, row), if any.
    pub fn nearest_depth(&self, column: u32, row: u32) -> Option<f32> {
        if column >= self.view.width || row >= self.view.height {
            return None;
        }
        let pixel = (row * self.view.width + column) as usize;
        self.layers.first()?.samples[pixel].map(|s| s.depth_mm)
    }
}
