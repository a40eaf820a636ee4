//! Real reflectance from the captured maps (paper 3.6): a real object
//! whose material names a reflectance map (`reflectance_map = "NAME"`)
//! takes each element's reflectance from the map of that name the cluster
//! holds, where the map saw the element; elsewhere, and for every other
//! object, the scene's albedo stays.

use crate::capture::cluster::reflectance_map;
use anyhow::Context;
use showcase_light::radiosity::RadiosityMesh;
use showcase_light::radiosity::mesh::MAX_REFLECTANCE;
use showcase_light::world_matrix;
use showcase_proto::capture::CapturedMap;
use showcase_proto::{ObjectKind, Showcase};

/// An element is sampled in the map at the centroids of the upward
/// triangles of its corners' `SPLIT x SPLIT` subdivision (10 points), so
/// it takes the map's mean over its area, not the value at one point.
const SPLIT: usize = 4;

/// The sample points of the triangle `v`.
fn samples(v: &[glam::DVec3; 3]) -> impl Iterator<Item = glam::DVec3> + '_ {
    (0..SPLIT).flat_map(move |i| {
        (0..SPLIT - i).map(move |j| {
            let s = (i as f64 + 1.0 / 3.0) / SPLIT as f64;
            let t = (j as f64 + 1.0 / 3.0) / SPLIT as f64;
            (1.0 - s - t) * v[0] + s * v[1] + t * v[2]
        })
    })
}

/// Replace the reflectance of `mesh`'s real elements whose object names
/// one of `maps` by what that map measured there (the element's samples
/// carried back to the capture pose through the object's transforms then
/// and now). Returns how many elements took it. A named map the cluster
/// does not hold is no error: the object keeps its albedo until one
/// arrives.
pub fn take_captured_reflectance(
    mesh: &mut RadiosityMesh,
    showcase: &Showcase,
    maps: &[CapturedMap],
) -> anyhow::Result<usize> {
    let mut per_object = Vec::with_capacity(showcase.objects.len());
    for (i, o) in showcase.objects.iter().enumerate() {
        let named = match (&o.kind, &o.material.reflectance_map) {
            (ObjectKind::Real, Some(name)) => maps.iter().find(|m| &m.name == name),
            _ => None,
        };
        let Some(captured) = named else {
            per_object.push(None);
            continue;
        };
        let map = reflectance_map(captured)?;
        let now = world_matrix(&o.transform)
            .with_context(|| format!("object {i} has a transform that is not invertible"))?;
        per_object.push(Some((map, now.inverse())));
    }
    let mut taken = 0;
    for e in &mut mesh.elements {
        let Some(Some((map, world_to_local))) = per_object.get(e.object as usize) else {
            continue;
        };
        if !e.real {
            continue;
        }
        let local: Vec<_> = samples(&e.vertices)
            .map(|p| world_to_local.transform_point3(p))
            .collect();
        if let Some(rho) = map.reflectance_at(e.object, &local) {
            e.reflectance = rho.clamp(glam::DVec3::ZERO, glam::DVec3::splat(MAX_REFLECTANCE));
            taken += 1;
        }
    }
    Ok(taken)
}
