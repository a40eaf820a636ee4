//! The demo's rendering stage: the node renderers' outputs at a few
//! frames of the walk, what the cabinet's camera measures of the
//! projectors' light (the end-to-end consistency check), and what each
//! observer sees of them next to its target.

use super::views::Transport;
use super::{DemoOptions, GalleryRow, INTERACTIVE_HZ, StageOutcome, progress, views};
use anyhow::{Context, Result};
use showcase_light::RgbImage;
use showcase_light::metrics::percentile;
use showcase_light::render::FrameScene;
use std::time::Instant;

/// Frames of the walk the rendering stage draws: a quarter, half and
/// three quarters of the way.
fn rendered_frames(frames: u64) -> Vec<u64> {
    let mut v: Vec<u64> = [1, 2, 3].iter().map(|q| q * frames / 4).collect();
    v.dedup();
    v
}

/// Every output of the cabinet rendered by the node renderers at a few
/// frames of the walk (calibrated devices, demo resolution) in global
/// mode (the field of `fields`, the cluster's solution followed from
/// frame to frame) and in direct mode, what the cabinet's
/// cameras measure of the projectors' light against the target, and what
/// each observer sees of them through the simulated cabinet (true
/// devices) next to its target, with CIEDE2000 heat maps: global mode in
/// the physically complete world (the headline figures), direct mode in
/// it (`_direct_mode`) and in a world of direct light only (`_direct`).
/// `complete_transport` is the complete world, with the targets and real
/// parts earlier phases traced.
pub(super) fn rendering_stage(
    truth: &showcase_proto::Showcase,
    calibrated: &showcase_proto::Showcase,
    opts: &DemoOptions,
    complete_transport: &Transport,
    gallery: &mut Vec<GalleryRow>,
    fields: &mut views::GlobalFields<'_>,
) -> Result<StageOutcome> {
    use crate::cluster::commands::walk_tracking;
    use crate::cluster::{Show, Tracking};
    use showcase_proto::config::TrackingSource;

    let frames = rendered_frames(opts.frames);
    let truth = views::at_demo_resolution(truth)?;
    let calibrated = std::sync::Arc::new(views::at_demo_resolution(calibrated)?);
    // The frame states the cluster sent: the same scripted walk, replayed.
    let tracker =
        crate::tracking::Tracker::new(&walk_tracking(&truth, TrackingSource::Scripted), &truth)?;
    let mut show = Show::new(Tracking::Scripted(tracker), INTERACTIVE_HZ as f64);
    let last = frames.last().copied().unwrap_or(0);
    let mut states = Vec::new();
    for f in 0..=last {
        let (state, _) = show.frame_state(f, 0.0, &truth, 1);
        if frames.contains(&f) {
            states.push(state);
        }
    }
    let backend = views::Backend::open();
    // Direct mode, and global mode (what the demo's cluster runs) with
    // each frame's solution, solved on the nodes' (calibrated) scene.
    let mut renderers = views::NodeRenderers::new(&backend, calibrated.clone())?;
    let mut global_renderers = views::NodeRenderers::new(&backend, calibrated.clone())?;
    eprintln!(
        "[demo] rendering: {} frames x {} outputs with {}...",
        states.len(),
        calibrated.projectors.len() + calibrated.faces.len(),
        backend.describe()
    );
    let observers = truth.observers.len();
    let mut direct = Judged::new(observers, ", direct light only", "-direct");
    let mut direct_mode = Judged::new(observers, ", direct mode", "-direct-mode");
    let mut complete = Judged::new(observers, ", physically complete", "");
    let mut render_s = Vec::new();
    let pb = progress("rendering", Some(states.len() as u64));
    for state in &states {
        pb.set_message(format!("frame {}", state.frame));
        let dir_name = format!("frames/frame-{:04}", state.frame);
        let dir = opts.out.join(&dir_name);
        std::fs::create_dir_all(&dir)
            .with_context(|| format!("cannot create {}", dir.display()))?;
        let t = Instant::now();
        let outputs = renderers.render(state)?;
        render_s.push(t.elapsed().as_secs_f64());
        let field = fields.at(&FrameScene::resolve(&calibrated, state)?)?;
        global_renderers.set_indirect(std::sync::Arc::new(field));
        let global = global_renderers.render(state)?;
        let mut nodes = Vec::new();
        for (mode, outputs) in [("", &global), ("-direct-mode", &outputs)] {
            for (p, img) in calibrated.projectors.iter().zip(&outputs.projectors) {
                let file = format!("{dir_name}/{}{mode}.png", p.name);
                views::write_values(&opts.out.join(&file), img)?;
                nodes.push((format!("{} (pixel values{mode})", p.name), file));
            }
        }
        let mut rows = Vec::new();
        for (judged, transport, outputs) in [
            (&mut direct, Transport::Direct, &outputs),
            (&mut direct_mode, complete_transport.clone(), &outputs),
            (&mut complete, complete_transport.clone(), &global),
        ] {
            let tag = judged.tag;
            for o in 0..observers {
                let r = views::observe(&truth, state, outputs, o, transport.clone())?;
                let name = &truth.observers[o].name;
                let mut images = Vec::new();
                let parts: &[(&str, &RgbImage)] = match transport {
                    Transport::Direct => &[
                        ("target", &r.view.target),
                        ("composite", &r.view.composite),
                        ("through-mirror", &r.view.reflected),
                    ],
                    // The mirror's part is the same in both worlds.
                    Transport::Complete(..) => {
                        &[("target", &r.view.target), ("composite", &r.view.composite)]
                    }
                };
                for (what, img) in parts {
                    let file = format!("{dir_name}/{name}-{what}{}.png", judged.file_suffix);
                    views::write_radiance(&opts.out.join(&file), img, r.exposure)?;
                    images.push((format!("{name}: {what}{tag}"), file));
                }
                let file = format!(
                    "{dir_name}/{name}{}{}",
                    judged.file_suffix,
                    views::HEAT_MAP_SUFFIX
                );
                views::write_heat_map(
                    &opts.out.join(&file),
                    r.view.target.width,
                    r.view.target.height,
                    &r.delta_e,
                )?;
                let median = percentile(&r.delta_e, 50.0).unwrap_or(f64::NAN);
                images.push((format!("{name}: CIEDE2000{tag} (median {median:.2})"), file));
                rows.push(GalleryRow {
                    title: format!(
                        "frame {}: {name}{tag} (rel RMSE {:.3})",
                        state.frame, r.rel_rmse
                    ),
                    images,
                });
                judged.add_observer(o, &r);
            }
            for (c, camera) in truth.cameras.iter().enumerate() {
                let r = views::camera_consistency(&truth, state, outputs, c, transport.clone())?;
                let name = &camera.name;
                let mut images = Vec::new();
                for (what, img) in [("target", &r.view.target), ("measured", &r.view.real)] {
                    let file = format!("{dir_name}/{name}-{what}{}.png", judged.file_suffix);
                    views::write_radiance(&opts.out.join(&file), img, r.exposure)?;
                    images.push((format!("{name}: {what}{tag}"), file));
                }
                rows.push(GalleryRow {
                    title: format!(
                        "frame {}: {name}, projectors only{tag} (rel RMSE {:.4} over {:.0}% of the real pixels)",
                        state.frame,
                        r.rel_rmse,
                        100.0 * r.compared_fraction
                    ),
                    images,
                });
                judged.add_noise(r.noise);
                judged.cameras.add(&r);
            }
        }
        for (mode, outputs) in [("", &global), ("-direct-mode", &outputs)] {
            for (f, _, [left, right]) in &outputs.faces {
                let face = calibrated
                    .faces
                    .get(*f)
                    .map_or("face".to_string(), |f| f.name.clone());
                for (eye, img) in [("left", left), ("right", right)] {
                    let file = format!("{dir_name}/{face}-{eye}{mode}.png");
                    views::write_radiance(&opts.out.join(&file), img, 1.0)?;
                    nodes.push((format!("{face}: {eye} eye{mode}"), file));
                }
            }
        }
        gallery.push(GalleryRow {
            title: format!("frame {}: node outputs", state.frame),
            images: nodes,
        });
        gallery.extend(rows);
        pb.inc(1);
    }
    pb.finish_and_clear();
    let mut figures = serde_json::Map::new();
    complete.insert_figures(&truth, "", &mut figures);
    direct_mode.insert_figures(&truth, "_direct_mode", &mut figures);
    direct.insert_figures(&truth, "_direct", &mut figures);
    // How much the ground truth can be trusted: the complete images' noise
    // over the compared pixels (worst view), and how much of what the
    // camera sees is interreflection.
    figures.insert(
        "ground_truth_noise_rel_rmse".into(),
        serde_json::json!(complete.noise.map(|n| n.target)),
    );
    figures.insert(
        "compared_noise_rel_rmse".into(),
        serde_json::json!(complete.noise.map(|n| n.compared)),
    );
    figures.insert(
        "ground_truth_leaves_out".into(),
        serde_json::json!(showcase_light::sim::world::LEFT_OUT),
    );
    figures.insert(
        "camera_interreflection_rel_rmse".into(),
        serde_json::json!(complete.cameras.interreflection),
    );
    figures.insert("renderer".into(), serde_json::json!(backend.describe()));
    render_s.sort_by(f64::total_cmp);
    Ok(StageOutcome {
        detail: format!(
            "frames {frames:?}: {} projectors and {} faces rendered with {} (median {:.2} s per frame for all outputs, direct mode); judged in the physically complete world (every bounce, path-traced by the sim, {} paths per irradiance-cache point, noise {}): global mode: {}; direct mode: {}; direct mode in a world of direct light only: {}; images in {}/frames",
            calibrated.projectors.len(),
            calibrated.faces.len(),
            backend.describe(),
            render_s
                .get(render_s.len() / 2)
                .copied()
                .unwrap_or(f64::NAN),
            opts.truth_paths,
            complete.noise.map_or("not measured".into(), |n| format!(
                "{:.4} in the target, {:.4} in what is compared",
                n.target, n.compared
            )),
            complete.describe(),
            direct_mode.describe(),
            direct.describe(),
            opts.out.display()
        ),
        figures,
    })
}

/// The rendering stage's seed of the complete views' paths.
pub(super) const COMPLETE_SEED: u64 = 24;

/// Everything the rendering stage measured in one world (direct light
/// only, or physically complete).
struct Judged {
    /// Added to image titles (", direct light only").
    tag: &'static str,
    /// Added to image file names ("-direct").
    file_suffix: &'static str,
    /// Every observer's CIEDE2000 values.
    all_de: Vec<f64>,
    per_observer: Vec<Seen>,
    cameras: SeenByCamera,
    /// The worst noise of the complete views over their compared pixels.
    noise: Option<views::TruthNoise>,
}

impl Judged {
    fn new(observers: usize, tag: &'static str, file_suffix: &'static str) -> Self {
        Self {
            tag,
            file_suffix,
            all_de: Vec::new(),
            per_observer: vec![Seen::default(); observers],
            cameras: SeenByCamera::default(),
            noise: None,
        }
    }

    fn add_observer(&mut self, o: usize, r: &views::ObserverResult) {
        self.all_de
            .extend(r.delta_e.iter().copied().filter(|d| d.is_finite()));
        self.per_observer[o].add(r);
        self.add_noise(r.noise);
    }

    fn add_noise(&mut self, noise: Option<views::TruthNoise>) {
        if let Some(n) = noise {
            let w = self.noise.get_or_insert(n);
            w.target = w.target.max(n.target);
            w.compared = w.compared.max(n.compared);
        }
    }

    /// The worst observer's whole-view figure.
    fn worst_observer(&self) -> f64 {
        self.per_observer
            .iter()
            .map(|p| p.rel)
            .fold(0.0f64, f64::max)
    }

    /// The observers' real surfaces where the method can be right by
    /// design (see `views::ObserverResult`), worst observer.
    fn comparable(&self) -> Option<f64> {
        self.per_observer
            .iter()
            .filter_map(|p| p.rel_real_comparable)
            .reduce(f64::max)
    }

    /// This world's figures, each key ending in `suffix`.
    fn insert_figures(
        &self,
        truth: &showcase_proto::Showcase,
        suffix: &str,
        figures: &mut serde_json::Map<String, serde_json::Value>,
    ) {
        let mut put = |key: &str, v: serde_json::Value| {
            figures.insert(format!("{key}{suffix}"), v);
        };
        put(
            "delta_e2000_median",
            serde_json::json!(percentile(&self.all_de, 50.0)),
        );
        put(
            "delta_e2000_p95",
            serde_json::json!(percentile(&self.all_de, 95.0)),
        );
        // The projector-role consistency figure, measured by the cabinet's camera.
        put(
            "interactive_consistency_rel_rmse",
            serde_json::json!(self.cameras.rel),
        );
        put(
            "interactive_consistency_rel_rmse_per_object",
            serde_json::json!(self.cameras.per_object),
        );
        put(
            "interactive_compared_fraction",
            serde_json::json!(self.cameras.compared_fraction),
        );
        // What each observer sees, composite against target: every covered
        // pixel off item edges, virtual objects and the mirror included.
        put(
            "observer_consistency_rel_rmse",
            serde_json::json!(self.worst_observer()),
        );
        put(
            "observers",
            serde_json::json!(
                self.per_observer
                    .iter()
                    .enumerate()
                    .map(|(o, seen)| serde_json::json!({
                        "observer": truth.observers[o].name,
                        "delta_e2000_median": percentile(&seen.delta_e, 50.0),
                        "delta_e2000_p95": percentile(&seen.delta_e, 95.0),
                        "consistency_rel_rmse": seen.rel,
                        "consistency_rel_rmse_real": seen.rel_real,
                        "consistency_rel_rmse_virtual": seen.rel_virtual,
                        "consistency_rel_rmse_reflective": seen.rel_reflective,
                        "consistency_rel_rmse_per_object": seen.per_object,
                        "projector_reach_fraction": seen.reach,
                        "consistency_rel_rmse_real_comparable": seen.rel_real_comparable,
                        "consistency_rel_rmse_real_comparable_per_object": seen.per_object_comparable,
                        "comparable_real_fraction": seen.comparable_fraction,
                    }))
                    .collect::<Vec<_>>()
            ),
        );
        // The consistency check seen from the eyes, for the real-surface
        // error budget.
        put(
            "observer_consistency_rel_rmse_real_comparable",
            serde_json::json!(self.comparable()),
        );
    }

    /// One line of this world's figures.
    fn describe(&self) -> String {
        format!(
            "camera {}; observers CIEDE2000 median {:.2}, p95 {:.2}, worst rel RMSE {:.3} (off edges, where a projector reaches), real surfaces where the method can be right {:.4}",
            self.cameras.rel.map_or(
                "not measured (the scene has no camera)".to_string(),
                |r| format!(
                    "rel RMSE {r:.4} over at least {:.0}% of the real pixels",
                    100.0 * self.cameras.compared_fraction.unwrap_or(0.0)
                )
            ),
            percentile(&self.all_de, 50.0).unwrap_or(f64::NAN),
            percentile(&self.all_de, 95.0).unwrap_or(f64::NAN),
            self.worst_observer(),
            self.comparable().unwrap_or(f64::NAN),
        )
    }
}

/// What one observer saw over the rendered frames: every CIEDE2000 value
/// and the worst of each figure.
#[derive(Clone, Debug)]
struct Seen {
    delta_e: Vec<f64>,
    rel: f64,
    rel_real: Option<f64>,
    rel_virtual: Option<f64>,
    rel_reflective: Option<f64>,
    per_object: std::collections::BTreeMap<String, f64>,
    reach: f64,
    rel_real_comparable: Option<f64>,
    per_object_comparable: std::collections::BTreeMap<String, f64>,
    comparable_fraction: f64,
}

impl Default for Seen {
    fn default() -> Self {
        Self {
            delta_e: Vec::new(),
            rel: 0.0,
            rel_real: None,
            rel_virtual: None,
            rel_reflective: None,
            per_object: std::collections::BTreeMap::new(),
            reach: 1.0,
            rel_real_comparable: None,
            per_object_comparable: std::collections::BTreeMap::new(),
            comparable_fraction: 1.0,
        }
    }
}

impl Seen {
    fn add(&mut self, r: &views::ObserverResult) {
        let worst = |a: Option<f64>, b: Option<f64>| match (a, b) {
            (Some(a), Some(b)) => Some(a.max(b)),
            (a, b) => a.or(b),
        };
        self.delta_e
            .extend(r.delta_e.iter().copied().filter(|d| d.is_finite()));
        self.rel = self.rel.max(r.rel_rmse);
        self.rel_real = worst(self.rel_real, r.rel_rmse_real);
        self.rel_virtual = worst(self.rel_virtual, r.rel_rmse_virtual);
        self.rel_reflective = worst(self.rel_reflective, r.rel_rmse_reflective);
        for (name, e) in &r.rel_rmse_per_object {
            let w = self.per_object.entry(name.clone()).or_insert(0.0);
            *w = w.max(*e);
        }
        self.reach = self.reach.min(r.reachable_fraction);
        self.rel_real_comparable = worst(self.rel_real_comparable, r.rel_rmse_real_comparable);
        for (name, e) in &r.rel_rmse_real_comparable_per_object {
            let w = self
                .per_object_comparable
                .entry(name.clone())
                .or_insert(0.0);
            *w = w.max(*e);
        }
        self.comparable_fraction = self.comparable_fraction.min(r.comparable_real_fraction);
    }
}

/// What the cabinet's cameras measured over the rendered frames: the worst
/// of each figure ([`views::CameraConsistency`]); all `None` or empty
/// until a camera measured.
#[derive(Clone, Debug, Default)]
struct SeenByCamera {
    rel: Option<f64>,
    per_object: std::collections::BTreeMap<String, f64>,
    compared_fraction: Option<f64>,
    /// The largest interreflection share of what a camera measured.
    interreflection: Option<f64>,
}

impl SeenByCamera {
    fn add(&mut self, r: &views::CameraConsistency) {
        self.rel = Some(self.rel.map_or(r.rel_rmse, |w| w.max(r.rel_rmse)));
        for (name, e) in &r.per_object {
            let w = self.per_object.entry(name.clone()).or_insert(0.0);
            *w = w.max(*e);
        }
        self.compared_fraction = Some(
            self.compared_fraction
                .map_or(r.compared_fraction, |c| c.min(r.compared_fraction)),
        );
        if let Some(share) = r.interreflection_share {
            self.interreflection = Some(self.interreflection.unwrap_or(0.0).max(share));
        }
    }
}
