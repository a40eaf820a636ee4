//! What lights the simulated world besides its emitting surfaces: the
//! projectors, and the scene's virtual lights as if they were real lamps
//! (the target of every physically complete figure).
//!
//! - A projector is a point light at its centre with per-pixel radiant
//!   intensity ([`ProjectorLight`]), evaluated exactly.
//! - A point or spot light is a delta light, evaluated exactly with true
//!   visibility; a spot's cone falls off by [`crate::spot`]'s one rule.
//! - An area light is its true parallelogram, one-sided, sampled by
//!   next-event estimation (uniform in area). It lights, but it is no
//!   geometry: no ray sees it or is stopped by it, as no surface of the
//!   scene stands for it.
//! - The scene's ambient irradiance `A` is a uniform environment of
//!   radiance `A / pi` arriving along every ray that leaves the scene, so
//!   an unoccluded surface facing open space receives exactly `A`.

use super::SimError;
use super::world::ProjectorLight;
use crate::finite::finite_or_zero;
use crate::spot::{cone_cosines, spot_falloff};
use crate::{IntensityLight, SceneGeometry};
use glam::{DVec3, Vec3};
use showcase_proto::{Light, LightSource};

/// A point light (its intensity in W/sr per channel, on the axis for a
/// spot), restricted to a cone for a spot.
#[derive(Clone, Debug)]
pub(super) struct DeltaLight {
    light: IntensityLight,
    /// `(unit axis, cos_inner, cos_outer)` of a spot.
    cone: Option<(DVec3, f64, f64)>,
}

impl DeltaLight {
    /// The share of the intensity sent toward point `q`: 1 for a point
    /// light, a spot's cone falloff ([`spot_falloff`]) for a spot.
    fn falloff_toward(&self, q: DVec3) -> f64 {
        self.cone.map_or(1.0, |(axis, ci, co)| {
            let from = (q - self.light.position).normalize_or_zero();
            spot_falloff(axis.dot(from), ci, co)
        })
    }
}

/// A one-sided emitting parallelogram `corner + s edge_u + t edge_v`.
#[derive(Clone, Debug)]
struct AreaLight {
    corner: DVec3,
    edge_u: DVec3,
    edge_v: DVec3,
    /// Unit normal of the emitting side, along `edge_u x edge_v`.
    normal: DVec3,
    area: f64,
    radiance: DVec3,
}

/// The lights of a simulated world (see the module docs).
#[derive(Clone, Debug, Default)]
pub struct SimLights<'a> {
    projectors: Vec<&'a ProjectorLight>,
    deltas: Vec<DeltaLight>,
    areas: Vec<AreaLight>,
    environment: DVec3,
}

impl<'a> SimLights<'a> {
    /// No light (the world's emitting surfaces may still glow).
    pub fn none() -> Self {
        Self::default()
    }

    /// The projectors that show something; dark ones are left out.
    pub fn projectors(projectors: impl IntoIterator<Item = &'a ProjectorLight>) -> Self {
        Self {
            projectors: projectors.into_iter().filter(|p| !p.is_dark()).collect(),
            ..Self::default()
        }
    }

    /// The scene's virtual `lights` and its `ambient` irradiance, as if
    /// they were real (see the module docs). A light that is not finite,
    /// a spot without an axis or an area light without an area is an
    /// error naming it.
    pub fn virtual_lights(lights: &[LightSource], ambient: Vec3) -> Result<Self, SimError> {
        let mut out = Self::default();
        for source in lights {
            let bad = || SimError::BadLight {
                name: source.name.clone(),
            };
            match &source.light {
                Light::Point {
                    position,
                    intensity,
                } => {
                    if !(position.is_finite() && intensity.is_finite()) {
                        return Err(bad());
                    }
                    out.deltas.push(DeltaLight {
                        light: IntensityLight::point(
                            position.as_dvec3(),
                            intensity.as_dvec3().max(DVec3::ZERO),
                        ),
                        cone: None,
                    });
                }
                Light::Spot {
                    position,
                    direction,
                    intensity,
                    inner_deg,
                    outer_deg,
                } => {
                    let axis = direction.as_dvec3().normalize_or_zero();
                    if !(position.is_finite() && intensity.is_finite() && axis != DVec3::ZERO) {
                        return Err(bad());
                    }
                    let (cos_inner, cos_outer) =
                        cone_cosines(f64::from(*inner_deg), f64::from(*outer_deg));
                    out.deltas.push(DeltaLight {
                        light: IntensityLight::point(
                            position.as_dvec3(),
                            intensity.as_dvec3().max(DVec3::ZERO),
                        ),
                        cone: Some((axis, cos_inner, cos_outer)),
                    });
                }
                Light::Area {
                    corner,
                    edge_u,
                    edge_v,
                    radiance,
                    ..
                } => {
                    let (u, v) = (edge_u.as_dvec3(), edge_v.as_dvec3());
                    let cross = u.cross(v);
                    let area = cross.length();
                    if !(corner.is_finite() && radiance.is_finite() && area > 0.0) {
                        return Err(bad());
                    }
                    out.areas.push(AreaLight {
                        corner: corner.as_dvec3(),
                        edge_u: u,
                        edge_v: v,
                        normal: cross / area,
                        area,
                        radiance: radiance.as_dvec3().max(DVec3::ZERO),
                    });
                }
            }
        }
        if !ambient.is_finite() {
            return Err(SimError::BadLight {
                name: "ambient".into(),
            });
        }
        out.environment = ambient.as_dvec3().max(DVec3::ZERO) * std::f64::consts::FRAC_1_PI;
        Ok(out)
    }

    /// Radiance (W/m^2/sr) arriving along a ray that leaves the scene.
    pub fn environment(&self) -> DVec3 {
        self.environment
    }

    /// True when some area light needs sampling.
    pub(super) fn has_areas(&self) -> bool {
        !self.areas.is_empty()
    }

    /// Irradiance (W/m^2) from the projectors and the point and spot
    /// lights at a surface point with the oriented geometric normal
    /// `facing` and shading normal `shading`, exactly, with true
    /// visibility.
    pub(super) fn delta_irradiance(
        &self,
        geometry: &SceneGeometry,
        point: DVec3,
        facing: DVec3,
        shading: DVec3,
    ) -> DVec3 {
        let mut e = DVec3::ZERO;
        for p in &self.projectors {
            e += p.irradiance(geometry, point, facing, shading);
        }
        for d in &self.deltas {
            // A spot's cone first: outside it no shadow ray is cast.
            let falloff = d.falloff_toward(point);
            if falloff > 0.0 {
                e += falloff * d.light.intensity_at(geometry, point, facing, shading);
            }
        }
        finite_or_zero(e)
    }

    /// The projectors and the point and spot lights, as a mirror sees them
    /// ([`super::mirrors`]).
    pub(super) fn delta_sources(&self) -> impl Iterator<Item = DeltaSource<'_>> {
        self.projectors
            .iter()
            .map(|p| DeltaSource::Projector(p))
            .chain(self.deltas.iter().map(DeltaSource::Lamp))
    }

    /// One next-event estimate of the irradiance from every area light at
    /// a surface point: one point on each light, picked by `u` (a point of
    /// the unit square, uniform over the light's area).
    pub(super) fn sample_areas(
        &self,
        geometry: &SceneGeometry,
        point: DVec3,
        facing: DVec3,
        shading: DVec3,
        u: (f64, f64),
    ) -> DVec3 {
        let mut e = DVec3::ZERO;
        for a in &self.areas {
            let y = a.corner + u.0 * a.edge_u + u.1 * a.edge_v;
            let d = y - point;
            let dist2 = d.length_squared();
            if !(dist2 > 0.0) {
                continue;
            }
            let l = d / dist2.sqrt();
            let (cos_x, cos_y) = (shading.dot(l), -a.normal.dot(l));
            if !(cos_x > 0.0 && cos_y > 0.0 && facing.dot(l) > 0.0) {
                continue;
            }
            if !geometry.visible(point, facing, y, false) {
                continue;
            }
            e += a.radiance * (cos_x * cos_y / dist2 * a.area);
        }
        finite_or_zero(e)
    }
}

/// A projector, point or spot light ([`SimLights::delta_sources`]).
pub(super) enum DeltaSource<'b> {
    Projector(&'b ProjectorLight),
    Lamp(&'b DeltaLight),
}

impl DeltaSource<'_> {
    /// Where the light leaves from.
    pub(super) fn position(&self) -> DVec3 {
        match self {
            Self::Projector(p) => p.position(),
            Self::Lamp(d) => d.light.position,
        }
    }

    /// Radiant intensity (W/sr) the source sends to surface point `q`
    /// (unit normal `normal`, on the source's side), with true visibility:
    /// zero outside a spot's cone or a projector's image, or when the
    /// segment is blocked.
    pub(super) fn intensity_toward(
        &self,
        geometry: &SceneGeometry,
        q: DVec3,
        normal: DVec3,
    ) -> DVec3 {
        match self {
            Self::Projector(p) => p.intensity_toward(geometry, q, normal),
            Self::Lamp(d) => {
                let falloff = d.falloff_toward(q);
                if falloff > 0.0 && geometry.visible(q, normal, d.light.position, false) {
                    finite_or_zero(falloff * d.light.color)
                } else {
                    DVec3::ZERO
                }
            }
        }
    }
}
