//! The pass list (DESIGN section 7): each skip is shown to happen (the
//! pass is not in the frame's report) and to leave the output identical
//! (bit for bit) to the full pipeline's; shadow map layers kept from an
//! earlier frame likewise.

use std::sync::Arc;

use anyhow::{Result, ensure};
use glam::Vec3;
use showcase_light::render::FrameScene;
use showcase_proto::{FrameState, Pose, Showcase};
use showcase_render::node::renderer::Renderer;
use showcase_render::render::bench::{bench_frame, bench_light, bench_projector, variant_scene};
use showcase_render::render::passes::{Pass, PassList};
use showcase_render::render::projector_gpu::{
    GpuIrradianceMap, ProjectorPipeline, ProjectorRenderer,
};

use super::gpu_or_skip;
use super::scenes::{bench, plate_scene, point};

/// Render `frame` with the pass list and with every pass forced; return
/// the passes the pass list ran and both hashes.
fn skip_and_full(
    r: &mut ProjectorRenderer,
    scene: &Showcase,
    frame: &FrameState,
) -> Result<(Vec<Pass>, u64, u64)> {
    r.force_all_passes = false;
    let skipped = r.render(frame, scene)?.hash;
    let passes = r.report().passes_run.clone();
    r.force_all_passes = true;
    let full = r.render(frame, scene)?.hash;
    ensure!(
        r.report().passes_run.len() == 3,
        "forced run ran {:?}",
        r.report().passes_run
    );
    r.force_all_passes = false;
    Ok((passes, skipped, full))
}

fn frame_of(scene: &Showcase, n: u64) -> FrameState {
    FrameState {
        frame: n,
        time_s: n as f64 / 60.0,
        scene_version: 1,
        heads: scene.observers.iter().map(|o| o.head).collect(),
        lights: scene.lights.clone(),
        object_transforms: vec![],
        tracking_time_ns: None,
        illumination_version: None,
    }
}

#[test]
fn shadow_views_are_skipped_when_no_occluder_can_be_lit() -> Result<()> {
    let Some(ctx) = gpu_or_skip("shadow_views_are_skipped_when_no_occluder_can_be_lit")? else {
        return Ok(());
    };
    // A flat plate cannot shadow itself.
    let mut scene = plate_scene(vec![point(Vec3::new(0.3, 0.8, 0.6), 1.0)]);
    scene.ambient = Vec3::splat(0.02);
    let mut r = ProjectorRenderer::new(ctx, 0, 256);
    r.set_scene(1, Arc::new(scene.clone()))?;
    let (passes, skipped, full) = skip_and_full(&mut r, &scene, &frame_of(&scene, 0))?;
    ensure!(passes == vec![Pass::IrradianceMap], "plate ran {passes:?}");
    ensure!(
        skipped == full,
        "skipping the shadow views changed the output"
    );
    // No light at all: nothing can be lit.
    let mut dark = bench()?;
    dark.lights.clear();
    dark.projectors = vec![bench_projector(160, 120)];
    let mut frame = frame_of(&dark, 0);
    frame.lights.clear();
    r.set_scene(1, Arc::new(dark.clone()))?;
    let (passes, skipped, full) = skip_and_full(&mut r, &dark, &frame)?;
    ensure!(
        !passes.contains(&Pass::LightShadowViews),
        "unlit scene ran {passes:?}"
    );
    ensure!(
        skipped == full,
        "skipping the shadow views of an unlit scene changed the output"
    );
    // The bench scene needs them.
    let mut lit = bench()?;
    lit.projectors = vec![bench_projector(160, 120)];
    r.set_scene(1, Arc::new(lit.clone()))?;
    let (passes, _, _) = skip_and_full(&mut r, &lit, &bench_frame(&lit, "full", 0))?;
    ensure!(passes.contains(&Pass::LightShadowViews) && passes.contains(&Pass::EyeShadowViews));
    Ok(())
}

#[test]
fn occlusion_views_are_skipped_without_virtual_objects_or_observers() -> Result<()> {
    let Some(ctx) =
        gpu_or_skip("occlusion_views_are_skipped_without_virtual_objects_or_observers")?
    else {
        return Ok(());
    };
    let mut r = ProjectorRenderer::new(ctx, 0, 256);
    let mut scene = variant_scene(&bench()?, "no_virtual_objects");
    scene.projectors = vec![bench_projector(160, 120)];
    r.set_scene(1, Arc::new(scene.clone()))?;
    let (passes, skipped, full) = skip_and_full(&mut r, &scene, &bench_frame(&scene, "full", 0))?;
    ensure!(
        passes == vec![Pass::LightShadowViews, Pass::IrradianceMap],
        "ran {passes:?}"
    );
    ensure!(skipped == full, "skipping the eye views changed the output");
    let mut scene = bench()?;
    scene.projectors = vec![bench_projector(160, 120)];
    let mut frame = bench_frame(&scene, "full", 0);
    frame.heads.clear();
    r.set_scene(1, Arc::new(scene.clone()))?;
    let (passes, skipped, full) = skip_and_full(&mut r, &scene, &frame)?;
    ensure!(
        !passes.contains(&Pass::EyeShadowViews),
        "no observer but ran {passes:?}"
    );
    ensure!(
        skipped == full,
        "skipping the eye views without observers changed the output"
    );
    Ok(())
}

#[test]
fn unchanged_frames_are_reused_and_changed_ones_are_not() -> Result<()> {
    let Some(ctx) = gpu_or_skip("unchanged_frames_are_reused_and_changed_ones_are_not")? else {
        return Ok(());
    };
    let mut scene = bench()?;
    scene.projectors = vec![bench_projector(160, 120)];
    let mut r = ProjectorRenderer::new(ctx, 0, 256);
    r.set_scene(1, Arc::new(scene.clone()))?;
    let f0 = bench_frame(&scene, "static", 0);
    let first = r.render(&f0, &scene)?;
    ensure!(!r.report().reused);
    // Same state, next frame number: reused, nothing ran, same output.
    let f1 = FrameState {
        frame: 1,
        ..f0.clone()
    };
    let again = r.render(&f1, &scene)?;
    ensure!(
        r.report().reused && r.report().passes_run.is_empty(),
        "{:?}",
        r.report()
    );
    ensure!(again == first);
    // ... and identical to a full render of that frame.
    r.force_all_passes = true;
    ensure!(
        r.render(&f1, &scene)?.hash == first.hash,
        "reused frame differs from a full render"
    );
    r.force_all_passes = false;
    // A head moves: occlusion shadows change, so the frame is drawn.
    let mut moved = f1.clone();
    moved.frame = 2;
    moved.heads[0] = Pose {
        position: moved.heads[0].position + Vec3::new(0.05, 0.0, 0.0),
        ..moved.heads[0]
    };
    let out = r.render(&moved, &scene)?;
    ensure!(
        !r.report().reused && out.hash != first.hash,
        "moving a head did not redraw"
    );
    // The light moves: drawn.
    let mut lit = moved.clone();
    lit.frame = 3;
    lit.lights = vec![bench_light(1.0)];
    ensure!(r.render(&lit, &scene)?.hash != out.hash && !r.report().reused);
    // Without virtual objects heads are invisible to a projector: reused.
    let plain = variant_scene(&scene, "no_virtual_objects");
    r.set_scene(2, Arc::new(plain.clone()))?;
    let g0 = FrameState {
        scene_version: 2,
        ..f0
    };
    let base = r.render(&g0, &plain)?;
    let mut g1 = g0.clone();
    g1.frame = 1;
    g1.heads[0].position.x += 0.05;
    ensure!(
        r.render(&g1, &plain)? == base && r.report().reused,
        "head move redrew a scene without virtual objects"
    );
    Ok(())
}

#[test]
fn kept_shadow_layers_give_the_output_of_a_fresh_pipeline() -> Result<()> {
    let Some(ctx) = gpu_or_skip("kept_shadow_layers_give_the_output_of_a_fresh_pipeline")? else {
        return Ok(());
    };
    let scene = bench()?;
    let projector = bench_projector(160, 120);
    let passes = PassList::full();
    let fresh = |state: &FrameState| -> Result<GpuIrradianceMap> {
        let frame = FrameScene::resolve(&scene, state)?;
        Ok(ProjectorPipeline::new(&ctx.device, 256).render(&ctx, &frame, &projector, &passes)?)
    };
    let mut kept = ProjectorPipeline::new(&ctx.device, 256);
    let mut render = |state: &FrameState| -> Result<(GpuIrradianceMap, u32)> {
        let frame = FrameScene::resolve(&scene, state)?;
        let map = kept.render(&ctx, &frame, &projector, &passes)?;
        Ok((map, kept.last_layers_drawn()))
    };
    // One point light (six cube faces) and four eyes (one fitted view each).
    let f0 = bench_frame(&scene, "full", 0);
    let (first, drawn) = render(&f0)?;
    ensure!(drawn == 10, "first frame drew {drawn} layers");
    let (again, drawn) = render(&f0)?;
    ensure!(
        drawn == 0 && again == first,
        "same frame drew {drawn} layers"
    );
    // Observer 1 moves: only its two eyes' layers are drawn, and the
    // output is that of a pipeline that drew everything.
    let mut f1 = f0.clone();
    f1.heads[1].position.x += 0.03;
    let (moved, drawn) = render(&f1)?;
    ensure!(drawn == 2, "a moved head drew {drawn} layers");
    ensure!(
        moved != first && moved == fresh(&f1)?,
        "kept layers changed the output"
    );
    // The light moves: its six faces are drawn.
    let mut f2 = f1.clone();
    f2.lights = vec![bench_light(0.7)];
    let (lit, drawn) = render(&f2)?;
    ensure!(drawn == 6, "a moved light drew {drawn} layers");
    ensure!(lit == fresh(&f2)?, "kept eye layers changed the output");
    Ok(())
}
