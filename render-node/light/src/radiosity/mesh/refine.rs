//! Element refinement: a quadtree leaf split in four by midpoint
//! subdivision, and the shared vertices rebuilt after a round of splits.

use super::{Element, MeshVertex, NONE, Node, RadiosityMesh, triangle_area};
use glam::DVec2;
use std::collections::HashMap;

/// Vertex positions are merged on a grid of this size (metres).
const VERTEX_WELD: f64 = 1e-7;

fn split(b: [DVec2; 3]) -> [[DVec2; 3]; 4] {
    let m01 = 0.5 * (b[0] + b[1]);
    let m12 = 0.5 * (b[1] + b[2]);
    let m20 = 0.5 * (b[2] + b[0]);
    [
        [b[0], m01, m20],
        [m01, b[1], m12],
        [m20, m12, b[2]],
        [m12, m20, m01],
    ]
}

impl RadiosityMesh {
    /// Split a leaf node into four children; returns the first child.
    pub(super) fn subdivide(&mut self, node: u32) -> u32 {
        let first = self.nodes.len() as u32;
        for b in split(self.nodes[node as usize].barycentric) {
            self.nodes.push(Node {
                barycentric: b,
                children: NONE,
                element: NONE,
            });
        }
        self.nodes[node as usize].children = first;
        self.nodes[node as usize].element = NONE;
        first
    }

    /// Split element `element` into four (its slot becomes the first child,
    /// three new elements are appended). Returns the indices of the four.
    /// Vertices are not rebuilt: call [`Self::rebuild_vertices`] after a
    /// round of splits.
    pub fn split_element(&mut self, element: u32) -> Option<[u32; 4]> {
        let e = self.elements.get(element as usize)?.clone();
        let first = self.subdivide(e.node);
        let prim = &self.primitives[e.primitive as usize];
        let mut out = [element; 4];
        for c in 0..4u32 {
            let node = first + c;
            let b = self.nodes[node as usize].barycentric;
            let vertices = b.map(|x| prim.point(x));
            let child = Element {
                barycentric: b,
                vertices,
                vertex_ids: [NONE; 3],
                center: (vertices[0] + vertices[1] + vertices[2]) / 3.0,
                area: triangle_area(&vertices),
                node,
                ..e.clone()
            };
            let index = if c == 0 {
                self.elements[element as usize] = child;
                element
            } else {
                self.elements.push(child);
                let i = self.elements.len() as u32 - 1;
                self.patches[e.patch as usize].elements.push(i);
                i
            };
            self.nodes[node as usize].element = index;
            out[c as usize] = index;
        }
        Some(out)
    }

    /// Recompute the shared vertices of all elements.
    pub fn rebuild_vertices(&mut self) {
        let mut map: HashMap<(u32, [i64; 3], [i64; 3]), u32> = HashMap::new();
        self.vertices.clear();
        for e in &mut self.elements {
            let nkey = (e.normal * 1e4).round().as_i64vec3().to_array();
            for (k, v) in e.vertices.iter().enumerate() {
                let pkey = (*v / VERTEX_WELD).round().as_i64vec3().to_array();
                let id = *map.entry((e.object, nkey, pkey)).or_insert_with(|| {
                    self.vertices.push(MeshVertex {
                        position: *v,
                        normal: e.normal,
                    });
                    self.vertices.len() as u32 - 1
                });
                e.vertex_ids[k] = id;
            }
        }
    }
}
