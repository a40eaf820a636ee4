//! Photometric consistency (`bench photometric`, the demo's photometric
//! phase, `calibrate --photometric` on the simulated showcase): each face
//! calibrated through its beam splitter by a camera in its observer's
//! place ([`crate::calibrate::photometric`]), the recovered parameters
//! judged against the simulated devices' truth, and what the observers see
//! at one frame of the walk in global mode, in three states of the faces'
//! profiles:
//! - `uncalibrated`: a nominal CRT (gamma 2.2) behind an ideal combiner,
//!   what a node assumes before calibration;
//! - `calibrated`: the measured profiles;
//! - `true`: the simulated devices themselves (the floor).
//!
//! Beside them, `ideal_photometry`: the world without the photometric
//! chain (an ideal combiner and a nominal CRT in the cabinet too), the
//! world of the figures before it was modelled.
//!
//! Each state is judged over every covered pixel and over the
//! occluding-occlusion seams ([`ObserverView::seams`]): where the face
//! draws a real surface next to the real surface itself.
//!
//! [`ObserverView::seams`]: showcase_light::observer_view::ObserverView::seams

use super::INTERACTIVE_HZ;
use super::views::{self, Backend, NodeRenderers, Outputs, Transport};
use crate::calibrate::photometric::{
    FaceCalibration, PhotometricOptions, ProjectorCalibration, SimMirrorCamera, calibrate_face,
    calibrate_projector,
};
use crate::cluster::commands::walk_tracking;
use crate::cluster::{Show, Tracking};
use anyhow::{Context, Result};
use serde_json::{Value, json};
use showcase_light::metrics::percentile;
use showcase_light::observer_view::complete::CompleteOptions;
use showcase_light::render::FrameScene;
use showcase_proto::config::TrackingSource;
use showcase_proto::{Camera, CrtPhotometry, CrtResponse, ProjectorResponse, Showcase};
use std::sync::Arc;
use std::time::Instant;

/// The gamma a node assumes of an uncalibrated CRT.
pub const NOMINAL_GAMMA: f32 = 2.2;

/// One face's calibration, with its errors against the simulated truth.
#[derive(Debug)]
pub struct JudgedFace {
    /// The face's index in the scene.
    pub face: usize,
    /// The calibration.
    pub calibration: FaceCalibration,
    /// Per channel, the largest relative error of the recovered camera
    /// response over the middle 90 % of its range of signal (after its one
    /// unknown scale per channel).
    pub camera_response_error: [f64; 3],
    /// The same over the middle 90 % of the codes.
    pub camera_response_error_codes: [f64; 3],
    /// Per channel, the largest relative error of the profile's light
    /// (`R / T * emit(d)`) against the true device's, for drive 0.1 to 1.
    pub crt_curve_error: [f64; 3],
    /// Per channel, the relative error of the profile's `R / T * peak`.
    pub balance_error: [f64; 3],
    /// Seconds the calibration took.
    pub seconds: f64,
}

/// One projector's calibration, with its errors against the simulated
/// truth.
#[derive(Debug)]
pub struct JudgedProjector {
    /// The projector's index in the scene.
    pub projector: usize,
    /// The calibration.
    pub calibration: ProjectorCalibration,
    /// Per channel, the largest relative error of the profile's light
    /// against the true device's, for device value 0.1 to 1.
    pub curve_error: [f64; 3],
    /// The same of the product's model alone (uncalibrated).
    pub curve_error_before: [f64; 3],
    /// Per channel, the profile's gamma less the true one.
    pub gamma_error: [f64; 3],
    /// Per channel, the profile's black level over the true one, less 1.
    pub black_error: [f64; 3],
    /// Seconds the calibration took.
    pub seconds: f64,
}

/// Every device calibrated photometrically: the faces, then the
/// projectors.
#[derive(Debug)]
pub struct Judged {
    /// The faces.
    pub faces: Vec<JudgedFace>,
    /// The projectors.
    pub projectors: Vec<JudgedProjector>,
}

/// Per channel, the largest relative error of `curve`'s light against
/// `truth`'s, for value 0.1 to 1 in steps of 0.01.
pub fn projector_curve_error(curve: &CrtResponse, truth: &CrtResponse) -> [f64; 3] {
    std::array::from_fn(|c| {
        (10..=100)
            .map(|k| {
                let d = glam::Vec3::splat(k as f32 / 100.0);
                let (got, want) = (curve.emit(d)[c], truth.emit(d)[c]);
                f64::from(((got - want) / want).abs())
            })
            .fold(0.0, f64::max)
    })
}

/// A projector's light per device value: its photometry, or its model.
fn curve_of(r: &ProjectorResponse) -> CrtResponse {
    r.photometry.unwrap_or_else(|| r.model_curve())
}

/// Calibrate every face of `product` (the nodes' scene: calibrated
/// devices) that serves an observer, in the simulated showcase `truth`,
/// with the scene's first camera on a tripod at that observer's left eye;
/// then every projector, with the first face's tripod and its recovered
/// response; the real light is path-traced with `truth_paths` paths per
/// point.
pub fn calibrate_faces(
    truth: &Showcase,
    product: &Showcase,
    options: &PhotometricOptions,
    truth_paths: u32,
) -> Result<Judged> {
    let mut projectors = Vec::new();
    let state = crate::cluster::illumination::initial_state(truth, 1);
    let frame = FrameScene::resolve(truth, &state)?;
    let tripod = truth
        .cameras
        .first()
        .context("photometric calibration needs a camera (the scene has none)")?;
    let mut judged = Vec::new();
    for (f, face) in truth.faces.iter().enumerate() {
        let Some(observer) = views::face_observer(truth, f) else {
            continue;
        };
        let t = Instant::now();
        // The observer's left eye's view at a quarter of its pixels: plenty
        // for regions of a uniform screen and a spot.
        let eye = views::eye_camera(truth, &state, observer);
        let (w, h) = (eye.width / 2, eye.height / 2);
        let camera = Camera {
            name: format!(
                "{} on a tripod at {}",
                tripod.name, truth.observers[observer].name
            ),
            device: crate::capture::resize_device(&eye, w, h)?,
            response: tripod.response.clone(),
        };
        let mut rig = SimMirrorCamera::new(
            &frame,
            face,
            &camera,
            CompleteOptions {
                paths_per_point: truth_paths,
                seed: 28 + f as u64,
            },
        )?;
        let product_face = product
            .faces
            .get(f)
            .context("the product scene lacks a face")?;
        let calibration = calibrate_face(
            &mut rig,
            product,
            product_face,
            &camera.device,
            &product_face.photometry,
            options,
        )
        .with_context(|| format!("calibrating {} photometrically", face.name))?;
        let seconds = t.elapsed().as_secs_f64();
        judged.push(JudgedFace {
            face: f,
            camera_response_error: camera_response_error(&calibration, &camera, false),
            camera_response_error_codes: camera_response_error(&calibration, &camera, true),
            crt_curve_error: crt_curve_error(&calibration.profile, &face.photometry),
            balance_error: std::array::from_fn(|c| {
                let p = &calibration.profile;
                let truth = &face.photometry;
                let ratio = |ph: &CrtPhotometry| {
                    f64::from(ph.splitter.reflection[c] / ph.splitter.transmission[c])
                        * f64::from(ph.crt.peak[c])
                };
                (ratio(p) / ratio(truth) - 1.0).abs()
            }),
            calibration,
            seconds,
        });
        if !projectors.is_empty() || truth.projectors.is_empty() {
            continue;
        }
        let response = &judged
            .last()
            .context("just calibrated")?
            .calibration
            .response;
        for (p, true_projector) in truth.projectors.iter().enumerate() {
            let t = Instant::now();
            let node = product
                .projectors
                .get(p)
                .context("the product scene lacks a projector")?;
            let calibration = calibrate_projector(&mut rig, p, node, response, options)
                .with_context(|| format!("calibrating {} photometrically", node.name))?;
            let truth_curve = curve_of(&true_projector.response);
            let model = node.response.model_curve();
            let got = calibration.profile;
            projectors.push(JudgedProjector {
                projector: p,
                curve_error: projector_curve_error(&got, &truth_curve),
                curve_error_before: projector_curve_error(&model, &truth_curve),
                gamma_error: std::array::from_fn(|c| {
                    f64::from(got.gamma[c]) - f64::from(truth_curve.gamma[c])
                }),
                black_error: std::array::from_fn(|c| {
                    f64::from(got.black_level[c]) / f64::from(truth_curve.black_level[c]) - 1.0
                }),
                calibration,
                seconds: t.elapsed().as_secs_f64(),
            });
        }
    }
    Ok(Judged {
        faces: judged,
        projectors,
    })
}

/// The recovered response against the camera's true one: per channel, the
/// ratio of recovered to true exposure over the codes whose true signal
/// lies in the middle 90 % of the camera's range (5 % to 95 % of full
/// scale: below, the read noise dominates a frame; above, the shoulder
/// and the clip), divided by its geometric mean; the largest departure
/// from 1. With `codes` instead over codes 5 % to 95 % of the code range.
fn camera_response_error(calibration: &FaceCalibration, camera: &Camera, codes: bool) -> [f64; 3] {
    let r = &calibration.response;
    let max = f64::from(r.levels() - 1);
    std::array::from_fn(|c| {
        let ratios: Vec<f64> = (0..r.levels())
            .filter_map(|z| {
                let z = f64::from(z);
                let truth = camera.response.decode(c, z / max);
                let inside = if codes {
                    (0.05 * max..=0.95 * max).contains(&z)
                } else {
                    (0.05..=0.95).contains(&truth)
                };
                inside.then(|| r.exposure(c, z) / truth)
            })
            .filter(|x| x.is_finite() && *x > 0.0)
            .collect();
        if ratios.is_empty() {
            return f64::NAN;
        }
        let scale = (ratios.iter().map(|x| x.ln()).sum::<f64>() / ratios.len() as f64).exp();
        ratios
            .iter()
            .map(|x| (x / scale - 1.0).abs())
            .fold(0.0, f64::max)
    })
}

/// Per channel, the largest relative error of `profile`'s light through
/// the mirror against `truth`'s, for drive 0.1 to 1 in steps of 0.01.
fn crt_curve_error(profile: &CrtPhotometry, truth: &CrtPhotometry) -> [f64; 3] {
    std::array::from_fn(|c| {
        (10..=100)
            .map(|k| {
                let mut d = glam::Vec3::ZERO;
                d[c] = k as f32 / 100.0;
                let (got, want) = (profile.seen(d)[c], truth.seen(d)[c]);
                f64::from(((got - want) / want).abs())
            })
            .fold(0.0, f64::max)
    })
}

/// The profiles of one state, by face index.
fn profiles(scene: &Showcase, by_face: impl Fn(usize) -> CrtPhotometry) -> Vec<CrtPhotometry> {
    (0..scene.faces.len()).map(by_face).collect()
}

/// What the observers see of `outputs` (its faces' and projectors'
/// profiles replaced by `profiles`) in `truth`: CIEDE2000 over every covered pixel and over the
/// seams, median and p95, and the fraction of face pixels driven to the
/// top (the CRT too dim for the light asked of it).
fn judge_state(
    truth: &Showcase,
    state: &showcase_proto::FrameState,
    outputs: &mut Outputs,
    (profiles, projector_profiles): (Vec<CrtPhotometry>, Vec<ProjectorResponse>),
    transport: &Transport,
) -> Result<Value> {
    outputs.profiles = profiles;
    outputs.projector_profiles = projector_profiles;
    let (mut all, mut seams) = (Vec::new(), Vec::new());
    let mut seam_pixels = 0;
    for o in 0..truth.observers.len() {
        let r = views::observe(truth, state, outputs, o, transport.clone())?;
        let mask = r.view.seams();
        seam_pixels += mask.data.iter().filter(|m| **m).count();
        for (d, m) in r.delta_e.iter().zip(&mask.data) {
            if d.is_finite() {
                all.push(*d);
                if *m {
                    seams.push(*d);
                }
            }
        }
    }
    Ok(json!({
        "observer_delta_e_median": percentile(&all, 50.0),
        "observer_delta_e_p95": percentile(&all, 95.0),
        "seam_delta_e_median": percentile(&seams, 50.0),
        "seam_delta_e_p95": percentile(&seams, 95.0),
        "seam_pixels": seam_pixels,
    }))
}

/// `bench photometric`'s record of the simulated showcase `truth` whose
/// nodes know `calibrated` (and the demo's figures), both taken to the
/// demo's resolution: the calibration of each face, starting from
/// `calibrated`'s profiles, judged against the truth, and the observers
/// at `frame` of the walk in each state; with the faces judged.
pub fn bench_photometric_scene(
    truth: &Showcase,
    calibrated: &Showcase,
    frame: u64,
    truth_paths: u32,
) -> Result<(Judged, Value)> {
    let transport = Transport::complete(CompleteOptions {
        paths_per_point: truth_paths,
        seed: super::rendering::COMPLETE_SEED,
    });
    let (scene, first) = views::live_scene(calibrated)?;
    let mut fields = views::GlobalFields::start(&scene, &first)?;
    photometric_record(truth, calibrated, frame, &transport, &mut fields)
}

/// [`bench_photometric_scene`] in the complete world `transport` (its
/// paths also trace the tripod's real light; targets and real parts
/// traced before are reused), with global mode's field at `frame` from
/// `fields`.
pub(super) fn photometric_record(
    truth: &Showcase,
    calibrated: &Showcase,
    frame: u64,
    transport: &Transport,
    fields: &mut views::GlobalFields<'_>,
) -> Result<(Judged, Value)> {
    let Transport::Complete(options, _) = transport else {
        anyhow::bail!("the photometric figures are judged in the complete world");
    };
    let truth_paths = options.paths_per_point;
    let truth = views::at_demo_resolution(truth)?;
    let calibrated = views::at_demo_resolution(calibrated)?;
    let t = Instant::now();
    let judged = calibrate_faces(
        &truth,
        &calibrated,
        &PhotometricOptions::default(),
        truth_paths,
    )?;
    let calibration_s = t.elapsed().as_secs_f64();
    let faces = &judged.faces;
    // One frame of the walk in global mode, as the demo's cluster draws it.
    let tracker =
        crate::tracking::Tracker::new(&walk_tracking(&truth, TrackingSource::Scripted), &truth)?;
    let mut show = Show::new(Tracking::Scripted(tracker), INTERACTIVE_HZ as f64);
    let mut state = None;
    for f in 0..=frame {
        state = Some(show.frame_state(f, 0.0, &truth, 1).0);
    }
    let state = state.context("no frame")?;
    let field = fields.at(&FrameScene::resolve(&calibrated, &state)?)?;
    let backend = Backend::open();
    let mut renderers = NodeRenderers::new(&backend, Arc::new(calibrated.clone()))?;
    renderers.set_indirect(Arc::new(field));
    let mut outputs = renderers.render(&state)?;
    let nominal = CrtPhotometry::nominal(NOMINAL_GAMMA);
    let measured: Vec<(usize, CrtPhotometry)> = faces
        .iter()
        .map(|j| (j.face, j.calibration.profile))
        .collect();
    // The projectors' nodes: the model alone, the measured profile, the
    // true device.
    let model: Vec<ProjectorResponse> = calibrated
        .projectors
        .iter()
        .map(|p| ProjectorResponse {
            photometry: None,
            ..p.response.clone()
        })
        .collect();
    let with = |curve: &dyn Fn(usize) -> Option<CrtResponse>| -> Vec<ProjectorResponse> {
        model
            .iter()
            .enumerate()
            .map(|(i, r)| ProjectorResponse {
                photometry: curve(i),
                ..r.clone()
            })
            .collect()
    };
    let projectors_measured = with(&|i| {
        judged
            .projectors
            .iter()
            .find(|j| j.projector == i)
            .map(|j| j.calibration.profile)
    });
    let projectors_true = with(&|i| Some(curve_of(&truth.projectors[i].response)));
    let mut states = serde_json::Map::new();
    for (name, p) in [
        (
            "uncalibrated",
            (profiles(&truth, |_| nominal), model.clone()),
        ),
        (
            "calibrated",
            (
                profiles(&truth, |f| {
                    measured
                        .iter()
                        .find(|(i, _)| *i == f)
                        .map_or(nominal, |(_, p)| *p)
                }),
                projectors_measured,
            ),
        ),
        (
            "true",
            (
                profiles(&truth, |f| truth.faces[f].photometry),
                projectors_true,
            ),
        ),
    ] {
        states.insert(
            name.into(),
            judge_state(&truth, &state, &mut outputs, p, transport)?,
        );
    }
    // The world without the chain: a nominal CRT behind an ideal combiner
    // in the cabinet, and the nodes assuming just that.
    let mut ideal = truth.clone();
    for f in &mut ideal.faces {
        f.photometry = nominal;
    }
    for p in &mut ideal.projectors {
        p.response.photometry = None;
    }
    states.insert(
        "ideal_photometry".into(),
        judge_state(
            &ideal,
            &state,
            &mut outputs,
            (profiles(&ideal, |_| nominal), model.clone()),
            transport,
        )?,
    );
    let record = json!({
        "scene": truth.name,
        "frame": state.frame,
        "renderer": backend.describe(),
        "calibration_s": calibration_s,
        "faces": faces.iter().map(|j| json!({
            "face": truth.faces[j.face].name,
            "seconds": j.seconds,
            "frames": j.calibration.frames,
            "camera_response_error": j.camera_response_error,
            "camera_response_error_codes": j.camera_response_error_codes,
            "crt_curve_error": j.crt_curve_error,
            "balance_error": j.balance_error,
            "held_out_error": j.calibration.held_out_error,
            "held_out_error_before": j.calibration.held_out_error_before,
            "kept_previous": j.calibration.kept_previous,
            "profile": j.calibration.profile,
            "truth": truth.faces[j.face].photometry,
            "reference": j.calibration.reference,
            "screen_pixels": j.calibration.screen_pixels,
        })).collect::<Vec<_>>(),
        "projectors": judged.projectors.iter().map(|j| json!({
            "projector": truth.projectors[j.projector].name,
            "seconds": j.seconds,
            "frames": j.calibration.frames,
            "pixels": j.calibration.pixels,
            "curve_error": j.curve_error,
            "curve_error_uncalibrated": j.curve_error_before,
            "gamma_error": j.gamma_error,
            "black_error": j.black_error,
            "held_out_error": j.calibration.held_out_error,
            "held_out_error_before": j.calibration.held_out_error_before,
            "kept_previous": j.calibration.kept_previous,
            "profile": j.calibration.profile,
            "truth": curve_of(&truth.projectors[j.projector].response),
        })).collect::<Vec<_>>(),
        "states": states,
    });
    Ok((judged, record))
}

/// `calibrate --photometric --scene SCENE --out DIR`: calibrate each face
/// and projector of the simulated showcase `scene` (its nodes starting
/// from the nominal profile and the projectors' model) and write
/// `DIR/<face>-photometric.json` and `DIR/<projector>-photometric.json`
/// (what a face's or projector's `photometric_profile` reads) and
/// `DIR/summary.json` (the measurements and, the sim knowing them, the
/// errors against the true devices).
pub fn run_calibrate_photometric(
    scene: &std::path::Path,
    out: &std::path::Path,
    truth_paths: u32,
) -> Result<()> {
    let truth = crate::scene_file::load_any(scene)?;
    let truth = views::at_demo_resolution(&truth)?;
    if let Some(reason) = super::unsupported(&truth, "photometric") {
        anyhow::bail!(
            "{}: cannot calibrate photometrically: {reason}",
            scene.display()
        );
    }
    let mut nodes = truth.clone();
    for f in &mut nodes.faces {
        f.photometry = CrtPhotometry::nominal(NOMINAL_GAMMA);
    }
    for p in &mut nodes.projectors {
        p.response.photometry = None;
    }
    std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
    let pb = crate::progress::spinner("calibrate --photometric", None);
    pb.set_message("each face through its mirror, from its observer's place");
    let judged = calibrate_faces(&truth, &nodes, &PhotometricOptions::default(), truth_paths)?;
    pb.finish_and_clear();
    let mut summary = Vec::new();
    for j in &judged.faces {
        let c = &j.calibration;
        let file = write_profile(
            out,
            &c.face,
            &crate::calibrate::photometric::ProfileFile::from(c),
        )?;
        eprintln!(
            "{}: {} frames in {:.1} s, held-out error {:.2} % (nominal profile {:.1} %){}; wrote {}",
            c.face,
            c.frames,
            j.seconds,
            100.0 * c.held_out_error,
            100.0 * c.held_out_error_before,
            kept_note(c.kept_previous),
            file.display()
        );
        summary.push(json!({
            "face": c.face,
            "seconds": j.seconds,
            "frames": c.frames,
            "profile": c.profile,
            "fitted": c.fitted,
            "kept_previous": c.kept_previous,
            "held_out_error": c.held_out_error,
            "held_out_error_before": c.held_out_error_before,
            "noise_floor": c.noise_floor,
            "screen_pixels": c.screen_pixels,
            "reference": c.reference,
            "levels": c.levels,
            "truth": truth.faces[j.face].photometry,
            "camera_response_error": j.camera_response_error,
            "camera_response_error_codes": j.camera_response_error_codes,
            "crt_curve_error": j.crt_curve_error,
            "balance_error": j.balance_error,
        }));
    }
    for j in &judged.projectors {
        let c = &j.calibration;
        let file = write_profile(
            out,
            &c.projector,
            &crate::calibrate::photometric::ProjectorProfileFile::from(c),
        )?;
        eprintln!(
            "{}: {} frames in {:.1} s, held-out error {:.2} % (its model {:.1} %){}; wrote {}",
            c.projector,
            c.frames,
            j.seconds,
            100.0 * c.held_out_error,
            100.0 * c.held_out_error_before,
            kept_note(c.kept_previous),
            file.display()
        );
        summary.push(json!({
            "projector": c.projector,
            "seconds": j.seconds,
            "frames": c.frames,
            "profile": c.profile,
            "fitted": c.fitted,
            "kept_previous": c.kept_previous,
            "held_out_error": c.held_out_error,
            "held_out_error_before": c.held_out_error_before,
            "pixels": c.pixels,
            "levels": c.levels,
            "truth": curve_of(&truth.projectors[j.projector].response),
            "curve_error": j.curve_error,
            "curve_error_uncalibrated": j.curve_error_before,
            "gamma_error": j.gamma_error,
            "black_error": j.black_error,
        }));
    }
    let path = out.join("summary.json");
    std::fs::write(&path, serde_json::to_string_pretty(&summary)? + "\n")
        .with_context(|| format!("cannot write {}", path.display()))?;
    eprintln!("wrote {}", path.display());
    Ok(())
}

/// Write `profile` to `out/<name>-photometric.json`; the file's path.
fn write_profile(
    out: &std::path::Path,
    name: &str,
    profile: &impl serde::Serialize,
) -> Result<std::path::PathBuf> {
    let file = out.join(format!("{name}-photometric.json"));
    std::fs::write(&file, serde_json::to_string_pretty(profile)? + "\n")
        .with_context(|| format!("cannot write {}", file.display()))?;
    Ok(file)
}

/// What a progress line adds when the new profile was worse than the
/// one in place.
fn kept_note(kept_previous: bool) -> &'static str {
    if kept_previous {
        ", worse than the profile in place, which is kept"
    } else {
        ""
    }
}
