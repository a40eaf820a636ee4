//! The global-illumination field the displays add to their direct target
//! ([`crate::radiosity::augmented::indirect_correction`]: the projectors
//! on the real surfaces, the faces on the virtual ones and on filled
//! occlusion shadows), as the frame model carries it: per vertex of the
//! radiosity mesh it was solved on, interpolated at the surface point a
//! pixel shows.

use crate::Hit;
use crate::radiosity::RadiosityMesh;
pub use crate::radiosity::augmented::IndirectLight;
use glam::{DVec2, DVec3};
use std::sync::Arc;

/// A global-illumination field over the scene's surfaces.
#[derive(Clone, Debug)]
pub struct IndirectField {
    mesh: Arc<RadiosityMesh>,
    /// [`IndirectLight::add`] averaged to the mesh's vertices.
    add: Vec<DVec3>,
    /// [`IndirectLight::cabinet`] averaged to the mesh's vertices.
    cabinet: Vec<DVec3>,
}

/// A piece of a field over one scene triangle ([`IndirectField::pieces`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FieldPiece {
    /// Corners in the triangle's barycentric coordinates `(u, v)` (weights
    /// of its second and third vertex).
    pub corners: [DVec2; 3],
    /// The field at the corners.
    pub values: [IndirectLight; 3],
}

/// Why a field cannot be made.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum IndirectFieldError {
    /// The values are not one per element of the mesh.
    #[error("{got} correction values for a mesh of {elements} elements")]
    Length {
        /// Values given.
        got: usize,
        /// Elements of the mesh.
        elements: usize,
    },
    /// A value is not finite.
    #[error("correction value {index} is not finite")]
    NotFinite {
        /// Its element.
        index: usize,
    },
}

impl IndirectField {
    /// The field of per-element `values` on `mesh`, averaged to its
    /// vertices ([`RadiosityMesh::vertex_values`]).
    pub fn new(
        mesh: Arc<RadiosityMesh>,
        values: &[IndirectLight],
    ) -> Result<Self, IndirectFieldError> {
        if values.len() != mesh.elements.len() {
            return Err(IndirectFieldError::Length {
                got: values.len(),
                elements: mesh.elements.len(),
            });
        }
        if let Some(index) = values.iter().position(|v| !v.is_finite()) {
            return Err(IndirectFieldError::NotFinite { index });
        }
        let add: Vec<DVec3> = values.iter().map(|v| v.add).collect();
        let cabinet: Vec<DVec3> = values.iter().map(|v| v.cabinet).collect();
        Ok(Self {
            add: mesh.vertex_values(&add),
            cabinet: mesh.vertex_values(&cabinet),
            mesh,
        })
    }

    /// The field at vertex `v` of the mesh (zero for none).
    fn vertex(&self, v: u32) -> IndirectLight {
        let at = |values: &[DVec3]| values.get(v as usize).copied().unwrap_or(DVec3::ZERO);
        IndirectLight {
            add: at(&self.add),
            cabinet: at(&self.cabinet),
        }
    }

    /// The field over scene triangle `triangle` of object `object` as
    /// pieces a renderer draws with per-vertex values: each leaf of the
    /// mesh's quadtree over the triangle, its corners in the triangle's
    /// barycentric coordinates `(u, v)` and the field there. [`Self::at`]
    /// interpolates the same values linearly inside each piece (zero in a
    /// piece without an element). `None` off the mesh.
    pub fn pieces(&self, object: u32, triangle: u32) -> Option<Vec<FieldPiece>> {
        let primitive = self.mesh.primitive_of(object, triangle)?;
        let mut out = Vec::new();
        self.mesh.for_each_leaf(primitive, |corners, element| {
            let values = element
                .and_then(|e| self.mesh.elements.get(e as usize))
                .map_or([IndirectLight::default(); 3], |e| {
                    e.vertex_ids.map(|v| self.vertex(v))
                });
            out.push(FieldPiece { corners, values });
        });
        Some(out)
    }

    /// The field at `hit` (zero off the mesh).
    pub fn at(&self, hit: &Hit) -> IndirectLight {
        let Some(p) = self.mesh.primitive_of(hit.object, hit.triangle) else {
            return IndirectLight::default();
        };
        let at = |values: &[DVec3]| {
            self.mesh
                .interpolate(p, hit.barycentric, values)
                .filter(|v| v.is_finite())
                .unwrap_or(DVec3::ZERO)
        };
        IndirectLight {
            add: at(&self.add),
            cabinet: at(&self.cabinet),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::radiosity::MeshOptions;
    use crate::{ObjectFilter, Ray, SceneGeometry};
    use glam::Vec3;
    use showcase_proto::{Material, Mesh, Object, ObjectKind, Showcase, Transform};

    /// `add` as given, `cabinet` half of it.
    fn light(add: DVec3) -> IndirectLight {
        IndirectLight {
            add,
            cabinet: add / 2.0,
        }
    }

    #[test]
    fn a_field_is_one_finite_value_per_element_read_where_a_ray_lands() {
        let mut s = Showcase::default();
        let mesh = s.add_mesh(Mesh {
            positions: vec![
                Vec3::new(0.0, 0.0, 0.0),
                Vec3::new(0.0, 0.0, 1.0),
                Vec3::new(1.0, 0.0, 1.0),
                Vec3::new(1.0, 0.0, 0.0),
            ],
            triangles: vec![[0, 1, 2], [0, 2, 3]],
            ..Mesh::default()
        });
        s.objects.push(Object {
            name: "floor".into(),
            mesh,
            material: Material::diffuse(Vec3::splat(0.5)),
            kind: ObjectKind::Real,
            transform: Transform::IDENTITY,
        });
        let g = SceneGeometry::build(&s, &ObjectFilter::All).unwrap();
        let m = Arc::new(RadiosityMesh::build(&s, &g, &MeshOptions::default()).unwrap());
        let n = m.elements.len();
        assert_eq!(
            IndirectField::new(m.clone(), &vec![light(DVec3::ONE); n + 1]).unwrap_err(),
            IndirectFieldError::Length {
                got: n + 1,
                elements: n
            }
        );
        let mut bad = vec![light(DVec3::ONE); n];
        bad[n / 2].cabinet = DVec3::NAN;
        assert_eq!(
            IndirectField::new(m.clone(), &bad).unwrap_err(),
            IndirectFieldError::NotFinite { index: n / 2 }
        );
        // A uniform field reads the same everywhere on the floor.
        let field =
            IndirectField::new(m.clone(), &vec![light(DVec3::new(0.1, 0.2, 0.3)); n]).unwrap();
        let ray = Ray::new(DVec3::new(0.3, 1.0, 0.7), -DVec3::Y);
        let hit = g.closest_hit(&ray, 0.0, f64::INFINITY).unwrap();
        let at = field.at(&hit);
        assert!((at.add - DVec3::new(0.1, 0.2, 0.3)).length() < 1e-12);
        assert!((at.cabinet - DVec3::new(0.1, 0.2, 0.3) / 2.0).length() < 1e-12);

        // A field that differs per element: its pieces tile each triangle,
        // and inside a piece the corner values interpolate to what `at`
        // reads there.
        let values: Vec<IndirectLight> = (0..n)
            .map(|i| IndirectLight {
                add: DVec3::new(i as f64, (i * i % 7) as f64, -(i as f64) / 3.0),
                cabinet: DVec3::new((i % 3) as f64, 0.5, i as f64),
            })
            .collect();
        let field = IndirectField::new(m, &values).unwrap();
        assert!(field.pieces(0, 2).is_none());
        for triangle in 0..2 {
            let pieces = field.pieces(0, triangle).unwrap();
            let area: f64 = pieces
                .iter()
                .map(|p| {
                    0.5 * (p.corners[1] - p.corners[0])
                        .perp_dot(p.corners[2] - p.corners[0])
                        .abs()
                })
                .sum();
            assert!((area - 0.5).abs() < 1e-12, "pieces cover {area} of 0.5");
            for p in &pieces {
                let w = DVec3::new(0.2, 0.3, 0.5);
                let b = w.x * p.corners[0] + w.y * p.corners[1] + w.z * p.corners[2];
                let lerp = |part: fn(&IndirectLight) -> DVec3| {
                    w.x * part(&p.values[0]) + w.y * part(&p.values[1]) + w.z * part(&p.values[2])
                };
                let expected = IndirectLight {
                    add: lerp(|l| l.add),
                    cabinet: lerp(|l| l.cabinet),
                };
                let hit = crate::Hit {
                    object: 0,
                    triangle,
                    barycentric: b,
                    ..hit
                };
                let at = field.at(&hit);
                assert!(
                    (at.add - expected.add).length() < 1e-9
                        && (at.cabinet - expected.cabinet).length() < 1e-9,
                    "triangle {triangle} at {b}: {at:?} against {expected:?}"
                );
            }
        }
    }
}
