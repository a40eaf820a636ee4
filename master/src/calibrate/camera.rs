//! The pinhole model being fitted: intrinsics, two radial distortion terms
//! and a pose, with its projection and the analytic Jacobian of a pixel.

use nalgebra::{Matrix3, Rotation3, Vector2, Vector3};

/// One fiducial: its world position (metres) and its marked pixel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Observation {
    /// World position in metres.
    pub(crate) world: Vector3<f64>,
    /// Marked pixel (OpenCV convention, origin top-left).
    pub(crate) pixel: Vector2<f64>,
}

/// A pinhole device with OpenCV radial distortion `k1`, `k2`:
/// `x_cam = R X + t`, `(x, y) = x_cam.xy / z`, `d = 1 + k1 r^2 + k2 r^4`,
/// `u = fx x d + skew y d + cx`, `v = fy y d + cy`.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct CameraModel {
    pub(crate) fx: f64,
    pub(crate) fy: f64,
    pub(crate) cx: f64,
    pub(crate) cy: f64,
    pub(crate) skew: f64,
    pub(crate) k1: f64,
    pub(crate) k2: f64,
    pub(crate) rotation: Matrix3<f64>,
    pub(crate) translation: Vector3<f64>,
}

/// Which parameters a refinement may change. The pose (rotation vector
/// increment and translation) is always free.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Layout {
    /// fx, fy, cx, cy are free.
    pub(crate) intrinsics: bool,
    /// The skew is free (only with `intrinsics`).
    pub(crate) skew: bool,
    /// k1 and k2 are free (only with `intrinsics`).
    pub(crate) distortion: bool,
}

impl Layout {
    /// Number of free parameters.
    pub(crate) fn len(&self) -> usize {
        6 + 4 * usize::from(self.intrinsics)
            + usize::from(self.intrinsics && self.skew)
            + 2 * usize::from(self.intrinsics && self.distortion)
    }
}

impl CameraModel {
    /// Intrinsics from an upper-triangular `K` with `K[2][2] = 1`.
    pub(crate) fn from_k(
        k: &Matrix3<f64>,
        rotation: Matrix3<f64>,
        translation: Vector3<f64>,
    ) -> Self {
        Self {
            fx: k[(0, 0)],
            fy: k[(1, 1)],
            cx: k[(0, 2)],
            cy: k[(1, 2)],
            skew: k[(0, 1)],
            k1: 0.0,
            k2: 0.0,
            rotation,
            translation,
        }
    }

    /// The intrinsic matrix K.
    pub(crate) fn k(&self) -> Matrix3<f64> {
        Matrix3::new(
            self.fx, self.skew, self.cx, 0.0, self.fy, self.cy, 0.0, 0.0, 1.0,
        )
    }

    /// Device-space position `R X + t`.
    pub(crate) fn to_device(&self, world: &Vector3<f64>) -> Vector3<f64> {
        self.rotation * world + self.translation
    }

    /// Pixel of a world point; `None` when it is not in front of the device.
    pub(crate) fn project(&self, world: &Vector3<f64>) -> Option<Vector2<f64>> {
        let c = self.to_device(world);
        if c.z <= 0.0 {
            return None;
        }
        Some(self.distort_to_pixel(c.x / c.z, c.y / c.z))
    }

    fn distort_to_pixel(&self, x: f64, y: f64) -> Vector2<f64> {
        let r2 = x * x + y * y;
        let d = 1.0 + self.k1 * r2 + self.k2 * r2 * r2;
        let (xd, yd) = (x * d, y * d);
        Vector2::new(
            self.fx * xd + self.skew * yd + self.cx,
            self.fy * yd + self.cy,
        )
    }

    /// Sum of squared pixel residuals over `obs`; `None` when a point is
    /// not in front of the device (the step that led here is rejected).
    pub(crate) fn cost(&self, obs: &[Observation]) -> Option<f64> {
        let mut sum = 0.0;
        for o in obs {
            sum += (self.project(&o.world)? - o.pixel).norm_squared();
        }
        sum.is_finite().then_some(sum)
    }

    /// Per-point pixel distances; a point behind the device counts as
    /// infinitely far (callers reject such solutions before reporting).
    pub(crate) fn residuals(&self, obs: &[Observation]) -> Vec<f64> {
        obs.iter()
            .map(|o| match self.project(&o.world) {
                Some(p) => (p - o.pixel).norm(),
                None => f64::INFINITY,
            })
            .collect()
    }

    /// Pixel of `world` and its 2 x `layout.len()` Jacobian, rows `u`, `v`,
    /// columns in the order of [`Self::apply`]. `None` behind the device.
    pub(crate) fn project_with_jacobian(
        &self,
        world: &Vector3<f64>,
        layout: Layout,
        jac: &mut [[f64; 2]],
    ) -> Option<Vector2<f64>> {
        let rx = self.rotation * world;
        let c = rx + self.translation;
        if c.z <= 0.0 {
            return None;
        }
        let iz = 1.0 / c.z;
        let (x, y) = (c.x * iz, c.y * iz);
        let r2 = x * x + y * y;
        let distorted = self.k1 != 0.0 || self.k2 != 0.0;
        // d(u, v) / d(x, y), and the distorted (xd, yd).
        let (b, xd, yd) = if distorted {
            let d = 1.0 + self.k1 * r2 + self.k2 * r2 * r2;
            let dd = self.k1 + 2.0 * self.k2 * r2;
            // d(xd, yd) / d(x, y)
            let (a11, a12) = (d + 2.0 * x * x * dd, 2.0 * x * y * dd);
            let (a21, a22) = (2.0 * x * y * dd, d + 2.0 * y * y * dd);
            let b = [
                [
                    self.fx * a11 + self.skew * a21,
                    self.fx * a12 + self.skew * a22,
                ],
                [self.fy * a21, self.fy * a22],
            ];
            (b, x * d, y * d)
        } else {
            // The same with d = 1, dd = 0 (the pose-only hot path).
            ([[self.fx, self.skew], [0.0, self.fy]], x, y)
        };
        // d(x, y) / d(x_cam) = [[1/z, 0, -x/z], [0, 1/z, -y/z]]
        let g: [[f64; 3]; 2] = std::array::from_fn(|r| {
            [
                b[r][0] * iz,
                b[r][1] * iz,
                -(b[r][0] * x + b[r][1] * y) * iz,
            ]
        });
        // d(x_cam) / d(omega) = -[R X]_x for the update R <- exp(omega) R,
        // so the row g of d(u, v) / d(x_cam) becomes -g [R X]_x = (R X) x g.
        let [gu, gv] = g.map(Vector3::from);
        let (du, dv) = (rx.cross(&gu), rx.cross(&gv));
        for k in 0..3 {
            jac[k] = [du[k], dv[k]];
            jac[3 + k] = [g[0][k], g[1][k]];
        }
        if layout.intrinsics {
            jac[6] = [xd, 0.0];
            jac[7] = [0.0, yd];
            jac[8] = [1.0, 0.0];
            jac[9] = [0.0, 1.0];
            let mut i = 10;
            if layout.skew {
                jac[i] = [yd, 0.0];
                i += 1;
            }
            if layout.distortion {
                let (pu, pv) = (self.fx * x + self.skew * y, self.fy * y);
                jac[i] = [pu * r2, pv * r2];
                jac[i + 1] = [pu * r2 * r2, pv * r2 * r2];
            }
        }
        Some(Vector2::new(
            self.fx * xd + self.skew * yd + self.cx,
            self.fy * yd + self.cy,
        ))
    }

    /// The model moved by `delta` (`layout.len()` entries): rotation vector
    /// increment (applied on the left), translation, then fx, fy, cx, cy,
    /// skew and k1, k2 where free.
    pub(crate) fn apply(&self, delta: &[f64], layout: Layout) -> Self {
        let omega = Vector3::new(delta[0], delta[1], delta[2]);
        let mut m = self.clone();
        m.rotation = Rotation3::new(omega).matrix() * self.rotation;
        m.translation += Vector3::new(delta[3], delta[4], delta[5]);
        if layout.intrinsics {
            m.fx += delta[6];
            m.fy += delta[7];
            m.cx += delta[8];
            m.cy += delta[9];
            let mut i = 10;
            if layout.skew {
                m.skew += delta[i];
                i += 1;
            }
            if layout.distortion {
                m.k1 += delta[i];
                m.k2 += delta[i + 1];
            }
        }
        m
    }

    /// All parameters finite.
    pub(crate) fn is_finite(&self) -> bool {
        [
            self.fx, self.fy, self.cx, self.cy, self.skew, self.k1, self.k2,
        ]
        .iter()
        .chain(self.rotation.iter())
        .chain(self.translation.iter())
        .all(|v| v.is_finite())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn model() -> CameraModel {
        CameraModel {
            fx: 900.0,
            fy: 910.0,
            cx: 500.0,
            cy: 700.0,
            skew: 2.0,
            k1: -0.1,
            k2: 0.03,
            rotation: Rotation3::new(Vector3::new(0.3, -0.5, 0.2)).into_inner(),
            translation: Vector3::new(0.1, -0.2, 1.2),
        }
    }

    #[test]
    fn analytic_jacobian_matches_central_differences() {
        let layout = Layout {
            intrinsics: true,
            skew: true,
            distortion: true,
        };
        // With distortion, and without (its own branch).
        let undistorted = CameraModel {
            k1: 0.0,
            k2: 0.0,
            ..model()
        };
        for m in [model(), undistorted] {
            jacobian_matches_central_differences(&m, layout);
        }
    }

    fn jacobian_matches_central_differences(m: &CameraModel, layout: Layout) {
        let x = Vector3::new(0.1, 0.05, -0.2);
        let mut jac = vec![[0.0; 2]; layout.len()];
        m.project_with_jacobian(&x, layout, &mut jac).unwrap();
        for (k, col) in jac.iter().enumerate() {
            let h = if k >= 11 { 1e-7 } else { 1e-6 };
            let mut d = vec![0.0; layout.len()];
            d[k] = h;
            let plus = m.apply(&d, layout).project(&x).unwrap();
            d[k] = -h;
            let minus = m.apply(&d, layout).project(&x).unwrap();
            let numeric = (plus - minus) / (2.0 * h);
            for r in 0..2 {
                let tol = 1e-5 * (1.0 + numeric[r].abs());
                assert!(
                    (numeric[r] - col[r]).abs() < tol,
                    "param {k} row {r}: analytic {} numeric {}",
                    col[r],
                    numeric[r]
                );
            }
        }
    }

    #[test]
    fn behind_the_device_projects_to_none() {
        let m = model();
        let behind = m.rotation.transpose() * (Vector3::new(0.0, 0.0, -1.0) - m.translation);
        assert!(m.project(&behind).is_none());
        assert!(
            m.cost(&[Observation {
                world: behind,
                pixel: Vector2::zeros()
            }])
            .is_none()
        );
    }
}
