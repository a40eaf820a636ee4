//! Meshing a scene: each primitive's quadtree grown to patch depth (the
//! shooters), then to element depth (the receivers), with the material
//! sampled at each element.

use super::{
    Element, MAX_REFLECTANCE, MeshError, MeshOptions, NONE, Node, Patch, Primitive, RadiosityMesh,
    triangle_area,
};
use crate::SceneGeometry;
use crate::finite::finite_or_zero;
use glam::{DVec2, DVec3};
use showcase_proto::{ObjectKind, Showcase};
use std::collections::HashMap;

fn sanitize(v: DVec3, max: f64) -> DVec3 {
    let v = DVec3::from_array(v.to_array().map(finite_or_zero));
    v.clamp(DVec3::ZERO, DVec3::splat(max))
}

impl RadiosityMesh {
    /// Mesh the objects of `geometry` (built from `showcase`) with their
    /// materials: albedo (sampled at the element centre where textured) as
    /// rho, and `pi * emission` as emitted exitance.
    pub fn build(
        showcase: &Showcase,
        geometry: &SceneGeometry,
        options: &MeshOptions,
    ) -> Result<Self, MeshError> {
        if !(options.max_patch_area > 0.0 && options.max_patch_area.is_finite()) {
            return Err(MeshError::BadPatchArea(options.max_patch_area));
        }
        if options.element_depth > 6 {
            return Err(MeshError::BadElementDepth(options.element_depth));
        }
        let mut mesh = Self {
            primitives: Vec::new(),
            patches: Vec::new(),
            elements: Vec::new(),
            vertices: Vec::new(),
            nodes: Vec::new(),
            lookup: HashMap::new(),
        };
        // Count first, so a huge request fails before allocating.
        let mut count = 0usize;
        for t in geometry.triangles().filter(|t| t.area > 0.0) {
            let depth = patch_depth(t.area, options.max_patch_area);
            let elements = element_depth(t.area, depth, options);
            count = count.saturating_add(4usize.saturating_pow(depth + elements));
        }
        if count > options.max_elements {
            return Err(MeshError::TooManyElements {
                count,
                limit: options.max_elements,
            });
        }
        for t in geometry.triangles().filter(|t| t.area > 0.0) {
            let pi = mesh.primitives.len() as u32;
            let root = mesh.nodes.len() as u32;
            mesh.nodes.push(Node {
                barycentric: [DVec2::ZERO, DVec2::X, DVec2::Y],
                children: NONE,
                element: NONE,
            });
            mesh.primitives.push(Primitive {
                object: t.object,
                triangle: t.triangle,
                vertices: t.vertices,
                normal: t.normal,
                root,
            });
            mesh.lookup.insert((t.object, t.triangle), pi);
            let depth = patch_depth(t.area, options.max_patch_area);
            let elements = element_depth(t.area, depth, options);
            mesh.grow_patches(showcase, pi, root, depth, elements);
        }
        mesh.rebuild_vertices();
        Ok(mesh)
    }

    fn grow_patches(
        &mut self,
        showcase: &Showcase,
        primitive: u32,
        node: u32,
        depth: u32,
        element_depth: u32,
    ) {
        if depth > 0 {
            let first = self.subdivide(node);
            for c in 0..4 {
                self.grow_patches(showcase, primitive, first + c, depth - 1, element_depth);
            }
            return;
        }
        let prim = &self.primitives[primitive as usize];
        let b = self.nodes[node as usize].barycentric;
        let vertices = b.map(|x| prim.point(x));
        let pi = self.patches.len() as u32;
        self.patches.push(Patch {
            primitive,
            object: prim.object,
            vertices,
            center: (vertices[0] + vertices[1] + vertices[2]) / 3.0,
            normal: prim.normal,
            area: triangle_area(&vertices),
            elements: Vec::new(),
        });
        self.grow_elements(showcase, pi, node, element_depth);
    }

    fn grow_elements(&mut self, showcase: &Showcase, patch: u32, node: u32, depth: u32) {
        if depth > 0 {
            let first = self.subdivide(node);
            for c in 0..4 {
                self.grow_elements(showcase, patch, first + c, depth - 1);
            }
            return;
        }
        let p = &self.patches[patch as usize];
        let prim = &self.primitives[p.primitive as usize];
        let b = self.nodes[node as usize].barycentric;
        let (reflectance, emission, real) = material(showcase, prim, (b[0] + b[1] + b[2]) / 3.0);
        let e = self.make_element(patch, node, reflectance, emission, real);
        self.patches[patch as usize].elements.push(e);
    }

    fn make_element(
        &mut self,
        patch: u32,
        node: u32,
        reflectance: DVec3,
        emission: DVec3,
        real: bool,
    ) -> u32 {
        let p = &self.patches[patch as usize];
        let prim = &self.primitives[p.primitive as usize];
        let b = self.nodes[node as usize].barycentric;
        let vertices = b.map(|x| prim.point(x));
        let ei = self.elements.len() as u32;
        self.elements.push(Element {
            primitive: p.primitive,
            object: p.object,
            patch,
            barycentric: b,
            vertices,
            vertex_ids: [NONE; 3],
            center: (vertices[0] + vertices[1] + vertices[2]) / 3.0,
            normal: prim.normal,
            area: triangle_area(&vertices),
            reflectance,
            emission,
            real,
            node,
        });
        self.nodes[node as usize].element = ei;
        ei
    }
}

/// Patch subdivision depth: each level quarters the area.
/// The element depth of a primitive of `area` split `patch_depth` times
/// into patches: `options.element_depth`, less where elements would fall
/// below `options.min_element_area`.
fn element_depth(area: f64, patch_depth: u32, options: &MeshOptions) -> u32 {
    let patch = area * 0.25f64.powi(patch_depth as i32);
    let mut depth = options.element_depth;
    while depth > 0 && patch * 0.25f64.powi(depth as i32) < options.min_element_area {
        depth -= 1;
    }
    depth
}

fn patch_depth(area: f64, max_area: f64) -> u32 {
    let mut depth = 0;
    let mut a = area;
    while a > max_area && depth < 12 {
        a *= 0.25;
        depth += 1;
    }
    depth
}

/// Reflectance, emitted exitance and realness of a primitive's material at
/// barycentric point `b`.
fn material(showcase: &Showcase, prim: &Primitive, b: DVec2) -> (DVec3, DVec3, bool) {
    let Some(object) = showcase.objects.get(prim.object as usize) else {
        return (DVec3::ZERO, DVec3::ZERO, false);
    };
    let m = &object.material;
    let mut albedo = m.albedo.as_dvec3();
    if m.texture.is_some() {
        let uv = showcase.mesh(&object.mesh).and_then(|mesh| {
            let tri = mesh.triangles.get(prim.triangle as usize)?;
            let uvs = tri.map(|i| mesh.uvs.get(i as usize).copied());
            let [Some(a), Some(b1), Some(c)] = uvs else {
                return None;
            };
            Some((1.0 - b.x - b.y) * a.as_dvec2() + b.x * b1.as_dvec2() + b.y * c.as_dvec2())
        });
        if let Some(uv) = uv {
            albedo = m.albedo_at(uv.as_vec2()).as_dvec3();
        }
    }
    let emission = sanitize(m.emission.as_dvec3(), f64::MAX) * std::f64::consts::PI;
    (
        sanitize(albedo, MAX_REFLECTANCE),
        sanitize(emission, f64::MAX),
        object.kind == ObjectKind::Real,
    )
}
