//! Virtual light sources (`showcase_proto::Light`) as direct irradiance at
//! surface points, with visibility: the first shot of a radiosity solve.
//! Lights are not geometry: they neither occlude nor receive.

use crate::finite::finite_or_zero;
use crate::sampling::stratified;
use crate::spot::{cone_cosines, spot_falloff};
use crate::{Occluders, form_factor_point_polygon};
use glam::DVec3;
use showcase_proto::Light;
use std::f64::consts::PI;

/// Direct irradiance (W/m^2 per channel) from `light` at surface point
/// `point` with unit normal `normal` (the front side), with visibility in
/// `geometry`. Area lights use the closed-form polygon form factor times the
/// visible fraction of `samples` stratified points (seeded by `seed`).
/// Returns zero for bad input.
pub fn direct_irradiance<G: Occluders + ?Sized>(
    light: &Light,
    geometry: &G,
    point: DVec3,
    normal: DVec3,
    samples: u32,
    seed: u64,
) -> DVec3 {
    let e = match light {
        Light::Point {
            position,
            intensity,
        } => {
            point_irradiance(geometry, point, normal, position.as_dvec3(), 1.0)
                * intensity.as_dvec3()
        }
        Light::Spot {
            position,
            direction,
            intensity,
            inner_deg,
            outer_deg,
        } => {
            let p = position.as_dvec3();
            let axis = direction.as_dvec3().normalize_or_zero();
            let to_point = (point - p).normalize_or_zero();
            let (cos_inner, cos_outer) = cone_cosines(f64::from(*inner_deg), f64::from(*outer_deg));
            let falloff = spot_falloff(axis.dot(to_point), cos_inner, cos_outer);
            if falloff > 0.0 {
                point_irradiance(geometry, point, normal, p, falloff) * intensity.as_dvec3()
            } else {
                DVec3::ZERO
            }
        }
        Light::Area {
            corner,
            edge_u,
            edge_v,
            radiance,
            ..
        } => {
            let (c, u, v) = (corner.as_dvec3(), edge_u.as_dvec3(), edge_v.as_dvec3());
            let polygon = [c, c + u, c + u + v, c + v];
            let f = form_factor_point_polygon(point, normal, &polygon).unwrap_or(0.0);
            if f > 0.0 {
                let pts = stratified(samples, seed);
                let seen = pts
                    .iter()
                    .filter(|s| geometry.visible(point, normal, c + s.x * u + s.y * v, false))
                    .count();
                PI * f * seen as f64 / pts.len() as f64 * radiance.as_dvec3()
            } else {
                DVec3::ZERO
            }
        }
    };
    finite_or_zero(e).max(DVec3::ZERO)
}

/// `scale * cos(theta) / r^2` towards a point light at `light`, if visible.
fn point_irradiance<G: Occluders + ?Sized>(
    geometry: &G,
    point: DVec3,
    normal: DVec3,
    light: DVec3,
    scale: f64,
) -> f64 {
    let d = light - point;
    let r2 = d.length_squared();
    let cos = normal.dot(d) / r2.sqrt();
    if !(r2 > 0.0 && cos > 0.0 && geometry.visible(point, normal, light, false)) {
        return 0.0;
    }
    scale * cos / r2
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{ObjectFilter, SceneGeometry};
    use glam::Vec3;
    use showcase_proto::Showcase;

    #[test]
    fn point_and_area_lights_match_inverse_square_and_lambert() {
        let g = SceneGeometry::build(&Showcase::default(), &ObjectFilter::All).unwrap();
        let point = Light::Point {
            position: Vec3::new(0.0, 2.0, 0.0),
            intensity: Vec3::new(4.0, 8.0, 0.0),
        };
        let n = DVec3::new(0.6, 0.8, 0.0);
        let e = direct_irradiance(&point, &g, DVec3::ZERO, n, 1, 0);
        assert!(
            (e - DVec3::new(4.0, 8.0, 0.0) * 0.8 / 4.0)
                .abs()
                .max_element()
                < 1e-12
        );
        // Behind the surface: nothing.
        assert_eq!(
            direct_irradiance(&point, &g, DVec3::ZERO, -n, 1, 0),
            DVec3::ZERO
        );
        // A huge area light approaches pi * L.
        let area = Light::Area {
            corner: Vec3::new(-1e4, 1.0, -1e4),
            edge_u: Vec3::new(2e4, 0.0, 0.0),
            edge_v: Vec3::new(0.0, 0.0, 2e4),
            radiance: Vec3::splat(2.0),
            samples: 4,
        };
        let e = direct_irradiance(&area, &g, DVec3::ZERO, DVec3::Y, 4, 1);
        assert!((e.x - 2.0 * PI).abs() < 1e-3, "{e}");
    }

    #[test]
    fn stratified_samples_stay_in_the_unit_square() {
        for count in [1, 2, 5, 16] {
            let s = stratified(count, 7);
            assert_eq!(s.len(), count as usize);
            assert!(
                s.iter()
                    .all(|p| (0.0..1.0).contains(&p.x) && (0.0..1.0).contains(&p.y))
            );
        }
    }
}
