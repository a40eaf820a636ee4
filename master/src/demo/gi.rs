//! `showcase-master bench gi`: global illumination for the projectors,
//! judged in the physically complete world, offline.
//!
//! For each scene, at one frame of the scripted walk (the demo's
//! resolution), the projectors' maps in direct mode and in global mode
//! (the hierarchical solution's indirect correction,
//! [`crate::radiosity_job::indirect_field`]), each seen by the cabinet's
//! cameras and the observers in the physically complete world
//! (`views::Transport::Complete`). The maps come from the projector
//! nodes' GPU renderer where an adapter opens, else from its CPU
//! reference; without occlusion shadows always from the CPU reference (the
//! GPU renderer always draws them); `renderer` says what drew the maps.
//! Beside them, the live figures of each mode ([`live_figures`]): the
//! scripted walk over a loopback cluster of state-hash nodes, direct and
//! global one after the other, once moving the light and once the carried
//! virtual object ([`WalkMove`]), with the global-illumination updates'
//! latency and frames stale, swap skew and tracking-to-swap.

use super::INTERACTIVE_HZ;
use super::views::{self, Backend, NodeRenderers, Transport};
use crate::cluster::commands::walk_tracking;
use crate::cluster::{Show, Tracking};
use anyhow::{Context, Result};
use serde_json::{Value, json};
use showcase_light::metrics::percentile;
use showcase_light::observer_view::complete::CompleteOptions;
use showcase_proto::config::TrackingSource;
use std::path::Path;
use std::sync::Arc;
use std::time::Instant;

/// What `bench gi` runs.
#[derive(Clone, Debug)]
pub struct GiBenchOptions {
    /// The frame of the scripted walk to judge.
    pub frame: u64,
    /// Paths per irradiance-cache point of the complete views.
    pub truth_paths: u32,
    /// Raise `truth_paths` four-fold, up to this, while the truth's noise
    /// over the compared pixels is more than [`NOISE_SHARE`] of global
    /// mode's camera figure: a figure is judged against a truth well below
    /// it (the figure-3 camera's 0.029 had noise 0.015 at 1,024 paths).
    /// At most `truth_paths`: the paths are fixed.
    pub max_truth_paths: u32,
    /// Also judge the maps drawn without occlusion shadows (what the dark
    /// patches they leave cost in the complete world, where they would
    /// have lit the rest of the room).
    pub without_occlusion: bool,
    /// Frames of the live loopback cluster per mode and move (0: none):
    /// the scripted walk at `INTERACTIVE_HZ` with one state-hash node per
    /// output, in direct and in global mode, one after the other.
    pub live_frames: u64,
    /// The largest radiosity patch of global mode's solution (m^2; `None`:
    /// the radiosity job's default), offline and live.
    pub patch_area: Option<f64>,
}

/// The largest share of a camera figure the truth's noise may be before
/// [`GiBenchOptions::max_truth_paths`] raises its paths.
pub const NOISE_SHARE: f64 = 1.0 / 3.0;

/// What the live cluster measured in one mode.
#[derive(Clone, Debug, Default)]
pub struct LiveFigures {
    /// Global-illumination updates: request to publish (ms), p50.
    pub update_ms_p50: Option<f64>,
    /// The same, p99.
    pub update_ms_p99: Option<f64>,
    /// Frames from a moved state to the first frame drawn with its
    /// update, at most.
    pub frames_stale_max: Option<u64>,
    /// Updates published.
    pub updates: usize,
    /// Swap skew p99 (ms).
    pub swap_skew_ms_p99: Option<f64>,
    /// Tracking to swap p99 (ms).
    pub tracking_to_swap_ms_p99: Option<f64>,
    /// Frame-clock ticks dropped.
    pub dropped_frames: u64,
}

/// What the walk moves in a live run besides the observers' heads.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum WalkMove {
    /// The whole walk: the light and the object.
    All,
    /// The carried light only.
    Light,
    /// The carried virtual object only
    /// ([`crate::tracking::scripted::carried_object`]).
    Object,
}

impl WalkMove {
    /// The record's `move`.
    pub fn name(self) -> &'static str {
        match self {
            Self::All => "light+object",
            Self::Light => "light",
            Self::Object => "object",
        }
    }

    /// The walk's bodies with the other move's body left untracked.
    fn bodies(self, scene: &showcase_proto::Showcase) -> showcase_proto::config::TrackingConfig {
        use crate::tracking::scripted::{LIGHT_BODY, OBJECT_BODY};
        let mut config = walk_tracking(scene, TrackingSource::Scripted);
        let other = match self {
            Self::All => None,
            Self::Light => Some(OBJECT_BODY),
            Self::Object => Some(LIGHT_BODY),
        };
        config.bodies.retain(|b| Some(b.id) != other);
        config
    }
}

/// Run the scripted walk on `scene` in `mode`, moving the heads and what
/// `moving` names, over a loopback cluster for `frames` frames (one
/// state-hash node per face and projector).
pub fn live_figures(
    scene: &showcase_proto::Showcase,
    mode: showcase_proto::IlluminationMode,
    moving: WalkMove,
    frames: u64,
    patch_area: Option<f64>,
) -> Result<LiveFigures> {
    use crate::cluster::commands::{bench_record, output_nodes, walk_plan_tracking};
    use crate::cluster::{LoopbackPlan, run_loopback};
    let mut scene = scene.clone();
    scene.illumination = mode;
    let nodes = output_nodes(&scene);
    let count = nodes.len();
    let plan = LoopbackPlan {
        nodes,
        keep_frames: true,
        illumination_patch_area: patch_area,
        ..walk_plan_tracking(&scene, &moving.bodies(&scene), 0, INTERACTIVE_HZ, frames)?
    };
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()
        .context("cannot start the async runtime")?;
    let result = runtime.block_on(run_loopback(plan))?;
    let rec = bench_record(count, INTERACTIVE_HZ, frames, &result);
    let u = crate::cluster::illumination::UpdateSummary::of(&result.run.illumination_updates);
    Ok(LiveFigures {
        update_ms_p50: u.latency_ms_p50,
        update_ms_p99: u.latency_ms_p99,
        frames_stale_max: u.frames_stale_max,
        updates: u.updates,
        swap_skew_ms_p99: rec.swap_skew_ms_p99,
        tracking_to_swap_ms_p99: rec.tracking_to_swap_ms_p99,
        dropped_frames: rec.dropped_frames,
    })
}

/// The records of one scene: one per mode (`direct`, `global`), and with
/// [`GiBenchOptions::without_occlusion`] one per mode without occlusion
/// shadows (`occlusion_shadows: false`).
pub fn bench_gi_scene(scene_path: &Path, options: &GiBenchOptions) -> Result<Vec<Value>> {
    let truth = crate::scene_file::load_any(scene_path)?;
    let truth = views::at_demo_resolution(&truth)?;
    anyhow::ensure!(
        !truth.projectors.is_empty() && !truth.cameras.is_empty(),
        "{}: bench gi needs a projector and a camera",
        scene_path.display()
    );
    let tracker =
        crate::tracking::Tracker::new(&walk_tracking(&truth, TrackingSource::Scripted), &truth)?;
    let mut show = Show::new(Tracking::Scripted(tracker), INTERACTIVE_HZ as f64);
    let mut state = None;
    for f in 0..=options.frame {
        state = Some(show.frame_state(f, 0.0, &truth, 1).0);
    }
    let state = state.context("no frame")?;
    let resolved = showcase_light::render::FrameScene::resolve(&truth, &state)?;
    let solve_options = crate::radiosity_job::RadiosityOptions {
        max_patch_area: options.patch_area,
        ..Default::default()
    }
    .for_scene(&resolved.showcase);
    let gpu = Backend::open();
    let cpu = Backend::Cpu("the GPU renderer always draws occlusion shadows".into());
    // The live cluster first, each move (the object's where the scene has
    // one to carry) and mode on its own: the offline judging below would
    // compete with it for the cores.
    let mut live = Vec::new();
    if options.live_frames > 0 {
        let mut moves = vec![WalkMove::Light];
        if crate::tracking::scripted::carried_object(&truth).is_some() {
            moves.push(WalkMove::Object);
        }
        for moving in moves {
            let mut both = Vec::new();
            for mode in [
                showcase_proto::IlluminationMode::Direct,
                showcase_proto::IlluminationMode::Global,
            ] {
                both.push(live_figures(
                    &truth,
                    mode,
                    moving,
                    options.live_frames,
                    options.patch_area,
                )?);
            }
            live.push((moving, both));
        }
    }
    let mut records = Vec::new();
    let occlusion: &[bool] = if options.without_occlusion {
        &[true, false]
    } else {
        &[true]
    };
    let mut paths = options.truth_paths.max(1);
    for &occlusion_shadows in occlusion {
        // Without occlusion shadows no element is left dark for an eye.
        let eyes = if occlusion_shadows {
            resolved.eyes.as_slice()
        } else {
            &[]
        };
        let t = Instant::now();
        let (field, elements) =
            crate::radiosity_job::indirect_field(&resolved.showcase, eyes, &solve_options)?;
        let solve_s = t.elapsed().as_secs_f64();
        let field = Arc::new(field);
        let judge_both = |paths: u32| -> Result<Vec<Value>> {
            let transport = Transport::complete(CompleteOptions {
                paths_per_point: paths,
                seed: 24,
            });
            ["direct", "global"]
                .into_iter()
                .map(|mode| {
                    judge(
                        &truth,
                        &state,
                        if occlusion_shadows { &gpu } else { &cpu },
                        transport.clone(),
                        (mode == "global").then(|| field.clone()),
                        occlusion_shadows,
                        elements,
                        solve_s,
                    )
                })
                .collect()
        };
        let mut judged = judge_both(paths)?;
        // The first setting finds the paths; the one without occlusion
        // shadows is judged with the same.
        if occlusion_shadows {
            loop {
                let global = &judged[1];
                let Some(more) = raised_truth_paths(
                    paths,
                    options.max_truth_paths,
                    global["camera_consistency_rel_rmse"]
                        .as_f64()
                        .unwrap_or(0.0),
                    global["compared_noise_rel_rmse"].as_f64().unwrap_or(0.0),
                ) else {
                    break;
                };
                paths = more;
                judged = judge_both(paths)?;
            }
        }
        for (m, judged) in judged.into_iter().enumerate() {
            // One record per move the live cluster ran, each with the same
            // offline figures; one without live figures where it ran none
            // (and without occlusion shadows).
            let runs: Vec<Option<(WalkMove, &LiveFigures)>> =
                if occlusion_shadows && !live.is_empty() {
                    live.iter()
                        .map(|(moving, both)| Some((*moving, &both[m])))
                        .collect()
                } else {
                    vec![None]
                };
            for run in runs {
                let mut record = judged.clone();
                if let (Some((moving, l)), Some(map)) = (run, record.as_object_mut()) {
                    // The walk moves the observers' heads and this.
                    map.insert("move".into(), json!(moving.name()));
                    map.insert("live_frames".into(), json!(options.live_frames));
                    map.insert("updates".into(), json!(l.updates));
                    map.insert("update_ms_p50".into(), json!(l.update_ms_p50));
                    map.insert("update_ms_p99".into(), json!(l.update_ms_p99));
                    map.insert("frames_stale_max".into(), json!(l.frames_stale_max));
                    map.insert("swap_skew_ms_p99".into(), json!(l.swap_skew_ms_p99));
                    map.insert(
                        "tracking_to_swap_ms_p99".into(),
                        json!(l.tracking_to_swap_ms_p99),
                    );
                    map.insert("dropped_frames".into(), json!(l.dropped_frames));
                }
                if let Some(map) = record.as_object_mut() {
                    map.insert("max_patch_area".into(), json!(solve_options.patch_area()));
                    map.insert("truth_paths".into(), json!(paths));
                }
                records.push(record);
            }
        }
    }
    Ok(records)
}

/// The truth's paths to judge with again: four times `paths`, at most
/// `max`, while its `noise` is over [`NOISE_SHARE`] of the camera
/// `figure`; `None`: these will do.
fn raised_truth_paths(paths: u32, max: u32, figure: f64, noise: f64) -> Option<u32> {
    (paths < max && noise > NOISE_SHARE * figure).then(|| paths.saturating_mul(4).min(max))
}

/// One record: the maps of one mode judged in the complete world.
#[allow(clippy::too_many_arguments)]
fn judge(
    truth: &showcase_proto::Showcase,
    state: &showcase_proto::FrameState,
    backend: &Backend,
    transport: Transport,
    field: Option<Arc<showcase_light::render::IndirectField>>,
    occlusion_shadows: bool,
    elements: usize,
    solve_s: f64,
) -> Result<Value> {
    let mode = if field.is_some() { "global" } else { "direct" };
    let mut renderers = NodeRenderers::new(backend, Arc::new(truth.clone()))?;
    if let Some(field) = field {
        renderers.set_indirect(field);
    }
    if !occlusion_shadows {
        renderers.without_occlusion_shadows()?;
    }
    let outputs = renderers.render(state)?;
    let mut camera = None;
    let mut per_object = serde_json::Map::new();
    let mut noise: f64 = 0.0;
    for c in 0..truth.cameras.len() {
        let r = views::camera_consistency(truth, state, &outputs, c, transport.clone())?;
        camera = Some(camera.map_or(r.rel_rmse, |w: f64| w.max(r.rel_rmse)));
        noise = noise.max(r.noise.map_or(0.0, |n| n.compared));
        for (name, e) in r.per_object {
            let w = per_object.entry(name).or_insert(json!(0.0));
            *w = json!(w.as_f64().unwrap_or(0.0).max(e));
        }
    }
    // Every covered pixel, those that show a virtual object, and every
    // covered pixel under the ideal CRT.
    let (mut delta_e, mut virtual_, mut ideal) = (Vec::new(), Vec::new(), Vec::new());
    for o in 0..truth.observers.len() {
        let r = views::observe(truth, state, &outputs, o, transport.clone())?;
        let finite = |d: &&f64| d.is_finite();
        delta_e.extend(r.delta_e.iter().filter(finite));
        virtual_.extend(
            r.delta_e
                .iter()
                .zip(&r.view.sees_virtual.data)
                .filter(|(d, v)| **v && d.is_finite())
                .map(|(d, _)| *d),
        );
        ideal.extend(r.delta_e_ideal_crt.iter().filter(finite));
        noise = noise.max(r.noise.map_or(0.0, |n| n.compared));
    }
    Ok(json!({
        "scene": truth.name,
        "elements": elements,
        "mode": mode,
        "occlusion_shadows": occlusion_shadows,
        "frame": state.frame,
        "renderer": backend.describe(),
        "solve_s": (mode == "global").then_some(solve_s),
        "camera_consistency_rel_rmse": camera,
        "camera_consistency_rel_rmse_per_object": per_object,
        "observer_delta_e_median": percentile(&delta_e, 50.0),
        "observer_delta_e_p95": percentile(&delta_e, 95.0),
        "observer_delta_e_median_virtual": percentile(&virtual_, 50.0),
        "observer_delta_e_p95_virtual": percentile(&virtual_, 95.0),
        "observer_delta_e_median_ideal_crt": percentile(&ideal, 50.0),
        "observer_delta_e_p95_ideal_crt": percentile(&ideal, 95.0),
        "compared_noise_rel_rmse": noise,
        "projector_clipped_fractions": outputs.reference_clipped,
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_truth_gets_more_paths_while_its_noise_is_over_a_third_of_the_figure() {
        // The figure-3 camera at 1,024 and 4,096 paths.
        assert_eq!(raised_truth_paths(1024, 16384, 0.0292, 0.0145), Some(4096));
        assert_eq!(raised_truth_paths(4096, 16384, 0.0264, 0.0079), None);
        // Never past the most, and not at all when the paths are fixed.
        assert_eq!(raised_truth_paths(8192, 16384, 0.02, 0.01), Some(16384));
        assert_eq!(raised_truth_paths(16384, 16384, 0.02, 0.01), None);
        assert_eq!(raised_truth_paths(256, 256, 0.02, 0.01), None);
        // No figure to judge: nothing to raise for.
        assert_eq!(raised_truth_paths(1024, 16384, f64::NAN, 0.01), None);
    }
}
