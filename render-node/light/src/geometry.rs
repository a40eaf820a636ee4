//! The world-space triangle scene of a [`Showcase`]: every selected object's
//! mesh transformed by its `Transform`, in one BVH, with closest-hit,
//! any-hit and point-to-point visibility queries.
//!
//! # Epsilon policy
//! Geometry is f64, so the rounding error of a hit point is about
//! `1e-16 * scene scale`. Rays leaving a surface start from the point offset
//! by [`SceneGeometry::epsilon`] (`1e-9 *` the largest absolute world
//! coordinate, at least `1e-12` m) along the geometric normal, on the side
//! the ray leaves to; rays ending on a surface stop `epsilon` short of it.
//! The offset is seven orders of magnitude above the rounding error (no
//! shadow acne) and, at about a nanometre for a metre-sized showcase, far
//! below any feature size (no light leaking through corners).

use super::bvh::Bvh;
use super::ray::{Aabb, Ray};
use crate::finite::finite_or_zero;
use glam::{DAffine3, DMat3, DMat4, DVec2, DVec3, Vec2};
use showcase_proto::{ObjectKind, Showcase, Transform};

/// Relative size of the surface offset, see the module docs.
const EPSILON_RELATIVE: f64 = 1e-9;
/// Smallest surface offset in metres.
const EPSILON_MIN: f64 = 1e-12;

/// Why a scene could not be turned into ray-casting geometry.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum GeometryError {
    /// An object refers to a mesh the showcase does not carry.
    #[error("object {object} ({name}) refers to a mesh that is not in the showcase")]
    MissingMesh {
        /// Index of the object.
        object: usize,
        /// Its name.
        name: String,
    },
    /// A triangle index points past the mesh's positions.
    #[error("object {object} ({name}): triangle {triangle} has vertex index {index} out of range")]
    IndexOutOfRange {
        /// Index of the object.
        object: usize,
        /// Its name.
        name: String,
        /// The triangle.
        triangle: usize,
        /// The offending vertex index.
        index: u32,
    },
    /// The transform is non-finite or singular (a zero scale).
    #[error("object {object} ({name}) has a non-finite or singular transform")]
    BadTransform {
        /// Index of the object.
        object: usize,
        /// Its name.
        name: String,
    },
}

/// Which objects of a showcase become geometry.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum ObjectFilter {
    /// Every object.
    All,
    /// Only real (physical) objects.
    Real,
    /// Only virtual objects.
    Virtual,
    /// Only the objects with these indices.
    Indices(Vec<usize>),
}

impl ObjectFilter {
    /// True when object `index` of kind `kind` passes.
    pub fn accepts(&self, index: usize, kind: ObjectKind) -> bool {
        match self {
            ObjectFilter::All => true,
            ObjectFilter::Real => kind == ObjectKind::Real,
            ObjectFilter::Virtual => kind == ObjectKind::Virtual,
            ObjectFilter::Indices(list) => list.contains(&index),
        }
    }
}

/// The object-to-world matrix of `transform` in f64 (`T * R * S`, the
/// quaternion renormalised in f64), as every CPU reference uses it; `None`
/// if it is not finite or the quaternion is zero.
pub fn world_matrix(transform: &Transform) -> Option<DMat4> {
    let q = transform.rotation.as_dquat();
    if !q.is_finite() || q.length() == 0.0 {
        return None;
    }
    let m = DMat4::from_scale_rotation_translation(
        transform.scale.as_dvec3(),
        q.normalize(),
        transform.translation.as_dvec3(),
    );
    m.is_finite().then_some(m)
}

/// Per-triangle data beside the BVH's positions.
#[derive(Clone, Copy, Debug)]
struct TriangleInfo {
    object: u32,
    /// Index of the triangle within its object's mesh.
    local: u32,
    /// Unit geometric normal (counter-clockwise winding), zero if degenerate.
    normal: DVec3,
    /// World-space vertex normals, if the mesh has them.
    vertex_normals: Option<[DVec3; 3]>,
    uvs: Option<[Vec2; 3]>,
}

/// One world-space triangle of a [`SceneGeometry`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WorldTriangle {
    /// Vertices in world space, counter-clockwise seen from the front.
    pub vertices: [DVec3; 3],
    /// Index into `Showcase::objects`.
    pub object: u32,
    /// Index of the triangle within that object's mesh.
    pub triangle: u32,
    /// Unit geometric normal of the front side (zero if degenerate).
    pub normal: DVec3,
    /// Area in square metres.
    pub area: f64,
}

/// A ray/scene intersection.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Index into `Showcase::objects`.
    pub object: u32,
    /// Index of the triangle within that object's mesh.
    pub triangle: u32,
    /// Index of the triangle in [`SceneGeometry::triangle`] numbering.
    pub primitive: u32,
    /// Ray parameter (distance when the direction is a unit vector).
    pub t: f64,
    /// Barycentric weights of the triangle's second and third vertex.
    pub barycentric: DVec2,
    /// The hit point, interpolated from the vertices (on the surface).
    pub point: DVec3,
    /// Unit geometric normal of the triangle's front (counter-clockwise) side.
    pub geometric_normal: DVec3,
    /// Unit interpolated vertex normal, or the geometric normal if the mesh
    /// has none (or they interpolate to zero). Not flipped.
    pub shading_normal: DVec3,
    /// Interpolated texture coordinate, if the mesh has them.
    pub uv: Option<Vec2>,
    /// True when the ray arrived at the front side.
    pub front_face: bool,
}

/// `n` turned to the side `towards` points to: `n` when
/// `n.dot(towards) >= 0.0` (so also when `towards` lies in the surface),
/// `-n` otherwise and when the product is NaN. The crate's one two-sided
/// normal rule: [`Hit::facing_normal`] and every flip of a shading normal
/// to the seen side use it.
pub fn face_forward(n: DVec3, towards: DVec3) -> DVec3 {
    if n.dot(towards) >= 0.0 { n } else { -n }
}

impl Hit {
    /// The geometric normal on the side that a ray arriving along
    /// `incoming` sees, pointing back against it: [`face_forward`] towards
    /// `-incoming`. A grazing ray (`geometric_normal.dot(incoming) == 0.0`)
    /// gets the front normal although [`Hit::front_face`] (`< 0.0`) calls it
    /// a back-face hit; a NaN product gets the back normal.
    pub fn facing_normal(&self, incoming: DVec3) -> DVec3 {
        face_forward(self.geometric_normal, -incoming)
    }
}

/// The surface offset of the epsilon policy (module docs) for the
/// triangles of `bvh`.
fn epsilon_of(bvh: &Bvh) -> f64 {
    let b = bvh.bounds();
    let scale = if b.is_empty() {
        0.0
    } else {
        b.min.abs().max(b.max.abs()).max_element()
    };
    (EPSILON_RELATIVE * scale).max(EPSILON_MIN)
}

/// What blocks light between two points: one scene's [`SceneGeometry`],
/// or a static scene and the objects that move in it, each in a BVH of its
/// own (so a move rebuilds only the moved object's).
pub trait Occluders: Sync {
    /// True when nothing blocks the segment from surface point `a` (normal
    /// `normal_a`) to `b`, as [`SceneGeometry::visible`].
    fn visible(&self, a: DVec3, normal_a: DVec3, b: DVec3, b_on_surface: bool) -> bool;
}

impl Occluders for SceneGeometry {
    fn visible(&self, a: DVec3, normal_a: DVec3, b: DVec3, b_on_surface: bool) -> bool {
        SceneGeometry::visible(self, a, normal_a, b, b_on_surface)
    }
}

/// World-space triangles of the selected objects in a BVH.
#[derive(Clone, Debug)]
pub struct SceneGeometry {
    bvh: Bvh,
    info: Vec<TriangleInfo>,
    /// Kind of every object of the showcase (selected or not).
    kinds: Vec<ObjectKind>,
    epsilon: f64,
}

impl SceneGeometry {
    /// Geometry of the objects of `showcase` that pass `filter`, in world
    /// space. Zero-area triangles are kept out of the BVH (never hit).
    pub fn build(showcase: &Showcase, filter: &ObjectFilter) -> Result<Self, GeometryError> {
        let mut triangles = Vec::new();
        let mut info = Vec::new();
        for (oi, object) in showcase.objects.iter().enumerate() {
            if !filter.accepts(oi, object.kind) {
                continue;
            }
            let mesh = showcase
                .mesh(&object.mesh)
                .ok_or_else(|| GeometryError::MissingMesh {
                    object: oi,
                    name: object.name.clone(),
                })?;
            let bad_transform = || GeometryError::BadTransform {
                object: oi,
                name: object.name.clone(),
            };
            let model = world_matrix(&object.transform).ok_or_else(bad_transform)?;
            let linear = DMat3::from_mat4(model);
            let det = linear.determinant();
            if det == 0.0 || !det.is_finite() {
                return Err(bad_transform());
            }
            let normal_matrix = linear.inverse().transpose();
            let world: Vec<DVec3> = mesh
                .positions
                .iter()
                .map(|p| model.transform_point3(p.as_dvec3()))
                .collect();
            let has_normals =
                mesh.normals.len() == mesh.positions.len() && !mesh.normals.is_empty();
            let has_uvs = mesh.uvs.len() == mesh.positions.len() && !mesh.uvs.is_empty();
            for (ti, tri) in mesh.triangles.iter().enumerate() {
                if let Some(&index) = tri.iter().find(|&&i| i as usize >= world.len()) {
                    return Err(GeometryError::IndexOutOfRange {
                        object: oi,
                        name: object.name.clone(),
                        triangle: ti,
                        index,
                    });
                }
                let v = tri.map(|i| world[i as usize]);
                let n = (v[1] - v[0]).cross(v[2] - v[0]).normalize_or_zero();
                let vertex_normals = has_normals.then(|| {
                    tri.map(|i| {
                        (normal_matrix * mesh.normals[i as usize].as_dvec3()).normalize_or_zero()
                    })
                });
                triangles.push(v);
                info.push(TriangleInfo {
                    object: oi as u32,
                    local: ti as u32,
                    normal: finite_or_zero(n),
                    vertex_normals,
                    uvs: has_uvs.then(|| tri.map(|i| mesh.uvs[i as usize])),
                });
            }
        }
        let bvh = Bvh::build(triangles);
        Ok(Self {
            epsilon: epsilon_of(&bvh),
            bvh,
            info,
            kinds: showcase.objects.iter().map(|o| o.kind).collect(),
        })
    }

    /// This geometry moved rigidly by `motion` (a rotation and a
    /// translation): every triangle and normal moved, the BVH built again.
    /// Moved by the same motion as a mesh made from it, it stays on that
    /// mesh to the last bit (a move's own BVH, see the radiosity
    /// hierarchy's movers).
    pub fn moved(&self, motion: &DAffine3) -> Self {
        let turn = motion.matrix3;
        let triangles = self
            .bvh
            .triangles()
            .iter()
            .map(|t| t.map(|v| motion.transform_point3(v)))
            .collect();
        let info = self
            .info
            .iter()
            .map(|i| TriangleInfo {
                normal: turn * i.normal,
                vertex_normals: i.vertex_normals.map(|n| n.map(|v| turn * v)),
                ..*i
            })
            .collect();
        let bvh = Bvh::build(triangles);
        Self {
            epsilon: epsilon_of(&bvh),
            bvh,
            info,
            kinds: self.kinds.clone(),
        }
    }

    /// Kind of object `index` of the showcase this was built from.
    pub fn object_kind(&self, index: u32) -> Option<ObjectKind> {
        self.kinds.get(index as usize).copied()
    }

    /// The surface offset of the epsilon policy (module docs), in metres.
    pub fn epsilon(&self) -> f64 {
        self.epsilon
    }

    /// Bounds of all hittable geometry.
    pub fn bounds(&self) -> Aabb {
        self.bvh.bounds()
    }

    /// Number of triangles (including degenerate ones that are never hit).
    pub fn triangle_count(&self) -> usize {
        self.info.len()
    }

    /// Triangle `index` (`0..triangle_count()`, in object order), degenerate
    /// ones included.
    pub fn triangle(&self, index: u32) -> Option<WorldTriangle> {
        let info = self.info.get(index as usize)?;
        let vertices = self.bvh.triangles()[index as usize];
        let area = 0.5
            * (vertices[1] - vertices[0])
                .cross(vertices[2] - vertices[0])
                .length();
        Some(WorldTriangle {
            vertices,
            object: info.object,
            triangle: info.local,
            normal: info.normal,
            area: finite_or_zero(area),
        })
    }

    /// All triangles, in object order.
    pub fn triangles(&self) -> impl Iterator<Item = WorldTriangle> + '_ {
        (0..self.info.len() as u32).filter_map(|i| self.triangle(i))
    }

    /// The underlying BVH.
    pub fn bvh(&self) -> &Bvh {
        &self.bvh
    }

    /// The closest hit with `t` in `(t_min, t_max)`.
    pub fn closest_hit(&self, ray: &Ray, t_min: f64, t_max: f64) -> Option<Hit> {
        let h = self.bvh.closest_hit(ray, t_min, t_max)?;
        let info = self.info[h.triangle as usize];
        let [a, b, c] = self.bvh.triangles()[h.triangle as usize];
        let (u, v) = (h.hit.u, h.hit.v);
        let w = 1.0 - u - v;
        let point = w * a + u * b + v * c;
        let ng = info.normal;
        let shading_normal = info
            .vertex_normals
            .map(|[na, nb, nc]| (w * na + u * nb + v * nc).normalize_or_zero())
            .filter(|n| *n != DVec3::ZERO && n.is_finite())
            .unwrap_or(ng);
        let uv = info.uvs.map(|[ta, tb, tc]| {
            (w * ta.as_dvec2() + u * tb.as_dvec2() + v * tc.as_dvec2()).as_vec2()
        });
        Some(Hit {
            object: info.object,
            triangle: info.local,
            primitive: h.triangle,
            t: h.hit.t,
            barycentric: DVec2::new(u, v),
            point,
            geometric_normal: ng,
            shading_normal,
            uv,
            front_face: ng.dot(ray.direction) < 0.0,
        })
    }

    /// True when anything lies on the ray with `t` in `(0, t_max)`.
    pub fn occluded(&self, origin: DVec3, direction: DVec3, t_max: f64) -> bool {
        self.bvh.any_hit(&Ray::new(origin, direction), 0.0, t_max)
    }

    /// `point` moved off its surface (normal `normal`) by [`Self::epsilon`]
    /// towards `toward`, the side a ray leaving it goes to.
    pub fn offset_point(&self, point: DVec3, normal: DVec3, toward: DVec3) -> DVec3 {
        let side = if normal.dot(toward - point) >= 0.0 {
            1.0
        } else {
            -1.0
        };
        point + side * self.epsilon * normal
    }

    /// True when nothing blocks the segment from surface point `a` (normal
    /// `normal_a`, zero for a point not on a surface) to point `b`, which
    /// counts as a surface point when `b_on_surface` (the ray then stops
    /// [`Self::epsilon`] short of it). Non-finite input is not visible.
    pub fn visible(&self, a: DVec3, normal_a: DVec3, b: DVec3, b_on_surface: bool) -> bool {
        if !(a.is_finite() && b.is_finite() && normal_a.is_finite()) {
            return false;
        }
        let origin = self.offset_point(a, normal_a, b);
        let d = b - origin;
        let len = d.length();
        let stop = if b_on_surface {
            len - self.epsilon
        } else {
            len
        };
        if !(stop > 0.0) {
            return true;
        }
        !self.occluded(origin, d / len, stop)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::{Quat, Vec3};
    use showcase_proto::{Material, Mesh, Object};

    fn one_object(mesh: Mesh, transform: Transform, kind: ObjectKind) -> Showcase {
        let mut s = Showcase::default();
        let id = s.add_mesh(mesh);
        s.objects.push(Object {
            name: "quad".into(),
            mesh: id,
            material: Material::diffuse(Vec3::ONE),
            kind,
            transform,
        });
        s
    }

    fn quad() -> Mesh {
        Mesh {
            positions: vec![Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.0), Vec3::Y],
            // Tilted, non-unit vertex normals.
            normals: vec![
                Vec3::new(1.0, 0.0, 1.0),
                Vec3::new(0.0, 0.0, 3.0),
                Vec3::Z,
                Vec3::new(0.0, 1.0, 1.0),
            ],
            uvs: vec![
                glam::Vec2::ZERO,
                glam::Vec2::X,
                glam::Vec2::ONE,
                glam::Vec2::Y,
            ],
            triangles: vec![[0, 1, 2], [0, 2, 3]],
        }
    }

    #[test]
    fn hit_interpolates_uv_and_transforms_normals_by_the_inverse_transpose() {
        let transform = Transform {
            translation: Vec3::new(1.0, 2.0, 3.0),
            rotation: Quat::from_rotation_y(0.4),
            scale: Vec3::new(2.0, 1.0, 0.5),
        };
        let s = one_object(quad(), transform, ObjectKind::Real);
        let g = SceneGeometry::build(&s, &ObjectFilter::Real).unwrap();
        let model = world_matrix(&transform).unwrap();
        let local = DVec3::new(0.75, 0.25, 0.0); // in triangle 0: weights a 0.25, b 0.5, c 0.25
        let target = model.transform_point3(local);
        let normal_matrix = DMat3::from_mat4(model).inverse().transpose();
        let front = (normal_matrix * DVec3::Z).normalize();
        let origin = target + front;
        let hit = g
            .closest_hit(&Ray::new(origin, target - origin), 0.0, f64::INFINITY)
            .unwrap();
        assert_eq!((hit.object, hit.triangle, hit.primitive), (0, 0, 0));
        let tri = g.triangle(hit.primitive).unwrap();
        assert_eq!(tri.normal, hit.geometric_normal);
        // Both triangles: the quad's area scaled by the transform.
        let area: f64 = g.triangles().map(|t| t.area).sum();
        let expected_area = (DMat3::from_mat4(model) * DVec3::X)
            .cross(DMat3::from_mat4(model) * DVec3::Y)
            .length();
        assert!((area - expected_area).abs() < 1e-12);
        assert!(g.triangle(2).is_none());
        assert!(hit.front_face);
        assert!((hit.point - target).length() < 1e-12);
        assert!((hit.t - 1.0).abs() < 1e-12);
        assert!((hit.barycentric - DVec2::new(0.5, 0.25)).length() < 1e-12);
        assert!((hit.uv.unwrap() - glam::Vec2::new(0.75, 0.25)).length() < 1e-6);
        assert!((hit.geometric_normal - front).length() < 1e-12);
        let n = |v: Vec3| v.as_dvec3().normalize();
        let blend = 0.25 * n(Vec3::new(1.0, 0.0, 1.0)) + 0.5 * DVec3::Z + 0.25 * DVec3::Z;
        let expected = (normal_matrix * blend).normalize();
        // Vertex normals are transformed then interpolated; with these
        // weights that equals interpolating the transformed unit normals.
        let transformed = |v: DVec3| (normal_matrix * v).normalize();
        let expected_interp = (0.25 * transformed(n(Vec3::new(1.0, 0.0, 1.0)))
            + 0.75 * transformed(DVec3::Z))
        .normalize();
        assert!((hit.shading_normal - expected_interp).length() < 1e-12);
        assert!(hit.shading_normal.dot(expected) > 0.99);
    }

    /// The rule every former copy wrote out: `geometric_normal.dot(incoming)
    /// <= 0.0` keeps the front normal.
    #[track_caller]
    fn check_facing(incoming: DVec3, expected: DVec3) {
        let hit = Hit {
            object: 0,
            triangle: 0,
            primitive: 0,
            t: 1.0,
            barycentric: DVec2::ZERO,
            point: DVec3::ZERO,
            geometric_normal: DVec3::Z,
            shading_normal: DVec3::Z,
            uv: None,
            front_face: DVec3::Z.dot(incoming) < 0.0,
        };
        let old_rule = if DVec3::Z.dot(incoming) <= 0.0 {
            DVec3::Z
        } else {
            -DVec3::Z
        };
        assert_eq!(hit.facing_normal(incoming), expected);
        assert_eq!(old_rule, expected);
    }

    #[test]
    fn facing_normal_turns_against_the_ray_and_keeps_the_front_when_grazing() {
        check_facing(DVec3::NEG_Z, DVec3::Z);
        check_facing(DVec3::new(1.0, 0.0, -1e-300), DVec3::Z);
        check_facing(DVec3::Z, DVec3::NEG_Z);
        check_facing(DVec3::new(1.0, 0.0, 1e-300), DVec3::NEG_Z);
        // Grazing: the front normal, although `front_face` is false.
        check_facing(DVec3::X, DVec3::Z);
        check_facing(DVec3::new(1.0, 0.0, -0.0), DVec3::Z);
        check_facing(DVec3::new(1.0, 0.0, 0.0), DVec3::Z);
        check_facing(DVec3::new(f64::NAN, 0.0, 1.0), DVec3::NEG_Z);
        check_facing(DVec3::new(0.0, 0.0, f64::INFINITY), DVec3::NEG_Z);
        check_facing(DVec3::new(0.0, 0.0, f64::NEG_INFINITY), DVec3::Z);
        assert_eq!(face_forward(DVec3::Y, DVec3::X), DVec3::Y);
        assert_eq!(face_forward(DVec3::Y, DVec3::NEG_Y), DVec3::NEG_Y);
        assert_eq!(face_forward(DVec3::Y, DVec3::NAN), DVec3::NEG_Y);
    }

    #[test]
    fn filters_select_objects_by_kind_and_index() {
        let s = one_object(quad(), Transform::IDENTITY, ObjectKind::Virtual);
        let count = |f: ObjectFilter| SceneGeometry::build(&s, &f).unwrap().triangle_count();
        assert_eq!(count(ObjectFilter::All), 2);
        assert_eq!(count(ObjectFilter::Virtual), 2);
        assert_eq!(count(ObjectFilter::Real), 0);
        assert_eq!(count(ObjectFilter::Indices(vec![0])), 2);
        assert_eq!(count(ObjectFilter::Indices(vec![1])), 0);
        let empty = SceneGeometry::build(&s, &ObjectFilter::Real).unwrap();
        assert!(empty.bounds().is_empty() && empty.epsilon() > 0.0);
        assert!(empty.visible(DVec3::ZERO, DVec3::Z, DVec3::ONE, true));
        assert_eq!(empty.object_kind(0), Some(ObjectKind::Virtual));
    }
}
