//! Layered depth images: per pixel, the surfaces a pinhole at the eye sees, nearest first.

use bytemuck::{Pod, Zeroable};

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

    /// Pixels in the view.
    pub fn pixels(&self) -> usize {
        self.width as usize * self.height as usize
    }
}

/// One surface sample: its distance from the eye along the axis and its linear RGB radiance.
/// Laid out as the kernel's vec4 (depth, r, g, b), so the GPU reads the image's own surfels.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct Surfel {
    pub depth_mm: f32,
    pub radiance: [f32; 3],
}

/// Layers ordered per pixel from near to far. Only the surfels that exist are stored: a
/// pixel's are consecutive, nearest first, so a pixel empty in layer i is empty in every later
/// layer (the depth-peeling invariant the tracer's early exit relies on). Storing every layer
/// of every pixel, empty or not, cost 20 bytes a slot; here a pixel costs 4 bytes and a
/// surfel 16.
#[derive(Clone, Debug, PartialEq)]
pub struct LayeredDepthImage {
    pub view: View,
    /// Pixel p's surfels are `surfels[starts[p]..starts[p + 1]]`.
    starts: Vec<u32>,
    surfels: Vec<Surfel>,
    /// Most surfels of any pixel, at least 1.
    layer_count: usize,
}

/// One layer of a [`LayeredDepthImage`]: at most one surfel per pixel, row-major.
#[derive(Clone, Copy, Debug)]
pub struct Layer<'a> {
    ldi: &'a LayeredDepthImage,
    index: usize,
}

impl Layer<'_> {
    /// The surfel of this layer at `pixel` (row-major), if any.
    pub fn get(&self, pixel: usize) -> Option<Surfel> {
        self.ldi.surfel(self.index, pixel)
    }

    /// Every pixel's surfel of this layer, row-major.
    pub fn samples(&self) -> impl ExactSizeIterator<Item = Option<Surfel>> + '_ {
        (0..self.ldi.view.pixels()).map(|pixel| self.get(pixel))
    }
}

/// Builds a [`LayeredDepthImage`] a pixel at a time, in row-major order, without holding a
/// list per pixel.
#[derive(Debug)]
pub struct LayerBuilder {
    ldi: LayeredDepthImage,
    max_layers: usize,
}

impl LayerBuilder {
    /// An image of `view` keeping at most `max_layers` surfels per pixel.
    pub fn new(view: View, max_layers: usize) -> LayerBuilder {
        let mut starts = Vec::with_capacity(view.pixels() + 1);
        starts.push(0);
        LayerBuilder {
            ldi: LayeredDepthImage {
                view,
                starts,
                surfels: Vec::new(),
                layer_count: 1,
            },
            max_layers: max_layers.max(1),
        }
    }

    /// Adds the next pixel's surfels, sorting them by depth and keeping the nearest
    /// `max_layers`.
    pub fn push_pixel(&mut self, surfels: &mut [Surfel]) {
        surfels.sort_by(|a, b| a.depth_mm.total_cmp(&b.depth_mm));
        self.push_sorted(&surfels[..surfels.len().min(self.max_layers)]);
    }

    /// Adds the next pixel's surfels, already nearest first and within the layer cap.
    fn push_sorted(&mut self, surfels: &[Surfel]) {
        let ldi = &mut self.ldi;
        debug_assert!(ldi.starts.len() <= ldi.view.pixels());
        ldi.surfels.extend_from_slice(surfels);
        // At most MAX_LAYER_PIXELS (2^28) surfels: u32 holds every start.
        ldi.starts.push(ldi.surfels.len() as u32);
        ldi.layer_count = ldi.layer_count.max(surfels.len());
    }

    /// The image; pixels never pushed are empty.
    pub fn finish(mut self) -> LayeredDepthImage {
        let end = self.ldi.surfels.len() as u32;
        self.ldi.starts.resize(self.ldi.view.pixels() + 1, end);
        self.ldi.surfels.shrink_to_fit();
        self.ldi
    }
}

impl LayeredDepthImage {
    /// Builds the layers from per-pixel surfel lists, sorting each by depth; at most
    /// `max_layers` are kept per pixel (the farthest are dropped).
    pub fn from_pixel_lists(view: View, mut lists: Vec<Vec<Surfel>>, max_layers: usize) -> Self {
        let mut builder = LayerBuilder::new(view, max_layers);
        for list in &mut lists {
            builder.push_pixel(list);
        }
        builder.finish()
    }

    /// Builds the image from whole layers (`layers[l][pixel]`), each pixel's surfels taken
    /// up to its first empty layer.
    pub fn from_layers(view: View, layers: &[Vec<Option<Surfel>>]) -> Self {
        let mut builder = LayerBuilder::new(view, layers.len());
        let mut pixel_surfels = Vec::with_capacity(layers.len());
        for pixel in 0..view.pixels() {
            pixel_surfels.clear();
            pixel_surfels.extend(layers.iter().map_while(|layer| layer[pixel]));
            builder.push_sorted(&pixel_surfels);
        }
        builder.finish()
    }

    /// Layers in the image: the most surfels any pixel has, at least 1.
    pub fn layer_count(&self) -> usize {
        self.layer_count
    }

    /// Layer `index` (below [`LayeredDepthImage::layer_count`]).
    pub fn layer(&self, index: usize) -> Layer<'_> {
        Layer { ldi: self, index }
    }

    /// Every layer, nearest first.
    pub fn layers(&self) -> impl ExactSizeIterator<Item = Layer<'_>> + '_ {
        (0..self.layer_count).map(|index| self.layer(index))
    }

    /// The surfels of `pixel` (row-major), nearest first.
    pub fn pixel_surfels(&self, pixel: usize) -> &[Surfel] {
        &self.surfels[self.starts[pixel] as usize..self.starts[pixel + 1] as usize]
    }

    /// The surfel of layer `layer` at `pixel`, if any.
    pub fn surfel(&self, layer: usize, pixel: usize) -> Option<Surfel> {
        self.pixel_surfels(pixel).get(layer).copied()
    }

    /// Surfels over all layers.
    pub fn surfel_count(&self) -> usize {
        self.surfels.len()
    }

    /// Where each pixel's surfels start in [`LayeredDepthImage::surfels`] (one entry per pixel
    /// and one past the last).
    pub fn starts(&self) -> &[u32] {
        &self.starts
    }

    /// Every surfel, pixel by pixel, nearest first within a pixel.
    pub fn surfels(&self) -> &[Surfel] {
        &self.surfels
    }

    /// The image with only its nearest `count` layers.
    pub fn nearest_layers(&self, count: usize) -> LayeredDepthImage {
        let mut builder = LayerBuilder::new(self.view, count);
        for pixel in 0..self.view.pixels() {
            let surfels = self.pixel_surfels(pixel);
            builder.push_sorted(&surfels[..surfels.len().min(count.max(1))]);
        }
        builder.finish()
    }

    /// Bytes the image holds: what the size policy counts for it.
    pub fn footprint_bytes(pixels: u64, surfels: u64) -> u64 {
        crate::limits::product(&[pixels + 1, 4])
            .saturating_add(crate::limits::product(&[surfels, SURFEL_BYTES]))
    }

    /// Nearest and farthest surfel depth over all layers, or None when every pixel is empty.
    pub fn depth_range(&self) -> Option<[f32; 2]> {
        let mut range: Option<[f32; 2]> = None;
        for s in &self.surfels {
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
        self.surfel(0, pixel).map(|s| s.depth_mm)
    }
}

/// Bytes of one stored surfel.
pub const SURFEL_BYTES: u64 = std::mem::size_of::<Surfel>() as u64;

#[cfg(test)]
mod tests {
    use super::*;

    fn surfel(depth_mm: f32) -> Surfel {
        Surfel {
            depth_mm,
            radiance: [depth_mm; 3],
        }
    }

    #[test]
    fn pixels_keep_their_nearest_surfels_in_order_and_empty_pixels_cost_no_surfel() {
        let view = View {
            eye_z: 0.0,
            tan_half: [1.0, 1.0],
            width: 3,
            height: 1,
        };
        let lists = vec![
            vec![surfel(3.0), surfel(1.0), surfel(2.0)],
            vec![],
            vec![surfel(5.0)],
        ];
        let ldi = LayeredDepthImage::from_pixel_lists(view, lists, 2);
        assert_eq!(ldi.layer_count(), 2);
        assert_eq!(ldi.surfel_count(), 3);
        assert_eq!(ldi.starts(), [0, 2, 2, 3]);
        let layer0: Vec<_> = ldi
            .layer(0)
            .samples()
            .map(|s| s.map(|s| s.depth_mm))
            .collect();
        let layer1: Vec<_> = ldi
            .layer(1)
            .samples()
            .map(|s| s.map(|s| s.depth_mm))
            .collect();
        assert_eq!(layer0, [Some(1.0), None, Some(5.0)]);
        assert_eq!(layer1, [Some(2.0), None, None]);
        let dense: Vec<Vec<Option<Surfel>>> = ldi.layers().map(|l| l.samples().collect()).collect();
        assert_eq!(LayeredDepthImage::from_layers(view, &dense), ldi);
        assert_eq!(ldi.nearest_layers(1).surfel_count(), 2);
        assert_eq!(ldi.depth_range(), Some([1.0, 5.0]));
    }
}
