//! The face role: per-eye views through the beam splitter against the CPU
//! reference (virtual objects shaded with shadow types 2 and 3, phantom
//! depth), and the geometric line-of-sight property of drawn pixels.

use std::sync::Arc;

use anyhow::{Result, ensure};
use glam::{DVec2, DVec3, Vec3};
use showcase_light::metrics::relative_rmse;
use showcase_light::render::face::{eyes_to_fill, face_image_cpu, reflected_pixel};
use showcase_light::render::projector::edge_mask;
use showcase_light::render::{FrameScene, Occluders};
use showcase_light::{Image, Ray};
use showcase_proto::{CrtFace, ObjectKind};
use showcase_render::gpu::GpuContext;
use showcase_render::node::renderer::Renderer;
use showcase_render::render::bench::{bench_face, bench_frame};
use showcase_render::render::compare::EDGE_RADIUS_PX;
use showcase_render::render::face_gpu::{FacePipeline, FaceRenderer, other_eyes};
use showcase_render::render::passes::{Pass, PassList};

use super::gpu_or_skip;
use super::projector::{GPU_CPU_REL_RMSE, OFF_EDGE_OUTLIERS};
use super::scenes::bench;

#[test]
fn face_pixels_lie_on_the_line_of_sight_through_their_reflection() -> Result<()> {
    let scene = bench()?;
    let frame = FrameScene::resolve(&scene, &bench_frame(&scene, "full", 0))?;
    let occ = Occluders::new(&frame)?;
    let face = bench_face(96, 72);
    let eye = frame.eyes[0];
    let image = face_image_cpu(&frame, &occ, &face, eye, &[])?;
    let sphere = scene
        .objects
        .iter()
        .position(|o| o.name == "virtual sphere")
        .unwrap() as u32;
    let mut checked = 0;
    for y in 0..face.height {
        for x in 0..face.width {
            if image.state.get(x, y).unwrap().object != Some(sphere) {
                continue;
            }
            // The sphere's surface point is on the line eye -> reflection.
            let through = reflected_pixel(&face, DVec2::new(x as f64 + 0.5, y as f64 + 0.5));
            let ray = Ray::new(eye, (through - eye).normalize());
            let hit = occ.all.closest_hit(&ray, 0.0, f64::INFINITY).unwrap();
            let view = showcase_light::mirror_view::FaceView::new(&face, eye, 0.01, 20.0).unwrap();
            let px = view.pixel(hit.point, face.width, face.height).unwrap();
            ensure!(
                (px - DVec2::new(x as f64 + 0.5, y as f64 + 0.5)).length() < 1e-6,
                "{x},{y} -> {px}"
            );
            checked += 1;
        }
    }
    ensure!(checked > 20, "the sphere covers only {checked} pixels");
    Ok(())
}

#[test]
fn gpu_face_view_matches_the_cpu_reference() -> Result<()> {
    let Some(ctx) = gpu_or_skip("gpu_face_view_matches_the_cpu_reference")? else {
        return Ok(());
    };
    let scene = bench()?;
    let frame = FrameScene::resolve(&scene, &bench_frame(&scene, "full", 0))?;
    check_gpu_face_against_cpu(&ctx, &frame, &bench_face(320, 240))?;
    Ok(())
}

/// Global mode: the face adds the global-illumination field to what it
/// shades (the virtual objects' indirect light, and the filled occlusion
/// shadows' correction), on the GPU as in the CPU reference, and the
/// field changes the image far more than GPU and CPU differ.
#[test]
fn gpu_face_global_mode_matches_the_cpu_reference() -> Result<()> {
    use showcase_master::radiosity_job::{RadiosityOptions, indirect_field};
    let Some(ctx) = gpu_or_skip("gpu_face_global_mode_matches_the_cpu_reference")? else {
        return Ok(());
    };
    let scene = bench()?;
    let direct = FrameScene::resolve(&scene, &bench_frame(&scene, "full", 0))?;
    let (field, elements) =
        indirect_field(&direct.showcase, &direct.eyes, &RadiosityOptions::default())?;
    ensure!(elements > 100, "{elements} elements");
    let global = direct.clone().with_indirect(Arc::new(field));
    let face = bench_face(320, 240);
    let occ = Occluders::new(&direct)?;
    for &eye in &direct.eyes[..2] {
        let d = face_image_cpu(&direct, &occ, &face, eye, &[])?;
        let g = face_image_cpu(&global, &occ, &face, eye, &[])?;
        let drawn = d.state.map(|s| !s.masked);
        let effect = relative_rmse(&d.radiance, &g.radiance, Some(&drawn))?;
        eprintln!("eye {eye}: the field changes the face by {effect}");
        ensure!(
            effect > 10.0 * GPU_CPU_REL_RMSE,
            "the field changes the face by only {effect}"
        );
    }
    check_gpu_face_against_cpu(&ctx, &global, &face)?;
    // Back to direct light: the same kind of pipeline without the field.
    check_gpu_face_against_cpu(&ctx, &direct, &face)?;
    Ok(())
}

/// Both eyes of observer 0 through `face` on the GPU against the CPU
/// reference: off edges within [`GPU_CPU_REL_RMSE`] and
/// [`OFF_EDGE_OUTLIERS`], the other observer's occlusion shadows filled
/// in, and no virtual object drawn behind a phantom.
fn check_gpu_face_against_cpu(ctx: &GpuContext, frame: &FrameScene, face: &CrtFace) -> Result<()> {
    let scene = &frame.showcase;
    let occ = Occluders::new(frame)?;
    let BothEyes { eyes, others, gpu } = gpu_both_eyes(ctx, frame, face, 1024)?;
    for (k, (eye, image)) in eyes.iter().zip(&gpu).enumerate() {
        let filled = eyes_to_fill(&eyes, k, &others);
        let cpu = face_image_cpu(frame, &occ, face, *eye, &filled)?;
        let g = Image {
            width: face.width,
            height: face.height,
            data: image.iter().map(|p| Vec3::new(p[0], p[1], p[2])).collect(),
        };
        let edges = edge_mask(&cpu.state, EDGE_RADIUS_PX, false);
        let drawn = cpu.state.map(|s| !s.masked);
        let off = Image {
            data: drawn
                .data
                .iter()
                .zip(&edges.data)
                .map(|(d, e)| *d && !e)
                .collect(),
            ..drawn.clone()
        };
        let all = relative_rmse(&g, &cpu.radiance, Some(&drawn))?;
        let off_edges = relative_rmse(&g, &cpu.radiance, Some(&off))?;
        let n = drawn.data.iter().filter(|d| **d).count();
        let outliers = (0..g.data.len())
            .filter(|&i| off.data[i])
            .filter(|&i| {
                (g.data[i] - cpu.radiance.data[i]).abs().max_element()
                    > 0.01 * cpu.radiance.data[i].max_element().max(1e-6)
            })
            .count();
        // Phantom depth: wherever the reference sees a real phantom first
        // (outside the filled-in occlusion shadows), the GPU draws nothing.
        let real_first = |i: usize| {
            cpu.state.data[i]
                .object
                .is_some_and(|o| scene.objects[o as usize].kind == ObjectKind::Real)
        };
        let hidden = (0..g.data.len())
            .filter(|&i| real_first(i) && !cpu.state.data[i].occluded)
            .filter(|&i| !edges.data[i] && image[i][3] != 0.0)
            .count();
        // Occluding occlusion shadows: the other observer's occlusion
        // shadows on the real room are filled in, on both sides.
        let filled: Vec<usize> = (0..g.data.len())
            .filter(|&i| real_first(i) && cpu.state.data[i].occluded)
            .collect();
        let filled_off_edges = filled.iter().filter(|&&i| !edges.data[i]).count();
        let filled_gpu = filled
            .iter()
            .filter(|&&i| !edges.data[i] && image[i][3] == 1.0)
            .count();
        eprintln!(
            "filled {} (off edges {filled_off_edges}, gpu {filled_gpu})",
            filled.len()
        );
        ensure!(filled.len() > 200, "only {} filled pixels", filled.len());
        ensure!(
            filled_gpu == filled_off_edges,
            "gpu fills {filled_gpu} of {filled_off_edges}"
        );
        eprintln!(
            "eye {eye}: rel RMSE {all} (off edges {off_edges}) over {n} pixels, {outliers} outliers off edges, {hidden} phantom leaks"
        );
        ensure!(n > 2000, "only {n} virtual pixels");
        ensure!(
            off_edges <= GPU_CPU_REL_RMSE,
            "face rel RMSE off edges {off_edges}"
        );
        ensure!(
            outliers as f64 <= OFF_EDGE_OUTLIERS * n as f64,
            "{outliers} outliers off edges"
        );
        ensure!(
            hidden == 0,
            "{hidden} pixels draw a virtual object behind a phantom"
        );
    }
    Ok(())
}

#[test]
fn face_renderer_draws_both_eyes_side_by_side() -> Result<()> {
    let Some(ctx) = gpu_or_skip("face_renderer_draws_both_eyes_side_by_side")? else {
        return Ok(());
    };
    let mut scene = bench()?;
    scene.faces.push(bench_face(64, 48));
    let mut r = FaceRenderer::new(ctx, 0, 1, 256);
    r.set_scene(1, Arc::new(scene.clone()))?;
    let out = r.render(&bench_frame(&scene, "full", 0), &scene)?;
    let image = out.image.clone().unwrap();
    ensure!((image.width, image.height) == (128, 48));
    let left: usize = (0..48)
        .flat_map(|y| (0..64).map(move |x| (x, y)))
        .filter(|&(x, y)| image.rgba[y * 128 + x][3] > 0.0)
        .count();
    let right: usize = (0..48)
        .flat_map(|y| (64..128).map(move |x| (x, y)))
        .filter(|&(x, y)| image.rgba[y * 128 + x][3] > 0.0)
        .count();
    let differ =
        (0..48).any(|y| (0..64).any(|x| image.rgba[y * 128 + x] != image.rgba[y * 128 + 64 + x]));
    ensure!(
        left > 50 && right > 50 && differ,
        "left {left} right {right}, halves differ: {differ}"
    );
    ensure!(
        r.last_passes()
            == [
                Pass::LightShadowViews,
                Pass::EyeShadowViews,
                Pass::CubeMaps,
                Pass::FaceView
            ],
        "{:?}",
        r.last_passes()
    );
    // The same state again: reused, nothing ran, the same output.
    let mut again = bench_frame(&scene, "full", 0);
    again.frame = 1;
    let second = r.render(&again, &scene)?;
    ensure!(r.last_passes().is_empty() && second.hash == out.hash);
    // Another observer's head moves: their occlusion shadows move, so the
    // face is drawn again.
    again.frame = 2;
    again.heads[0].position.x += 0.03;
    let third = r.render(&again, &scene)?;
    ensure!(!r.last_passes().is_empty() && third.hash != out.hash);
    Ok(())
}

#[test]
fn occluding_occlusion_passes_are_skipped_with_one_eye() -> Result<()> {
    let Some(ctx) = gpu_or_skip("occluding_occlusion_passes_are_skipped_with_one_eye")? else {
        return Ok(());
    };
    let scene = bench()?;
    let mut state = bench_frame(&scene, "full", 0);
    state.heads.truncate(1);
    let frame = FrameScene::resolve(&scene, &state)?;
    let others = other_eyes(&frame, 0);
    ensure!(others.is_empty());
    // In stereo each eye fills the other's occlusion shadows.
    ensure!(PassList::for_face(&frame, others.len() + 1).runs(Pass::EyeShadowViews));
    // One eye of one observer: no other eye casts a shadow it sees.
    let passes = PassList::for_face(&frame, others.len());
    ensure!(!passes.runs(Pass::EyeShadowViews), "{passes:?}");
    let face = bench_face(96, 72);
    let eyes = [frame.eyes[0]];
    let mut pipeline = FacePipeline::new(&ctx.device, 256);
    let skipped = pipeline.render(&ctx, &frame, &face, &eyes, &others, &passes)?;
    let full = pipeline.render(&ctx, &frame, &face, &eyes, &others, &PassList::full_face())?;
    ensure!(
        skipped == full,
        "skipping the other eyes' views changed the output"
    );
    Ok(())
}

#[test]
fn kept_face_shadow_layers_give_the_output_of_a_fresh_pipeline() -> Result<()> {
    let Some(ctx) = gpu_or_skip("kept_face_shadow_layers_give_the_output_of_a_fresh_pipeline")?
    else {
        return Ok(());
    };
    let scene = bench()?;
    let face = bench_face(96, 72);
    let passes = PassList::full_face();
    let views = |state: &showcase_proto::FrameState| -> Result<_> {
        let frame = FrameScene::resolve(&scene, state)?;
        let others = other_eyes(&frame, 0);
        Ok((frame.eyes[0], frame.eyes[1], others, frame))
    };
    let fresh = |state: &showcase_proto::FrameState| -> Result<Vec<Vec<[f32; 4]>>> {
        let (l, r, others, frame) = views(state)?;
        Ok(FacePipeline::new(&ctx.device, 256).render(
            &ctx,
            &frame,
            &face,
            &[l, r],
            &others,
            &passes,
        )?)
    };
    let mut kept = FacePipeline::new(&ctx.device, 256);
    let mut render = |state: &showcase_proto::FrameState| -> Result<_> {
        let (l, r, others, frame) = views(state)?;
        let images = kept.render(&ctx, &frame, &face, &[l, r], &others, &passes)?;
        Ok((images, kept.last_layers_drawn()))
    };
    // A point light's six cube faces, the other observer's two eyes and
    // this observer's own two (each eye fills the other's shadows).
    let f0 = bench_frame(&scene, "full", 0);
    let (first, drawn) = render(&f0)?;
    ensure!(drawn == 10, "first frame drew {drawn} layers");
    let (again, drawn) = render(&f0)?;
    ensure!(
        drawn == 0 && again == first,
        "same frame drew {drawn} layers"
    );
    let mut f1 = f0.clone();
    f1.heads[1].position.x += 0.03;
    let (moved, drawn) = render(&f1)?;
    ensure!(drawn == 2, "the other head's move drew {drawn} layers");
    ensure!(moved == fresh(&f1)?, "kept light layers changed the output");
    Ok(())
}

/// The face and cube-map shaders read their per-frame arrays from uniform
/// arrays of fixed capacity, and from storage arrays when a frame exceeds
/// one (`gpu::frame_arrays`). A frame at the light-sample capacity and the
/// same frame with one more, dark, light (so the other variant) must give
/// bit-identical images. Without light shadow views: 65 cube maps would
/// exceed the device's array layers.
#[test]
fn face_storage_array_variant_gives_the_uniform_variants_output() -> Result<()> {
    use showcase_render::gpu::face_view::{capacity, space};
    use showcase_render::gpu::frame_arrays::ArraySpace;
    let Some(ctx) = gpu_or_skip("face_storage_array_variant_gives_the_uniform_variants_output")?
    else {
        return Ok(());
    };
    let cap = capacity("lights");
    ensure!(cap >= 2, "light capacity {cap}");
    let scene = bench()?;
    let face = bench_face(160, 120);
    let passes = PassList {
        passes: vec![Pass::EyeShadowViews, Pass::CubeMaps, Pass::FaceView],
    };
    let mut images = Vec::new();
    let sets = super::scenes::light_sets_at_and_over_capacity(cap);
    for (lights, expected) in sets
        .into_iter()
        .zip([ArraySpace::Uniform, ArraySpace::Storage])
    {
        let mut state = bench_frame(&scene, "full", 0);
        state.lights = lights;
        let frame = FrameScene::resolve(&scene, &state)?;
        let others = other_eyes(&frame, 0);
        let albedos = frame.showcase.objects.len();
        // One fitted view per other eye.
        let s = space(frame.samples.len(), others.len(), albedos, others.len());
        ensure!(
            s == expected,
            "{} samples: {s:?}, expected {expected:?}",
            frame.samples.len()
        );
        let eyes = [frame.eyes[0], frame.eyes[1]];
        images.push(
            FacePipeline::new(&ctx.device, 256)
                .render(&ctx, &frame, &face, &eyes, &others, &passes)?,
        );
    }
    let lit = images[0][0].iter().filter(|p| p[0] > 0.0).count();
    ensure!(lit > 100, "only {lit} lit pixels");
    ensure!(
        images[0] == images[1],
        "the storage variant differs from the uniform one"
    );
    Ok(())
}

/// Without virtual objects the face shows nothing: the phantoms have
/// nothing to hide and no occlusion shadow to fill, so the face view skips
/// drawing them. With every pass forced, both eyes' images must still be
/// the CPU reference's, which is black everywhere.
#[test]
fn face_without_virtual_objects_is_the_black_cpu_reference() -> Result<()> {
    use showcase_render::render::bench::variant_scene;
    let Some(ctx) = gpu_or_skip("face_without_virtual_objects_is_the_black_cpu_reference")? else {
        return Ok(());
    };
    let scene = variant_scene(&bench()?, "no_virtual_objects");
    let frame = FrameScene::resolve(&scene, &bench_frame(&scene, "full", 0))?;
    let occ = Occluders::new(&frame)?;
    let face = bench_face(160, 120);
    let BothEyes { eyes, others, gpu } = gpu_both_eyes(&ctx, &frame, &face, 256)?;
    for (k, (eye, image)) in eyes.iter().zip(&gpu).enumerate() {
        let filled = eyes_to_fill(&eyes, k, &others);
        let cpu = face_image_cpu(&frame, &occ, &face, *eye, &filled)?;
        ensure!(
            cpu.radiance.data.iter().all(|c| *c == Vec3::ZERO),
            "eye {k}: the reference shows something"
        );
        ensure!(image.len() == cpu.radiance.data.len(), "eye {k}: size");
        let lit = image.iter().filter(|p| **p != [0.0; 4]).count();
        ensure!(lit == 0, "eye {k}: {lit} pixels drawn");
    }
    Ok(())
}

/// The first observer's two eyes, the other observers' eyes, and each of
/// the two eyes' images drawn on the GPU.
struct BothEyes {
    eyes: [DVec3; 2],
    others: Vec<DVec3>,
    gpu: Vec<Vec<[f32; 4]>>,
}

/// [`BothEyes`] of `frame` with every face pass (shadow maps of
/// `shadow_res` texels per side).
fn gpu_both_eyes(
    ctx: &GpuContext,
    frame: &FrameScene,
    face: &CrtFace,
    shadow_res: u32,
) -> Result<BothEyes> {
    let eyes = [frame.eyes[0], frame.eyes[1]];
    let others = other_eyes(frame, 0);
    let gpu = FacePipeline::new(&ctx.device, shadow_res).render(
        ctx,
        frame,
        face,
        &eyes,
        &others,
        &PassList::full_face(),
    )?;
    Ok(BothEyes { eyes, others, gpu })
}
