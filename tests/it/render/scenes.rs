//! Test scenes: the bench scene from the shared Cornell box and bunny
//! OBJ files, and small hand-built scenes with analytic answers.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use glam::{DVec3, Vec3};
use showcase_proto::{
    Light, LightSource, Material, Mesh, Object, ObjectKind, PinholeDevice, Projector,
    ProjectorResponse, Showcase, Transform,
};
use showcase_render::render::bench::bench_scene;

/// `../shared/data/<name>` from the workspace root.
pub(crate) fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../shared/data")
        .join(name)
}

/// Every model of an OBJ: name, mesh and diffuse albedo (grey 0.8 where
/// it has none). Shared with the GPU bring-up tests.
pub(crate) fn load_obj(path: &Path) -> Result<Vec<(String, Mesh, Vec3)>> {
    let (models, materials) = tobj::load_obj(path, &tobj::GPU_LOAD_OPTIONS)
        .with_context(|| format!("loading {}", path.display()))?;
    let materials = materials.unwrap_or_default();
    Ok(models
        .into_iter()
        .map(|m| {
            let positions = m
                .mesh
                .positions
                .chunks_exact(3)
                .map(|p| Vec3::new(p[0], p[1], p[2]))
                .collect();
            let triangles = m
                .mesh
                .indices
                .chunks_exact(3)
                .map(|t| [t[0], t[1], t[2]])
                .collect();
            let albedo = m
                .mesh
                .material_id
                .and_then(|i| materials.get(i))
                .and_then(|mat| mat.diffuse)
                .map_or(Vec3::splat(0.8), Vec3::from_array);
            (
                m.name,
                Mesh {
                    positions,
                    triangles,
                    ..Mesh::default()
                },
                albedo,
            )
        })
        .collect())
}

/// The render bench's scene: Cornell walls (no blocks, no light quad) as
/// the real room, the real bunny, a virtual sphere and bunny, two observers.
pub(super) fn bench() -> Result<Showcase> {
    let walls = load_obj(&data("cornell-box.obj"))?
        .into_iter()
        .filter(|(name, _, _)| {
            ["floor", "ceiling", "back", "right_green", "left_red"].contains(&name.as_str())
        })
        .collect::<Vec<_>>();
    anyhow::ensure!(
        walls.len() == 5,
        "expected five Cornell walls, got {}",
        walls.len()
    );
    let bunny = load_obj(&data("bunny.obj"))?
        .into_iter()
        .next()
        .context("bunny.obj has no model")?
        .1;
    Ok(bench_scene(walls, bunny))
}

/// A unit-ish square plate `[0, size]^2` on `y = 0`, facing up.
pub(super) fn plate_mesh(size: f32) -> Mesh {
    Mesh {
        positions: vec![
            Vec3::ZERO,
            Vec3::new(0.0, 0.0, size),
            Vec3::new(size, 0.0, size),
            Vec3::new(size, 0.0, 0.0),
        ],
        triangles: vec![[0, 1, 2], [0, 2, 3]],
        ..Mesh::default()
    }
}

/// A projector looking down at the plate from `eye`.
pub(super) fn projector_at(eye: DVec3, target: DVec3, width: u32, height: u32) -> Projector {
    let mut device = PinholeDevice::look_at(eye, target, DVec3::Z, 60.0, width, height);
    device.near = 0.01;
    device.far = 10.0;
    Projector {
        name: "p".into(),
        device,
        response: ProjectorResponse {
            gamma: 2.2,
            eta: 4.0,
            black_level: 0.0,
            ..ProjectorResponse::default()
        },
    }
}

/// A real plate of 1 m lit by `lights`, seen by a projector 1.5 m above.
pub(super) fn plate_scene(lights: Vec<LightSource>) -> Showcase {
    let mut s = Showcase::default();
    let id = s.add_mesh(plate_mesh(1.0));
    s.objects.push(Object {
        name: "plate".into(),
        mesh: id,
        material: Material::diffuse(Vec3::splat(0.5)),
        kind: ObjectKind::Real,
        transform: Transform::IDENTITY,
    });
    s.lights = lights;
    s.projectors.push(projector_at(
        DVec3::new(0.5, 1.5, 0.5),
        DVec3::new(0.5, 0.0, 0.5),
        64,
        48,
    ));
    s
}

/// A point light.
pub(super) fn point(position: Vec3, intensity: f32) -> LightSource {
    LightSource {
        name: format!("point {position}"),
        light: Light::Point {
            position,
            intensity: Vec3::splat(intensity),
        },
    }
}

/// The light sets of the storage-variant tests: an area light with
/// `samples` samples (the shader's light capacity, so the uniform variant)
/// and the same plus one dark point light (one sample over, so the storage
/// variant), which must render identically.
pub(super) fn light_sets_at_and_over_capacity(samples: usize) -> [Vec<LightSource>; 2] {
    let area = LightSource {
        name: "area".into(),
        light: Light::Area {
            corner: Vec3::new(0.2, 0.54, 0.2),
            edge_u: Vec3::new(0.15, 0.0, 0.0),
            edge_v: Vec3::new(0.0, 0.0, 0.12),
            radiance: Vec3::splat(1.5),
            samples: samples as u32,
        },
    };
    let dark = point(Vec3::new(0.3, 0.4, 0.3), 0.0);
    [vec![area.clone()], vec![area, dark]]
}
