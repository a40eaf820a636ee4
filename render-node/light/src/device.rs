//! Pinhole devices (projectors and cameras, OpenCV convention) as ray
//! generators and projectors of world points, plus point-to-device
//! visibility: is a surface point lit by a projector, seen by a camera.
//!
//! Pixel `(x, y)` covers `[x, x+1) x [y, y+1)` with its centre at
//! `(x + 0.5, y + 0.5)`, the origin at the top-left corner (as in
//! `PinholeDevice`). Lens distortion is ignored here, as in
//! `PinholeDevice::project`; the simulated devices have none.

use super::geometry::SceneGeometry;
use super::ray::Ray;
use glam::{DMat3, DVec2, DVec3};
use showcase_proto::PinholeDevice;

/// Why a device cannot be used for ray casting.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum DeviceError {
    /// K, R or t has a non-finite entry.
    #[error("device has a non-finite intrinsic or extrinsic parameter")]
    NonFinite,
    /// K is not invertible (zero focal length or `K[2][2] = 0`).
    #[error("device intrinsic matrix is singular (determinant {det})")]
    SingularIntrinsics {
        /// The determinant of K.
        det: f64,
    },
    /// The image has no pixels.
    #[error("device image is empty ({width}x{height})")]
    EmptyImage {
        /// Width in pixels.
        width: u32,
        /// Height in pixels.
        height: u32,
    },
}

/// A validated pinhole device with its ray-generation matrix precomputed.
#[derive(Clone, Debug)]
pub struct DeviceRays {
    device: PinholeDevice,
    center: DVec3,
    /// `R^T K^-1`: pixel `(u, v, 1)` to a world direction.
    pixel_to_world: DMat3,
}

impl DeviceRays {
    /// Check `device` and precompute its rays.
    pub fn new(device: &PinholeDevice) -> Result<Self, DeviceError> {
        if device.width == 0 || device.height == 0 {
            return Err(DeviceError::EmptyImage {
                width: device.width,
                height: device.height,
            });
        }
        if !(device.k.is_finite() && device.rotation.is_finite() && device.translation.is_finite())
        {
            return Err(DeviceError::NonFinite);
        }
        let det = device.k.determinant();
        if det == 0.0 || !det.is_finite() {
            return Err(DeviceError::SingularIntrinsics { det });
        }
        let pixel_to_world = device.rotation.transpose() * device.k.inverse();
        if !pixel_to_world.is_finite() {
            return Err(DeviceError::SingularIntrinsics { det });
        }
        Ok(Self {
            device: device.clone(),
            center: device.center(),
            pixel_to_world,
        })
    }

    /// The device.
    pub fn device(&self) -> &PinholeDevice {
        &self.device
    }

    /// Centre of projection in world space.
    pub fn center(&self) -> DVec3 {
        self.center
    }

    /// The ray from the centre of projection through image point `pixel`
    /// (continuous pixel coordinates), with a unit direction. `None` for
    /// non-finite input or a point that maps to no direction.
    pub fn ray_through(&self, pixel: DVec2) -> Option<Ray> {
        let d = (self.pixel_to_world * pixel.extend(1.0)).normalize_or_zero();
        (pixel.is_finite() && d != DVec3::ZERO && d.is_finite()).then(|| Ray::new(self.center, d))
    }

    /// The ray through the centre `(x + 0.5, y + 0.5)` of pixel `(x, y)`.
    pub fn pixel_ray(&self, x: u32, y: u32) -> Option<Ray> {
        self.ray_through(DVec2::new(x as f64 + 0.5, y as f64 + 0.5))
    }

    /// Continuous pixel coordinates of a world point; `None` when it is not
    /// strictly in front of the device (device z <= 0) or not finite.
    pub fn project(&self, world: DVec3) -> Option<DVec2> {
        let c = self.device.to_device(world);
        if !(c.z > 0.0) || !c.is_finite() {
            return None;
        }
        let p = self.device.k * (c / c.z);
        let px = DVec2::new(p.x, p.y);
        px.is_finite().then_some(px)
    }

    /// True when continuous pixel coordinates fall inside the image,
    /// `[0, width) x [0, height)`.
    pub fn in_image(&self, pixel: DVec2) -> bool {
        pixel.x >= 0.0
            && pixel.y >= 0.0
            && pixel.x < self.device.width as f64
            && pixel.y < self.device.height as f64
    }

    /// The integer pixel holding a world point, if it projects into the image.
    pub fn pixel_of(&self, world: DVec3) -> Option<(u32, u32)> {
        let p = self.project(world)?;
        self.in_image(p).then_some((p.x as u32, p.y as u32))
    }

    /// True when surface point `point` (unit normal `normal`) and the device
    /// see each other: the point is in front of the device and inside its
    /// image, the device is on the side `normal` points to, and nothing in
    /// `geometry` blocks the segment between them. A projector "sees" the
    /// points it lights; a camera the points it images.
    pub fn sees(&self, geometry: &SceneGeometry, point: DVec3, normal: DVec3) -> bool {
        let Some(p) = self.project(point) else {
            return false;
        };
        if !self.in_image(p) || !(normal.dot(self.center - point) > 0.0) {
            return false;
        }
        geometry.visible(point, normal, self.center, false)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn device() -> PinholeDevice {
        let mut d = PinholeDevice::look_at(
            DVec3::new(0.3, 0.4, -1.0),
            DVec3::new(0.25, 0.2, 0.5),
            DVec3::Y,
            50.0,
            64,
            48,
        );
        d.k.y_axis.x = 0.7; // skew
        d.k.z_axis.x += 3.0; // off-centre principal point
        d
    }

    #[test]
    fn pixel_centre_round_trip() {
        let rays = DeviceRays::new(&device()).unwrap();
        for (x, y) in [(0, 0), (63, 47), (10, 30), (32, 24)] {
            let ray = rays.pixel_ray(x, y).unwrap();
            assert!((ray.direction.length() - 1.0).abs() < 1e-14);
            for depth in [0.05, 1.0, 37.0] {
                let p = rays.project(ray.at(depth)).unwrap();
                assert!((p - DVec2::new(x as f64 + 0.5, y as f64 + 0.5)).length() < 1e-9);
                assert_eq!(rays.pixel_of(ray.at(depth)), Some((x, y)));
            }
        }
    }

    #[test]
    fn matches_proto_unproject_and_projection_matrix() {
        let d = device();
        let rays = DeviceRays::new(&d).unwrap();
        let px = DVec2::new(12.25, 40.75);
        assert!((rays.ray_through(px).unwrap().direction - d.unproject(px)).length() < 1e-14);
        let w = DVec3::new(0.1, 0.3, 0.9);
        let p = d.projection();
        let h: [f64; 3] =
            std::array::from_fn(|r| p[r][0] * w.x + p[r][1] * w.y + p[r][2] * w.z + p[r][3]);
        let expect = DVec2::new(h[0] / h[2], h[1] / h[2]);
        assert!((rays.project(w).unwrap() - expect).length() < 1e-9);
    }

    #[test]
    fn behind_and_outside_points_do_not_project_into_the_image() {
        let rays = DeviceRays::new(&device()).unwrap();
        let c = rays.center();
        let forward = rays.pixel_ray(32, 24).unwrap().direction;
        assert!(rays.project(c - forward).is_none());
        assert!(rays.project(c).is_none());
        assert!(rays.project(DVec3::NAN).is_none());
        assert!(!rays.in_image(DVec2::new(64.0, 1.0)) && !rays.in_image(DVec2::new(-1e-12, 1.0)));
    }

    #[test]
    fn rejects_bad_devices() {
        let mut d = device();
        d.k = DMat3::ZERO;
        assert!(matches!(
            DeviceRays::new(&d),
            Err(DeviceError::SingularIntrinsics { .. })
        ));
        d = device();
        d.translation.x = f64::NAN;
        assert_eq!(DeviceRays::new(&d).unwrap_err(), DeviceError::NonFinite);
        d = device();
        d.width = 0;
        assert!(matches!(
            DeviceRays::new(&d),
            Err(DeviceError::EmptyImage { .. })
        ));
    }
}
