//! Integration tests: gpu. The wgpu bring-up pass against the CPU reference rasteriser (Stanford bunny, Cornell box, fill-rule ties), the device-to-clip mapping against `PinholeDevice::project`, and naga validation of every WGSL file.
//!
//! GPU adapter policy ([`gpu_or_skip`]): without an adapter a GPU test
//! fails when the `CI` environment variable is set, and otherwise prints
//! "skipping" and passes. CI runs them on lavapipe (`mesa-vulkan-drivers`).

mod compare;
mod wgsl;

use std::path::Path;

use anyhow::{Context, Result, bail, ensure};
use compare::{MESH_TOLERANCE, Tolerance, compare};
use glam::{DMat3, DVec2, DVec3, Quat, Vec3};
use rand::{Rng, SeedableRng};
use showcase_light::raster::{
    DrawItem, FlatLambertScene, RasterImage, SceneError, rasterise_flat_lambert,
};
use showcase_proto::{Mesh, PinholeDevice, Transform};
use showcase_render::gpu::{FlatLambertPass, GpuContext, GpuError, OffscreenTarget};

/// Open a headless GPU, or explain why the test is skipped. With `CI` set
/// a missing adapter is an error, so CI cannot pass by skipping.
pub(crate) fn gpu_or_skip(test: &str) -> Result<Option<GpuContext>> {
    match GpuContext::new_headless() {
        Ok(ctx) => {
            eprintln!("{test}: adapter {}", ctx.describe());
            Ok(Some(ctx))
        }
        Err(GpuError::NoAdapter(e)) => {
            if std::env::var_os("CI").is_some() {
                bail!("{test}: no GPU adapter and CI is set (install mesa-vulkan-drivers): {e}");
            }
            eprintln!("{test}: skipping: no GPU adapter ({e}) (set CI to make this fatal)");
            Ok(None)
        }
        Err(e) => Err(e).context(format!("{test}: opening a GPU device")),
    }
}

/// All models of an OBJ as meshes, with each model's diffuse albedo
/// (grey 0.8 where it has none): the render tests' loader without names.
fn load_obj(path: &Path) -> Result<Vec<(Mesh, Vec3)>> {
    Ok(crate::render::scenes::load_obj(path)?
        .into_iter()
        .map(|(_, mesh, albedo)| (mesh, albedo))
        .collect())
}

/// Render `scene` on the GPU and read back colour and depth.
fn render_gpu(ctx: &GpuContext, scene: &FlatLambertScene<'_>) -> Result<(Vec<[f32; 4]>, Vec<f32>)> {
    let (device, queue) = (&ctx.device, &ctx.queue);
    let pass = FlatLambertPass::new(device);
    let target = OffscreenTarget::new(device, scene.device.width, scene.device.height)?;
    let batch = pass.upload(device, scene)?;
    pass.render(device, queue, &target, &batch)?;
    Ok((
        target.read_rgba_f32(device, queue)?,
        target.read_depth(device, queue)?,
    ))
}

/// Render on both sides, check that the picture is not trivially empty or
/// flat, and compare.
fn check_scene(
    name: &str,
    ctx: &GpuContext,
    scene: &FlatLambertScene<'_>,
    min_drawn: f64,
    min_shades: usize,
) -> Result<()> {
    let cpu = rasterise_flat_lambert(scene)?;
    let drawn = cpu.colour.iter().filter(|c| c[3] == 1.0).count();
    let total = cpu.colour.len();
    ensure!(
        drawn as f64 >= min_drawn * total as f64,
        "{name}: only {drawn} of {total} pixels drawn; the view misses the mesh"
    );
    let mut shades: Vec<u32> = cpu
        .colour
        .iter()
        .filter(|c| c[3] == 1.0)
        .map(|c| c[0].to_bits())
        .collect();
    shades.sort_unstable();
    shades.dedup();
    ensure!(
        shades.len() >= min_shades,
        "{name}: only {} distinct shades; shading untested",
        shades.len()
    );
    let uncertain = cpu.uncertain.iter().filter(|&&u| u).count();
    ensure!(
        uncertain * 5 < drawn,
        "{name}: {uncertain} uncertain pixels of {drawn} drawn; the comparison would test little"
    );
    let (colour, depth) = render_gpu(ctx, scene)?;
    compare(name, &cpu, &colour, &depth, &MESH_TOLERANCE)
}

/// The Stanford bunny as shipped (about 10 units tall, y up).
fn bunny_mesh() -> Result<Mesh> {
    let mut models = load_obj(&crate::render::scenes::data("bunny.obj"))?;
    ensure!(models.len() == 1, "bunny.obj has {} models", models.len());
    Ok(models.remove(0).0)
}

/// Place `mesh` standing on the floor (y = 0) at `at`: scaled to `height`
/// metres tall, then stretched per axis by `stretch`, turned `yaw_deg`
/// about y.
fn standing(mesh: &Mesh, height: f32, stretch: Vec3, yaw_deg: f32, at: Vec3) -> Result<Transform> {
    let (lo, hi) = mesh.bounds().context("mesh has no vertices")?;
    let scale = stretch * (height / (hi.y - lo.y));
    let foot = Vec3::new(0.5 * (lo.x + hi.x), lo.y, 0.5 * (lo.z + hi.z));
    let rotation = Quat::from_rotation_y(yaw_deg.to_radians());
    Ok(Transform {
        translation: at - rotation * (foot * scale),
        rotation,
        scale,
    })
}

/// The device of the bunny tests: 1024x768, 0.6 m away, a little above.
fn bunny_device() -> PinholeDevice {
    let mut device = PinholeDevice::look_at(
        DVec3::new(0.25, 0.3, 0.65),
        DVec3::new(0.0, 0.14, 0.0),
        DVec3::Y,
        40.0,
        1024,
        768,
    );
    device.near = 0.1;
    device.far = 10.0;
    device
}

#[test]
fn bunny_gpu_matches_cpu_reference() -> Result<()> {
    let Some(ctx) = gpu_or_skip("bunny_gpu_matches_cpu_reference")? else {
        return Ok(());
    };
    let mesh = bunny_mesh()?;
    let device = bunny_device();
    let items = [DrawItem {
        mesh: &mesh,
        transform: standing(&mesh, 0.3, Vec3::ONE, 30.0, Vec3::ZERO)?,
        albedo: Vec3::new(0.8, 0.7, 0.6),
    }];
    let scene = FlatLambertScene {
        device: &device,
        items: &items,
        to_light: Vec3::new(0.5, 1.0, 0.7),
    };
    check_scene("bunny", &ctx, &scene, 0.1, 1000)
}

#[test]
fn cornell_box_gpu_matches_cpu_reference() -> Result<()> {
    let Some(ctx) = gpu_or_skip("cornell_box_gpu_matches_cpu_reference")? else {
        return Ok(());
    };
    let models = load_obj(&crate::render::scenes::data("cornell-box.obj"))?;
    ensure!(
        models.len() >= 8,
        "cornell-box.obj has {} models",
        models.len()
    );
    let mut items: Vec<DrawItem<'_>> = models
        .iter()
        .map(|(mesh, albedo)| DrawItem {
            mesh,
            transform: Transform::IDENTITY,
            albedo: *albedo,
        })
        .collect();
    // A squashed, stretched bunny on the floor beside the tall block:
    // non-uniform scale exercises the normal matrix.
    let bunny = bunny_mesh()?;
    items.push(DrawItem {
        mesh: &bunny,
        transform: standing(
            &bunny,
            0.14,
            Vec3::new(1.4, 0.7, 1.0),
            120.0,
            Vec3::new(0.46, 0.0, 0.3),
        )?,
        albedo: Vec3::new(0.3, 0.5, 0.8),
    });
    // The classic camera, in front of the open side, looking in.
    let mut device = PinholeDevice::look_at(
        DVec3::new(0.278, 0.273, -0.8),
        DVec3::new(0.278, 0.273, 0.0),
        DVec3::Y,
        39.3,
        640,
        480,
    );
    device.near = 0.1;
    device.far = 10.0;
    let scene = FlatLambertScene {
        device: &device,
        items: &items,
        to_light: Vec3::new(-0.3, 0.8, -0.5),
    };
    check_scene("cornell-box", &ctx, &scene, 0.5, 100)
}

#[test]
fn near_plane_clipping_matches_cpu_reference() -> Result<()> {
    let Some(ctx) = gpu_or_skip("near_plane_clipping_matches_cpu_reference")? else {
        return Ok(());
    };
    // A device 0.2 m above a 20 m floor, tilted down: the floor runs
    // through the near plane and behind the device. Also drawn: an empty
    // mesh, and a bunny wholly behind the device.
    let mut device = PinholeDevice::look_at(
        DVec3::new(0.0, 0.2, 0.0),
        DVec3::new(0.3, 0.0, 1.0),
        DVec3::Y,
        90.0,
        320,
        240,
    );
    device.near = 0.1;
    device.far = 30.0;
    let floor = Mesh {
        positions: vec![
            Vec3::new(-10.0, 0.0, -10.0),
            Vec3::new(10.0, 0.0, -10.0),
            Vec3::new(10.0, 0.0, 10.0),
            Vec3::new(-10.0, 0.0, 10.0),
        ],
        // Counter-clockwise seen from above: normal +y.
        triangles: vec![[0, 2, 1], [0, 3, 2]],
        ..Mesh::default()
    };
    let empty = Mesh::default();
    let bunny = bunny_mesh()?;
    let items = [
        DrawItem {
            mesh: &floor,
            transform: Transform::IDENTITY,
            albedo: Vec3::new(0.5, 0.6, 0.7),
        },
        DrawItem {
            mesh: &empty,
            transform: Transform::IDENTITY,
            albedo: Vec3::ONE,
        },
        DrawItem {
            mesh: &bunny,
            transform: standing(&bunny, 0.3, Vec3::ONE, 0.0, Vec3::new(0.0, 0.0, -1.0))?,
            albedo: Vec3::ONE,
        },
    ];
    let scene = FlatLambertScene {
        device: &device,
        items: &items,
        to_light: Vec3::new(0.2, 1.0, 0.1),
    };
    check_scene("near-clip", &ctx, &scene, 0.3, 1)
}

/// A device looking down +z whose clip mapping is exact in f32:
/// `ndc = (x / z, -y / z)`, so dyadic world points land exactly on
/// dyadic framebuffer positions and fill-rule ties are real ties on the
/// GPU too.
fn exact_device(size: u32) -> PinholeDevice {
    let f = 0.5 * size as f64;
    PinholeDevice {
        width: size,
        height: size,
        k: DMat3::from_cols(
            DVec3::new(f, 0.0, 0.0),
            DVec3::new(0.0, f, 0.0),
            DVec3::new(f, f, 1.0),
        ),
        rotation: DMat3::IDENTITY,
        translation: DVec3::ZERO,
        dist_coeffs: [0.0; 5],
        near: 0.5,
        far: 2.0,
    }
}

#[test]
fn fill_rule_ties_match_exactly() -> Result<()> {
    let Some(ctx) = gpu_or_skip("fill_rule_ties_match_exactly")? else {
        return Ok(());
    };
    // A lattice of 3x3-pixel cells whose corners sit on pixel centres,
    // split along alternating diagonals: every edge runs through pixel
    // centres, horizontally, vertically and at +-45 degrees. Each
    // triangle is its own item with its own albedo, so a centre given to
    // the wrong triangle shows.
    let size = 16u32;
    let device = exact_device(size);
    let world = |sx: f64, sy: f64| {
        let f = 0.5 * size as f64;
        Vec3::new(((sx - f) / f) as f32, ((sy - f) / f) as f32, 1.0)
    };
    let mut meshes = Vec::new();
    for j in 0..5 {
        for i in 0..5 {
            let (x0, y0) = (0.5 + 3.0 * i as f64, 0.5 + 3.0 * j as f64);
            let c = [
                world(x0, y0),
                world(x0 + 3.0, y0),
                world(x0 + 3.0, y0 + 3.0),
                world(x0, y0 + 3.0),
            ];
            // Front faces wind clockwise in the y-down framebuffer.
            let tris: [[usize; 3]; 2] = if (i + j) % 2 == 0 {
                [[0, 2, 1], [0, 3, 2]]
            } else {
                [[0, 3, 1], [1, 3, 2]]
            };
            for t in tris {
                meshes.push(Mesh {
                    positions: t.iter().map(|&k| c[k]).collect(),
                    triangles: vec![[0, 1, 2]],
                    ..Mesh::default()
                });
            }
        }
    }
    let items: Vec<DrawItem<'_>> = meshes
        .iter()
        .enumerate()
        .map(|(k, mesh)| DrawItem {
            mesh,
            transform: Transform::IDENTITY,
            albedo: Vec3::new((k + 1) as f32 / 64.0, 0.5, 0.25),
        })
        .collect();
    let scene = FlatLambertScene {
        device: &device,
        items: &items,
        to_light: Vec3::NEG_Z,
    };
    let cpu = rasterise_flat_lambert(&scene)?;
    // Centres 0.5 ..= 14.5 on both axes: the right and bottom borders of
    // the lattice (at 15.5) are not top-left edges.
    let drawn = cpu.colour.iter().filter(|c| c[3] == 1.0).count();
    ensure!(drawn == 15 * 15, "cpu drew {drawn} pixels, expected 225");
    let (colour, depth) = render_gpu(&ctx, &scene)?;
    let exact = Tolerance {
        colour: 0.0,
        depth: MESH_TOLERANCE.depth,
        mismatch_fraction: 0.0,
    };
    let certain = RasterImage {
        uncertain: vec![false; cpu.colour.len()],
        ..cpu
    };
    compare("fill-rule", &certain, &colour, &depth, &exact)
}

#[test]
fn clip_from_world_matches_projection() {
    // The one device-to-clip mapping: framebuffer position
    // ((ndc_x + 1) w / 2, (1 - ndc_y) h / 2) must be the OpenCV pixel of
    // `project`, and depth must run 0..1 from near to far, for devices
    // with skew and an off-centre principal point.
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(6);
    for case in 0..200 {
        let (w, h) = (rng.random_range(1..2000u32), rng.random_range(1..2000u32));
        let eye = DVec3::new(
            rng.random_range(-2.0..2.0),
            rng.random_range(0.0..2.0),
            rng.random_range(-2.0..2.0),
        );
        let target = DVec3::new(
            rng.random_range(-0.5..0.5),
            rng.random_range(-0.5..0.5),
            rng.random_range(-0.5..0.5),
        );
        if (target - eye).length() < 0.1 {
            continue;
        }
        let mut d =
            PinholeDevice::look_at(eye, target, DVec3::Y, rng.random_range(10.0..120.0), w, h);
        d.k.y_axis.x = rng.random_range(-5.0..5.0);
        d.k.z_axis.x += rng.random_range(-50.0..50.0);
        d.k.z_axis.y += rng.random_range(-50.0..50.0);
        d.near = rng.random_range(0.01..0.5);
        d.far = d.near + rng.random_range(0.5..50.0);
        let clip = d.clip_from_world();
        for _ in 0..10 {
            let world = target
                + DVec3::new(
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                );
            let Some(pixel) = d.project(world) else {
                continue;
            };
            let c = clip * world.extend(1.0);
            let fb = DVec2::new(
                (c.x / c.w + 1.0) * 0.5 * w as f64,
                (1.0 - c.y / c.w) * 0.5 * h as f64,
            );
            assert!(
                (fb - pixel).length() < 1e-6 * (1.0 + pixel.length()),
                "case {case}: {fb} vs {pixel}"
            );
            let z = d.to_device(world).z;
            let expected = d.far * (z - d.near) / (z * (d.far - d.near));
            assert!((c.z / c.w - expected).abs() < 1e-9, "case {case}: depth");
            assert!((c.w - z).abs() < 1e-9, "case {case}: w is the device z");
        }
        // Near and far planes at depth 0 and 1 on the optical axis.
        let axis = d.rotation.row(2);
        for (dist, expected) in [(d.near, 0.0), (d.far, 1.0)] {
            let c = clip * (d.center() + axis * dist).extend(1.0);
            assert!(
                (c.z / c.w - expected).abs() < 1e-9,
                "case {case}: plane at {dist}"
            );
        }
    }
}

#[test]
fn bad_gpu_input_is_an_error() -> Result<()> {
    let Some(ctx) = gpu_or_skip("bad_gpu_input_is_an_error")? else {
        return Ok(());
    };
    let (device, queue) = (&ctx.device, &ctx.queue);
    assert!(matches!(
        OffscreenTarget::new(device, 0, 16),
        Err(GpuError::BadTargetSize { width: 0, .. })
    ));
    let huge = device.limits().max_texture_dimension_2d + 1;
    assert!(matches!(
        OffscreenTarget::new(device, 16, huge),
        Err(GpuError::BadTargetSize { .. })
    ));
    let pass = FlatLambertPass::new(device);
    let view = exact_device(16);
    let broken = Mesh {
        positions: vec![Vec3::Z; 3],
        triangles: vec![[0, 1, 3]],
        ..Mesh::default()
    };
    let items = [DrawItem {
        mesh: &broken,
        transform: Transform::IDENTITY,
        albedo: Vec3::ONE,
    }];
    let scene = FlatLambertScene {
        device: &view,
        items: &items,
        to_light: Vec3::Y,
    };
    assert!(matches!(
        pass.upload(device, &scene),
        Err(GpuError::Scene(SceneError::IndexOutOfRange {
            index: 3,
            ..
        }))
    ));
    let batch = pass.upload(
        device,
        &FlatLambertScene {
            items: &[],
            ..scene
        },
    )?;
    let wrong_size = OffscreenTarget::new(device, 8, 16)?;
    assert!(matches!(
        pass.render(device, queue, &wrong_size, &batch),
        Err(GpuError::SizeMismatch {
            target_width: 8,
            width: 16,
            ..
        })
    ));
    // The right size draws the clear colour and depth.
    let target = OffscreenTarget::new(device, 16, 16)?;
    pass.render(device, queue, &target, &batch)?;
    ensure!(
        target
            .read_rgba_f32(device, queue)?
            .iter()
            .all(|c| *c == [0.0; 4])
    );
    ensure!(target.read_depth(device, queue)?.iter().all(|&d| d == 1.0));
    Ok(())
}
