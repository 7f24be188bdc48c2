//! Exact ray casting against a mesh scene's triangles (f64, a median-split bounding volume
//! hierarchy): the true geometry the reference renderer traces for meshes.

use super::gpu_types::PeelTexture;
use super::mesh::{MeshScene, cross3, dot3, sub3};
use super::raster::sample_texture;

/// Triangles per leaf.
const LEAF_SIZE: usize = 4;

#[derive(Clone, Copy, Debug)]
struct Node {
    min: [f64; 3],
    max: [f64; 3],
    /// Leaf: first triangle in `order`; inner: index of the second child (the first follows).
    start: usize,
    /// Leaf: triangle count; inner: 0.
    count: usize,
}

/// A mesh scene ready for ray casting.
pub struct TracedMesh<'a> {
    scene: &'a MeshScene,
    nodes: Vec<Node>,
    order: Vec<usize>,
}

fn bounds(scene: &MeshScene, triangles: &[usize]) -> ([f64; 3], [f64; 3]) {
    let mut min = [f64::INFINITY; 3];
    let mut max = [f64::NEG_INFINITY; 3];
    for &t in triangles {
        for c in &scene.triangles[t].corners {
            for k in 0..3 {
                min[k] = min[k].min(c[k]);
                max[k] = max[k].max(c[k]);
            }
        }
    }
    (min, max)
}

fn centroid(scene: &MeshScene, t: usize, axis: usize) -> f64 {
    scene.triangles[t]
        .corners
        .iter()
        .map(|c| c[axis])
        .sum::<f64>()
}

impl<'a> TracedMesh<'a> {
    pub fn new(scene: &'a MeshScene) -> TracedMesh<'a> {
        let mut traced = TracedMesh {
            scene,
            nodes: Vec::new(),
            order: (0..scene.triangles.len()).collect(),
        };
        if !scene.triangles.is_empty() {
            traced.build(0, scene.triangles.len());
        }
        traced
    }

    fn build(&mut self, start: usize, end: usize) -> usize {
        let (min, max) = bounds(self.scene, &self.order[start..end]);
        let index = self.nodes.len();
        self.nodes.push(Node {
            min,
            max,
            start,
            count: end - start,
        });
        if end - start <= LEAF_SIZE {
            return index;
        }
        let axis = (0..3)
            .max_by(|&a, &b| (max[a] - min[a]).total_cmp(&(max[b] - min[b])))
            .unwrap_or(0);
        let middle = (start + end) / 2;
        let scene = self.scene;
        self.order[start..end].select_nth_unstable_by(middle - start, |&a, &b| {
            centroid(scene, a, axis).total_cmp(&centroid(scene, b, axis))
        });
        self.build(start, middle);
        let second = self.build(middle, end);
        self.nodes[index].start = second;
        self.nodes[index].count = 0;
        index
    }

    /// Parameter of the nearest hit of `origin + t direction` (t > 0) with triangle `t`, if any;
    /// single-sided triangles are hit only on their front (counter-clockwise) side.
    fn hit(
        &self,
        triangle: usize,
        origin: [f64; 3],
        direction: [f64; 3],
    ) -> Option<(f64, f64, f64)> {
        let tri = &self.scene.triangles[triangle];
        let [a, b, c] = tri.corners;
        let (e1, e2) = (sub3(b, a), sub3(c, a));
        let p = cross3(direction, e2);
        let det = dot3(e1, p);
        let double_sided = self.scene.materials[tri.material].double_sided;
        // det > 0: the ray meets the counter-clockwise (front) side.
        if det == 0.0 || !(det > 0.0 || double_sided) {
            return None;
        }
        let s = sub3(origin, a);
        let u = dot3(s, p) / det;
        if !(0.0..=1.0).contains(&u) {
            return None;
        }
        let q = cross3(s, e1);
        let v = dot3(direction, q) / det;
        if v < 0.0 || u + v > 1.0 {
            return None;
        }
        let t = dot3(e2, q) / det;
        (t > 0.0).then_some((t, u, v))
    }

    /// The nearest hit along the ray (t, triangle, barycentric u and v), if any.
    fn nearest(&self, origin: [f64; 3], direction: [f64; 3]) -> Option<(f64, usize, f64, f64)> {
        let inverse = direction.map(|d| 1.0 / d);
        let mut best: Option<(f64, usize, f64, f64)> = None;
        let mut stack = if self.nodes.is_empty() {
            vec![]
        } else {
            vec![0usize]
        };
        while let Some(n) = stack.pop() {
            let node = self.nodes[n];
            let limit = best.map_or(f64::INFINITY, |b| b.0);
            if !slab_hit(&node, origin, inverse, limit) {
                continue;
            }
            if node.count == 0 {
                stack.push(node.start);
                stack.push(n + 1);
                continue;
            }
            for &t in &self.order[node.start..node.start + node.count] {
                if let Some((d, u, v)) = self.hit(t, origin, direction)
                    && best.is_none_or(|b| d < b.0)
                {
                    best = Some((d, t, u, v));
                }
            }
        }
        best
    }

    /// The radiance seen along the ray from `origin` in direction `direction`: the nearest
    /// triangle it meets, shaded as the rasterisers shade it; black when it meets none.
    pub fn radiance_towards(&self, origin: [f64; 3], direction: [f64; 3]) -> [f32; 3] {
        let Some((_, t, u, v)) = self.nearest(origin, direction) else {
            return [0.0; 3];
        };
        let tri = &self.scene.triangles[t];
        let material = &self.scene.materials[tri.material];
        let uv = [0, 1].map(|k| {
            let (a, b, c) = (tri.uvs[0][k], tri.uvs[1][k], tri.uvs[2][k]);
            (a + u * (b - a) + v * (c - a)) as f32
        });
        let base = match material.base_texture {
            Some(texture) => {
                let image = &self.scene.images[texture.image];
                sample_texture(
                    &image.texels,
                    &PeelTexture::of(image, texture.sampler, 0),
                    uv,
                )
            }
            None => [1.0; 3],
        };
        [0, 1, 2].map(|k| material.base_colour[k] * base[k] + material.emissive[k])
    }
}

fn slab_hit(node: &Node, origin: [f64; 3], inverse: [f64; 3], limit: f64) -> bool {
    let (mut near, mut far) = (0.0f64, limit);
    for k in 0..3 {
        let t0 = (node.min[k] - origin[k]) * inverse[k];
        let t1 = (node.max[k] - origin[k]) * inverse[k];
        // NaN (a ray in the slab's plane) keeps the interval: max/min ignore it.
        near = near.max(t0.min(t1));
        far = far.min(t0.max(t1));
    }
    near <= far
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::scene::Scene;

    #[test]
    fn bvh_finds_what_brute_force_finds() {
        let scene = MeshScene::from_panels(&Scene::demo());
        let traced = TracedMesh::new(&scene);
        let mut hits = 0;
        for i in 0..2500 {
            let tan = [(i % 50) as f64 * 0.016 - 0.4, (i / 50) as f64 * 0.012 - 0.3];
            let origin = [3.0, -2.0, 20.0];
            let direction = [tan[0], tan[1], -1.0];
            let brute = (0..scene.triangles.len())
                .filter_map(|t| traced.hit(t, origin, direction).map(|h| (h.0, t)))
                .min_by(|a, b| a.0.total_cmp(&b.0));
            let found = traced.nearest(origin, direction).map(|h| (h.0, h.1));
            assert_eq!(found.map(|f| f.0), brute.map(|b| b.0), "ray {i}");
            hits += usize::from(found.is_some());
        }
        // The wall fills the view; the rest are posts, chart, bar and lights in front of it.
        assert_eq!(hits, 2500);
    }
}
