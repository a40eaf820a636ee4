//! One scene's global-illumination field as the live cluster keeps it
//! ([`showcase_light::radiosity::live::LiveCorrection`]): what is made once
//! per scene (the mesh, the real occluders, each virtual object's own,
//! which real elements a projector reaches), and how a frame's state is
//! turned into an update (the virtual objects' places and the lights) and
//! a field (the elements the eyes' occlusion shadows leave dark).

use super::{RadiosityOptions, check_solvable, memory_check};
use anyhow::Context;
use glam::{DAffine3, DVec3};
use rayon::prelude::*;
use showcase_light::radiosity::live::{LiveCorrection, LiveUpdate};
use showcase_light::radiosity::{self, RadiosityMesh};
use showcase_light::render::IndirectLight;
use showcase_light::{ObjectFilter, SceneGeometry, world_matrix};
use showcase_proto::capture::CapturedMap;
use showcase_proto::{ObjectKind, Showcase, Transform};

/// What a live solution of one scene is made over.
pub struct LiveScene {
    mesh: RadiosityMesh,
    /// The real objects' occluders: the static ones.
    real: SceneGeometry,
    /// Each virtual object's index, occluders alone and world transform.
    movers: Vec<(u32, SceneGeometry, DAffine3)>,
    /// The real objects' transforms: when one changes, solve afresh.
    real_places: Vec<(usize, Transform)>,
    /// Per element: a projector reaches it.
    reach: Vec<bool>,
    options: radiosity::HierarchyOptions,
    /// Real elements whose reflectance came from a captured map.
    captured: usize,
}

/// A frame's state the live solution cannot follow.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum Afresh {
    /// A real object moved.
    #[error("real object {0} moved")]
    RealMoved(usize),
    /// The objects are not the scene's.
    #[error("the scene has {got} objects, the solution {expected}")]
    Objects {
        /// The solution's.
        expected: usize,
        /// The state's.
        got: usize,
    },
    /// An object's transform is not finite or not invertible.
    #[error("object {0} has a transform that is not a rigid move")]
    BadTransform(usize),
}

impl LiveScene {
    /// Mesh `showcase` (as it stands) with `options`' hierarchical mesh,
    /// with its virtual objects as movers, and the real reflectance from
    /// the captured `maps` where the scene names them
    /// ([`super::captured::take_captured_reflectance`]).
    pub fn new(
        showcase: &Showcase,
        maps: &[CapturedMap],
        options: &RadiosityOptions,
    ) -> anyhow::Result<Self> {
        let options = &options.for_scene(showcase);
        let all =
            SceneGeometry::build(showcase, &ObjectFilter::All).context("building geometry")?;
        let real =
            SceneGeometry::build(showcase, &ObjectFilter::Real).context("building geometry")?;
        let mut mesh = RadiosityMesh::build(showcase, &all, &options.hierarchical_mesh())
            .context("meshing")?;
        drop(all);
        let captured = super::captured::take_captured_reflectance(&mut mesh, showcase, maps)
            .context("taking the real reflectance from the captured maps")?;
        let lights: Vec<_> = showcase.lights.iter().map(|l| l.light.clone()).collect();
        check_solvable(&mesh, &lights)?;
        let mut options = options.clone();
        options.max_links = memory_check(mesh.elements.len(), &options)?;
        let mut movers = Vec::new();
        let mut real_places = Vec::new();
        for (i, o) in showcase.objects.iter().enumerate() {
            if o.kind == ObjectKind::Virtual {
                let own = SceneGeometry::build(showcase, &ObjectFilter::Indices(vec![i]))
                    .context("building geometry")?;
                movers.push((i as u32, own, place(&o.transform, i)?));
            } else {
                real_places.push((i, o.transform));
            }
        }
        let projectors: Vec<showcase_light::DeviceRays> = showcase
            .projectors
            .iter()
            .map(|p| showcase_light::DeviceRays::new(&p.device))
            .collect::<Result<_, _>>()?;
        let reach = radiosity::augmented::projector_reach(&mesh, &real, &projectors);
        Ok(Self {
            mesh,
            real,
            movers,
            real_places,
            reach,
            options: options.hierarchy(),
            captured,
        })
    }

    /// How many real elements took their reflectance from a captured map.
    pub fn captured_elements(&self) -> usize {
        self.captured
    }

    /// The mesh the solution is made over (its elements' reflectance as
    /// solved).
    pub fn mesh(&self) -> &RadiosityMesh {
        &self.mesh
    }

    /// The live solution under `showcase`'s lights (the state this scene
    /// was made for).
    pub fn start(&self, showcase: &Showcase) -> anyhow::Result<LiveCorrection<'_>> {
        let lights: Vec<_> = showcase.lights.iter().map(|l| l.light.clone()).collect();
        let movers = self
            .movers
            .iter()
            .map(|(o, g, p)| (*o, g.clone(), *p))
            .collect();
        LiveCorrection::new(
            &self.mesh,
            &self.real,
            movers,
            &self.real,
            &lights,
            &self.options,
        )
        .context("solving the global-illumination correction")
    }

    /// Where `showcase`'s virtual objects are, for
    /// [`LiveCorrection::update`]; an error when the live solution cannot
    /// follow it (a real object moved).
    pub fn places(&self, showcase: &Showcase) -> Result<Vec<(u32, DAffine3)>, Afresh> {
        let objects = &showcase.objects;
        let expected = self.movers.len() + self.real_places.len();
        if objects.len() != expected {
            return Err(Afresh::Objects {
                expected,
                got: objects.len(),
            });
        }
        if let Some((i, _)) = self
            .real_places
            .iter()
            .find(|(i, t)| objects[*i].transform != *t)
        {
            return Err(Afresh::RealMoved(*i));
        }
        self.movers
            .iter()
            .map(|(o, _, _)| {
                let i = *o as usize;
                Ok((
                    *o,
                    place(&objects[i].transform, i).map_err(|_| Afresh::BadTransform(i))?,
                ))
            })
            .collect()
    }

    /// The field of `live` seen by `eyes`, with `showcase`'s virtual
    /// objects where they are: the real elements no projector reaches or
    /// in an eye's occlusion shadow are left dark.
    pub fn field(
        &self,
        live: &LiveCorrection<'_>,
        showcase: &Showcase,
        eyes: &[DVec3],
    ) -> anyhow::Result<Vec<IndirectLight>> {
        let mesh = live.mesh().context("the live solution is gone")?;
        let virtual_only =
            SceneGeometry::build(showcase, &ObjectFilter::Virtual).context("building geometry")?;
        let lit: Vec<bool> = mesh
            .elements
            .par_iter()
            .zip(&self.reach)
            .map(|(e, r)| {
                *r && !showcase_light::render::projector::in_occlusion_shadow(
                    &virtual_only,
                    eyes,
                    e.center,
                    e.normal,
                )
            })
            .collect();
        Ok(live.correction(Some(&lit))?)
    }
}

/// A live solution that follows one scene's states as the cluster's solver
/// does: made once for the scene, each later state an update of it (the
/// virtual objects' places and the lights).
pub struct Following<'s> {
    scene: &'s LiveScene,
    live: LiveCorrection<'s>,
}

impl<'s> Following<'s> {
    /// The solution of `scene` under `showcase`'s lights (the state the
    /// scene was made for).
    pub fn start(scene: &'s LiveScene, showcase: &Showcase) -> anyhow::Result<Self> {
        Ok(Self {
            scene,
            live: scene.start(showcase)?,
        })
    }

    /// Follow `showcase`, a later state of the scene; the outer error when
    /// the update failed (the solution is then gone), the inner one when
    /// the solution cannot follow the state (solve it afresh).
    pub fn update(&mut self, showcase: &Showcase) -> anyhow::Result<Result<LiveUpdate, Afresh>> {
        let places = match self.scene.places(showcase) {
            Ok(p) => p,
            Err(afresh) => return Ok(Err(afresh)),
        };
        let lights: Vec<_> = showcase.lights.iter().map(|l| l.light.clone()).collect();
        Ok(Ok(self.live.update(&lights, &places)?))
    }

    /// The field seen by `eyes` with `showcase`'s virtual objects where
    /// they are ([`LiveScene::field`]).
    pub fn field(&self, showcase: &Showcase, eyes: &[DVec3]) -> anyhow::Result<Vec<IndirectLight>> {
        self.scene.field(&self.live, showcase, eyes)
    }

    /// The mesh, with the virtual objects where the last update put them.
    pub fn mesh(&self) -> anyhow::Result<&RadiosityMesh> {
        self.live.mesh().context("the live solution is gone")
    }
}

/// An object's world transform as an affine map.
fn place(transform: &Transform, index: usize) -> anyhow::Result<DAffine3> {
    let m = world_matrix(transform)
        .with_context(|| format!("object {index} has a transform that is not invertible"))?;
    Ok(DAffine3::from_mat4(m))
}
