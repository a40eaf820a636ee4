//! The input of the flat-Lambert passes: meshes, a pinhole device and a directional light, with the shading math both the CPU reference and the GPU pass share.

use glam::{DMat3, DVec3, Vec3};
use showcase_proto::{Mesh, PinholeDevice, Transform};

/// One mesh placed in the world with a uniform diffuse albedo.
#[derive(Clone, Copy, Debug)]
pub struct DrawItem<'a> {
    /// The mesh, in object space.
    pub mesh: &'a Mesh,
    /// Object-to-world transform.
    pub transform: Transform,
    /// Linear RGB albedo.
    pub albedo: Vec3,
}

/// What the flat-Lambert passes draw: meshes seen from a pinhole device,
/// lit by one directional light.
#[derive(Clone, Copy, Debug)]
pub struct FlatLambertScene<'a> {
    /// The viewing device; its resolution is the image size.
    pub device: &'a PinholeDevice,
    /// The meshes, drawn in this order.
    pub items: &'a [DrawItem<'a>],
    /// Direction towards the light, world space (normalised on use; must
    /// be non-zero and finite).
    pub to_light: Vec3,
}

/// Why a [`FlatLambertScene`] cannot be drawn.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SceneError {
    /// The device has a zero width or height.
    #[error("device resolution {width}x{height} has no pixels")]
    EmptyImage {
        /// Width in pixels.
        width: u32,
        /// Height in pixels.
        height: u32,
    },
    /// The device's near/far planes or matrices are unusable.
    #[error("device clip mapping is not finite or near {near} / far {far} is not 0 < near < far")]
    BadDevice {
        /// Near plane.
        near: f64,
        /// Far plane.
        far: f64,
    },
    /// The light direction is zero or not finite.
    #[error("light direction {0:?} is zero or not finite")]
    BadLight(Vec3),
    /// A triangle refers to a vertex that does not exist.
    #[error("item {item}: triangle {triangle} uses vertex {index}, but the mesh has {vertices}")]
    IndexOutOfRange {
        /// Index into `items`.
        item: usize,
        /// Triangle index in the mesh.
        triangle: usize,
        /// The offending vertex index.
        index: u32,
        /// Number of vertices in the mesh.
        vertices: usize,
    },
    /// A vertex position, transform or albedo is not finite.
    #[error("item {item}: {what} is not finite")]
    NonFinite {
        /// Index into `items`.
        item: usize,
        /// Which value.
        what: &'static str,
    },
}

impl FlatLambertScene<'_> {
    /// Check everything a pass relies on: a non-empty image, a usable
    /// clip mapping, a finite light and finite, in-range meshes.
    pub fn validate(&self) -> Result<(), SceneError> {
        let d = self.device;
        if d.width == 0 || d.height == 0 {
            return Err(SceneError::EmptyImage {
                width: d.width,
                height: d.height,
            });
        }
        let clip_ok = d
            .clip_from_world()
            .to_cols_array()
            .iter()
            .all(|v| v.is_finite());
        if !(d.near > 0.0 && d.far > d.near && d.far.is_finite() && clip_ok) {
            return Err(SceneError::BadDevice {
                near: d.near,
                far: d.far,
            });
        }
        if !self.to_light.is_finite() || self.to_light.length_squared() == 0.0 {
            return Err(SceneError::BadLight(self.to_light));
        }
        for (i, it) in self.items.iter().enumerate() {
            let t = &it.transform;
            let transform_ok = t.translation.is_finite()
                && t.rotation.is_finite()
                && t.scale.is_finite()
                && normal_from_object(t)
                    .to_cols_array()
                    .iter()
                    .all(|v| v.is_finite());
            if !transform_ok {
                return Err(SceneError::NonFinite {
                    item: i,
                    what: "transform",
                });
            }
            if !it.albedo.is_finite() {
                return Err(SceneError::NonFinite {
                    item: i,
                    what: "albedo",
                });
            }
            if !it.mesh.positions.iter().all(|p| p.is_finite()) {
                return Err(SceneError::NonFinite {
                    item: i,
                    what: "vertex position",
                });
            }
            let n = it.mesh.positions.len();
            for (ti, tri) in it.mesh.triangles.iter().enumerate() {
                if let Some(&index) = tri.iter().find(|&&v| v as usize >= n) {
                    return Err(SceneError::IndexOutOfRange {
                        item: i,
                        triangle: ti,
                        index,
                        vertices: n,
                    });
                }
            }
        }
        Ok(())
    }

    /// The unit direction towards the light, in f64.
    pub fn light_direction(&self) -> DVec3 {
        self.to_light.as_dvec3().normalize_or_zero()
    }
}

/// Unit geometric normal of triangle `tri` in object space,
/// `(b - a) x (c - a)` normalised; zero for a degenerate triangle.
/// Indices must be in range ([`FlatLambertScene::validate`]).
pub fn face_normal(mesh: &Mesh, tri: [u32; 3]) -> DVec3 {
    let [a, b, c] = tri.map(|i| mesh.positions[i as usize].as_dvec3());
    (b - a).cross(c - a).normalize_or_zero()
}

/// The matrix that takes object-space normals to world space: the
/// inverse transpose of the transform's linear part (zero if singular).
pub fn normal_from_object(transform: &Transform) -> DMat3 {
    let m = DMat3::from_mat4(transform.matrix().as_dmat4());
    if m.determinant() == 0.0 {
        return DMat3::ZERO;
    }
    m.inverse().transpose()
}

/// The flat Lambert factor `max(0, n . l)` of a face whose object-space
/// normal is `n_object`, for a unit `to_light`.
pub fn lambert(normal_from_object: &DMat3, n_object: DVec3, to_light: DVec3) -> f64 {
    let n = (*normal_from_object * n_object).normalize_or_zero();
    n.dot(to_light).max(0.0)
}
