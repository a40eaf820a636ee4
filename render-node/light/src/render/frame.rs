//! One frame's world: the scene with the frame's object transforms and
//! lights applied, its virtual lights broken into point samples, and the
//! tracked eyes. Shared by every CPU reference and GPU pass of `render`.

use super::RenderSetupError;
use super::indirect::IndirectField;
use crate::finite::finite_or_zero;
use crate::spot::{cone_cosines, spot_falloff};
use crate::{ObjectFilter, SceneGeometry};
use glam::{DVec3, Vec3};
use showcase_proto::{FrameState, Light, Observer, Showcase};
use std::sync::Arc;

/// How a light sample's radiant intensity depends on direction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Lobe {
    /// The same in every direction (a point light).
    Isotropic,
    /// A spot cone around the unit `axis`: full inside `cos_inner`, zero
    /// outside `cos_outer`, smoothstep in between ([`spot_falloff`]).
    Spot {
        /// Unit cone axis.
        axis: DVec3,
        /// Cosine of the inner half-angle.
        cos_inner: f64,
        /// Cosine of the outer half-angle.
        cos_outer: f64,
    },
    /// A Lambertian emitter patch with unit `normal`: `cos` towards the
    /// direction, zero behind it (one sample of an area light).
    Cosine {
        /// Unit emitting side normal.
        normal: DVec3,
    },
}

/// A point sample of a virtual light: the interactive passes (shadow maps
/// and the CPU references alike) see every light as a set of these.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightSample {
    /// Position in world space.
    pub position: DVec3,
    /// Peak radiant intensity (W/sr per channel).
    pub intensity: DVec3,
    /// Directional shape.
    pub lobe: Lobe,
}

impl LightSample {
    /// Radiant intensity (W/sr) leaving towards unit direction `dir`.
    pub fn intensity_towards(&self, dir: DVec3) -> DVec3 {
        let factor = match self.lobe {
            Lobe::Isotropic => 1.0,
            Lobe::Spot {
                axis,
                cos_inner,
                cos_outer,
            } => spot_falloff(axis.dot(dir), cos_inner, cos_outer),
            Lobe::Cosine { normal } => normal.dot(dir).max(0.0),
        };
        let i = self.intensity * factor;
        finite_or_zero(i)
    }
}

/// Break lights into point samples (area lights into a stratified grid
/// of `samples` cells, each carrying its share of the emitter).
pub fn light_samples(
    lights: &[showcase_proto::LightSource],
) -> Result<Vec<LightSample>, RenderSetupError> {
    let mut out = Vec::new();
    for source in lights {
        let bad = || RenderSetupError::BadLight {
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
                out.push(LightSample {
                    position: position.as_dvec3(),
                    intensity: intensity.as_dvec3(),
                    lobe: Lobe::Isotropic,
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
                let finite = position.is_finite()
                    && intensity.is_finite()
                    && inner_deg.is_finite()
                    && outer_deg.is_finite();
                if !finite || axis == DVec3::ZERO {
                    return Err(bad());
                }
                let (cos_inner, cos_outer) =
                    cone_cosines(f64::from(*inner_deg), f64::from(*outer_deg));
                out.push(LightSample {
                    position: position.as_dvec3(),
                    intensity: intensity.as_dvec3(),
                    lobe: Lobe::Spot {
                        axis,
                        cos_inner,
                        cos_outer,
                    },
                });
            }
            Light::Area {
                corner,
                edge_u,
                edge_v,
                radiance,
                samples,
            } => {
                let (c, u, v) = (corner.as_dvec3(), edge_u.as_dvec3(), edge_v.as_dvec3());
                let cross = u.cross(v);
                let area = cross.length();
                if !(c.is_finite() && cross.is_finite() && radiance.is_finite() && area > 0.0) {
                    return Err(bad());
                }
                let normal = cross / area;
                let n = (*samples).clamp(1, 64);
                let nu = (f64::from(n).sqrt().ceil() as u32).max(1);
                let nv = n.div_ceil(nu);
                let share = radiance.as_dvec3() * (area / f64::from(n));
                for i in 0..n {
                    let s = (f64::from(i % nu) + 0.5) / f64::from(nu);
                    let t = (f64::from(i / nu) + 0.5) / f64::from(nv);
                    out.push(LightSample {
                        position: c + s * u + t * v,
                        intensity: share,
                        lobe: Lobe::Cosine { normal },
                    });
                }
            }
        }
    }
    Ok(out)
}

/// The scene as this frame sees it.
#[derive(Clone, Debug)]
pub struct FrameScene {
    /// The showcase with the frame's object transforms and lights applied.
    pub showcase: Showcase,
    /// Every light as point samples.
    pub samples: Vec<LightSample>,
    /// Eye positions of every tracked head (two per head).
    pub eyes: Vec<DVec3>,
    /// The global-illumination field the displays add to the direct
    /// target (the projectors on real surfaces, the faces on what they
    /// shade) (`illumination = "global"`); `None`: direct light
    /// only.
    pub indirect: Option<Arc<IndirectField>>,
}

impl FrameScene {
    /// Apply `frame` to `scene`: its transforms replace the objects'
    /// transforms, its lights replace the scene's lights, and its heads
    /// give the eyes (with the observers' IPDs, [`Observer::DEFAULT_IPD`] beyond them).
    pub fn resolve(scene: &Showcase, frame: &FrameState) -> Result<Self, RenderSetupError> {
        let mut showcase = scene.clone();
        for t in &frame.object_transforms {
            let count = showcase.objects.len();
            let object = showcase.objects.get_mut(t.object as usize).ok_or(
                RenderSetupError::ObjectOutOfRange {
                    object: t.object,
                    count,
                },
            )?;
            object.transform = t.transform;
        }
        showcase.lights = frame.lights.clone();
        Self::from_parts(showcase, &eyes_of(frame, scene))
    }

    /// A frame of `showcase` as it is (its own lights), seen by `eyes`.
    pub fn from_parts(showcase: Showcase, eyes: &[DVec3]) -> Result<Self, RenderSetupError> {
        if !eyes.iter().all(|e| e.is_finite()) || !showcase.ambient.is_finite() {
            return Err(RenderSetupError::NonFinite);
        }
        Ok(Self {
            samples: light_samples(&showcase.lights)?,
            eyes: eyes.to_vec(),
            showcase,
            indirect: None,
        })
    }

    /// This frame with the global-illumination field.
    pub fn with_indirect(self, indirect: Arc<IndirectField>) -> Self {
        Self {
            indirect: Some(indirect),
            ..self
        }
    }

    /// Ambient irradiance (W/m^2 per channel), negative parts cut to 0.
    pub fn ambient(&self) -> DVec3 {
        self.showcase.ambient.max(Vec3::ZERO).as_dvec3()
    }

    /// Ray-casting geometry of the objects passing `filter`.
    pub fn geometry(&self, filter: &ObjectFilter) -> Result<SceneGeometry, RenderSetupError> {
        Ok(SceneGeometry::build(&self.showcase, filter)?)
    }
}

/// Eye positions of a frame's heads, two per head.
fn eyes_of(frame: &FrameState, scene: &Showcase) -> Vec<DVec3> {
    frame
        .heads
        .iter()
        .enumerate()
        .flat_map(|(i, head)| {
            let ipd = scene
                .observers
                .get(i)
                .map_or(Observer::DEFAULT_IPD, |o| o.ipd);
            Observer::eyes(head, ipd).map(|e| e.as_dvec3())
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use showcase_proto::LightSource;

    #[test]
    fn area_samples_carry_the_emitters_intensity() {
        // A 0.5 x 0.2 m patch of radiance 2: I(normal) = L A = 0.2 W/sr.
        let light = LightSource {
            name: "a".into(),
            light: Light::Area {
                corner: Vec3::ZERO,
                edge_u: Vec3::new(0.5, 0.0, 0.0),
                edge_v: Vec3::new(0.0, 0.0, 0.2),
                radiance: Vec3::splat(2.0),
                samples: 5,
            },
        };
        let s = light_samples(&[light]).unwrap();
        assert_eq!(s.len(), 5);
        let normal = DVec3::new(0.0, -1.0, 0.0); // x cross z = -y
        let total: DVec3 = s.iter().map(|x| x.intensity_towards(normal)).sum();
        assert!((total - DVec3::splat(0.2)).length() < 1e-6, "{total}");
        let behind: DVec3 = s.iter().map(|x| x.intensity_towards(-normal)).sum();
        assert_eq!(behind, DVec3::ZERO);
        assert!(s.iter().all(|x| x.position.x > 0.0 && x.position.x < 0.5));
    }

    #[test]
    fn bad_lights_are_errors() {
        let spot = LightSource {
            name: "s".into(),
            light: Light::Spot {
                position: Vec3::ZERO,
                direction: Vec3::ZERO,
                intensity: Vec3::ONE,
                inner_deg: 10.0,
                outer_deg: 20.0,
            },
        };
        assert!(matches!(
            light_samples(&[spot]),
            Err(RenderSetupError::BadLight { .. })
        ));
    }
}
