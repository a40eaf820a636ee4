//! The two-level radiosity mesh: every scene triangle (a *primitive*) is
//! split by midpoint subdivision into *patches* no larger than a maximum
//! area (the shooters), and each patch into *elements* (the receivers),
//! which are refined further where the radiosity changes fast.
//!
//! Each primitive owns a quadtree in its barycentric coordinates, so a ray
//! hit `(primitive, barycentric)` finds its element by descending the tree,
//! and patches and elements keep the winding (front side) of their
//! primitive. Vertices are shared between elements of one object with the
//! same plane orientation, for per-vertex (Gouraud) interpolation.

use glam::{DAffine3, DVec2, DVec3};
use std::collections::HashMap;

mod build;
mod refine;

/// Sentinel for "no element / no child".
const NONE: u32 = u32::MAX;
/// Largest albedo used, so that energy always decays.
pub const MAX_REFLECTANCE: f64 = 0.999;

/// Why a radiosity mesh could not be built.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum MeshError {
    /// The maximum patch area is not a positive finite number.
    #[error("maximum patch area {0} must be positive and finite")]
    BadPatchArea(f64),
    /// The element subdivision depth is too large (at most 6).
    #[error("element depth {0} is above the maximum of 6")]
    BadElementDepth(u32),
    /// The mesh would have more elements than the limit.
    #[error("the mesh would have {count} elements, above the limit {limit}")]
    TooManyElements {
        /// Elements requested.
        count: usize,
        /// The limit.
        limit: usize,
    },
    /// A move of an object is not a rotation and translation (a scale or
    /// shear would change the elements' areas, so the mesh must be built
    /// again).
    #[error("moving object {object}: the transform is not rigid (rotation and translation only)")]
    NotRigid {
        /// The object.
        object: u32,
    },
    /// The object to move has no elements in the mesh.
    #[error("moving object {object}: the mesh has no element of it")]
    NoSuchObject {
        /// The object.
        object: u32,
    },
}

/// How a scene is meshed.
#[derive(Clone, Debug, PartialEq)]
pub struct MeshOptions {
    /// Patches are split until their area is at most this (m^2).
    pub max_patch_area: f64,
    /// Each patch starts as `4^element_depth` elements.
    pub element_depth: u32,
    /// Fewer elements where they would be smaller than this (m^2): a
    /// patch is split only as deep as keeps its elements at least this
    /// large, so a scanned mesh's small triangles stay one element each.
    /// 0 splits every patch `element_depth` times.
    pub min_element_area: f64,
    /// Hard limit on the number of elements (a guard against runaway input).
    pub max_elements: usize,
}

impl Default for MeshOptions {
    fn default() -> Self {
        Self {
            max_patch_area: 0.01,
            element_depth: 1,
            min_element_area: 0.0,
            max_elements: 2_000_000,
        }
    }
}

/// One scene triangle.
#[derive(Clone, Debug, PartialEq)]
pub struct Primitive {
    /// Index into `Showcase::objects`.
    pub object: u32,
    /// Triangle index within the object's mesh.
    pub triangle: u32,
    /// World-space vertices, counter-clockwise seen from the front.
    pub vertices: [DVec3; 3],
    /// Unit front normal.
    pub normal: DVec3,
    root: u32,
}

/// A shooter: a node of a primitive's quadtree at patch level.
#[derive(Clone, Debug, PartialEq)]
pub struct Patch {
    /// Its primitive.
    pub primitive: u32,
    /// Its object.
    pub object: u32,
    /// World-space corners (counter-clockwise from the front).
    pub vertices: [DVec3; 3],
    /// Centroid.
    pub center: DVec3,
    /// Unit front normal.
    pub normal: DVec3,
    /// Area (m^2).
    pub area: f64,
    /// The elements of this patch.
    pub elements: Vec<u32>,
}

/// A receiver: a leaf of a primitive's quadtree.
#[derive(Clone, Debug, PartialEq)]
pub struct Element {
    /// Its primitive.
    pub primitive: u32,
    /// Its object.
    pub object: u32,
    /// The patch it belongs to.
    pub patch: u32,
    /// Corners in the primitive's barycentric coordinates `(u, v)`.
    pub barycentric: [DVec2; 3],
    /// World-space corners.
    pub vertices: [DVec3; 3],
    /// Indices of the corners into [`RadiosityMesh::vertices`].
    pub vertex_ids: [u32; 3],
    /// Centroid.
    pub center: DVec3,
    /// Unit front normal.
    pub normal: DVec3,
    /// Area (m^2).
    pub area: f64,
    /// Diffuse reflectance rho per channel, in `[0, MAX_REFLECTANCE]`.
    pub reflectance: DVec3,
    /// Emitted exitance (W/m^2): `pi * Ke`.
    pub emission: DVec3,
    /// True for a real (physical) object's surface.
    pub real: bool,
    node: u32,
}

#[derive(Clone, Debug, PartialEq)]
struct Node {
    barycentric: [DVec2; 3],
    /// First of four consecutive children, or `NONE` for a leaf.
    children: u32,
    /// The element of a leaf, or `NONE`.
    element: u32,
}

/// A shared mesh vertex for interpolated rendering.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MeshVertex {
    /// World position.
    pub position: DVec3,
    /// Unit normal (of the plane the vertex is shared in).
    pub normal: DVec3,
}

/// The patch/element hierarchy of a scene.
#[derive(Clone, Debug, PartialEq)]
pub struct RadiosityMesh {
    /// Scene triangles (non-degenerate ones).
    pub primitives: Vec<Primitive>,
    /// Shooters.
    pub patches: Vec<Patch>,
    /// Receivers.
    pub elements: Vec<Element>,
    /// Shared corners of the elements.
    pub vertices: Vec<MeshVertex>,
    nodes: Vec<Node>,
    /// `(object, triangle)` to primitive.
    lookup: HashMap<(u32, u32), u32>,
}

impl Primitive {
    /// World point at barycentric `(u, v)` (weights of the second and third
    /// vertex).
    pub fn point(&self, b: DVec2) -> DVec3 {
        barycentric_point(&self.vertices, b)
    }

    /// Area of the primitive (m^2).
    pub fn area(&self) -> f64 {
        triangle_area(&self.vertices)
    }
}

/// Area of a triangle.
pub fn triangle_area(v: &[DVec3; 3]) -> f64 {
    0.5 * (v[1] - v[0]).cross(v[2] - v[0]).length()
}

impl RadiosityMesh {
    /// The primitive of scene triangle `triangle` of object `object`.
    pub fn primitive_of(&self, object: u32, triangle: u32) -> Option<u32> {
        self.lookup.get(&(object, triangle)).copied()
    }

    /// Every leaf of `primitive`'s quadtree, in depth-first order: its
    /// corners in the primitive's barycentric coordinates (the corner
    /// order [`Self::interpolate`] weights the element's `vertex_ids` in)
    /// and its element, if it has one. The leaves tile the primitive.
    pub fn for_each_leaf(&self, primitive: u32, mut f: impl FnMut([DVec2; 3], Option<u32>)) {
        let Some(p) = self.primitives.get(primitive as usize) else {
            return;
        };
        let mut stack = vec![p.root];
        while let Some(node) = stack.pop() {
            let Some(n) = self.nodes.get(node as usize) else {
                continue;
            };
            if n.children == NONE {
                f(n.barycentric, (n.element != NONE).then_some(n.element));
            } else {
                stack.extend((0..4).rev().map(|k| n.children + k));
            }
        }
    }

    /// The element containing barycentric point `b` of `primitive`, and the
    /// point's barycentric weights `(w0, w1, w2)` within that element.
    pub fn locate(&self, primitive: u32, b: DVec2) -> Option<(u32, DVec3)> {
        let mut node = self.primitives.get(primitive as usize)?.root;
        loop {
            let n = &self.nodes[node as usize];
            let w = local_weights(n.barycentric, b);
            if n.children == NONE {
                return (n.element != NONE).then_some((n.element, w));
            }
            node = n.children
                + if w.x >= 0.5 {
                    0
                } else if w.y >= 0.5 {
                    1
                } else if w.z >= 0.5 {
                    2
                } else {
                    3
                };
        }
    }

    /// Per-vertex values from per-element values: the area-weighted mean of
    /// the elements sharing each vertex.
    pub fn vertex_values(&self, element_values: &[DVec3]) -> Vec<DVec3> {
        let mut sum = vec![DVec3::ZERO; self.vertices.len()];
        let mut weight = vec![0.0; self.vertices.len()];
        for (e, value) in self.elements.iter().zip(element_values) {
            for &v in &e.vertex_ids {
                if let (Some(s), Some(w)) = (sum.get_mut(v as usize), weight.get_mut(v as usize)) {
                    *s += *value * e.area;
                    *w += e.area;
                }
            }
        }
        sum.iter()
            .zip(&weight)
            .map(|(s, &w)| if w > 0.0 { *s / w } else { DVec3::ZERO })
            .collect()
    }

    /// The interpolated value at barycentric point `b` of `primitive`
    /// (Gouraud over the element's corners), from [`Self::vertex_values`].
    pub fn interpolate(&self, primitive: u32, b: DVec2, vertex_values: &[DVec3]) -> Option<DVec3> {
        let (e, w) = self.locate(primitive, b)?;
        let ids = self.elements[e as usize].vertex_ids;
        let w = w.clamp(DVec3::ZERO, DVec3::ONE);
        let w = w / (w.x + w.y + w.z).max(1e-300);
        let mut out = DVec3::ZERO;
        for (k, id) in ids.iter().enumerate() {
            out += w[k] * *vertex_values.get(*id as usize)?;
        }
        Some(out)
    }

    /// Total area of the elements (m^2).
    pub fn total_area(&self) -> f64 {
        self.elements.iter().map(|e| e.area).sum()
    }

    /// This mesh with `object` moved rigidly by `motion` (applied to its
    /// current place): its primitives, patches, elements and vertices
    /// moved, everything else and every index unchanged. The same mesh as
    /// one built from the moved scene, without meshing it again (vertices
    /// are shared within an object only, so no other object's corner
    /// moves).
    pub fn with_object_moved(&self, object: u32, motion: &DAffine3) -> Result<Self, MeshError> {
        let mut out = self.clone();
        out.move_object(object, motion)?;
        Ok(out)
    }

    /// [`Self::with_object_moved`] in place; on an error nothing moved.
    pub fn move_object(&mut self, object: u32, motion: &DAffine3) -> Result<(), MeshError> {
        let m = motion.matrix3;
        // Within single precision: scene rotations are f32 quaternions.
        let rigid = (m.transpose() * m - glam::DMat3::IDENTITY)
            .to_cols_array()
            .iter()
            .all(|v| v.abs() < 1e-6)
            && (m.determinant() - 1.0).abs() < 1e-6
            && motion.translation.is_finite();
        if !rigid {
            return Err(MeshError::NotRigid { object });
        }
        if !self.elements.iter().any(|e| e.object == object) {
            return Err(MeshError::NoSuchObject { object });
        }
        let point = |p: DVec3| motion.transform_point3(p);
        let normal = |n: DVec3| m * n;
        let out = self;
        for p in out.primitives.iter_mut().filter(|p| p.object == object) {
            p.vertices = p.vertices.map(point);
            p.normal = normal(p.normal);
        }
        for p in out.patches.iter_mut().filter(|p| p.object == object) {
            p.vertices = p.vertices.map(point);
            p.center = point(p.center);
            p.normal = normal(p.normal);
        }
        let mut moved = vec![false; out.vertices.len()];
        for e in out.elements.iter_mut().filter(|e| e.object == object) {
            e.vertices = e.vertices.map(point);
            e.center = point(e.center);
            e.normal = normal(e.normal);
            for &v in &e.vertex_ids {
                moved[v as usize] = true;
            }
        }
        for (v, _) in out.vertices.iter_mut().zip(&moved).filter(|(_, m)| **m) {
            v.position = point(v.position);
            v.normal = normal(v.normal);
        }
        Ok(())
    }
}

/// Barycentric `(u, v)` centroids of the `n^2` equal sub-triangles of a
/// regular `n`-fold split of a triangle.
pub fn sub_centroids(n: u32) -> Vec<DVec2> {
    let n = n.max(1);
    let mut out = Vec::with_capacity((n * n) as usize);
    for i in 0..n {
        for j in 0..n - i {
            out.push(DVec2::new(i as f64 + 1.0 / 3.0, j as f64 + 1.0 / 3.0) / n as f64);
            if i + j + 1 < n {
                out.push(DVec2::new(i as f64 + 2.0 / 3.0, j as f64 + 2.0 / 3.0) / n as f64);
            }
        }
    }
    out
}

/// The point of triangle `v` at barycentric `(u, v)`.
pub fn barycentric_point(v: &[DVec3; 3], b: DVec2) -> DVec3 {
    (1.0 - b.x - b.y) * v[0] + b.x * v[1] + b.y * v[2]
}

/// Barycentric weights of uv point `b` in the uv triangle `t`.
fn local_weights(t: [DVec2; 3], b: DVec2) -> DVec3 {
    let (e1, e2, d) = (t[1] - t[0], t[2] - t[0], b - t[0]);
    let det = e1.perp_dot(e2);
    if det == 0.0 {
        return DVec3::new(1.0, 0.0, 0.0);
    }
    let w1 = d.perp_dot(e2) / det;
    let w2 = e1.perp_dot(d) / det;
    DVec3::new(1.0 - w1 - w2, w1, w2)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{ObjectFilter, SceneGeometry};
    use glam::Vec3;
    use showcase_proto::{Material, Mesh, Object, ObjectKind, Showcase, Transform};

    pub(crate) fn quad_scene(size: f32) -> Showcase {
        let mut s = Showcase::default();
        let id = s.add_mesh(Mesh {
            positions: vec![
                Vec3::ZERO,
                Vec3::new(size, 0.0, 0.0),
                Vec3::new(size, size, 0.0),
                Vec3::new(0.0, size, 0.0),
            ],
            normals: vec![],
            uvs: vec![],
            triangles: vec![[0, 1, 2], [0, 2, 3]],
        });
        s.objects.push(Object {
            name: "quad".into(),
            mesh: id,
            material: Material::diffuse(Vec3::splat(0.5)),
            kind: ObjectKind::Real,
            transform: Transform::IDENTITY,
        });
        s
    }

    #[test]
    fn patches_respect_the_maximum_area_and_tile_the_surface() {
        let s = quad_scene(1.0);
        let g = SceneGeometry::build(&s, &ObjectFilter::All).unwrap();
        for max in [1.0, 0.1, 0.01] {
            let m = RadiosityMesh::build(
                &s,
                &g,
                &MeshOptions {
                    max_patch_area: max,
                    element_depth: 1,
                    ..MeshOptions::default()
                },
            )
            .unwrap();
            assert!(m.patches.iter().all(|p| p.area <= max * (1.0 + 1e-12)));
            let pa: f64 = m.patches.iter().map(|p| p.area).sum();
            assert!((pa - 1.0).abs() < 1e-12 && (m.total_area() - 1.0).abs() < 1e-12);
            assert_eq!(m.elements.len(), 4 * m.patches.len());
            // A regular grid of 2 * 4^d triangles has (2^d + 1)^2 vertices.
            let side = (m.elements.len() as f64 / 2.0).sqrt() as usize;
            assert_eq!(m.vertices.len(), (side + 1) * (side + 1));
        }
        assert!(matches!(
            RadiosityMesh::build(
                &s,
                &g,
                &MeshOptions {
                    max_patch_area: 0.0,
                    ..MeshOptions::default()
                }
            ),
            Err(MeshError::BadPatchArea(_))
        ));
        assert!(matches!(
            RadiosityMesh::build(
                &s,
                &g,
                &MeshOptions {
                    max_patch_area: 1e-9,
                    ..MeshOptions::default()
                }
            ),
            Err(MeshError::TooManyElements { .. })
        ));
    }

    #[test]
    fn elements_stop_splitting_at_the_minimum_area() {
        // A 1 m^2 quad: two triangles of 0.5 m^2, patches of at most 0.2
        // (4 per triangle, 0.125 m^2), element depth 2 (16 per patch at
        // 0.0078 m^2) unless that is below the minimum.
        let s = quad_scene(1.0);
        let g = SceneGeometry::build(&s, &ObjectFilter::All).unwrap();
        let elements = |min_element_area| {
            RadiosityMesh::build(
                &s,
                &g,
                &MeshOptions {
                    max_patch_area: 0.2,
                    element_depth: 2,
                    min_element_area,
                    ..MeshOptions::default()
                },
            )
            .unwrap()
            .elements
        };
        assert_eq!(elements(0.0).len(), 2 * 4 * 16);
        // 0.0078 is too small, 0.031 is not: one split per patch.
        let e = elements(0.01);
        assert_eq!(e.len(), 2 * 4 * 4);
        assert!(e.iter().all(|e| (e.area - 0.125 / 4.0).abs() < 1e-12));
        // Patches themselves are never merged: one element each.
        assert_eq!(elements(1.0).len(), 2 * 4);
    }

    #[test]
    fn locate_finds_the_element_containing_a_point() {
        let s = quad_scene(1.0);
        let g = SceneGeometry::build(&s, &ObjectFilter::All).unwrap();
        let mut m = RadiosityMesh::build(&s, &g, &MeshOptions::default()).unwrap();
        m.split_element(3).unwrap();
        m.rebuild_vertices();
        for (i, e) in m.elements.iter().enumerate() {
            let c = (e.barycentric[0] + e.barycentric[1] + e.barycentric[2]) / 3.0;
            let (found, w) = m.locate(e.primitive, c).unwrap();
            assert_eq!(found as usize, i);
            assert!((w - DVec3::splat(1.0 / 3.0)).abs().max_element() < 1e-12);
        }
        // Interpolating a linear field at vertices reproduces it exactly.
        let f = |p: DVec3| DVec3::new(p.x + 2.0 * p.y, 1.0, p.y);
        let values: Vec<DVec3> = m.vertices.iter().map(|v| f(v.position)).collect();
        let prim = &m.primitives[1];
        let b = DVec2::new(0.21, 0.33);
        let got = m.interpolate(1, b, &values).unwrap();
        assert!((got - f(prim.point(b))).abs().max_element() < 1e-12);
    }
}
