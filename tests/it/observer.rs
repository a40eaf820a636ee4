//! What an observer sees, simulated (`showcase_light::observer_view`),
//! and the projector blending it exposes: on the demo cabinet, whose two
//! projectors overlap on most of the room, the CPU reference irradiance
//! maps of both projectors, sent through the true projectors onto the real
//! objects, must give the target radiance once, not twice.

use glam::DVec3;
use showcase_light::observer_view::{ObserverView, ProjectedLight, observer_view};
use showcase_light::render::{FrameScene, Occluders, ProjectorOptions, irradiance_map_cpu};
use showcase_light::{Image, metrics::relative_rmse};
use showcase_proto::{ObjectKind, Showcase};

/// The demo cabinet with its projectors at `1 / projector_divisor` of
/// their width and height and its faces at `1 / face_divisor`.
fn cabinet_at(projector_divisor: u32, face_divisor: u32) -> Showcase {
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../deploy/scenes/showcase.toml");
    let mut s = showcase_master::scene_file::load_scene(&path).expect("the demo scene loads");
    for p in &mut s.projectors {
        let d = &p.device;
        p.device = showcase_master::capture::resize_device(
            d,
            d.width / projector_divisor,
            d.height / projector_divisor,
        )
        .unwrap();
    }
    for f in &mut s.faces {
        f.width /= face_divisor;
        f.height /= face_divisor;
    }
    s
}

/// The demo cabinet's real objects and lamp (virtual objects removed, so
/// that what the eye sees of the real room is the whole target), with its
/// projectors at a quarter of their pixels.
fn real_cabinet() -> Showcase {
    let mut s = cabinet_at(2, 1);
    s.objects.retain(|o| o.kind == ObjectKind::Real);
    s
}

/// The cabinet's real room seen from above its front edge, lit by both
/// projectors' maps made with `options`.
fn view(scene: &Showcase, options: ProjectorOptions) -> ObserverView {
    let frame = FrameScene::from_parts(scene.clone(), &[]).unwrap();
    let occluders = Occluders::new(&frame).unwrap();
    // Each node's values, sent to its device through its own light (the
    // device boundary: the simulated devices are the scene's).
    let maps: Vec<_> = scene
        .projectors
        .iter()
        .map(|p| {
            let map = irradiance_map_cpu(&frame, &occluders, p, options).unwrap();
            map.value.map(|v| p.response.encode(*v))
        })
        .collect();
    let projected: Vec<ProjectedLight<'_>> = scene
        .projectors
        .iter()
        .zip(&maps)
        .map(|(projector, value)| ProjectedLight { projector, value })
        .collect();
    let eye = showcase_proto::PinholeDevice::look_at(
        DVec3::new(0.15, 0.55, 0.9),
        DVec3::new(-0.05, 0.1, -0.05),
        DVec3::Y,
        35.0,
        240,
        180,
    );
    observer_view(&frame, &occluders, &eye, &projected, None).unwrap()
}

/// Over the pixels the eye sees off edges, where some projector reaches
/// the surface (the rest of the room is out of every projector's frustum
/// or shadowed from it: no map can light it).
fn rel_rmse_off_edges(v: &ObserverView) -> f64 {
    let mask = Image {
        width: v.covered.width,
        height: v.covered.height,
        data: v
            .covered
            .data
            .iter()
            .zip(&v.edge.data)
            .zip(&v.reachable.data)
            .map(|((c, e), r)| *c && !e && *r)
            .collect(),
    };
    relative_rmse(&v.composite, &v.target, Some(&mask)).unwrap()
}

#[test]
fn blended_projectors_deliver_the_target_once() {
    let scene = real_cabinet();
    assert_eq!(scene.projectors.len(), 2);
    let blended = view(&scene, ProjectorOptions::default());
    let e = rel_rmse_off_edges(&blended);
    eprintln!("blended: rel RMSE {e:.4}");
    // Left: black level, and a projector pixel's footprint seen through
    // the nearest pixel on smoothly lit surfaces.
    assert!(e <= 0.02, "blended projectors miss the target by {e}");
    // Each projector alone delivering the whole target doubles the overlap.
    let unblended = view(
        &scene,
        ProjectorOptions {
            blend: false,
            ..ProjectorOptions::default()
        },
    );
    let e = rel_rmse_off_edges(&unblended);
    eprintln!("unblended: rel RMSE {e:.4}");
    assert!(e > 0.3, "unblended projectors pass ({e})");
}

/// The demo cabinet, whole, with its projectors at a sixteenth of their
/// pixels and its faces at a sixty-fourth.
fn cabinet() -> Showcase {
    cabinet_at(4, 8)
}

/// A node's renderer finds its output by name in each snapshot and draws
/// exactly what the role's renderer draws for that output; a face serves
/// the observer in front of its mirror. Bad names and roles are errors
/// that name them.
#[test]
fn a_node_renders_its_named_output() -> anyhow::Result<()> {
    use showcase_proto::Role;
    use showcase_render::node::{OutputRenderer, Renderer, observer_in_front};
    use showcase_render::render::face_gpu::FaceRenderer;
    use showcase_render::render::projector_gpu::ProjectorRenderer;
    use std::sync::Arc;

    let scene = Arc::new(cabinet());
    assert_eq!(observer_in_front(&scene, 0), Some(0));
    assert_eq!(observer_in_front(&scene, 1), Some(1));
    let Some(ctx) = crate::gpu::gpu_or_skip("a_node_renders_its_named_output")? else {
        return Ok(());
    };
    let share = || ctx.clone();
    let frame = showcase_master::tracking::initial_frame(&scene, 3, 0.05, 7);
    let mut node = OutputRenderer::new(share(), "projector-1", Role::Projector, 128)?;
    node.set_scene(7, scene.clone())?;
    let got = node.render(&frame, &scene)?;
    let mut direct = ProjectorRenderer::new(share(), 1, 128);
    direct.set_scene(7, scene.clone())?;
    assert_eq!(got, direct.render(&frame, &scene)?);
    let mut node = OutputRenderer::new(share(), "face-1", Role::Face, 128)?;
    node.set_scene(7, scene.clone())?;
    let got = node.render(&frame, &scene)?;
    let mut direct = FaceRenderer::new(share(), 1, 1, 128);
    direct.set_scene(7, scene.clone())?;
    assert_eq!(got, direct.render(&frame, &scene)?);

    let mut wrong = OutputRenderer::new(share(), "projector-9", Role::Projector, 128)?;
    let e = wrong.set_scene(7, scene.clone()).unwrap_err().to_string();
    assert!(
        e.contains("projector-9") && e.contains("projector-0"),
        "{e}"
    );
    let e = wrong.render(&frame, &scene).unwrap_err().to_string();
    assert!(e.contains("before any scene"), "{e}");
    let e = OutputRenderer::new(share(), "camera-0", Role::Camera, 128)
        .unwrap_err()
        .to_string();
    assert!(e.contains("camera-0"), "{e}");
    Ok(())
}

/// The GPU projector pass blends overlapping projectors as the CPU
/// reference does: on the demo cabinet (two overlapping projectors) each
/// projector's map matches the reference within the projector tests'
/// GPU-vs-CPU tolerance, and the shares are really applied (the map with
/// blending off differs by far more).
#[test]
fn gpu_blends_overlapping_projectors_like_the_cpu_reference() -> anyhow::Result<()> {
    use crate::render::projector::{GPU_CPU_REL_RMSE, OFF_EDGE_OUTLIERS};
    use showcase_render::render::compare::compare_maps;
    use showcase_render::render::passes::PassList;
    use showcase_render::render::projector_gpu::ProjectorPipeline;

    let Some(ctx) = crate::gpu::gpu_or_skip("gpu_blends_overlapping_projectors")? else {
        return Ok(());
    };
    let scene = cabinet();
    let frame = FrameScene::from_parts(scene.clone(), &[])?;
    let occluders = Occluders::new(&frame)?;
    for projector in &scene.projectors {
        let mut pipeline = ProjectorPipeline::new(&ctx.device, 1024);
        let gpu = pipeline.render(&ctx, &frame, projector, &PassList::full())?;
        let cpu = irradiance_map_cpu(&frame, &occluders, projector, ProjectorOptions::default())?;
        let c = compare_maps(&gpu, &cpu)?;
        eprintln!("{}: {c:?}", projector.name);
        anyhow::ensure!(
            c.rel_rmse_off_edges <= GPU_CPU_REL_RMSE,
            "{}: rel RMSE off edges {}",
            projector.name,
            c.rel_rmse_off_edges
        );
        anyhow::ensure!(
            (c.outliers_off_edges as f64) <= OFF_EDGE_OUTLIERS * c.pixels as f64,
            "{}: {c:?}",
            projector.name
        );
        let unblended = irradiance_map_cpu(
            &frame,
            &occluders,
            projector,
            ProjectorOptions {
                blend: false,
                ..ProjectorOptions::default()
            },
        )?;
        let u = compare_maps(&gpu, &unblended)?;
        anyhow::ensure!(
            u.rel_rmse_off_edges > 0.1,
            "{}: the GPU map also matches the unblended map ({u:?})",
            projector.name
        );
    }
    Ok(())
}

/// A face node in global mode draws the master's solution: the node
/// meshes its own copy of the scene with the solution's mesh options and
/// draws what a face renderer given the master's field draws (to the f32
/// rounding of the values on the wire), far from its direct-mode image;
/// back in direct mode it draws the direct image exactly.
#[test]
fn a_face_node_draws_the_masters_solution() -> anyhow::Result<()> {
    use showcase_master::cluster::illumination::{Request, solve};
    use showcase_master::radiosity_job::{RadiosityOptions, indirect_field};
    use showcase_proto::Role;
    use showcase_proto::session::Solution;
    use showcase_render::node::{OutputRenderer, Renderer};
    use showcase_render::render::face_gpu::FaceRenderer;
    use std::sync::Arc;

    let Some(ctx) = crate::gpu::gpu_or_skip("a_face_node_draws_the_masters_solution")? else {
        return Ok(());
    };
    let scene = Arc::new(cabinet());
    let state = showcase_master::tracking::initial_frame(&scene, 3, 0.05, 7);
    let options = RadiosityOptions::default();
    let solved = solve(Request::of(&scene, &state), &options)?;
    let solution = Arc::new(Solution {
        version: 1,
        scene_version: 7,
        mesh: solved.mesh,
        values: solved.values,
    });
    let image = |o: showcase_render::node::RenderOutput| {
        let img = o.image.expect("a face keeps its image");
        Image {
            width: img.width,
            height: img.height,
            data: img
                .rgba
                .iter()
                .map(|p| glam::Vec3::new(p[0], p[1], p[2]))
                .collect::<Vec<_>>(),
        }
    };
    let mut node = OutputRenderer::new(ctx.clone(), "face-0", Role::Face, 128)?;
    node.set_scene(7, scene.clone())?;
    node.set_illumination(Some(&solution))?;
    let global = image(node.render(&state, &scene)?);

    let resolved = FrameScene::resolve(&scene, &state)?;
    let (field, _) = indirect_field(&resolved.showcase, &resolved.eyes, &options)?;
    let mut offline = FaceRenderer::new(ctx.clone(), 0, 0, 128);
    offline.set_scene(7, scene.clone())?;
    offline.set_indirect(Some(Arc::new(field)));
    let expected = image(offline.render(&state, &scene)?);
    let mut direct = FaceRenderer::new(ctx, 0, 0, 128);
    direct.set_scene(7, scene.clone())?;
    let direct_out = direct.render(&state, &scene)?;
    let direct_image = image(direct_out.clone());

    let drawn = Image {
        width: direct_image.width,
        height: direct_image.height,
        data: direct_image
            .data
            .iter()
            .zip(&global.data)
            .map(|(d, g)| d.max_element() > 0.0 || g.max_element() > 0.0)
            .collect::<Vec<bool>>(),
    };
    let effect = relative_rmse(&direct_image, &global, Some(&drawn))?;
    let wire = relative_rmse(&expected, &global, Some(&drawn))?;
    eprintln!("the solution changes the face by {effect}; node against offline {wire}");
    anyhow::ensure!(effect > 0.05, "the solution changes the face by {effect}");
    anyhow::ensure!(wire < 1e-4, "node against offline field: {wire}");

    node.set_illumination(None)?;
    anyhow::ensure!(
        node.render(&state, &scene)? == direct_out,
        "back in direct mode the node draws another image"
    );
    Ok(())
}
